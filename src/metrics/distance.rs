//! Distances between surfaces (the papers' evaluation protocol): symmetric Hausdorff distance
//! and mean minimum distance, point-to-surface from every vertex to the other mesh's triangles,
//! and the minimum distance between a structure and a reference structure.

use crate::mesh::Mesh;
use crate::parallel::deterministic_sum;
use crate::spatial::TriangleGrid;
use serde::Serialize;

/// How far two surfaces are apart, measured from each one's vertices to the other's triangles.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SurfaceDistance {
    /// max(a_to_b_max, b_to_a_max) in mm.
    pub hausdorff_mm: f64,
    pub a_to_b_max_mm: f64,
    pub b_to_a_max_mm: f64,
    /// Mean over a's vertices of the distance to b (mm).
    pub a_to_b_mean_mm: f64,
    pub b_to_a_mean_mm: f64,
    /// Mean over the vertices of both (mm).
    pub mean_mm: f64,
}

fn max_and_sum(d: &[f64]) -> (f64, f64) {
    let max = d.iter().cloned().fold(0.0, f64::max);
    (max, deterministic_sum(d.len(), |i| d[i]))
}

/// Symmetric Hausdorff and mean minimum distances between `a` and `b` (vertex to surface).
/// Pass prebuilt grids to reuse them across calls.
pub fn surface_distance(
    a: &Mesh,
    grid_a: &TriangleGrid,
    b: &Mesh,
    grid_b: &TriangleGrid,
) -> SurfaceDistance {
    let ab = grid_b.distances(a.positions());
    let ba = grid_a.distances(b.positions());
    let (ab_max, ab_sum) = max_and_sum(&ab);
    let (ba_max, ba_sum) = max_and_sum(&ba);
    let mean = |sum: f64, n: usize| if n == 0 { 0.0 } else { sum / n as f64 };
    SurfaceDistance {
        hausdorff_mm: ab_max.max(ba_max),
        a_to_b_max_mm: ab_max,
        b_to_a_max_mm: ba_max,
        a_to_b_mean_mm: mean(ab_sum, ab.len()),
        b_to_a_mean_mm: mean(ba_sum, ba.len()),
        mean_mm: mean(ab_sum + ba_sum, ab.len() + ba.len()),
    }
}

/// Symmetric Hausdorff distance (mm) between two meshes, building the grids.
pub fn hausdorff_distance(a: &Mesh, b: &Mesh) -> f64 {
    surface_distance(a, &TriangleGrid::build(a), b, &TriangleGrid::build(b)).hausdorff_mm
}

/// Minimum distance (mm) between a structure and a reference: the smaller of the closest
/// vertex-to-surface distances in both directions (exact unless the closest pair is two edges
/// crossing at a distance, where it can exceed the true value by a fraction of an edge).
pub fn minimum_distance(
    mesh: &Mesh,
    mesh_grid: &TriangleGrid,
    reference: &Mesh,
    reference_grid: &TriangleGrid,
) -> f64 {
    let a = reference_grid.distances(mesh.positions());
    let b = mesh_grid.distances(reference.positions());
    a.iter().chain(&b).cloned().fold(f64::INFINITY, f64::min)
}
