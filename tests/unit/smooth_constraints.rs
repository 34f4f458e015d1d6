//! Tests of `src/smooth/constraints.rs`.

use destair::smooth::constraints::*;

#[test]
fn diamond_clip_lands_on_the_face() {
    let h = [1.0, 2.0, 3.0];
    let d = clip(Region::Diamond(h), [1.0, 1.0, 1.0]);
    let s = d[0] / h[0] + d[1] / h[1] + d[2] / h[2];
    assert!((s - 0.5).abs() < 1e-6);
    assert_eq!(clip(Region::Diamond(h), [0.1, 0.0, 0.0]), [0.1, 0.0, 0.0]);
    assert_eq!(clip(Region::Box(h), [1.0, -2.0, 0.5]), [0.5, -1.0, 0.5]);
}
