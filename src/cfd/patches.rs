//! Boundary patches of a vessel surface for flow solvers: every cap (a clipped end, detected as
//! in [`crate::analysis::caps`]) and every open boundary loop becomes a patch with a stable id,
//! its centre, its normal pointing out of the fluid, its area and equivalent diameter; the rest
//! of the surface is the wall. Ids follow VMTK's `CellEntityIds`: wall 1, then the patches from
//! 2, the inlet first and the outlets by decreasing area.
//!
//! A surface that is not one 2-manifold vessel (non-manifold edges, several components,
//! inconsistent orientation, no end at all) is refused with the reason: a mesher fed such a
//! surface fails later, far from the cause.

use crate::analysis::caps::{detect_caps, CapParams};
use crate::mesh::geometry::{cross64 as cross, dot64 as dot, sub64 as sub};
use crate::mesh::{Mesh, Topology};
use serde::Serialize;
use thiserror::Error;

/// `CellEntityIds` of the wall (VMTK's convention).
pub const WALL_ID: u32 = 1;

/// What a patch is on the surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PatchKind {
    /// A flat cap where the vessel was clipped (its faces belong to the patch).
    Cap,
    /// An open boundary loop (no faces until it is closed).
    OpenEnd,
    /// An open end closed by a flat cap ([`super::close_open_ends`]).
    ClosedEnd,
}

/// Which patch is the inlet.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Inlet {
    /// The patch of largest area.
    Largest,
    /// The patch at this position when patches are ordered by decreasing area (0 = largest).
    Index(usize),
    /// The patch whose centre is nearest to this point (mm).
    Point([f64; 3]),
}

impl std::str::FromStr for Inlet {
    type Err = String;

    /// `largest`, a patch index in order of decreasing area (0 is the largest), or `X,Y,Z` (mm).
    fn from_str(s: &str) -> Result<Inlet, String> {
        if s == "largest" {
            return Ok(Inlet::Largest);
        }
        if let Ok(index) = s.parse::<usize>() {
            return Ok(Inlet::Index(index));
        }
        let parts: Vec<f64> = s
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("{s:?}: expected largest, a patch index, or X,Y,Z in mm"))?;
        match parts[..] {
            [x, y, z] if parts.iter().all(|v| v.is_finite()) => Ok(Inlet::Point([x, y, z])),
            _ => Err(format!("{s:?}: a point is three finite numbers X,Y,Z (mm)")),
        }
    }
}

/// One boundary patch.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Patch {
    /// `CellEntityIds` value: 2 for the inlet, then 3, 4, ... for the outlets.
    pub id: u32,
    /// `inlet`, `outlet_1`, `outlet_2`, ...
    pub name: String,
    pub kind: PatchKind,
    /// Area-weighted centre (mm).
    pub centre_mm: [f64; 3],
    /// Unit normal pointing out of the fluid.
    pub normal: [f64; 3],
    /// Area of the cap, or of the flat disc spanning the open loop (mm²).
    pub area_mm2: f64,
    /// Diameter of the circle of the same area (mm).
    pub diameter_mm: f64,
    /// Largest distance of the patch's vertices (a loop's rim, a cap's vertices) from the plane
    /// through its centre along its normal (mm): 0 for an exactly planar end.
    pub planarity_mm: f64,
    /// Length of the flow extension that ends in this patch (mm; 0 without one).
    pub extension_mm: f64,
    /// Faces of the patch (empty for an open end).
    #[serde(skip)]
    pub faces: Vec<u32>,
    /// A cap's vertices, or an open loop's vertices in order along the loop.
    #[serde(skip)]
    pub vertices: Vec<u32>,
}

/// The patches of a vessel surface and the `CellEntityIds` of every face.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Patches {
    /// The inlet first, then the outlets.
    pub patches: Vec<Patch>,
    /// Faces of the wall.
    pub wall_faces: usize,
    /// Per face: [`WALL_ID`] or the id of the patch it belongs to.
    #[serde(skip)]
    pub face_ids: Vec<u32>,
}

