//! Flow extensions: a straight tube added at an inlet or outlet along the patch normal, so the
//! flow a solver imposes there develops before it reaches the vessel. The tube starts at the
//! patch's rim (a cap's faces are removed, an open end is used as it is), changes its cross
//! section smoothly (a smoothstep over the first diameter) from the rim's shape to the circle
//! of the patch's equivalent diameter, runs on as that cylinder, and ends in a flat cap at
//! `diameters` x the diameter from the patch centre, which becomes the patch.

use super::patches::{PatchKind, Patches, WALL_ID};
use crate::mesh::geometry::{cross64 as cross, dot64 as dot, sub64 as sub};
use crate::mesh::{Mesh, Topology};
use thiserror::Error;

/// Why a flow extension could not be added.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ExtendError {
    #[error("the flow extension length must be a positive number of diameters, not {0}")]
    Length(f64),
    #[error("patch {0} has no rim that closes into one loop")]
    Rim(String),
    #[error(
        "the rim of patch {0} folds over itself seen from its centre: the extension would fold"
    )]
    NotStarShaped(String),
    #[error("no patch has id {id} (the patches are {known}); ids start at 2 with the inlet")]
    UnknownPatch { id: u32, known: String },
    #[error("the extended surface would have more vertices than indices can address")]
    TooLarge,
    #[error("the extended surface is not a valid mesh: {0}")]
    Mesh(#[from] crate::mesh::MeshError),
}

/// The mesh with a flow extension of `diameters` x each patch's equivalent diameter at every
/// patch in `which` (patch ids; all patches when empty), and the patches with the extended ends
/// as their new end caps (`extension_mm` set, face ids matching the new mesh).
pub fn add_flow_extensions(
    mesh: &Mesh,
    patches: &Patches,
    diameters: f64,
    which: &[u32],
) -> Result<(Mesh, Patches), ExtendError> {
    if !(diameters.is_finite() && diameters > 0.0) {
        return Err(ExtendError::Length(diameters));
    }
    if let Some(&id) = which
        .iter()
        .find(|&&id| !patches.patches.iter().any(|p| p.id == id))
    {
        let known: Vec<String> = patches
            .patches
            .iter()
            .map(|p| format!("{} {}", p.id, p.name))
            .collect();
        return Err(ExtendError::UnknownPatch {
            id,
            known: known.join(", "),
        });
    }
    let chosen = |id: u32| which.is_empty() || which.contains(&id);
    let mut positions = mesh.positions().to_vec();
    // Faces kept: everything but the faces of the extended caps.
    let mut triangles = Vec::with_capacity(mesh.n_triangles());
    let mut face_ids = Vec::with_capacity(mesh.n_triangles());
    for (f, t) in mesh.triangles().iter().enumerate() {
        let id = patches.face_ids.get(f).copied().unwrap_or(WALL_ID);
        if id != WALL_ID && chosen(id) {
            continue;
        }
        triangles.push(*t);
        face_ids.push(id);
    }
    let mut out = patches.clone();
    let kept = Mesh::new(positions.clone(), triangles.clone())?;
    let topology = Topology::build(&kept);
    for patch in out.patches.iter_mut().filter(|p| chosen(p.id)) {
        let rim = rim_of(&kept, &topology, patch.centre_mm)
            .ok_or_else(|| ExtendError::Rim(patch.name.clone()))?;
        let (c, n) = (patch.centre_mm, patch.normal);
        let radius = patch.diameter_mm / 2.0;
        let length = diameters * patch.diameter_mm;
        let at = |v: u32| positions[v as usize].map(f64::from);
        // The rim split into its offset along the normal and its direction in the plane.
        let mut in_plane = Vec::with_capacity(rim.len());
        let mut offsets = Vec::with_capacity(rim.len());
        let mut mean_edge = 0.0;
        for (i, &v) in rim.iter().enumerate() {
            let d = sub(at(v), c);
            let off = dot(d, n);
            in_plane.push([d[0] - off * n[0], d[1] - off * n[1], d[2] - off * n[2]]);
            offsets.push(off);
            let edge = sub(at(rim[(i + 1) % rim.len()]), at(v));
            mean_edge += dot(edge, edge).sqrt();
        }
        mean_edge /= rim.len() as f64;
        // Seen from the centre, the rim must turn one way all round (as the cap's will).
        let turn = |i: usize| cross(in_plane[i], in_plane[(i + 1) % rim.len()]);
        let sign = (0..rim.len())
            .map(|i| dot(turn(i), n))
            .sum::<f64>()
            .signum();
        if (0..rim.len()).any(|i| dot(turn(i), n) * sign <= 0.0) {
            return Err(ExtendError::NotStarShaped(patch.name.clone()));
        }
        let rings = ((length / mean_edge.max(1e-9)).ceil() as usize).clamp(1, 10_000);
        let blend = length.min(patch.diameter_mm);
        if positions.len() + rings * rim.len() + 1 >= u32::MAX as usize {
            return Err(ExtendError::TooLarge);
        }
        let mut previous: Vec<u32> = rim.clone();
        for j in 1..=rings {
            let t = length * j as f64 / rings as f64;
            let x = (t / blend).min(1.0);
            let s = x * x * (3.0 - 2.0 * x);
            let mut ring = Vec::with_capacity(rim.len());
            for i in 0..rim.len() {
                let p = in_plane[i];
                let len = dot(p, p).sqrt();
                let u = if len > 0.0 { p.map(|q| q / len) } else { p };
                let along = t + (1.0 - s) * offsets[i];
                let q: [f64; 3] = std::array::from_fn(|k| {
                    c[k] + along * n[k] + (1.0 - s) * p[k] + s * radius * u[k]
                });
                ring.push(positions.len() as u32);
                positions.push(q.map(|x| x as f32));
            }
            for i in 0..rim.len() {
                let i1 = (i + 1) % rim.len();
                let (a, b, qa, qb) = (previous[i], previous[i1], ring[i], ring[i1]);
                triangles.push([b, a, qa]);
                triangles.push([b, qa, qb]);
                face_ids.extend([WALL_ID, WALL_ID]);
            }
            previous = ring;
        }
        // The end cap: a fan from the centre of the last ring, exactly on its plane.
        let centre = positions.len() as u32;
        positions.push([0, 1, 2].map(|k| (c[k] + length * n[k]) as f32));
        let mut faces = Vec::with_capacity(rim.len());
        for i in 0..rim.len() {
            let i1 = (i + 1) % rim.len();
            faces.push(triangles.len() as u32);
            triangles.push([centre, previous[i1], previous[i]]);
            face_ids.push(patch.id);
        }
        let mut vertices = previous;
        vertices.push(centre);
        patch.faces = faces;
        patch.vertices = vertices;
        patch.centre_mm = std::array::from_fn(|k| c[k] + length * n[k]);
        patch.extension_mm = length;
        if patch.kind == PatchKind::OpenEnd {
            patch.kind = PatchKind::ClosedEnd;
        }
    }
    // Without the vertices only the removed caps used (numbered by first use).
    let all: Vec<u32> = (0..triangles.len() as u32).collect();
    let mesh = Mesh::new(positions, triangles)?.select_faces(&all);
    out.wall_faces = face_ids.iter().filter(|&&id| id == WALL_ID).count();
    out.face_ids = face_ids;
    let topology = Topology::build(&mesh);
    let measured = super::remeasure_patches(&mesh, &topology, out.face_ids.clone(), &out);
    Ok((mesh, measured))
}

