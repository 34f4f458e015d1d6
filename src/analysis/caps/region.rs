//! Examining one grown flat region (the checks of cap detection after growth): its border,
//! the side the surface leaves it on, how sharply the surface turns beyond the border, its
//! extent, and how the part behind it runs on (its cross-section with depth); with the
//! per-vertex scratch passed between regions.

use super::{angle_deg, dot, region_area, unit_f32, Candidate, Cap, CapEvidence, CapParams, NONE};
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
    /// The searches' per-vertex figures (path lengths, depths).
    reached: Reached,
    /// Per face: the tag of the last region that holds it.
    face_stamp: Vec<u32>,
}

impl RegionScratch {
    pub(super) fn new(n_vertices: usize, n_faces: usize) -> Self {
        Self {
            stamp: vec![(NONE, 0); n_vertices],
            tag: 0,
            reached: Reached::new(n_vertices),
            face_stamp: vec![NONE; n_faces],
        }
    }

    /// Whether the scratch is sized for a mesh of `n_vertices` and `n_faces`.
    pub(super) fn fits(&self, n_vertices: usize, n_faces: usize) -> bool {
        self.stamp.len() == n_vertices && self.face_stamp.len() == n_faces
    }

    /// A tag no vertex holds yet (all stamps cleared once every 2^32 - 2 regions).
    fn next_tag(&mut self) -> u32 {
        if self.tag == NONE - 1 {
            self.stamp.fill((NONE, 0));
            self.face_stamp.fill(NONE);
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
    (normals, outward): (&[[f32; 3]], Option<bool>),
    (faces, terrace_gap): (&[u32], impl Fn() -> f32),
    scratch: &mut RegionScratch,
    params: &CapParams,
) -> Verdict {
    let id = scratch.next_tag();
    let RegionScratch {
        stamp,
        reached,
        face_stamp,
        ..
    } = scratch;
    let (tris, p) = (mesh.triangles(), mesh.positions());
    // The region's vertices, each stamped with its id once (no sort of every corner and no
    // search per lookup: a region can be the whole of a finely sampled surface), with the
    // number of the region's faces around it; and the sum of the area vectors, in fixed point
    // so that it does not depend on the order the file lists the faces in (the depths below
    // are measured along the normal, and on a grid many vertices lie exactly on a slab's face).
    let mut vertices: Vec<u32> = Vec::new();
    let mut fixed_sum = [0i128; 3];
    for &f in faces {
        face_stamp[f as usize] = id;
        let t = tris[f as usize];
        let a = triangle_area_vector(mesh, t);
        for k in 0..3 {
            fixed_sum[k] += (f64::from(a[k]) * FIXED_POINT).round() as i128;
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
    let area_sum = fixed_sum.map(|x| x as f64 / FIXED_POINT);
    let normal = unit_f32(area_sum);
    // Sign of the largest offset of the outside neighbours along the region normal, counted
    // where the slope is clear.
    let sides: Vec<Side> = border
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
                Side::Up
            } else if d < -params.min_slope * len {
                Side::Down
            } else {
                Side::Level
            }
        })
        .collect();
    let (up, down) = count_sides(&sides, &[]);
    if up + down == 0 {
        return Verdict::Other;
    }
    if up.min(down) as f32 > params.max_minority * (up + down) as f32 {
        return Verdict::Terrace;
    }
    // A clipped end: the wall beyond the rim runs on along the normal with the cap's
    // cross-section. The top of a lobe steps outward into the next terrace (its cross-section
    // grows), a slab ends within a slice and the side of a tube lying across the normal
    // within its width (the wall does not run on), a facet on a slope has the whole structure
    // behind it (the cross-section is many times the facet).
    let (width, length) = region_extent(p, &vertices, normal);
    // A tube's cut is compact (a circle, an ellipse when cut obliquely); a long flat strip is
    // the side of a tube lying across the normal, or a chamfer along one.
    if length > params.max_aspect * width {
        return Verdict::Other;
    }
    // A cut leaves a rim where the wall turns away sharply (near 90 degrees for a tube cut
    // across); a flat facet of a rounded surface is followed by more facets at shallow angles.
    // Follow the surface outwards from the border up to a share of the region's width and see
    // how far it turns.
    let beyond = turning_border(
        mesh,
        topology,
        normals,
        &border,
        in_region,
        (
            normal,
            params.turn_reach * width,
            params.turn_deg,
            params.min_slope,
        ),
        reached,
    );
    // On a smoothed mesh the first ring beyond a border may show no slope where the surface
    // rises gently into the next terrace or a junction: where it rises within the reach, the
    // border vertex counts as leaving upwards.
    let (up, down) = count_sides(&sides, &beyond.rises);
    if up.min(down) as f32 > params.max_minority * (up + down) as f32 {
        return Verdict::Terrace;
    }
    // Behind a clipped end lies the structure: the surface leaves it inwards. Where it leaves
    // outwards all round, the region is the floor of a dent (an inner corner's chamfer).
    if outward.is_some_and(|out| out != (down > up)) {
        return Verdict::Other;
    }
    if (beyond.turned as f32) < params.min_turning_border * border.len() as f32 {
        return Verdict::Other;
    }
    // The slices along the normal: the grid's spacing, or (grid unknown) the gap to the next
    // terrace facing the same way when it is within the region's width (a tube's far end
    // is no terrace).
    let slice = match params.grid {
        Some(g) => g.spacing_along(normal),
        None => Some(terrace_gap())
            .filter(|&gap| gap <= width)
            .unwrap_or(0.0),
    };
    let slices = params.runs_on_slices * slice;
    let depths = Depths {
        section: (params.section_depth_share * width).max(slices),
        run: (params.run_depth_share * length).max(slices),
    };
    let face_in_region = |f: u32| face_stamp[f as usize] == id;
    let section = cross_sections(
        mesh,
        topology,
        (&border, &in_region, &face_in_region),
        (normal, length),
        depths.section,
        area_sum,
        reached,
    );
    // The wall's run is followed only behind a region whose cross-section passed: it may
    // reach far.
    let is_cap = section.is_cut(params)
        && slab(
            mesh,
            topology,
            (&border, &in_region),
            (normal, length),
            depths.run,
            reached,
        )
        .1;
    let mut sorted_faces = faces.to_vec();
    sorted_faces.par_sort_unstable();
    let cap = Cap {
        faces: sorted_faces,
        vertices,
        normal,
        area_mm2: region_area(mesh, faces),
        evidence: CapEvidence {
            width_mm: width,
            length_mm: length,
            section_depth_mm: depths.section,
            run_depth_mm: depths.run,
            span: section.span(),
            growth: section.growth(),
        },
    };
    if !is_cap {
        return Verdict::Other;
    }
    Verdict::Cap(Candidate { cap, border })
}

/// Units per mm² of the fixed-point sum of area vectors (2^32: below float noise of any face
/// a mesh in mm holds; sums stay far inside i128).
const FIXED_POINT: f64 = 4_294_967_296.0;

/// Relative margin at the slab's faces and the bins' edges, far above float noise in a normal
/// and far below any spacing.
const SNAP: f32 = 1e-3;

/// How deep the surface behind a flat region is examined (mm below its plane).
#[derive(Debug, Clone, Copy)]
struct Depths {
    /// The cross-section is measured down to here...
    section: f32,
    /// ...and the wall must run on at least this far.
    run: f32,
}

/// How the cross-section of the part behind a flat region changes with depth: what tells a
/// clipped end from the top of a lobe.
#[derive(Debug, Clone, Copy)]
struct CrossSections {
    /// The region's own area projected on its plane (mm²).
    cap_mm2: f64,
    /// The cross-section enclosed by the surface reached from the rim at half the section
    /// depth and at all of it (mm²).
    half_mm2: f64,
    full_mm2: f64,
}

impl CrossSections {
    /// Cross-section at half the depth over the region's area.
    fn span(&self) -> f64 {
        if self.cap_mm2 > 0.0 {
            self.half_mm2 / self.cap_mm2
        } else {
            f64::INFINITY
        }
    }

