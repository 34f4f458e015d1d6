//! What a mesh tells about the volume it came from (Bade 2007, Moench 2012).

pub mod voxel_size;

pub use voxel_size::{voxel_size, AxisSpacing, VoxelSizeEstimate};
