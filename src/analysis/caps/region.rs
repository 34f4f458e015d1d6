//! Examining one grown flat region (the checks of cap detection after growth): its border,
//! the side the surface leaves it on, how sharply the surface turns beyond the border, and its
//! width; with the per-vertex scratch passed between regions.

use super::{angle_deg, dot, region_area, unit_f32, Candidate, Cap, CapParams, NONE};
use crate::mesh::geometry::triangle_area_vector;
use crate::mesh::{Mesh, Topology};
use rayon::prelude::*;

/// What examining one grown flat region found.
pub(super) enum Verdict {
    /// A cap, unless the staircase-border check turns it down.
    Cap(Candidate),
    /// The surface leaves it both ways: a staircase terrace.
    Terrace,
    /// No border, no clear direction or no sharp turn.
    Other,
}

/// Per-vertex scratch passed between the regions [`examine_region`] looks at, so that a
/// region costs what its vertices cost, not the mesh's size.
pub(super) struct RegionScratch {
    /// Per vertex: the tag of the last region that stamped it, and that region's faces there.
    stamp: Vec<(u32, u32)>,
    /// The last tag handed out (tags only grow, so no vertex holds a new region's tag).
    tag: u32,
    /// The outward search's distances.
    reached: Reached,
}

impl RegionScratch {
    pub(super) fn new(n_vertices: usize) -> Self {
        Self {
            stamp: vec![(NONE, 0); n_vertices],
            tag: 0,
            reached: Reached::new(n_vertices),
        }
    }

    /// Whether the scratch is sized for a mesh of `n_vertices`.
    pub(super) fn fits(&self, n_vertices: usize) -> bool {
        self.stamp.len() == n_vertices
    }

    /// A tag no vertex holds yet (all stamps cleared once every 2^32 - 2 regions).
    fn next_tag(&mut self) -> u32 {
        if self.tag == NONE - 1 {
            self.stamp.fill((NONE, 0));
            self.tag = 0;
        }
        self.tag += 1;
        self.tag
    }
}

