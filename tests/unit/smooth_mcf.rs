//! Tests of `src/smooth/mcf.rs`.

use destair::smooth::mcf::*;

#[test]
fn cotangents_by_hand() {
    // Right isosceles triangle: 90 degrees at corner 0, 45 at the others.
    let c = cotangents([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    assert!(c[0].abs() < 1e-6 && (c[1] - 1.0).abs() < 1e-6 && (c[2] - 1.0).abs() < 1e-6);
    // Obtuse angle clamps to 0; a degenerate sliver stays finite.
    let o = cotangents([[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [-1.0, 0.1, 0.0]]);
    assert_eq!(o[0], 0.0);
    let d = cotangents([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
    assert!(d.iter().all(|x| x.is_finite() && *x >= 0.0));
}
