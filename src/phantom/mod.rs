//! Phantoms: label volumes from analytic shapes and their marching-cubes surfaces, with the
//! staircases, terraces and clipped ends of real segmentations (Bade 2007, Moench 2012).

pub mod marching_cubes;
pub mod volume;

pub use marching_cubes::{extract_surface, extract_surface_interpolated, BorderEnds};
pub use volume::{LabelVolume, Shape};
pub mod cases;
pub mod gaussian;

pub use cases::{big_case, cohort_case, named_case, write_case, PhantomCase, PhantomOptions};
