//! Tests of `src/extract/constrained.rs`.

use destair::extract::constrained::Kernel;

fn flat_kernel() -> Kernel {
    let t = [0.1f32, 0.2, 0.4, 0.2, 0.1];
    Kernel::from_taps([t, t, t])
}

#[test]
fn the_shrink_free_kernel_is_twice_the_gaussian_minus_its_square() {
    let k = flat_kernel();
    // g * g per axis, by hand: 0.01 + 0.04 + 0.16 + 0.04 + 0.01 = 0.26 at 0, 0.02 + 0.08 +
    // 0.08 + 0.02 = 0.2 at 1, 0.04 * 3 = 0.12 at 2, 0.02 * 2 = 0.04 at 3, 0.01 at 4.
    let h = [0.01f64, 0.04, 0.12, 0.2, 0.26, 0.2, 0.12, 0.04, 0.01];
    for (&got, &want) in k.h[0].iter().zip(&h) {
        assert!((got as f64 - want).abs() < 1e-7, "{:?}", k.h[0]);
    }
    assert!((k.tap([0, 0, 0]) - (2.0 * 0.064 - 0.26f64.powi(3))).abs() < 1e-7);
    assert!((k.tap([1, 0, 0]) - (2.0 * 0.2 * 0.16 - 0.2 * 0.26 * 0.26)).abs() < 1e-7);
    // Beyond the Gaussian's reach only -g * g is left; beyond 4 voxels nothing.
    assert!((k.tap([3, 0, 0]) + 0.04 * 0.26 * 0.26).abs() < 1e-7);
    assert_eq!(k.tap([5, 0, 0]), 0.0);
    // The kernel sums to one, as the Gaussian does: flat regions keep their weight.
    let mut sum = 0.0;
    for o in 0..729 {
        sum += k.tap([o % 9 - 4, o / 9 % 9 - 4, o / 81 - 4]);
    }
    assert!((sum - 1.0).abs() < 1e-6, "{sum}");
}
