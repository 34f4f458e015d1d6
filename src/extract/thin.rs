//! Thin parts of a label (thesis §6.3.4): voxels where the label is only one voxel thick, so
//! that constrained smoothing would shrink it onto its voxel centres. Found by a morphological
//! opening (erosion then dilation, 26-neighbourhood) on the dual grid: a corner is set when
//! any of its 8 voxels holds the label, and after the opening a voxel stays only when all 8 of
//! its corners are still set. A plain opening on the voxels would also remove parts two voxels
//! thick; on the dual grid only one-voxel parts go. Computed with 64 voxels per word over the
//! label's bounding box, every step separable along the three axes.

use crate::volume::LabelVolume;
use rayon::prelude::*;

/// Empty voxels kept around a label's bounding box: the dual grid, the erosion and the
/// dilation each reach one voxel further, so the box's edges never decide anything.
const PAD: usize = 3;

/// The thin voxels of one label.
#[derive(Debug, Clone, Default)]
pub struct ThinVoxels {
    /// Voxel index of the box's first element (the bounding box minus the padding).
    origin: [i64; 3],
    dims: [usize; 3],
    words: usize,
    bits: Vec<u64>,
    /// How many voxels are thin.
    pub count: u64,
}

impl ThinVoxels {
    /// Whether voxel `v` (index coordinates) is a thin voxel of the label.
    pub fn contains(&self, v: [i64; 3]) -> bool {
        let mut local = [0usize; 3];
        for a in 0..3 {
            let x = v[a] - self.origin[a];
            if x < 0 || x >= self.dims[a] as i64 {
                return false;
            }
            local[a] = x as usize;
        }
        let row = local[1] + self.dims[1] * local[2];
        self.bits[row * self.words + local[0] / 64] >> (local[0] % 64) & 1 == 1
    }
}

impl ThinVoxels {
    /// How many thin voxels lie within `radius` voxels of `v` along every axis (itself
    /// included).
    pub fn count_near(&self, v: [i64; 3], radius: i64) -> usize {
        let mut n = 0;
        for dz in -radius..=radius {
            for dy in -radius..=radius {
                for dx in -radius..=radius {
                    n += usize::from(self.contains([v[0] + dx, v[1] + dy, v[2] + dz]));
                }
            }
        }
        n
    }
}

/// Inclusive bounding boxes (min, max voxel) of every dense label, `None` for labels without
/// voxels; entry 0 is the background's.
pub fn label_boxes(volume: &LabelVolume) -> Vec<Option<([usize; 3], [usize; 3])>> {
    let n = volume.labels.len() + 1;
    let [nx, ny, _] = volume.dims;
    let slice = nx * ny;
    if slice == 0 {
        return vec![None; n];
    }
    let merge = |mut a: Vec<Option<([usize; 3], [usize; 3])>>,
                 b: Vec<Option<([usize; 3], [usize; 3])>>| {
        for (x, y) in a.iter_mut().zip(b) {
            *x = match (*x, y) {
                (None, y) => y,
                (x, None) => x,
                (Some((l0, h0)), Some((l1, h1))) => Some((
                    std::array::from_fn(|k| l0[k].min(l1[k])),
                    std::array::from_fn(|k| h0[k].max(h1[k])),
                )),
            };
        }
        a
    };
    volume
        .voxels
        .par_chunks(slice)
        .enumerate()
        .map(|(z, plane)| {
            let mut boxes = vec![None; n];
            for (y, row) in plane.chunks(nx).enumerate() {
                // Runs of one label: one update per run, not per voxel.
                let mut start = 0;
                while start < row.len() {
                    let l = row[start];
                    let end = start
                        + row[start..]
                            .iter()
                            .position(|&m| m != l)
                            .unwrap_or(row.len() - start);
                    let b: &mut Option<([usize; 3], [usize; 3])> = &mut boxes[l as usize];
                    *b = Some(match *b {
                        None => ([start, y, z], [end - 1, y, z]),
                        Some((lo, hi)) => (
                            [lo[0].min(start), lo[1].min(y), z.min(lo[2])],
                            [hi[0].max(end - 1), hi[1].max(y), z.max(hi[2])],
                        ),
                    });
                    start = end;
                }
            }
            boxes
        })
        .reduce(|| vec![None; n], merge)
}

/// A bit volume over a padded box, x fastest, `words` 64-bit words per row.
struct Bits {
    dims: [usize; 3],
    words: usize,
    data: Vec<u64>,
}

#[derive(Clone, Copy)]
enum Op {
    And,
    Or,
}

