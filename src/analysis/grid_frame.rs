//! The voxel grid of a marching-cubes mesh that was turned off the axes (a scanner's oblique
//! frame, a registration, a user's rotation): its axes and spacing.
//!
//! [`voxel_size`](fn@super::voxel_size) reads the grid from edge offsets along x, y and z, so it
//! sees a grid only where the mesh lies on an axis-aligned one. On a turned grid the flat faces
//! still face its axes exactly (a plane of marching-cubes faces on a grid face has the grid
//! axis as its normal to float precision), so the axes are read from them: one axis from the
//! directions that carry most face area, the second from the faces perpendicular to it,
//! whose directions repeat every 90 degrees around it on a grid. The mesh seen in that frame
//! then has to pass the same offset test as an axis-aligned one; a frame taken from a diagonal
//! facet, or a mesh on no grid, fails it (a sample of edges decides most of them), and the
//! next candidate is tried.
//!
//! Without this a tube along the slice axis, turned, takes its in-plane pixel walls for the
//! stack axis (the corpus trachea: 90 degrees off).

use super::voxel_size::{axis_spacing, zero_tolerance, AxisSpacing, MIN_EXPLAINED};
use crate::mesh::geometry::{cross64, dot64, unit64};
use crate::mesh::{Mesh, Topology};
use rayon::prelude::*;

/// A voxel grid a mesh lies on: its axes and spacing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// The grid's unit axes (rows): x, y, z ([`Grid::MESH_AXES`]) or turned, right-handed.
    pub axes: [[f64; 3]; 3],
    /// Bounds (smallest, largest; mm) on the spacing along each axis, as
    /// [`VoxelSizeEstimate::spacing_bounds`](super::VoxelSizeEstimate::spacing_bounds) gives them.
    pub spacing_mm: [(f64, f64); 3],
}

impl Grid {
    /// The mesh's own axes x, y, z (rows).
    pub const MESH_AXES: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

    /// A grid along the mesh's own axes with spacing bounds (mm along x, y, z).
    pub fn along_mesh_axes(spacing_mm: [(f64, f64); 3]) -> Grid {
        Grid {
            axes: Self::MESH_AXES,
            spacing_mm,
        }
    }

    /// Whether the grid is turned off the mesh's axes.
    pub fn is_turned(&self) -> bool {
        self.axes != Self::MESH_AXES
    }

    /// The spacing (mm) along a unit direction `n`: the largest spacing bound of each axis,
    /// weighted by how much `n` runs along it (the slice spacing along a face normal).
    pub fn spacing_along(&self, n: [f32; 3]) -> f32 {
        let n = n.map(f64::from);
        (0..3)
            .map(|k| dot64(self.axes[k], n).abs() * self.spacing_mm[k].1)
            .sum::<f64>() as f32
    }
}

/// A face counts as facing a direction when its normal is within this angle (degrees).
const FACING_DEG: f64 = 0.5;
/// Width of a histogram bin of directions around the first axis (degrees, over 0-90).
const BIN_DEG: f64 = 0.1;
/// Directions with most face area taken as candidate axes (with their pairs' cross products),
/// and second axes tried per first axis.
const PEAKS_TAKEN: usize = 8;
const SECOND_AXES_TRIED: usize = 2;
/// Peaks closer than this (degrees, modulo 90) are one direction.
const PEAKS_APART_DEG: f64 = 5.0;
/// Faces sampled (about) to find the grid's axes.
const SAMPLED_FACES: usize = 1 << 14;
/// Vertices whose edges the quick test samples (about).
const SAMPLED_VERTICES: usize = 1 << 12;

