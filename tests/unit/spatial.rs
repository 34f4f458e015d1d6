//! Tests of `src/spatial/mod.rs`.

use destair::spatial::*;

#[test]
fn closest_point_regions_by_hand() {
    let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    assert_eq!(point_triangle_distance([0.25, 0.25, 2.0], t), 2.0);
    assert_eq!(point_triangle_distance([-1.0, -1.0, 0.0], t), 2f64.sqrt());
    assert_eq!(point_triangle_distance([0.5, -3.0, 4.0], t), 5.0);
    assert!((point_triangle_distance([1.0, 1.0, 0.0], t) - 0.5f64.sqrt()).abs() < 1e-12);
    // Collinear triangle: distance to the segment.
    let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
    assert!((point_triangle_distance([1.5, 1.0, 0.0], line) - 1.0).abs() < 1e-12);
}

#[test]
fn regions_name_where_the_closest_point_lies() {
    use TriangleRegion::{Corner, Edge, Inside};
    let (a, b, c) = ([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]);
    let region = |p| closest_point_and_region(p, a, b, c).1;
    assert_eq!(region([0.5, 0.5, 1.0]), Inside);
    assert_eq!(region([-1.0, -1.0, 0.0]), Corner(0));
    assert_eq!(region([3.0, -0.5, 0.0]), Corner(1));
    assert_eq!(region([-0.5, 3.0, 0.0]), Corner(2));
    assert_eq!(region([1.0, -1.0, 0.0]), Edge(0));
    assert_eq!(region([2.0, 2.0, 0.0]), Edge(1));
    assert_eq!(region([-1.0, 1.0, 0.0]), Edge(2));
    // On random triangles the point matches its region: a corner is that corner, an
    // edge point lies on that edge, an inside point is off every edge.
    let mut rng = fastrand::Rng::with_seed(7);
    let mut r = || 4.0 * rng.f64() - 2.0;
    for _ in 0..2000 {
        let t: [[f64; 3]; 3] = std::array::from_fn(|_| [r(), r(), r()]);
        let p = [r(), r(), r()];
        let (x, region) = closest_point_and_region(p, t[0], t[1], t[2]);
        let on_segment = |i: usize| {
            let (s, e) = (t[i], t[(i + 1) % 3]);
            let d = sub(e, s);
            let u = (dot(sub(x, s), d) / dot(d, d)).clamp(0.0, 1.0);
            let y = along(s, d, u);
            dot(sub(x, y), sub(x, y)).sqrt() < 1e-9
        };
        match region {
            Corner(i) => assert_eq!(x, t[i as usize]),
            Edge(i) => assert!(on_segment(i as usize), "{t:?} {p:?}"),
            Inside => assert!((0..3).all(|i| !on_segment(i)), "{t:?} {p:?}"),
        }
        assert_eq!(x, closest_point_on_triangle(p, t[0], t[1], t[2]));
    }
}
