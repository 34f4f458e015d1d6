//! Exact point-to-surface distance: the closest point on a triangle, and a uniform grid over a
//! mesh's triangles that answers nearest-triangle queries by searching rings of cells outward
//! until no unvisited cell can hold anything closer (queries far from the surface go to a
//! bounding volume hierarchy instead, [`bvh`]); exact triangle-triangle intersection
//! ([`intersect`]).

pub mod bvh;
pub mod intersect;

use crate::mesh::Mesh;
use rayon::prelude::*;

type V3 = [f64; 3];

#[inline]
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
fn along(a: V3, d: V3, t: f64) -> V3 {
    [a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]]
}

/// The point of triangle (a, b, c) closest to p (Ericson, Real-Time Collision Detection, 5.1.5),
/// in f64 so distances are exact to float precision even for slivers.
#[inline]
pub fn closest_point_on_triangle(p: V3, a: V3, b: V3, c: V3) -> V3 {
    closest_point_and_region(p, a, b, c).0
}

/// Where on a triangle its closest point to a query lies: lets a walk over a mesh step to
/// the neighbour across that edge or around that corner, and stop inside a face.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TriangleRegion {
    /// Corner 0, 1 or 2.
    Corner(u8),
    /// Edge i, from corner i to corner (i + 1) % 3.
    Edge(u8),
    Inside,
}

