//! Tests of `src/extract/kernel.rs`.

use destair::extract::kernel::Kernel;

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

/// The row-shared evaluation of both ends of an edge (row sums looked up by mask, or added
/// tap by tap) against the kernel summed tap by tap, on random label volumes, at edges along every axis, inside and at the volume's faces (outside
/// is background).
#[test]
fn edge_weights_match_the_kernel_summed_tap_by_tap() {
    use destair::extract::kernel::edge_weights;
    use destair::volume::{Grid, LabelVolume, Space};
    let mut rng = fastrand::Rng::with_seed(62);
    let dims = [13usize, 11, 10];
    for _ in 0..4 {
        let values: Vec<i64> = (0..dims.iter().product::<usize>())
            .map(|_| rng.i64(0..3))
            .collect();
        let grid = Grid::axis_aligned([0.8, 0.9, 2.5], [0.0; 3], Space::Lps);
        let volume = LabelVolume::from_values(dims, grid, values.into_iter()).unwrap();
        let mut taps = || {
            let t: [f32; 5] = std::array::from_fn(|_| rng.f32() + 0.05);
            let sum: f32 = t.iter().sum();
            t.map(|x| x / sum)
        };
        // One kernel looks its row sums up by mask, the other adds them tap by tap.
        let kernels = [
            Kernel::from_taps([taps(), taps(), taps()]).with_row_sums(),
            Kernel::from_taps([taps(), taps(), taps()]),
        ];
        let label_at = |p: [i64; 3]| {
            if (0..3).all(|k| p[k] >= 0 && p[k] < dims[k] as i64) {
                volume.voxels[p[0] as usize + dims[0] * (p[1] as usize + dims[1] * p[2] as usize)]
            } else {
                0
            }
        };
        for _ in 0..300 {
            let axis = rng.usize(0..3);
            let lo: [i64; 3] =
                std::array::from_fn(|k| rng.i64(-1..dims[k] as i64 - i64::from(k == axis) + 1));
            let (a, b) = (rng.u16(0..3), rng.u16(0..3));
            let fast = edge_weights(&volume, [&kernels[0], &kernels[1]], [a, b], lo, axis);
            // Row sums by mask are the same numbers as tap by tap.
            let plain = kernels[0].clone().without_row_sums();
            assert_eq!(
                fast,
                edge_weights(&volume, [&plain, &kernels[1]], [a, b], lo, axis)
            );
            for (end, offset) in [0i64, 1].into_iter().enumerate() {
                let v: [i64; 3] =
                    std::array::from_fn(|k| lo[k] + if k == axis { offset } else { 0 });
                let mut slow = [0f64; 2];
                for o in 0..729i64 {
                    let d = [o % 9 - 4, o / 9 % 9 - 4, o / 81 - 4];
                    let l = label_at(std::array::from_fn(|k| v[k] + d[k]));
                    for (s, (&label, k)) in slow.iter_mut().zip([a, b].iter().zip(&kernels)) {
                        if l == label {
                            *s += k.tap(d);
                        }
                    }
                }
                for l in 0..2 {
                    let got = fast[2 * end + l] as f64;
                    assert!(
                        (got - slow[l]).abs() < 1e-5,
                        "{lo:?} axis {axis} end {end}: {got} vs {}",
                        slow[l]
                    );
                }
            }
        }
    }
}
