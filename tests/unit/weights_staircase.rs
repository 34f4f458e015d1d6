//! Tests of `src/weights/staircase.rs`.

use destair::mesh::{Mesh, Topology};
use destair::weights::staircase::*;

/// Two terraces joined by a wall: z = 0 for x < 2, z = 1 for x > 2 (a step along x).
fn step() -> Mesh {
    let mut p = Vec::new();
    for x in [0.0f32, 1.0, 2.0, 2.0, 3.0, 4.0] {
        for y in [0.0f32, 1.0] {
            let z = if p.len() / 2 >= 3 { 1.0 } else { 0.0 };
            p.push([x, y, z]);
        }
    }
    let mut t = Vec::new();
    for i in 0..5u32 {
        let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
        t.push([a, c, d]);
        t.push([a, d, b]);
    }
    Mesh::new(p, t).unwrap()
}

#[test]
fn step_edges_are_staircases_and_weights_fall_off_with_surface_distance() {
    let m = step();
    let topo = Topology::build(&m);
    let theta = face_orientation(&m, [0.0, 0.0, 1.0]);
    assert_eq!(theta[0], 0.0);
    assert_eq!(theta[4], 1.0); // the wall
    let params = StaircaseParams {
        tau: Tau::Fixed(0.7),
        tau_max_mm: 10.0,
        beta_min: 0.0,
    };
    let s = staircase_weights(&m, &topo, [0.0, 0.0, 1.0], &params);
    // Vertices on both edges of the wall (x = 2 at z 0 and z 1) are staircase vertices.
    assert_eq!(
        s.is_staircase,
        vec![false, false, false, false, true, true, true, true, false, false, false, false]
    );
    // Distance along the surface: 2 mm to the far ends; weight 1 - d / max D.
    assert_eq!(s.distance_mm[0], 2.0);
    assert_eq!(s.weights.as_slice()[0], 0.0);
    assert_eq!(s.weights.as_slice()[2], 0.5);
    assert_eq!(s.weights.as_slice()[4], 1.0);
    let with_floor = staircase_weights(
        &m,
        &topo,
        [0.0, 0.0, 1.0],
        &StaircaseParams {
            beta_min: 0.1,
            ..params
        },
    );
    assert!((with_floor.weights.as_slice()[0] - 0.1).abs() < 1e-7);
    // Beyond tau_max nothing is reached.
    let short = staircase_weights(
        &m,
        &topo,
        [0.0, 0.0, 1.0],
        &StaircaseParams {
            tau_max_mm: 1.5,
            ..params
        },
    );
    assert!(short.distance_mm[0].is_infinite());
    assert_eq!(short.weights.as_slice()[0], 0.0);
}

#[test]
fn auto_tau_is_mean_plus_three_and_a_half_sd_within_its_range() {
    // Mean 0.2, population sd sqrt(2/300) = 0.08165: 0.2 + 3.5 x 0.08165 = 0.48577.
    let t = auto_tau(&[0.1, 0.2, 0.3]);
    assert!((t - 0.485_77).abs() < 1e-4, "{t}");
    // No spread: the floor 0.2; a wide spread: the paper's 0.7.
    assert_eq!(auto_tau(&[0.05; 10]), 0.2);
    assert_eq!(auto_tau(&[0.0, 0.0, 0.0, 1.0]), 0.7);
    assert_eq!(auto_tau(&[]), 0.7);
    assert_eq!("auto".parse::<Tau>(), Ok(Tau::Auto));
    assert_eq!("0.3".parse::<Tau>(), Ok(Tau::Fixed(0.3)));
    assert!("1.5".parse::<Tau>().is_err() && "often".parse::<Tau>().is_err());
}
