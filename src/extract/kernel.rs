//! The label weights' smoothing kernel (thesis §6.3.2 with issue 62's change): shrink-free,
//! `2 g - g * g` for the chapter's 5-tap Gaussian `g`, separable per axis, and the weights of
//! two labels at both ends of a cell edge summed over their shared rows.

use crate::volume::LabelVolume;

/// Half-width of the Gaussian in voxels along each axis: 5 x 5 x 5 taps, as the thesis uses.
const RADIUS: i64 = 2;

/// Half-width of the shrink-free kernel `2 g - g * g` (voxels): the Gaussian convolved with
/// itself reaches twice as far.
pub const REACH: i64 = 2 * RADIUS;

/// A label's smoothing kernel, shrink-free: `2 g - g * g` (twicing) for the Gaussian `g`, so
/// that a convex part loses no volume to the smoothing to second order (a plain Gaussian moves
/// a surface of mean curvature `H` inwards by about `sigma² H`), while staircases, which are
/// much finer than the Gaussian, are still smoothed away. Separable parts per axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Kernel {
    /// The Gaussian's 5 taps per axis, normalised.
    pub g: [[f32; 5]; 3],
    /// `g * g` per axis: 9 taps.
    pub h: [[f32; 9]; 3],
    /// For kernels used at many edges (a label's): the row sums along x by mask.
    row_sums: Option<Box<RowSums>>,
}

/// A kernel's sums along x over every subset of its taps (bit k of the index: tap k), added
/// in increasing tap order from 0: a row's sum is one lookup by the mask of the label's
/// voxels in it, the same number as adding its taps one by one.
#[derive(Debug, Clone, PartialEq)]
struct RowSums {
    h: [f32; 512],
    g: [f32; 32],
}

/// The sum of `taps` chosen by the bits of `mask` (bit k: tap k), in increasing tap order
/// from 0.
fn masked_sum(taps: &[f32], mut mask: usize) -> f32 {
    let mut sum = 0f32;
    while mask != 0 {
        sum += taps[mask.trailing_zeros() as usize];
        mask &= mask - 1;
    }
    sum
}

impl Kernel {
    /// The kernel for a per-axis sigma in voxels, without row sums (for use at one edge).
    pub fn new(sigma_voxels: [f64; 3]) -> Kernel {
        let g: [[f64; 5]; 3] = std::array::from_fn(|axis| {
            let sigma = sigma_voxels[axis].max(1e-6);
            let mut taps: [f64; 5] =
                std::array::from_fn(|d| (-((d as f64 - 2.0) / sigma).powi(2) / 2.0).exp());
            let sum: f64 = taps.iter().sum();
            for t in &mut taps {
                *t /= sum;
            }
            taps
        });
        Kernel::from_taps(g.map(|a| a.map(|t| t as f32)))
    }

    /// The kernel of a Gaussian given by its 5 taps per axis (normalised).
    pub fn from_taps(g: [[f32; 5]; 3]) -> Kernel {
        let g64 = g.map(|a| a.map(f64::from));
        let h = std::array::from_fn(|axis| {
            std::array::from_fn(|i| {
                (0..5)
                    .filter_map(|j| {
                        let k = i as i64 - j as i64;
                        (0..5)
                            .contains(&k)
                            .then(|| g64[axis][j] * g64[axis][k as usize])
                    })
                    .sum::<f64>() as f32
            })
        });
        Kernel {
            g,
            h,
            row_sums: None,
        }
    }

    /// The same kernel with its row sums by mask, for use at many edges.
    pub fn with_row_sums(mut self) -> Kernel {
        let (h, g) = (self.h[0], self.g[0]);
        self.row_sums = Some(Box::new(RowSums {
            h: std::array::from_fn(|m| masked_sum(&h, m)),
            g: std::array::from_fn(|m| masked_sum(&g, m)),
        }));
        self
    }

    /// The same kernel without row sums (its row sums are then added tap by tap: the same
    /// numbers).
    pub fn without_row_sums(mut self) -> Kernel {
        self.row_sums = None;
        self
    }

    /// The sum along x of `g * g` over the taps in `mask` (9 bits).
    fn h_sum(&self, mask: usize) -> f32 {
        match &self.row_sums {
            Some(t) => t.h[mask & 511],
            None => masked_sum(&self.h[0], mask & 511),
        }
    }

    /// The sum along x of `g` over the taps in `mask` (5 bits).
    fn g_sum(&self, mask: usize) -> f32 {
        match &self.row_sums {
            Some(t) => t.g[mask & 31],
            None => masked_sum(&self.g[0], mask & 31),
        }
    }

    /// The kernel of a label with `sigma_mm` on `volume`'s grid.
    pub(super) fn on(volume: &LabelVolume, sigma_mm: f64) -> Kernel {
        let s = volume.grid.spacing();
        Kernel::new(std::array::from_fn(|a| sigma_mm / s[a])).with_row_sums()
    }