    /// Cross-section at the depth over that at half of it.
    fn growth(&self) -> f64 {
        if self.half_mm2 > 0.0 {
            self.full_mm2 / self.half_mm2
        } else {
            f64::INFINITY
        }
    }

    /// Whether the cross-section neither grows nor shrinks much (a lobe widening below its top
    /// terrace, a neck below a bulge) and does not dwarf the region (a facet on a slope).
    fn is_cut(&self, params: &CapParams) -> bool {
        let growth = self.growth();
        growth <= f64::from(params.max_section_growth)
            && growth * f64::from(params.max_section_growth) >= 1.0
            && self.span() <= f64::from(params.max_section_span)
    }
}

/// Cross-sections of the surface behind a flat region (`border`, vertices by `in_region`,
/// faces by `face_in_region`) with outward unit `normal` and area vectors summing to
/// `area_sum`, down to `depth` mm below its plane. By the divergence theorem the region and the
/// surface reached from its rim within the slab, projected on the normal, enclose the
/// cross-section at the slab's lower edge, so no plane has to be cut.
fn cross_sections(
    mesh: &Mesh,
    topology: &Topology,
    (border, in_region, face_in_region): (&[u32], &impl Fn(u32) -> bool, &impl Fn(u32) -> bool),
    (normal, length): ([f32; 3], f32),
    depth: f32,
    area_sum: [f64; 3],
    seen: &mut Reached,
) -> CrossSections {
    let tris = mesh.triangles();
    let n = normal.map(f64::from);
    let (patch, _) = slab(
        mesh,
        topology,
        (border, in_region),
        (normal, length),
        depth,
        seen,
    );
    // Projected area of the patch's faces by the depth of their deepest corner.
    const BINS: usize = 16;
    let mut bins = [0.0f64; BINS];
    let reached = |w: u32| in_region(w) || seen.distance[w as usize] != f32::INFINITY;
    for &v in &patch {
        for &f in topology.vertex_faces(v as usize) {
            let t = tris[f as usize];
            // Each face once: at its first corner outside the region.
            if face_in_region(f)
                || t.iter().copied().find(|&w| !in_region(w)) != Some(v)
                || !t.iter().all(|&w| reached(w))
            {
                continue;
            }
            let deepest = (t.iter())
                .map(|&w| {
                    if in_region(w) {
                        0.0
                    } else {
                        seen.distance[w as usize]
                    }
                })
                .fold(0.0f32, f32::max);
            let a = triangle_area_vector(mesh, t);
            // Nudged up: corners on the grid lie exactly on bin edges, and float noise in the
            // normal (summed in face order) must not move them across.
            let bin = (deepest / depth.max(f32::MIN_POSITIVE) * BINS as f32 + SNAP) as usize;
            bins[bin.min(BINS - 1)] += 0.5 * (0..3).map(|k| a[k] as f64 * n[k]).sum::<f64>();
        }
    }
    let cap_mm2 = 0.5 * (0..3).map(|k| area_sum[k] * n[k]).sum::<f64>();
    let half_mm2 = cap_mm2 + bins[..BINS / 2].iter().sum::<f64>();
    CrossSections {
        cap_mm2,
        half_mm2,
        full_mm2: half_mm2 + bins[BINS / 2..].iter().sum::<f64>(),
    }
}

/// The vertices reached breadth first from a region's rim (`border`, region vertices by
/// `in_region`) without leaving the slab from slightly above its plane (outward unit `normal`)
/// down to `depth` mm, nor the cylinder around the normal through the rim's centre within the
/// region's length plus the depth (the slab behind a facet on a long wall would otherwise run
/// along all of it), with their depth in `seen`; and whether the surface goes on below the
/// slab (an edge leaves it there: the structure does not end within the depth).
fn slab(
    mesh: &Mesh,
    topology: &Topology,
    (border, in_region): (&[u32], &impl Fn(u32) -> bool),
    (normal, length): ([f32; 3], f32),
    depth: f32,
    seen: &mut Reached,
) -> (Vec<u32>, bool) {
    let p = mesh.positions();
    let n = normal.map(f64::from);
    let centre: [f64; 3] = std::array::from_fn(|k| {
        border.iter().map(|&v| p[v as usize][k] as f64).sum::<f64>() / border.len().max(1) as f64
    });
    let radius = f64::from(length + depth);
    let within = |v: u32| {
        let d: [f64; 3] = std::array::from_fn(|k| p[v as usize][k] as f64 - centre[k]);
        let h = (0..3).map(|k| d[k] * n[k]).sum::<f64>();
        (0..3).map(|k| d[k] * d[k]).sum::<f64>() - h * h <= radius * radius
    };
    let along = |v: u32| (0..3).map(|k| p[v as usize][k] as f64 * n[k]).sum::<f64>();
    // The plane through the rim (its mean position along the normal).
    let level = border.iter().map(|&v| along(v)).sum::<f64>() / border.len().max(1) as f64;
    let depth_of = |v: u32| (level - along(v)) as f32;
    let above = 0.1 * depth;
    seen.clear();
    let mut queue: Vec<u32> = border.to_vec();
    for &v in border {
        seen.set(v, 0.0);
    }
    let mut goes_on = false;
    let mut next = 0;
    while let Some(&v) = queue.get(next) {
        next += 1;
        for &u in topology.neighbors(v as usize) {
            if in_region(u) || seen.distance[u as usize] != f32::INFINITY {
                continue;
            }
            let d = depth_of(u);
            // Vertices on the grid lie exactly on the slab's faces; a margin keeps float noise
            // in the normal from moving them in or out.
            if d > depth * (1.0 + SNAP) {
                goes_on = true;
            } else if d >= -above * (1.0 + SNAP) && within(u) {
                seen.set(u, d.max(0.0));
                queue.push(u);
            }
        }
    }
    (queue, goes_on)
}

/// Per-vertex figures of a search behind a region's border (the turning test's path lengths,
/// the slab's depths; mm; infinite where not reached),
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

/// How a border vertex's outside neighbours leave a region's plane (the paper's sign test).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Side {
    Up,
    Down,
    Level,
}

