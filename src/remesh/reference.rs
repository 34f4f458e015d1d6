//! What the remeshed surface is projected back onto: the input surface, patch by patch (a
//! vertex inside a patch projects onto the input faces of that patch, so caps stay in their
//! plane), and the input's feature lines (cap rims, open borders) for the vertices on them.
//! Each input vertex carries a target edge length (mm), interpolated at the projection.

use crate::mesh::{Mesh, Topology};
use crate::spatial::{closest_point_and_region, TriangleBvh, TriangleRegion};
use rayon::prelude::*;

/// A feature line of the input (a cap rim, an open border, or a piece of one between two
/// corners) as a polyline parametrised by arc length, with the target edge length at each
/// point. Rim vertices of the remeshed surface live at arc positions on it, so a split puts
/// the new vertex between its neighbours on the line, never onto another part of it.
#[derive(Debug, Clone, Default)]
pub(super) struct Line {
    /// Points in order; a closed loop repeats its first point at the end.
    points: Vec<[f64; 3]>,
    sizes: Vec<f64>,
    /// Arc length at each point (mm).
    cum: Vec<f64>,
    pub closed: bool,
}

impl Line {
    fn new(points: Vec<[f64; 3]>, sizes: Vec<f64>, closed: bool) -> Line {
        let mut cum = Vec::with_capacity(points.len());
        let mut total = 0.0;
        for (i, p) in points.iter().enumerate() {
            if i > 0 {
                let q = points[i - 1];
                total +=
                    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
            }
            cum.push(total);
        }
        Line {
            points,
            sizes,
            cum,
            closed,
        }
    }

    /// Total length (mm).
    pub fn length(&self) -> f64 {
        self.cum.last().copied().unwrap_or(0.0)
    }

    /// Point and target edge length at arc position s (wrapped on a loop, clamped otherwise).
    pub fn eval(&self, s: f64) -> ([f64; 3], f64) {
        let len = self.length();
        if self.points.len() < 2 || len <= 0.0 {
            return (
                self.points.first().copied().unwrap_or([0.0; 3]),
                self.sizes.first().copied().unwrap_or(1.0),
            );
        }
        let s = if self.closed {
            s.rem_euclid(len)
        } else {
            s.clamp(0.0, len)
        };
        let i = self
            .cum
            .partition_point(|&c| c <= s)
            .saturating_sub(1)
            .min(self.points.len() - 2);
        let seg = self.cum[i + 1] - self.cum[i];
        let t = if seg > 0.0 {
            ((s - self.cum[i]) / seg).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (a, b) = (self.points[i], self.points[i + 1]);
        (
            std::array::from_fn(|k| a[k] + t * (b[k] - a[k])),
            self.sizes[i] + t * (self.sizes[i + 1] - self.sizes[i]),
        )
    }

    /// The arc position halfway between s0 and s1 (the shorter way round a loop).
    pub fn between(&self, s0: f64, s1: f64) -> f64 {
        if self.closed {
            let len = self.length();
            if len <= 0.0 {
                return s0;
            }
            let mut d = (s1 - s0).rem_euclid(len);
            if d > len / 2.0 {
                d -= len;
            }
            (s0 + d / 2.0).rem_euclid(len)
        } else {
            0.5 * (s0 + s1)
        }
    }

    /// Arc position of the point of the line nearest to q.
    pub fn param_near(&self, q: [f64; 3]) -> f64 {
        let mut best = (f64::INFINITY, 0.0);
        for i in 0..self.points.len().saturating_sub(1) {
            let (a, b) = (self.points[i], self.points[i + 1]);
            let d: [f64; 3] = std::array::from_fn(|k| b[k] - a[k]);
            let len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let t = if len2 > 0.0 {
                (((q[0] - a[0]) * d[0] + (q[1] - a[1]) * d[1] + (q[2] - a[2]) * d[2]) / len2)
                    .clamp(0.0, 1.0)
            } else {
                0.0
            };
            let x: [f64; 3] = std::array::from_fn(|k| a[k] + t * d[k]);
            let dist2: f64 = (0..3).map(|k| (x[k] - q[k]).powi(2)).sum();
            if dist2 < best.0 {
                best = (dist2, self.cum[i] + t * (self.cum[i + 1] - self.cum[i]));
            }
        }
        best.1
    }
}

/// One patch of the input: its faces indexed for nearest-point queries, and the target edge
/// length at the corners of each indexed face.
#[derive(Debug, Clone)]
struct PatchSurface {
    id: u32,
    tree: TriangleBvh,
    corner_size: Vec<[f64; 3]>,
    /// Faces (local vertex indices) and, per local vertex, the faces around it (CSR), for
    /// walking from a face to its neighbours.
    triangles: Vec<[u32; 3]>,
    vertex_face_offsets: Vec<u32>,
    vertex_faces: Vec<u32>,
}

impl PatchSurface {
    fn new(id: u32, sub: &Mesh, corner_size: Vec<[f64; 3]>) -> PatchSurface {
        let triangles = sub.triangles().to_vec();
        let mut vertex_face_offsets = vec![0u32; sub.n_vertices() + 1];
        for t in &triangles {
            for &v in t {
                vertex_face_offsets[v as usize + 1] += 1;
            }
        }
        for i in 1..vertex_face_offsets.len() {
            vertex_face_offsets[i] += vertex_face_offsets[i - 1];
        }
        let mut cursor = vertex_face_offsets.clone();
        let mut vertex_faces = vec![0u32; triangles.len() * 3];
        for (f, t) in triangles.iter().enumerate() {
            for &v in t {
                vertex_faces[cursor[v as usize] as usize] = f as u32;
                cursor[v as usize] += 1;
            }
        }
        PatchSurface {
            id,
            tree: TriangleBvh::build(sub),
            corner_size,
            triangles,
            vertex_face_offsets,
            vertex_faces,
        }
    }

