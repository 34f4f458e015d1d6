//! The smoothers made of the umbrella operator ([`crate::mesh::umbrella`]): Laplace, Taubin
//! lambda|mu (steps alternate through the factors), and Laplace with node-position constraint
//! (Moench 2010).

use super::max_step;
use crate::mesh::umbrella::{padded, umbrella_pass, unpadded, written_before_read, NeighbourLists};

/// Runs `iterations` iterations; each iteration applies one pass per factor (one for Laplace,
/// lambda then mu for Taubin). Returns positions and the last pass's largest step.
pub(super) fn laplace(
    original: &[[f32; 3]],
    rows: &NeighbourLists<'_>,
    scale: &[f32],
    factors: &[f32],
    iterations: usize,
    npc_voxel: Option<[f32; 3]>,
) -> (Vec<[f32; 3]>, f32) {
    let mut a = padded(original);
    let mut b = written_before_read(&a);
    for _ in 0..iterations {
        for &f in factors {
            umbrella_pass(&a, &mut b, rows, scale, f, npc_voxel.map(|v| (original, v)));
            std::mem::swap(&mut a, &mut b);
        }
    }
    let last = if iterations > 0 {
        max_step(&a, &b)
    } else {
        0.0
    };
    (unpadded(&a), last)
}
