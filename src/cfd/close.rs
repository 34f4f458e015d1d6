//! Open ends closed by flat caps (`close_open_ends`): each open boundary loop's rim is moved
//! onto the loop's plane (through its centre, along its normal) and filled with a fan from
//! the centre, oriented like the mesh. The cap is then planar to float precision, as a
//! solver's inlet or outlet must be; the wall moves only by the rim's distance from that plane
//! (the loop's `planarity_mm`).

use super::patches::{patch, polygon_area_centre, PatchKind, Patches};
use crate::mesh::geometry::{cross64, dot64, sub64};
use crate::mesh::Mesh;
use thiserror::Error;

/// Why an open end could not be closed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CloseError {
    #[error("open end {name} folds over itself seen from its centre: a flat fan cannot close it")]
    NotStarShaped { name: String },
    #[error("the closed surface would have {0} vertices, more than indices can address")]
    TooLarge(usize),
    #[error("the patches were not found on this mesh (vertex {0} is out of range)")]
    Mismatch(u32),
    #[error("the closed surface is not a valid mesh: {0}")]
    Mesh(#[from] crate::mesh::MeshError),
}

/// The mesh with every open end of `patches` (found on this mesh) closed, and the patches with
/// those ends as [`PatchKind::ClosedEnd`] holding their new faces (face ids extended to match).
pub fn close_open_ends(mesh: &Mesh, patches: &Patches) -> Result<(Mesh, Patches), CloseError> {
    let n = mesh.n_vertices();
    let out_of_range = patches
        .patches
        .iter()
        .flat_map(|p| &p.vertices)
        .find(|&&v| v as usize >= n);
    if let Some(&v) = out_of_range {
        return Err(CloseError::Mismatch(v));
    }
    let mut positions = mesh.positions().to_vec();
    let mut triangles = mesh.triangles().to_vec();
    let mut out = patches.clone();
    for patch_at in 0..out.patches.len() {
        let end = &out.patches[patch_at];
        if end.kind != PatchKind::OpenEnd {
            continue;
        }
        let rim = end.vertices.clone();
        // Onto the plane: the rim in f64, then stored in f32.
        let (c, n) = (end.centre_mm, end.normal);
        for &v in &rim {
            let q = positions[v as usize].map(f64::from);
            let off = dot64(sub64(q, c), n);
            positions[v as usize] = [0, 1, 2].map(|k| (q[k] - off * n[k]) as f32);
        }
        let at = |v: u32| positions[v as usize].map(f64::from);
        let flat: Vec<[f64; 3]> = rim.iter().map(|&v| at(v)).collect();
        let (area_vector, centre) = polygon_area_centre(&flat);
        let centre_vertex = positions.len();
        if centre_vertex >= u32::MAX as usize {
            return Err(CloseError::TooLarge(centre_vertex + 1));
        }
        // The rim runs with the faces next to it; the cap runs against it.
        let disc = area_vector.map(|x| -x);
        let mut faces = Vec::with_capacity(rim.len());
        for i in 0..rim.len() {
            let (a, b) = (rim[i], rim[(i + 1) % rim.len()]);
            let t = cross64(sub64(at(a), centre), sub64(at(b), centre)).map(|x| -x);
            if dot64(t, disc) <= 0.0 {
                return Err(CloseError::NotStarShaped {
                    name: end.name.clone(),
                });
            }
            faces.push(triangles.len() as u32);
            triangles.push([centre_vertex as u32, b, a]);
        }
        positions.push(centre.map(|x| x as f32));
        let vertices: Vec<u32> = rim
            .iter()
            .copied()
            .chain(std::iter::once(centre_vertex as u32))
            .collect();
        let at = |v: u32| positions[v as usize].map(f64::from);
        let mut closed = patch(PatchKind::ClosedEnd, faces, vertices, disc, centre, &at);
        // Keep the orientation found for the open end (out of the fluid).
        if dot64(closed.normal, end.normal) < 0.0 {
            closed.normal = closed.normal.map(|x| -x + 0.0);
        }
        closed.id = end.id;
        closed.name = end.name.clone();
        out.face_ids
            .extend(std::iter::repeat_n(closed.id, closed.faces.len()));
        out.patches[patch_at] = closed;
    }
    let mesh = Mesh::new(positions, triangles)?;
    Ok((mesh, out))
}
