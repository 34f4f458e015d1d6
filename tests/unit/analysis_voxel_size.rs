//! Tests of `src/analysis/voxel_size.rs`.

use destair::analysis::voxel_size::*;
use destair::mesh::{Mesh, Topology};

#[test]
fn clusters_half_and_full_steps_with_noise() {
    let mut v: Vec<f64> = (0..300)
        .map(|i| 1.5 + (i % 7) as f64 * 1e-6)
        .chain((0..200).map(|i| 3.0 - (i % 5) as f64 * 1e-6))
        .collect();
    v.sort_by(f64::total_cmp);
    match axis_spacing(&v, 1e-6) {
        AxisSpacing::Spacing { mm } => assert!((mm - 3.0).abs() < 1e-5),
        other => panic!("{other:?}"),
    }
}

#[test]
fn one_step_and_irregular() {
    assert!(matches!(
        axis_spacing(&[0.5; 10], 1e-7),
        AxisSpacing::OneStep { .. }
    ));
    let spread: Vec<f64> = (1..100).map(|i| i as f64 * 0.01).collect();
    assert!(matches!(
        axis_spacing(&spread, 1e-7),
        AxisSpacing::Irregular { .. }
    ));
    let wrong_ratio = [vec![1.0; 50], vec![3.0; 50]].concat();
    assert!(matches!(
        axis_spacing(&wrong_ratio, 1e-7),
        AxisSpacing::Irregular { .. }
    ));
    assert_eq!(axis_spacing(&[], 1e-7), AxisSpacing::NoSteps);
}

/// A staircase strip whose vertices sit on grid-edge midpoints of a 0.45 x 0.7 x 3 mm grid
/// far from the origin (so float noise is real); each axis sees offsets h/2 and h.
fn midpoint_strip(rotate_deg: f32) -> Mesh {
    let h = [0.45f32, 0.7, 3.0];
    let origin = [-120.3f32, 87.1, 1013.0];
    let (s, c) = rotate_deg.to_radians().sin_cos();
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let (mut a, mut z) = (0u32, 0u32);
    for i in 0..40u32 {
        // Half-step offsets along every axis alternate between 1 and 2 (h/2 and h).
        let rows = [
            [a as f32, 0.0, z as f32],
            [a as f32 + 1.0, if i % 2 == 0 { 2.0 } else { 1.0 }, z as f32],
        ];
        for g in rows {
            let p = [0.5 * g[0] * h[0], 0.5 * g[1] * h[1], 0.5 * g[2] * h[2]];
            let (x, y) = (c * p[0] - s * p[1], s * p[0] + c * p[1]);
            positions.push([origin[0] + x, origin[1] + y, origin[2] + p[2]]);
        }
        a += 1 + i % 2;
        z += 1 + i % 2;
        if i > 0 {
            let (a, b, cc, d) = (2 * i - 2, 2 * i - 1, 2 * i, 2 * i + 1);
            triangles.push([a, cc, b]);
            triangles.push([b, cc, d]);
        }
    }
    Mesh::new(positions, triangles).unwrap()
}

#[test]
fn reconstructs_grid_spacing_and_refuses_rotated_grids() {
    let m = midpoint_strip(0.0);
    let est = voxel_size(&m, &Topology::build(&m));
    let got = est.spacing().unwrap_or_else(|| panic!("{est:?}"));
    for (g, want) in got.iter().zip([0.45, 0.7, 3.0]) {
        assert!((g - want).abs() < 1e-4, "{got:?}");
    }
    let r = midpoint_strip(30.0);
    let est = voxel_size(&r, &Topology::build(&r));
    assert!(est.spacing().is_none() && est.is_irregular(), "{est:?}");
}

