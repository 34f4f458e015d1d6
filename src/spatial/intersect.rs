//! Exact triangle-triangle intersection: closed triangles (touching counts), decided with
//! Shewchuk's adaptive exact predicates (`robust`), so a result never depends on rounding.
//! A uniform grid over triangle bounding boxes finds candidate pairs; pairs of one mesh that
//! share vertices intersect only where they meet beyond what they share (a fold, a crossing).
//!
//! Triangles whose three corners are exactly collinear are degenerate: they have no plane, are
//! counted by [`exactly_degenerate_triangles`] and are left out of the pair tests.

use crate::mesh::Mesh;
use rayon::prelude::*;
use robust::{orient2d, orient3d, Coord, Coord3D};

type P = [f32; 3];

#[inline]
fn c3(p: P) -> Coord3D<f64> {
    Coord3D {
        x: p[0] as f64,
        y: p[1] as f64,
        z: p[2] as f64,
    }
}

/// Sign of the orientation of d against the plane (a, b, c): exact, -1, 0 or 1.
#[inline]
fn orient(a: P, b: P, c: P, d: P) -> i8 {
    // Four points in one axis-aligned plane (a staircase's terraces and walls) are coplanar:
    // 0 at once, where the predicate would take its slowest, exact path to find it.
    if (0..3).any(|k| a[k] == b[k] && a[k] == c[k] && a[k] == d[k]) {
        return 0;
    }
    let o = orient3d(c3(a), c3(b), c3(c), c3(d));
    (o > 0.0) as i8 - (o < 0.0) as i8
}

/// A point projected onto the coordinate plane without axis `drop`.
#[inline]
fn flat(p: P, drop: usize) -> Coord<f64> {
    let (i, j) = match drop {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    };
    Coord {
        x: p[i] as f64,
        y: p[j] as f64,
    }
}

/// Sign of the orientation of c against the line (a, b) in the projection without axis
/// `drop`: exact, -1, 0 or 1.
#[inline]
fn orient_flat(a: P, b: P, c: P, drop: usize) -> i8 {
    let (a, b, c) = (flat(a, drop), flat(b, drop), flat(c, drop));
    // Three points on one axis-parallel line (the edges of a staircase) are collinear.
    if (a.x == b.x && a.x == c.x) || (a.y == b.y && a.y == c.y) {
        return 0;
    }
    let o = orient2d(a, b, c);
    (o > 0.0) as i8 - (o < 0.0) as i8
}

/// The axis to drop so that the triangle stays non-degenerate in projection (exact), or `None`
/// for a triangle whose corners are collinear.
fn projection_axis(t: [P; 3]) -> Option<usize> {
    // Try the axis of the largest normal component first; any axis with a non-zero exact
    // projected area will do.
    let e1: [f64; 3] = std::array::from_fn(|k| t[1][k] as f64 - t[0][k] as f64);
    let e2: [f64; 3] = std::array::from_fn(|k| t[2][k] as f64 - t[0][k] as f64);
    let n = [
        (e1[1] * e2[2] - e1[2] * e2[1]).abs(),
        (e1[2] * e2[0] - e1[0] * e2[2]).abs(),
        (e1[0] * e2[1] - e1[1] * e2[0]).abs(),
    ];
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| n[b].total_cmp(&n[a]));
    order
        .into_iter()
        .find(|&axis| orient_flat(t[0], t[1], t[2], axis) != 0)
}

/// True when the triangle's corners are exactly collinear (zero area, no plane).
pub fn is_exactly_degenerate(t: [P; 3]) -> bool {
    projection_axis(t).is_none()
}

/// Whether p lies on the closed segment ab, given that the three are collinear.
#[inline]
fn within(a: P, b: P, p: P) -> bool {
    (0..3).all(|k| p[k] >= a[k].min(b[k]) && p[k] <= a[k].max(b[k]))
}

