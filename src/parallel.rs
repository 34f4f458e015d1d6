//! Parallel helpers whose results do not depend on the thread count.
//!
//! Floating-point sums depend on the order of additions; rayon's `sum` splits work by thread
//! count. Here work is cut into fixed-size blocks, each summed sequentially in parallel, and the
//! block sums are added in block order, so the bits are identical for 1 or N threads.

use rayon::prelude::*;

/// Items per block in deterministic reductions.
pub const REDUCE_BLOCK: usize = 16_384;

/// Sum of `term(i)` for `i` in `0..n`, identical for every thread count.
pub fn deterministic_sum<F>(n: usize, term: F) -> f64
where
    F: Fn(usize) -> f64 + Sync,
{
    let block_sums: Vec<f64> = (0..n.div_ceil(REDUCE_BLOCK))
        .into_par_iter()
        .map(|b| {
            let end = ((b + 1) * REDUCE_BLOCK).min(n);
            (b * REDUCE_BLOCK..end).map(&term).sum::<f64>()
        })
        .collect();
    block_sums.iter().sum()
}

/// Splits `data` into consecutive mutable slices of the given lengths (which must not add up
/// to more than `data.len()`), for filling disjoint stretches of one array in parallel.
pub fn split_lengths<T>(lengths: impl Iterator<Item = usize>, data: &mut [T]) -> Vec<&mut [T]> {
    let mut parts = Vec::new();
    let mut rest = data;
    for len in lengths {
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(len);
        parts.push(head);
        rest = tail;
    }
    parts
}
