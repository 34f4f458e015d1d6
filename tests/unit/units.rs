//! Tests of `src/units.rs`.

use destair::units::readable;

#[test]
fn numbers_stay_short() {
    assert_eq!(readable(1e300), "1.000e300");
    assert_eq!(readable(0.5), "0.5");
    assert_eq!(readable(-0.53), "-0.53");
    assert_eq!(readable(3.0), "3");
    assert_eq!(readable(30.667575), "30.6676");
    assert_eq!(readable(0.0), "0");
    assert_eq!(readable(1e-7), "1.000e-7");
    assert_eq!(readable(f64::NAN), "NaN");
    assert_eq!(readable(f32::MAX as f64), "3.403e38");
}
