//! Exact point-to-surface distance: the closest point on a triangle, a bounding volume
//! hierarchy over a mesh's triangles that answers nearest-triangle queries near and far from
//! the surface ([`bvh`]), and exact triangle-triangle intersection ([`intersect`]).

pub mod bvh;
pub mod cells;
pub mod intersect;

pub use bvh::{Nearest, TriangleBvh};

type V3 = [f64; 3];

/// a - b.
#[inline]
pub fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// a . b.
#[inline]
pub fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The point a + t d.
#[inline]
pub fn along(a: V3, d: V3, t: f64) -> V3 {
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

/// Box of a triangle's corners (mm): its lowest and highest coordinate on each axis.
#[inline]
pub fn triangle_box(t: &[[f32; 3]; 3]) -> ([f32; 3], [f32; 3]) {
    let lo = std::array::from_fn(|a| min(min(t[0][a], t[1][a]), t[2][a]));
    let hi = std::array::from_fn(|a| max(max(t[0][a], t[1][a]), t[2][a]));
    (lo, hi)
}

/// The larger of `a` and `b` as one compare-and-select (`maxss`), where `f32::max`'s care for
/// NaN costs several instructions in the search's innermost loops; `b` when either is NaN
/// (coordinates here are finite).
#[inline(always)]
pub fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// The smaller of `a` and `b`, as [`max`] does it.
#[inline(always)]
pub fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// Distance (mm) from p to triangle (a, b, c).
pub fn point_triangle_distance(p: [f32; 3], t: [[f32; 3]; 3]) -> f64 {
    point_triangle_distance2(p, t).sqrt()
}

/// Squared distance (mm^2) from p to triangle (a, b, c): [`point_triangle_distance`] before
/// its square root, for searches that need the root only when a triangle may beat the best.
#[inline]
pub fn point_triangle_distance2(p: [f32; 3], t: [[f32; 3]; 3]) -> f64 {
    let f = |q: [f32; 3]| q.map(f64::from);
    let p = f(p);
    let q = closest_point_on_triangle(p, f(t[0]), f(t[1]), f(t[2]));
    let d = sub(p, q);
    dot(d, d)
}

/// Most (item, cell) pairs per item a grid may list, beyond [`PAIRS_ROOM`]: like-sized
/// triangles or boxes overlap about 3 cells each (one to eight cells twice their size). A few
/// huge items among many small ones (a sliver across the box, a triangle soup) can overlap
/// millions of cells each; the grid is then made coarser instead, which changes only the
/// speed of its searches, so memory stays bounded and counts fit `u32`.
pub(crate) const PAIRS_PER_ITEM: usize = 32;

/// Pairs a grid (or each stretch of items building one) may list besides [`PAIRS_PER_ITEM`]
/// per item.
pub(crate) const PAIRS_ROOM: usize = 1 << 16;

/// Cell size and cell counts of a uniform grid over a box of `extent` (mm): cells of about
/// `wanted` mm, but no more than `per_item` per item (`per_item` n + 64 in all).
pub(crate) fn grid_cells(
    extent: [f64; 3],
    wanted: f64,
    n_items: usize,
    per_item: usize,
) -> (f64, [usize; 3]) {
    let max_extent = extent.iter().cloned().fold(0.0, f64::max).max(1e-9);
    let mut cell = wanted.max(max_extent * 1e-6).max(1e-9);
    let budget = (per_item as f64) * n_items as f64 + 64.0;
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
