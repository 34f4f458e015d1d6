//! Tests of `src/spatial/bvh.rs`.

use destair::spatial::bvh::*;
use destair::spatial::point_triangle_distance2;

/// `n` small triangles scattered in a 40 mm box, the last a copy of the first (a tie).
fn scattered_triangles(rng: &mut fastrand::Rng, n: usize) -> Vec<[[f32; 3]; 3]> {
    let mut triangles: Vec<[[f32; 3]; 3]> = (0..n)
        .map(|_| {
            let c: [f32; 3] = std::array::from_fn(|_| rng.f32() * 40.0);
            std::array::from_fn(|_| std::array::from_fn(|a| c[a] + rng.f32() * 2.0))
        })
        .collect();
    if n > 3 {
        triangles[n - 1] = triangles[0];
    }
    triangles
}

#[test]
fn the_tree_finds_what_testing_every_triangle_finds() {
    let mut rng = fastrand::Rng::with_seed(21);
    for round in 0..30 {
        let n = [1, 2, 5, 40, 300, 3000][round % 6];
        let triangles = scattered_triangles(&mut rng, n);
        let tree = TriangleBvh::from_triangles(&triangles);
        for _ in 0..200 {
            // Near and far (up to 60 mm outside the box), and on the surface (next to a
            // corner, where the cells settle the query).
            // And a few mm off the surface, often in an empty cell beside listed ones.
            let corner = triangles[rng.usize(0..n)][rng.usize(0..3)];
            let p: [f32; 3] = match rng.u32(0..3) {
                0 => std::array::from_fn(|_| rng.f32() * 160.0 - 60.0),
                1 => corner.map(|x| x + 0.02 * (rng.f32() - 0.5)),
                _ => corner.map(|x| x + 8.0 * (rng.f32() - 0.5)),
            };
            let within = if rng.bool() {
                f64::INFINITY
            } else {
                rng.f64() * 30.0
            };
            // Sometimes nothing is kept: the search then never narrows.
            let none = round % 5 == 4;
            let keep = |f: u32| f % 7 != 3 && !none;
            let fast = tree
                .nearest_matching_within(p, within, keep)
                .map(|n| (n.distance, n.triangle));
            let slow = tree.fallback(p, within, keep);
            assert_eq!(fast, slow, "round {round}, point {p:?}, within {within}");
        }
    }
}

/// A guessed start changes nothing: near and far points, with guesses that are right, close,
/// far, tied with a lower-numbered copy, out of range or missing, give the distances testing
/// every triangle gives.
#[test]
fn a_guessed_start_gives_the_same_distances() {
    let mut rng = fastrand::Rng::with_seed(22);
    for n in [1, 4, 60, 2000] {
        let triangles = scattered_triangles(&mut rng, n);
        let tree = TriangleBvh::from_triangles(&triangles);
        let points: Vec<[f32; 3]> = (0..400)
            .map(|i| {
                let corner = triangles[rng.usize(0..n)][rng.usize(0..3)];
                if i % 2 == 0 {
                    corner.map(|x| x + 0.3 * (rng.f32() - 0.5))
                } else {
                    std::array::from_fn(|_| rng.f32() * 160.0 - 60.0)
                }
            })
            .collect();
        // One guess short: the last point has none.
        let guesses: Vec<u32> = (0..points.len() - 1)
            .map(|i| match i % 4 {
                0 => rng.u32(0..n as u32),
                1 => (n - 1) as u32,
                2 => u32::MAX,
                _ => n as u32 + rng.u32(0..5),
            })
            .collect();
        let slow: Vec<f64> = points
            .iter()
            .map(|&p| {
                tree.fallback(p, f64::INFINITY, |_| true)
                    .map_or(f64::INFINITY, |b| b.0)
            })
            .collect();
        assert_eq!(tree.distances_from(&points, &guesses), slow, "n {n}");
        assert_eq!(tree.distances(&points), slow, "n {n}");
    }
}