/// The checks of [`caps_of`](super::caps_of) on one grown region (its `faces`), with scratch passed between
/// regions.
pub(super) fn examine_region(
    mesh: &Mesh,
    topology: &Topology,
    normals: &[[f32; 3]],
    faces: &[u32],
    scratch: &mut RegionScratch,
    params: &CapParams,
) -> Verdict {
    let id = scratch.next_tag();
    let RegionScratch { stamp, reached, .. } = scratch;
    let (tris, p) = (mesh.triangles(), mesh.positions());
    // The region's vertices, each stamped with its id once (no sort of every corner and no
    // search per lookup: a region can be the whole of a finely sampled surface), with the
    // number of the region's faces around it; and the sum of the area vectors, in face order
    // as in `region_normal`.
    let mut vertices: Vec<u32> = Vec::new();
    let mut area_sum = [0.0f64; 3];
    for &f in faces {
        let t = tris[f as usize];
        let a = triangle_area_vector(mesh, t);
        for k in 0..3 {
            area_sum[k] += a[k] as f64;
        }
        for v in t {
            let s = &mut stamp[v as usize];
            if s.0 == id {
                s.1 += 1;
            } else {
                *s = (id, 1);
                vertices.push(v);
            }
        }
    }
    let stamp = &*stamp;
    let in_region = |v: u32| stamp[v as usize].0 == id;
    // Border vertices: some incident face outside the region, so fewer region faces around
    // them than faces (a region face has three distinct corners, each listing it once). A
    // region without one (a closed surface flat everywhere at this sampling) is no cap.
    let border_of = |chunk: &[u32]| -> Vec<u32> {
        (chunk.iter().copied())
            .filter(|&v| (stamp[v as usize].1 as usize) < topology.vertex_faces(v as usize).len())
            .collect()
    };
    let mut border: Vec<u32> = if vertices.len() <= 1 << 14 {
        border_of(&vertices)
    } else {
        let parts: Vec<Vec<u32>> = vertices.par_chunks(1 << 14).map(border_of).collect();
        parts.concat()
    };
    if border.is_empty() {
        return Verdict::Other;
    }
    border.par_sort_unstable();
    let normal = unit_f32(area_sum);
    // Sign of the largest offset of the outside neighbours along the region normal, counted
    // where the slope is clear.
    let (up, down) = border
        .par_iter()
        .with_min_len(4096)
        .map(|&v| {
            let pv = p[v as usize];
            let mut best = (0.0f32, 0.0f32);
            for &u in topology.neighbors(v as usize) {
                if in_region(u) {
                    continue;
                }
                let pu = p[u as usize];
                let d = (0..3).map(|k| (pu[k] - pv[k]) * normal[k]).sum::<f32>();
                if d.abs() > best.0.abs() {
                    let len = (0..3).map(|k| (pu[k] - pv[k]).powi(2)).sum::<f32>().sqrt();
                    best = (d, len);
                }
            }
            let (d, len) = best;
            if d > params.min_slope * len {
                (1, 0)
            } else if d < -params.min_slope * len {
                (0, 1)
            } else {
                (0, 0)
            }
        })
        .reduce(|| (0usize, 0usize), |a, b| (a.0 + b.0, a.1 + b.1));
    if up + down == 0 {
        return Verdict::Other;
    }
    if up.min(down) as f32 > params.max_minority * (up + down) as f32 {
        return Verdict::Terrace;
    }
    // A cut leaves a rim where the wall turns away sharply (near 90 degrees for a tube cut
    // across); a flat facet of a rounded surface is followed by more facets at shallow angles.
    // Follow the surface outwards from the border up to a share of the region's width and see
    // how far it turns.
    let width = region_width(p, &vertices, normal);
    let turned = turning_border(
        mesh,
        topology,
        normals,
        &border,
        in_region,
        (normal, params.turn_reach * width, params.turn_deg),
        reached,
    );
    if (turned as f32) < params.min_turning_border * border.len() as f32 {
        return Verdict::Other;
    }
    let mut sorted_faces = faces.to_vec();
    sorted_faces.par_sort_unstable();
    Verdict::Cap(Candidate {
        cap: Cap {
            faces: sorted_faces,
            vertices,
            normal,
            area_mm2: region_area(mesh, faces),
        },
        border,
    })
}

/// Distances of the outward search from a region's border (mm; infinite where not reached),
/// one per vertex of the mesh and kept between regions: a search resets what it reached, so
/// no region pays for clearing or hashing the whole mesh.
struct Reached {
    distance: Vec<f32>,
    touched: Vec<u32>,
}

impl Reached {
    fn new(n_vertices: usize) -> Self {
        Self {
            distance: vec![f32::INFINITY; n_vertices],
            touched: Vec::new(),
        }
    }

    fn set(&mut self, v: u32, d: f32) {
        if self.distance[v as usize] == f32::INFINITY {
            self.touched.push(v);
        }
        self.distance[v as usize] = d;
    }

    fn clear(&mut self) {
        for &v in &self.touched {
            self.distance[v as usize] = f32::INFINITY;
        }
        self.touched.clear();
    }
}

