//! Tests of `src/spatial/intersect.rs`.

use destair::mesh::Mesh;
use destair::spatial::intersect::*;

/// Independent reference on integer corners: the separating axis test in exact integer
/// arithmetic. Closed convex sets are disjoint iff one of the candidate axes (both normals,
/// the nine edge cross products, and the in-plane edge normals for coplanar pairs)
/// separates their projections strictly.
fn sat_intersect(t: [[i64; 3]; 3], u: [[i64; 3]; 3]) -> bool {
    let sub = |a: [i64; 3], b: [i64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [i64; 3], b: [i64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let dot = |a: [i64; 3], b: [i64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let edges = |x: [[i64; 3]; 3]| [0, 1, 2].map(|k| sub(x[(k + 1) % 3], x[k]));
    let (et, eu) = (edges(t), edges(u));
    let (nt, nu) = (cross(et[0], et[1]), cross(eu[0], eu[1]));
    let mut axes = vec![nt, nu];
    for a in et {
        for b in eu {
            axes.push(cross(a, b));
        }
    }
    for e in et {
        axes.push(cross(nt, e));
    }
    for e in eu {
        axes.push(cross(nu, e));
    }
    !axes.iter().any(|&ax| {
        let pt = t.map(|p| dot(p, ax));
        let pu = u.map(|p| dot(p, ax));
        let (tl, th) = (*pt.iter().min().unwrap(), *pt.iter().max().unwrap());
        let (ul, uh) = (*pu.iter().min().unwrap(), *pu.iter().max().unwrap());
        th < ul || uh < tl
    })
}

fn random_triangle(rng: &mut fastrand::Rng, span: i64) -> [[i64; 3]; 3] {
    loop {
        let t = [0; 3].map(|_| [0; 3].map(|_| rng.i64(0..span)));
        if !is_exactly_degenerate(t.map(|p| p.map(|x| x as f32))) {
            return t;
        }
    }
}

#[test]
fn matches_the_separating_axis_test_on_random_integer_triangles() {
    // Small integer ranges make touching, coplanar and collinear cases common.
    let mut rng = fastrand::Rng::with_seed(7);
    let mut hits = [0usize; 2];
    for span in [3, 4, 6, 10] {
        for _ in 0..20_000 {
            let t = random_triangle(&mut rng, span);
            let u = random_triangle(&mut rng, span);
            let expected = sat_intersect(t, u);
            let f = |x: [[i64; 3]; 3]| x.map(|p| p.map(|c| c as f32));
            assert_eq!(
                triangles_intersect(f(t), f(u)),
                expected,
                "triangles {t:?} and {u:?}"
            );
            assert_eq!(triangles_intersect(f(u), f(t)), expected);
            hits[expected as usize] += 1;
        }
    }
    // Both outcomes well represented.
    assert!(hits[0] > 10_000 && hits[1] > 10_000, "{hits:?}");
}

/// Integer points of a plane: (i, j) on the coordinate plane z = 5 (whose orientations are
/// settled before the exact predicate), or on the tilted plane spanned by (1, 2, 0) and
/// (0, 1, 3) through (1, 1, 1) (whose are not).
fn on_plane(tilted: bool, [i, j]: [i64; 2]) -> [i64; 3] {
    if tilted {
        [1 + i, 1 + 2 * i + j, 1 + 3 * j]
    } else {
        [i, j, 5]
    }
}

#[test]
fn coplanar_triangles_match_the_separating_axis_test() {
    let mut rng = fastrand::Rng::with_seed(11);
    let mut hits = [0usize; 2];
    for tilted in [false, true] {
        for span in [3, 5, 8] {
            for _ in 0..10_000 {
                let flat = |rng: &mut fastrand::Rng| loop {
                    let t = [0; 3].map(|_| on_plane(tilted, [rng.i64(0..span), rng.i64(0..span)]));
                    if !is_exactly_degenerate(t.map(|p| p.map(|x| x as f32))) {
                        return t;
                    }
                };
                let (t, u) = (flat(&mut rng), flat(&mut rng));
                let expected = sat_intersect(t, u);
                let f = |x: [[i64; 3]; 3]| x.map(|p| p.map(|c| c as f32));
                assert_eq!(triangles_intersect(f(t), f(u)), expected, "{t:?} and {u:?}");
                assert_eq!(triangles_intersect(f(u), f(t)), expected, "{u:?} and {t:?}");
                hits[expected as usize] += 1;
            }
        }
    }
    assert!(hits[0] > 5_000 && hits[1] > 5_000, "{hits:?}");
}

/// Faces sharing one corner meet beyond it iff the side opposite it in one meets the other
/// face: `faces_intersect`'s shortcuts (a side strictly off the other's plane, overlapping
/// corners when coplanar) against that definition, on random integer faces, many coplanar.
#[test]
fn faces_sharing_a_corner_match_the_side_tests() {
    let mut rng = fastrand::Rng::with_seed(13);
    let mut hits = [0usize; 2];
    for (tilted, span) in [(None, 3), (None, 5), (Some(false), 4), (Some(true), 4)] {
        for _ in 0..20_000 {
            let point = |rng: &mut fastrand::Rng| -> [f32; 3] {
                let p = match tilted {
                    None => [0; 3].map(|_| rng.i64(0..span)),
                    Some(tilted) => on_plane(tilted, [rng.i64(0..span), rng.i64(0..span)]),
                };
                p.map(|x| x as f32)
            };
            let v = point(&mut rng);
            let (a, b, c, d) = (
                point(&mut rng),
                point(&mut rng),
                point(&mut rng),
                point(&mut rng),
            );
            let (t, u) = ([v, a, b], [c, v, d]);
            if is_exactly_degenerate(t) || is_exactly_degenerate(u) {
                continue;
            }
            let expected = segment_meets_triangle(a, b, u) || segment_meets_triangle(c, d, t);
            // Vertex 0 shared, the others distinct indices (positions may coincide).
            assert_eq!(
                faces_intersect([0, 1, 2], t, [3, 0, 4], u),
                expected,
                "{t:?} and {u:?}"
            );
            assert_eq!(faces_intersect([3, 0, 4], u, [0, 1, 2], t), expected);
            hits[expected as usize] += 1;
        }
    }
    assert!(hits[0] > 10_000 && hits[1] > 10_000, "{hits:?}");
}

#[test]
fn coplanar_and_touching_cases_by_hand() {
    let t = [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]];
    // Coplanar, inside.
    assert!(triangles_intersect(
        t,
        [[1.0, 1.0, 0.0], [2.0, 1.0, 0.0], [1.0, 2.0, 0.0]]
    ));
    // Coplanar, apart across the hypotenuse.
    assert!(!triangles_intersect(
        t,
        [[3.0, 3.0, 0.0], [5.0, 3.0, 0.0], [3.0, 5.0, 0.0]]
    ));
    // Touching at a corner on the hypotenuse.
    assert!(triangles_intersect(
        t,
        [[2.0, 2.0, 0.0], [5.0, 3.0, 0.0], [3.0, 5.0, 0.0]]
    ));
    // Standing on the plane, touching in one point; a hair above it, apart.
    assert!(triangles_intersect(
        t,
        [[1.0, 1.0, 0.0], [1.0, 1.0, 3.0], [2.0, 1.0, 3.0]]
    ));
    let eps = f32::EPSILON;
    assert!(!triangles_intersect(
        t,
        [[1.0, 1.0, eps], [1.0, 1.0, 3.0], [2.0, 1.0, 3.0]]
    ));
    // Piercing.
    assert!(triangles_intersect(
        t,
        [[1.0, 1.0, -1.0], [1.0, 1.0, 1.0], [2.0, 1.0, 1.0]]
    ));
    assert!(is_exactly_degenerate([
        [0.0, 0.0, 0.0],
        [1.0, 1.0, 1.0],
        [2.0, 2.0, 2.0]
    ]));
}

#[test]
fn neighbours_intersect_only_when_folded() {
    // Two faces sharing edge (0,1): flat, then folded onto each other.
    let flat = Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
        ],
        vec![[0, 1, 2], [1, 0, 3]],
    )
    .unwrap();
    assert!(self_intersections(&flat).is_empty());
    let folded = Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, 0.5, 0.0],
        ],
        vec![[0, 1, 2], [1, 0, 3]],
    )
    .unwrap();
    assert_eq!(self_intersections(&folded), vec![[0, 1]]);
    // Sharing one corner: apart, then the second face's far edge crossing the first.
    let fan = |d: [f32; 3]| {
        Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                [1.0, 1.0, 1.0],
                d,
            ],
            vec![[0, 1, 2], [0, 3, 4]],
        )
        .unwrap()
    };
    assert!(self_intersections(&fan([-1.0, -1.0, 1.0])).is_empty());
    assert_eq!(self_intersections(&fan([0.5, 0.5, -1.0])), vec![[0, 1]]);
}

