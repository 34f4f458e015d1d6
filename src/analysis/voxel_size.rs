//! Voxel-size reconstruction from a marching-cubes mesh (Bade 2007, §3.2).
//!
//! Marching cubes on a binary volume puts every vertex at a grid-edge midpoint, so along each
//! axis the offset between two adjacent vertices is 0, h/2 or h (h = spacing). The paper stops at
//! the first two distinct non-zero offsets; that breaks on float noise and on edited meshes, so
//! here all edge offsets are clustered with a tolerance scaled to the coordinates' float
//! precision, and an axis is accepted only if two clusters in ratio 2 explain nearly all of them.

use crate::mesh::{Mesh, Topology};
use rayon::prelude::*;
use serde::Serialize;

/// Share of non-zero edge offsets the h/2 and h clusters must explain for a grid to be accepted.
pub(super) const MIN_EXPLAINED: f64 = 0.99;
/// Relative tolerance on the h : h/2 ratio of 2.
const RATIO_TOLERANCE: f64 = 0.01;

/// What the edge offsets along one axis say about the grid spacing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum AxisSpacing {
    /// Offsets are h/2 and h: the spacing is h (mm).
    Spacing { mm: f64 },
    /// Only one non-zero offset occurs, so it is h or h/2 and the spacing is ambiguous.
    OneStep { mm: f64 },
    /// No edge runs along this axis (a flat mesh).
    NoSteps,
    /// Offsets take many values: the mesh is not a marching-cubes surface on a grid aligned
    /// with this axis (rotated, resampled, decimated or already smoothed).
    Irregular {
        n_clusters: usize,
        share_explained: f64,
    },
}

/// Per-axis result of the voxel-size reconstruction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct VoxelSizeEstimate {
    pub axes: [AxisSpacing; 3],
}

impl VoxelSizeEstimate {
    /// Grid spacing (x, y, z) in mm when every axis was reconstructed unambiguously.
    pub fn spacing(&self) -> Option<[f64; 3]> {
        let mut out = [0.0; 3];
        for (k, axis) in self.axes.iter().enumerate() {
            match axis {
                AxisSpacing::Spacing { mm } => out[k] = *mm,
                _ => return None,
            }
        }
        Some(out)
    }

    /// Bounds (smallest, largest; mm) on the spacing along x, y and z when the mesh lies on an
    /// axis-aligned grid: exact where both offsets occur, h or 2h where only one does. None
    /// when some axis is irregular or has no steps.
    pub fn spacing_bounds(&self) -> Option<[(f64, f64); 3]> {
        let mut out = [(0.0, 0.0); 3];
        for (k, axis) in self.axes.iter().enumerate() {
            out[k] = match *axis {
                AxisSpacing::Spacing { mm } => (mm, mm),
                AxisSpacing::OneStep { mm } => (mm, 2.0 * mm),
                _ => return None,
            };
        }
        Some(out)
    }

    /// True when some axis shows offsets that no axis-aligned grid produces.
    pub fn is_irregular(&self) -> bool {
        self.axes
            .iter()
            .any(|a| matches!(a, AxisSpacing::Irregular { .. }))
    }
}

/// Offsets (mm) below a few ulps of the largest coordinate magnitude `max_abs` (mm) are float
/// noise around 0.
pub fn zero_tolerance(max_abs: f64) -> f64 {
    8.0 * f32::EPSILON as f64 * max_abs.max(1e-6)
}

/// Distinct offsets counted per axis beyond which the axis is sorted instead (a mesh off any
/// grid has about as many distinct offsets as edges).
const MAX_DISTINCT: usize = 1 << 16;
/// Edges sampled (about) to see whether an axis's offsets are few enough to count.
const SAMPLE: usize = 1 << 15;
/// Vertices per parallel work item in passes over every edge (results do not depend on it).
const VERTEX_CHUNK: usize = 1 << 13;

