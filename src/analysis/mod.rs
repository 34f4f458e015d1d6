//! What a mesh tells about the volume it came from (Bade 2007, Moench 2012).

pub mod caps;
pub mod grid_frame;
pub mod stack_axis;
pub mod voxel_size;

pub use caps::{
    cap_candidates, detect_caps, Cap, CapCandidates, CapDetection, CapEvidence, CapLook, CapParams,
    CapSearch,
};
pub use grid_frame::{turned_grid, Grid};
pub use stack_axis::{stack_axis, stack_axis_with, AxisEvidence, StackAxis, StackAxisParams};
pub use voxel_size::{coarse_axis, voxel_size, AxisSpacing, VoxelSizeEstimate};