/// The estimate as the paper's procedure states it: every axis's offsets sorted whole.
fn sorted_estimate(m: &Mesh, t: &Topology) -> [AxisSpacing; 3] {
    let p = m.positions();
    std::array::from_fn(|k| {
        let max_abs = p.iter().map(|q| q[k].abs()).fold(0.0f32, f32::max) as f64;
        let zero_tol = 8.0 * f32::EPSILON as f64 * max_abs.max(1e-6);
        let mut offsets: Vec<f64> = t
            .edges()
            .iter()
            .map(|&[a, b]| (p[a as usize][k] as f64 - p[b as usize][k] as f64).abs())
            .filter(|&d| d > zero_tol)
            .collect();
        offsets.sort_by(f64::total_cmp);
        axis_spacing(&offsets, zero_tol)
    })
}

/// Counting distinct offsets (few on a grid) and sorting them all (an axis with too many to
/// count) give what sorting every offset gives, to the bit: on grid meshes, on a rotated grid,
/// on a jittered mesh with an offset per edge, and on one with a single jittered axis.
#[test]
fn counted_offsets_match_sorting_them_all() {
    let grid = destair::phantom::big_case(200_000, &Default::default()).meshes[0]
        .1
        .clone();
    let mut rng = fastrand::Rng::with_seed(7);
    let mut jittered = grid.clone();
    for q in jittered.positions_mut() {
        for x in q.iter_mut() {
            *x += rng.f32() * 0.3;
        }
    }
    // A slightly scaled grid with noise within a cluster's tolerance: the spacing is the
    // middle of many distinct offsets.
    let mut noisy = grid.clone();
    for q in noisy.positions_mut() {
        for x in q.iter_mut() {
            *x = *x * 1.00003 + rng.f32() * 4e-5;
        }
    }
    let mut one_axis = grid.clone();
    for q in one_axis.positions_mut() {
        q[1] += rng.f32() * 0.3;
    }
    // Distinct y offsets: the grid's few are counted; the jittered meshes' are nearly all
    // distinct, so their sample sends them to sorting.
    let distinct_y = |m: &Mesh| {
        let p = m.positions();
        let t = Topology::build(m);
        let mut bits: Vec<u64> = t
            .edges()
            .iter()
            .map(|&[a, b]| {
                (p[a as usize][1] as f64 - p[b as usize][1] as f64)
                    .abs()
                    .to_bits()
            })
            .collect();
        bits.sort_unstable();
        bits.dedup();
        bits.len()
    };
    assert!(distinct_y(&grid) < 1 << 15, "{}", distinct_y(&grid));
    assert!(distinct_y(&one_axis) > 1 << 17, "{}", distinct_y(&one_axis));
    let noisy_spacing = voxel_size(&noisy, &Topology::build(&noisy)).spacing();
    assert!(
        noisy_spacing.is_some_and(|s| s[0] != 1.0),
        "{noisy_spacing:?}"
    );
    for m in [
        midpoint_strip(0.0),
        midpoint_strip(30.0),
        grid,
        noisy,
        jittered,
        one_axis,
    ] {
        let t = Topology::build(&m);
        assert_eq!(voxel_size(&m, &t).axes, sorted_estimate(&m, &t));
    }
}

#[test]
fn the_coarse_axis_is_clearly_coarser_than_every_other() {
    use destair::analysis::coarse_axis;
    assert_eq!(
        coarse_axis([(0.45, 0.45), (0.45, 0.45), (3.0, 3.0)]),
        Some(2)
    );
    assert_eq!(coarse_axis([(2.0, 2.0), (0.5, 0.5), (0.5, 0.5)]), Some(0));
    // Isotropic, or two coarse axes: none.
    assert_eq!(coarse_axis([(0.4, 0.4), (0.4, 0.4), (0.4, 0.4)]), None);
    assert_eq!(coarse_axis([(3.0, 3.0), (0.5, 0.5), (3.0, 3.0)]), None);
    // Within 1.25: none. An axis known only as h or 2h counts by its smaller and larger bound.
    assert_eq!(coarse_axis([(0.5, 0.5), (0.5, 0.5), (0.6, 0.6)]), None);
    assert_eq!(
        coarse_axis([(0.45, 0.9), (0.45, 0.45), (3.0, 3.0)]),
        Some(2)
    );
    assert_eq!(coarse_axis([(0.45, 0.45), (0.45, 0.45), (0.5, 1.0)]), None);
}
