//! Constrained smoothing of label weights (thesis §6.3.2): each label's indicator (1 on its
//! voxels, 0 elsewhere) is smoothed and then clamped, so that a voxel
//! of the label keeps a weight above 1/2 and every other voxel stays below it. Every voxel
//! therefore keeps its own label as the largest weight, and the surfaces where the two largest
//! interpolated weights are equal still separate every pair of differently labelled voxel
//! centres; they only move to sub-voxel positions, which makes them smooth. The chapter's two
//! refinements run on top: lone pinned voxels ("pimples", §6.3.3, [`super::noise`]) get their
//! constraint relaxed, and where a label is thin (§6.3.4) the smoothing narrows so thin sheets
//! and tubes keep a real thickness.
//!
//! Two departures from the chapter keep each label's size (issue 62): the smoothing kernel is
//! shrink-free ([`super::kernel`]), `2 g - g * g` for the chapter's 5-tap Gaussian `g` (a
//! Gaussian alone moves convex surfaces inwards by about sigma² times their mean curvature),
//! and along each axis the Gaussian is at most [`THICKNESS_FRACTION`] of the label's local
//! thickness there (the chapter's thin protection held one-voxel parts only; parts a few
//! voxels thick shrank).
//!
//! The surfaces keep the topology of the consistent extraction ([`super::interfaces`]): each
//! vertex on a cell edge moves along that edge to where the two labels' interpolated weights
//! tie (strictly between the two voxel centres, thanks to the clamp), branching points on cell
//! faces go to the mean of the face's edge vertices next to them, and the branching point inside
//! a cell to the mean of its fan's rim. Weights are evaluated only at the voxels next to the
//! surface, so memory grows with the surface, not with the volume.

use super::kernel::{edge_weights, label_at, Kernel};
use super::noise::Pinned;
use super::{Interfaces, VERTEX_APEX, VERTEX_EDGE, VERTEX_FACE};
use crate::volume::LabelVolume;
use rayon::prelude::*;
use serde::Serialize;

/// Widest the Gaussian may be along an axis where a label is thin, as a fraction of the
/// label's local thickness along that axis (its run of voxels through the edge's voxel, in
/// mm): a Gaussian much wider than a part cannot tell it from its surroundings and shrinks it
/// onto its voxel centres (0.8 x 0.8 x 2.5 mm: tubes of radius 1-2 mm kept 18-67 % of their
/// cross-section at the full sigma).
pub const THICKNESS_FRACTION: f64 = 0.175;

/// Narrowing at or below which an edge's voxels are never noise: the part there is at most
/// twice the Gaussian's sigma thick, a structure the Gaussian cannot see, not a bump on one.
const NOISE_THICKNESS: f64 = 2.0 * THICKNESS_FRACTION;

/// Fewest voxels of its own label among its 26 neighbours for a pinned voxel to be a bump on
/// a surface (noise); fewer is a structure of its own (a single voxel, a 2 x 2 block), which
/// keeps its size.
const MIN_ATTACHED: usize = 4;

/// Most face neighbours of its own label a pinned voxel may have to be noise: a one-voxel
/// bump on a face has 1, each voxel of a two-voxel bump 2; a voxel on a staircase's edge or a
/// box's corner has 3 or more and is shape, not noise.
const MOST_FACES_OF_A_BUMP: usize = 2;

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

/// Default sigma, in smallest voxel spacings. The chapter's 2 cuts the 5-tap Gaussian at one
/// sigma along the finest axis; 1.5 is closer to real anatomy and smoother there (MNI ICBM152
/// white / grey matter at 1 x 1 x 3 mm against the 1 mm surface: 0.236 / 0.220 mm at 26.1 /
/// 20.9 degrees, against 0.245 / 0.227 mm at 27.1 / 21.3 with 2).
pub const DEFAULT_SIGMA_SPACINGS: f64 = 1.5;

/// The default sigma on `volume`: [`DEFAULT_SIGMA_SPACINGS`] of its smallest spacing (mm).
pub fn default_sigma_mm(volume: &LabelVolume) -> f64 {
    let s = volume.grid.spacing();
    DEFAULT_SIGMA_SPACINGS * s[0].min(s[1]).min(s[2])
}