/// Reconstructs the voxel size (mm per axis) of the grid a marching-cubes mesh came from.
/// A mesh on a grid has few distinct edge offsets, so they are counted in one pass over the
/// edges; an axis with too many to count (by a sample, or past 65,536) is sorted
/// whole. Both give the same clusters.
pub fn voxel_size(mesh: &Mesh, topology: &Topology) -> VoxelSizeEstimate {
    let p = mesh.positions();
    // The largest magnitude along each axis, in one parallel pass (`max` passes NaN over,
    // and the largest of a set does not depend on how it is split).
    let max_abs = p
        .par_iter()
        .with_min_len(VERTEX_CHUNK)
        .fold(
            || [0.0f32; 3],
            |m, q| std::array::from_fn(|k| m[k].max(q[k].abs())),
        )
        .reduce(
            || [0.0f32; 3],
            |a, b| std::array::from_fn(|k| a[k].max(b[k])),
        );
    let zero_tol: [f64; 3] = std::array::from_fn(|k| zero_tolerance(max_abs[k] as f64));
    let offset =
        |[a, b]: [u32; 2], k: usize| (p[a as usize][k] as f64 - p[b as usize][k] as f64).abs();
    let counted = count_offsets(topology, offset, zero_tol);
    let axes = std::array::from_fn(|k| match &counted[k] {
        Some(distinct) => clusters_spacing(distinct, zero_tol[k]),
        None => {
            let mut offsets: Vec<f64> = (0..topology.n_vertices())
                .into_par_iter()
                .with_min_len(VERTEX_CHUNK)
                .flat_map_iter(|v| {
                    (topology.larger_neighbors(v).iter())
                        .map(move |&u| offset([v as u32, u], k))
                        .filter(move |&d| d > zero_tol[k])
                })
                .collect();
            offsets.par_sort_unstable_by(f64::total_cmp);
            axis_spacing(&offsets, zero_tol[k])
        }
    });
    VoxelSizeEstimate { axes }
}

/// Per axis, the distinct edge offsets above `zero_tol` with how often each occurs, ascending;
/// `None` for an axis with more than [`MAX_DISTINCT`] of them. The edges are read from the
/// neighbour lists (each vertex's edges to larger neighbours), not listed.
fn count_offsets(
    topology: &Topology,
    offset: impl Fn([u32; 2], usize) -> f64 + Sync,
    zero_tol: [f64; 3],
) -> [Option<Vec<(f64, usize)>>; 3] {
    let n = topology.n_vertices();
    let edges_of = |v: usize| (topology.larger_neighbors(v).iter()).map(move |&u| [v as u32, u]);
    // A strided sample tells a mesh off any grid (nearly every sampled offset distinct) at
    // once, so it goes straight to sorting without filling maps first. A vertex owns about
    // three edges on a closed surface.
    let step = (3 * n / SAMPLE).max(1);
    let countable: [bool; 3] = std::array::from_fn(|k| {
        let mut bits: Vec<u64> = ((0..n).step_by(step))
            .flat_map(edges_of)
            .map(|e| offset(e, k).to_bits())
            .collect();
        bits.sort_unstable();
        bits.dedup();
        bits.len() <= SAMPLE / 2
    });
    type Counts = [Option<rustc_hash::FxHashMap<u64, usize>>; 3];
    let fresh = || -> Counts { countable.map(|c| c.then(Default::default)) };
    let chunks: Vec<std::ops::Range<usize>> = (0..n)
        .step_by(VERTEX_CHUNK)
        .map(|s| s..(s + VERTEX_CHUNK).min(n))
        .collect();
    let merged = chunks
        .into_par_iter()
        .fold(fresh, |mut counts, chunk| {
            // The first few distinct offsets of each axis are counted in a short list (a mesh
            // on a grid has few: no hashing per edge), the rest in the map.
            let mut few = [FewOffsets::default(); 3];
            for e in chunk.flat_map(edges_of) {
                for (k, (slot, few)) in counts.iter_mut().zip(&mut few).enumerate() {
                    let Some(map) = slot else { continue };
                    let d = offset(e, k);
                    if d > zero_tol[k] && !few.count(d.to_bits()) {
                        *map.entry(d.to_bits()).or_insert(0) += 1;
                    }
                }
            }
            for (slot, few) in counts.iter_mut().zip(&few) {
                let Some(map) = slot else { continue };
                for &(bits, n) in few.listed() {
                    *map.entry(bits).or_insert(0) += n;
                }
                if map.len() > MAX_DISTINCT {
                    *slot = None;
                }
            }
            counts
        })
        .reduce(fresh, |mut a, b| {
            for (slot, other) in a.iter_mut().zip(b) {
                *slot = match (slot.take(), other) {
                    (Some(mut x), Some(y)) => {
                        for (bits, n) in y {
                            *x.entry(bits).or_insert(0) += n;
                        }
                        (x.len() <= MAX_DISTINCT).then_some(x)
                    }
                    _ => None,
                };
            }
            a
        });
    merged.map(|slot| {
        slot.map(|map| {
            let mut distinct: Vec<(f64, usize)> = map
                .into_iter()
                .map(|(bits, n)| (f64::from_bits(bits), n))
                .collect();
            distinct.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            distinct
        })
    })
}

