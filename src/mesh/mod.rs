//! The in-memory triangle mesh: flat `[f32; 3]` positions and `[u32; 3]` triangles.
//!
//! A `Mesh` is validated on construction (coordinates finite and within
//! [`MAX_COORDINATE_MM`], indices in range), so every algorithm downstream can index without
//! checks and compute lengths, areas and sums of coordinates without overflow. Topology is
//! built once, separately ([`Topology::build`]), because many callers (writers, converters)
//! never need it.

pub mod face_neighbours;
pub mod geometry;
pub mod manifold;
pub mod order;
pub mod topology;
pub mod umbrella;

pub use topology::Topology;

use crate::units::readable;
use std::sync::Arc;
use thiserror::Error;

/// Largest coordinate magnitude a mesh may hold (mm): 10 km. Squares and products of
/// coordinates (lengths, areas, normals, sums over neighbours) stay far inside f32's range
/// below it, while near f32's limit (3.4e38) one sum of two coordinates overflows. No surface
/// of a body or a specimen lies that far from its origin: beyond it is a corrupt file, or one
/// in other units.
pub const MAX_COORDINATE_MM: f32 = 1e7;

/// Whether `x` may be a mesh coordinate: finite and within +-[`MAX_COORDINATE_MM`].
#[inline]
pub fn is_valid_coordinate(x: f32) -> bool {
    x.abs() <= MAX_COORDINATE_MM
}

/// Why a set of positions and triangles is not a valid mesh.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MeshError {
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "triangle {triangle} refers to vertex {index}, but the mesh has {n_vertices} vertices"
    )]
    IndexOutOfRange {
        triangle: usize,
        index: u32,
        n_vertices: usize,
    },
    /// A vertex coordinate is NaN, infinite, or beyond +-[`MAX_COORDINATE_MM`].
    #[error("vertex {vertex} has a coordinate that is not a finite number within +-1e7 mm ({}, {}, {})", readable(f64::from(*x)), readable(f64::from(*y)), readable(f64::from(*z)))]
    NonFinite {
        vertex: usize,
        x: f32,
        y: f32,
        z: f32,
    },
    /// More vertices or triangles than 32-bit indices and CSR offsets can address.
    #[error("mesh too large: {n_vertices} vertices and {n_triangles} triangles (at most {max} of each, and 3 x triangles must fit in 32 bits)", max = u32::MAX)]
    TooLarge {
        n_vertices: usize,
        n_triangles: usize,
    },
}

/// A triangle mesh in millimetres. Vertex order is the file's order and is never changed,
/// so per-vertex outputs (weights, displacements) line up with the input file.
///
/// The triangles never change once a mesh is built, so copies of a mesh (a smoothed one, a
/// low-pass copy) share them instead of copying every face.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Mesh {
    positions: Vec<[f32; 3]>,
    triangles: Arc<Vec<[u32; 3]>>,
}

impl Mesh {
    /// Builds a mesh after checking every index and coordinate.
    pub fn new(positions: Vec<[f32; 3]>, triangles: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        check_size(positions.len(), triangles.len())?;
        if let Some(vertex) = positions
            .iter()
            .position(|p| !p.iter().all(|&x| is_valid_coordinate(x)))
        {
            let [x, y, z] = positions[vertex];
            return Err(MeshError::NonFinite { vertex, x, y, z });
        }
        let n = positions.len();
        for (triangle, t) in triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::IndexOutOfRange {
                    triangle,
                    index,
                    n_vertices: n,
                });
            }
        }
        Ok(Self {
            positions,
            triangles: Arc::new(triangles),
        })
    }

    /// Builds a mesh from parts the caller has already validated (readers check each index
    /// and coordinate while decoding, so checking again would cost a second pass).
    pub(crate) fn from_checked_parts(positions: Vec<[f32; 3]>, triangles: Vec<[u32; 3]>) -> Self {
        debug_assert!(Mesh::new(positions.clone(), triangles.clone()).is_ok());
        Self {
            positions,
            triangles: Arc::new(triangles),
        }
    }

    /// A mesh of checked positions and faces shared with another mesh (no copy of the faces).
    pub(crate) fn from_shared_parts(
        positions: Vec<[f32; 3]>,
        triangles: Arc<Vec<[u32; 3]>>,
    ) -> Self {
        debug_assert!(Mesh::new(positions.clone(), triangles.to_vec()).is_ok());
        Self {
            positions,
            triangles,
        }
    }

    /// The faces, shared (no copy), for a mesh built from the same faces later.
    pub(crate) fn shared_triangles(&self) -> Arc<Vec<[u32; 3]>> {
        Arc::clone(&self.triangles)
    }

    /// The same faces with other positions (one per vertex, valid coordinates, as the caller
    /// has made sure): the faces are shared, not copied.
    pub(crate) fn with_checked_positions(&self, positions: Vec<[f32; 3]>) -> Mesh {
        debug_assert_eq!(positions.len(), self.positions.len());
        debug_assert!(positions.iter().flatten().all(|&x| is_valid_coordinate(x)));
        Self {
            positions,
            triangles: Arc::clone(&self.triangles),
        }
    }

    /// The faces `faces` as a mesh of their own: only the vertices they use, numbered in order
    /// of first use (a patch of a surface, or a mesh without unreferenced vertices).
    pub fn select_faces(&self, faces: &[u32]) -> Mesh {
        let mut map = vec![u32::MAX; self.positions.len()];
        let mut positions = Vec::new();
        let triangles = faces
            .iter()
            .map(|&f| {
                self.triangles[f as usize].map(|v| {
                    if map[v as usize] == u32::MAX {
                        map[v as usize] = positions.len() as u32;
                        positions.push(self.positions[v as usize]);
                    }
                    map[v as usize]
                })
            })
            .collect();
        Mesh {
            positions,
            triangles: Arc::new(triangles),
        }
    }

    /// Vertex positions in mm, in file order.
    pub fn positions(&self) -> &[[f32; 3]] {
        &self.positions
    }

    /// Mutable positions for smoothers; indices stay valid whatever is written here.
    pub fn positions_mut(&mut self) -> &mut [[f32; 3]] {
        &mut self.positions
    }

    /// Triangles as vertex indices, counter-clockwise seen from outside for oriented meshes.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Number of vertices, including unreferenced ones.
    pub fn n_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn n_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// Takes the mesh apart into its positions and triangles (copied if another mesh shares
    /// them).
    pub fn into_parts(self) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let triangles = Arc::try_unwrap(self.triangles).unwrap_or_else(|shared| (*shared).clone());
        (self.positions, triangles)
    }
}

/// Checks that counts fit the 32-bit indices and CSR offsets used throughout.
pub(crate) fn check_size(n_vertices: usize, n_triangles: usize) -> Result<(), MeshError> {
    if n_vertices > u32::MAX as usize || n_triangles.saturating_mul(3) > u32::MAX as usize {
        return Err(MeshError::TooLarge {
            n_vertices,
            n_triangles,
        });
    }
    Ok(())
}
