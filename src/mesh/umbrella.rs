//! The umbrella operator over a vertex adjacency (CSR): each vertex moves towards the mean of
//! its neighbours. Shared by the smoothers and by the low-pass copy cap detection looks at.

use rayon::prelude::*;

/// Vertices per parallel work item (results do not depend on it).
pub(crate) const CHUNK: usize = 2048;

/// Mean of `values` over the given neighbour indices (callers ensure the list is not empty).
#[inline]
pub(crate) fn neighbour_mean(values: &[[f32; 3]], neighbors: &[u32]) -> [f32; 3] {
    let mut sum = [0.0f32; 3];
    for &n in neighbors {
        let q = values[n as usize];
        sum[0] += q[0];
        sum[1] += q[1];
        sum[2] += q[2];
    }
    let inv = 1.0 / neighbors.len() as f32;
    [sum[0] * inv, sum[1] * inv, sum[2] * inv]
}

/// One umbrella pass from `src` into `dst`: v + factor * scale_v * (mean(neighbours) - v),
/// optionally clamped into the box of +-voxel/2 around the original position.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn umbrella_pass(
    src: &[[f32; 3]],
    dst: &mut [[f32; 3]],
    offsets: &[u32],
    neighbors: &[u32],
    scale: &[f32],
    factor: f32,
    clamp: Option<(&[[f32; 3]], [f32; 3])>,
) {
    dst.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
        // The chunk's own stretches of every array, walked together: no index arithmetic or
        // bounds checks per vertex besides the neighbour reads.
        let first = c * CHUNK;
        let own = first..first + out.len();
        let lists = offsets[first..=own.end].windows(2);
        let vertices = src[own.clone()].iter().zip(&scale[own]).zip(lists);
        for (i, (o, ((&p, &w), list))) in out.iter_mut().zip(vertices).enumerate() {
            let s = factor * w;
            if s == 0.0 {
                *o = p;
                continue;
            }
            let m = neighbour_mean(src, &neighbors[list[0] as usize..list[1] as usize]);
            let mut r = [
                p[0] + s * (m[0] - p[0]),
                p[1] + s * (m[1] - p[1]),
                p[2] + s * (m[2] - p[2]),
            ];
            if let Some((original, voxel)) = clamp {
                let o0 = original[first + i];
                for k in 0..3 {
                    let h = 0.5 * voxel[k];
                    r[k] = o0[k] + (r[k] - o0[k]).clamp(-h, h);
                }
            }
            *o = r;
        }
    });
}