/// Every pair by brute force, for checking the grid's candidate search.
fn brute_self_intersections(mesh: &Mesh) -> Vec<[u32; 2]> {
    let p = mesh.positions();
    let t = mesh.triangles();
    let c = |f: usize| t[f].map(|v| p[v as usize]);
    let mut out = Vec::new();
    for f in 0..t.len() {
        for g in f + 1..t.len() {
            if !is_exactly_degenerate(c(f))
                && !is_exactly_degenerate(c(g))
                && faces_intersect(t[f], c(f), t[g], c(g))
            {
                out.push([f as u32, g as u32]);
            }
        }
    }
    out
}

#[test]
fn grid_search_matches_all_pairs() {
    let mut rng = fastrand::Rng::with_seed(3);
    for round in 0..20 {
        // A jittered grid surface (neighbours share vertices) plus loose triangles.
        let n = 8;
        let mut positions = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let z = if round % 2 == 0 { rng.f32() * 2.0 } else { 0.0 };
                positions.push([i as f32, j as f32, z]);
            }
        }
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = (j * n + i) as u32;
                triangles.push([v, v + 1, v + n as u32]);
                triangles.push([v + 1, v + n as u32 + 1, v + n as u32]);
            }
        }
        for _ in 0..30 {
            let base = positions.len() as u32;
            for _ in 0..3 {
                positions.push([rng.f32() * 7.0, rng.f32() * 7.0, rng.f32() * 2.0 - 0.5]);
            }
            triangles.push([base, base + 1, base + 2]);
        }
        let mesh = Mesh::new(positions, triangles).unwrap();
        let fast = self_intersections(&mesh);
        assert_eq!(fast, brute_self_intersections(&mesh), "round {round}");
        assert!(!fast.is_empty());
    }
}

