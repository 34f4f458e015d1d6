//! Tests of `src/report/pictures.rs`.

use destair::report::pictures::*;

#[test]
fn histogram_bins_and_counts() {
    let h = histogram(&[0.0, 0.05, 0.26, 0.5, f32::NAN]);
    assert!((h.bin_mm - 0.025).abs() < 1e-9);
    assert_eq!(h.counts.iter().sum::<u64>(), 4);
    assert_eq!(h.counts[0], 1);
    assert_eq!(h.counts[2], 1);
    assert_eq!(h.counts[10], 1);
    assert_eq!(h.counts[19], 1);
    assert_eq!(h.max_mm, 0.5);
}
