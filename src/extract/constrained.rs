//! Constrained smoothing of label weights (thesis §6.3.2): each label's indicator (1 on its
//! voxels, 0 elsewhere) is smoothed with a discrete Gaussian and then clamped, so that a voxel
//! of the label keeps a weight above 1/2 and every other voxel stays below it. Every voxel
//! therefore keeps its own label as the largest weight, and the surfaces where the two largest
//! interpolated weights are equal still separate every pair of differently labelled voxel
//! centres; they only move to sub-voxel positions, which makes them smooth. The chapter's two
//! refinements run on top: lone pinned voxels ("pimples", §6.3.3, [`super::noise`]) get their
//! constraint relaxed, and voxels where a label is one voxel thick (§6.3.4, [`super::thin`])
//! get the strongest one, so thin sheets and tubes keep a real thickness.
//!
//! The surfaces keep the topology of the consistent extraction ([`super::interfaces`]): each
//! vertex on a cell edge moves along that edge to where the two labels' interpolated weights
//! tie (strictly between the two voxel centres, thanks to the clamp), branching points on cell
//! faces go to the mean of the face's edge vertices next to them, and the branching point inside
//! a cell to the mean of its fan's rim. Weights are evaluated only at the voxels next to the
//! surface, so memory grows with the surface, not with the volume.

use super::noise::Pinned;
use super::{Interfaces, VERTEX_APEX, VERTEX_EDGE, VERTEX_FACE};
use crate::volume::LabelVolume;
use rayon::prelude::*;
use serde::Serialize;

/// Half-width of the discrete kernel in voxels along each axis: 5 x 5 x 5 taps, as the thesis
/// uses.
const RADIUS: i64 = 2;

/// Fewest thin voxels of a label within the kernel's reach for a thin voxel to be protected
/// (fewer are a one- or two-voxel bump: surface noise).
const MIN_THIN_PART: usize = 3;

/// Below this smoothed weight a thin voxel is held at full weight (rods, walls and sheets one
/// voxel thick fall to 0.05-0.3; the rim of a thick slice stays near 1/2).
const THIN_BELOW: f32 = 0.35;

/// How far from 1/2 the clamp keeps weights: surfaces stay a little off voxel centres (at 0,
/// one-voxel-thin parts would collapse onto them).
pub const MARGIN: f32 = 0.02;

/// How a label's surface is made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Surface {
    /// Vertices at cell-edge midpoints: the plain consistent extraction (terraced).
    Binary,
    /// Label weights smoothed and clamped (§6.3): smooth, every voxel keeps its label.
    Constrained,
}

/// What constrained smoothing does with one- and two-voxel bumps and pits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Noise {
    /// Relax their constraint so they become gentle swellings (§6.3.3).
    Smooth,
    /// Keep them as pinned as every other voxel.
    Keep,
}

/// What constrained smoothing does where a label is one voxel thick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Thin {
    /// Fix the weights there to full (§6.3.4), so the part keeps a real thickness.
    Protect,
    /// Treat them like any voxel (thin parts shrink onto their voxel centres).
    Off,
}

impl Surface {
    /// The config word.
    pub fn name(self) -> &'static str {
        match self {
            Surface::Binary => "binary",
            Surface::Constrained => "constrained",
        }
    }
}

impl Noise {
    /// The config word.
    pub fn name(self) -> &'static str {
        match self {
            Noise::Smooth => "smooth",
            Noise::Keep => "keep",
        }
    }
}

impl Thin {
    /// The config word.
    pub fn name(self) -> &'static str {
        match self {
            Thin::Protect => "protect",
            Thin::Off => "off",
        }
    }
}

/// How one label is extracted; the defaults are the chapter's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LabelSmoothing {
    pub surface: Surface,
    /// Gaussian sigma (mm); `None` is twice the volume's smallest voxel spacing.
    pub sigma_mm: Option<f64>,
    pub noise: Noise,
    pub thin: Thin,
    /// Which of the label's voxels form one object (26: also across edges and corners).
    pub connectivity: super::Connectivity,
}

impl Default for LabelSmoothing {
    fn default() -> LabelSmoothing {
        LabelSmoothing {
            surface: Surface::Constrained,
            sigma_mm: None,
            noise: Noise::Smooth,
            thin: Thin::Protect,
            connectivity: super::Connectivity::Corners,
        }
    }
}