/// The turned grid the mesh lies on, or None when it lies on no grid found this way (an
/// axis-aligned one is [`voxel_size`](fn@super::voxel_size)'s).
pub fn turned_grid(mesh: &Mesh, topology: &Topology) -> Option<Grid> {
    let faces = SampledFaces::of(mesh);
    // The largest coordinate magnitude any frame can give: the float noise of the offsets.
    let max_norm = mesh
        .positions()
        .par_iter()
        .map(|p| p.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>().sqrt())
        .reduce(|| 0.0, f64::max);
    let zero_tol = zero_tolerance(max_norm);
    let sample = sampled_edges(mesh, topology);
    // A first axis must show grid steps in the sampled edges on its own before any frame
    // around it is tried: most candidates fail there, for the price of one sort.
    // (The candidates are exact already: refined peaks and their cross products.)
    for a in faces.first_axes() {
        let Some(along_a) = sampled_steps(&sample, a, zero_tol) else {
            continue;
        };
        for b in faces.around(a) {
            let axes = [a, b, cross64(a, b)];
            let Some(along_b) = sampled_steps(&sample, b, zero_tol) else {
                continue;
            };
            let Some(along_c) = sampled_steps(&sample, axes[2], zero_tol) else {
                continue;
            };
            let steps = [along_a, along_b, along_c];
            if explains_every_edge(mesh, topology, axes, steps, zero_tol) {
                return Some(Grid {
                    axes,
                    spacing_mm: steps.map(|s| s.bounds),
                });
            }
        }
    }
    None
}

/// An evenly strided sample of about [`SAMPLED_FACES`] faces with area: their unit normals
/// and areas (mm^2). A grid's walls hold a large share of the area, and every face of a wall
/// has the wall's normal to float precision, so a sample finds the axes as precisely as all
/// faces would.
struct SampledFaces {
    normals: Vec<[f64; 3]>,
    areas: Vec<f64>,
}

impl SampledFaces {
    fn of(mesh: &Mesh) -> SampledFaces {
        let (tris, p) = (mesh.triangles(), mesh.positions());
        let step = (tris.len() / SAMPLED_FACES) | 1;
        let (normals, areas) = (tris.iter().step_by(step))
            .filter_map(|t| {
                let [a, b, c] = t.map(|v| p[v as usize].map(f64::from));
                let twice = cross64(
                    std::array::from_fn(|k| b[k] - a[k]),
                    std::array::from_fn(|k| c[k] - a[k]),
                );
                let len = dot64(twice, twice).sqrt();
                (len > 0.0 && len.is_finite()).then(|| (twice.map(|x| x / len), 0.5 * len))
            })
            .unzip();
        SampledFaces { normals, areas }
    }

