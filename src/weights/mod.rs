//! Per-vertex weights in [0, 1] that scale each smoother's displacement (Moench 2010, Eq. 4-5):
//! 0 keeps a vertex where it is, 1 lets it move as the smoother says.

pub mod context;
pub mod distance;
pub mod staircase;

pub use context::{context_weights, AxisChoice, AxisSource, CapPolicy, Context, ContextParams};
pub use distance::{distance_weights, reference_distances, DistanceScaling};
pub use staircase::{auto_tau, staircase_weights, StaircaseParams, StaircaseWeights, Tau};

use thiserror::Error;

/// One weight per vertex, each finite and in [0, 1].
#[derive(Debug, Clone, PartialEq)]
pub struct VertexWeights(Vec<f32>);

/// How two weightings are combined (Moench: staircase and distance weights multiply).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Combine {
    #[default]
    Product,
    Min,
}

/// Why a set of weights was rejected.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum WeightsError {
    #[error("{got} weights for a mesh with {expected} vertices")]
    Count { expected: usize, got: usize },
    #[error("weight of vertex {vertex} is {value}, outside [0, 1]")]
    OutOfRange { vertex: usize, value: f32 },
}

impl VertexWeights {
    /// Weight 1 everywhere: plain uniform smoothing.
    pub fn uniform(n_vertices: usize) -> Self {
        let mut ones = crate::hugepages::with_capacity(n_vertices);
        ones.resize(n_vertices, 1.0);
        Self(ones)
    }

    /// Checks count and range.
    pub fn new(values: Vec<f32>, n_vertices: usize) -> Result<Self, WeightsError> {
        if values.len() != n_vertices {
            return Err(WeightsError::Count {
                expected: n_vertices,
                got: values.len(),
            });
        }
        if let Some(vertex) = values.iter().position(|w| !(0.0..=1.0).contains(w)) {
            return Err(WeightsError::OutOfRange {
                vertex,
                value: values[vertex],
            });
        }
        Ok(Self(values))
    }

    /// The weights, indexed by vertex.
    pub fn as_slice(&self) -> &[f32] {
        &self.0
    }

    /// Combines two weightings vertex by vertex.
    pub fn combine(&self, other: &VertexWeights, how: Combine) -> VertexWeights {
        let values = self
            .0
            .iter()
            .zip(&other.0)
            .map(|(&a, &b)| match how {
                Combine::Product => a * b,
                Combine::Min => a.min(b),
            })
            .collect();
        VertexWeights(values)
    }

    /// Sets the weight of the given vertices to 0 (e.g. preserved caps).
    pub fn zero(&mut self, vertices: impl IntoIterator<Item = u32>) {
        for v in vertices {
            if let Some(w) = self.0.get_mut(v as usize) {
                *w = 0.0;
            }
        }
    }

    /// The weights of a mesh renumbered by `order`, in the mesh's own numbering.
    pub fn scattered(&self, order: &crate::mesh::order::Renumbering) -> VertexWeights {
        VertexWeights(order.scatter(&self.0))
    }

    /// The weights in the numbering `order` gives (the inverse of [`VertexWeights::scattered`]).
    pub fn gathered(&self, order: &crate::mesh::order::Renumbering) -> VertexWeights {
        VertexWeights(order.gather(&self.0))
    }

    /// The weights as a plain vector.
    pub fn into_inner(self) -> Vec<f32> {
        self.0
    }
}
