//! Distances between surfaces (the papers' evaluation protocol): symmetric Hausdorff distance
//! and mean minimum distance, point-to-surface from every vertex to the other mesh's triangles,
//! and the minimum distance between a structure and a reference structure.

use crate::mesh::Mesh;
use crate::parallel::deterministic_sum;
use crate::spatial::TriangleBvh;
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

/// Per vertex, the lowest-numbered face it is a corner of (`u32::MAX` for none).
fn a_face_per_vertex(mesh: &Mesh) -> Vec<u32> {
    let mut face = vec![u32::MAX; mesh.n_vertices()];
    for (f, t) in (0..mesh.n_triangles() as u32).zip(mesh.triangles()).rev() {
        for &v in t {
            face[v as usize] = f;
        }
    }
    face
}

fn max_and_sum(d: &[f64]) -> (f64, f64) {
    let max = d.iter().cloned().fold(0.0, f64::max);
    (max, deterministic_sum(d.len(), |i| d[i]))
}

/// Symmetric Hausdorff and mean minimum distances between `a` and `b` (vertex to surface).
/// Pass prebuilt trees to reuse them across calls.
pub fn surface_distance(
    a: &Mesh,
    tree_a: &TriangleBvh,
    b: &Mesh,
    tree_b: &TriangleBvh,
) -> SurfaceDistance {
    // A smoothed copy with the same triangles: each vertex's search starts from one of its
    // own faces in the other mesh, which is close to its nearest point there.
    let (ab, ba) = if a.n_vertices() == b.n_vertices() && a.triangles() == b.triangles() {
        let faces = a_face_per_vertex(a);
        (
            tree_b.distances_from(a.positions(), &faces),
            tree_a.distances_from(b.positions(), &faces),
        )
    } else {
        (
            tree_b.distances(a.positions()),
            tree_a.distances(b.positions()),
        )
    };
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

/// Symmetric Hausdorff distance (mm) between two meshes, building the trees.
pub fn hausdorff_distance(a: &Mesh, b: &Mesh) -> f64 {
    surface_distance(a, &TriangleBvh::build(a), b, &TriangleBvh::build(b)).hausdorff_mm
}

/// Minimum distance (mm) between a structure and a reference: the smaller of the closest
/// vertex-to-surface distances in both directions (exact unless the closest pair is two edges
/// crossing at a distance, where it can exceed the true value by a fraction of an edge).
pub fn minimum_distance(
    mesh: &Mesh,
    mesh_tree: &TriangleBvh,
    reference: &Mesh,
    reference_tree: &TriangleBvh,
) -> f64 {
    // An upper bound from a sample of vertices, then every vertex searched only within the
    // best distance so far: a search from a far vertex ends a few nodes down. The minimum
    // of exact distances does not depend on the order, so the result is the full search's.
    let sample = |points: &[[f32; 3]], tree: &TriangleBvh| {
        let step = (points.len() / 64).max(1);
        points
            .iter()
            .step_by(step)
            .filter_map(|&p| tree.nearest(p).map(|n| n.distance))
            .fold(f64::INFINITY, f64::min)
    };
    let bound =
        sample(mesh.positions(), reference_tree).min(sample(reference.positions(), mesh_tree));
    let a = smallest_distance_within(reference_tree, mesh.positions(), bound);
    smallest_distance_within(mesh_tree, reference.positions(), a)
}

/// The smallest distance from `points` to the surface of `tree` if it is at most `bound`,
/// else `bound`; in parallel, each chunk narrowing its search as it finds closer points.
fn smallest_distance_within(tree: &TriangleBvh, points: &[[f32; 3]], bound: f64) -> f64 {
    use rayon::prelude::*;
    points
        .par_chunks(4096)
        .map(|chunk| {
            let mut best = bound;
            for &p in chunk {
                if let Some(n) = tree.nearest_matching_within(p, best, |_| true) {
                    best = best.min(n.distance);
                }
            }
            best
        })
        .reduce(|| bound, f64::min)
}
