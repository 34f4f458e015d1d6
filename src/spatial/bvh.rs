//! Exact nearest-point queries over a mesh's triangles, near the surface or centimetres away.
//!
//! A query first looks at the triangles of its own grid cell and the 26 around it
//! (the `cells` module); on or near the surface that settles it. Any other query goes to a
//! bounding volume hierarchy, which prunes whole regions out of reach at once, so its cost
//! grows with the logarithm of the mesh size whatever the distance (searching a grid ring by
//! ring grows with the cube of the distance). Four children per node, their boxes tested
//! together; built by two median splits per node on the longest axis of the box centres
//! (subtrees in parallel), nodes depth first, at most four triangles per leaf, with the
//! leaves' corners copied in leaf order.

use super::{dot, max, point_triangle_distance, point_triangle_distance2, sub, triangle_box};
use crate::mesh::Mesh;
use rayon::prelude::*;

/// Most triangles in a leaf.
pub const LEAF: usize = 4;
/// Most triangles whose boxes are tested together (a leaf's, or a stretch of a cell's list).
const BATCH: usize = 8;
/// Most triangles under an inner child (a twig) that gets a disk as a leaf does: near the
/// leaves, where a patch's box is loosest against its flat shape. On a 1 M-triangle surface,
/// 12 mm out, the nodes a query visits at the two lowest levels drop from 7.2 and 12.2 to
/// 4.6 and 6.6; larger twigs (256) cost more than they prune.
pub const TWIG: usize = 64;
/// Subtrees with more triangles than this are built in parallel.
const PARALLEL: usize = 1 << 14;
/// Marks a child that is a leaf: the rest of the word is its first entry in the leaf order.
pub const LEAF_BIT: u32 = 1 << 31;
/// Marks an unused child slot (its box is empty, so no query reaches it).
const NO_CHILD: u32 = u32::MAX;

/// An inner node of four children: their boxes (mm; lane k is child k, so the four are
/// tested together) and, per child, either the index of its node or [`LEAF_BIT`] with the
/// leaf's first entry in the leaf order, and its triangle count: for a leaf, or for a twig
/// (a node of at most [`TWIG`] triangles; 0 for larger nodes). A child with a count has a disk.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub struct Node {
    lo: [[f32; 4]; 3],
    hi: [[f32; 4]; 3],
    child: [u32; 4],
    count: [u32; 4],
}

impl Default for Node {
    fn default() -> Node {
        Node {
            lo: [[f32::INFINITY; 4]; 3],
            hi: [[f32::NEG_INFINITY; 4]; 3],
            child: [NO_CHILD; 4],
            count: [0; 4],
        }
    }
}

/// Where the triangles of a node's leaf and twig children lie, lane k for child k: within `r`
/// (mm) of the centre `c` and within `t` (mm) of the plane through `c` with unit normal `n`.
/// A leaf (or twig) of a gently curved surface is a thin disk, which bounds the distance of a
/// point well above the surface far more tightly than its box.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(64))]
pub struct Disks {
    /// Centres (mm), by axis then child.
    pub c: [[f32; 4]; 3],
    /// Unit normals, by axis then child.
    pub n: [[f32; 4]; 3],
    /// Radii (mm).
    pub r: [f32; 4],
    /// Greatest distances from the plane (mm).
    pub t: [f32; 4],
}

/// The disk of the triangles `corners` (mm): centre, unit normal (area-weighted mean; zero for
/// degenerate leaves), radius and thickness, both rounded up so no corner lies outside.
pub fn leaf_disk(corners: &[[[f32; 3]; 3]]) -> ([f32; 3], [f32; 3], f32, f32) {
    let mut sum = [0.0f64; 3];
    let mut normal = [0.0f64; 3];
    for t in corners {
        let x = t.map(|p| p.map(f64::from));
        let (u, v) = (sub(x[1], x[0]), sub(x[2], x[0]));
        let cross = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        for a in 0..3 {
            normal[a] += cross[a];
            sum[a] += x[0][a] + x[1][a] + x[2][a];
        }
    }
    let count = (3 * corners.len()).max(1) as f64;
    let c = sum.map(|x| (x / count) as f32);
    let len = dot(normal, normal).sqrt();
    let n = if len > 0.0 && len.is_finite() {
        normal.map(|x| (x / len) as f32)
    } else {
        [0.0; 3]
    };
    // Radius and thickness about the stored centre and the stored normal made unit again.
    let m = n.map(f64::from);
    let m_len = dot(m, m).sqrt();
    let m = if m_len > 0.0 { m.map(|x| x / m_len) } else { m };
    let (mut r, mut t) = (0.0f64, 0.0f64);
    for corner in corners.iter().flatten() {
        let w = sub(corner.map(f64::from), c.map(f64::from));
        r = r.max(dot(w, w).sqrt());
        t = t.max(dot(w, m).abs());
    }
    let up = |x: f64| (x * (1.0 + 1e-6)) as f32 + f32::MIN_POSITIVE;
    (c, n, up(r), up(t))
}

