//! Normal curvature as the papers define it (Moench 2010, §4; Moench et al. 2010, §4): per
//! vertex, the largest angle in degrees between the vertex normal and its incident face normals.
//! Flat regions give 0; terrace edges of a staircase give large values.

use crate::mesh::geometry::{face_normals, vertex_normals};
use crate::mesh::{Mesh, Topology};
use crate::parallel::deterministic_sum;
use rayon::prelude::*;

/// Normal curvature per vertex in degrees; `None` where the vertex has no incident face with
/// area or its normal cancels out (unreferenced or degenerate neighbourhoods).
pub fn vertex_normal_curvature(mesh: &Mesh, topology: &Topology) -> Vec<Option<f32>> {
    vertex_normal_turn(mesh, topology)
        .into_iter()
        .map(|t| t.map(|t| t.deg))
        .collect()
}

/// How much the surface turns at a vertex: the normal curvature, and the same angle per mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalTurn {
    /// Largest angle between the vertex normal and an incident face normal (degrees).
    pub deg: f32,
    /// Largest such angle divided by the distance from the vertex to that face's centroid
    /// (degrees per mm): about 57.3 / radius of curvature, whatever the edge length, so that a
    /// finely sampled round surface is not taken for a flat one.
    pub deg_per_mm: f32,
}

/// [`NormalTurn`] per vertex; `None` where the normal curvature is undefined.
pub fn vertex_normal_turn(mesh: &Mesh, topology: &Topology) -> Vec<Option<NormalTurn>> {
    let fnormals = face_normals(mesh);
    let vnormals = vertex_normals(mesh, topology);
    let (p, triangles) = (mesh.positions(), mesh.triangles());
    (0..mesh.n_vertices())
        .into_par_iter()
        .map(|v| {
            let n = vnormals[v];
            if n == [0.0; 3] {
                return None;
            }
            let mut largest: Option<(f64, f64)> = None;
            for &f in topology.vertex_faces(v) {
                let m = fnormals[f as usize];
                if m == [0.0; 3] {
                    continue;
                }
                let angle = angle_between(n, m);
                let t = triangles[f as usize];
                let distance = (0..3)
                    .map(|k| {
                        let c = (t.iter().map(|&w| p[w as usize][k] as f64).sum::<f64>()) / 3.0;
                        (c - p[v][k] as f64).powi(2)
                    })
                    .sum::<f64>()
                    .sqrt();
                let rate = if distance > 0.0 {
                    angle / distance
                } else {
                    f64::INFINITY
                };
                largest = Some(largest.map_or((angle, rate), |(a, r)| (a.max(angle), r.max(rate))));
            }
            largest.map(|(a, r)| NormalTurn {
                deg: a.to_degrees() as f32,
                deg_per_mm: r.to_degrees() as f32,
            })
        })
        .collect()
}

/// Mean normal curvature in degrees over the vertices where it is defined; 0 if none.
pub fn average_normal_curvature(mesh: &Mesh, topology: &Topology) -> f64 {
    let per_vertex = vertex_normal_curvature(mesh, topology);
    let n_defined = per_vertex.iter().filter(|c| c.is_some()).count();
    if n_defined == 0 {
        return 0.0;
    }
    let total = deterministic_sum(per_vertex.len(), |v| per_vertex[v].map_or(0.0, f64::from));
    total / n_defined as f64
}

/// Angle between two unit vectors in radians, accurate near 0 (atan2 of |a x b| and a . b).
fn angle_between(a: [f32; 3], b: [f32; 3]) -> f64 {
    let a = [a[0] as f64, a[1] as f64, a[2] as f64];
    let b = [b[0] as f64, b[1] as f64, b[2] as f64];
    let c = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let sin = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    sin.atan2(cos)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_grid_has_zero_curvature() {
        let p = vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [1., 1., 0.]];
        let m = Mesh::new(p, vec![[0, 1, 3], [0, 3, 2]]).unwrap();
        let t = Topology::build(&m);
        assert_eq!(average_normal_curvature(&m, &t), 0.0);
    }

    #[test]
    fn right_angle_fold_by_hand() {
        // Two unit right triangles meeting at 90 degrees along the edge (0,1): equal areas, so
        // the edge vertices' normal bisects the fold and each face is 45 degrees away from it.
        let p = vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]];
        let m = Mesh::new(p, vec![[0, 1, 2], [1, 0, 3]]).unwrap();
        let t = Topology::build(&m);
        let c = vertex_normal_curvature(&m, &t);
        assert!((c[0].unwrap() - 45.0).abs() < 1e-4);
        assert!((c[1].unwrap() - 45.0).abs() < 1e-4);
        assert_eq!(c[2], Some(0.0));
        assert_eq!(c[3], Some(0.0));
        assert!((average_normal_curvature(&m, &t) - 22.5).abs() < 1e-4);
    }
}
