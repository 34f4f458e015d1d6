//! A uniform grid of cells over a mesh's triangles: the first look of a nearest-point query.
//!
//! A query on or very near the surface (a vertex of a smoothed copy, as a Hausdorff distance
//! asks) is settled by the triangles of its own cell and its neighbours: the nearest of them
//! is closer than any wall of that block. That costs a few lookups, where descending a
//! hierarchy costs a dozen nodes whose boxes all hold the point, and building the hierarchy
//! costs more than the grid. Queries it does not settle go to the hierarchy
//! ([`super::bvh`]) with the best distance found as their bound.

use rayon::prelude::*;

/// Cells over the triangles' box, about twice the mean edge length wide, each listing the
/// triangles whose box overlaps it (CSR).
#[derive(Debug, Clone, Default)]
pub struct TriangleCells {
    /// Lowest corner of the grid (mm).
    pub origin: [f64; 3],
    /// Cell width (mm).
    pub cell: f64,
    /// Its reciprocal (cells per mm): a cell is found by a multiplication, not a division.
    per_cell: f64,
    /// Cells along x, y, z.
    pub dims: [usize; 3],
    /// Per cell, where its triangles start in the list (CSR, one more than the cells).
    pub offsets: Vec<u32>,
    ids: Vec<u32>,
    /// Per cell: whether it or one of its 26 neighbours lists a triangle, so that a query
    /// whose own cell is empty knows at once whether its neighbours are worth a look.
    near_listed: Vec<bool>,
    /// Far above the rounding of a wall's distance at this grid's coordinates (mm).
    slack: f64,
}

impl TriangleCells {
    /// Cells over `triangles` (mm); indices are positions in the slice.
    pub fn build(triangles: &[[[f32; 3]; 3]]) -> TriangleCells {
        if triangles.is_empty() {
            return TriangleCells::default();
        }
        let n = triangles.len();
        // The box, exactly (f32 minima and maxima), from every corner; a NaN coordinate is
        // passed over (the corner goes first: `min` and `max` keep the second on NaN).
        let (lo, hi) = triangles
            .par_iter()
            .fold(
                || ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
                |(mut lo, mut hi), t| {
                    for q in t {
                        for a in 0..3 {
                            lo[a] = super::min(q[a], lo[a]);
                            hi[a] = super::max(q[a], hi[a]);
                        }
                    }
                    (lo, hi)
                },
            )
            .reduce(
                || ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
                |(l1, h1), (l2, h2)| {
                    (
                        std::array::from_fn(|a| super::min(l1[a], l2[a])),
                        std::array::from_fn(|a| super::max(h1[a], h2[a])),
                    )
                },
            );
        let (lo, hi) = (lo.map(f64::from), hi.map(f64::from));
        // The mean edge length sets the cell size, which only tunes the speed of queries (not
        // their answers): estimated from an even sample of at most 2^16 triangles.
        let stride = n.div_ceil(1 << 16);
        let (edge_sum, sampled) =
            triangles
                .iter()
                .step_by(stride)
                .fold((0.0f64, 0usize), |(sum, count), t| {
                    let length = |k: usize| {
                        let (q, r) = (t[k], t[(k + 1) % 3]);
                        (0..3)
                            .map(|a| (q[a] as f64 - r[a] as f64).powi(2))
                            .sum::<f64>()
                            .sqrt()
                    };
                    (sum + length(0) + length(1) + length(2), count + 1)
                });
        let extent: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(0.0));
        let (cell, dims) = super::grid_cells(extent, 2.0 * edge_sum / (3 * sampled) as f64, n);
        let per_cell = 1.0 / cell;
        // As `TriangleCells::cell_of`.
        let cell_of = |x: f64, a: usize| (((x - lo[a]) * per_cell) as usize).min(dims[a] - 1);
        // The cells a triangle's box overlaps: lowest and highest along each axis.
        let range = |t: &[[f32; 3]; 3]| -> CellBox {
            let (mn, mx) = super::triangle_box(t);
            (
                std::array::from_fn(|a| cell_of(mn[a] as f64, a)),
                std::array::from_fn(|a| cell_of(mx[a] as f64, a)),
            )
        };
        let n_cells = dims[0] * dims[1] * dims[2];
        let (offsets, ids) = cell_lists(triangles, dims, range);
        let scale = (0..3)
            .map(|a| lo[a].abs().max(hi[a].abs()))
            .fold(cell, f64::max);
        let near_listed = dilate(
            (0..n_cells)
                .into_par_iter()
                .map(|c| offsets[c] < offsets[c + 1])
                .collect(),
            dims,
        );
        TriangleCells {
            origin: lo,
            cell,
            per_cell,
            dims,
            offsets,
            ids,
            near_listed,
            slack: 1e-9 * scale,
        }
    }

    /// Whether the cell of `p` or one of its 26 neighbours lists a triangle; false for a point
    /// more than a cell outside the grid, whose nearest cell's neighbours are no nearer to it
    /// than the rest.
    pub fn near_listed(&self, p: [f32; 3]) -> bool {
        if self.offsets.is_empty() {
            return false;
        }
        let q = p.map(f64::from);
        let inside = (0..3).all(|a| {
            let x = (q[a] - self.origin[a]) / self.cell;
            x >= -1.0 && x <= (self.dims[a] + 1) as f64
        });
        let at: [usize; 3] = std::array::from_fn(|a| self.cell_of(q[a], a));
        inside && self.near_listed[(at[2] * self.dims[1] + at[1]) * self.dims[0] + at[0]]
    }

    /// The cell index of coordinate `x` along axis `a`, clamped to the grid. By the
    /// reciprocal of the width, which may put a point within rounding of a wall on its other
    /// side: the walls' distances are taken less a slack far above that.
    fn cell_of(&self, x: f64, a: usize) -> usize {
        // Truncation is floor at and above 0; below, both end at cell 0 (NaN too).
        (((x - self.origin[a]) * self.per_cell) as usize).min(self.dims[a] - 1)
    }

    /// Visits the cells of ring `ring` around the cell of `p` (the nearest cell for a point
    /// outside; ring 0 is that cell, ring 1 its 26 neighbours) with a lower bound of the
    /// squared distance from `p` to each (mm^2), and returns how far `p` is from the walls of the block of rings 0
    /// to `ring` where the grid goes on, less a slack for rounding (mm; infinite when the
    /// block is the whole grid): every triangle listed in no cell of the block is at least
    /// that far, so a triangle of the block strictly closer is the nearest of all.
    pub fn visit_ring(&self, p: [f32; 3], ring: usize, mut visit: impl FnMut(&[u32], f64)) -> f64 {
        if self.offsets.is_empty() {
            return f64::NEG_INFINITY;
        }
        let q = p.map(f64::from);
        let dims = self.dims;
        let at: [usize; 3] = std::array::from_fn(|a| self.cell_of(q[a], a));
        let lo: [usize; 3] = std::array::from_fn(|a| at[a].saturating_sub(ring));
        let hi: [usize; 3] = std::array::from_fn(|a| (at[a] + ring).min(dims[a] - 1));
        let on_ring = |x: usize, a: usize| x + ring == at[a] || x == at[a] + ring;
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    if !(on_ring(i, 0) || on_ring(j, 1) || on_ring(k, 2)) {
                        continue;
                    }
                    let gap2: f64 = [i, j, k]
                        .iter()
                        .enumerate()
                        .map(|(a, &x)| {
                            let wall = self.origin[a] + x as f64 * self.cell;
                            // Less the slack, as the walls below: a lower bound whatever
                            // the rounding of the wall's place.
                            let gap = (wall - q[a]).max(q[a] - (wall + self.cell));
                            let gap = (gap - self.slack).max(0.0);
                            gap * gap
                        })
                        .sum();
                    let c = (k * dims[1] + j) * dims[0] + i;
                    visit(
                        &self.ids[self.offsets[c] as usize..self.offsets[c + 1] as usize],
                        gap2,
                    );
                }
            }
        }
        let mut walls = f64::INFINITY;
        for a in 0..3 {
            if lo[a] > 0 {
                walls = walls.min(q[a] - (self.origin[a] + lo[a] as f64 * self.cell));
            }
            if hi[a] + 1 < dims[a] {
                walls = walls.min(self.origin[a] + (hi[a] + 1) as f64 * self.cell - q[a]);
            }
        }
        walls - self.slack
    }
}

