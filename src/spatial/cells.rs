//! A uniform grid of cells over a mesh's triangles: the first look of a nearest-point query.
//!
//! A query on or very near the surface (a vertex of a smoothed copy, as a Hausdorff distance
//! asks) is settled by the triangles of its own cell and its neighbours: the nearest of them
//! is closer than any wall of that block. That costs a few lookups, where descending a
//! hierarchy costs a dozen nodes whose boxes all hold the point, and building the hierarchy
//! costs more than the grid. Queries it does not settle go to the hierarchy
//! ([`super::bvh`]) with the best distance found as their bound.
//!
//! A surface fills a few percent of the cells of its box, so only listed cells have lists:
//! the grid is kept in blocks of 4 x 4 x 4 cells, one bit per cell in a 64-bit word saying
//! which cells list a triangle, and a listed cell's list is found from its block's first
//! listed cell and the bits before its own. The 1 M-triangle phantom (3.5 M cells, 120 k
//! of them listed) then keeps 1.6 MB besides its lists, where a list start and a flag per
//! cell took 17.6 MB, and builds in about 12 MB where per-cell counts took over 50 MB.

use rayon::prelude::*;

/// Cells per block along each axis.
const B: usize = 4;

/// Most cells per triangle: a grid finer than twice the mean edge only for surfaces that
/// fill their box sparsely (a few triangles far apart), where it costs under a byte a cell.
const CELLS_PER_TRIANGLE: usize = 16;