/// Squared distances (mm^2) from `q` to the four lanes' disks, lower bounds of their leaves'
/// distances as [`reach2`] needs them: a point of a leaf is at most `t` off the plane and at
/// most `r` from the centre, so its distance is at least the plane gap less `t` and the
/// in-plane gap less `r`. In f32, all four lanes at once, every rounding covered: the offset
/// `w = q - c` as computed is the exact offset of a point within 1.2e-7 |w|_1 of `q`; the
/// plane gap `h` is off by less than 4.2e-7 |w|_1 (rounding and the stored normal's error);
/// the in-plane gap's square `|w|^2 - h^2` by less than 1.6e-6 |w|^2, which shrinking
/// `|w|^2` by 1e-5 more than covers, square root included; both gaps then lose 2e-6 |w|_1
/// and the sum of squares 1e-6 of itself. The in-plane gap thus errs by about 5e-6 |w|^2 /
/// rho, far less than the leaf's size even centimetres away.
#[inline]
pub fn disk_distances2(q: [f32; 3], d: &Disks) -> [f32; 4] {
    let mut h = [0.0f32; 4];
    let mut ww = [0.0f32; 4];
    let mut w1 = [0.0f32; 4];
    for (a, &x) in q.iter().enumerate() {
        for k in 0..4 {
            let w = x - d.c[a][k];
            h[k] += w * d.n[a][k];
            ww[k] += w * w;
            w1[k] += w.abs();
        }
    }
    std::array::from_fn(|k| {
        let rho = max(ww[k] * (1.0 - 1e-5) - h[k] * h[k], 0.0).sqrt();
        let off_plane = max(h[k].abs() - d.t[k] - 2e-6 * w1[k], 0.0);
        let in_plane = max(rho - d.r[k] - 2e-6 * w1[k], 0.0);
        (off_plane * off_plane + in_plane * in_plane) * (1.0 - 1e-6)
    })
}

/// The nearest point of a surface to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// Distance in mm.
    pub distance: f64,
    pub triangle: u32,
}

/// Nearest-triangle queries over a mesh's triangles (by their indices in the mesh): a grid of
/// cells answers queries on and near the surface, the hierarchy the rest. Build once, query
/// many; the same answers for any thread count.
#[derive(Debug, Clone, Default)]
pub struct TriangleBvh {
    /// Corners (mm), in the mesh's order.
    triangles: Vec<[[f32; 3]; 3]>,
    /// The first look of a query: the triangles of its own and the neighbouring cells.
    cells: super::cells::TriangleCells,
    /// Built on the first query the cells do not settle, so indexes only ever asked near
    /// the surface (a Hausdorff distance) never pay for it.
    tree: std::sync::OnceLock<Tree>,
}

/// The hierarchy proper.
#[derive(Debug, Clone, Default)]
pub struct Tree {
    /// Inner nodes, depth first: the root first, a node's first child right after it. None
    /// when every triangle fits in one leaf.
    pub nodes: Vec<Node>,
    /// Triangle indices in leaf order.
    pub order: Vec<u32>,
    /// Their corners (mm), copied in leaf order so a leaf reads one contiguous stretch.
    pub corners: Vec<[[f32; 3]; 3]>,
    /// Per inner node, the disks of its leaf and twig children.
    pub disks: Vec<Disks>,
}

/// The best triangle of a search so far.
struct Best {
    /// Its distance (mm), or the search's bound while there is none.
    distance: f64,
    /// The square `distance` is the root of (for the bound, its square).
    distance2: f64,
    /// u32::MAX while there is none.
    triangle: u32,
    /// [`reach2`] of `distance`.
    reach: f32,
}

