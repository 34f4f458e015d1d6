//! Constrained smoothing of label weights (thesis §6.3.2): each label's indicator (1 on its
//! voxels, 0 elsewhere) is smoothed with a discrete Gaussian and then clamped, so that a voxel
//! of the label keeps a weight above 1/2 and every other voxel stays below it. Every voxel
//! therefore keeps its own label as the largest weight, and the surfaces where the two largest
//! interpolated weights are equal still separate every pair of differently labelled voxel
//! centres; they only move to sub-voxel positions, which makes them smooth.
//!
//! The surfaces keep the topology of the consistent extraction ([`super::interfaces`]): each
//! vertex on a cell edge moves along that edge to where the two labels' interpolated weights
//! tie (strictly between the two voxel centres, thanks to the clamp), branching points on cell
//! faces go to the mean of the face's edge vertices next to them, and the branching point inside
//! a cell to the mean of its fan's rim. Weights are evaluated only at the voxels next to the
//! surface, so memory grows with the surface, not with the volume.

use super::{Interfaces, VERTEX_APEX, VERTEX_EDGE, VERTEX_FACE};
use crate::volume::LabelVolume;
use rayon::prelude::*;

/// Half-width of the discrete kernel in voxels along each axis: 5 x 5 x 5 taps, as the thesis
/// uses.
const RADIUS: i64 = 2;

/// Parameters of constrained smoothing.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ConstrainedParams {
    /// Gaussian sigma (mm); the thesis's default is twice the smallest voxel spacing.
    pub sigma_mm: f64,
    /// How far from 1/2 the clamp keeps weights (0 lets surfaces touch voxel centres; the
    /// default keeps them a little off, in units of weight).
    pub margin: f32,
}

impl ConstrainedParams {
    /// The defaults for a volume: sigma twice its smallest spacing, margin 0.02.
    pub fn for_volume(volume: &LabelVolume) -> ConstrainedParams {
        let s = volume.grid.spacing();
        ConstrainedParams {
            sigma_mm: 2.0 * s[0].min(s[1]).min(s[2]),
            margin: 0.02,
        }
    }
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

/// The clamped smoothed weights of dense labels `a` and `b` at voxel `v`, in one pass over the
/// kernel (voxels outside the volume are background).
fn weights(
    volume: &LabelVolume,
    g: &[[f32; 5]; 3],
    margin: f32,
    [a, b]: [u16; 2],
    v: [i64; 3],
) -> [f32; 2] {
    let [nx, ny, nz] = volume.dims.map(|d| d as i64);
    let inside = (0..3).all(|k| v[k] >= RADIUS && v[k] + RADIUS < [nx, ny, nz][k]);
    let mut w = [0f32; 2];
    for dz in -RADIUS..=RADIUS {
        let gz = g[2][(dz + RADIUS) as usize];
        for dy in -RADIUS..=RADIUS {
            let gyz = gz * g[1][(dy + RADIUS) as usize];
            let (y, z) = (v[1] + dy, v[2] + dz);
            if inside {
                // The whole row lies in the volume: no bounds to check.
                let start = (v[0] - RADIUS + nx * (y + ny * z)) as usize;
                let row = &volume.voxels[start..start + 5];
                for (gx, &l) in g[0].iter().zip(row) {
                    w[0] += if l == a { gyz * gx } else { 0.0 };
                    w[1] += if l == b { gyz * gx } else { 0.0 };
                }
                continue;
            }
            for dx in -RADIUS..=RADIUS {
                let l = label_at(volume, [v[0] + dx, y, z]);
                let gx = g[0][(dx + RADIUS) as usize];
                w[0] += if l == a { gyz * gx } else { 0.0 };
                w[1] += if l == b { gyz * gx } else { 0.0 };
            }
        }
    }
    let own = label_at(volume, v);
    let clamp = |w: f32, label: u16| {
        if own == label {
            w.max(0.5 + margin)
        } else {
            w.min(0.5 - margin)
        }
    };
    [clamp(w[0], a), clamp(w[1], b)]
}

/// Moves the vertices of `all` (extracted from `volume`) to where the two largest constrained
/// weights tie: edge vertices along their edges, then face and cell branching points to the
/// means of their neighbours. Positions stay in voxel index coordinates.
pub fn place_on_weights(volume: &LabelVolume, all: &mut Interfaces, params: &ConstrainedParams) {
    let g = kernel(volume, params.sigma_mm);
    let margin = params.margin.clamp(0.0, 0.49);
    // Edge vertices: the edge runs along the one axis where the position is not a whole number.
    let kinds = &all.kinds;
    all.positions
        .par_iter_mut()
        .zip(kinds.par_iter())
        .filter(|(_, &kind)| kind == VERTEX_EDGE)
        .for_each(|(p, _)| {
            let Some(axis) = (0..3).find(|&a| p[a].fract() != 0.0) else {
                return;
            };
            let lo: [i64; 3] = std::array::from_fn(|a| p[a].floor() as i64);
            let mut hi = lo;
            hi[axis] += 1;
            let (a, b) = (label_at(volume, lo), label_at(volume, hi));
            if a == b {
                return;
            }
            // d = w_a - w_b, positive at lo and negative at hi after the clamp.
            let [wa, wb] = weights(volume, &g, margin, [a, b], lo);
            let d_lo = wa - wb;
            let [wa, wb] = weights(volume, &g, margin, [a, b], hi);
            let d_hi = wa - wb;
            let denominator = d_lo - d_hi;
            if denominator > 0.0 && d_lo >= 0.0 {
                let t = (d_lo / denominator).clamp(0.0, 1.0) as f64;
                p[axis] = lo[axis] as f64 + t;
            }
        });
    // Branching points: the mean of their neighbours (edge vertices on the same face for face
    // points; the whole rim for cell points), faces first.
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); all.positions.len()];
    let mut link = |a: u32, b: u32| {
        if all.kinds[a as usize] != VERTEX_EDGE {
            neighbours[a as usize].push(b);
        }
    };
    for (t, tri) in all.triangles.iter().enumerate() {
        let apex = all.outer_apex[t];
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
    for kind in [VERTEX_FACE, VERTEX_APEX] {
        let updates: Vec<(usize, [f64; 3])> = neighbours
            .par_iter()
            .enumerate()
            .filter(|(v, _)| all.kinds[*v] == kind)
            .filter_map(|(v, list)| {
                let own = all.positions[v];
                // A face point's face: the axis along which it sits on a whole number.
                let normal = (0..3).find(|&a| own[a].fract() == 0.0);
                let mut seen: Vec<u32> = Vec::new();
                let mut sum = [0.0; 3];
                for &n in list {
                    let q = all.positions[n as usize];
                    let on_face = match (kind, normal) {
                        (VERTEX_FACE, Some(a)) => {
                            all.kinds[n as usize] == VERTEX_EDGE && q[a] == own[a]
                        }
                        (VERTEX_FACE, None) => false,
                        _ => true,
                    };
                    if on_face && !seen.contains(&n) {
                        seen.push(n);
                        for c in 0..3 {
                            sum[c] += q[c];
                        }
                    }
                }
                (!seen.is_empty()).then(|| (v, sum.map(|x| x / seen.len() as f64)))
            })
            .collect();
        for (v, p) in updates {
            all.positions[v] = p;
        }
    }
}
