//! Tests of `src/weights/mod.rs`.

use destair::weights::*;

#[test]
fn validates_count_and_range() {
    assert!(VertexWeights::new(vec![0.0, 0.5, 1.0], 3).is_ok());
    assert!(VertexWeights::new(vec![0.0, 0.5], 3).is_err());
    assert!(VertexWeights::new(vec![0.0, 1.5, 1.0], 3).is_err());
    assert!(VertexWeights::new(vec![0.0, f32::NAN, 1.0], 3).is_err());
}
