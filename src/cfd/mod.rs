//! The cfd profile: what a flow solver's mesher needs from a smoothed vessel surface. So far
//! its boundary patches (inlet, outlets, wall), open ends closed by flat caps, the exact checks
//! a surface passes before hand-over, and the files solvers' meshers take (multi-solid STL,
//! VTP with `CellEntityIds`, the patch table), flow extensions. Remeshing is
//! [`crate::remesh`].

pub mod checks;
pub mod close;
pub mod extend;
pub mod outputs;
pub mod patches;
pub mod profile;
pub mod rims;

pub use checks::{check_surface, SurfaceChecks};
pub use close::{close_open_ends, CloseError};
pub use extend::{add_flow_extensions, ExtendError};
pub use outputs::{encode_patch_files, write_patch_files};
pub use patches::{
    find_patches, remeasure_patches, Inlet, Patch, PatchError, PatchKind, Patches, WALL_ID,
};
pub use profile::{
    finish_surface, patch_vertices, prepare_surface, CfdError, CfdOptions, CfdParams, CfdProfile,
    CfdSurface, PreparedSurface, RemeshSummary,
};
