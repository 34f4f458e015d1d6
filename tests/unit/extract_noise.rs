//! Tests of `src/extract/noise.rs`.

use destair::extract::noise::*;

fn flat_kernel() -> [[f32; 9]; 3] {
    let t = [0.02f32, 0.03, 0.1, 0.15, 0.4, 0.15, 0.1, 0.03, 0.02];
    [t, t, t]
}

#[test]
fn a_lone_pinned_voxel_is_relaxed_to_one_half() {
    let dims = [10, 10, 10];
    let kernels = [flat_kernel(); 2];
    let voxel = 5 + 10 * (5 + 10 * 5);
    let r = relax(
        dims,
        &kernels,
        vec![Pinned {
            voxel,
            label: 1,
            raw: 0.3,
        }],
        2,
    );
    assert_eq!(r.relaxed_per_label, vec![0, 1]);
    // g0 = 0.4^3 = 0.064: offset 0.2 / 0.064, and the voxel itself gains exactly 0.2.
    assert!((r.delta(voxel, 1) - 0.2).abs() < 1e-6);
    assert!(r.is_relaxed(voxel, 1) && !r.is_relaxed(voxel, 0));
    assert_eq!(r.delta(voxel, 0), 0.0);
    // A neighbour along x gains g(1,0,0) * offset = 0.15 * 0.4 * 0.4 / 0.064 * 0.2; four
    // voxels away 0.02 * 0.4 * 0.4 / 0.064 * 0.2; five away nothing.
    assert!((r.delta(voxel + 1, 1) - 0.075).abs() < 1e-6);
    assert!((r.delta(voxel + 4, 1) - 0.01).abs() < 1e-6);
    assert_eq!(r.delta(voxel + 5, 1), 0.0);
}

#[test]
fn a_pair_solves_together_and_a_crowd_is_not_noise() {
    let dims = [20, 20, 20];
    let kernels = [flat_kernel(); 2];
    let at = |x: u64, y: u64, z: u64| x + 20 * (y + 20 * z);
    let pair = vec![
        Pinned {
            voxel: at(5, 5, 5),
            label: 1,
            raw: 0.3,
        },
        Pinned {
            voxel: at(6, 5, 5),
            label: 1,
            raw: 0.4,
        },
    ];
    let r = relax(dims, &kernels, pair.clone(), 2);
    assert_eq!(r.relaxed_per_label[1], 2);
    for p in &pair {
        let reached = p.raw + r.delta(p.voxel, 1);
        assert!((reached - 0.5).abs() < 1e-5, "{reached}");
    }
    // A 3 x 3 plate of pinned voxels: each has 8 others within reach, so none is noise.
    let crowd: Vec<Pinned> = (0..3)
        .flat_map(|y| (0..3).map(move |x| (x, y)))
        .map(|(x, y)| Pinned {
            voxel: at(10 + x, 10 + y, 10),
            label: 1,
            raw: 0.4,
        })
        .collect();
    let r = relax(dims, &kernels, crowd, 2);
    assert_eq!(r.relaxed_per_label[1], 0);
    assert!(r.is_empty());
}

/// The fast path (bricks within reach, occupied rows, binary search) against the sum over
/// every offset, at every voxel of random volumes and for every label.
#[test]
fn delta_is_the_kernel_sum_over_every_offset() {
    let mut rng = fastrand::Rng::with_seed(62);
    let kernels = [flat_kernel(); 3];
    let tap = |d: [i64; 3]| -> f64 {
        if d.iter().any(|x| x.abs() > 4) {
            return 0.0;
        }
        (0..3)
            .map(|a| kernels[1][a][(d[a] + 4) as usize] as f64)
            .product()
    };
    let mut relaxed = 0;
    for _ in 0..20 {
        let dims = [rng.usize(1..23), rng.usize(1..19), rng.usize(1..15)];
        let n = (dims[0] * dims[1] * dims[2]) as u64;
        let pinned: Vec<Pinned> = (0..rng.usize(0..12))
            .map(|_| Pinned {
                voxel: rng.u64(0..n),
                label: rng.u16(1..3),
                raw: 0.3 + 0.15 * rng.f32(),
            })
            .collect();
        let r = relax(dims, &kernels, pinned, 3);
        relaxed += r.offsets().len();
        let at = |v: u64| {
            let (nx, ny) = (dims[0] as u64, dims[1] as u64);
            [
                (v % nx) as i64,
                (v / nx % ny) as i64,
                (v / (nx * ny)) as i64,
            ]
        };
        for v in 0..n {
            for label in 0..3u16 {
                let want: f64 = r
                    .offsets()
                    .iter()
                    .filter(|e| e.0 == label)
                    .map(|&(_, o, offset)| {
                        let (p, q) = (at(v), at(o));
                        tap(std::array::from_fn(|k| p[k] - q[k])) * offset
                    })
                    .sum();
                let got = r.delta(v, label) as f64;
                assert!(
                    (got - want).abs() <= 1e-5 * (1.0 + want.abs()),
                    "{dims:?} voxel {v} label {label}: {got} vs {want}"
                );
            }
        }
    }
    assert!(relaxed > 20, "{relaxed} offsets");
}