/// The disks of `leaf` in lane `k`, with its centre and normal.
fn disk_in_lane(leaf: &[[[f32; 3]; 3]], k: usize) -> (Disks, [f32; 3], [f32; 3]) {
    let (c, nrm, r, t) = leaf_disk(leaf);
    let mut disks = Disks::default();
    for a in 0..3 {
        disks.c[a][k] = c[a];
        disks.n[a][k] = nrm[a];
    }
    (disks.r[k], disks.t[k]) = (r, t);
    (disks, c, nrm)
}

/// Lane `k`'s disk bound from `q` is no more than the squared distance to any triangle of
/// `leaf` (checked in f64).
fn assert_bound_below(q: [f32; 3], disks: &Disks, k: usize, leaf: &[[[f32; 3]; 3]], round: usize) {
    let bound = f64::from(disk_distances2(q, disks)[k]);
    for tri in leaf {
        let d2 = point_triangle_distance2(q, *tri);
        assert!(
            bound <= d2,
            "round {round}: bound {bound} > {d2}, {q:?}, {tri:?}"
        );
    }
}

/// The disk bound never exceeds the distance to any triangle of its leaf (checked in f64
/// against every triangle), for near-flat and folded leaves, tiny and huge offsets.
#[test]
fn a_leaf_disk_bounds_its_triangles_from_below() {
    let mut rng = fastrand::Rng::with_seed(8);
    for round in 0..2000 {
        let scale = [0.01f32, 1.0, 300.0][round % 3];
        let origin: [f32; 3] = std::array::from_fn(|_| (rng.f32() - 0.5) * 1000.0);
        let bend = [0.0f32, 0.05, 1.0][(round / 3) % 3];
        let n = 1 + rng.usize(0..LEAF);
        let leaf: Vec<[[f32; 3]; 3]> = (0..n)
            .map(|_| {
                std::array::from_fn(|_| {
                    let (x, y) = (rng.f32() * scale, rng.f32() * scale);
                    [
                        origin[0] + x,
                        origin[1] + y,
                        origin[2] + bend * scale * rng.f32(),
                    ]
                })
            })
            .collect();
        let k = round % 4;
        let (disks, c, _) = disk_in_lane(&leaf, k);
        for _ in 0..20 {
            let reach = [0.0f32, 0.5, 3.0, 100.0][rng.usize(0..4)] * scale;
            let q: [f32; 3] = std::array::from_fn(|a| {
                c[a] + (rng.f32() - 0.5) * 2.0 * reach + if a == 2 { reach } else { 0.0 }
            });
            assert_bound_below(q, &disks, k, &leaf, round);
        }
    }
}

/// Where the disk bound is tightest, just past the rim of the disk's farthest corner and
/// far off its plane (a reference a few cm away), it still stays below that corner's
/// distance, for offsets from centimetres down to rounding.
#[test]
fn a_leaf_disk_bound_stays_below_the_corner_at_its_rim() {
    let mut rng = fastrand::Rng::with_seed(9);
    for round in 0..4000 {
        let scale = [0.01f32, 0.3, 1.0, 300.0][round % 4];
        let origin: [f32; 3] = std::array::from_fn(|_| (rng.f32() - 0.5) * 1000.0);
        // Flat leaves (no thickness to spare) and curved ones.
        let flat = [0.0f32, 1e-3, 0.3][(round / 4) % 3];
        let n = 1 + rng.usize(0..LEAF);
        let leaf: Vec<[[f32; 3]; 3]> = (0..n)
            .map(|_| {
                std::array::from_fn(|_| {
                    std::array::from_fn(|a| {
                        origin[a]
                            + scale
                                * if a == 2 {
                                    flat * rng.f32()
                                } else {
                                    0.1 + rng.f32()
                                }
                    })
                })
            })
            .collect();
        let k = round % 4;
        let (disks, c, nrm) = disk_in_lane(&leaf, k);
        // The corner farthest from the centre, and its in-plane direction (f64).
        let f = |p: [f32; 3]| p.map(f64::from);
        let (cc, nn) = (f(c), f(nrm));
        let far = leaf
            .iter()
            .flatten()
            .copied()
            .max_by(|a, b| {
                let d = |p: [f32; 3]| (0..3).map(|i| (f(p)[i] - cc[i]).powi(2)).sum::<f64>();
                d(*a).total_cmp(&d(*b))
            })
            .unwrap();
        let w: Vec<f64> = (0..3).map(|i| f(far)[i] - cc[i]).collect();
        let h: f64 = (0..3).map(|i| w[i] * nn[i]).sum();
        let u: Vec<f64> = (0..3).map(|i| w[i] - h * nn[i]).collect();
        let len = u.iter().map(|x| x * x).sum::<f64>().sqrt();
        if len == 0.0 {
            continue;
        }
        for _ in 0..20 {
            let height = [0.0f64, 1.0, 12.0, 40.0, 150.0][rng.usize(0..5)] * (1.0 + rng.f64());
            let past = [0.0f64, 1e-6, 1e-4, 1e-2, 1.0][rng.usize(0..5)] * f64::from(scale);
            let q: [f32; 3] = std::array::from_fn(|i| {
                (cc[i] + u[i] / len * (len + past) + nn[i] * (h + height)) as f32
            });
            assert_bound_below(q, &disks, k, &leaf, round);
        }
    }
}