/// Largest sigma accepted, in smallest voxel spacings. The kernel's 5 taps reach 2 voxels
/// along each axis; beyond 2 voxels along the finest one the Gaussian is cut short into a box,
/// and surfaces get rougher, not smoother (0.8 x 0.8 x 2.5 mm, plain Gaussian: a 12 mm sphere
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
            "sigma_mm = {} is more than {} mm, twice this map's smallest voxel spacing ({} mm): the 5 x 5 x 5 kernel would cut the Gaussian short and make the surface rougher, not smoother; use a sigma up to {} mm (the default is {} mm), less for less smoothing",
            crate::units::readable(sigma_mm),
            crate::units::readable(most),
            crate::units::readable(finest),
            crate::units::readable(most),
            crate::units::readable(default_sigma_mm(volume))
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
    /// Voxels of the label at the ends of edges where the Gaussian was narrowed because a
    /// label there is thin.
    pub thin_voxels: u64,
}

/// How many voxels of `label` lie in a row along `axis` through voxel `v` (which holds it),
/// counting at most `cap`.
fn run(volume: &LabelVolume, label: u16, v: [i64; 3], axis: usize, cap: usize) -> usize {
    let mut n = 1;
    for step in [-1, 1] {
        let mut q = v;
        q[axis] += step;
        while n < cap && label_at(volume, q) == label {
            n += 1;
            q[axis] += step;
        }
    }
    n
}

/// A label's thickness along axis `ax` at voxel `v` (which holds it), in voxels, counting at
/// most `cap`: its run through `v` along the edge's own axis (`axes[0]`); along another axis,
/// the longest run through the voxels from `v` into the label along the edge's axis (`step`
/// -1 or 1), so a tube's chord at its rim counts as its diameter, not as the short chord there.
fn thickness(
    volume: &LabelVolume,
    label: u16,
    v: [i64; 3],
    [edge_axis, ax]: [usize; 2],
    step: i64,
    cap: usize,
) -> usize {
    if ax == edge_axis {
        return run(volume, label, v, ax, cap);
    }
    let mut longest = 0;
    let mut q = v;
    for _ in 0..cap {
        longest = longest.max(run(volume, label, q, ax, cap));
        q[edge_axis] += step;
        if longest >= cap || label_at(volume, q) != label {
            break;
        }
    }
    longest
}

/// Whether voxel `v` (which holds `label`) sticks out of its label's surface as a bump or a
/// pit of one or two voxels: at most [`MOST_FACES_OF_A_BUMP`] of its 6 face neighbours hold its
/// label, and (unless it is the background) at least [`MIN_ATTACHED`] of its 26 neighbours do.
fn bump_or_pit(volume: &LabelVolume, label: u16, v: [i64; 3]) -> bool {
    let (mut faces, mut all) = (0, 0);
    for o in 0..27i64 {
        let d = [o % 3 - 1, o / 3 % 3 - 1, o / 9 - 1];
        if d != [0, 0, 0] && label_at(volume, std::array::from_fn(|k| v[k] + d[k])) == label {
            all += 1;
            if d.iter().filter(|&&x| x != 0).count() == 1 {
                faces += 1;
            }
        }
    }
    faces <= MOST_FACES_OF_A_BUMP && (label == 0 || all >= MIN_ATTACHED)
}

/// One edge's smoothed weights with the full kernels, [a at lo, b at lo, a at hi, b at hi],
/// and per axis how far the Gaussian narrows there (`None`: not at all).
#[derive(Debug, Clone, Copy)]
struct Sample {
    weights: [f32; 4],
    narrowing: Option<[f64; 3]>,
    /// Whether `weights` are already the narrowed kernels' (where no noise can be pinned, the
    /// full kernels' would serve nothing).
    narrowed: bool,
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
    let sigmas: Vec<f64> = per.iter().map(|s| s.sigma_on(volume)).collect();
    let kernels: Vec<Kernel> = sigmas.iter().map(|&s| Kernel::on(volume, s)).collect();
    let smoothed = |l: u16| per[l as usize].surface == Surface::Constrained;
    if !(1..n_labels as u16).any(smoothed) {
        // All binary: the consistent extraction stays as it is.
        return vec![LabelCounts::default(); n_labels];
    }
    let relaxes = |l: u16| smoothed(l) && per[l as usize].noise == Noise::Smooth;
    let protects = |l: u16| smoothed(l) && per[l as usize].thin == Thin::Protect;
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

