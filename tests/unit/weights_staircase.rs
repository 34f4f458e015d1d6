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
        ..Default::default()
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

/// Dijkstra's search with a binary heap (what `geodesic_distance` did before its bucket
/// search): the reference the fast search must match bit for bit.
fn dijkstra(mesh: &Mesh, topology: &Topology, sources: &[bool], limit: f64) -> Vec<f32> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let p = mesh.positions();
    let mut dist = vec![f64::INFINITY; mesh.n_vertices()];
    let mut heap = BinaryHeap::new();
    for v in (0..sources.len()).filter(|&v| sources[v]) {
        dist[v] = 0.0;
        // Non-negative f64 bits order like the values.
        heap.push(Reverse((0u64, v as u32)));
    }
    while let Some(Reverse((bits, v))) = heap.pop() {
        let d = f64::from_bits(bits);
        if d > dist[v as usize] {
            continue;
        }
        let pv = p[v as usize];
        for &u in topology.neighbors(v as usize) {
            let pu = p[u as usize];
            let len = (0..3)
                .map(|k| (pu[k] as f64 - pv[k] as f64).powi(2))
                .sum::<f64>()
                .sqrt();
            let nd = d + len;
            if nd <= limit && nd < dist[u as usize] {
                dist[u as usize] = nd;
                heap.push(Reverse((nd.to_bits(), u)));
            }
        }
    }
    dist.into_iter().map(|d| d as f32).collect()
}

/// The bucket search gives Dijkstra's distances bit for bit: on a marching-cubes blob (many
/// equal edges, so many ties) and on jittered and stretched copies, with sparse and dense
/// sources, limits short and long, and no limit (distances far beyond the buckets' range).
#[test]
fn geodesic_distance_matches_dijkstra_bit_for_bit() {
    let blob = destair::phantom::big_case(20_000, &Default::default()).meshes[0]
        .1
        .clone();
    let mut rng = fastrand::Rng::with_seed(5);
    let jittered: Vec<[f32; 3]> = blob
        .positions()
        .iter()
        .map(|p| p.map(|x| x + 0.3 * (rng.f32() - 0.5)))
        .collect();
    // A few edges 1000 times longer than the rest.
    let stretched: Vec<[f32; 3]> = blob
        .positions()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if i % 97 == 0 {
                p.map(|x| x * 1000.0)
            } else {
                *p
            }
        })
        .collect();
    let triangles = blob.triangles().to_vec();
    for positions in [blob.positions().to_vec(), jittered, stretched] {
        let mesh = Mesh::new(positions, triangles.clone()).unwrap();
        let topology = Topology::build(&mesh);
        for share in [0.001, 0.05, 0.5] {
            let sources: Vec<bool> = (0..mesh.n_vertices()).map(|_| rng.f64() < share).collect();
            for limit in [0.0, 0.7, 3.0, 40.0, f64::INFINITY] {
                let fast = geodesic_distance(&mesh, &topology, &sources, limit);
                let slow = dijkstra(&mesh, &topology, &sources, limit);
                let reached = fast.iter().filter(|d| d.is_finite()).count();
                assert!(
                    fast.iter()
                        .zip(&slow)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "share {share}, limit {limit}: {reached} reached"
                );
            }
        }
    }
    // No sources: nothing is reached.
    let topology = Topology::build(&blob);
    let none = vec![false; blob.n_vertices()];
    assert!(geodesic_distance(&blob, &topology, &none, 3.0)
        .iter()
        .all(|d| d.is_infinite()));
}

#[test]
fn slice_step_change_is_the_orientation_of_marching_cubes_chamfer() {
    // The chamfer marching cubes puts where a one-slice step leaves its terrace, on a grid of
    // h x h x H: through the midpoints of a y edge and a z edge of one cell, along x.
    for (h, big) in [(0.4f32, 0.8f32), (0.5, 1.5), (0.45, 3.0), (1.0, 1.25)] {
        let m = Mesh::new(
            vec![
                [0.0, h / 2.0, 0.0],
                [h, h / 2.0, 0.0],
                [0.0, 0.0, big / 2.0],
            ],
            vec![[0, 1, 2]],
        )
        .unwrap();
        let theta = face_orientation(&m, [0.0, 0.0, 1.0])[0];
        let want = slice_step_change(f64::from(big / h));
        assert!(
            (theta - want).abs() < 1e-6,
            "{h} x {big}: {theta} vs {want}"
        );
    }
    // Hand-computed: 1 - 1/sqrt(5) at ratio 2, 1 - 1/sqrt(10) at ratio 3.
    assert!((slice_step_change(2.0) - 0.552_786).abs() < 1e-6);
    assert!((slice_step_change(3.0) - 0.683_772).abs() < 1e-6);
}

#[test]
fn auto_tau_stays_below_a_known_slice_step() {
    // Terrace-chamfer corners of a ratio-2 grid change by 0.553, below the paper's 0.7: with the
    // grid known, auto finds them; a fixed tau is left as given.
    let m = step();
    let topo = Topology::build(&m);
    let step_change = slice_step_change(2.0);
    let auto = StaircaseParams {
        slice_step_change: Some(step_change),
        ..Default::default()
    };
    let s = staircase_weights(&m, &topo, [0.0, 0.0, 1.0], &auto);
    assert!(s.tau_auto);
    assert!(
        (s.tau - (step_change - SLICE_STEP_MARGIN)).abs() < 1e-6,
        "{}",
        s.tau
    );
    let fixed = StaircaseParams {
        tau: Tau::Fixed(0.7),
        ..auto
    };
    assert_eq!(
        staircase_weights(&m, &topo, [0.0, 0.0, 1.0], &fixed).tau,
        0.7
    );
}