/// The triangles of a height field over an m x m grid of squares `step` mm wide, two per
/// square.
fn height_grid(m: usize, step: f32, height: &dyn Fn(f32, f32) -> f32) -> Vec<[[f32; 3]; 3]> {
    let at = |i: usize, j: usize| {
        let (x, y) = (i as f32 * step, j as f32 * step);
        [x, y, height(x, y)]
    };
    let mut triangles = Vec::new();
    for i in 0..m {
        for j in 0..m {
            triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    triangles
}

/// Far above flat, gently curved and bumpy surfaces, where the disks prune most leaves and
/// twigs, and with exact ties (points straight above grid vertices of a flat grid), the tree
/// still finds what testing every triangle finds.
#[test]
fn far_above_a_surface_the_tree_finds_what_testing_every_triangle_finds() {
    let mut rng = fastrand::Rng::with_seed(5);
    let grid = |m, height: &dyn Fn(f32, f32) -> f32| height_grid(m, 1.0, height);
    let flat = grid(60, &|_, _| 0.0);
    let dome = grid(60, &|x, y| {
        -((x - 30.0).powi(2) + (y - 30.0).powi(2)) / 200.0
    });
    // Bumps a few mm across: the disks of twigs (up to 64 triangles) are thick there.
    let bumps = grid(60, &|x, y| 3.0 * (x / 3.0).sin() * (y / 4.0).cos());
    for triangles in [flat, dome, bumps] {
        let tree = TriangleBvh::from_triangles(&triangles);
        for i in 0..400 {
            let (x, y) = if i % 2 == 0 {
                (rng.usize(5..55) as f32, rng.usize(5..55) as f32)
            } else {
                (5.0 + rng.f32() * 50.0, 5.0 + rng.f32() * 50.0)
            };
            let p = [x, y, [3.0f32, 12.0, 40.0][i % 3]];
            let fast = tree.nearest(p).map(|n| (n.distance, n.triangle));
            assert_eq!(fast, tree.fallback(p, f64::INFINITY, |_| true), "{p:?}");
        }
    }
}

#[test]
fn the_tree_does_not_depend_on_the_thread_count() {
    let mut rng = fastrand::Rng::with_seed(4);
    let triangles: Vec<[[f32; 3]; 3]> = (0..40_000)
        .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| rng.f32() * 100.0)))
        .collect();
    let build = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| Tree::build(&triangles))
    };
    let (one, three) = (build(1), build(3));
    assert_eq!(one.order, three.order);
    assert_eq!(one.nodes.len(), three.nodes.len());
    assert_eq!(one.corners, three.corners);
}