impl Bits {
    /// Clears the bits past the row's end in each row's last word.
    fn mask_tail(&mut self) {
        let tail = self.dims[0] % 64;
        if tail == 0 {
            return;
        }
        let mask = (1u64 << tail) - 1;
        let words = self.words;
        for row in self.data.chunks_mut(words) {
            row[words - 1] &= mask;
        }
    }

    /// `out[i] = op over offsets o of self[i + o]` along `axis` (outside the box: unset).
    fn combine(&self, axis: usize, offsets: &[i64], op: Op) -> Bits {
        let words = self.words;
        let [_, ny, nz] = self.dims;
        let mut out = Bits {
            dims: self.dims,
            words,
            data: vec![0; self.data.len()],
        };
        let first = matches!(op, Op::And);
        out.data
            .par_chunks_mut(words)
            .enumerate()
            .for_each(|(r, dst)| {
                let (y, z) = ((r % ny) as i64, (r / ny) as i64);
                for (k, &o) in offsets.iter().enumerate() {
                    for (w, d) in dst.iter_mut().enumerate() {
                        let v = match axis {
                            0 => shifted(&self.data[r * words..(r + 1) * words], w, o),
                            _ => {
                                let (yy, zz) = if axis == 1 { (y + o, z) } else { (y, z + o) };
                                if yy < 0 || zz < 0 || yy >= ny as i64 || zz >= nz as i64 {
                                    0
                                } else {
                                    self.data[(yy as usize + ny * zz as usize) * words + w]
                                }
                            }
                        };
                        *d = match (op, k == 0 && first) {
                            (_, true) => v,
                            (Op::And, false) => *d & v,
                            (Op::Or, false) => *d | v,
                        };
                    }
                }
            });
        out.mask_tail();
        out
    }

    /// Applies `combine` along x, y and z in turn: a box operation, separably.
    fn box_op(&self, offsets: &[i64], op: Op) -> Bits {
        self.combine(0, offsets, op)
            .combine(1, offsets, op)
            .combine(2, offsets, op)
    }
}

/// Word `w` of a row whose bit `i` is the source's bit `i + o` (`o` in -1..=1).
fn shifted(row: &[u64], w: usize, o: i64) -> u64 {
    match o {
        0 => row[w],
        -1 => (row[w] << 1) | if w > 0 { row[w - 1] >> 63 } else { 0 },
        _ => (row[w] >> 1) | row.get(w + 1).map_or(0, |n| n << 63),
    }
}