/// Lowest and highest cell along each axis of a box of cells.
type CellBox = ([usize; 3], [usize; 3]);

/// The cells' triangle lists (CSR offsets and ids) of a grid of `dims` cells, where `range`
/// gives the cells a triangle overlaps. Stretches of triangles are counted and filled side by
/// side, each from its own cursors, so every list holds its triangles in ascending order
/// whatever the number of threads: the lists a serial pass would make.
fn cell_lists(
    triangles: &[[[f32; 3]; 3]],
    dims: [usize; 3],
    range: impl Fn(&[[f32; 3]; 3]) -> CellBox + Sync,
) -> (Vec<u32>, Vec<u32>) {
    use std::sync::atomic::{AtomicU32, Ordering::Relaxed};
    let n_cells = dims[0] * dims[1] * dims[2];
    // Every cell of a box, by linear index.
    fn each_cell((lo, hi): CellBox, dims: [usize; 3], mut visit: impl FnMut(usize)) {
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    visit((k * dims[1] + j) * dims[0] + i);
                }
            }
        }
    }
    // One stretch per thread, but the stretches' counts (4 bytes per cell each) together no
    // larger than the corners the index keeps (36 bytes per triangle): a grid of about 3.5
    // cells per triangle gets two stretches whatever the number of cores.
    let by_memory = (9 * triangles.len() / n_cells.max(1)).max(1);
    let stretch = triangles
        .len()
        .div_ceil(rayon::current_num_threads().clamp(1, 8).min(by_memory))
        .max(1 << 14);
    let stretches: Vec<&[[[f32; 3]; 3]]> = triangles.chunks(stretch).collect();
    // Per stretch, its triangles in each cell.
    let mut counts: Vec<Vec<u32>> = stretches
        .par_iter()
        .map(|part| {
            let mut count = crate::hugepages::zeroed_vec::<u32>(n_cells);
            for t in *part {
                each_cell(range(t), dims, |c| count[c] += 1);
            }
            count
        })
        .collect();
    // Offsets, and each stretch's count turned into its first slot in the cell: blocks of
    // cells in parallel, each from the total of the blocks before it.
    const BLOCK: usize = 1 << 16;
    let block_totals: Vec<u32> = (0..n_cells.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let cells = b * BLOCK..((b + 1) * BLOCK).min(n_cells);
            counts
                .iter()
                .map(|c| c[cells.clone()].iter().sum::<u32>())
                .sum()
        })
        .collect();
    let mut block_starts = Vec::with_capacity(block_totals.len());
    let mut total = 0u32;
    for t in &block_totals {
        block_starts.push(total);
        total += t;
    }
    let mut offsets = crate::hugepages::zeroed_vec::<u32>(n_cells + 1);
    offsets[n_cells] = total;
    // Per block: its first slot, its offsets and each stretch's counts there.
    type Block<'a> = (u32, &'a mut [u32], Vec<&'a mut [u32]>);
    let mut blocks: Vec<Block> = offsets[..n_cells]
        .chunks_mut(BLOCK)
        .zip(&block_starts)
        .map(|(o, &start)| (start, o, Vec::with_capacity(counts.len())))
        .collect();
    for count in counts.iter_mut() {
        for (block, part) in blocks.iter_mut().zip(count.chunks_mut(BLOCK)) {
            block.2.push(part);
        }
    }
    blocks
        .into_par_iter()
        .for_each(|(start, offsets, mut parts)| {
            let mut at = start;
            for (i, o) in offsets.iter_mut().enumerate() {
                *o = at;
                for part in parts.iter_mut() {
                    let n = part[i];
                    part[i] = at;
                    at += n;
                }
            }
        });
    // Huge pages where offered: these buffers are written at scattered places.
    let mut ids: Vec<AtomicU32> = crate::hugepages::with_capacity(total as usize);
    (0..total)
        .into_par_iter()
        .map(|_| AtomicU32::new(0))
        .collect_into_vec(&mut ids);
    stretches
        .par_iter()
        .zip(counts.par_iter_mut())
        .enumerate()
        .for_each(|(k, (part, cursor))| {
            for (i, t) in part.iter().enumerate() {
                let f = (k * stretch + i) as u32;
                each_cell(range(t), dims, |c| {
                    ids[cursor[c] as usize].store(f, Relaxed);
                    cursor[c] += 1;
                });
            }
        });
    // In place: a Vec's own iterator mapped to a type of the same size and alignment collects
    // into the same buffer (no second buffer of fresh pages).
    let plain: Vec<u32> = ids.into_iter().map(AtomicU32::into_inner).collect();
    (offsets, plain)
}