impl Best {
    fn within(within: f64) -> Best {
        Best {
            distance: within,
            distance2: within * within,
            triangle: u32::MAX,
            reach: reach2(within),
        }
    }

    /// Takes triangle `f` (corners `t`) if `keep` accepts it and it is closer than the best,
    /// or as close with a lower index (so the answer does not depend on the order triangles
    /// are offered in). `keep` is asked first: a search that rejects most triangles (an
    /// opposite wall) then reads few corners.
    #[inline]
    fn offer(&mut self, p: [f32; 3], f: u32, t: &[[f32; 3]; 3], keep: &impl Fn(u32) -> bool) {
        if !keep(f) {
            return;
        }
        let (lo, hi) = triangle_box(t);
        if box_distance2(p, lo, hi) > self.reach {
            return;
        }
        self.offer_exact(p, f, t);
    }

    /// [`Best::offer`] for `n` (at most [`BATCH`]) triangles, `triangle(i)` giving the index
    /// and corners of the i-th: their boxes first, all into a mask (no branch per triangle),
    /// then `keep` and the exact distance for each whose box is still in reach, in order.
    #[inline]
    fn offer_batch<'a>(
        &mut self,
        p: [f32; 3],
        n: usize,
        triangle: impl Fn(usize) -> (u32, &'a [[f32; 3]; 3]),
        keep: &impl Fn(u32) -> bool,
    ) {
        let mut gaps = [0.0f32; BATCH];
        let mut mask = 0u32;
        for (i, gap) in gaps.iter_mut().enumerate().take(n) {
            let (lo, hi) = triangle_box(triangle(i).1);
            *gap = box_distance2(p, lo, hi);
            mask |= ((*gap <= self.reach) as u32) << i;
        }
        while mask != 0 {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let (f, t) = triangle(i);
            // The best so far (a start offered first, or a triangle listed in two cells)
            // is not measured again.
            if gaps[i] <= self.reach && f != self.triangle && keep(f) {
                self.offer_exact(p, f, t);
            }
        }
    }

    /// [`Best::offer`] past `keep` and the box: the exact distance decides.
    #[inline]
    fn offer_exact(&mut self, p: [f32; 3], f: u32, t: &[[f32; 3]; 3]) {
        // A square further than the best's by more than two units in the last place has a
        // root that rounds further than the best: no root needed.
        let d2 = point_triangle_distance2(p, *t);
        if d2 > self.distance2 * (1.0 + 1e-15) {
            return;
        }
        let d = d2.sqrt();
        if d < self.distance || (d == self.distance && f < self.triangle) {
            self.distance = d;
            self.distance2 = d2;
            self.triangle = f;
            self.reach = reach2(d);
        }
    }

    fn found(&self) -> Option<Nearest> {
        (self.triangle != u32::MAX).then_some(Nearest {
            distance: self.distance,
            triangle: self.triangle,
        })
    }
}

/// Squared distances (mm^2) from `q` to four boxes, in f32. Each difference, square and sum
/// is correctly rounded, so each result is within a relative 2^-21 of the exact value, or
/// within 2^-146 of it where it is subnormal.
#[inline]
fn box_distances2(q: [f32; 3], lo: &[[f32; 4]; 3], hi: &[[f32; 4]; 3]) -> [f32; 4] {
    let mut sum = [0.0f32; 4];
    for a in 0..3 {
        for k in 0..4 {
            let d = max(max(lo[a][k] - q[a], q[a] - hi[a][k]), 0.0);
            sum[k] += d * d;
        }
    }
    sum
}

/// Squared distance (mm^2) from `q` to one box, as [`box_distances2`] computes it.
#[inline]
fn box_distance2(q: [f32; 3], lo: [f32; 3], hi: [f32; 3]) -> f32 {
    let mut sum = 0.0f32;
    for a in 0..3 {
        let d = max(max(lo[a] - q[a], q[a] - hi[a]), 0.0);
        sum += d * d;
    }
    sum
}

/// The largest squared box distance, as computed in f32, that may hold a triangle no further
/// than `best` (mm): above the rounding of the f32 distances and of this bound by a wide
/// margin (relative 1e-5, and the smallest normal f32 for subnormal results), so a box is
/// pruned only when it is truly further than `best` and cannot hold even a tie.
#[inline]
pub fn reach2(best: f64) -> f32 {
    (best * best * (1.0 + 1e-5)) as f32 + f32::MIN_POSITIVE
}