/// [`closest_point_on_triangle`] and the region of the triangle the point is in.
pub fn closest_point_and_region(p: V3, a: V3, b: V3, c: V3) -> (V3, TriangleRegion) {
    use TriangleRegion::{Corner, Edge, Inside};
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Corner(0));
    }
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Corner(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (along(a, ab, v), Edge(0));
    }
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Corner(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (along(a, ac, w), Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (along(b, sub(c, b), w), Edge(1));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE || !denom.is_finite() {
        // Degenerate (collinear) triangle: the closest of its three edges.
        let edges = [(a, b), (b, c), (c, a)];
        return edges
            .iter()
            .enumerate()
            .map(|(i, &(s, e))| {
                let d = sub(e, s);
                let len2 = dot(d, d);
                let t = if len2 > 0.0 {
                    (dot(sub(p, s), d) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (along(s, d, t), Edge(i as u8))
            })
            .min_by(|(x, _), (y, _)| {
                dot(sub(p, *x), sub(p, *x)).total_cmp(&dot(sub(p, *y), sub(p, *y)))
            })
            .unwrap_or((a, Corner(0)));
    }
    let v = vb / denom;
    let w = vc / denom;
    (
        [
            a[0] + ab[0] * v + ac[0] * w,
            a[1] + ab[1] * v + ac[1] * w,
            a[2] + ab[2] * v + ac[2] * w,
        ],
        Inside,
    )
}

/// Distance (mm) from p to triangle (a, b, c).
pub fn point_triangle_distance(p: [f32; 3], t: [[f32; 3]; 3]) -> f64 {
    let f = |q: [f32; 3]| q.map(f64::from);
    let p = f(p);
    let q = closest_point_on_triangle(p, f(t[0]), f(t[1]), f(t[2]));
    let d = sub(p, q);
    dot(d, d).sqrt()
}

/// Cell size and cell counts of a uniform grid over a box of `extent` (mm): cells of about
/// `wanted` mm, but no more than a few per item (4 n + 64 in all).
pub(crate) fn grid_cells(extent: [f64; 3], wanted: f64, n_items: usize) -> (f64, [usize; 3]) {
    let max_extent = extent.iter().cloned().fold(0.0, f64::max).max(1e-9);
    let mut cell = wanted.max(max_extent * 1e-6).max(1e-9);
    let budget = (4 * n_items + 64) as f64;
    let count = |c: f64| {
        extent
            .iter()
            .map(|e| (e / c).floor() + 1.0)
            .product::<f64>()
    };
    if count(cell) > budget {
        cell *= (count(cell) / budget).cbrt();
        while count(cell) > budget {
            cell *= 1.1;
        }
    }
    let dims = std::array::from_fn(|a| (extent[a] / cell).floor() as usize + 1);
    (cell, dims)
}

/// A sphere around a triangle: its centroid and the distance to its furthest corner (mm).
pub(crate) fn sphere_around(t: &[[f32; 3]; 3]) -> ([f64; 3], f64) {
    let c: [f64; 3] =
        std::array::from_fn(|a| (t[0][a] as f64 + t[1][a] as f64 + t[2][a] as f64) / 3.0);
    let r = t
        .iter()
        .map(|q| (0..3).map(|a| (q[a] as f64 - c[a]).powi(2)).sum::<f64>())
        .fold(0.0, f64::max)
        .sqrt();
    (c, r)
}

/// Offers triangle `f` to a nearest-point search from `p`: skipped when its bounding sphere
/// lies further than the best distance so far (mm), taken when it is closer, or as close with
/// a lower index (so the answer does not depend on the order triangles are offered in).
pub(crate) fn offer(
    triangles: &[[[f32; 3]; 3]],
    spheres: &[([f64; 3], f64)],
    p: [f32; 3],
    f: u32,
    best: &mut f64,
    best_triangle: &mut u32,
) {
    let (centre, radius) = spheres[f as usize];
    let to_centre = (0..3)
        .map(|a| (p[a] as f64 - centre[a]).powi(2))
        .sum::<f64>()
        .sqrt();
    if to_centre - radius > *best {
        return;
    }
    let d = point_triangle_distance(p, triangles[f as usize]);
    if d < *best || (d == *best && f < *best_triangle) {
        *best = d;
        *best_triangle = f;
    }
}

/// A uniform grid over a mesh's triangles for nearest-triangle queries. Build once, query many.
#[derive(Debug, Clone)]
pub struct TriangleGrid {
    triangles: Vec<[[f32; 3]; 3]>,
    /// Bounding sphere per triangle (centre, radius), to skip most exact tests.
    spheres: Vec<([f64; 3], f64)>,
    origin: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    cell_offsets: Vec<u32>,
    cell_triangles: Vec<u32>,
    /// For queries the first rings of cells do not settle (far from the surface); built on
    /// the first such query, so grids only ever queried near the surface never pay for it.
    tree: std::sync::OnceLock<bvh::TriangleBvh>,
}

/// Rings of grid cells searched before a query that has found nothing yet, or is still far
/// from settled, goes to the tree instead: beyond that, the cells to visit grow with the cube
/// of the distance and the tree's pruning wins.
const NEAR_RINGS: usize = 1;

/// The nearest point of a surface to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// Distance in mm.
    pub distance: f64,
    pub triangle: u32,
}

impl TriangleGrid {
    /// Indexes the triangles of `mesh`; cells are about twice the mean edge length.
    pub fn build(mesh: &Mesh) -> TriangleGrid {
        let p = mesh.positions();
        let triangles: Vec<[[f32; 3]; 3]> = mesh
            .triangles()
            .iter()
            .map(|t| t.map(|v| p[v as usize]))
            .collect();
        let n = triangles.len().max(1);
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut edge_sum = 0.0f64;
        for t in &triangles {
            for (k, q) in t.iter().enumerate() {
                for a in 0..3 {
                    lo[a] = lo[a].min(q[a] as f64);
                    hi[a] = hi[a].max(q[a] as f64);
                }
                let r = t[(k + 1) % 3];
                edge_sum += (0..3)
                    .map(|a| (q[a] as f64 - r[a] as f64).powi(2))
                    .sum::<f64>()
                    .sqrt();
            }
        }
        if triangles.is_empty() {
            lo = [0.0; 3];
            hi = [0.0; 3];
        }
        let extent: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(0.0));
        let (cell, dims) = grid_cells(extent, 2.0 * edge_sum / (3 * n) as f64, n);
        let cell_of =
            |x: f64, a: usize| (((x - lo[a]) / cell).floor().max(0.0) as usize).min(dims[a] - 1);
        let linear = |i: usize, j: usize, k: usize| (k * dims[1] + j) * dims[0] + i;
        let range = |t: &[[f32; 3]; 3]| -> [std::ops::RangeInclusive<usize>; 3] {
            std::array::from_fn(|a| {
                let mn = t.iter().map(|q| q[a] as f64).fold(f64::INFINITY, f64::min);
                let mx = t
                    .iter()
                    .map(|q| q[a] as f64)
                    .fold(f64::NEG_INFINITY, f64::max);
                cell_of(mn, a)..=cell_of(mx, a)
            })
        };
        let n_cells = dims[0] * dims[1] * dims[2];
        let mut cell_offsets = vec![0u32; n_cells + 1];
        for t in &triangles {
            let [ri, rj, rk] = range(t);
            for k in rk {
                for j in rj.clone() {
                    for i in ri.clone() {
                        cell_offsets[linear(i, j, k) + 1] += 1;
                    }
                }
            }
        }
        for i in 1..cell_offsets.len() {
            cell_offsets[i] += cell_offsets[i - 1];
        }
        let mut cursor = cell_offsets[..n_cells].to_vec();
        let mut cell_triangles = vec![0u32; cell_offsets[n_cells] as usize];
        for (f, t) in triangles.iter().enumerate() {
            let [ri, rj, rk] = range(t);
            for k in rk {
                for j in rj.clone() {
                    for i in ri.clone() {
                        let c = &mut cursor[linear(i, j, k)];
                        cell_triangles[*c as usize] = f as u32;
                        *c += 1;
                    }
                }
            }
        }
        let spheres = triangles.par_iter().map(sphere_around).collect();
        TriangleGrid {
            triangles,
            spheres,
            origin: lo,
            cell,
            dims,
            cell_offsets,
            cell_triangles,
            tree: std::sync::OnceLock::new(),
        }
    }

    /// Number of indexed triangles.
    pub fn n_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// Corners of indexed triangle `f` (mm), in the order of the mesh it was built from.
    pub fn triangle(&self, f: u32) -> [[f32; 3]; 3] {
        self.triangles[f as usize]
    }

    /// A sphere around triangle `f`: its centroid and the distance to its furthest corner (mm),
    /// for rejecting it cheaply in nearest-point searches.
    pub fn bounding_sphere(&self, f: u32) -> ([f64; 3], f64) {
        self.spheres[f as usize]
    }

    /// The nearest triangle to `p` and its distance; `None` if there are no triangles.
    pub fn nearest(&self, p: [f32; 3]) -> Option<Nearest> {
        self.nearest_matching(p, |_| true)
    }

    /// The nearest triangle to `p` among those `keep` accepts (by index); `None` if none is.
    pub fn nearest_matching(&self, p: [f32; 3], keep: impl Fn(u32) -> bool) -> Option<Nearest> {
        self.nearest_matching_within(p, f64::INFINITY, keep)
    }

    /// As [`Self::nearest_matching`], among triangles no further than `within` (mm): a search
    /// that only needs to beat a known distance stops there.
    pub fn nearest_matching_within(
        &self,
        p: [f32; 3],
        within: f64,
        keep: impl Fn(u32) -> bool,
    ) -> Option<Nearest> {
        if self.triangles.is_empty() || within.is_nan() {
            return None;
        }
        let q = p.map(f64::from);
        let dims = self.dims;
        let center: [usize; 3] = std::array::from_fn(|a| {
            (((q[a] - self.origin[a]) / self.cell).floor().max(0.0) as usize).min(dims[a] - 1)
        });
        let mut best = within;
        // None yet: a triangle exactly at `within` still counts.
        let mut best_triangle = u32::MAX;
        let max_ring = dims.iter().copied().max().unwrap_or(1);
        let mut settled = false;
        for r in 0..=max_ring {
            let lo: [usize; 3] = std::array::from_fn(|a| center[a].saturating_sub(r));
            let hi: [usize; 3] = std::array::from_fn(|a| (center[a] + r).min(dims[a] - 1));
            // Only the shell of ring r (inner cells were searched already): whole rows where
            // j or k is on the shell, else just the two end cells of the row.
            let mut visit = |i: usize, j: usize, k: usize| {
                // Skip cells that cannot hold anything closer than the best so far.
                let cell_gap2: f64 = [i, j, k]
                    .iter()
                    .enumerate()
                    .map(|(a, &x)| {
                        let lo = self.origin[a] + x as f64 * self.cell;
                        let gap = (lo - q[a]).max(q[a] - (lo + self.cell)).max(0.0);
                        gap * gap
                    })
                    .sum();
                if cell_gap2 > best * best {
                    return;
                }
                let c = (k * dims[1] + j) * dims[0] + i;
                let ids = &self.cell_triangles
                    [self.cell_offsets[c] as usize..self.cell_offsets[c + 1] as usize];
                for &f in ids {
                    if keep(f) {
                        let (triangles, spheres) = (&self.triangles, &self.spheres);
                        offer(triangles, spheres, p, f, &mut best, &mut best_triangle);
                    }
                }
            };
            let on_shell = |x: usize, a: usize| x + r == center[a] || x == center[a] + r;
            for k in lo[2]..=hi[2] {
                for j in lo[1]..=hi[1] {
                    if on_shell(k, 2) || on_shell(j, 1) {
                        for i in lo[0]..=hi[0] {
                            visit(i, j, k);
                        }
                    } else {
                        if center[0] >= r {
                            visit(center[0] - r, j, k);
                        }
                        if r > 0 && center[0] + r < dims[0] {
                            visit(center[0] + r, j, k);
                        }
                    }
                }
            }
            // Nothing unvisited can be closer than the nearest face of the visited block on
            // a side where the grid goes on.
            let mut bound = f64::INFINITY;
            for a in 0..3 {
                if lo[a] > 0 {
                    bound = bound.min(q[a] - (self.origin[a] + lo[a] as f64 * self.cell));
                }
                if hi[a] + 1 < dims[a] {
                    bound = bound.min(self.origin[a] + (hi[a] + 1) as f64 * self.cell - q[a]);
                }
            }
            if best <= bound {
                settled = true;
                break;
            }
            // Nothing found yet, or more than two rings still to search: the rings left grow
            // with the cube of the distance, the tree's search does not.
            if r >= NEAR_RINGS && (best_triangle == u32::MAX || best > bound + 2.0 * self.cell) {
                break;
            }
        }
        if !settled {
            // Far from the surface: the tree finds the nearest of all triangles no further
            // than the best so far (the same answer, ties included, as more rings would).
            if let Some((d, f)) = self
                .tree
                .get_or_init(|| bvh::TriangleBvh::build(&self.triangles))
                .nearest_matching_within(&self.triangles, &self.spheres, p, best, &keep)
            {
                if d < best || (d == best && f < best_triangle) {
                    best = d;
                    best_triangle = f;
                }
            }
        }
        (best_triangle != u32::MAX).then_some(Nearest {
            distance: best,
            triangle: best_triangle,
        })
    }

    /// Distance from each point to the surface (mm), in parallel; infinite if it is empty.
    pub fn distances(&self, points: &[[f32; 3]]) -> Vec<f64> {
        points
            .par_iter()
            .map(|&p| self.nearest(p).map_or(f64::INFINITY, |n| n.distance))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_point_regions_by_hand() {
        let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert_eq!(point_triangle_distance([0.25, 0.25, 2.0], t), 2.0);
        assert_eq!(point_triangle_distance([-1.0, -1.0, 0.0], t), 2f64.sqrt());
        assert_eq!(point_triangle_distance([0.5, -3.0, 4.0], t), 5.0);
        assert!((point_triangle_distance([1.0, 1.0, 0.0], t) - 0.5f64.sqrt()).abs() < 1e-12);
        // Collinear triangle: distance to the segment.
        let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!((point_triangle_distance([1.5, 1.0, 0.0], line) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn regions_name_where_the_closest_point_lies() {
        use TriangleRegion::{Corner, Edge, Inside};
        let (a, b, c) = ([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]);
        let region = |p| closest_point_and_region(p, a, b, c).1;
        assert_eq!(region([0.5, 0.5, 1.0]), Inside);
        assert_eq!(region([-1.0, -1.0, 0.0]), Corner(0));
        assert_eq!(region([3.0, -0.5, 0.0]), Corner(1));
        assert_eq!(region([-0.5, 3.0, 0.0]), Corner(2));
        assert_eq!(region([1.0, -1.0, 0.0]), Edge(0));
        assert_eq!(region([2.0, 2.0, 0.0]), Edge(1));
        assert_eq!(region([-1.0, 1.0, 0.0]), Edge(2));
        // On random triangles the point matches its region: a corner is that corner, an
        // edge point lies on that edge, an inside point is off every edge.
        let mut rng = fastrand::Rng::with_seed(7);
        let mut r = || 4.0 * rng.f64() - 2.0;
        for _ in 0..2000 {
            let t: [[f64; 3]; 3] = std::array::from_fn(|_| [r(), r(), r()]);
            let p = [r(), r(), r()];
            let (x, region) = closest_point_and_region(p, t[0], t[1], t[2]);
            let on_segment = |i: usize| {
                let (s, e) = (t[i], t[(i + 1) % 3]);
                let d = sub(e, s);
                let u = (dot(sub(x, s), d) / dot(d, d)).clamp(0.0, 1.0);
                let y = along(s, d, u);
                dot(sub(x, y), sub(x, y)).sqrt() < 1e-9
            };
            match region {
                Corner(i) => assert_eq!(x, t[i as usize]),
                Edge(i) => assert!(on_segment(i as usize), "{t:?} {p:?}"),
                Inside => assert!((0..3).all(|i| !on_segment(i)), "{t:?} {p:?}"),
            }
            assert_eq!(x, closest_point_on_triangle(p, t[0], t[1], t[2]));
        }
    }
}
