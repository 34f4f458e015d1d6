//! The constrained relaxations of Bade, Konrad, Preim 2007 (§4): each vertex moves towards the
//! centre of its neighbours, but its displacement from the original position is clipped to a
//! region the binary volume allows: the voxel box (cell-size, §4.1), the vertex's own grid edge
//! (cell-edge, §4.3) or the diamond |dx|/hx + |dy|/hy + |dz|/hz <= 1/2 (§4.4). Iteration stops
//! when the largest step falls below a threshold (the paper uses 0.002).

use super::{max_step, CHUNK};
use crate::mesh::umbrella::{padded, unpadded, written_before_read, NeighbourLists, Padded};
use crate::mesh::Mesh;
use rayon::prelude::*;

/// The region a vertex's displacement from its original position is clipped to.
#[derive(Debug, Clone, Copy)]
pub enum Region {
    /// +-h/2 per axis.
    Box([f32; 3]),
    /// The octahedron with vertices at +-h/2 on each axis.
    Diamond([f32; 3]),
}

/// The part of step `d` (mm) that stays inside `region`.
#[inline]
pub fn clip(region: Region, d: [f32; 3]) -> [f32; 3] {
    match region {
        Region::Box(h) => std::array::from_fn(|k| d[k].clamp(-0.5 * h[k], 0.5 * h[k])),
        Region::Diamond(h) => {
            // Scale the displacement back onto the face it points at (Bade 2007, Fig. 6).
            let s = d[0].abs() / h[0] + d[1].abs() / h[1] + d[2].abs() / h[2];
            if s > 0.5 {
                let t = 0.5 / s;
                [d[0] * t, d[1] * t, d[2] * t]
            } else {
                d
            }
        }
    }
}

/// Grid-edge axis (0, 1, 2) of each vertex of a marching-cubes mesh with the given voxel size:
/// the one axis on which the vertex is not at a half-voxel offset from the grid. The grid's
/// phase per axis comes from the lowest vertex on that axis, which always lies on an edge along
/// it (Bade 2007, §3.3). `None` for vertices that fit no single axis (edited or rotated meshes).
pub fn cell_edge_axes(mesh: &Mesh, voxel: [f32; 3]) -> Vec<Option<u8>> {
    let p = mesh.positions();
    let lowest: [f32; 3] =
        std::array::from_fn(|k| p.iter().map(|q| q[k]).fold(f32::INFINITY, f32::min));
    p.par_iter()
        .map(|q| {
            let mut axis = None;
            for k in 0..3 {
                let g = (q[k] as f64 - lowest[k] as f64) / voxel[k] as f64;
                let frac = g - g.round();
                // Tolerance: a thousandth of a voxel absorbs float noise.
                let on_edge_phase = frac.abs() < 1e-3;
                let on_half = (frac.abs() - 0.5).abs() < 1e-3;
                match (on_edge_phase, on_half, axis) {
                    (true, _, None) => axis = Some(k as u8),
                    (true, _, Some(_)) => return None,
                    (false, true, _) => {}
                    (false, false, _) => return None,
                }
            }
            axis
        })
        .collect()
}

/// Relaxes until the largest step is below `threshold` or `max_iterations` have run.
/// Returns positions, iterations run, the last largest step and whether it converged.
#[allow(clippy::too_many_arguments)]
pub(super) fn relax(
    original: &[[f32; 3]],
    rows: &NeighbourLists<'_>,
    scale: &[f32],
    lambda: f32,
    region: Region,
    edge_axes: Option<&[Option<u8>]>,
    threshold: f32,
    max_iterations: usize,
) -> (Vec<[f32; 3]>, usize, f32, bool) {
    let n = rows.len();
    let mut a = padded(original);
    let mut b = written_before_read(&a);
    let mut last = 0.0f32;
    for iteration in 0..max_iterations {
        b[..n]
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, out)| {
                let first = c * CHUNK;
                for (i, o) in out.iter_mut().enumerate() {
                    let v = first + i;
                    let p = a[v];
                    let s = scale[v];
                    if s == 0.0 {
                        *o = p;
                        continue;
                    }
                    let m = rows.mean(&a, v);
                    let target = p + (m - p) * lambda;
                    let orig = original[v];
                    let mut d: [f32; 3] = std::array::from_fn(|k| target[k] - orig[k]);
                    if let Some(axes) = edge_axes {
                        // Only the component along the vertex's grid edge may change.
                        let axis = axes[v].map_or(3, usize::from);
                        for (k, dk) in d.iter_mut().enumerate() {
                            if k != axis {
                                *dk = 0.0;
                            }
                        }
                    }
                    let d = clip(region, d);
                    let r: [f32; 3] = std::array::from_fn(|k| p[k] + s * (orig[k] + d[k] - p[k]));
                    *o = Padded::new(r[0], r[1], r[2], 0.0);
                }
            });
        std::mem::swap(&mut a, &mut b);
        last = max_step(&a, &b);
        if last < threshold {
            return (unpadded(&a), iteration + 1, last, true);
        }
    }
    (unpadded(&a), max_iterations, last, max_iterations == 0)
}
