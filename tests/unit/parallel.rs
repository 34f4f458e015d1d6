//! Tests of `src/parallel.rs`.

use destair::parallel::*;

#[test]
fn same_bits_for_one_and_two_threads() {
    let term = |i: usize| 1.0 / (i as f64 + 0.37);
    let n = 100_003;
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| deterministic_sum(n, term));
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap()
        .install(|| deterministic_sum(n, term));
    assert_eq!(one.to_bits(), two.to_bits());
    let serial: f64 = (0..n).map(term).sum();
    assert!((one - serial).abs() < 1e-9 * serial);
}