/// Closed segments pq and ab, coplanar, in the projection without axis `drop`.
fn segments_meet_flat(p: P, q: P, a: P, b: P, drop: usize) -> bool {
    let d1 = orient_flat(a, b, p, drop);
    let d2 = orient_flat(a, b, q, drop);
    let d3 = orient_flat(p, q, a, drop);
    let d4 = orient_flat(p, q, b, drop);
    if d1 * d2 < 0 && d3 * d4 < 0 {
        return true;
    }
    (d1 == 0 && within(a, b, p))
        || (d2 == 0 && within(a, b, q))
        || (d3 == 0 && within(p, q, a))
        || (d4 == 0 && within(p, q, b))
}

/// Whether p lies in the closed triangle t, all coplanar, projected without axis `drop`.
#[inline]
fn inside_flat(p: P, t: [P; 3], drop: usize) -> bool {
    let s = [
        orient_flat(t[0], t[1], p, drop),
        orient_flat(t[1], t[2], p, drop),
        orient_flat(t[2], t[0], p, drop),
    ];
    s.iter().all(|&x| x >= 0) || s.iter().all(|&x| x <= 0)
}

/// Whether the closed segment pq meets the closed, non-degenerate triangle t.
pub fn segment_meets_triangle(p: P, q: P, t: [P; 3]) -> bool {
    let [a, b, c] = t;
    segment_meets_triangle_oriented(p, q, t, orient(a, b, c, p), orient(a, b, c, q))
}

/// [`segment_meets_triangle`] given the orientations `o1`, `o2` of p and q against t's plane.
fn segment_meets_triangle_oriented(p: P, q: P, t: [P; 3], o1: i8, o2: i8) -> bool {
    let [a, b, c] = t;
    if o1 * o2 > 0 {
        return false;
    }
    if o1 == 0 && o2 == 0 {
        let Some(drop) = projection_axis(t) else {
            return false;
        };
        return inside_flat(p, t, drop)
            || inside_flat(q, t, drop)
            || segments_meet_flat(p, q, a, b, drop)
            || segments_meet_flat(p, q, b, c, drop)
            || segments_meet_flat(p, q, c, a, drop);
    }
    // pq crosses or touches the plane at one point: it lies in t when the line pq passes the
    // three edges on the same side.
    let s1 = orient(p, q, a, b);
    let s2 = orient(p, q, b, c);
    let s3 = orient(p, q, c, a);
    (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0)
}

/// Whether two closed, non-degenerate triangles share at least one point. Two triangles meet
/// exactly when an edge of one meets the other (the intersection's ends lie on edges).
pub fn triangles_intersect(t: [P; 3], u: [P; 3]) -> bool {
    // Separating planes first: all of one triangle strictly on one side of the other's plane.
    let side_u = [0, 1, 2].map(|k| orient(t[0], t[1], t[2], u[k]));
    if side_u.iter().all(|&s| s > 0) || side_u.iter().all(|&s| s < 0) {
        return false;
    }
    if side_u == [0; 3] {
        // Coplanar (a staircase's flat terraces are full of such neighbours).
        return projection_axis(t).is_some_and(|drop| triangles_meet_flat(t, u, drop));
    }
    let side_t = [0, 1, 2].map(|k| orient(u[0], u[1], u[2], t[k]));
    if side_t.iter().all(|&s| s > 0) || side_t.iter().all(|&s| s < 0) {
        return false;
    }
    (0..3).any(|k| segment_meets_triangle(t[k], t[(k + 1) % 3], u))
        || (0..3).any(|k| segment_meets_triangle(u[k], u[(k + 1) % 3], t))
}

