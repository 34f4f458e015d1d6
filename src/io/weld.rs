//! Welding of triangle-soup corners (STL) into shared vertices: corners with bit-identical
//! coordinates (+0 and -0 taken as equal) become one vertex, numbered in order of first
//! appearance. Parallel and deterministic: the result is the one a sequential hash-map pass
//! gives, for any thread count.
//!
//! 1. Each chunk of the file welds its own corners with a hash map that stays in cache. Files
//!    list a vertex's triangles close together, so a chunk's distinct coordinates (its
//!    *entries*) are about a fifth of its corners (3.2 M entries for 15 M corners on the 5 M
//!    triangle phantom). The same pass finds the first coordinate that is not valid (NaN,
//!    infinite, beyond +-1e7 mm).
//! 2. Entries go to shards by a hash of their coordinates (each chunk keeping its own list per
//!    shard, in its order). Each shard numbers its distinct coordinates with a small map, in
//!    chunk order, so a vertex's first entry holds its first corner in the file.
//! 3. The global vertex numbers are the ranks of the first corners in file order (a bitmap
//!    with per-word counts), and a last walk per chunk turns its corners' local numbers into
//!    vertex numbers.

use crate::mesh::is_valid_coordinate;
use crate::parallel::split_lengths;
use rayon::prelude::*;
use rustc_hash::FxHashMap;
use std::hash::{Hash, Hasher};
use std::sync::atomic::{AtomicU64, Ordering};

/// Shards of the entry set: 256 keeps each shard's map near 10 k vertices for a 2.5 M vertex
/// mesh.
const SHARDS: usize = 256;
/// Triangles per chunk: 65,535 corners, so a chunk's local numbers fit below 2^16 and its map
/// stays in cache.
const CHUNK_TRIANGLES: usize = 21_845;

/// The welding key of a corner: its coordinates' bits, with -0 turned into +0. Hashed as one
/// mixed word (one multiply in the map's hasher instead of three rounds).
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Key(pub [u32; 3]);

