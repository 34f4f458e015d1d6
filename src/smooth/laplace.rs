//! The umbrella operator and the smoothers made of it: Laplace, Taubin lambda|mu (steps
//! alternate through the factors), and Laplace with node-position constraint (Moench 2010).

use super::{max_step, neighbour_mean, CHUNK};
use crate::mesh::Topology;
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
        let first = c * CHUNK;
        for (i, o) in out.iter_mut().enumerate() {
            let v = first + i;
            let p = src[v];
            let s = factor * scale[v];
            if s == 0.0 {
                *o = p;
                continue;
            }
            let m = neighbour_mean(
                src,
                &neighbors[offsets[v] as usize..offsets[v + 1] as usize],
            );
            let mut r = [
                p[0] + s * (m[0] - p[0]),
                p[1] + s * (m[1] - p[1]),
                p[2] + s * (m[2] - p[2]),
            ];
            if let Some((original, voxel)) = clamp {
                let o0 = original[v];
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
    topology: &Topology,
    scale: &[f32],
    factors: &[f32],
    iterations: usize,
    npc_voxel: Option<[f32; 3]>,
) -> (Vec<[f32; 3]>, f32) {
    let (offsets, neighbors) = topology.neighbor_csr();
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