/// Whether two triangles of one mesh meet anywhere beyond the vertices they share (by index).
/// `ti`, `tu` are vertex indices, `t`, `u` the corresponding positions; both non-degenerate.
pub fn faces_intersect(ti: [u32; 3], t: [P; 3], ui: [u32; 3], u: [P; 3]) -> bool {
    let shared_in_t = [0, 1, 2].map(|k| ui.contains(&ti[k]));
    match shared_in_t.iter().filter(|&&s| s).count() {
        0 => triangles_intersect(t, u),
        1 => {
            // Shared corner v: the faces meet elsewhere iff the edge opposite v in one meets
            // the other face. Where that edge lies strictly on one side of the other face's
            // plane, so does all of its face but v, and they meet at v alone (most pairs end
            // there, after two orientations); coplanar faces meet beyond v iff their corners
            // at v overlap.
            let k = shared_in_t.iter().position(|&s| s).unwrap_or(0);
            let m = ui.iter().position(|&x| x == ti[k]).unwrap_or(0);
            let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
            let (c, d) = (u[(m + 1) % 3], u[(m + 2) % 3]);
            let (oa, ob) = (orient(u[0], u[1], u[2], a), orient(u[0], u[1], u[2], b));
            if oa * ob > 0 {
                return false;
            }
            if oa == 0 && ob == 0 {
                return projection_axis(u)
                    .is_some_and(|drop| corners_overlap_flat(t[k], (a, b), (c, d), drop));
            }
            let (oc, od) = (orient(t[0], t[1], t[2], c), orient(t[0], t[1], t[2], d));
            if oc * od > 0 {
                return false;
            }
            segment_meets_triangle_oriented(a, b, u, oa, ob)
                || segment_meets_triangle_oriented(c, d, t, oc, od)
        }
        2 => {
            // Shared edge: they overlap iff coplanar with both opposite corners on one side.
            let k = shared_in_t.iter().position(|&s| !s).unwrap_or(0);
            let (e0, e1, a) = (t[(k + 1) % 3], t[(k + 2) % 3], t[k]);
            let m = (0..3).find(|&m| !ti.contains(&ui[m])).unwrap_or(0);
            let b = u[m];
            if orient(e0, e1, a, b) != 0 {
                return false;
            }
            let Some(drop) = projection_axis(t) else {
                return false;
            };
            orient_flat(e0, e1, a, drop) * orient_flat(e0, e1, b, drop) > 0
        }
        // The same three corners: one face lies on the other.
        _ => true,
    }
}

/// Whether two coplanar, non-degenerate closed triangles meet, in the projection without axis
/// `drop` (exact): they are disjoint iff the line along a side of one has the other strictly
/// on the far side of it from its own third corner.
fn triangles_meet_flat(t: [P; 3], u: [P; 3], drop: usize) -> bool {
    let separates = |x: [P; 3], y: [P; 3]| {
        (0..3).any(|k| {
            let (p, q, r) = (x[k], x[(k + 1) % 3], x[(k + 2) % 3]);
            let own = orient_flat(p, q, r, drop);
            y.iter().all(|&z| orient_flat(p, q, z, drop) * own < 0)
        })
    };
    !separates(t, u) && !separates(u, t)
}

/// Whether two coplanar, non-degenerate triangles with the common corner v, the one's other
/// corners `ab` and the other's `cd`, overlap beyond v, in the projection without axis
/// `drop`: near v each triangle is its corner's wedge (under 180 degrees), and two such
/// wedges overlap iff one holds a side of the other (exact).
fn corners_overlap_flat(v: P, (a, b): (P, P), (c, d): (P, P), drop: usize) -> bool {
    // Whether the ray from v through x lies in the closed wedge from v along p and q, whose
    // turn from p to q is s.
    let holds = |(p, q, s): (P, P, i8), x: P| {
        orient_flat(v, p, x, drop) * s >= 0 && orient_flat(v, x, q, drop) * s >= 0
    };
    let t = (a, b, orient_flat(v, a, b, drop));
    let u = (c, d, orient_flat(v, c, d, drop));
    holds(t, c) || holds(t, d) || holds(u, a) || holds(u, b)
}

/// Faces of `mesh` whose corners are exactly collinear (including repeated indices).
pub fn exactly_degenerate_triangles(mesh: &Mesh) -> Vec<u32> {
    let p = mesh.positions();
    mesh.triangles()
        .par_iter()
        .enumerate()
        .filter(|(_, t)| is_exactly_degenerate(t.map(|v| p[v as usize])))
        .map(|(f, _)| f as u32)
        .collect()
}