impl LabelSmoothing {
    /// The plain consistent extraction.
    pub fn binary() -> LabelSmoothing {
        LabelSmoothing {
            surface: Surface::Binary,
            ..LabelSmoothing::default()
        }
    }

    /// The sigma used on `volume` (mm).
    pub fn sigma_on(&self, volume: &LabelVolume) -> f64 {
        self.sigma_mm.unwrap_or_else(|| default_sigma_mm(volume))
    }
}

/// Each label's connectivity from its extraction settings (for [`super::interfaces`]).
pub fn connectivity_of(smoothing: &[LabelSmoothing]) -> Vec<super::Connectivity> {
    smoothing.iter().map(|s| s.connectivity).collect()
}

/// The chapter's sigma: twice the smallest voxel spacing (mm).
pub fn default_sigma_mm(volume: &LabelVolume) -> f64 {
    let s = volume.grid.spacing();
    2.0 * s[0].min(s[1]).min(s[2])
}

/// Largest sigma accepted, in smallest voxel spacings: the default. The kernel's 5 taps reach
/// 2 voxels along each axis; beyond 2 voxels along the finest one the Gaussian is cut short
/// into a box, and surfaces get rougher, not smoother (0.8 x 0.8 x 2.5 mm: a 12 mm sphere
/// 6.0 degrees at 1.6 mm, 9.7 at 3.2, 12.9 at 10; a 3 mm tube 16.1, 21.1, 21.3).
pub const MAX_SIGMA_SPACINGS: f64 = 2.0;

/// Refuses a sigma beyond [`MAX_SIGMA_SPACINGS`] of `volume`'s smallest spacing, naming the
/// range that makes sense there.
pub fn check_sigma(sigma_mm: f64, volume: &LabelVolume) -> Result<(), String> {
    let s = volume.grid.spacing();
    let finest = s[0].min(s[1]).min(s[2]);
    let most = MAX_SIGMA_SPACINGS * finest;
    if sigma_mm > most * (1.0 + 1e-9) {
        return Err(format!(
            "sigma_mm = {} is more than {} mm, twice this map's smallest voxel spacing ({} mm): the 5 x 5 x 5 kernel would cut the Gaussian short and make the surface rougher, not smoother; use a sigma up to {} mm (the default), less for less smoothing",
            crate::units::readable(sigma_mm),
            crate::units::readable(most),
            crate::units::readable(finest),
            crate::units::readable(most)
        ));
    }
    Ok(())
}

/// What the refinements did to one label.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct LabelCounts {
    /// Voxels relaxed as surface noise (bumps of the label and pits in it).
    pub noise_voxels: u64,
    /// Noise voxels left pinned: their group of near noise voxels was too large to solve.
    pub noise_unsolved: u64,
    /// Voxels of the label found one voxel thick and held at full weight.
    pub thin_voxels: u64,
}

/// The 5 taps of the Gaussian along each axis, normalised (per-axis sigma in voxels from the
/// spacing).
fn kernel(volume: &LabelVolume, sigma_mm: f64) -> [[f32; 5]; 3] {
    let s = volume.grid.spacing();
    std::array::from_fn(|axis| {
        let sigma = (sigma_mm / s[axis]).max(1e-6);
        let mut taps: [f64; 5] =
            std::array::from_fn(|d| (-((d as f64 - 2.0) / sigma).powi(2) / 2.0).exp());
        let sum: f64 = taps.iter().sum();
        for t in &mut taps {
            *t /= sum;
        }
        taps.map(|t| t as f32)
    })
}

/// The dense label at voxel `p`; background outside the volume.
fn label_at(volume: &LabelVolume, p: [i64; 3]) -> u16 {
    let [nx, ny, nz] = volume.dims.map(|d| d as i64);
    if p.iter().any(|&x| x < 0) || p[0] >= nx || p[1] >= ny || p[2] >= nz {
        0
    } else {
        volume.voxels[(p[0] + nx * (p[1] + ny * p[2])) as usize]
    }
}