/// Why a surface has no usable patches.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PatchError {
    #[error("not a 2-manifold: {0} edges have more than two faces")]
    NonManifoldEdges(usize),
    #[error("not a 2-manifold: {0} vertices join separate fans of faces")]
    NonManifoldVertices(usize),
    #[error("not one vessel: the surface has {0} separate components")]
    Components(usize),
    #[error("inconsistently oriented: {0} edges are used in the same direction by both faces")]
    Inconsistent(usize),
    #[error("an open boundary of {0} vertices does not close into a loop")]
    UnclosedBoundary(usize),
    #[error("no caps and no open ends: nothing marks where the flow enters or leaves")]
    NoEnds,
    #[error("{found} patches found, {expected} expected (expect_patches)")]
    Count { found: usize, expected: usize },
    #[error("inlet index {index} given, but there are only {n} patches (0 is the largest)")]
    InletIndex { index: usize, n: usize },
}

/// Finds the patches of a vessel surface (`topology` built from `mesh`). `expect` is the number
/// of patches the caller knows the vessel has; a different count is an error.
pub fn find_patches(
    mesh: &Mesh,
    topology: &Topology,
    inlet: Inlet,
    expect: Option<usize>,
) -> Result<Patches, PatchError> {
    if !topology.non_manifold_edges().is_empty() {
        return Err(PatchError::NonManifoldEdges(
            topology.non_manifold_edges().len(),
        ));
    }
    if !topology.non_manifold_vertices().is_empty() {
        return Err(PatchError::NonManifoldVertices(
            topology.non_manifold_vertices().len(),
        ));
    }
    if topology.n_components() > 1 {
        return Err(PatchError::Components(topology.n_components()));
    }
    if !topology.inconsistent_edges().is_empty() {
        return Err(PatchError::Inconsistent(
            topology.inconsistent_edges().len(),
        ));
    }
    if let Some(open) = topology
        .boundary_loops()
        .iter()
        .find(|l| !l.closed || l.vertices.len() < 3)
    {
        return Err(PatchError::UnclosedBoundary(open.vertices.len()));
    }
    let p = mesh.positions();
    let at = |v: u32| p[v as usize].map(f64::from);

    // Open ends: the loop as the mesh's orientation runs along it, so that the disc closing
    // it (traversing each border edge the other way) is oriented like the mesh.
    let mut found: Vec<Patch> = Vec::new();
    for l in topology.boundary_loops() {
        let mut vertices = l.vertices.clone();
        if !follows_faces(mesh, topology, vertices[0], vertices[1]) {
            vertices.reverse();
        }
        // The closing disc runs against the loop: its vector area is minus the loop's.
        let rim: Vec<[f64; 3]> = vertices.iter().map(|&v| at(v)).collect();
        let (area_vector, centre) = polygon_area_centre(&rim);
        let disc = area_vector.map(|x| -x);
        found.push(patch(
            PatchKind::OpenEnd,
            Vec::new(),
            vertices,
            disc,
            centre,
            &at,
        ));
    }
    // Caps.
    let caps = detect_caps(mesh, topology, None, &CapParams::default());
    for cap in caps.caps {
        found.push(faces_patch(mesh, PatchKind::Cap, cap.faces, cap.vertices));
    }
    if found.is_empty() {
        return Err(PatchError::NoEnds);
    }
    if let Some(expected) = expect {
        if found.len() != expected {
            return Err(PatchError::Count {
                found: found.len(),
                expected,
            });
        }
    }
    // Out of the fluid: the face orientation's outside, unless the surface encloses a
    // negative volume (inside out).
    if enclosed_volume(mesh, &found) < 0.0 {
        for patch in &mut found {
            patch.normal = patch.normal.map(|x| -x);
        }
    }
    // Decreasing area (ties by the order found: loops, then caps), the inlet moved first.
    found.sort_by(|a, b| b.area_mm2.total_cmp(&a.area_mm2));
    let inlet_at = match inlet {
        Inlet::Largest => 0,
        Inlet::Index(index) if index < found.len() => index,
        Inlet::Index(index) => {
            return Err(PatchError::InletIndex {
                index,
                n: found.len(),
            })
        }
        Inlet::Point(q) => (0..found.len())
            .min_by(|&a, &b| {
                norm(sub(found[a].centre_mm, q)).total_cmp(&norm(sub(found[b].centre_mm, q)))
            })
            .unwrap_or(0),
    };
    let first = found.remove(inlet_at);
    found.insert(0, first);
    let mut face_ids = vec![WALL_ID; mesh.n_triangles()];
    for (k, patch) in found.iter_mut().enumerate() {
        patch.id = WALL_ID + 1 + k as u32;
        patch.name = if k == 0 {
            "inlet".into()
        } else {
            format!("outlet_{k}")
        };
        for &f in &patch.faces {
            face_ids[f as usize] = patch.id;
        }
    }
    let wall_faces = face_ids.iter().filter(|&&id| id == WALL_ID).count();
    Ok(Patches {
        patches: found,
        wall_faces,
        face_ids,
    })
}

