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
