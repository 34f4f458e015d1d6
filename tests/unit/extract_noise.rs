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
    let row = 5 + 10 * 5;
    assert!((r.delta(voxel, row, 1) - 0.2).abs() < 1e-6);
    assert!(r.is_relaxed(voxel, 1) && !r.is_relaxed(voxel, 0));
    assert_eq!(r.delta(voxel, row, 0), 0.0);
    // A neighbour along x gains g(1,0,0) * offset = 0.15 * 0.4 * 0.4 / 0.064 * 0.2; four
    // voxels away 0.02 * 0.4 * 0.4 / 0.064 * 0.2; five away nothing.
    assert!((r.delta(voxel + 1, row, 1) - 0.075).abs() < 1e-6);
    assert!((r.delta(voxel + 4, row, 1) - 0.01).abs() < 1e-6);
    assert_eq!(r.delta(voxel + 5, row, 1), 0.0);
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
        let row = (p.voxel / 20) as usize;
        let reached = p.raw + r.delta(p.voxel, row, 1);
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
