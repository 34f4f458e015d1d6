//! PLY: header parsing, a fast fixed-stride binary decoder with a general row decoder behind
//! it, and a binary little-endian writer.

pub mod header;
pub mod read;
pub mod write;

pub use header::{ElementDef, Encoding, Header, PropertyDef, PropertyType, ScalarType};
pub use write::{encode_ply, write_ply, write_ply_with_faces};