    /// The kernel's weight at offset `d` (voxels); 0 beyond its reach.
    pub fn tap(&self, d: [i64; 3]) -> f64 {
        if d.iter().any(|x| x.abs() > REACH) {
            return 0.0;
        }
        let h: f64 = (0..3)
            .map(|a| self.h[a][(d[a] + REACH) as usize] as f64)
            .product();
        let g: f64 = if d.iter().all(|x| x.abs() <= RADIUS) {
            (0..3)
                .map(|a| self.g[a][(d[a] + RADIUS) as usize] as f64)
                .product()
        } else {
            0.0
        };
        2.0 * g - h
    }
}

/// The dense label at voxel `p`; background outside the volume.
pub(super) fn label_at(volume: &LabelVolume, p: [i64; 3]) -> u16 {
    let [nx, ny, nz] = volume.dims.map(|d| d as i64);
    if p.iter().any(|&x| x < 0) || p[0] >= nx || p[1] >= ny || p[2] >= nz {
        0
    } else {
        volume.voxels[(p[0] + nx * (p[1] + ny * p[2])) as usize]
    }
}

/// The smoothed (unclamped) weights of dense labels `a` and `b`, each with its own kernel, at
/// both ends of the cell edge from voxel `lo` one step along `axis`, as [a at lo, b at lo, a at
/// hi, b at hi] (voxels outside the volume are background). One pass over the union of the
/// two ends' 9 x 9 x 9 boxes, row by row along x: a row's sums for `g * g` (9 taps) and `g`
/// (the middle 5) serve both ends where the boxes share it (edges along y and z share 72 of 81
/// rows), so the pair costs little more than one end.
pub fn edge_weights(
    volume: &LabelVolume,
    [ka, kb]: [&Kernel; 2],
    [a, b]: [u16; 2],
    lo: [i64; 3],
    axis: usize,
) -> [f32; 4] {
    let [nx, ny, nz] = volume.dims.map(|d| d as i64);
    let step: [i64; 3] = std::array::from_fn(|k| i64::from(k == axis));
    let inside = (0..3).all(|k| lo[k] >= REACH && lo[k] + step[k] + REACH < [nx, ny, nz][k]);
    let width = (2 * REACH + 1 + step[0]) as usize;
    // Per end: the -g*g part and the Gaussian part, per label.
    let mut w = [[0f32; 2]; 2];
    let mut plain = [[0f32; 2]; 2];
    let mut row = [0u16; 10];
    // The sums of a row's 9 voxels from `shift`: g*g for a and b, then g for a and b (one
    // lookup each by the mask of the label's voxels; the same sums as tap by tap).
    let sums = |row: &[u16; 10], shift: usize, middle: bool| {
        let (mut mask_a, mut mask_b) = (0usize, 0usize);
        for (k, &l) in row.iter().enumerate() {
            mask_a |= usize::from(l == a) << k;
            mask_b |= usize::from(l == b) << k;
        }
        let (mask_a, mask_b) = (mask_a >> shift, mask_b >> shift);
        let mut s = [ka.h_sum(mask_a), kb.h_sum(mask_b), 0.0, 0.0];
        if middle {
            s[2] = ka.g_sum(mask_a >> 2);
            s[3] = kb.g_sum(mask_b >> 2);
        }
        s
    };
    for dz in -REACH..=REACH + step[2] {
        for dy in -REACH..=REACH + step[1] {
            let (y, z) = (lo[1] + dy, lo[2] + dz);
            if inside {
                // The whole row lies in the volume: no bounds to check.
                let start = (lo[0] - REACH + nx * (y + ny * z)) as usize;
                row[..width].copy_from_slice(&volume.voxels[start..start + width]);
            } else {
                for (dx, l) in (-REACH..).zip(row[..width].iter_mut()) {
                    *l = label_at(volume, [lo[0] + dx, y, z]);
                }
            }
            // Where this row sits in each end's box (hi's box starts one step further).
            let at = [
                (dz + REACH, dy + REACH),
                (dz + REACH - step[2], dy + REACH - step[1]),
            ];
            let within = |(i, j): (i64, i64)| (0..9).contains(&i) && (0..9).contains(&j);
            let middle = |(i, j): (i64, i64)| (2..7).contains(&i) && (2..7).contains(&j);
            let shared = sums(&row, 0, at.iter().any(|&p| within(p) && middle(p)));
            for (end, &(i, j)) in at.iter().enumerate() {
                if !within((i, j)) {
                    continue;
                }
                let s = if end == 1 && step[0] == 1 {
                    sums(&row, 1, middle((i, j)))
                } else {
                    shared
                };
                let (i, j) = (i as usize, j as usize);
                if middle((i as i64, j as i64)) {
                    plain[end][0] += ka.g[2][i - 2] * ka.g[1][j - 2] * s[2];
                    plain[end][1] += kb.g[2][i - 2] * kb.g[1][j - 2] * s[3];
                }
                w[end][0] -= ka.h[2][i] * ka.h[1][j] * s[0];
                w[end][1] -= kb.h[2][i] * kb.h[1][j] * s[1];
            }
        }
    }
    let end = |e: usize, l: usize| w[e][l] + 2.0 * plain[e][l];
    [end(0, 0), end(0, 1), end(1, 0), end(1, 1)]
}