/// How a node splits `n` triangles: the sizes of its up to four children, in order (two
/// median splits; a half that fits in a leaf is not split again).
fn child_sizes(n: usize) -> impl Iterator<Item = usize> {
    let halves = [n / 2, n - n / 2];
    halves.into_iter().flat_map(|h| {
        let parts = if h <= LEAF {
            [h, 0]
        } else {
            [h / 2, h - h / 2]
        };
        parts.into_iter().filter(|&p| p > 0)
    })
}

/// Inner nodes of a subtree of `n` triangles (a leaf is no node), remembered by size: a
/// tree of median splits has at most two sizes per level.
fn inner_nodes(n: usize, memo: &mut std::collections::HashMap<usize, usize>) -> usize {
    if n <= LEAF {
        return 0;
    }
    if let Some(&k) = memo.get(&n) {
        return k;
    }
    let k = 1 + child_sizes(n).map(|c| inner_nodes(c, memo)).sum::<usize>();
    memo.insert(n, k);
    k
}

impl TriangleBvh {
    /// Indexes the triangles of `mesh`.
    pub fn build(mesh: &Mesh) -> TriangleBvh {
        let p = mesh.positions();
        // Huge pages where offered: written whole at once, 36 bytes a triangle.
        let mut triangles = crate::hugepages::with_capacity(mesh.n_triangles());
        mesh.triangles()
            .par_iter()
            .map(|t| t.map(|v| p[v as usize]))
            .collect_into_vec(&mut triangles);
        TriangleBvh::from_corners(triangles)
    }

    /// Indexes triangles given by their corners (mm); indices are positions in the slice.
    pub fn from_triangles(triangles: &[[[f32; 3]; 3]]) -> TriangleBvh {
        TriangleBvh::from_corners(triangles.to_vec())
    }

    /// [`TriangleBvh::from_triangles`] keeping the corners it is given (no copy).
    fn from_corners(triangles: Vec<[[f32; 3]; 3]>) -> TriangleBvh {
        TriangleBvh {
            cells: super::cells::TriangleCells::build(&triangles),
            triangles,
            tree: std::sync::OnceLock::new(),
        }
    }

    /// Builds the hierarchy now rather than on the first query the cells do not settle (for
    /// timing it apart from the queries).
    pub fn build_hierarchy(&self) {
        self.hierarchy();
    }

    /// The hierarchy, built on first use.
    fn hierarchy(&self) -> &Tree {
        self.tree.get_or_init(|| Tree::build(&self.triangles))
    }

    /// Number of indexed triangles.
    pub fn n_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// Corners of triangle `f` (mm), in the order of the mesh it was built from.
    pub fn triangle(&self, f: u32) -> [[f32; 3]; 3] {
        self.triangles[f as usize]
    }

    /// The nearest triangle to `p` and its distance; `None` if there are no triangles.
    pub fn nearest(&self, p: [f32; 3]) -> Option<Nearest> {
        self.nearest_matching_within(p, f64::INFINITY, |_| true)
    }

    /// The nearest triangle to `p` among those `keep` accepts (by index); `None` if none is.
    pub fn nearest_matching(&self, p: [f32; 3], keep: impl Fn(u32) -> bool) -> Option<Nearest> {
        self.nearest_matching_within(p, f64::INFINITY, keep)
    }

    /// Distance from each point to the surface (mm), in parallel; infinite if it is empty.
    /// Points go in runs, each search starting from the previous point's nearest triangle:
    /// neighbouring points (a mesh's vertices) start close to their answer, and the answer
    /// does not depend on where a search starts.
    pub fn distances(&self, points: &[[f32; 3]]) -> Vec<f64> {
        const RUN: usize = 256;
        let mut out = vec![0.0; points.len()];
        out.par_chunks_mut(RUN)
            .zip(points.par_chunks(RUN))
            .for_each(|(out, points)| {
                let mut previous = None;
                for (d, &p) in out.iter_mut().zip(points) {
                    let found = self.nearest_from(p, f64::INFINITY, previous, &|_| true);
                    previous = found.map(|n| n.triangle);
                    *d = found.map_or(f64::INFINITY, |n| n.distance);
                }
            });
        out
    }

