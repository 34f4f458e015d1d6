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
pub(crate) const CHUNK: usize = 2048;

/// Mean of `values` over the given neighbour indices (callers ensure the list is not empty).
#[inline]
pub(crate) fn neighbour_mean(values: &[[f32; 3]], neighbors: &[u32]) -> [f32; 3] {
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
pub(crate) type Padded = glam::Vec4;

/// A kernel's working copy of per-vertex vectors: the values padded, then one zero vector, the
/// sentinel that [`NeighbourLists`] fill short rows with.
pub(crate) fn padded(values: &[[f32; 3]]) -> Vec<Padded> {
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
pub(crate) fn copied(values: &[Padded]) -> Vec<Padded> {
    let mut out = crate::hugepages::with_capacity(values.len());
    out.extend_from_slice(values);
    out
}

/// The values of a working copy made by [`padded`], without its sentinel.
pub(crate) fn unpadded(values: &[Padded]) -> Vec<[f32; 3]> {
    values[..values.len().saturating_sub(1)]
        .par_iter()
        .with_min_len(CHUNK)
        .map(|p| p.truncate().to_array())
        .collect()
}

/// Neighbours a kernel reads for every vertex at once: a vertex's list and the entries after it,
/// the ones past its list counted as the sentinel. Longer lists (rare on surfaces:
/// marching-cubes vertices have 3-9 neighbours, mostly 6) are read in a loop of their own length.
pub(crate) const WINDOW: usize = 8;

/// A vertex adjacency (CSR) as iterated kernels read it: every list of up to [`WINDOW`]
/// neighbours in a loop of fixed length (no data-dependent branch; a loop of varying count
/// mispredicts at almost every vertex), the entries past the list replaced by the sentinel
/// (vertex n, the zero vector of a [`padded`] copy). Borrows the mesh's adjacency, or holds it
/// renumbered.
#[derive(Debug, Clone)]
pub(crate) struct NeighbourLists<'a> {
    offsets: Cow<'a, [u32]>,
    neighbors: Cow<'a, [u32]>,
}

impl<'a> NeighbourLists<'a> {
    /// The adjacency (CSR `offsets`, `neighbors`); with a renumbering, in its new numbering
    /// (vertex i is vertex `old[i]`, each list in the same order, so sums round as before).
    pub(crate) fn new(
        offsets: &'a [u32],
        neighbors: &'a [u32],
        renumbering: Option<&Renumbering>,
    ) -> NeighbourLists<'a> {
        match renumbering {
            None => NeighbourLists {
                offsets: Cow::Borrowed(offsets),
                neighbors: Cow::Borrowed(neighbors),
            },
            Some(r) => {
                let (offsets, neighbors) = renumbered(r, offsets, neighbors);
                NeighbourLists {
                    offsets: Cow::Owned(offsets),
                    neighbors: Cow::Owned(neighbors),
                }
            }
        }
    }

    /// Number of vertices.
    pub(crate) fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Sum of `values` (a [`padded`] copy) over v's neighbours, in list order, and their
    /// number. Adding the sentinel's zero changes no bit: a sum that starts at +0 is never -0.
    #[inline(always)]
    fn sum(&self, values: &[Padded], v: usize) -> (Padded, usize) {
        let (start, end) = (self.offsets[v] as usize, self.offsets[v + 1] as usize);
        let degree = end.saturating_sub(start);
        let sentinel = self.len() as u32;
        let mut sum = Padded::ZERO;
        match self.neighbors.get(start..start + WINDOW) {
            Some(window) if degree <= WINDOW => {
                for (k, &w) in window.iter().enumerate() {
                    let w = if k < degree { w } else { sentinel };
                    sum += values[w as usize];
                }
            }
            _ => {
                for &w in &self.neighbors[start..end] {
                    sum += values[w as usize];
                }
            }
        }
        (sum, degree)
    }

    /// Mean of `values` (a [`padded`] copy) over v's neighbours; v must have some.
    #[inline(always)]
    pub(crate) fn mean(&self, values: &[Padded], v: usize) -> Padded {
        let (sum, degree) = self.sum(values, v);
        sum * (1.0 / degree as f32)
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
pub(crate) fn umbrella_pass(
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A random adjacency: degrees 0-20 (a sixth of them longer than a row), any neighbours.
    fn random_csr(n: usize, seed: u64) -> (Vec<u32>, Vec<u32>) {
        let mut rng = fastrand::Rng::with_seed(seed);
        let (mut offsets, mut neighbors) = (vec![0u32], Vec::new());
        for _ in 0..n {
            let degree = if rng.u8(0..6) == 0 {
                rng.usize(WINDOW + 1..=20)
            } else {
                rng.usize(0..=WINDOW)
            };
            neighbors.extend((0..degree).map(|_| rng.u32(0..n as u32)));
            offsets.push(neighbors.len() as u32);
        }
        (offsets, neighbors)
    }

    fn random_values(n: usize, rng: &mut fastrand::Rng) -> Vec<[f32; 3]> {
        (0..n)
            .map(|_| std::array::from_fn(|_| (rng.f32() - 0.5) * 200.0))
            .collect()
    }

    /// The old numbering's list of new vertex i, renamed.
    fn renamed_list(
        (offsets, neighbors): (&[u32], &[u32]),
        r: Option<&Renumbering>,
        i: usize,
    ) -> Vec<u32> {
        let v = r.map_or(i, |r| r.old[i] as usize);
        neighbors[offsets[v] as usize..offsets[v + 1] as usize]
            .iter()
            .map(|&w| r.map_or(w, |r| r.new[w as usize]))
            .collect()
    }

    /// Rows give every vertex's mean with the bits of a plain loop over its CSR list, in the
    /// mesh's numbering and in a renumbering, short and long lists alike.
    #[test]
    fn row_means_have_the_bits_of_the_plain_loop() {
        let n = 3000;
        let (offsets, neighbors) = random_csr(n, 1);
        let mut rng = fastrand::Rng::with_seed(2);
        let values = random_values(n, &mut rng);
        let mut old: Vec<u32> = (0..n as u32).collect();
        rng.shuffle(&mut old);
        let mut new = vec![0u32; n];
        for (i, &v) in old.iter().enumerate() {
            new[v as usize] = i as u32;
        }
        let shuffle = Renumbering { old, new };
        for r in [None, Some(&shuffle)] {
            let rows = NeighbourLists::new(&offsets, &neighbors, r);
            assert_eq!(rows.len(), n);
            let in_rows: Vec<[f32; 3]> = r.map_or(values.clone(), |r| r.gather(&values));
            let padded_values = padded(&in_rows);
            let (mut long, mut checked) = (0, 0);
            for i in 0..n {
                let list = renamed_list((&offsets, &neighbors), r, i);
                if list.is_empty() {
                    continue;
                }
                long += usize::from(list.len() > WINDOW);
                checked += 1;
                let want = neighbour_mean(&in_rows, &list);
                let got = rows.mean(&padded_values, i);
                assert_eq!(
                    got.to_array().map(f32::to_bits)[..3],
                    want.map(f32::to_bits)
                );
                assert_eq!(got.w, 0.0);
            }
            assert!(long > 300 && checked > 2500, "{long} long of {checked}");
        }
    }

    /// A pass equals the scalar umbrella step vertex by vertex, bit for bit, with fixed
    /// vertices, with and without the node-position clamp; the sentinel stays zero.
    #[test]
    fn a_pass_has_the_bits_of_the_scalar_step() {
        let n = 2000;
        let (offsets, neighbors) = random_csr(n, 3);
        let mut rng = fastrand::Rng::with_seed(4);
        let original = random_values(n, &mut rng);
        let scale: Vec<f32> = (0..n)
            .map(|v| {
                if offsets[v] == offsets[v + 1] || rng.u8(0..5) == 0 {
                    0.0
                } else {
                    rng.f32()
                }
            })
            .collect();
        let rows = NeighbourLists::new(&offsets, &neighbors, None);
        for clamp in [None, Some([0.7f32, 0.9, 2.1])] {
            let src = padded(&original);
            let mut dst = copied(&src);
            umbrella_pass(
                &src,
                &mut dst,
                &rows,
                &scale,
                0.5,
                clamp.map(|v| (&original[..], v)),
            );
            assert_eq!(dst[n], Padded::ZERO);
            let got = unpadded(&dst);
            for v in 0..n {
                let (p, s) = (original[v], 0.5 * scale[v]);
                let want = if s == 0.0 {
                    p
                } else {
                    let list = &neighbors[offsets[v] as usize..offsets[v + 1] as usize];
                    let m = neighbour_mean(&original, list);
                    std::array::from_fn(|k| {
                        let r = p[k] + s * (m[k] - p[k]);
                        match clamp {
                            Some(voxel) => {
                                let h = 0.5 * voxel[k];
                                p[k] + (r - p[k]).clamp(-h, h)
                            }
                            None => r,
                        }
                    })
                };
                assert_eq!(
                    got[v].map(f32::to_bits),
                    want.map(f32::to_bits),
                    "vertex {v}"
                );
            }
        }
    }
}