impl Key {
    /// The key of a corner at `p` (mm).
    pub fn of(p: [f32; 3]) -> Key {
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

/// One chunk's distinct coordinates after step 1, grouped by shard (the chunk's order kept
/// within a shard), and each entry's shard in the chunk's order.
struct ChunkEntries {
    /// Per shard, where its entries start in `first` and `positions` (SHARDS + 1 bounds).
    start: Vec<u32>,
    /// The file index of each entry's first corner, grouped by shard.
    first: Vec<u32>,
    /// Each entry's coordinates, grouped by shard.
    positions: Vec<[f32; 3]>,
    /// Each entry's shard, in the chunk's order (local numbers).
    shard_of: Vec<u8>,
}

/// Vertex positions in order of first appearance and each triangle's vertices.
pub(crate) type Welded = (Vec<[f32; 3]>, Vec<[u32; 3]>);

/// Welds `n_triangles` triangles (`corner(c)` gives the coordinates of corner c, corner
/// `3 t + k` being corner k of triangle t): the vertex positions in order of first appearance
/// and each triangle's vertices. `Err(c)` names the first corner with a coordinate that is not
/// [valid](crate::mesh::is_valid_coordinate) (NaN, infinite, or beyond +-1e7 mm).
/// `3 n_triangles` must fit in u32.
pub fn weld_triangles(
    n_triangles: usize,
    corner: impl Fn(usize) -> [f32; 3] + Sync,
) -> Result<Welded, usize> {
    let n = 3 * n_triangles;
    // Step 1: per chunk, its corners' local numbers (in the output, replaced in step 3) and
    // its entries.
    let mut triangles: Vec<[u32; 3]> = crate::hugepages::zeroed_vec(n_triangles);
    let chunks: Vec<Result<ChunkEntries, usize>> = triangles
        .par_chunks_mut(CHUNK_TRIANGLES)
        .enumerate()
        .map_init(
            // Sized for a chunk, or for the whole file when it is smaller.
            || FxHashMap::<Key, u32>::with_capacity_and_hasher(n.min(1 << 15), Default::default()),
            |seen, (c, out)| weld_chunk(seen, 3 * c * CHUNK_TRIANGLES, out, &corner),
        )
        .collect();
    let chunks: Vec<ChunkEntries> = chunks.into_iter().collect::<Result<_, _>>()?;
    // Step 2: per shard, each entry's local vertex (in the shard's order) and the first corner
    // of each local vertex. First corners are marked in a bitmap over all corners.
    let words = n.div_ceil(64);
    let firsts_bits: Vec<AtomicU64> = (0..words).map(|_| AtomicU64::new(0)).collect();
    let sizes: Vec<usize> = (0..SHARDS)
        .map(|s| {
            chunks
                .iter()
                .map(|e| (e.start[s + 1] - e.start[s]) as usize)
                .sum()
        })
        .collect();
    // Each entry's local vertex, shard after shard (one flat array, split by shard sizes).
    let mut local_all: Vec<u32> = crate::hugepages::zeroed_vec(sizes.iter().sum());
    let shards: Vec<Vec<u32>> = split_lengths(sizes.iter().copied(), &mut local_all)
        .into_par_iter()
        .enumerate()
        .map(|(s, local)| {
            let mut seen: FxHashMap<Key, u32> =
                FxHashMap::with_capacity_and_hasher(local.len() / 2 + 1, Default::default());
            let mut slots = local.iter_mut();
            let mut first = Vec::new();
            for e in &chunks {
                let own = e.start[s] as usize..e.start[s + 1] as usize;
                for (&c, &p) in e.first[own.clone()].iter().zip(&e.positions[own]) {
                    let next = first.len() as u32;
                    let v = *seen.entry(Key::of(p)).or_insert(next);
                    if v == next {
                        first.push(c);
                        firsts_bits[c as usize / 64].fetch_or(1 << (c % 64), Ordering::Relaxed);
                    }
                    if let Some(slot) = slots.next() {
                        *slot = v;
                    }
                }
            }
            first
        })
        .collect();
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
    before_word.push(count);
    let rank = |c: u32| {
        let (w, b) = (c as usize / 64, c % 64);
        before_word[w] + (firsts_bits[w] & ((1u64 << b) - 1)).count_ones()
    };
    // Per shard, its local vertices' global numbers.
    let global: Vec<Vec<u32>> = shards
        .par_iter()
        .map(|first| first.iter().map(|&c| rank(c)).collect())
        .collect();
    // The positions: the first corners in file order, read back from the file by stretches
    // of the bitmap (each stretch fills its own run of vertices).
    const WORDS: usize = 4096;
    let mut positions: Vec<[f32; 3]> = crate::hugepages::zeroed_vec(count as usize);
    let firsts_per_stretch = (0..words)
        .step_by(WORDS)
        .map(|w| (before_word[(w + WORDS).min(words)] - before_word[w]) as usize);
    let stretches = split_lengths(firsts_per_stretch, &mut positions);
    stretches.into_par_iter().enumerate().for_each(|(k, out)| {
        let w0 = k * WORDS;
        let mut out = out.iter_mut();
        for (w, &bits) in firsts_bits.iter().enumerate().skip(w0).take(WORDS) {
            let mut bits = bits;
            while bits != 0 {
                let c = w * 64 + bits.trailing_zeros() as usize;
                if let Some(o) = out.next() {
                    *o = corner(c);
                }
                bits &= bits - 1;
            }
        }
    });
    // Where each chunk's entries start in each shard's list.
    let mut part_start = vec![[0u32; SHARDS]; chunks.len()];
    let mut at = [0u32; SHARDS];
    for (c, e) in chunks.iter().enumerate() {
        part_start[c] = at;
        for (s, a) in at.iter_mut().enumerate() {
            *a += e.start[s + 1] - e.start[s];
        }
    }
    // Step 3: per chunk, each entry's vertex, read from its shard, and each corner's vertex
    // from its entry.
    let (global, local_all) = (&global, &local_all);
    triangles
        .par_chunks_mut(CHUNK_TRIANGLES)
        .zip(&chunks)
        .zip(&part_start)
        .for_each_init(Vec::new, |vertex_of, ((out, e), start)| {
            let mut next = *start;
            vertex_of.clear();
            vertex_of.extend(e.shard_of.iter().map(|&s| {
                let s = s as usize;
                let v = global[s][local_all[shard_offset[s] + next[s] as usize] as usize];
                next[s] += 1;
                v
            }));
            for t in out.iter_mut() {
                *t = t.map(|local| vertex_of[local as usize]);
            }
        });
    Ok((positions, triangles))
}

/// Step 1 for the chunk whose first corner is `first`: writes each corner's local number
/// (order of first appearance in the chunk) into `out` and returns the chunk's entries, or
/// the first corner with a coordinate that is not valid.
fn weld_chunk(
    seen: &mut FxHashMap<Key, u32>,
    first: usize,
    out: &mut [[u32; 3]],
    corner: &impl Fn(usize) -> [f32; 3],
) -> Result<ChunkEntries, usize> {
    seen.clear();
    let mut entry_first: Vec<u32> = Vec::new();
    let mut entry_at: Vec<[f32; 3]> = Vec::new();
    let mut finite = true;
    for (t, tri) in out.iter_mut().enumerate() {
        for (k, local) in tri.iter_mut().enumerate() {
            let c = first + 3 * t + k;
            let p = corner(c);
            finite &= p.iter().all(|&v| is_valid_coordinate(v));
            let next = entry_first.len() as u32;
            *local = *seen.entry(Key::of(p)).or_insert(next);
            if *local == next {
                entry_first.push(c as u32);
                entry_at.push(p);
            }
        }
    }
    if !finite {
        let bad = (first..first + 3 * out.len())
            .find(|&c| !corner(c).iter().all(|&v| is_valid_coordinate(v)))
            .unwrap_or(first);
        return Err(bad);
    }
    // The entries grouped by shard, in the chunk's order within a shard.
    let shard_of: Vec<u8> = entry_at.iter().map(|&p| Key::of(p).shard() as u8).collect();
    let mut start = vec![0u32; SHARDS + 1];
    for &s in &shard_of {
        start[s as usize + 1] += 1;
    }
    for s in 0..SHARDS {
        start[s + 1] += start[s];
    }
    let mut next = start.clone();
    let mut grouped_first = vec![0u32; entry_first.len()];
    let mut grouped_at = vec![[0.0f32; 3]; entry_at.len()];
    for ((&s, &c), &p) in shard_of.iter().zip(&entry_first).zip(&entry_at) {
        let at = next[s as usize] as usize;
        grouped_first[at] = c;
        grouped_at[at] = p;
        next[s as usize] += 1;
    }
    Ok(ChunkEntries {
        start,
        first: grouped_first,
        positions: grouped_at,
        shard_of,
    })
}
