//! The umbrella operator over a vertex adjacency: each vertex moves towards the mean of its
//! neighbours. Shared by the smoothers and by the low-pass copy cap detection looks at.
//!
//! The iterated kernels read the adjacency as `NeighbourLists` and positions as `Padded`
//! vectors: every vertex of ordinary degree sums a row of fixed width with no data-dependent
//! branch (a varying loop count mispredicts at almost every vertex), and each neighbour is one
//! aligned vector add. Sums run in list order, so results are bit-identical to a plain loop
//! over the CSR lists.

use crate::mesh::order::Renumbering;
use rayon::prelude::*;
use std::borrow::Cow;

/// Vertices per parallel work item (results do not depend on it).
pub const CHUNK: usize = 2048;

/// Mean of `values` over the given neighbour indices (callers ensure the list is not empty).
#[inline]
pub fn neighbour_mean(values: &[[f32; 3]], neighbors: &[u32]) -> [f32; 3] {
    let mut sum = [0.0f32; 3];
    for &n in neighbors {
        let q = values[n as usize];
        sum[0] += q[0];
        sum[1] += q[1];
        sum[2] += q[2];
    }
    let inv = 1.0 / neighbors.len() as f32;
    [sum[0] * inv, sum[1] * inv, sum[2] * inv]
}

/// A position (or displacement, mm) padded to 16 bytes: one aligned load reads it and one
/// vector add sums it, lane by lane with the rounding of three scalar adds (the fourth lane
/// stays 0).
pub type Padded = glam::Vec4;

/// A kernel's working copy of per-vertex vectors: the values padded, then one zero vector, the
/// sentinel that [`NeighbourLists`] fill short rows with.
pub fn padded(values: &[[f32; 3]]) -> Vec<Padded> {
    let mut out = crate::hugepages::with_capacity(values.len() + 1);
    values
        .par_iter()
        .with_min_len(CHUNK)
        .map(|&[x, y, z]| Padded::new(x, y, z, 0.0))
        .collect_into_vec(&mut out);
    out.push(Padded::ZERO);
    out
}

/// A second working copy (huge pages as [`padded`] gives them).
pub fn copied(values: &[Padded]) -> Vec<Padded> {
    let mut out = crate::hugepages::with_capacity(values.len());
    out.extend_from_slice(values);
    out
}

/// A second working copy for a kernel whose passes write every vertex before reading it
/// (as [`umbrella_pass`] does): zeros written in parallel (nothing is read; `Padded` has no
/// lazily zeroed allocation, so `vec!` would fill it on one thread), the sentinel zero.
pub fn written_before_read(values: &[Padded]) -> Vec<Padded> {
    let mut out = crate::hugepages::with_capacity(values.len());
    (0..values.len())
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|_| Padded::ZERO)
        .collect_into_vec(&mut out);
    out
}

/// The values of a working copy made by [`padded`], without its sentinel.
pub fn unpadded(values: &[Padded]) -> Vec<[f32; 3]> {
    let mut out = crate::hugepages::with_capacity(values.len().saturating_sub(1));
    values[..values.len().saturating_sub(1)]
        .par_iter()
        .with_min_len(CHUNK)
        .map(|p| p.truncate().to_array())
        .collect_into_vec(&mut out);
    out
}

/// Neighbours a kernel reads for every vertex at once, from its row. Longer lists (rare on
/// surfaces: marching-cubes vertices have 3-9 neighbours, mostly 6) read the rest from the
/// CSR lists after the row.
pub const WINDOW: usize = 8;

/// A vertex adjacency (CSR) as iterated kernels read it: a row of [`WINDOW`] neighbours per
/// vertex, its list then the sentinel (vertex n, the zero vector of a [`padded`] copy), summed
/// in a loop of fixed length (no data-dependent branch: a loop of varying count mispredicts at
/// almost every vertex), and each vertex's 1 / degree. Rows cost a pass to make and 36 bytes a
/// vertex; they save the two offsets and a select per neighbour that reading the CSR lists in
/// a window costs, about 15 % of a pass. Borrows the mesh's CSR lists, or holds them renumbered.
#[derive(Debug, Clone)]
pub struct NeighbourLists<'a> {
    offsets: Cow<'a, [u32]>,
    neighbors: Cow<'a, [u32]>,
    rows: Vec<[u32; WINDOW]>,
    /// 1 / degree, rounded as `1.0 / degree as f32`; below 1 / WINDOW for the long lists.
    inverse_degree: Vec<f32>,
}