    /// [`TriangleBvh::distances`], the search for `points[i]` starting from triangle
    /// `guesses[i]` (none where that is missing or out of range): the same answers, found
    /// sooner when the guesses are close (a vertex's own faces, for a smoothed copy of the
    /// mesh with the same triangles).
    pub fn distances_from(&self, points: &[[f32; 3]], guesses: &[u32]) -> Vec<f64> {
        points
            .par_iter()
            .enumerate()
            .map(|(i, &p)| {
                self.nearest_from(p, f64::INFINITY, guesses.get(i).copied(), &|_| true)
                    .map_or(f64::INFINITY, |n| n.distance)
            })
            .collect()
    }

    /// The triangle nearest to `p` among those `keep` accepts and no further than `within`
    /// (mm), with its distance; ties go to the lower index. A search that only needs to beat
    /// a known distance stops there.
    pub fn nearest_matching_within(
        &self,
        p: [f32; 3],
        within: f64,
        keep: impl Fn(u32) -> bool,
    ) -> Option<Nearest> {
        self.nearest_from(p, within, None, &keep)
    }

    /// [`TriangleBvh::nearest_matching_within`] with triangle `start` (if in range) offered
    /// first: a close guess bounds the search from its first step. Ties still go to the lower
    /// index, so the answer does not depend on the guess.
    fn nearest_from(
        &self,
        p: [f32; 3],
        within: f64,
        start: Option<u32>,
        keep: &impl Fn(u32) -> bool,
    ) -> Option<Nearest> {
        if self.triangles.is_empty() || within.is_nan() {
            return None;
        }
        let mut best = Best::within(within);
        if let Some(t) = start.and_then(|f| self.triangles.get(f as usize).map(|t| (f, t))) {
            best.offer(p, t.0, t.1, keep);
        }
        // The query's own cell, then its neighbours: enough on the surface. A point whose
        // cell and neighbours list nothing (far from the surface) goes to the hierarchy at
        // once: every triangle is beyond those cells' walls, so they cannot settle it.
        let mut listed = false;
        let rings = if self.cells.near_listed(p) {
            0..2
        } else {
            0..0
        };
        for ring in rings {
            // Cells beyond the best distance hold nothing nearer.
            let walls = self.cells.visit_ring(p, ring, best.distance, |ids, gap2| {
                listed |= !ids.is_empty();
                if gap2 <= best.distance * best.distance * (1.0 + 1e-9) {
                    for ids in ids.chunks(BATCH) {
                        best.offer_batch(
                            p,
                            ids.len(),
                            |i| (ids[i], &self.triangles[ids[i] as usize]),
                            &keep,
                        );
                    }
                }
            });
            if best.distance < walls {
                return best.found();
            }
            // Nothing found in its own cell, though a triangle is listed there: a filter
            // rejected them (as an opposite wall's does), and the neighbours are unlikely to
            // settle it either.
            if best.triangle == u32::MAX && listed {
                break;
            }
        }
        match self.hierarchy().search(p, best, &keep) {
            Some(best) => best.found(),
            None => self
                .fallback(p, within, keep)
                .map(|(distance, triangle)| Nearest { distance, triangle }),
        }
    }
}

