//! A bounding volume hierarchy over triangles for nearest-point queries far from the surface.
//!
//! The uniform grid ([`super::TriangleGrid`]) answers a query near the surface from a few
//! cells, but a query 1 cm away searches every cell within 1 cm: a cubic cost. The tree
//! prunes whole empty regions at once, so its cost grows with the logarithm of the mesh size
//! whatever the distance. Built by median splits on the longest axis of the centroids
//! (subtrees in parallel), nodes in depth-first order, at most four triangles per leaf.

use super::{offer, point_triangle_distance};
use rayon::prelude::*;

/// Most triangles in a leaf.
const LEAF: usize = 4;
/// Subtrees with more triangles than this are built in parallel.
const PARALLEL: usize = 1 << 14;

/// A node: its box (mm), and either a leaf's stretch of [`TriangleBvh::order`] or, for an
/// inner node, how far ahead its second child is (the first follows it directly).
#[derive(Debug, Clone, Copy)]
struct Node {
    lo: [f32; 3],
    hi: [f32; 3],
    /// Leaf: first entry in `order`. Inner: offset of the second child from this node.
    start_or_skip: u32,
    /// Leaf: number of triangles (at least 1). Inner: 0.
    count: u32,
}

/// The hierarchy over a set of triangles (by their indices in the slice it was built from).
#[derive(Debug, Clone, Default)]
pub struct TriangleBvh {
    nodes: Vec<Node>,
    /// Triangle indices in leaf order.
    order: Vec<u32>,
}

/// Squared distance from `q` to the box `lo..hi` (0 inside).
fn box_distance2(q: [f64; 3], lo: [f32; 3], hi: [f32; 3]) -> f64 {
    (0..3)
        .map(|a| {
            let d = (lo[a] as f64 - q[a]).max(q[a] - hi[a] as f64).max(0.0);
            d * d
        })
        .sum()
}

impl TriangleBvh {
    /// Builds the hierarchy; the same tree for any thread count.
    pub fn build(triangles: &[[[f32; 3]; 3]]) -> TriangleBvh {
        if triangles.is_empty() {
            return TriangleBvh::default();
        }
        let bounds: Vec<([f32; 3], [f32; 3])> = triangles
            .par_iter()
            .map(|t| {
                let lo = std::array::from_fn(|a| t[0][a].min(t[1][a]).min(t[2][a]));
                let hi = std::array::from_fn(|a| t[0][a].max(t[1][a]).max(t[2][a]));
                (lo, hi)
            })
            .collect();
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let nodes = subtree(&mut order, 0, &bounds);
        TriangleBvh { nodes, order }
    }

    /// The triangle nearest to `p` among those `keep` accepts and no further than `within`,
    /// with its distance (mm); ties go to the lower index. `triangles` must be the slice the
    /// tree was built from; `spheres` their bounding spheres (centre, radius), to skip most
    /// exact tests.
    pub fn nearest_matching_within(
        &self,
        triangles: &[[[f32; 3]; 3]],
        spheres: &[([f64; 3], f64)],
        p: [f32; 3],
        within: f64,
        keep: impl Fn(u32) -> bool,
    ) -> Option<(f64, u32)> {
        if self.nodes.is_empty() || within.is_nan() {
            return None;
        }
        let q = p.map(f64::from);
        let mut best = within;
        let mut best_triangle = u32::MAX;
        // Depth is at most log2(n / LEAF) + 1 with median splits; 64 covers any u32 count.
        let mut stack = [0u32; 64];
        let mut depth = 1;
        while depth > 0 {
            depth -= 1;
            let node = self.nodes[stack[depth] as usize];
            // Strictly further than the best: nothing inside can tie it either.
            if box_distance2(q, node.lo, node.hi) > best * best {
                continue;
            }
            if node.count > 0 {
                let start = node.start_or_skip as usize;
                for &f in &self.order[start..start + node.count as usize] {
                    if keep(f) {
                        offer(triangles, spheres, p, f, &mut best, &mut best_triangle);
                    }
                }
                continue;
            }
            let first = stack[depth] + 1;
            let second = stack[depth] + node.start_or_skip;
            let d1 = {
                let n = self.nodes[first as usize];
                box_distance2(q, n.lo, n.hi)
            };
            let d2 = {
                let n = self.nodes[second as usize];
                box_distance2(q, n.lo, n.hi)
            };
            // The nearer child is searched first (pushed last).
            let (near, far) = if d2 < d1 {
                (second, first)
            } else {
                (first, second)
            };
            if depth + 2 > stack.len() {
                // Unreachable with median splits; searched in turn rather than lost.
                return self.fallback(triangles, p, within, keep);
            }
            stack[depth] = far;
            stack[depth + 1] = near;
            depth += 2;
        }
        (best_triangle != u32::MAX).then_some((best, best_triangle))
    }

