//! Tests of `src/render/colour.rs`.

use destair::render::colour::*;

#[test]
fn viridis_ends_and_middle() {
    assert_eq!(viridis(0.0), VIRIDIS[0]);
    assert_eq!(viridis(1.0), VIRIDIS[8]);
    assert_eq!(viridis(0.5), VIRIDIS[4]);
    assert_eq!(viridis(-3.0), VIRIDIS[0]);
    assert_eq!(viridis(f32::NAN), MISSING);
}

#[test]
fn scales_round_up_to_readable_ends() {
    assert_eq!(round_up(0.37), 0.5);
    assert_eq!(round_up(1.0), 1.0);
    assert_eq!(round_up(1.2), 2.0);
    assert_eq!(round_up(7.0), 10.0);
    assert_eq!(round_up(0.0012), 0.002);
    let s = Scale::zero_to_max(&[0.1, f32::NAN, 0.3], 0.01, "mm");
    assert_eq!((s.lo, s.hi), (0.0, 0.5));
    assert_eq!(s.colour(0.0), VIRIDIS[0]);
    assert_eq!(s.colour(0.5), VIRIDIS[8]);
    assert_eq!(s.colour(f32::INFINITY), MISSING);
    // All zero: the floor keeps the scale open.
    assert_eq!(Scale::zero_to_max(&[0.0], 0.01, "mm").hi, 0.01);
}