/// Up to eight distinct offsets (their bits) with how often each occurred.
#[derive(Debug, Clone, Copy, Default)]
struct FewOffsets {
    listed: [(u64, usize); 8],
    len: usize,
}

impl FewOffsets {
    /// Counts `bits` if it is listed or there is room to list it; false if it is not counted.
    fn count(&mut self, bits: u64) -> bool {
        if let Some(entry) = self.listed[..self.len].iter_mut().find(|e| e.0 == bits) {
            entry.1 += 1;
            return true;
        }
        if self.len < self.listed.len() {
            self.listed[self.len] = (bits, 1);
            self.len += 1;
            return true;
        }
        false
    }

    fn listed(&self) -> &[(u64, usize)] {
        &self.listed[..self.len]
    }
}

/// Classifies one axis from its sorted non-zero edge offsets.
pub fn axis_spacing(sorted: &[f64], zero_tol: f64) -> AxisSpacing {
    // Clusters of offsets equal up to float noise: (representative, count).
    let mut clusters: Vec<(f64, usize)> = Vec::new();
    let mut start = 0;
    for i in 1..=sorted.len() {
        let tol = (4.0 * zero_tol).max(1e-4 * sorted[start]);
        if i == sorted.len() || sorted[i] - sorted[start] > tol {
            clusters.push((sorted[(start + i) / 2], i - start));
            start = i;
        }
    }
    classify(clusters, sorted.len())
}

/// [`axis_spacing`] from the distinct offsets (ascending) with their counts: the same clusters,
/// each represented by its middle offset counted with repeats.
fn clusters_spacing(distinct: &[(f64, usize)], zero_tol: f64) -> AxisSpacing {
    let mut clusters: Vec<(f64, usize)> = Vec::new();
    let mut start = 0;
    for i in 1..=distinct.len() {
        let tol = (4.0 * zero_tol).max(1e-4 * distinct[start].0);
        if i == distinct.len() || distinct[i].0 - distinct[start].0 > tol {
            let members = &distinct[start..i];
            let count: usize = members.iter().map(|m| m.1).sum();
            let mut middle = count / 2;
            let mut representative = members[0].0;
            for &(v, n) in members {
                representative = v;
                if middle < n {
                    break;
                }
                middle -= n;
            }
            clusters.push((representative, count));
            start = i;
        }
    }
    classify(clusters, distinct.iter().map(|m| m.1).sum())
}

/// The spacing that clusters of offsets (representative mm, count; `total` offsets) show.
fn classify(mut clusters: Vec<(f64, usize)>, total: usize) -> AxisSpacing {
    if clusters.is_empty() {
        return AxisSpacing::NoSteps;
    }
    clusters.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.total_cmp(&b.0)));
    let total = total as f64;
    let top = clusters[0];
    let second = clusters.get(1).copied().unwrap_or((0.0, 0));
    let explained = (top.1 + second.1) as f64 / total;
    if explained < MIN_EXPLAINED {
        return AxisSpacing::Irregular {
            n_clusters: clusters.len(),
            share_explained: explained,
        };
    }
    if second.1 == 0 || (second.1 as f64) < (1.0 - MIN_EXPLAINED) * total {
        return AxisSpacing::OneStep { mm: top.0 };
    }
    let (small, large) = (top.0.min(second.0), top.0.max(second.0));
    if (large / small - 2.0).abs() <= 2.0 * RATIO_TOLERANCE {
        AxisSpacing::Spacing { mm: large }
    } else {
        AxisSpacing::Irregular {
            n_clusters: clusters.len(),
            share_explained: explained,
        }
    }
}

/// How much coarser than every other grid axis the slice axis must be (spacing ratio).
pub const COARSE_AXIS_RATIO: f64 = 1.25;

/// The grid axis (0 x, 1 y, 2 z) whose spacing is clearly the coarsest, at least
/// [`COARSE_AXIS_RATIO`] times any other for every spacing the bounds (mm) allow: the slice
/// axis of an anisotropic grid. None for a grid without one (isotropic, or two coarse axes).
pub fn coarse_axis(bounds: [(f64, f64); 3]) -> Option<usize> {
    (0..3).find(|&k| {
        (0..3)
            .filter(|&j| j != k)
            .all(|j| bounds[k].0 >= COARSE_AXIS_RATIO * bounds[j].1)
    })
}
