//! Enclosed volume of meshes that may be open: each boundary loop is closed by a fan of
//! triangles around its centroid before the divergence theorem is applied, and the result says so.

use crate::mesh::geometry::signed_volume;
use crate::mesh::{Mesh, Topology};
use serde::Serialize;

/// Enclosed volume and how it was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EnclosedVolume {
    /// Signed volume in mm³ (positive for outward normals).
    pub mm3: f64,
    /// Boundary loops closed by centroid fans to compute it (0 for closed meshes).
    pub loops_closed_by_fans: usize,
}

/// Volume of `mesh`, with open boundary loops closed by centroid fans.
pub fn enclosed_volume(mesh: &Mesh, topology: &Topology) -> EnclosedVolume {
    let loops = topology.boundary_loops();
    if loops.is_empty() {
        return EnclosedVolume {
            mm3: signed_volume(mesh),
            loops_closed_by_fans: 0,
        };
    }
    let mut positions = mesh.positions().to_vec();
    let mut triangles = mesh.triangles().to_vec();
    for l in loops {
        let n = l.vertices.len();
        if n < 3 {
            continue;
        }
        let c: [f64; 3] = std::array::from_fn(|k| {
            l.vertices
                .iter()
                .map(|&v| positions[v as usize][k] as f64)
                .sum::<f64>()
                / n as f64
        });
        let centre = positions.len() as u32;
        positions.push(c.map(|x| x as f32));
        // Loops run in the faces' direction, so the cap walks them backwards.
        for i in 0..n {
            let (a, b) = (l.vertices[i], l.vertices[(i + 1) % n]);
            triangles.push([centre, b, a]);
        }
    }
    let closed = Mesh::from_checked_parts(positions, triangles);
    EnclosedVolume {
        mm3: signed_volume(&closed),
        loops_closed_by_fans: loops.len(),
    }
}
