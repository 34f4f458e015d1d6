//! Welding of triangle-soup corners (STL) into shared vertices: corners with bit-identical
//! coordinates (+0 and -0 taken as equal) become one vertex, numbered in order of first
//! appearance. Parallel and deterministic: the result is the one a sequential hash-map pass
//! gives, for any thread count.
//!
//! Corners go to shards by a hash of their coordinates, each chunk of the file keeping its own
//! list per shard (so a shard's corners stay in file order and nothing is scattered). Each
//! shard numbers its distinct coordinates with a hash map small enough to stay in cache; the
//! global vertex numbers are the ranks of the first corners in file order (a bitmap with
//! per-word counts), and a last walk in file order reads every corner's vertex back from its
//! shard.

use rayon::prelude::*;
use rustc_hash::FxHashMap;
use std::hash::{Hash, Hasher};
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

/// Shards of the corner set: 256 keeps each shard's map near 10 k vertices for a 2.5 M vertex
/// mesh.
const SHARDS: usize = 256;
/// Corners per parallel chunk in the passes over all corners.
const CHUNK: usize = 1 << 16;

/// The welding key of a corner: its coordinates' bits, with -0 turned into +0. Hashed as one
/// mixed word (one multiply in the map's hasher instead of three rounds).
#[derive(Clone, Copy, PartialEq, Eq)]
struct Key([u32; 3]);

impl Key {
    fn of(p: [f32; 3]) -> Key {
        Key(p.map(|v| (v + 0.0).to_bits()))
    }

    fn mixed(&self) -> u64 {
        let [x, y, z] = self.0.map(u64::from);
        (x | y << 32).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ z.wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
    }

    /// The shard, from bits of the mix that the maps' hash does not lean on.
    fn shard(&self) -> usize {
        (self.mixed().rotate_left(17) >> 56) as usize % SHARDS
    }
}

impl Hash for Key {
    fn hash<H: Hasher>(&self, state: &mut H) {
        state.write_u64(self.mixed());
    }
}