/// A patch made of faces (a cap, a closed end): vector area, area-weighted centre and planarity
/// from the faces themselves.
fn faces_patch(mesh: &Mesh, kind: PatchKind, faces: Vec<u32>, vertices: Vec<u32>) -> Patch {
    let p = mesh.positions();
    let at = |v: u32| p[v as usize].map(f64::from);
    let tris = mesh.triangles();
    let mut area_vector = [0.0f64; 3];
    let mut weighted = [0.0f64; 3];
    let mut total = 0.0;
    for &f in &faces {
        let [a, b, c] = tris[f as usize].map(at);
        let n = cross(sub(b, a), sub(c, a)).map(|x| x / 2.0);
        let area = norm(n);
        for k in 0..3 {
            area_vector[k] += n[k];
            weighted[k] += area * (a[k] + b[k] + c[k]) / 3.0;
        }
        total += area;
    }
    let centre = weighted.map(|x| if total > 0.0 { x / total } else { 0.0 });
    patch(kind, faces, vertices, area_vector, centre, &at)
}

/// The patches of `prior` measured again on a mesh that was changed without changing its
/// patches (remeshed, extended): faces by `face_ids`, open ends as the boundary loop nearest to
/// where each was. Ids, names, kinds and the direction of each normal are kept.
pub fn remeasure_patches(
    mesh: &Mesh,
    topology: &Topology,
    face_ids: Vec<u32>,
    prior: &Patches,
) -> Patches {
    let p = mesh.positions();
    let at = |v: u32| p[v as usize].map(f64::from);
    let mut patches = Vec::with_capacity(prior.patches.len());
    for old in &prior.patches {
        let mut new = if old.kind == PatchKind::OpenEnd {
            let nearest = topology
                .boundary_loops()
                .iter()
                .map(|l| {
                    let rim: Vec<[f64; 3]> = l.vertices.iter().map(|&v| at(v)).collect();
                    (l, polygon_area_centre(&rim))
                })
                .min_by(|x, y| {
                    norm(sub(x.1 .1, old.centre_mm)).total_cmp(&norm(sub(y.1 .1, old.centre_mm)))
                });
            match nearest {
                Some((l, (area_vector, centre))) => {
                    let mut vertices = l.vertices.clone();
                    let mut disc = area_vector.map(|x| -x);
                    if vertices.len() > 1
                        && !follows_faces(mesh, topology, vertices[0], vertices[1])
                    {
                        vertices.reverse();
                        disc = area_vector;
                    }
                    patch(PatchKind::OpenEnd, Vec::new(), vertices, disc, centre, &at)
                }
                None => old.clone(),
            }
        } else {
            let faces: Vec<u32> = (0..face_ids.len() as u32)
                .filter(|&f| face_ids[f as usize] == old.id)
                .collect();
            let mut vertices: Vec<u32> = faces
                .iter()
                .flat_map(|&f| mesh.triangles()[f as usize])
                .collect();
            vertices.sort_unstable();
            vertices.dedup();
            faces_patch(mesh, old.kind, faces, vertices)
        };
        if dot(new.normal, old.normal) < 0.0 {
            new.normal = new.normal.map(|x| -x + 0.0);
        }
        new.id = old.id;
        new.name = old.name.clone();
        new.extension_mm = old.extension_mm;
        patches.push(new);
    }
    let wall_faces = face_ids.iter().filter(|&&id| id == WALL_ID).count();
    Patches {
        patches,
        wall_faces,
        face_ids,
    }
}