/// The thin voxels of dense label `label`, whose voxels lie in the inclusive box `bounds`.
pub fn thin_voxels(
    volume: &LabelVolume,
    label: u16,
    bounds: ([usize; 3], [usize; 3]),
) -> ThinVoxels {
    let (lo, hi) = bounds;
    let dims: [usize; 3] = std::array::from_fn(|a| hi[a] - lo[a] + 1 + 2 * PAD);
    let origin: [i64; 3] = std::array::from_fn(|a| lo[a] as i64 - PAD as i64);
    let words = dims[0].div_ceil(64);
    let [nx, ny, _] = volume.dims;
    let mut voxels = Bits {
        dims,
        words,
        data: vec![0; words * dims[1] * dims[2]],
    };
    voxels
        .data
        .par_chunks_mut(words)
        .enumerate()
        .for_each(|(r, dst)| {
            let (y, z) = (r % dims[1], r / dims[1]);
            if y < PAD || z < PAD || y >= dims[1] - PAD || z >= dims[2] - PAD {
                return;
            }
            let (vy, vz) = (y - PAD + lo[1], z - PAD + lo[2]);
            let start = lo[0] + nx * (vy + ny * vz);
            let row = &volume.voxels[start..start + hi[0] - lo[0] + 1];
            for (x, &l) in row.iter().enumerate() {
                if l == label {
                    let bit = x + PAD;
                    dst[bit / 64] |= 1 << (bit % 64);
                }
            }
        });
    // Corner c lies between voxels c - 1 and c; the opening runs on corners; a voxel v stays
    // when corners v and v + 1 along every axis all survive.
    let corners = voxels.box_op(&[-1, 0], Op::Or);
    let opened = corners
        .box_op(&[-1, 0, 1], Op::And)
        .box_op(&[-1, 0, 1], Op::Or);
    let kept = opened.box_op(&[0, 1], Op::And);
    let mut bits = voxels.data;
    for (b, k) in bits.iter_mut().zip(&kept.data) {
        *b &= !k;
    }
    let count = bits.iter().map(|w| w.count_ones() as u64).sum();
    ThinVoxels {
        origin,
        dims,
        words,
        bits,
        count,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Grid, LabelVolume};

    fn volume(dims: [usize; 3], set: impl Fn(usize, usize, usize) -> bool) -> LabelVolume {
        let mut values = Vec::new();
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    values.push(i64::from(set(x, y, z)));
                }
            }
        }
        LabelVolume::from_values(
            dims,
            Grid::axis_aligned([1.0; 3], [0.0; 3], crate::volume::Space::Lps),
            values.into_iter(),
        )
        .unwrap()
    }

    fn thin_of(v: &LabelVolume) -> ThinVoxels {
        let boxes = label_boxes(v);
        thin_voxels(v, 1, boxes[1].unwrap())
    }

    /// Brute force of the same definition, straight from the chapter's steps.
    fn brute(v: &LabelVolume) -> Vec<[i64; 3]> {
        let d = v.dims.map(|x| x as i64);
        let set = |p: [i64; 3]| {
            (0..3).all(|a| p[a] >= 0 && p[a] < d[a])
                && v.at(p[0] as usize, p[1] as usize, p[2] as usize) == 1
        };
        let cube = |r: std::ops::RangeInclusive<i64>| {
            let r2 = r.clone();
            let r3 = r.clone();
            r.flat_map(move |x| {
                let r3 = r3.clone();
                r2.clone()
                    .flat_map(move |y| r3.clone().map(move |z| [x, y, z]))
            })
            .collect::<Vec<_>>()
        };
        let corner = |c: [i64; 3]| {
            cube(-1..=0)
                .iter()
                .any(|o| set([c[0] + o[0], c[1] + o[1], c[2] + o[2]]))
        };
        let eroded = |c: [i64; 3]| {
            cube(-1..=1)
                .iter()
                .all(|o| corner([c[0] + o[0], c[1] + o[1], c[2] + o[2]]))
        };
        let opened = |c: [i64; 3]| {
            cube(-1..=1)
                .iter()
                .any(|o| eroded([c[0] + o[0], c[1] + o[1], c[2] + o[2]]))
        };
        let mut thin = Vec::new();
        for z in 0..d[2] {
            for y in 0..d[1] {
                for x in 0..d[0] {
                    let p = [x, y, z];
                    if set(p)
                        && !cube(0..=1)
                            .iter()
                            .all(|o| opened([x + o[0], y + o[1], z + o[2]]))
                    {
                        thin.push(p);
                    }
                }
            }
        }
        thin
    }

    #[test]
    fn one_voxel_parts_are_thin_and_two_voxel_parts_are_not() {
        // A plate 2 voxels thick with a one-voxel sheet and a one-voxel rod sticking out.
        let v = volume([24, 24, 16], |x, y, z| {
            let plate = (3..=20).contains(&x) && (3..=20).contains(&y) && (3..=4).contains(&z);
            let sheet = (3..=20).contains(&x) && y == 10 && (5..=12).contains(&z);
            let rod = x == 16 && y == 16 && (5..=12).contains(&z);
            plate || sheet || rod
        });
        let thin = thin_of(&v);
        assert!(!thin.contains([10, 5, 3]) && !thin.contains([10, 5, 4]));
        assert!(thin.contains([10, 10, 9]) && thin.contains([16, 16, 9]));
        assert!(!thin.contains([-1, 0, 0]) && !thin.contains([100, 100, 100]));
    }

    #[test]
    fn bit_parallel_opening_matches_brute_force() {
        let mut rng = fastrand::Rng::with_seed(11);
        for round in 0..40 {
            let dims = [rng.usize(1..70), rng.usize(1..9), rng.usize(1..9)];
            let density = rng.f64() * 0.8 + 0.1;
            let cells: Vec<bool> = (0..dims.iter().product::<usize>())
                .map(|_| rng.f64() < density)
                .collect();
            let v = volume(dims, |x, y, z| cells[x + dims[0] * (y + dims[1] * z)]);
            if v.labels.is_empty() {
                continue;
            }
            let fast = thin_of(&v);
            let mut expected = brute(&v);
            let mut got = Vec::new();
            for z in 0..dims[2] as i64 {
                for y in 0..dims[1] as i64 {
                    for x in 0..dims[0] as i64 {
                        if fast.contains([x, y, z]) {
                            got.push([x, y, z]);
                        }
                    }
                }
            }
            expected.sort_by_key(|p| (p[2], p[1], p[0]));
            assert_eq!(got, expected, "round {round}, dims {dims:?}");
            assert_eq!(fast.count, got.len() as u64);
        }
    }
}
