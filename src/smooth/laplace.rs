//! The umbrella operator and the smoothers made of it: Laplace, Taubin lambda|mu (steps
//! alternate through the factors), and Laplace with node-position constraint (Moench 2010).

use super::{max_step, neighbour_mean, CHUNK};
use rayon::prelude::*;

/// One umbrella pass from `src` into `dst`: v + factor * scale_v * (mean(neighbours) - v),
/// optionally clamped into the box of +-voxel/2 around the original position.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(super) fn umbrella_pass(
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

/// Runs `iterations` iterations; each iteration applies one pass per factor (one for Laplace,
/// lambda then mu for Taubin). Returns positions and the last pass's largest step.
pub(super) fn laplace(
    original: &[[f32; 3]],
    (offsets, neighbors): (&[u32], &[u32]),
    scale: &[f32],
    factors: &[f32],
    iterations: usize,
    npc_voxel: Option<[f32; 3]>,
) -> (Vec<[f32; 3]>, f32) {
    let mut a = original.to_vec();
    let mut b = original.to_vec();
    for _ in 0..iterations {
        for &f in factors {
            umbrella_pass(
                &a,
                &mut b,
                offsets,
                neighbors,
                scale,
                f,
                npc_voxel.map(|v| (original, v)),
            );
            std::mem::swap(&mut a, &mut b);
        }
    }
    let last = if iterations > 0 {
        max_step(&a, &b)
    } else {
        0.0
    };
    (a, last)
}
