//! Tests of `src/phantom/volume.rs`.

use destair::phantom::volume::*;

#[test]
fn shapes_contain_what_they_should() {
    let s = Shape::Sphere {
        center: [0.0; 3],
        radius: 2.0,
    };
    assert!(s.contains([1.9, 0.0, 0.0]) && !s.contains([1.5, 1.5, 0.0]));
    let c = Shape::Cylinder {
        start: [0.0; 3],
        end: [0.0, 0.0, 10.0],
        radius: 1.0,
    };
    assert!(c.contains([0.5, 0.5, 9.9]) && !c.contains([0.0, 0.0, 10.1]));
    let t = Shape::Tube {
        points: vec![[0.0; 3], [10.0, 0.0, 0.0]],
        radii: vec![1.0, 3.0],
    };
    assert!(t.contains([10.0, 2.9, 0.0]) && !t.contains([0.0, 1.1, 0.0]));
    let b = Shape::Cuboid {
        center: [0.0; 3],
        half_extent: [1.0, 1.0, 5.0],
        rotation_deg: [90.0, 0.0, 0.0],
    };
    // Rotated 90 degrees about x: the long axis now runs along y.
    assert!(b.contains([0.0, 4.5, 0.0]) && !b.contains([0.0, 0.0, 4.5]));
    let d = Shape::Difference(Box::new(s.clone()), Box::new(c));
    assert!(!d.contains([0.0, 0.0, 1.0]) && d.contains([1.5, 0.0, -1.0]));
}

#[test]
fn painting_counts_match_the_analytic_volume() {
    let mut v = LabelVolume::new([40, 40, 40], [1.0; 3], [0.0; 3]);
    v.paint(
        &Shape::Sphere {
            center: [20.0; 3],
            radius: 15.0,
        },
        3,
    );
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 15f64.powi(3);
    let n = v.count(3) as f64;
    assert!((n - exact).abs() / exact < 0.01, "{n} vs {exact}");
}