    fn iter(&self) -> impl Iterator<Item = ([f64; 3], f64)> + '_ {
        self.normals.iter().copied().zip(self.areas.iter().copied())
    }

    /// Candidate first axes: the directions carrying most face area (cells of about 0.3
    /// degrees on the Gauss map, n and -n together, refined), strongest first, then the cross
    /// products of pairs of them. A grid axis is perpendicular to every face normal without a
    /// component along it (terraces, walls and chamfers of the other two axes); on a vessel
    /// crossing the slices at 45 degrees, or an isotropic sphere, diagonal facets carry more
    /// area than any wall, and the axes are found only as such cross products.
    fn first_axes(&self) -> Vec<[f64; 3]> {
        const CELLS_PER_UNIT: f64 = 200.0;
        let key = |n: [f64; 3]| -> Option<[i32; 3]> {
            // n and -n in one cell: the first non-zero component made positive.
            let s = n.iter().find(|&&x| x != 0.0)?.signum();
            Some(n.map(|x| (x * s * CELLS_PER_UNIT).round() as i32))
        };
        let mut keyed: Vec<([i32; 3], f64)> = self
            .iter()
            .filter_map(|(n, w)| Some((key(n)?, w)))
            .collect();
        keyed.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        let mut heaviest: Vec<([i32; 3], f64)> = Vec::new();
        for (k, w) in keyed {
            match heaviest.last_mut() {
                Some(last) if last.0 == k => last.1 += w,
                _ => heaviest.push((k, w)),
            }
        }
        heaviest.sort_unstable_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let cos_apart = PEAKS_APART_DEG.to_radians().cos();
        let distinct =
            |list: &[[f64; 3]], d: [f64; 3]| list.iter().all(|&o| dot64(o, d).abs() < cos_apart);
        let mut peaks: Vec<[f64; 3]> = Vec::new();
        for (k, _) in heaviest {
            let Some(d) = unit64(k.map(f64::from)) else {
                continue;
            };
            let d = self.refined(d).unwrap_or(d);
            if distinct(&peaks, d) {
                peaks.push(d);
                if peaks.len() == PEAKS_TAKEN {
                    break;
                }
            }
        }
        let mut candidates = peaks.clone();
        for (i, &p) in peaks.iter().enumerate() {
            for &q in &peaks[i + 1..] {
                if let Some(c) = unit64(cross64(p, q)) {
                    if distinct(&candidates, c) {
                        candidates.push(c);
                    }
                }
            }
        }
        candidates
    }

    /// The area-weighted mean of the normals facing the line of `a` (sign-aligned to `a`).
    fn refined(&self, a: [f64; 3]) -> Option<[f64; 3]> {
        let cos_max = FACING_DEG.to_radians().cos();
        let mut sum = [0.0; 3];
        for (n, w) in self.iter() {
            let c = dot64(n, a);
            if c.abs() >= cos_max {
                let s = w * c.signum();
                (0..3).for_each(|k| sum[k] += s * n[k]);
            }
        }
        unit64(sum)
    }

    /// Unit directions perpendicular to `a` that may be a grid's second axis: the (up to
    /// [`SECOND_AXES_TRIED`]) peaks of the area of faces facing perpendicular to `a` by their
    /// angle around it, taken modulo 90 degrees (a grid's walls face four ways 90 degrees
    /// apart), strongest first, and the two peaks' bisector; then each of these turned by 45
    /// degrees.
    fn around(&self, a: [f64; 3]) -> Vec<[f64; 3]> {
        let u = perpendicular(a);
        let v = cross64(a, u);
        let sin_max = FACING_DEG.to_radians().sin();
        let n_bins = (90.0 / BIN_DEG).round() as usize;
        // The angle around `a`, modulo 90 degrees, of the faces facing perpendicular to it.
        let angles: Vec<(f64, f64)> = self
            .iter()
            .filter(|&(n, _)| dot64(n, a).abs() <= sin_max)
            .map(|(n, w)| {
                let deg = dot64(n, v).atan2(dot64(n, u)).to_degrees();
                (deg.rem_euclid(90.0), w)
            })
            .collect();
        let mut histogram = vec![0.0; n_bins];
        for &(deg, w) in &angles {
            histogram[((deg / BIN_DEG) as usize).min(n_bins - 1)] += w;
        }
        let mut order: Vec<usize> = (0..n_bins).filter(|&i| histogram[i] > 0.0).collect();
        order.sort_by(|&i, &j| histogram[j].total_cmp(&histogram[i]).then(i.cmp(&j)));
        let mut peaks: Vec<f64> = Vec::new();
        for i in order {
            let deg = (i as f64 + 0.5) * BIN_DEG;
            if peaks
                .iter()
                .all(|&p| apart_mod_90(p, deg) >= PEAKS_APART_DEG)
            {
                peaks.push(deg);
                if peaks.len() == SECOND_AXES_TRIED {
                    break;
                }
            }
        }
        let mut peak_deg: Vec<f64> = peaks
            .into_iter()
            .map(|peak| {
                // The circular mean of four times the angle of the faces near the peak.
                let (mut c, mut s) = (0.0, 0.0);
                for &(deg, w) in &angles {
                    if apart_mod_90(deg, peak) <= FACING_DEG {
                        let r = (4.0 * deg).to_radians();
                        c += w * r.cos();
                        s += w * r.sin();
                    }
                }
                if c == 0.0 && s == 0.0 {
                    peak
                } else {
                    s.atan2(c).to_degrees() / 4.0
                }
            })
            .collect();
        // Corner facets of an anisotropic cell face mirror images of each other about the
        // axes (the diamond-shaped section of a rod one voxel across): the axes bisect them.
        if let [p, q] = peak_deg[..] {
            let (s4, c4) = [p, q].iter().fold((0.0, 0.0), |(s, c), &d: &f64| {
                let r = (4.0 * d).to_radians();
                (s + r.sin(), c + r.cos())
            });
            if s4 != 0.0 || c4 != 0.0 {
                peak_deg.push(s4.atan2(c4).to_degrees() / 4.0);
            }
        }
        // Marching cubes cuts a grid cell's corner with a facet at 45 degrees to its walls: a
        // thin tube's cross-section (a diamond of pixels) may have no wall facet at all, so
        // each angle also stands for the axes 45 degrees from it.
        let mut axes = Vec::with_capacity(2 * peak_deg.len());
        for offset in [0.0, 45.0] {
            for &deg in &peak_deg {
                let (sin, cos) = (deg + offset).to_radians().sin_cos();
                axes.push(std::array::from_fn(|k| cos * u[k] + sin * v[k]));
            }
        }
        axes
    }
}