/// The smoothed (unclamped) weights of dense labels `a` and `b`, each with its own kernel, at
/// voxel `v`, in one pass over the kernel (voxels outside the volume are background).
fn weights(
    volume: &LabelVolume,
    [ga, gb]: [&[[f32; 5]; 3]; 2],
    [a, b]: [u16; 2],
    v: [i64; 3],
) -> [f32; 2] {
    let [nx, ny, nz] = volume.dims.map(|d| d as i64);
    let inside = (0..3).all(|k| v[k] >= RADIUS && v[k] + RADIUS < [nx, ny, nz][k]);
    let mut w = [0f32; 2];
    for dz in -RADIUS..=RADIUS {
        let i = (dz + RADIUS) as usize;
        let (za, zb) = (ga[2][i], gb[2][i]);
        for dy in -RADIUS..=RADIUS {
            let j = (dy + RADIUS) as usize;
            let (yza, yzb) = (za * ga[1][j], zb * gb[1][j]);
            let (y, z) = (v[1] + dy, v[2] + dz);
            if inside {
                // The whole row lies in the volume: no bounds to check.
                let start = (v[0] - RADIUS + nx * (y + ny * z)) as usize;
                let row = &volume.voxels[start..start + 5];
                for ((xa, xb), &l) in ga[0].iter().zip(&gb[0]).zip(row) {
                    w[0] += if l == a { yza * xa } else { 0.0 };
                    w[1] += if l == b { yzb * xb } else { 0.0 };
                }
                continue;
            }
            for dx in -RADIUS..=RADIUS {
                let l = label_at(volume, [v[0] + dx, y, z]);
                let k = (dx + RADIUS) as usize;
                w[0] += if l == a { yza * ga[0][k] } else { 0.0 };
                w[1] += if l == b { yzb * gb[0][k] } else { 0.0 };
            }
        }
    }
    w
}

/// The cell edge an edge vertex lies on: its axis and lower voxel (the position is a whole
/// number along the other two axes).
fn edge_of(p: &[f64; 3]) -> Option<(usize, [i64; 3])> {
    let axis = (0..3).find(|&a| p[a].fract() != 0.0)?;
    Some((axis, std::array::from_fn(|a| p[a].floor() as i64)))
}