    /// Every triangle tested: the answer the tree must give.
    fn fallback(
        &self,
        triangles: &[[[f32; 3]; 3]],
        p: [f32; 3],
        within: f64,
        keep: impl Fn(u32) -> bool,
    ) -> Option<(f64, u32)> {
        let mut best: Option<(f64, u32)> = None;
        for (f, t) in triangles.iter().enumerate() {
            let f = f as u32;
            if !keep(f) {
                continue;
            }
            let d = point_triangle_distance(p, *t);
            if d <= within && best.is_none_or(|(b, _)| d < b) {
                best = Some((d, f));
            }
        }
        best
    }
}

/// The nodes of the subtree over `order` (entries `base..` of the whole order), depth first.
fn subtree(order: &mut [u32], base: usize, bounds: &[([f32; 3], [f32; 3])]) -> Vec<Node> {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    let mut clo = [f32::INFINITY; 3];
    let mut chi = [f32::NEG_INFINITY; 3];
    for &f in order.iter() {
        let (l, h) = bounds[f as usize];
        for a in 0..3 {
            lo[a] = lo[a].min(l[a]);
            hi[a] = hi[a].max(h[a]);
            let c = 0.5 * (l[a] + h[a]);
            clo[a] = clo[a].min(c);
            chi[a] = chi[a].max(c);
        }
    }
    if order.len() <= LEAF {
        return vec![Node {
            lo,
            hi,
            start_or_skip: base as u32,
            count: order.len() as u32,
        }];
    }
    let axis = (0..3)
        .max_by(|&a, &b| {
            (chi[a] - clo[a])
                .total_cmp(&(chi[b] - clo[b]))
                .then(b.cmp(&a))
        })
        .unwrap_or(0);
    let centre = |f: u32| {
        let (l, h) = bounds[f as usize];
        0.5 * (l[axis] + h[axis])
    };
    let mid = order.len() / 2;
    // Ties by index: the same halves whatever the order the slice arrived in.
    order.select_nth_unstable_by(mid, |&x, &y| {
        centre(x).total_cmp(&centre(y)).then(x.cmp(&y))
    });
    let (left, right) = order.split_at_mut(mid);
    let (left, right) = if left.len() + right.len() > PARALLEL {
        rayon::join(
            || subtree(left, base, bounds),
            || subtree(right, base + mid, bounds),
        )
    } else {
        (
            subtree(left, base, bounds),
            subtree(right, base + mid, bounds),
        )
    };
    let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
    nodes.push(Node {
        lo,
        hi,
        start_or_skip: 1 + left.len() as u32,
        count: 0,
    });
    nodes.extend(left);
    nodes.extend(right);
    nodes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tree_finds_what_testing_every_triangle_finds() {
        let mut rng = fastrand::Rng::with_seed(21);
        for round in 0..30 {
            let n = [1, 2, 5, 40, 300, 3000][round % 6];
            // Small triangles scattered in a box, some repeated exactly (ties).
            let mut triangles: Vec<[[f32; 3]; 3]> = (0..n)
                .map(|_| {
                    let c: [f32; 3] = std::array::from_fn(|_| rng.f32() * 40.0);
                    std::array::from_fn(|_| std::array::from_fn(|a| c[a] + rng.f32() * 2.0))
                })
                .collect();
            if n > 3 {
                triangles[n - 1] = triangles[0];
            }
            let spheres: Vec<_> = triangles.iter().map(super::super::sphere_around).collect();
            let tree = TriangleBvh::build(&triangles);
            for _ in 0..200 {
                // Near and far: up to 60 mm outside the box.
                let p: [f32; 3] = std::array::from_fn(|_| rng.f32() * 160.0 - 60.0);
                let within = if rng.bool() {
                    f64::INFINITY
                } else {
                    rng.f64() * 30.0
                };
                let keep = |f: u32| f % 7 != 3;
                let fast = tree.nearest_matching_within(&triangles, &spheres, p, within, keep);
                let slow = tree.fallback(&triangles, p, within, keep);
                assert_eq!(fast, slow, "round {round}, point {p:?}, within {within}");
            }
        }
    }

    #[test]
    fn the_tree_does_not_depend_on_the_thread_count() {
        let mut rng = fastrand::Rng::with_seed(4);
        let triangles: Vec<[[f32; 3]; 3]> = (0..40_000)
            .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| rng.f32() * 100.0)))
            .collect();
        let build = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| TriangleBvh::build(&triangles))
        };
        let (one, three) = (build(1), build(3));
        assert_eq!(one.order, three.order);
        assert_eq!(one.nodes.len(), three.nodes.len());
    }
}