/// Query points with NaN coordinates (a corrupt vertex) find nothing, and infinite ones what
/// testing every triangle finds, without a panic (the children's sort keys are made from the
/// bits of their distances, NaN payloads included).
#[test]
fn a_query_point_that_is_not_finite_finds_nothing() {
    let mut rng = fastrand::Rng::with_seed(31);
    let triangles = scattered_triangles(&mut rng, 3000);
    let tree = TriangleBvh::from_triangles(&triangles);
    let nans = [
        f32::NAN,
        -f32::NAN,
        f32::from_bits(0xffff_ffff),
        f32::from_bits(0x7fff_ffff),
    ];
    for (i, &nan) in nans.iter().enumerate() {
        for p in [
            [nan, 1.0, 2.0],
            [3.0, nan, nan],
            [f32::INFINITY, 5.0, 5.0],
            [5.0, f32::NEG_INFINITY, f32::INFINITY],
        ] {
            let slow = tree.fallback(p, f64::INFINITY, |_| true);
            let fast = tree.nearest(p).map(|n| (n.distance, n.triangle));
            assert_eq!(fast, slow, "{i}: {p:?}");
            if p.iter().any(|x| x.is_nan()) {
                assert_eq!(fast, None, "{i}: {p:?}");
            }
        }
    }
    let points = [[f32::NAN, 0.0, 0.0], [20.0, 20.0, 20.0], [f32::NAN; 3]];
    let d = tree.distances(&points);
    assert!(
        d[0].is_infinite() && d[1].is_finite() && d[2].is_infinite(),
        "{d:?}"
    );
}

/// Points on and just off a surface, next to and on the walls of the grid's cells, where a
/// query's own cell does not settle it and the cells across the nearby walls are searched:
/// with a guessed start (as `compare` gives one) or none, the cells find what testing every
/// triangle finds, exact ties on a flat grid included.
#[test]
fn next_to_cell_walls_the_cells_find_what_testing_every_triangle_finds() {
    let mut rng = fastrand::Rng::with_seed(17);
    let flat = height_grid(40, 0.7, &|_, _| 0.0);
    let bumps = height_grid(40, 0.7, &|x, y| 2.0 * (x / 2.0).sin() * (y / 3.0).cos());
    for triangles in [flat, bumps] {
        let tree = TriangleBvh::from_triangles(&triangles);
        let cells = destair::spatial::cells::TriangleCells::build(&triangles);
        let mut points = Vec::new();
        let mut guesses = Vec::new();
        for i in 0..3000 {
            let f = rng.usize(0..triangles.len());
            let t = triangles[f];
            let (u, v) = (rng.f32(), rng.f32());
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            let mut p: [f32; 3] = std::array::from_fn(|a| {
                t[0][a] + u * (t[1][a] - t[0][a]) + v * (t[2][a] - t[0][a])
            });
            p[2] += [0.0, 0.01, -0.01, 0.2, -0.3, 0.9, -1.4][i % 7];
            // Onto the nearest wall along one axis, or a hair either side of it.
            let a = rng.usize(0..3);
            let k = ((f64::from(p[a]) - cells.origin[a]) / cells.cell).round();
            let wall = (cells.origin[a] + k * cells.cell) as f32;
            p[a] = wall + [0.0, 1e-4, -1e-4, 0.02, -0.05, 0.3, -0.45][rng.usize(0..7)];
            points.push(p);
            guesses.push(f as u32);
        }
        let slow: Vec<(f64, u32)> = points
            .iter()
            .map(|&p| tree.fallback(p, f64::INFINITY, |_| true).unwrap())
            .collect();
        for (p, want) in points.iter().zip(&slow) {
            let fast = tree.nearest(*p).map(|n| (n.distance, n.triangle));
            assert_eq!(fast, Some(*want), "{p:?}");
        }
        let distances: Vec<f64> = slow.iter().map(|s| s.0).collect();
        assert_eq!(tree.distances_from(&points, &guesses), distances);
    }
}
