//! The papers' evaluation measures (Moench 2010/2012, Bade 2007).

pub mod normal_curvature;

pub use normal_curvature::{average_normal_curvature, vertex_normal_curvature};