    /// Closest point of face f to q, its squared distance and where on f it lies.
    fn closest(&self, f: u32, q: [f64; 3]) -> ([f64; 3], f64, TriangleRegion) {
        let t = self.tree.triangle(f).map(|c| c.map(f64::from));
        let (x, region) = closest_point_and_region(q, t[0], t[1], t[2]);
        let d2 = (0..3).map(|k| (x[k] - q[k]).powi(2)).sum();
        (x, d2, region)
    }

    /// Faces around local vertex v.
    fn faces_at(&self, v: u32) -> &[u32] {
        let (a, b) = (
            self.vertex_face_offsets[v as usize] as usize,
            self.vertex_face_offsets[v as usize + 1] as usize,
        );
        &self.vertex_faces[a..b]
    }

    /// From face `start`, steps to a closer neighbour across the edge or around the corner
    /// where the closest point lies, until it lies inside a face or no such neighbour is
    /// closer: the nearest face near where the vertex was, which for the small moves of
    /// relaxation is the nearest face, found in one to three triangle tests without a tree
    /// search, and never a face across a thin gap.
    fn walk(&self, start: u32, q: [f64; 3]) -> (u32, [f64; 3], f64) {
        let (mut x, mut best, mut region) = self.closest(start, q);
        let mut face = start;
        for _ in 0..64 {
            let corners = self.triangles[face as usize];
            let (around, other) = match region {
                TriangleRegion::Inside => break,
                TriangleRegion::Corner(i) => (corners[i as usize], NO_CORNER),
                TriangleRegion::Edge(i) => (corners[i as usize], corners[(i as usize + 1) % 3]),
            };
            let mut moved = false;
            for &g in self.faces_at(around) {
                if g == face || (other != NO_CORNER && !self.triangles[g as usize].contains(&other))
                {
                    continue;
                }
                let (y, d2, r) = self.closest(g, q);
                if d2 < best {
                    (face, x, best, region) = (g, y, d2, r);
                    moved = true;
                }
            }
            if !moved {
                break;
            }
        }
        (face, x, best)
    }
}

/// No second corner: the walk looks at all faces round one corner.
const NO_CORNER: u32 = u32::MAX;

#[derive(Debug, Clone)]
pub(super) struct Reference {
    patches: Vec<PatchSurface>,
    pub lines: Vec<Line>,
    /// For each input vertex inside a feature line: the line and the arc position there.
    pub on_line: Vec<Option<(u32, f64)>>,
    /// For each input vertex, a face of its patch around it (local index; a start for walks).
    pub start_face: Vec<u32>,
    /// Which corner of its `start_face` each input vertex is.
    start_corner: Vec<u8>,
}

/// Border marker in a feature line's key (the open side of a boundary edge).
pub(super) const OPEN: u32 = u32::MAX;

/// The key of the line an edge between faces of ids `i` and `j` belongs to.
#[inline]
pub(super) fn line_key(i: u32, j: u32) -> (u32, u32) {
    (i.min(j), i.max(j))
}

impl Reference {
    /// `size` is the target edge length at each input vertex (mm).
    pub fn build(mesh: &Mesh, topology: &Topology, face_ids: &[u32], size: &[f64]) -> Reference {
        let tris = mesh.triangles();
        let mut ids: Vec<u32> = face_ids.to_vec();
        ids.sort_unstable();
        ids.dedup();
        let patches = ids
            .par_iter()
            .map(|&id| {
                let faces: Vec<u32> = (0..tris.len() as u32)
                    .filter(|&f| face_ids[f as usize] == id)
                    .collect();
                let sub = mesh.select_faces(&faces);
                let corner_size = faces
                    .iter()
                    .map(|&f| tris[f as usize].map(|v| size[v as usize]))
                    .collect();
                PatchSurface::new(id, &sub, corner_size)
            })
            .collect();
        let (lines, on_line) = feature_lines(mesh, topology, face_ids, size);
        // Local face indices run in input order within each patch.
        let mut start_face = vec![u32::MAX; mesh.n_vertices()];
        let mut start_corner = vec![0u8; mesh.n_vertices()];
        let mut next_local = vec![0u32; ids.len()];
        for (f, t) in tris.iter().enumerate() {
            let k = ids.binary_search(&face_ids[f]).unwrap_or(0);
            for (i, &v) in t.iter().enumerate() {
                start_face[v as usize] = next_local[k];
                start_corner[v as usize] = i as u8;
            }
            next_local[k] += 1;
        }
        Reference {
            patches,
            lines,
            on_line,
            start_face,
            start_corner,
        }
    }