/// A patch from its vector area (oriented like the mesh), centre and vertices; id and name
/// are given once the patches are ordered.
pub(super) fn patch(
    kind: PatchKind,
    faces: Vec<u32>,
    vertices: Vec<u32>,
    area_vector: [f64; 3],
    centre: [f64; 3],
    at: &impl Fn(u32) -> [f64; 3],
) -> Patch {
    let area = norm(area_vector);
    let normal = if area > 0.0 {
        // + 0.0: no negative zeros in reports.
        area_vector.map(|x| x / area + 0.0)
    } else {
        [0.0; 3]
    };
    let planarity_mm = vertices
        .iter()
        .map(|&v| dot(sub(at(v), centre), normal).abs())
        .fold(0.0, f64::max);
    Patch {
        id: 0,
        name: String::new(),
        kind,
        centre_mm: centre,
        normal,
        area_mm2: area,
        diameter_mm: (4.0 * area / std::f64::consts::PI).sqrt(),
        planarity_mm,
        extension_mm: 0.0,
        faces,
        vertices,
    }
}

/// Whether a face of the mesh runs along the border edge from `a` to `b` in that direction.
fn follows_faces(mesh: &Mesh, topology: &Topology, a: u32, b: u32) -> bool {
    topology.vertex_faces(a as usize).iter().any(|&f| {
        let t = mesh.triangles()[f as usize];
        (0..3).any(|k| t[k] == a && t[(k + 1) % 3] == b)
    })
}

/// Vector area (half the sum of cross products, mm²) and area-weighted centre of a closed
/// polygon, from a fan around its vertex mean.
pub(super) fn polygon_area_centre(rim: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let n = rim.len().max(1) as f64;
    let mean = rim
        .iter()
        .fold([0.0; 3], |s, q| [s[0] + q[0], s[1] + q[1], s[2] + q[2]])
        .map(|x| x / n);
    let mut area_vector = [0.0; 3];
    let mut parts = Vec::with_capacity(rim.len());
    for (i, &a) in rim.iter().enumerate() {
        let b = rim[(i + 1) % rim.len()];
        let t = cross(sub(a, mean), sub(b, mean)).map(|x| x / 2.0);
        for k in 0..3 {
            area_vector[k] += t[k];
        }
        parts.push((t, [0, 1, 2].map(|k| (mean[k] + a[k] + b[k]) / 3.0)));
    }
    let area = norm(area_vector);
    if area == 0.0 {
        return (area_vector, mean);
    }
    let normal = area_vector.map(|x| x / area);
    let mut centre = [0.0; 3];
    for (t, c) in parts {
        let w = dot(t, normal) / area;
        for k in 0..3 {
            centre[k] += w * c[k];
        }
    }
    (area_vector, centre)
}

/// Volume enclosed by the mesh with its open ends closed by discs (mm³, negative when the
/// faces point inwards).
fn enclosed_volume(mesh: &Mesh, patches: &[Patch]) -> f64 {
    let p = mesh.positions();
    let at = |v: u32| p[v as usize].map(f64::from);
    let origin = p.first().map_or([0.0; 3], |q| q.map(f64::from));
    let tet = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
        dot(sub(a, origin), cross(sub(b, origin), sub(c, origin))) / 6.0
    };
    let mut volume: f64 = mesh
        .triangles()
        .iter()
        .map(|t| tet(at(t[0]), at(t[1]), at(t[2])))
        .sum();
    for patch in patches.iter().filter(|p| p.kind == PatchKind::OpenEnd) {
        // The disc runs against the loop.
        let rim = &patch.vertices;
        for i in 0..rim.len() {
            let (a, b) = (at(rim[i]), at(rim[(i + 1) % rim.len()]));
            volume += tet(patch.centre_mm, b, a);
        }
    }
    volume
}

pub(super) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
