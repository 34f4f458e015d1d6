//! The papers' evaluation measures (Moench 2010/2012, Bade 2007): surface distances,
//! enclosed volume, normal curvature, distances to reference structures, displacement and
//! triangle quality.

pub mod distance;
pub mod normal_curvature;
pub mod quality;
pub mod volume;

pub use distance::{hausdorff_distance, minimum_distance, surface_distance, SurfaceDistance};
pub use normal_curvature::{
    average_normal_curvature, vertex_normal_curvature, vertex_normal_turn, NormalTurn,
};
pub use quality::{displacement_stats, displacements, min_triangle_angle, DisplacementStats};
pub use volume::{enclosed_volume, EnclosedVolume};

/// Whether the angle of the direction (`cos_a`, `sin_a`) is wider than that of (`cos_b`,
/// `sin_b`), sines >= 0 (angles in [0, 180] degrees), without the arctangents: the sign of the
/// 2-D cross product decides, and only when it is within rounding of zero (a tie, or a zero
/// vector) are the arctangents compared. It never says the opposite of comparing
/// `sin.atan2(cos)` of each, so a widest or narrowest pick has the arctangents' own value.
#[inline]
pub fn wider_angle(sin_a: f64, cos_a: f64, sin_b: f64, cos_b: f64) -> bool {
    let (x, y) = (sin_a * cos_b, cos_a * sin_b);
    if (x - y).abs() > 1e-12 * (x.abs() + y.abs()) {
        x > y
    } else if sin_a.to_bits() == sin_b.to_bits() && cos_a.to_bits() == cos_b.to_bits() {
        // The same pair (faces of one plane), so the same arctangent: neither is wider.
        false
    } else {
        sin_a.atan2(cos_a) > sin_b.atan2(cos_b)
    }
}
