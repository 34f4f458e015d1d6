//! Distance-aware weights (Moench et al. 2010, IWDE): each vertex's exact minimum distance to the
//! surfaces of the structure's reference structures, scaled to [0, 1] so vertices close to a
//! neighbour barely move and distant ones are smoothed fully.

use super::VertexWeights;
use crate::mesh::Mesh;
use crate::spatial::TriangleBvh;
use serde::{Deserialize, Serialize};

/// How a distance becomes a weight.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "scaling", rename_all = "snake_case")]
pub enum DistanceScaling {
    /// Closest vertex 0, farthest 1, linear in between (the paper's default).
    Linear,
    /// 0 within `margin_mm`, then linear up to 1 at the farthest vertex (surgical safety margin).
    SafetyMargin { margin_mm: f32 },
    /// The linear value b mapped by (e^{k b} - 1) / (e^k - 1) (paper: k = 3), a soft margin.
    Exponential { k: f32 },
    /// Absolute ramp: 0 below `d0_mm`, 1 above `d1_mm`; means the same in every case of a cohort.
    Ramp { d0_mm: f32, d1_mm: f32 },
}

impl std::str::FromStr for DistanceScaling {
    type Err = String;

    /// Parses `linear`, `margin:MM`, `exp:K` or `ramp:D0,D1` (mm).
    fn from_str(s: &str) -> Result<Self, String> {
        let number = |x: &str| {
            x.trim()
                .parse::<f32>()
                .ok()
                .filter(|v| v.is_finite() && *v >= 0.0)
        };
        let bad = || format!("expected linear, margin:MM, exp:K or ramp:D0,D1, got {s:?}");
        match s.split_once(':') {
            None if s == "linear" => Ok(DistanceScaling::Linear),
            Some(("margin", m)) => Ok(DistanceScaling::SafetyMargin {
                margin_mm: number(m).ok_or_else(bad)?,
            }),
            // k = 0 is 0/0 and |k| beyond 50 overflows e^k in f32.
            Some(("exp", k)) => Ok(DistanceScaling::Exponential {
                k: k.trim()
                    .parse::<f32>()
                    .ok()
                    .filter(|v| v.is_finite() && *v != 0.0 && v.abs() <= 50.0)
                    .ok_or_else(|| format!("exp:K needs 0 < |K| <= 50, got {s:?}"))?,
            }),
            Some(("ramp", r)) => {
                let (a, b) = r.split_once(',').ok_or_else(bad)?;
                let (d0_mm, d1_mm) = (number(a).ok_or_else(bad)?, number(b).ok_or_else(bad)?);
                if d1_mm <= d0_mm {
                    return Err(format!("ramp needs D0 < D1, got {s:?}"));
                }
                Ok(DistanceScaling::Ramp { d0_mm, d1_mm })
            }
            _ => Err(bad()),
        }
    }
}

/// Minimum distance (mm) from each vertex of `mesh` to the nearest of the reference surfaces.
pub fn reference_distances(mesh: &Mesh, references: &[&TriangleBvh]) -> Vec<f64> {
    let mut best = vec![f64::INFINITY; mesh.n_vertices()];
    for tree in references {
        for (b, d) in best.iter_mut().zip(tree.distances(mesh.positions())) {
            *b = b.min(d);
        }
    }
    best
}

/// Weights from distances to references, scaled as asked. Without references (or with all
/// distances infinite) every weight is 1.
pub fn distance_weights(distances: &[f64], scaling: DistanceScaling) -> VertexWeights {
    let finite = || distances.iter().copied().filter(|d| d.is_finite());
    let lo = finite().fold(f64::INFINITY, f64::min);
    let hi = finite().fold(f64::NEG_INFINITY, f64::max);
    let linear = |d: f64, from: f64| {
        if !d.is_finite() {
            1.0
        } else if hi > from {
            ((d - from) / (hi - from)).clamp(0.0, 1.0)
        } else {
            1.0
        }
    };
    let values = distances
        .iter()
        .map(|&d| {
            let w = match scaling {
                DistanceScaling::Linear => linear(d, lo),
                DistanceScaling::SafetyMargin { margin_mm } => {
                    if d <= margin_mm as f64 {
                        0.0
                    } else {
                        linear(d, (margin_mm as f64).max(lo))
                    }
                }
                DistanceScaling::Exponential { k } => {
                    let b = linear(d, lo);
                    let k = k as f64;
                    if k.abs() < 1e-9 {
                        b
                    } else {
                        ((k * b).exp() - 1.0) / (k.exp() - 1.0)
                    }
                }
                DistanceScaling::Ramp { d0_mm, d1_mm } => {
                    let (d0, d1) = (d0_mm as f64, d1_mm as f64);
                    if !d.is_finite() || d >= d1 {
                        1.0
                    } else if d <= d0 || d1 <= d0 {
                        0.0
                    } else {
                        (d - d0) / (d1 - d0)
                    }
                }
            };
            w.clamp(0.0, 1.0) as f32
        })
        .collect();
    VertexWeights::new(values, distances.len())
        .unwrap_or_else(|_| VertexWeights::uniform(distances.len()))
}