    /// The patches' ids, ascending: the k-th is the k-th patch.
    pub fn patch_ids(&self) -> Vec<u32> {
        self.patches.iter().map(|s| s.id).collect()
    }

    /// Number of faces of the k-th patch.
    pub fn patch_faces(&self, k: usize) -> usize {
        self.patches[k].triangles.len()
    }

    /// Faces (local indices) of the k-th patch around input vertex x, which must lie in it.
    pub fn faces_around_input(&self, k: usize, x: u32) -> &[u32] {
        let patch = &self.patches[k];
        let f = self.start_face[x as usize] as usize;
        patch.faces_at(patch.triangles[f][self.start_corner[x as usize] as usize])
    }

    /// Faces of the k-th patch that share a corner with its face f (f among them).
    pub fn faces_touching(&self, k: usize, f: u32) -> impl Iterator<Item = u32> + '_ {
        let patch = &self.patches[k];
        patch.triangles[f as usize]
            .into_iter()
            .flat_map(move |c| patch.faces_at(c).iter().copied())
    }

    /// The nearest point of patch `id` to `q`, the target edge length there and the face it is
    /// on; `None` if the input has no such patch. With a `hint` (the face the point was on
    /// before a small move), the search walks from there and asks the tree only when the walk
    /// ends further than `reach` (mm) from q.
    pub fn project_to_patch(
        &self,
        id: u32,
        q: [f64; 3],
        hint: u32,
        reach: f64,
    ) -> Option<([f64; 3], f64, u32)> {
        let patch = self.patches.iter().find(|s| s.id == id)?;
        let walked = (hint < patch.triangles.len() as u32).then(|| patch.walk(hint, q));
        let (face, x) = match walked {
            Some((f, x, d2)) if d2 <= reach * reach => (f, x),
            _ => {
                let near = patch.tree.nearest(q.map(|x| x as f32))?;
                let (x, _, _) = patch.closest(near.triangle, q);
                (near.triangle, x)
            }
        };
        let t = patch.tree.triangle(face).map(|c| c.map(f64::from));
        let w = barycentric(x, t);
        let s = patch.corner_size[face as usize];
        Some((x, w[0] * s[0] + w[1] * s[1] + w[2] * s[2], face))
    }
}