    // Thin parts (§6.3.4): where a label's run of voxels through an edge's end is short along
    // an axis, the Gaussian along that axis narrows to a fraction of the run, for both labels
    // of the edge, so a thin part keeps its size instead of shrinking onto its voxel centres.
    // Such edges pin no noise (a thin part is structure); relaxed noise keeps the full kernel
    // (it is meant to be smoothed away).
    let spacing = volume.grid.spacing();
    let narrowed = |axis_sigma: [f64; 2], runs: [usize; 2], ax: usize| {
        let thickness = runs[0].min(runs[1]) as f64 * spacing[ax];
        (THICKNESS_FRACTION * thickness / axis_sigma[0].max(axis_sigma[1])).min(1.0)
    };
    let scale = |(axis, lo, hi, a, b): (usize, [i64; 3], [i64; 3], u16, u16)| {
        if !(protects(a) && protects(b)) {
            return None;
        }
        let (sa, sb) = (sigmas[a as usize], sigmas[b as usize]);
        let factor: [f64; 3] = std::array::from_fn(|ax| {
            // Runs beyond this length leave the Gaussian as it is.
            let cap =
                ((sa.max(sb) / (THICKNESS_FRACTION * spacing[ax])).ceil() as usize + 1).min(64);
            let runs = [
                thickness(volume, a, lo, [axis, ax], -1, cap),
                thickness(volume, b, hi, [axis, ax], 1, cap),
            ];
            narrowed([sa, sb], runs, ax)
        });
        factor.iter().any(|&f| f < 1.0).then_some(factor)
    };

    // Pass 1: the smoothed weights at both ends of every edge between two smoothed labels, as
    // [a at lo, b at lo, a at hi, b at hi], and how far the Gaussian narrows there.
    // The weights with each label's Gaussian narrowed by `f` per axis.
    let narrowed_weights = |f: [f64; 3], [a, b]: [u16; 2], lo: [i64; 3], axis: usize| {
        let k = |l: u16| {
            Kernel::new(std::array::from_fn(|ax| {
                sigmas[l as usize] * f[ax] / spacing[ax]
            }))
        };
        edge_weights(volume, [&k(a), &k(b)], [a, b], lo, axis)
    };
    // Whether noise may be pinned at an edge: both labels relax it and the part is not thin.
    let pins_noise = |a: u16, b: u16, narrowing: Option<[f64; 3]>| {
        relaxes(a)
            && relaxes(b)
            && !narrowing.is_some_and(|f| f.iter().any(|&x| x <= NOISE_THICKNESS))
    };
    let kinds = &all.kinds;
    let samples: Vec<Option<Sample>> = all
        .positions
        .par_iter()
        .zip(kinds.par_iter())
        .map(|(p, &kind)| {
            let e = (kind == VERTEX_EDGE).then(|| edge(p)).flatten()?;
            let (axis, lo, _, a, b) = e;
            let narrowing = scale(e);
            Some(match narrowing {
                Some(f) if !pins_noise(a, b, narrowing) => Sample {
                    weights: narrowed_weights(f, [a, b], lo, axis),
                    narrowing,
                    narrowed: true,
                },
                _ => {
                    let g = [&kernels[a as usize], &kernels[b as usize]];
                    Sample {
                        weights: edge_weights(volume, g, [a, b], lo, axis),
                        narrowing,
                        narrowed: false,
                    }
                }
            })
        })
        .collect();

    // Surface noise (§6.3.3): the voxels the clamp pins, where both labels relax noise and the
    // part is not thin. A pinned voxel is noise only as a one- or two-voxel bump or pit
    // ([`bump_or_pit`]): staircase edges and box corners are shape, and a structure of one or
    // two voxels keeps its size.
    let pinned: Vec<Pinned> = all
        .positions
        .par_iter()
        .zip(samples.par_iter())
        .flat_map_iter(|(p, w)| {
            let mut pins = Vec::new();
            let Some((sample, (_, lo, hi, a, b))) = w.as_ref().zip(edge(p)) else {
                return pins;
            };
            if !pins_noise(a, b, sample.narrowing) {
                return pins;
            }
            // lo holds a and hi holds b: a's weight must win at lo, b's at hi.
            let w = sample.weights;
            for (voxel, label, raw, own) in [
                (lo, a, w[0], true),
                (lo, b, w[1], false),
                (hi, b, w[3], true),
                (hi, a, w[2], false),
            ] {
                let wrong_side = (own && raw < 0.5) || (!own && raw > 0.5);
                // The voxel's own label sticks out here (or it is a pit of the background).
                let holds = if own { label } else { label_at(volume, voxel) };
                let bump = bump_or_pit(volume, holds, voxel);
                if let (true, true, Some(index)) = (wrong_side, bump, linear(voxel)) {
                    pins.push(Pinned {
                        voxel: index,
                        label,
                        raw,
                    });
                }
            }
            pins
        })
        .collect();
    // Offsets spread with the Gaussian convolved with itself: a wider, gentler swelling than
    // the shrink-free kernel makes (measured 2026-12-07 under the earlier noise rule: a
    // pimple's steepest facet 35 degrees with the shrink-free kernel, 11 so).
    let spreads: Vec<[[f32; 9]; 3]> = kernels.iter().map(|k| k.h).collect();
    let relaxation = super::noise::relax(volume.dims, &spreads, pinned, n_labels);

