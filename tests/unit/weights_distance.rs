//! Tests of `src/weights/distance.rs`.

use destair::weights::distance::*;

#[test]
fn scalings_by_hand() {
    let d = [1.0, 2.0, 3.0, 5.0];
    assert_eq!(
        distance_weights(&d, DistanceScaling::Linear).as_slice(),
        &[0.0, 0.25, 0.5, 1.0]
    );
    assert_eq!(
        distance_weights(&d, DistanceScaling::SafetyMargin { margin_mm: 2.0 }).as_slice(),
        &[0.0, 0.0, 1.0 / 3.0, 1.0]
    );
    let e = distance_weights(&d, DistanceScaling::Exponential { k: 3.0 });
    let expect = ((3.0f64 * 0.25).exp() - 1.0) / (3f64.exp() - 1.0);
    assert!((e.as_slice()[1] as f64 - expect).abs() < 1e-6);
    assert_eq!(e.as_slice()[0], 0.0);
    assert_eq!(e.as_slice()[3], 1.0);
    assert_eq!(
        distance_weights(
            &d,
            DistanceScaling::Ramp {
                d0_mm: 1.5,
                d1_mm: 3.5
            }
        )
        .as_slice(),
        &[0.0, 0.25, 0.75, 1.0]
    );
    assert_eq!(
        distance_weights(&[f64::INFINITY; 2], DistanceScaling::Linear).as_slice(),
        &[1.0, 1.0]
    );
}