type Aabb = ([f32; 3], [f32; 3]);

fn aabb(t: [P; 3]) -> Aabb {
    let lo = std::array::from_fn(|k| t[0][k].min(t[1][k]).min(t[2][k]));
    let hi = std::array::from_fn(|k| t[0][k].max(t[1][k]).max(t[2][k]));
    (lo, hi)
}

#[inline]
fn boxes_overlap(a: &Aabb, b: &Aabb) -> bool {
    (0..3).all(|k| a.0[k] <= b.1[k] && b.0[k] <= a.1[k])
}

/// A uniform grid of cells listing the boxes that overlap them (CSR).
struct BoxGrid {
    origin: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl BoxGrid {
    /// Cells about twice the mean box size, at most a few per box; `extra` widens the bounds
    /// so boxes of another set can be located too.
    fn build(boxes: &[Aabb], extra: &[Aabb]) -> BoxGrid {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut size = 0.0f64;
        for b in boxes.iter().chain(extra) {
            for k in 0..3 {
                lo[k] = lo[k].min(b.0[k] as f64);
                hi[k] = hi[k].max(b.1[k] as f64);
                size += (b.1[k] - b.0[k]) as f64;
            }
        }
        if !lo[0].is_finite() {
            lo = [0.0; 3];
            hi = [0.0; 3];
        }
        let extent: [f64; 3] = std::array::from_fn(|k| hi[k] - lo[k]);
        let mut wanted = 2.0 * size / (3 * (boxes.len() + extra.len()).max(1)) as f64;
        // Cells twice as wide until the boxes overlap few enough of them (see PAIRS_PER_ITEM).
        let most_pairs =
            ((super::PAIRS_PER_ITEM * boxes.len() + super::PAIRS_ROOM) as u64).min(u32::MAX as u64);
        let mut grid = loop {
            let (cell, dims) = super::grid_cells(extent, wanted, boxes.len().max(1), 4);
            let grid = BoxGrid {
                origin: lo,
                cell,
                dims,
                offsets: Vec::new(),
                items: Vec::new(),
            };
            let pairs: u64 = boxes
                .par_iter()
                .map(|b| {
                    grid.cell_ranges(b)
                        .iter()
                        .map(|r| (r.end() + 1 - r.start()) as u64)
                        .product::<u64>()
                })
                .sum();
            if pairs <= most_pairs {
                break BoxGrid {
                    offsets: vec![0; dims[0] * dims[1] * dims[2] + 1],
                    ..grid
                };
            }
            wanted = 2.0 * cell;
        };
        // Counted and filled by all threads (atomics), then each cell's list sorted: boxes in
        // ascending order, as one thread filling them in order would list them.
        use std::sync::atomic::{AtomicU32, Ordering::Relaxed};
        let n_cells = grid.offsets.len() - 1;
        let counts: Vec<AtomicU32> = (0..n_cells)
            .into_par_iter()
            .map(|_| AtomicU32::new(0))
            .collect();
        boxes.par_iter().for_each(|b| {
            for c in cells(grid.dims, grid.cell_ranges(b)) {
                counts[c].fetch_add(1, Relaxed);
            }
        });
        for (c, count) in counts.iter().enumerate() {
            grid.offsets[c + 1] = grid.offsets[c] + count.load(Relaxed);
        }
        // Each cell's next free place (the counts, no longer needed, become the cursors).
        counts
            .par_iter()
            .zip(&grid.offsets[..n_cells])
            .for_each(|(cursor, &start)| cursor.store(start, Relaxed));
        let items: Vec<AtomicU32> = (0..grid.offsets[n_cells])
            .into_par_iter()
            .map(|_| AtomicU32::new(0))
            .collect();
        boxes.par_iter().enumerate().for_each(|(i, b)| {
            for c in cells(grid.dims, grid.cell_ranges(b)) {
                items[counts[c].fetch_add(1, Relaxed) as usize].store(i as u32, Relaxed);
            }
        });
        grid.items = items.into_iter().map(AtomicU32::into_inner).collect();
        // Runs of cells side by side, each sorting its cells' lists in its stretch of items.
        const RUN: usize = 4096;
        let offsets = &grid.offsets;
        let mut runs: Vec<(usize, &mut [u32])> = Vec::with_capacity(n_cells.div_ceil(RUN));
        let mut rest = grid.items.as_mut_slice();
        for first in (0..n_cells).step_by(RUN) {
            let last = (first + RUN).min(n_cells);
            let (run, tail) = rest.split_at_mut((offsets[last] - offsets[first]) as usize);
            runs.push((first, run));
            rest = tail;
        }
        runs.into_par_iter().for_each(|(first, run)| {
            let base = offsets[first];
            let last = (first + RUN).min(n_cells);
            for w in offsets[first..=last].windows(2) {
                run[(w[0] - base) as usize..(w[1] - base) as usize].sort_unstable();
            }
        });
        grid
    }

    /// The cell index along axis k holding coordinate x (clamped to the grid).
    #[inline]
    fn cell_of(&self, x: f32, k: usize) -> usize {
        // The cast rounds toward zero and takes what is below 0 (or NaN) to 0: the floor,
        // clamped at 0, without a call to `floor`.
        (((x as f64 - self.origin[k]) / self.cell) as usize).min(self.dims[k] - 1)
    }

    fn cell_ranges(&self, b: &Aabb) -> [std::ops::RangeInclusive<usize>; 3] {
        std::array::from_fn(|k| self.cell_of(b.0[k], k)..=self.cell_of(b.1[k], k))
    }

    fn items(&self, c: usize) -> &[u32] {
        &self.items[self.offsets[c] as usize..self.offsets[c + 1] as usize]
    }

    /// The one cell where a pair of overlapping boxes is tested: the cell of the overlap's
    /// lowest corner, so each pair is tested once however many cells both cover.
    #[inline]
    fn owner_cell(&self, a: &Aabb, b: &Aabb) -> usize {
        let k: [usize; 3] = std::array::from_fn(|k| self.cell_of(a.0[k].max(b.0[k]), k));
        (k[2] * self.dims[1] + k[1]) * self.dims[0] + k[0]
    }
}

/// Linear indices of the cells in the given ranges of a grid of `dims` cells.
fn cells(dims: [usize; 3], r: [std::ops::RangeInclusive<usize>; 3]) -> impl Iterator<Item = usize> {
    let [rx, ry, rz] = r;
    rz.flat_map(move |z| {
        let rx = rx.clone();
        ry.clone()
            .flat_map(move |y| rx.clone().map(move |x| (z * dims[1] + y) * dims[0] + x))
    })
}

/// Pairs of faces `[f, g]` (f < g) of `mesh` that intersect beyond the vertices and edges
/// they share: crossings, touching and folded-over neighbours. Sorted; exact; degenerate
/// faces (see [`exactly_degenerate_triangles`]) are left out.
pub fn self_intersections(mesh: &Mesh) -> Vec<[u32; 2]> {
    let p = mesh.positions();
    let tris = mesh.triangles();
    let corners: Vec<[P; 3]> = tris.par_iter().map(|t| t.map(|v| p[v as usize])).collect();
    let valid: Vec<bool> = corners
        .par_iter()
        .map(|&t| !is_exactly_degenerate(t))
        .collect();
    let boxes: Vec<Aabb> = corners.par_iter().map(|&t| aabb(t)).collect();
    let grid = BoxGrid::build(&boxes, &[]);
    // Each box's lowest cell: a pair's owner cell is the larger of theirs along each axis
    // (`cell_of` is monotonic), with no division per pair.
    let low_cells: Vec<[u32; 3]> = boxes
        .par_iter()
        .map(|b| std::array::from_fn(|k| grid.cell_of(b.0[k], k) as u32))
        .collect();
    let owner = |f: usize, g: usize| {
        let (a, b) = (low_cells[f], low_cells[g]);
        let k: [usize; 3] = std::array::from_fn(|i| a[i].max(b[i]) as usize);
        (k[2] * grid.dims[1] + k[1]) * grid.dims[0] + k[0]
    };
    let mut pairs: Vec<[u32; 2]> = (0..tris.len())
        .into_par_iter()
        .filter(|&f| valid[f])
        .flat_map_iter(|f| {
            let mut found = Vec::new();
            for c in cells(grid.dims, grid.cell_ranges(&boxes[f])) {
                for &g in grid.items(c) {
                    let g = g as usize;
                    if g <= f
                        || !valid[g]
                        || !boxes_overlap(&boxes[f], &boxes[g])
                        || owner(f, g) != c
                    {
                        continue;
                    }
                    if faces_intersect(tris[f], corners[f], tris[g], corners[g]) {
                        found.push([f as u32, g as u32]);
                    }
                }
            }
            found
        })
        .collect();
    pairs.sort_unstable();
    pairs
}

/// Candidate triangle pairs of two meshes: a grid over b's triangle boxes.
struct CrossSearch {
    ca: Vec<[P; 3]>,
    cb: Vec<[P; 3]>,
    boxes_a: Vec<Aabb>,
    boxes_b: Vec<Aabb>,
    valid_b: Vec<bool>,
    grid: BoxGrid,
}

impl CrossSearch {
    fn new(a: &Mesh, b: &Mesh) -> Self {
        let corners = |m: &Mesh| -> Vec<[P; 3]> {
            let p = m.positions();
            m.triangles()
                .par_iter()
                .map(|t| t.map(|v| p[v as usize]))
                .collect()
        };
        let (ca, cb) = (corners(a), corners(b));
        let boxes_a: Vec<Aabb> = ca.par_iter().map(|&t| aabb(t)).collect();
        let boxes_b: Vec<Aabb> = cb.par_iter().map(|&t| aabb(t)).collect();
        let valid_b: Vec<bool> = cb.par_iter().map(|&t| !is_exactly_degenerate(t)).collect();
        let grid = BoxGrid::build(&boxes_b, &boxes_a);
        CrossSearch {
            ca,
            cb,
            boxes_a,
            boxes_b,
            valid_b,
            grid,
        }
    }