/// Welds `n` corners (`corner(c)` gives corner c's coordinates): the vertex positions in
/// order of first appearance, and each corner's vertex number. `n` must fit in u32.
pub(crate) fn weld_corners(
    n: usize,
    corner: impl Fn(usize) -> [f32; 3] + Sync,
) -> (Vec<[f32; 3]>, Vec<u32>) {
    let chunks = n.div_ceil(CHUNK);
    let range = |c: usize| c * CHUNK..((c + 1) * CHUNK).min(n);
    // Each corner's shard; then per chunk, its corners grouped by shard (file order within a
    // shard), in place of the chunk's stretch of two flat arrays. Flat and advised huge, so
    // the hundreds of MB cost a few hundred page faults, not tens of thousands.
    let mut shard_of: Vec<u8> = crate::hugepages::zeroed_vec(n);
    let mut grouped: Vec<u32> = crate::hugepages::zeroed_vec(n);
    let mut grouped_at: Vec<[f32; 3]> = crate::hugepages::zeroed_vec(n);
    // Per chunk: where each shard's entries start in its stretch (SHARDS + 1 bounds).
    let starts: Vec<Vec<u32>> = shard_of
        .par_chunks_mut(CHUNK)
        .zip(grouped.par_chunks_mut(CHUNK))
        .zip(grouped_at.par_chunks_mut(CHUNK))
        .enumerate()
        .map(|(c, ((shards, corners), positions))| {
            for (slot, i) in shards.iter_mut().zip(range(c)) {
                *slot = Key::of(corner(i)).shard() as u8;
            }
            let mut start = vec![0u32; SHARDS + 1];
            for &s in shards.iter() {
                start[s as usize + 1] += 1;
            }
            for s in 0..SHARDS {
                start[s + 1] += start[s];
            }
            let mut next = start.clone();
            for (i, &s) in range(c).zip(shards.iter()) {
                let at = next[s as usize] as usize;
                corners[at] = i as u32;
                positions[at] = corner(i);
                next[s as usize] += 1;
            }
            start
        })
        .collect();
    // Per shard: each corner's local vertex (in the shard's file order) and the first corner
    // and position of each local vertex. First corners are marked in a bitmap over all
    // corners.
    let words = n.div_ceil(64);
    let firsts_bits: Vec<AtomicU64> = (0..words).map(|_| AtomicU64::new(0)).collect();
    // Each corner's local vertex, shard after shard (one flat array, split by shard sizes).
    let sizes: Vec<usize> = (0..SHARDS)
        .map(|s| {
            starts
                .iter()
                .map(|start| (start[s + 1] - start[s]) as usize)
                .sum()
        })
        .collect();
    let mut local_all: Vec<u32> = crate::hugepages::zeroed_vec(n);
    let mut local_parts: Vec<&mut [u32]> = Vec::with_capacity(SHARDS);
    let mut rest = local_all.as_mut_slice();
    for &size in &sizes {
        let (part, tail) = rest.split_at_mut(size);
        local_parts.push(part);
        rest = tail;
    }
    let shards: Vec<(Vec<u32>, Vec<[f32; 3]>)> = local_parts
        .into_par_iter()
        .enumerate()
        .map(|(s, local)| {
            let mut seen: FxHashMap<Key, u32> =
                FxHashMap::with_capacity_and_hasher(local.len() / 4 + 1, Default::default());
            let mut slots = local.iter_mut();
            let mut first = Vec::new();
            let mut positions = Vec::new();
            for (c, start) in starts.iter().enumerate() {
                let own = c * CHUNK + start[s] as usize..c * CHUNK + start[s + 1] as usize;
                for (&c, &p) in (&grouped)[own.clone()].iter().zip(&(&grouped_at)[own]) {
                    let next = first.len() as u32;
                    let v = *seen.entry(Key::of(p)).or_insert(next);
                    if v == next {
                        first.push(c);
                        positions.push(p);
                        firsts_bits[c as usize / 64].fetch_or(1 << (c % 64), Ordering::Relaxed);
                    }
                    if let Some(slot) = slots.next() {
                        *slot = v;
                    }
                }
            }
            (first, positions)
        })
        .collect();
    drop((grouped, grouped_at));
    let shard_offset: Vec<usize> = sizes
        .iter()
        .scan(0, |at, &size| {
            let start = *at;
            *at += size;
            Some(start)
        })
        .collect();
    let firsts_bits: Vec<u64> = firsts_bits.into_iter().map(AtomicU64::into_inner).collect();
    // Vertex number of a first corner: how many first corners come before it.
    let mut before_word = Vec::with_capacity(words + 1);
    let mut count = 0u32;
    for w in &firsts_bits {
        before_word.push(count);
        count += w.count_ones();
    }
    let n_vertices = count as usize;
    let rank = |c: u32| {
        let (w, b) = (c as usize / 64, c % 64);
        before_word[w] + (firsts_bits[w] & ((1u64 << b) - 1)).count_ones()
    };
    // Per shard, its local vertices' global numbers; positions scattered to them (each vertex
    // is written by exactly one shard).
    let global: Vec<Vec<u32>> = shards
        .par_iter()
        .map(|(first, _)| first.iter().map(|&c| rank(c)).collect())
        .collect();
    let slots: Vec<[AtomicU32; 3]> = (0..n_vertices)
        .map(|_| [AtomicU32::new(0), AtomicU32::new(0), AtomicU32::new(0)])
        .collect();
    shards
        .par_iter()
        .zip(&global)
        .for_each(|((_, positions), global)| {
            for (&g, p) in global.iter().zip(positions) {
                for (slot, x) in slots[g as usize].iter().zip(p) {
                    slot.store(x.to_bits(), Ordering::Relaxed);
                }
            }
        });
    let positions: Vec<[f32; 3]> = slots
        .into_par_iter()
        .map(|s| s.map(|x| f32::from_bits(x.into_inner())))
        .collect();
    // Where each chunk's corners start in each shard's list.
    let mut part_start = vec![[0u32; SHARDS]; chunks];
    let mut at = [0u32; SHARDS];
    for (c, start) in starts.iter().enumerate() {
        part_start[c] = at;
        for (s, a) in at.iter_mut().enumerate() {
            *a += start[s + 1] - start[s];
        }
    }
    // Back in file order: each corner's vertex, read from its shard.
    let (global, local_all) = (&global, &local_all);
    let mut vertex_of: Vec<u32> = crate::hugepages::zeroed_vec(n);
    vertex_of
        .par_chunks_mut(CHUNK)
        .zip(shard_of.par_chunks(CHUNK))
        .zip(&part_start)
        .for_each(|((out, shards), start)| {
            let mut next = *start;
            for (v, &s) in out.iter_mut().zip(shards) {
                let s = s as usize;
                *v = global[s][local_all[shard_offset[s] + next[s] as usize] as usize];
                next[s] += 1;
            }
        });
    (positions, vertex_of)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sequential reference: one hash map over all corners in file order.
    fn weld_sequential(corners: &[[f32; 3]]) -> (Vec<[f32; 3]>, Vec<u32>) {
        let mut index: FxHashMap<[u32; 3], u32> = FxHashMap::default();
        let mut positions = Vec::new();
        let numbers = corners
            .iter()
            .map(|&p| {
                *index.entry(Key::of(p).0).or_insert_with(|| {
                    positions.push(p);
                    positions.len() as u32 - 1
                })
            })
            .collect();
        (positions, numbers)
    }

    #[test]
    fn parallel_welding_matches_the_sequential_pass_on_random_soups() {
        let mut rng = fastrand::Rng::with_seed(11);
        for round in 0..40 {
            // From a handful to a few hundred thousand corners, drawn from a small pool so
            // most repeat; some coordinates are -0.
            let n = [0, 1, 3, 7, 1000, 70_000, 250_000][round % 7];
            let pool: Vec<[f32; 3]> = (0..(n / 5).max(1))
                .map(|_| {
                    std::array::from_fn(|_| match rng.u8(..10) {
                        0 => 0.0,
                        1 => -0.0,
                        _ => rng.f32() * 100.0 - 50.0,
                    })
                })
                .collect();
            let corners: Vec<[f32; 3]> = (0..n).map(|_| pool[rng.usize(..pool.len())]).collect();
            let (p, v) = weld_corners(n, |c| corners[c]);
            let (q, w) = weld_sequential(&corners);
            assert_eq!(v, w, "round {round}: vertex numbers");
            assert_eq!(
                p.iter().map(|x| Key::of(*x).0).collect::<Vec<_>>(),
                q.iter().map(|x| Key::of(*x).0).collect::<Vec<_>>(),
                "round {round}: positions"
            );
        }
    }

    #[test]
    fn welding_does_not_depend_on_the_thread_count() {
        let mut rng = fastrand::Rng::with_seed(5);
        let corners: Vec<[f32; 3]> = (0..200_000)
            .map(|_| std::array::from_fn(|_| rng.u8(..20) as f32))
            .collect();
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| weld_corners(corners.len(), |c| corners[c]));
        let three = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap()
            .install(|| weld_corners(corners.len(), |c| corners[c]));
        assert_eq!(one, three);
    }
}
