//! The cohort runner: configuration, plan, discovery, sharding, per-case processing, the
//! streaming pipeline, resume manifests and the cohort summary.

pub mod case;
pub mod config;
pub mod discover;
mod guard;
pub mod index_page;
pub mod label_map;
pub mod load;
pub mod lock;
pub mod memory;
pub mod outputs;
pub mod paths;
mod pictures;
pub mod pipeline;
pub mod plan;
pub mod review;
pub mod settings;
pub mod summary;

pub use config::{Config, ConfigError};
pub use discover::{discover, CaseInput, Discovery, Shard};
pub use lock::{LockError, LockMode, LockScope, OutputLock, Wait};
pub use plan::{Plan, StructureSettings};