    /// Faces of b that face `f` of a meets, in grid order; only the first when `first`.
    fn hits(&self, f: usize, first: bool) -> Vec<[u32; 2]> {
        let mut found = Vec::new();
        if is_exactly_degenerate(self.ca[f]) {
            return found;
        }
        let grid = &self.grid;
        for c in cells(grid.dims, grid.cell_ranges(&self.boxes_a[f])) {
            for &g in grid.items(c) {
                let g = g as usize;
                if !self.valid_b[g]
                    || !boxes_overlap(&self.boxes_a[f], &self.boxes_b[g])
                    || grid.owner_cell(&self.boxes_a[f], &self.boxes_b[g]) != c
                {
                    continue;
                }
                if triangles_intersect(self.ca[f], self.cb[g]) {
                    found.push([f as u32, g as u32]);
                    if first {
                        return found;
                    }
                }
            }
        }
        found
    }
}

/// Pairs of faces `[f of a, g of b]` where two meshes intersect (touching counts). Sorted;
/// exact; degenerate faces are left out.
pub fn mesh_intersections(a: &Mesh, b: &Mesh) -> Vec<[u32; 2]> {
    let search = CrossSearch::new(a, b);
    let mut pairs: Vec<[u32; 2]> = (0..search.ca.len())
        .into_par_iter()
        .flat_map_iter(|f| search.hits(f, false))
        .collect();
    pairs.sort_unstable();
    pairs
}

/// Whether two meshes touch or cross anywhere: [`mesh_intersections`] is not empty, found
/// without listing every pair (structures that share a face meet at the first one tried).
pub fn meshes_touch(a: &Mesh, b: &Mesh) -> bool {
    let search = CrossSearch::new(a, b);
    (0..search.ca.len())
        .into_par_iter()
        .any(|f| !search.hits(f, true).is_empty())
}