/// The feature lines of the input: chains of edges whose two faces differ in id (or that have
/// one face), split where more than two such edges meet or where the pair of ids changes.
fn feature_lines(
    mesh: &Mesh,
    topology: &Topology,
    face_ids: &[u32],
    size: &[f64],
) -> (Vec<Line>, Vec<Option<(u32, f64)>>) {
    let tris = mesh.triangles();
    let n = mesh.n_vertices();
    // Feature edges with their key, and per vertex the feature edges at it.
    let mut edges: Vec<([u32; 2], (u32, u32))> = Vec::new();
    let mut at: Vec<Vec<u32>> = vec![Vec::new(); n];
    for &[a, b] in topology.edges() {
        let faces: Vec<u32> = topology
            .vertex_faces(a as usize)
            .iter()
            .copied()
            .filter(|&f| tris[f as usize].contains(&b))
            .collect();
        let key = match faces.as_slice() {
            [f] => line_key(face_ids[*f as usize], OPEN),
            [f, g] if face_ids[*f as usize] != face_ids[*g as usize] => {
                line_key(face_ids[*f as usize], face_ids[*g as usize])
            }
            _ => continue,
        };
        let e = edges.len() as u32;
        edges.push(([a, b], key));
        at[a as usize].push(e);
        at[b as usize].push(e);
    }
    // A vertex continues a line when exactly two feature edges of one key meet there.
    let inner = |v: u32| {
        let es = &at[v as usize];
        es.len() == 2 && edges[es[0] as usize].1 == edges[es[1] as usize].1
    };
    let p = mesh.positions();
    let pos = |v: u32| p[v as usize].map(f64::from);
    let mut used = vec![false; edges.len()];
    let mut lines = Vec::new();
    let mut on_line = vec![None; n];
    let walk = |start: u32, first: u32, used: &mut Vec<bool>| -> (Vec<u32>, bool) {
        let mut chain = vec![start];
        let (mut v, mut e) = (start, first);
        loop {
            used[e as usize] = true;
            let [a, b] = edges[e as usize].0;
            let w = if a == v { b } else { a };
            if w == start {
                // Back at the start: a loop, unless the start is a corner (then a line
                // from the corner round to itself).
                chain.push(w);
                return (chain, inner(start));
            }
            chain.push(w);
            if !inner(w) {
                return (chain, false);
            }
            match at[w as usize].iter().find(|&&x| !used[x as usize]) {
                Some(&x) => {
                    v = w;
                    e = x;
                }
                None => return (chain, false),
            }
        }
    };
    let mut chains = Vec::new();
    // Open chains from corners first, then the closed loops left.
    for v in 0..n as u32 {
        if inner(v) {
            continue;
        }
        for &e in &at[v as usize] {
            if !used[e as usize] {
                chains.push(walk(v, e, &mut used));
            }
        }
    }
    for e in 0..edges.len() {
        if !used[e] {
            let start = edges[e].0[0];
            chains.push(walk(start, e as u32, &mut used));
        }
    }
    for (chain, closed) in chains {
        let line = Line::new(
            chain.iter().map(|&v| pos(v)).collect(),
            chain.iter().map(|&v| size[v as usize]).collect(),
            closed,
        );
        let l = lines.len() as u32;
        for (i, &v) in chain.iter().enumerate() {
            if inner(v) && on_line[v as usize].is_none() {
                on_line[v as usize] = Some((l, line.cum[i]));
            }
        }
        lines.push(line);
    }
    (lines, on_line)
}

/// Barycentric coordinates of x (on triangle t) by sub-areas; equal thirds for a sliver.
fn barycentric(x: [f64; 3], t: [[f64; 3]; 3]) -> [f64; 3] {
    let area = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
        let u: [f64; 3] = std::array::from_fn(|k| b[k] - a[k]);
        let v: [f64; 3] = std::array::from_fn(|k| c[k] - a[k]);
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
    };
    let w = [
        area(x, t[1], t[2]),
        area(t[0], x, t[2]),
        area(t[0], t[1], x),
    ];
    let sum = w[0] + w[1] + w[2];
    if sum > 0.0 && sum.is_finite() {
        w.map(|x| x / sum)
    } else {
        [1.0 / 3.0; 3]
    }
}
