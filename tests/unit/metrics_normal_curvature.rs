//! Tests of `src/metrics/normal_curvature.rs`.

use destair::mesh::{Mesh, Topology};
use destair::metrics::normal_curvature::*;

#[test]
fn flat_grid_has_zero_curvature() {
    let p = vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [1., 1., 0.]];
    let m = Mesh::new(p, vec![[0, 1, 3], [0, 3, 2]]).unwrap();
    let t = Topology::build(&m);
    assert_eq!(average_normal_curvature(&m, &t), 0.0);
}

#[test]
fn right_angle_fold_by_hand() {
    // Two unit right triangles meeting at 90 degrees along the edge (0,1): equal areas, so
    // the edge vertices' normal bisects the fold and each face is 45 degrees away from it.
    let p = vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]];
    let m = Mesh::new(p, vec![[0, 1, 2], [1, 0, 3]]).unwrap();
    let t = Topology::build(&m);
    let c = vertex_normal_curvature(&m, &t);
    assert!((c[0].unwrap() - 45.0).abs() < 1e-4);
    assert!((c[1].unwrap() - 45.0).abs() < 1e-4);
    assert_eq!(c[2], Some(0.0));
    assert_eq!(c[3], Some(0.0));
    assert!((average_normal_curvature(&m, &t) - 22.5).abs() < 1e-4);
}

/// The float just below a non-negative `x` (f32::next_down needs Rust 1.86).
fn next_down(x: f32) -> f32 {
    if x > 0.0 {
        f32::from_bits(x.to_bits() - 1)
    } else {
        -f32::from_bits(1)
    }
}

/// The float just above a non-negative finite `x`.
fn next_up(x: f32) -> f32 {
    f32::from_bits(x.abs().to_bits() + 1)
}

/// A jittered phantom, its turn values, and limits set to values that occur (ties) and just
/// around them, with a few plain ones.
fn jittered_turns_and_limits() -> (Mesh, Vec<Option<NormalTurn>>, Vec<(f32, f32)>) {
    let case = destair::phantom::big_case(20_000, &Default::default());
    let mut mesh = case.meshes[0].1.clone();
    let mut rng = fastrand::Rng::with_seed(4);
    for p in mesh.positions_mut().iter_mut() {
        for x in p.iter_mut() {
            *x += (rng.f32() - 0.5) * 0.2;
        }
    }
    let topology = Topology::build(&mesh);
    let turn = vertex_normal_turn(&mesh, &topology);
    let defined: Vec<NormalTurn> = turn.iter().flatten().copied().collect();
    let mut limits: Vec<(f32, f32)> = vec![(5.0, f32::INFINITY), (5.0, 3.0), (0.0, 0.0)];
    for t in defined.iter().step_by(97) {
        for d in [t.deg, next_down(t.deg), next_up(t.deg)] {
            limits.push((d, f32::INFINITY));
            limits.push((d, t.deg_per_mm));
            limits.push((90.0, next_down(t.deg_per_mm)));
        }
    }
    (mesh, turn, limits)
}

/// The quick tangent test decides as the values of `vertex_normal_turn` do, also with the
/// limits set to values that occur (ties) and just around them.
#[test]
fn turns_within_limits_agree_with_the_turn_values() {
    let (mesh, turn, limits) = jittered_turns_and_limits();
    let topology = Topology::build(&mesh);
    let mut both = [0usize; 2];
    for (max_deg, max_per_mm) in limits {
        let fast = TurnLimits::new(&mesh, &topology).within(max_deg, max_per_mm);
        for (v, t) in turn.iter().enumerate() {
            let want = t.is_some_and(|t| t.deg <= max_deg && t.deg_per_mm <= max_per_mm);
            assert_eq!(fast[v], want, "vertex {v}, limits {max_deg} / {max_per_mm}");
            both[usize::from(want)] += 1;
        }
    }
    // Both answers occur often.
    assert!(both[0] > 10_000 && both[1] > 10_000, "{both:?}");
}

/// Limits found together in one walk (`remember`, up to eight at a time) decide as the turn
/// values do, each on its own; limits not remembered are still found on request.
#[test]
fn remembered_limits_agree_with_the_turn_values() {
    let (mesh, turn, limits) = jittered_turns_and_limits();
    let topology = Topology::build(&mesh);
    let check = |turns: &TurnLimits, (max_deg, max_per_mm): (f32, f32)| {
        let flags = turns.within(max_deg, max_per_mm);
        for (v, t) in turn.iter().enumerate() {
            let want = t.is_some_and(|t| t.deg <= max_deg && t.deg_per_mm <= max_per_mm);
            assert_eq!(
                flags[v], want,
                "vertex {v}, limits {max_deg} / {max_per_mm}"
            );
        }
    };
    let mut turns = TurnLimits::new(&mesh, &topology);
    for group in limits.chunks(8) {
        turns.remember(group);
        for &limit in group {
            check(&turns, limit);
        }
        check(&turns, (2.5, 1.0));
    }
    // More than eight: the first eight are remembered, the rest found on request.
    turns.remember(&limits[..12]);
    for &limit in &limits[..12] {
        check(&turns, limit);
    }
}