/// Number of border vertices from which the surface, followed outwards (outside the region)
/// up to `reach` mm, reaches a face whose normal is at least `turn_deg` from `normal`.
fn turning_border(
    mesh: &Mesh,
    topology: &Topology,
    face_normals: &[[f32; 3]],
    border: &[u32],
    in_region: impl Fn(u32) -> bool,
    (normal, reach, turn_deg): ([f32; 3], f32, f32),
    best: &mut Reached,
) -> usize {
    use std::collections::BinaryHeap;
    let p = mesh.positions();
    // Multi-source search from the border; each queued vertex carries its source.
    best.clear();
    let mut heap = BinaryHeap::new();
    for (i, &v) in border.iter().enumerate() {
        best.set(v, 0.0);
        heap.push(std::cmp::Reverse((0u32, v, i)));
    }
    let mut turned = vec![false; border.len()];
    let turned_from = at_least_angle(normal, turn_deg);
    while let Some(std::cmp::Reverse((d_bits, v, source))) = heap.pop() {
        let d = f32::from_bits(d_bits);
        if best.distance[v as usize] < d {
            continue;
        }
        // A source that has turned stays turned; its search goes on only to keep the other
        // sources' nearest vertices what they were.
        if !turned[source] {
            turned[source] = (topology.vertex_faces(v as usize).iter())
                .any(|&f| turned_from(face_normals[f as usize]));
        }
        let pv = p[v as usize];
        for &u in topology.neighbors(v as usize) {
            if in_region(u) {
                continue;
            }
            let pu = p[u as usize];
            let nd = d + (0..3).map(|k| (pu[k] - pv[k]).powi(2)).sum::<f32>().sqrt();
            if nd <= reach && nd < best.distance[u as usize] {
                best.set(u, nd);
                // Non-negative f32 bits order like the values.
                heap.push(std::cmp::Reverse((nd.to_bits(), u, source)));
            }
        }
    }
    turned.iter().filter(|&&t| t).count()
}

/// A test of whether a face normal is at least `turn_deg` from `normal` (unit), deciding as
/// `angle_deg(n, normal) >= turn_deg` does, zero normals excepted (never): by the cosine where
/// it is clear by a wide margin (1e-4, thousands of times the arc cosine's rounding), by the arc
/// cosine only near the limit.
fn at_least_angle(normal: [f32; 3], turn_deg: f32) -> impl Fn([f32; 3]) -> bool {
    let quick = turn_deg > 0.0 && turn_deg < 180.0;
    let cos_limit = f64::from(turn_deg).to_radians().cos();
    move |n: [f32; 3]| {
        if n == [0.0; 3] {
            return false;
        }
        let cos = f64::from(dot(n, normal));
        if quick && cos < cos_limit - 1e-4 {
            return true;
        }
        if quick && cos > cos_limit + 1e-4 {
            return false;
        }
        angle_deg(n, normal) >= turn_deg
    }
}

/// Smallest extent of a region within its plane (mm): four standard deviations along the
/// in-plane direction of least spread (a disk gives its diameter, a strip about its width).
fn region_width(p: &[[f32; 3]], vertices: &[u32], normal: [f32; 3]) -> f32 {
    // An orthonormal basis (u, w) of the plane.
    let helper = if normal[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let cross = |a: [f32; 3], b: [f32; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let unit = |a: [f32; 3]| {
        let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
            .sqrt()
            .max(f32::MIN_POSITIVE);
        a.map(|x| x / l)
    };
    let u = unit(cross(normal, helper));
    let w = cross(normal, u);
    let coords: Vec<(f64, f64)> = vertices
        .iter()
        .map(|&v| {
            let q = p[v as usize];
            let dot = |a: [f32; 3]| (q[0] * a[0] + q[1] * a[1] + q[2] * a[2]) as f64;
            (dot(u), dot(w))
        })
        .collect();
    let n = coords.len().max(1) as f64;
    let (mx, my) = coords
        .iter()
        .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x / n, b + y / n));
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for &(x, y) in &coords {
        sxx += (x - mx) * (x - mx) / n;
        syy += (y - my) * (y - my) / n;
        sxy += (x - mx) * (y - my) / n;
    }
    // Smaller eigenvalue of the 2 x 2 covariance.
    let half_trace = 0.5 * (sxx + syy);
    let det = sxx * syy - sxy * sxy;
    let min_var = (half_trace - (half_trace * half_trace - det).max(0.0).sqrt()).max(0.0);
    (4.0 * min_var.sqrt()) as f32
}
