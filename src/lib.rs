//! destair: removes staircase and terrace artifacts from medical surface meshes in bulk, while
//! keeping inter-structure distances, flat caps, volume and artifact-free surface in place.
//!
//! See ARCHITECTURE.md for the map of modules; each module is one concept.

pub mod analysis;
pub mod cfd;
pub mod extract;
pub mod guard;
pub mod hugepages;
pub mod io;
pub mod job;
pub mod mesh;
pub mod metrics;
pub mod parallel;
pub mod phantom;
pub mod remesh;
pub mod render;
pub mod report;
pub mod smooth;
pub mod spatial;
pub mod units;
pub mod volume;
pub mod weights;

pub use mesh::{Mesh, Topology};
pub mod bench;
