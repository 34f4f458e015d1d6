//! Tests of `src/metrics/distance.rs`.

use destair::mesh::Mesh;
use destair::metrics::distance::*;
use destair::spatial::TriangleBvh;

/// Triangles scattered in a box: a soup, as a mesh.
fn soup(rng: &mut fastrand::Rng, n: usize, offset: [f32; 3]) -> Mesh {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for t in 0..n as u32 {
        let c: [f32; 3] = std::array::from_fn(|k| offset[k] + 20.0 * rng.f32());
        for _ in 0..3 {
            positions.push(std::array::from_fn(|k| c[k] + 2.0 * rng.f32() - 1.0));
        }
        triangles.push([3 * t, 3 * t + 1, 3 * t + 2]);
    }
    Mesh::new(positions, triangles).unwrap()
}

#[test]
fn bounded_minimum_distance_equals_the_full_search() {
    let mut rng = fastrand::Rng::with_seed(11);
    for round in 0..40 {
        let gap = 25.0 * rng.f32() - 5.0;
        let (na, nb) = (1 + rng.usize(..3000), 1 + rng.usize(..3000));
        let a = soup(&mut rng, na, [0.0; 3]);
        let b = soup(&mut rng, nb, [gap, 0.5 * gap, 0.0]);
        let (ga, gb) = (TriangleBvh::build(&a), TriangleBvh::build(&b));
        let full = gb
            .distances(a.positions())
            .into_iter()
            .chain(ga.distances(b.positions()))
            .fold(f64::INFINITY, f64::min);
        assert_eq!(minimum_distance(&a, &ga, &b, &gb), full, "round {round}");
    }
}