/// Moves the vertices of `all` (extracted from `volume`) to where the two largest constrained
/// weights tie: edge vertices along their edges, then face and cell branching points to the
/// means of their neighbours. Positions stay in voxel index coordinates. `smoothing[l]` is how
/// dense label `l` is extracted (entry 0 is the background; missing entries take the
/// defaults); an interface with a binary label on either side stays binary. Returns what the
/// refinements did, per dense label.
pub fn place_on_weights(
    volume: &LabelVolume,
    all: &mut Interfaces,
    smoothing: &[LabelSmoothing],
) -> Vec<LabelCounts> {
    let n_labels = volume.labels.len() + 1;
    let per: Vec<LabelSmoothing> = (0..n_labels)
        .map(|l| smoothing.get(l).copied().unwrap_or_default())
        .collect();
    let kernels: Vec<[[f32; 5]; 3]> = per
        .iter()
        .map(|s| kernel(volume, s.sigma_on(volume)))
        .collect();
    let smoothed = |l: u16| per[l as usize].surface == Surface::Constrained;
    if !(1..n_labels as u16).any(smoothed) {
        // All binary: the consistent extraction stays as it is.
        return vec![LabelCounts::default(); n_labels];
    }
    let relaxes = |l: u16| smoothed(l) && per[l as usize].noise == Noise::Smooth;
    let protects = |l: u16| l > 0 && smoothed(l) && per[l as usize].thin == Thin::Protect;
    let [nx, ny, _] = volume.dims.map(|d| d as u64);
    // Linear index of a voxel in the volume; `None` for the background outside it.
    let dims = volume.dims.map(|d| d as i64);
    let linear = |v: [i64; 3]| {
        ((0..3).all(|k| v[k] >= 0 && v[k] < dims[k]))
            .then(|| v[0] as u64 + nx * (v[1] as u64 + ny * v[2] as u64))
    };
    // The edge of an edge vertex between two smoothed labels: (axis, lo, hi, a, b).
    let edge = |p: &[f32; 3]| {
        let (axis, lo) = edge_of(&p.map(f64::from))?;
        let mut hi = lo;
        hi[axis] += 1;
        let (a, b) = (label_at(volume, lo), label_at(volume, hi));
        (a != b && smoothed(a) && smoothed(b)).then_some((axis, lo, hi, a, b))
    };

    // Pass 1: the smoothed weights at both ends of every edge between two smoothed labels.
    let kinds = &all.kinds;
    let samples: Vec<Option<[f32; 4]>> = all
        .positions
        .par_iter()
        .zip(kinds.par_iter())
        .map(|(p, &kind)| {
            let (_, lo, hi, a, b) = (kind == VERTEX_EDGE).then(|| edge(p)).flatten()?;
            let g = [&kernels[a as usize], &kernels[b as usize]];
            let [a_lo, b_lo] = weights(volume, g, [a, b], lo);
            let [a_hi, b_hi] = weights(volume, g, [a, b], hi);
            Some([a_lo, b_lo, a_hi, b_hi])
        })
        .collect();

    // Thin parts (§6.3.4): a voxel is held at full weight when its smoothed weight fell well
    // below 1/2 (the clamp alone would pin the surface onto its centre), it is thin by the
    // dual-grid opening, and at least three such voxels of its label lie within 2 voxels (a
    // lone one- or two-voxel bump is surface noise). The rim of a thick slice's widest contour
    // is thin by the opening too, but its weight stays near 1/2, so it smooths like any voxel.
    let mut low: Vec<(u16, u64)> = all
        .positions
        .par_iter()
        .zip(samples.par_iter())
        .flat_map_iter(|(p, w)| {
            let ends = w.and_then(|w| {
                let (_, lo, hi, a, b) = edge(p)?;
                Some([(w[0], lo, a), (w[3], hi, b)])
            });
            ends.into_iter().flatten().filter_map(|(own, v, l)| {
                (own < THIN_BELOW && protects(l)).then_some((l, linear(v)?))
            })
        })
        .collect();
    low.par_sort_unstable();
    low.dedup();
    let thin: Vec<(u16, u64)> = low
        .into_par_iter()
        .filter(|&(l, i)| super::thin::is_thin(volume, l, super::noise::coords(volume.dims, i)))
        .collect();
    let near = |l: u16, c: [i64; 3]| super::noise::in_box(&thin, |&e| e, volume.dims, l, c).count();
    let held: Vec<(u16, u64)> = thin
        .par_iter()
        .filter(|&&(l, i)| near(l, super::noise::coords(volume.dims, i)) >= MIN_THIN_PART)
        .copied()
        .collect();
    let is_held = |own_weight: f32, v: [i64; 3], l: u16| {
        own_weight < THIN_BELOW && linear(v).is_some_and(|i| held.binary_search(&(l, i)).is_ok())
    };

    // Surface noise (§6.3.3): the voxels the clamp pins, where both labels relax noise.
    let pinned: Vec<Pinned> = all
        .positions
        .par_iter()
        .zip(samples.par_iter())
        .flat_map_iter(|(p, w)| {
            let mut pins = Vec::new();
            let Some((w, (_, lo, hi, a, b))) = w.zip(edge(p)) else {
                return pins;
            };
            if !(relaxes(a) && relaxes(b)) {
                return pins;
            }
            let hold = [is_held(w[0], lo, a), is_held(w[3], hi, b)];
            // lo holds a and hi holds b: a's weight must win at lo, b's at hi.
            for (voxel, label, w, own, h) in [
                (lo, a, w[0], true, hold[0]),
                (lo, b, w[1], false, hold[0]),
                (hi, b, w[3], true, hold[1]),
                (hi, a, w[2], false, hold[1]),
            ] {
                let wrong_side = (own && w < 0.5) || (!own && w > 0.5);
                if let (false, true, Some(index)) = (h, wrong_side, linear(voxel)) {
                    pins.push(Pinned {
                        voxel: index,
                        label,
                        raw: w,
                    });
                }
            }
            pins
        })
        .collect();
    let relaxation = super::noise::relax(volume.dims, &kernels, pinned, n_labels);

    // Pass 2: offsets, thin protection and the clamp; then the tie along the edge.
    let margin = MARGIN;
    all.positions
        .par_iter_mut()
        .zip(samples.par_iter())
        .for_each(|(p, sample)| {
            let Some((raw, (axis, lo, hi, a, b))) = sample.zip(edge(p)) else {
                return;
            };
            let mut w = raw;
            if !relaxation.is_empty() {
                // Offsets live inside the volume only.
                if let Some(v) = linear(lo) {
                    let row = (v / nx) as usize;
                    w[0] += relaxation.delta(v, row, a);
                    w[1] += relaxation.delta(v, row, b);
                }
                if let Some(v) = linear(hi) {
                    let row = (v / nx) as usize;
                    w[2] += relaxation.delta(v, row, a);
                    w[3] += relaxation.delta(v, row, b);
                }
            }
            // A held thin voxel keeps its label fully (decided on the weights before offsets,
            // as when pinning).
            if is_held(raw[0], lo, a) {
                (w[0], w[1]) = (1.0, 0.0);
            }
            if is_held(raw[3], hi, b) {
                (w[2], w[3]) = (0.0, 1.0);
            }
            // d = w_a - w_b: positive at lo and negative at hi after the clamp.
            let d_lo = w[0].max(0.5 + margin) - w[1].min(0.5 - margin);
            let d_hi = w[2].min(0.5 - margin) - w[3].max(0.5 + margin);
            let denominator = d_lo - d_hi;
            if denominator > 0.0 && d_lo >= 0.0 {
                let t = (d_lo / denominator).clamp(0.0, 1.0) as f64;
                p[axis] = (lo[axis] as f64 + t) as f32;
            }
        });
    drop(samples);
    // Branching points: the mean of their neighbours (edge vertices on the same face for face
    // points; the whole rim for cell points), faces first. Their neighbours as CSR, counted,
    // then filled, in triangle order.
    let kinds = &all.kinds;
    let each_link = |f: &mut dyn FnMut(u32, u32)| {
        for (tri, &apex) in all.triangles.iter().zip(&all.outer_apex) {
            let mut link = |a: u32, b: u32| {
                if kinds[a as usize] != VERTEX_EDGE {
                    f(a, b);
                }
            };
            for (x, y) in [(0, 1), (1, 2), (2, 0)] {
                link(tri[x], tri[y]);
                link(tri[y], tri[x]);
            }
            if apex != tri[2] {
                for &v in &[tri[0], tri[1]] {
                    link(apex, v);
                    link(v, apex);
                }
            }
        }
    };
    let mut start = vec![0u32; all.positions.len() + 1];
    each_link(&mut |a, _| start[a as usize + 1] += 1);
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut list = vec![0u32; start[all.positions.len()] as usize];
    let mut fill = start.clone();
    each_link(&mut |a, b| {
        list[fill[a as usize] as usize] = b;
        fill[a as usize] += 1;
    });
    drop(fill);
    let groups: Vec<(usize, &[u32])> = (0..all.positions.len())
        .filter(|&v| start[v + 1] > start[v])
        .map(|v| (v, &list[start[v] as usize..start[v + 1] as usize]))
        .collect();
    for kind in [VERTEX_FACE, VERTEX_APEX] {
        let updates: Vec<(usize, [f64; 3])> = groups
            .par_iter()
            .filter(|(v, _)| all.kinds[*v] == kind)
            .filter_map(|&(v, neighbours)| {
                let own = all.positions[v].map(f64::from);
                // A face point's face: the axis along which it sits on a whole number.
                let normal = (0..3).find(|&a| own[a].fract() == 0.0);
                let mut count = 0;
                let mut sum = [0.0; 3];
                for (i, &n) in neighbours.iter().enumerate() {
                    if neighbours[..i].contains(&n) {
                        continue;
                    }
                    let q = all.positions[n as usize].map(f64::from);
                    let on_face = match (kind, normal) {
                        (VERTEX_FACE, Some(a)) => {
                            all.kinds[n as usize] == VERTEX_EDGE && q[a] == own[a]
                        }
                        (VERTEX_FACE, None) => false,
                        _ => true,
                    };
                    if on_face {
                        count += 1;
                        for c in 0..3 {
                            sum[c] += q[c];
                        }
                    }
                }
                (count > 0).then(|| (v, sum.map(|x| x / count as f64)))
            })
            .collect();
        for (v, p) in updates {
            all.positions[v] = p.map(|x| x as f32);
        }
    }
    (0..n_labels)
        .map(|l| LabelCounts {
            noise_voxels: relaxation.relaxed_per_label[l],
            noise_unsolved: relaxation.unsolved_per_label[l],
            thin_voxels: held.iter().filter(|(h, _)| *h as usize == l).count() as u64,
        })
        .collect()
}
