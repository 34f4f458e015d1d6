//! Tests of `src/phantom/gaussian.rs`.

use destair::phantom::gaussian::*;
use destair::phantom::volume::LabelVolume;

#[test]
fn the_filter_keeps_the_mass_and_blurs_a_step_symmetrically() {
    let mut v = LabelVolume::new([20, 9, 9], [1.0; 3], [0.0; 3]);
    v.paint_where([0.0; 3], [9.0, 9.0, 9.0], 1, |_, _| true);
    let g = gaussian_indicator(&v, 1, [1.0, 0.0, 0.0]);
    let row: Vec<f32> = (0..20).map(|i| g[v.index(i, 4, 4)]).collect();
    // A step between x = 9 and 10: values mirror about 1/2 there.
    for d in 0..4 {
        assert!((row[9 - d] + row[10 + d] - 1.0).abs() < 1e-6, "{row:?}");
    }
    assert!(row[9] > 0.5 && row[10] < 0.5);
    // Far from the step and the border: unchanged.
    assert!((row[4] - 1.0).abs() < 1e-6 && row[15].abs() < 1e-6);
}