impl Tree {
    /// Continues the search for the nearest triangle to `p` from `best` (by value, so its
    /// fields live in registers); `None` if the stack would overflow (unreachable with median
    /// splits), for the caller to search in turn rather than lose the answer.
    fn search(&self, p: [f32; 3], mut best: Best, keep: &impl Fn(u32) -> bool) -> Option<Best> {
        // Child words, their counts and their boxes' squared distances, re-checked when
        // popped. Depth is at most log4(n / LEAF) + 1; each level leaves at most three
        // entries behind, so 64 covers any u32 count.
        let mut stack = [(0u32, 0u32, 0.0f32); 64];
        stack[0] = if self.nodes.is_empty() {
            (LEAF_BIT, self.order.len() as u32, 0.0)
        } else {
            (0, 0, 0.0)
        };
        let mut depth = 1;
        while depth > 0 {
            depth -= 1;
            let (child, count, gap2) = stack[depth];
            if gap2 > best.reach {
                continue;
            }
            if child & LEAF_BIT != 0 {
                let start = (child & !LEAF_BIT) as usize;
                let n = (count as usize).min(LEAF);
                let (order, corners) = (&self.order[start..start + n], &self.corners[start..]);
                best.offer_batch(p, n, |i| (order[i], &corners[i]), keep);
                continue;
            }
            let node = &self.nodes[child as usize];
            let gaps = box_distances2(p, &node.lo, &node.hi);
            // A leaf's or twig's disk bounds it more tightly than its box from afar.
            let disks = if node.count == [0; 4] {
                [0.0; 4]
            } else {
                disk_distances2(p, &self.disks[child as usize])
            };
            // The children in reach, nearest pushed last (searched first), without a branch
            // per child: which of four children are in reach and in what order is data the
            // branch predictor cannot learn. Each child gets a key, its distance's bits (a
            // non-negative f32 orders as its bits; the sign bit is cleared, so -0 is 0) with
            // the low two traded for its slot, one step up so that a key is never 0, which
            // marks a child out of reach; the four keys sorted by decreasing value by a
            // sorting network of min and max, and all four entries written, only the hits
            // counted.
            let mut keys = [0u32; 4];
            let mut n_hits = 0;
            // Only a child with a count (a leaf or a twig) has a disk.
            let gaps: [f32; 4] = std::array::from_fn(|k| {
                if node.count[k] > 0 {
                    max(gaps[k], disks[k])
                } else {
                    gaps[k]
                }
            });
            for (k, &gap) in gaps.iter().enumerate() {
                // An unused slot's box is empty (infinitely far), which an infinite reach
                // would still take.
                let hit = gap <= best.reach && node.child[k] != NO_CHILD;
                let key = ((gap.to_bits() & 0x7fff_fffc).wrapping_add(4)) | k as u32;
                keys[k] = if hit { key } else { 0 };
                n_hits += hit as usize;
            }
            for (i, j) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
                let (a, b) = (keys[i], keys[j]);
                keys[i] = a.max(b);
                keys[j] = a.min(b);
            }
            if depth + keys.len() > stack.len() {
                return None;
            }
            for (i, &key) in keys.iter().enumerate() {
                let k = (key & 3) as usize;
                stack[depth + i] = (node.child[k], node.count[k], gaps[k]);
            }
            depth += n_hits;
        }
        Some(best)
    }
}

impl TriangleBvh {
    /// Every triangle tested: the answer the tree must give.
    pub fn fallback(
        &self,
        p: [f32; 3],
        within: f64,
        keep: impl Fn(u32) -> bool,
    ) -> Option<(f64, u32)> {
        let mut best: Option<(f64, u32)> = None;
        for (f, t) in (0..).zip(&self.triangles) {
            if !keep(f) {
                continue;
            }
            let d = point_triangle_distance(p, *t);
            if d <= within && best.is_none_or(|(b, g)| d < b || (d == b && f < g)) {
                best = Some((d, f));
            }
        }
        best
    }
}

impl Tree {
    /// The hierarchy over `triangles`; the same tree for any thread count.
    pub fn build(triangles: &[[[f32; 3]; 3]]) -> Tree {
        // Boxes carried along with the indices: the splits compare records in place rather
        // than look up each index's box in scattered memory.
        let mut items: Vec<Item> = triangles
            .par_iter()
            .enumerate()
            .map(|(f, t)| {
                let (lo, hi) = triangle_box(t);
                Item {
                    lo,
                    hi,
                    f: f as u32,
                }
            })
            .collect();
        // Every subtree's node count is known before it is built, so subtrees fill disjoint
        // stretches of one array in parallel.
        let mut memo = std::collections::HashMap::new();
        let mut nodes = vec![Node::default(); inner_nodes(items.len(), &mut memo)];
        if !nodes.is_empty() {
            subtree(&mut items, 0, &mut nodes, 0, &memo);
        }
        let order: Vec<u32> = items.par_iter().map(|item| item.f).collect();
        let corners: Vec<[[f32; 3]; 3]> =
            order.par_iter().map(|&f| triangles[f as usize]).collect();
        let disks = nodes
            .par_iter()
            .map(|node| {
                let mut disks = Disks::default();
                for k in 0..4 {
                    if node.count[k] == 0 || node.child[k] == NO_CHILD {
                        continue;
                    }
                    // A twig's triangles start at its first leaf's.
                    let mut first = node.child[k];
                    while first & LEAF_BIT == 0 {
                        first = nodes[first as usize].child[0];
                    }
                    let start = (first & !LEAF_BIT) as usize;
                    let leaf = &corners[start..start + node.count[k] as usize];
                    let (c, n, r, t) = leaf_disk(leaf);
                    for a in 0..3 {
                        disks.c[a][k] = c[a];
                        disks.n[a][k] = n[a];
                    }
                    disks.r[k] = r;
                    disks.t[k] = t;
                }
                disks
            })
            .collect();
        Tree {
            nodes,
            order,
            corners,
            disks,
        }
    }
}