/// Angle (degrees) between two directions given modulo 90 degrees.
fn apart_mod_90(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(90.0);
    d.min(90.0 - d)
}

/// A unit vector perpendicular to the unit vector `a`.
fn perpendicular(a: [f64; 3]) -> [f64; 3] {
    let k = (0..3)
        .min_by(|&i, &j| a[i].abs().total_cmp(&a[j].abs()))
        .unwrap_or(0);
    let mut e = [0.0; 3];
    e[k] = 1.0;
    unit64(cross64(a, e)).unwrap_or([1.0, 0.0, 0.0])
}

/// The offset vectors (mm) of the edges of an evenly strided sample of about
/// [`SAMPLED_VERTICES`] vertices, for a quick test of each frame.
fn sampled_edges(mesh: &Mesh, topology: &Topology) -> Vec<[f64; 3]> {
    let p = mesh.positions();
    let n = topology.n_vertices().min(p.len());
    let step = (n / SAMPLED_VERTICES).max(1);
    (0..n)
        .step_by(step)
        .flat_map(|v| {
            (topology.larger_neighbors(v).iter()).map(move |&u| {
                std::array::from_fn(|k| f64::from(p[v][k]) - f64::from(p[u as usize][k]))
            })
        })
        .collect()
}

/// The offsets (mm) a grid shows along one axis: h/2 and h, or one step that is h or h/2,
/// with the spacing bounds they give.
#[derive(Debug, Clone, Copy)]
struct Steps {
    offsets: [f64; 2],
    bounds: (f64, f64),
}

/// The steps the sampled edge offsets (mm) show along the unit direction `axis`, or None when
/// they are not a grid's.
fn sampled_steps(sample: &[[f64; 3]], axis: [f64; 3], zero_tol: f64) -> Option<Steps> {
    let mut offsets: Vec<f64> = sample
        .iter()
        .map(|&d| dot64(axis, d).abs())
        .filter(|&d| d > zero_tol)
        .collect();
    offsets.sort_unstable_by(f64::total_cmp);
    match axis_spacing(&offsets, zero_tol) {
        AxisSpacing::Spacing { mm } => Some(Steps {
            offsets: [mm / 2.0, mm],
            bounds: (mm, mm),
        }),
        AxisSpacing::OneStep { mm } => Some(Steps {
            offsets: [mm, mm],
            bounds: (mm, 2.0 * mm),
        }),
        _ => None,
    }
}

/// Whether the steps the sample showed along `axes` (unit rows) explain the offsets of every
/// edge as [`voxel_size`](fn@super::voxel_size) demands (within the tolerance its clusters are
/// drawn with).
fn explains_every_edge(
    mesh: &Mesh,
    topology: &Topology,
    axes: [[f64; 3]; 3],
    steps: [Steps; 3],
    zero_tol: f64,
) -> bool {
    let p = mesh.positions();
    let n = topology.n_vertices().min(p.len());
    let near = |d: f64, step: f64| (d - step).abs() <= (4.0 * zero_tol).max(1e-4 * step);
    let counts = (0..n)
        .into_par_iter()
        .with_min_len(1 << 13)
        .map(|v| {
            let mut c = [[0usize; 2]; 3];
            for &u in topology.larger_neighbors(v) {
                let e: [f64; 3] =
                    std::array::from_fn(|k| f64::from(p[v][k]) - f64::from(p[u as usize][k]));
                for k in 0..3 {
                    let d = dot64(axes[k], e).abs();
                    if d > zero_tol {
                        c[k][0] += 1;
                        c[k][1] += usize::from(steps[k].offsets.iter().any(|&h| near(d, h)));
                    }
                }
            }
            c
        })
        .reduce(
            || [[0usize; 2]; 3],
            |a, b| std::array::from_fn(|k| [a[k][0] + b[k][0], a[k][1] + b[k][1]]),
        );
    counts
        .iter()
        .all(|&[total, explained]| explained as f64 >= MIN_EXPLAINED * total as f64)
}