/// Border vertices leaving upwards and downwards: by the first ring's `sides`, a vertex that
/// `rises` (when given) counting as up whatever its first ring shows.
fn count_sides(sides: &[Side], rises: &[bool]) -> (usize, usize) {
    let mut counts = (0, 0);
    for (i, side) in sides.iter().enumerate() {
        match (rises.get(i).copied().unwrap_or(false), side) {
            (true, _) | (false, Side::Up) => counts.0 += 1,
            (false, Side::Down) => counts.1 += 1,
            (false, Side::Level) => {}
        }
    }
    counts
}

/// What the surface does beyond a region's border, followed outwards up to the reach.
struct Beyond {
    /// Border vertices from which it reaches a face turned at least the turn angle.
    turned: usize,
    /// Per border vertex: it reaches a vertex above the vertex's level along the normal by
    /// more than the least slope times the path there.
    rises: Vec<bool>,
}

/// Follows the surface outwards (outside the region) from each border vertex up to `reach`
/// mm: which border vertices reach a face whose normal is at least `turn_deg` from `normal`,
/// and which reach a vertex rising above them by more than `min_slope` times the path.
fn turning_border(
    mesh: &Mesh,
    topology: &Topology,
    face_normals: &[[f32; 3]],
    border: &[u32],
    in_region: impl Fn(u32) -> bool,
    (normal, reach, turn_deg, min_slope): ([f32; 3], f32, f32, f32),
    best: &mut Reached,
) -> Beyond {
    use std::collections::BinaryHeap;
    let p = mesh.positions();
    // Height of `v` above `from` along the normal (from the difference: where the mesh lies
    // does not matter).
    let above = |v: u32, from: u32| {
        let (a, b) = (p[v as usize], p[from as usize]);
        (0..3).map(|k| (a[k] - b[k]) * normal[k]).sum::<f32>()
    };
    // Multi-source search from the border; each queued vertex carries its source.
    best.clear();
    let mut heap = BinaryHeap::new();
    for (i, &v) in border.iter().enumerate() {
        best.set(v, 0.0);
        heap.push(std::cmp::Reverse((0u32, v, i)));
    }
    let mut turned = vec![false; border.len()];
    let mut rises = vec![false; border.len()];
    let turned_from = at_least_angle(normal, turn_deg);
    while let Some(std::cmp::Reverse((d_bits, v, source))) = heap.pop() {
        let d = f32::from_bits(d_bits);
        if best.distance[v as usize] < d {
            continue;
        }
        if !rises[source] && above(v, border[source]) > min_slope * d {
            rises[source] = true;
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
    Beyond {
        turned: turned.iter().filter(|&&t| t).count(),
        rises,
    }
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

/// Smallest and largest extent of a region within its plane (mm): four standard deviations
/// along the in-plane directions of least and most spread (a disk gives its diameter twice, a
/// strip about its width and its length).
fn region_extent(p: &[[f32; 3]], vertices: &[u32], normal: [f32; 3]) -> (f32, f32) {
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
    // Eigenvalues of the 2 x 2 covariance.
    let half_trace = 0.5 * (sxx + syy);
    let det = sxx * syy - sxy * sxy;
    let root = (half_trace * half_trace - det).max(0.0).sqrt();
    let extent = |var: f64| (4.0 * var.max(0.0).sqrt()) as f32;
    (extent(half_trace - root), extent(half_trace + root))
}