impl<'a> NeighbourLists<'a> {
    /// The adjacency (CSR `offsets`, `neighbors`); with a renumbering, in its new numbering
    /// (vertex i is vertex `old[i]`, each list in the same order, so sums round as before).
    pub fn new(
        offsets: &'a [u32],
        neighbors: &'a [u32],
        renumbering: Option<&Renumbering>,
    ) -> NeighbourLists<'a> {
        let (offsets, neighbors) = match renumbering {
            None => (Cow::Borrowed(offsets), Cow::Borrowed(neighbors)),
            Some(r) => {
                let (offsets, neighbors) = renumbered(r, offsets, neighbors);
                (Cow::Owned(offsets), Cow::Owned(neighbors))
            }
        };
        let n = offsets.len().saturating_sub(1);
        let sentinel = n as u32;
        let list = |v: usize| &neighbors[offsets[v] as usize..offsets[v + 1] as usize];
        // One pass makes both, chunk by chunk (into zeroed buffers: fresh pages, no writes).
        let mut rows: Vec<[u32; WINDOW]> = crate::hugepages::zeroed_vec(n);
        let mut inverse_degree: Vec<f32> = crate::hugepages::zeroed_vec(n);
        rows.par_chunks_mut(CHUNK)
            .zip(inverse_degree.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(c, (rows, inverse))| {
                for (i, (row, inverse)) in rows.iter_mut().zip(inverse).enumerate() {
                    let list = list(c * CHUNK + i);
                    *row = std::array::from_fn(|k| list.get(k).copied().unwrap_or(sentinel));
                    *inverse = 1.0 / list.len() as f32;
                }
            });
        NeighbourLists {
            offsets,
            neighbors,
            rows,
            inverse_degree,
        }
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Whether the lists are of a mesh without vertices.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Mean of `values` (a [`padded`] copy) over v's neighbours, summed in list order; v must
    /// have some. Adding the sentinel's zero changes no bit: a sum that starts at +0 is never
    /// -0.
    #[inline(always)]
    pub fn mean(&self, values: &[Padded], v: usize) -> Padded {
        let mut sum = Padded::ZERO;
        for &w in &self.rows[v] {
            sum += values[w as usize];
        }
        let inverse = self.inverse_degree[v];
        if inverse < 1.0 / WINDOW as f32 {
            let (start, end) = (self.offsets[v] as usize, self.offsets[v + 1] as usize);
            for &w in &self.neighbors[start + WINDOW..end] {
                sum += values[w as usize];
            }
        }
        sum * inverse
    }
}

/// The adjacency (CSR offsets and neighbours) in the new numbering of `r`; every vertex keeps
/// its neighbours in the same order.
fn renumbered(r: &Renumbering, offsets: &[u32], neighbors: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let mut new_offsets = Vec::with_capacity(offsets.len());
    new_offsets.push(0u32);
    let mut end = 0u32;
    for &v in &r.old {
        end += offsets[v as usize + 1] - offsets[v as usize];
        new_offsets.push(end);
    }
    // Names first, in the old layout (a streaming pass), then each list moved whole.
    let renamed: Vec<u32> = neighbors
        .par_iter()
        .with_min_len(1 << 14)
        .map(|&w| r.new[w as usize])
        .collect();
    let mut new_neighbors = vec![0u32; neighbors.len()];
    // The lists of each block of new vertices are one stretch: blocks are filled in parallel.
    const BLOCK: usize = 16 * 1024;
    let mut blocks: Vec<(&[u32], &mut [u32])> = Vec::new();
    let mut rest = new_neighbors.as_mut_slice();
    for (b, vertices) in r.old.chunks(BLOCK).enumerate() {
        let (first, stop) = (b * BLOCK, b * BLOCK + vertices.len());
        let len = (new_offsets[stop] - new_offsets[first]) as usize;
        let (head, tail) = rest.split_at_mut(len);
        blocks.push((vertices, head));
        rest = tail;
    }
    blocks.into_par_iter().for_each(|(vertices, out)| {
        let mut k = 0;
        for &v in vertices {
            let list = &renamed[offsets[v as usize] as usize..offsets[v as usize + 1] as usize];
            out[k..k + list.len()].copy_from_slice(list);
            k += list.len();
        }
    });
    (new_offsets, new_neighbors)
}

/// One umbrella pass from `src` into `dst` (both [`padded`] copies; the sentinel is not
/// written): v + factor * scale_v * (mean(neighbours) - v), optionally clamped into the box of
/// +-voxel/2 around the original position.
#[inline]
pub fn umbrella_pass(
    src: &[Padded],
    dst: &mut [Padded],
    rows: &NeighbourLists<'_>,
    scale: &[f32],
    factor: f32,
    clamp: Option<(&[[f32; 3]], [f32; 3])>,
) {
    let n = rows.len();
    dst[..n]
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, out)| {
            let first = c * CHUNK;
            let own = first..first + out.len();
            let vertices = src[own.clone()].iter().zip(&scale[own]);
            for (i, (o, (&p, &w))) in out.iter_mut().zip(vertices).enumerate() {
                let s = factor * w;
                if s == 0.0 {
                    *o = p;
                    continue;
                }
                let mut r = p + (rows.mean(src, first + i) - p) * s;
                if let Some((original, voxel)) = clamp {
                    let o0 = original[first + i];
                    for k in 0..3 {
                        let h = 0.5 * voxel[k];
                        r[k] = o0[k] + (r[k] - o0[k]).clamp(-h, h);
                    }
                }
                *o = r;
            }
        });
}