/// The one-arctangent path gives `vertex_normal_turn`'s angles on a jittered phantom, with
/// degenerate faces and folds past 90 degrees mixed in.
#[test]
fn curvature_matches_the_turn_angles() {
    let case = destair::phantom::big_case(20_000, &Default::default());
    let mut mesh = case.meshes[0].1.clone();
    let mut rng = fastrand::Rng::with_seed(9);
    let n = mesh.n_vertices();
    let tris = mesh.triangles().to_vec();
    let p = mesh.positions_mut();
    for x in p.iter_mut().flatten() {
        *x += (rng.f32() - 0.5) * 0.3;
    }
    for _ in 0..200 {
        // A corner pulled onto another (a degenerate face) or far through the surface (a fold).
        let [a, b, _] = tris[rng.usize(..tris.len())];
        if rng.bool() {
            p[a as usize] = p[b as usize];
        } else {
            for x in p[a as usize].iter_mut() {
                *x += (rng.f32() - 0.5) * 20.0;
            }
        }
    }
    let topology = Topology::build(&mesh);
    let fast = vertex_normal_curvature(&mesh, &topology);
    let turn = vertex_normal_turn(&mesh, &topology);
    assert_eq!(fast.len(), n);
    let mut wide = 0;
    for (v, (f, t)) in fast.iter().zip(&turn).enumerate() {
        assert_eq!(*f, t.map(|t| t.deg), "vertex {v}");
        wide += usize::from(f.is_some_and(|d| d > 90.0));
    }
    assert!(wide > 20, "{wide} vertices turn past 90 degrees");
}

/// The average is the mean of the per-vertex curvatures where defined, summed in the fixed
/// blocks of `deterministic_sum`: the same bits as summing the per-vertex values.
#[test]
fn average_is_the_mean_of_the_vertex_curvatures_to_the_bit() {
    // About 50,000 vertices (several blocks), jittered, and unreferenced vertices (undefined)
    // among them.
    let case = destair::phantom::big_case(100_000, &Default::default());
    let (mut positions, triangles) = case.meshes[0].1.clone().into_parts();
    let mut rng = fastrand::Rng::with_seed(5);
    for x in positions.iter_mut().flatten() {
        *x += (rng.f32() - 0.5) * 0.2;
    }
    positions.extend([[0.0, 0.0, 0.0]; 100]);
    let mesh = Mesh::new(positions, triangles).unwrap();
    let topology = Topology::build(&mesh);
    let per_vertex = vertex_normal_curvature(&mesh, &topology);
    let n_defined = per_vertex.iter().flatten().count();
    assert!(per_vertex.len() > 3 * 16_384 && n_defined + 100 == per_vertex.len());
    let total = destair::parallel::deterministic_sum(per_vertex.len(), |v| {
        per_vertex[v].map_or(0.0, f64::from)
    });
    let want = total / n_defined as f64;
    assert_eq!(
        average_normal_curvature(&mesh, &topology).to_bits(),
        want.to_bits()
    );
}

/// The curvature found in the limits' walk is `average_normal_curvature`'s to the bit (degenerate
/// faces and folds past 90 degrees mixed in), and the flags are those `remember` finds alone.
#[test]
fn curvature_found_with_the_limits_is_the_average_to_the_bit() {
    let (mut mesh, _, limits) = jittered_turns_and_limits();
    // Some faces without area, and some folded over.
    let tris = mesh.triangles().to_vec();
    let p = mesh.positions_mut();
    for (i, t) in tris.iter().enumerate().step_by(211) {
        p[t[1] as usize] = p[t[0] as usize];
        if i % 2 == 0 {
            p[t[2] as usize][2] += 5.0;
        }
    }
    let topology = Topology::build(&mesh);
    let want = average_normal_curvature(&mesh, &topology);
    assert!(want > 1.0, "{want}");
    for group in limits.chunks(8).take(6) {
        let mut alone = TurnLimits::new(&mesh, &topology);
        alone.remember(group);
        let mut both = TurnLimits::new(&mesh, &topology);
        assert_eq!(
            both.remember_with_curvature(group).to_bits(),
            want.to_bits()
        );
        for &(max_deg, max_per_mm) in group {
            assert_eq!(
                alone.within(max_deg, max_per_mm),
                both.within(max_deg, max_per_mm)
            );
        }
    }
}