/// `listed` (one flag per cell of a grid of `dims`) widened by one cell along every axis in
/// turn: a cell's result is set when any cell of its 3 x 3 x 3 block is. Each pass ORs whole
/// rows or planes shifted by one cell (no branch per cell), planes in parallel: along x and y
/// within each plane (through one plane of scratch per worker), then along z into `listed`'s
/// own buffer.
fn dilate(mut listed: Vec<bool>, dims: [usize; 3]) -> Vec<bool> {
    let [nx, ny, _] = dims;
    let plane = nx * ny;
    if plane == 0 {
        return listed;
    }
    let mut along_xy = vec![false; listed.len()];
    along_xy
        .par_chunks_mut(plane)
        .zip(listed.par_chunks(plane))
        .for_each_init(Vec::new, |along_x, (out, src)| {
            // Along x, within each row.
            along_x.clear();
            along_x.extend_from_slice(src);
            for (o, s) in along_x.chunks_mut(nx).zip(src.chunks(nx)) {
                or_shifted(o, s);
            }
            // Along y: rows ORed with the rows before and after.
            out.copy_from_slice(along_x);
            if ny > 1 {
                or_into(&mut out[nx..], &along_x[..plane - nx]);
                or_into(&mut out[..plane - nx], &along_x[nx..]);
            }
        });
    // Along z: planes ORed with the planes before and after.
    let from = &along_xy;
    listed
        .par_chunks_mut(plane)
        .enumerate()
        .for_each(|(k, out)| {
            out.copy_from_slice(&from[k * plane..(k + 1) * plane]);
            if k > 0 {
                or_into(out, &from[(k - 1) * plane..k * plane]);
            }
            if let Some(next) = from.get((k + 1) * plane..(k + 2) * plane) {
                or_into(out, next);
            }
        });
    listed
}

/// `out[i] |= src[i]`.
fn or_into(out: &mut [bool], src: &[bool]) {
    for (o, &s) in out.iter_mut().zip(src) {
        *o |= s;
    }
}

/// `out[i] |= src[i - 1] | src[i + 1]` where those exist (`out` starts as a copy of `src`).
fn or_shifted(out: &mut [bool], src: &[bool]) {
    if src.len() > 1 {
        or_into(&mut out[1..], &src[..src.len() - 1]);
        or_into(&mut out[..src.len() - 1], &src[1..]);
    }
}