/// The open boundary loop of `mesh` whose centre is nearest `centre`, ordered the way the
/// faces along it run (each consecutive pair is an edge of a face in that direction).
fn rim_of(mesh: &Mesh, topology: &Topology, centre: [f64; 3]) -> Option<Vec<u32>> {
    let p = mesh.positions();
    let at = |v: u32| p[v as usize].map(f64::from);
    let loop_ = topology
        .boundary_loops()
        .iter()
        .filter(|l| l.closed && l.vertices.len() >= 3)
        .min_by(|a, b| {
            let mean = |l: &crate::mesh::topology::BoundaryLoop| {
                let n = l.vertices.len() as f64;
                let s = l
                    .vertices
                    .iter()
                    .fold([0.0; 3], |s, &v| {
                        let q = at(v);
                        [s[0] + q[0], s[1] + q[1], s[2] + q[2]]
                    })
                    .map(|x| x / n);
                let d = sub(s, centre);
                dot(d, d)
            };
            mean(a).total_cmp(&mean(b))
        })?;
    let mut vertices = loop_.vertices.clone();
    let (a, b) = (vertices[0], vertices[1]);
    let follows = topology.vertex_faces(a as usize).iter().any(|&f| {
        let t = mesh.triangles()[f as usize];
        (0..3).any(|k| t[k] == a && t[(k + 1) % 3] == b)
    });
    if !follows {
        vertices.reverse();
    }
    Some(vertices)
}
