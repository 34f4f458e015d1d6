//! The cfd profile: what a flow solver's mesher needs from a smoothed vessel surface. So far
//! its boundary patches (inlet, outlets, wall) and open ends closed by flat caps; flow
//! extensions, remeshing, checks and the solver-ready outputs follow.

pub mod close;
pub mod patches;

pub use close::{close_open_ends, CloseError};
pub use patches::{find_patches, Inlet, Patch, PatchError, PatchKind, Patches, WALL_ID};