/// Cells over the triangles' box, about twice the mean edge length wide, each listing the
/// triangles whose box overlaps it (CSR over the listed cells only).
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
    /// Blocks of 4 x 4 x 4 cells along x, y, z (the last may reach past the grid).
    blocks: [usize; 3],
    /// Per block, which of its cells list a triangle: bit x + 4 y + 16 z for the cell at
    /// (x, y, z) within the block. Empty when there are no triangles.
    listed: Vec<u64>,
    /// Per block, how many cells the blocks before it list: listed cells are numbered block
    /// by block and bit by bit.
    first: Vec<u32>,
    /// Per block, as `listed`: which cells have a listed cell among themselves and their 26
    /// neighbours, so that a query whose own cell is empty knows at once whether its
    /// neighbours are worth a look.
    near: Vec<u64>,
    /// Per listed cell, where its triangles start in `ids` (CSR, one more than the listed
    /// cells).
    offsets: Vec<u32>,
    ids: Vec<u32>,
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
        let mut wanted = 2.0 * edge_sum / (3 * sampled) as f64;
        // Cells twice as wide until the triangles overlap few enough of them (a few rounds at
        // most, and only for surfaces of very unequal triangles: see PAIRS_PER_ITEM).
        let (cell, per_cell, dims, blocks, lists) = loop {
            let (cell, dims) = super::grid_cells(extent, wanted, n, CELLS_PER_TRIANGLE);
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
            let blocks = dims.map(|d| d.div_ceil(B));
            match cell_lists(triangles, dims, blocks, range) {
                Some(lists) => break (cell, per_cell, dims, blocks, lists),
                None => wanted = 2.0 * cell,
            }
        };
        let scale = (0..3)
            .map(|a| lo[a].abs().max(hi[a].abs()))
            .fold(cell, f64::max);
        TriangleCells {
            origin: lo,
            cell,
            per_cell,
            dims,
            blocks,
            near: dilate(&lists.listed, blocks),
            listed: lists.listed,
            first: lists.first,
            offsets: lists.offsets,
            ids: lists.ids,
            slack: 1e-9 * scale,
        }
    }

    /// The triangles cell `at` (x, y, z) lists, ascending; none outside the grid.
    pub fn list(&self, at: [usize; 3]) -> &[u32] {
        if self.listed.is_empty() || (0..3).any(|a| at[a] >= self.dims[a]) {
            return &[];
        }
        self.list_in(at)
    }

    /// [`TriangleCells::list`] of a cell inside the grid.
    #[inline]
    fn list_in(&self, at: [usize; 3]) -> &[u32] {
        let (b, bit) = block_bit(self.blocks, at);
        if self.listed[b] >> bit & 1 == 0 {
            return &[];
        }
        let s = slot(&self.listed, &self.first, b, bit);
        &self.ids[self.offsets[s] as usize..self.offsets[s + 1] as usize]
    }

    /// Whether the cell of `p` or one of its 26 neighbours lists a triangle; false for a point
    /// more than a cell outside the grid, whose nearest cell's neighbours are no nearer to it
    /// than the rest.
    pub fn near_listed(&self, p: [f32; 3]) -> bool {
        if self.listed.is_empty() {
            return false;
        }
        let q = p.map(f64::from);
        let inside = (0..3).all(|a| {
            let x = (q[a] - self.origin[a]) / self.cell;
            x >= -1.0 && x <= (self.dims[a] + 1) as f64
        });
        let at: [usize; 3] = std::array::from_fn(|a| self.cell_of(q[a], a));
        let (b, bit) = block_bit(self.blocks, at);
        inside && self.near[b] >> bit & 1 != 0
    }

    /// The cell index of coordinate `x` along axis `a`, clamped to the grid. By the
    /// reciprocal of the width, which may put a point within rounding of a wall on its other
    /// side: the walls' distances are taken less a slack far above that.
    fn cell_of(&self, x: f64, a: usize) -> usize {
        // Truncation is floor at and above 0; below, both end at cell 0 (NaN too).
        (((x - self.origin[a]) * self.per_cell) as usize).min(self.dims[a] - 1)
    }

    /// Visits the listed cells of ring `ring` around the cell of `p` (the nearest cell for a
    /// point outside; ring 0 is that cell, ring 1 its 26 neighbours) with a lower bound of the
    /// squared distance from `p` to each (mm^2), and returns how far `p` is from the walls of
    /// the block of rings 0 to `ring` where the grid goes on, less a slack for rounding (mm;
    /// infinite when the block is the whole grid): every triangle listed in no cell of the
    /// block is at least that far, so a triangle of the block strictly closer is the nearest
    /// of all. Cells further than `reach` (mm) along an axis (with room for the rounding of
    /// their walls) are passed over without a look: a search that has found a triangle at
    /// that distance does not need them (a point near a wall, an edge or a corner of its cell
    /// then looks at the one, three or seven cells beyond, not all 26).
    pub fn visit_ring(
        &self,
        p: [f32; 3],
        ring: usize,
        reach: f64,
        mut visit: impl FnMut(&[u32], f64),
    ) -> f64 {
        if self.listed.is_empty() {
            return f64::NEG_INFINITY;
        }
        let q = p.map(f64::from);
        let dims = self.dims;
        let at: [usize; 3] = std::array::from_fn(|a| self.cell_of(q[a], a));
        let lo: [usize; 3] = std::array::from_fn(|a| at[a].saturating_sub(ring));
        let hi: [usize; 3] = std::array::from_fn(|a| (at[a] + ring).min(dims[a] - 1));
        // The cells within reach (all of the block for an infinite reach): a wall of a cell
        // further than the reach is found on the far side of `q +- reach`.
        let reach = reach * (1.0 + 1e-9) + 2.0 * self.slack;
        let near_lo: [usize; 3] =
            std::array::from_fn(|a| lo[a].max(self.cell_of(q[a] - reach, a)).min(at[a]));
        let near_hi: [usize; 3] =
            std::array::from_fn(|a| hi[a].min(self.cell_of(q[a] + reach, a).max(at[a])));
        let on_ring = |x: usize, a: usize| x + ring == at[a] || x == at[a] + ring;
        for k in near_lo[2]..=near_hi[2] {
            for j in near_lo[1]..=near_hi[1] {
                for i in near_lo[0]..=near_hi[0] {
                    if !(on_ring(i, 0) || on_ring(j, 1) || on_ring(k, 2)) {
                        continue;
                    }
                    let ids = self.list_in([i, j, k]);
                    if ids.is_empty() {
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
                    visit(ids, gap2);
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

/// The block of cell `at` in a grid of `blocks` blocks, and the cell's bit in it.
#[inline]
fn block_bit(blocks: [usize; 3], at: [usize; 3]) -> (usize, u32) {
    let b = ((at[2] / B) * blocks[1] + at[1] / B) * blocks[0] + at[0] / B;
    let bit = at[0] % B + B * (at[1] % B) + B * B * (at[2] % B);
    (b, bit as u32)
}

/// The number of listed cell `bit` of block `b` among all listed cells (its bit set in
/// `listed[b]`): the cells listed before the block and the block's bits below its own.
#[inline]
fn slot(listed: &[u64], first: &[u32], b: usize, bit: u32) -> usize {
    first[b] as usize + (listed[b] & ((1u64 << bit) - 1)).count_ones() as usize
}

/// The listed cells of a grid and their triangle lists.
struct Lists {
    /// As [`TriangleCells`]'s fields of the same names.
    listed: Vec<u64>,
    first: Vec<u32>,
    offsets: Vec<u32>,
    ids: Vec<u32>,
}

/// The cells' triangle lists of a grid of `dims` cells in `blocks` blocks, where `range`
/// gives the cells a triangle overlaps; `None` when a stretch of triangles overlaps more
/// cells than [`PAIRS_PER_ITEM`](super::PAIRS_PER_ITEM) allows (the grid is too fine for
/// them). Stretches of triangles mark, count and fill side by side, each from its own cursors, so every list holds its triangles in ascending order
/// whatever the number of threads: the lists a serial pass would make. Each stretch finds
/// its triangles' cells once, while marking, and keeps them (block and bit, 5 bytes a cell)
/// for counting and filling: a cell of a triangle found again from its corners cost three
/// times as much.
fn cell_lists(
    triangles: &[[[f32; 3]; 3]],
    dims: [usize; 3],
    blocks: [usize; 3],
    range: impl Fn(&[[f32; 3]; 3]) -> CellBox + Sync,
) -> Option<Lists> {
    use std::sync::atomic::{AtomicU32, Ordering::Relaxed};
    let n_blocks = blocks[0] * blocks[1] * blocks[2];
    let stretch = triangles
        .len()
        .div_ceil(rayon::current_num_threads().clamp(1, 8))
        .max(1 << 14);
    let stretches: Vec<&[[[f32; 3]; 3]]> = triangles.chunks(stretch).collect();
    // Per stretch, which cells are listed, and its triangles' cells: their blocks (later their
    // listed-cell numbers), their bits, and where each triangle's cells end.
    let found: Option<Vec<StretchCells>> = stretches
        .par_iter()
        .map(|part| {
            let mut found = StretchCells {
                mask: vec![0u64; n_blocks],
                cells: Vec::with_capacity(part.len() * 3),
                bits: Vec::with_capacity(part.len() * 3),
                ends: Vec::with_capacity(part.len()),
            };
            let most = super::PAIRS_PER_ITEM * part.len() + super::PAIRS_ROOM;
            for t in *part {
                let (lo, hi) = range(t);
                debug_assert!((0..3).all(|a| hi[a] < dims[a]));
                let overlapped = (0..3).map(|a| hi[a] + 1 - lo[a]).product::<usize>();
                if found.cells.len() + overlapped > most {
                    return None;
                }
                for k in lo[2]..=hi[2] {
                    for j in lo[1]..=hi[1] {
                        for i in lo[0]..=hi[0] {
                            let (b, bit) = block_bit(blocks, [i, j, k]);
                            found.mask[b] |= 1 << bit;
                            found.cells.push(b as u32);
                            found.bits.push(bit as u8);
                        }
                    }
                }
                found.ends.push(found.cells.len() as u32);
            }
            Some(found)
        })
        .collect();
    let mut found = found?;
    // Every count below fits u32 (the pairs are at most 32 per triangle plus a little).
    let pairs: usize = found.iter().map(|f| f.cells.len()).sum();
    if u32::try_from(pairs).is_err() {
        return None;
    }
    let mut listed = vec![0u64; n_blocks];
    listed.par_iter_mut().enumerate().for_each(|(b, m)| {
        *m = found.iter().fold(0, |m, f| m | f.mask[b]);
    });
    let mut first = Vec::with_capacity(n_blocks);
    let mut n_listed = 0u32;
    for m in &listed {
        first.push(n_listed);
        n_listed += m.count_ones();
    }
    // Per stretch, its triangles in each listed cell; each cell's block turned into its
    // listed-cell number.
    let mut counts: Vec<Vec<u32>> = found
        .par_iter_mut()
        .map(|found| {
            found.mask = Vec::new();
            let mut count = vec![0u32; n_listed as usize];
            for (cell, &bit) in found.cells.iter_mut().zip(&found.bits) {
                let s = slot(&listed, &first, *cell as usize, bit as u32);
                count[s] += 1;
                *cell = s as u32;
            }
            count
        })
        .collect();
    // Offsets, and each stretch's count turned into its first place in the cell's list.
    let mut offsets = Vec::with_capacity(n_listed as usize + 1);
    let mut at = 0u32;
    for s in 0..n_listed as usize {
        offsets.push(at);
        for count in counts.iter_mut() {
            let n = count[s];
            count[s] = at;
            at += n;
        }
    }
    offsets.push(at);
    // Huge pages where offered: this buffer is written at scattered places.
    let mut ids: Vec<AtomicU32> = crate::hugepages::with_capacity(at as usize);
    (0..at)
        .into_par_iter()
        .map(|_| AtomicU32::new(0))
        .collect_into_vec(&mut ids);
    found
        .par_iter()
        .zip(counts.par_iter_mut())
        .enumerate()
        .for_each(|(k, (found, cursor))| {
            let mut start = 0;
            for (i, &end) in found.ends.iter().enumerate() {
                let f = (k * stretch + i) as u32;
                for &s in &found.cells[start..end as usize] {
                    ids[cursor[s as usize] as usize].store(f, Relaxed);
                    cursor[s as usize] += 1;
                }
                start = end as usize;
            }
        });
    drop(found);
    // In place: a Vec's own iterator mapped to a type of the same size and alignment collects
    // into the same buffer (no second buffer of fresh pages).
    let ids: Vec<u32> = ids.into_iter().map(AtomicU32::into_inner).collect();
    Some(Lists {
        listed,
        first,
        offsets,
        ids,
    })
}

/// What one stretch of triangles finds while marking its cells.
struct StretchCells {
    /// Per block, the bits of the cells its triangles overlap.
    mask: Vec<u64>,
    /// Per cell of a triangle, in triangle order: its block, later its listed-cell number.
    cells: Vec<u32>,
    /// Per cell of a triangle: its bit in the block.
    bits: Vec<u8>,
    /// Per triangle, where its cells end in `cells`.
    ends: Vec<u32>,
}

/// The cells with a listed cell among themselves and their 26 neighbours, as block bits
/// (`listed` widened by one cell along each axis in turn). Each pass shifts a block's 64
/// bits by one cell along its axis, masks the bits that would wrap into the next row, and
/// brings in the facing layer of the two neighbouring blocks along that axis.
fn dilate(listed: &[u64], blocks: [usize; 3]) -> Vec<u64> {
    /// Cells at x = 0, y = 0 and z = 0 of a block.
    const X0: u64 = 0x1111_1111_1111_1111;
    const Y0: u64 = 0x000f_000f_000f_000f;
    const Z0: u64 = 0xffff;
    // Along one axis, with the cells one step along it (`step` bits) and the layers at
    // either end of the block (`low`, `high`).
    let pass = |src: &[u64], axis: usize, step: u32, low: u64, high: u64| -> Vec<u64> {
        let stride = [1, blocks[0], blocks[0] * blocks[1]][axis];
        let across = (B as u32 - 1) * step;
        (0..src.len())
            .into_par_iter()
            .map(|b| {
                let along = (b / stride) % blocks[axis];
                let before = if along > 0 { src[b - stride] } else { 0 };
                let after = if along + 1 < blocks[axis] {
                    src[b + stride]
                } else {
                    0
                };
                let m = src[b];
                m | ((m << step) & !low)
                    | ((m >> step) & !high)
                    | ((before & high) >> across)
                    | ((after & low) << across)
            })
            .collect()
    };
    let along_x = pass(listed, 0, 1, X0, X0 << 3);
    let along_y = pass(&along_x, 1, B as u32, Y0, Y0 << 12);
    pass(&along_y, 2, (B * B) as u32, Z0, Z0 << 48)
}