    // Pass 2: narrowed kernels where thin, offsets and the clamp; then the tie along the edge.
    let margin = MARGIN;
    let placed: Vec<Option<(f32, bool)>> = all
        .positions
        .par_iter()
        .zip(samples.par_iter())
        .map(|(p, sample)| {
            let (sample, (axis, lo, hi, a, b)) = sample.as_ref().zip(edge(p))?;
            // The offsets of relaxed noise within reach, if any.
            let offsets = (!relaxation.is_empty())
                .then(|| {
                    let mut d = [0f32; 4];
                    // Offsets live inside the volume only.
                    for (v, i) in [(lo, 0), (hi, 2)] {
                        if let Some(v) = linear(v) {
                            d[i] = relaxation.delta(v, a);
                            d[i + 1] = relaxation.delta(v, b);
                        }
                    }
                    d
                })
                .filter(|d| d.iter().any(|&x| x != 0.0));
            // The edges of a relaxed voxel keep the full kernel (it is meant to be smoothed
            // away); every other edge keeps its narrowing and gets the offsets on top. The
            // full kernel everywhere the offsets reach (9 x 9 x 9 voxels) undid the narrowing
            // of real thin parts: MNI white matter lay 0.253 mm from its 1 mm surface, 0.244
            // with no noise relaxed, 0.245 so.
            let near_noise = offsets.is_some()
                && [(lo, a), (lo, b), (hi, a), (hi, b)]
                    .iter()
                    .any(|&(v, l)| linear(v).is_some_and(|v| relaxation.is_relaxed(v, l)));
            let factor = if near_noise { None } else { sample.narrowing };
            let base = match (factor, sample.narrowed) {
                (Some(f), false) => narrowed_weights(f, [a, b], lo, axis),
                (None, true) => {
                    let g = [&kernels[a as usize], &kernels[b as usize]];
                    edge_weights(volume, g, [a, b], lo, axis)
                }
                _ => sample.weights,
            };
            let w = if let Some(d) = offsets {
                std::array::from_fn(|i| base[i] + d[i])
            } else {
                base
            };
            // d = w_a - w_b: positive at lo and negative at hi after the clamp.
            let d_lo = w[0].max(0.5 + margin) - w[1].min(0.5 - margin);
            let d_hi = w[2].min(0.5 - margin) - w[3].max(0.5 + margin);
            let denominator = d_lo - d_hi;
            (denominator > 0.0 && d_lo >= 0.0).then(|| {
                let t = (d_lo / denominator).clamp(0.0, 1.0) as f64;
                ((lo[axis] as f64 + t) as f32, factor.is_some())
            })
        })
        .collect();
    // The voxels at the ends of narrowed edges, per label: the thin voxels reported.
    let mut thin: Vec<(u16, u64)> = Vec::new();
    for (p, placed) in all.positions.iter_mut().zip(&placed) {
        let Some((x, narrow)) = *placed else {
            continue;
        };
        let Some((axis, lo, hi, a, b)) = edge(p) else {
            continue;
        };
        if narrow {
            thin.extend(
                [(a, lo), (b, hi)]
                    .iter()
                    .filter_map(|&(l, v)| Some((l, linear(v)?))),
            );
        }
        p[axis] = x;
    }
    thin.sort_unstable();
    thin.dedup();
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
            thin_voxels: thin.iter().filter(|(h, _)| *h as usize == l).count() as u64,
        })
        .collect()
}