#[test]
fn two_meshes_intersect_where_they_cross() {
    let a = Mesh::new(
        vec![[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let b = |z: f32| {
        Mesh::new(
            vec![
                [1.0, 1.0, z - 1.0],
                [1.0, 1.0, z + 1.0],
                [2.0, 1.0, z + 1.0],
                [9.0, 9.0, 9.0],
                [9.0, 9.5, 9.0],
                [9.5, 9.0, 9.0],
            ],
            vec![[3, 4, 5], [0, 1, 2]],
        )
        .unwrap()
    };
    assert_eq!(mesh_intersections(&a, &b(0.0)), vec![[0, 1]]);
    assert!(mesh_intersections(&a, &b(1.5)).is_empty());
    // Touching at one point (the corner of b on a's face) counts.
    assert_eq!(mesh_intersections(&a, &b(1.0)), vec![[0, 1]]);
    for z in [0.0, 1.0, 1.5, -1.0, -1.01] {
        assert_eq!(
            meshes_touch(&a, &b(z)),
            !mesh_intersections(&a, &b(z)).is_empty(),
            "z = {z}"
        );
    }
}

/// Huge slivers across the box among many small triangles: the grid, which would list each
/// sliver in nearly every cell, is made coarser, and finds the same pairs as testing all.
#[test]
fn grid_search_with_huge_slivers_matches_all_pairs() {
    let mut rng = fastrand::Rng::with_seed(29);
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for _ in 0..2000 {
        let c: [f32; 3] = std::array::from_fn(|_| rng.f32() * 40.0);
        let base = positions.len() as u32;
        for _ in 0..3 {
            positions.push(std::array::from_fn(|a| c[a] + rng.f32() * 0.3));
        }
        triangles.push([base, base + 1, base + 2]);
    }
    for k in 0..40 {
        let s = k as f32 * 0.37;
        let base = positions.len() as u32;
        positions.extend([[s, 0.0, 0.0], [40.0, 40.0 - s, 40.0], [s, 0.5, 40.0]]);
        triangles.push([base, base + 1, base + 2]);
    }
    let mesh = Mesh::new(positions, triangles).unwrap();
    let fast = self_intersections(&mesh);
    assert_eq!(fast, brute_self_intersections(&mesh));
    // The slivers cross small triangles (and each other at their shared corner region).
    assert!(fast.len() > 40, "{} pairs", fast.len());
}