/// A triangle while the tree is built: its box (mm) and its index.
#[derive(Debug, Clone, Copy)]
struct Item {
    lo: [f32; 3],
    hi: [f32; 3],
    f: u32,
}

/// Box of `items`.
fn extent(items: &[Item]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for item in items {
        for a in 0..3 {
            lo[a] = lo[a].min(item.lo[a]);
            hi[a] = hi[a].max(item.hi[a]);
        }
    }
    (lo, hi)
}

/// Splits `items` at their middle along the longest axis of their box centres; ties by index,
/// so the halves do not depend on the order the slice arrived in.
fn median_split(items: &mut [Item]) -> (&mut [Item], &mut [Item]) {
    // Centres doubled (lo + hi): the same order as the centres, one multiplication less.
    let mut clo = [f32::INFINITY; 3];
    let mut chi = [f32::NEG_INFINITY; 3];
    for item in items.iter() {
        for a in 0..3 {
            let c = item.lo[a] + item.hi[a];
            clo[a] = clo[a].min(c);
            chi[a] = chi[a].max(c);
        }
    }
    let axis = (0..3)
        .max_by(|&a, &b| {
            (chi[a] - clo[a])
                .total_cmp(&(chi[b] - clo[b]))
                .then(b.cmp(&a))
        })
        .unwrap_or(0);
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |x, y| {
        let (cx, cy) = (x.lo[axis] + x.hi[axis], y.lo[axis] + y.hi[axis]);
        cx.total_cmp(&cy).then(x.f.cmp(&y.f))
    });
    items.split_at_mut(mid)
}

/// A half of a node split again, unless it fits in a leaf.
fn split_unless_leaf(half: &mut [Item]) -> (&mut [Item], Option<&mut [Item]>) {
    if half.len() <= LEAF {
        (half, None)
    } else {
        let (c, d) = median_split(half);
        (c, Some(d))
    }
}

/// Builds the subtree over `items` (more than [`LEAF`] triangles, entries `base..` of the
/// whole leaf order) into `nodes`, its stretch of the node array, which starts at index
/// `first` of the whole.
fn subtree(
    items: &mut [Item],
    base: usize,
    nodes: &mut [Node],
    first: usize,
    memo: &std::collections::HashMap<usize, usize>,
) {
    // Two levels of median splits: up to four parts, in leaf order.
    let large = items.len() > PARALLEL;
    let (a, b) = median_split(items);
    let (a, b) = if large {
        rayon::join(|| split_unless_leaf(a), || split_unless_leaf(b))
    } else {
        (split_unless_leaf(a), split_unless_leaf(b))
    };
    let mut parts: Vec<&mut [Item]> = Vec::with_capacity(4);
    for (c, d) in [a, b] {
        parts.push(c);
        parts.extend(d);
    }
    let (this, mut rest) = nodes.split_at_mut(1);
    let mut node = Node::default();
    let mut jobs = Vec::with_capacity(4);
    let (mut at_order, mut at_node) = (base, first + 1);
    for (k, part) in parts.into_iter().enumerate() {
        let (lo, hi) = extent(part);
        for a in 0..3 {
            node.lo[a][k] = lo[a];
            node.hi[a][k] = hi[a];
        }
        let n = part.len();
        if n <= LEAF {
            node.child[k] = LEAF_BIT | at_order as u32;
            node.count[k] = n as u32;
        } else {
            let size = memo.get(&n).copied().unwrap_or(0);
            let (stretch, tail) = rest.split_at_mut(size);
            rest = tail;
            node.child[k] = at_node as u32;
            node.count[k] = if n <= TWIG { n as u32 } else { 0 };
            jobs.push((part, at_order, stretch, at_node));
            at_node += size;
        }
        at_order += n;
    }
    this[0] = node;
    let total: usize = jobs.iter().map(|j| j.0.len()).sum();
    if total > PARALLEL {
        jobs.into_par_iter()
            .for_each(|(part, base, stretch, first)| subtree(part, base, stretch, first, memo));
    } else {
        for (part, base, stretch, first) in jobs {
            subtree(part, base, stretch, first, memo);
        }
    }
}
