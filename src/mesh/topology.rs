//! Mesh connectivity, built once per mesh: CSR vertex->vertex and vertex->face adjacency, the
//! edges' face counts (the edge list itself on first request), and the findings `inspect`
//! reports (boundary loops, non-manifold edges and vertices, orientation consistency,
//! connected components, Euler characteristic).
//!
//! Triangles with a repeated vertex index are degenerate: they are listed and left out of all
//! adjacency, since they have no well-defined edges or normal.

use crate::mesh::Mesh;
use crate::parallel::split_lengths;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::OnceLock;

/// Vertices per parallel block when a CSR array is split among threads.
const VERTEX_BLOCK: usize = 8192;

/// Blocks found side by side before they are appended (a wave: about 5 MB of block buffers).
const WAVE_BLOCKS: usize = 8;

/// One boundary loop: vertices in order along edges that have a single incident face.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BoundaryLoop {
    /// Vertex indices along the loop, first vertex not repeated at the end.
    pub vertices: Vec<u32>,
    /// False when the chain could not be closed (it runs into a non-manifold vertex).
    pub closed: bool,
}

/// Connectivity and topological findings of a [`Mesh`].
#[derive(Debug, Clone)]
pub struct Topology {
    vv_offsets: Vec<u32>,
    vv_neighbors: Vec<u32>,
    vf_offsets: Vec<u32>,
    vf_faces: Vec<u32>,
    /// The edges, listed on first request from the neighbour lists (smoothing never asks).
    edges: OnceLock<Vec<[u32; 2]>>,
    edge_n_faces: Vec<u32>,
    boundary_loops: Vec<BoundaryLoop>,
    non_manifold_edges: Vec<u32>,
    non_manifold_vertices: Vec<u32>,
    inconsistent_edges: Vec<u32>,
    degenerate_triangles: Vec<u32>,
    unreferenced_vertices: Vec<u32>,
    /// Connected components, found on first request (most analyses never ask).
    components: OnceLock<(Vec<u32>, usize)>,
}

impl Topology {
    /// Builds all adjacency and findings (the edge list and connected components on first
    /// request); O(F log valence), parallel where it pays.
    pub fn build(mesh: &Mesh) -> Topology {
        let n = mesh.n_vertices();
        let tris = mesh.triangles();
        let is_degenerate = |t: &[u32; 3]| t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
        let degenerate_triangles: Vec<u32> = tris
            .iter()
            .enumerate()
            .filter(|(_, t)| is_degenerate(t))
            .map(|(i, _)| i as u32)
            .collect();
        let valid = |t: &[u32; 3]| !is_degenerate(t);

        // Vertex -> face CSR, faces ascending per vertex. A few ranges of vertices side by
        // side, each reading every triangle for the corners it owns: its counts and faces land
        // in its own stretch of the arrays (no atomics), in triangle order.
        let ranges: Vec<Range<usize>> = {
            let parts = rayon::current_num_threads().clamp(1, 4);
            (0..parts)
                .map(|i| i * n / parts..(i + 1) * n / parts)
                .collect()
        };
        let mut vf_offsets: Vec<u32> = crate::hugepages::zeroed_vec(n + 1);
        split_lengths(ranges.iter().map(|r| r.len()), &mut vf_offsets[1..])
            .into_par_iter()
            .zip(&ranges)
            .for_each(|(counts, range)| {
                for t in tris.iter().filter(|t| valid(t)) {
                    for &v in t {
                        if range.contains(&(v as usize)) {
                            counts[v as usize - range.start] += 1;
                        }
                    }
                }
            });
        prefix_sum(&mut vf_offsets);
        let mut vf_faces: Vec<u32> = crate::hugepages::zeroed_vec(vf_offsets[n] as usize);
        let stretch = |r: &Range<usize>| (vf_offsets[r.end] - vf_offsets[r.start]) as usize;
        split_lengths(ranges.iter().map(stretch), &mut vf_faces)
            .into_par_iter()
            .zip(&ranges)
            .for_each(|(faces, range)| {
                let base = vf_offsets[range.start];
                let mut cursor: Vec<u32> = vf_offsets[range.clone()]
                    .iter()
                    .map(|&o| o - base)
                    .collect();
                for (f, t) in tris.iter().enumerate().filter(|(_, t)| valid(t)) {
                    for &v in t {
                        if range.contains(&(v as usize)) {
                            let c = &mut cursor[v as usize - range.start];
                            faces[*c as usize] = f as u32;
                            *c += 1;
                        }
                    }
                }
            });

        // Parallel sweeps over waves of vertex blocks: each vertex gathers the spokes of its
        // faces, which give its sorted neighbours, the edges it owns (those to larger vertices)
        // with their face counts and orientation, and its fans. A wave's blocks are appended in
        // order while the next wave is found, so the blocks' buffers are two waves' worth,
        // reused (fresh pages cost a fault each: a buffer per block, copied into the joined
        // lists, made half of the build's faults).
        let blocks = vertex_blocks(n);
        let waves: Vec<&[Range<usize>]> = blocks.chunks(WAVE_BLOCKS).collect();
        let mut joined = Joined::with_capacity(n, vf_faces.len());
        let mut front: Vec<BlockTopology> = Vec::new();
        let mut back: Vec<BlockTopology> = Vec::new();
        let find_wave = |wave: &[Range<usize>], out: &mut Vec<BlockTopology>| {
            out.resize_with(wave.len(), BlockTopology::default);
            out.par_iter_mut().zip(wave).for_each_init(
                Spokes::default,
                |spokes, (block, range)| {
                    block_topology(tris, &vf_offsets, &vf_faces, range.clone(), spokes, block)
                },
            );
        };
        if let Some(first) = waves.first() {
            find_wave(first, &mut front);
        }
        for k in 0..waves.len() {
            std::mem::swap(&mut front, &mut back);
            rayon::join(
                || joined.append(&back),
                || {
                    if let Some(next) = waves.get(k + 1) {
                        find_wave(next, &mut front);
                    }
                },
            );
        }
        drop((front, back));
        let Joined {
            vv_offsets,
            mut vv_neighbors,
            mut edge_n_faces,
            non_manifold_edges,
            inconsistent_edges,
            boundary_edges,
            non_manifold_vertices,
        } = joined;
        // Give back the reserve's untouched address space (large buffers shrink in place).
        vv_neighbors.shrink_to_fit();
        edge_n_faces.shrink_to_fit();

        let unreferenced_vertices: Vec<u32> = (0..n)
            .filter(|&v| vf_offsets[v] == vf_offsets[v + 1])
            .map(|v| v as u32)
            .collect();
        let boundary_loops = boundary_loops(&boundary_edges);

        Topology {
            vv_offsets,
            vv_neighbors,
            vf_offsets,
            vf_faces,
            edges: OnceLock::new(),
            edge_n_faces,
            boundary_loops,
            non_manifold_edges,
            non_manifold_vertices,
            inconsistent_edges,
            degenerate_triangles,
            unreferenced_vertices,
            components: OnceLock::new(),
        }
    }

    /// Number of vertices the topology was built for.
    pub fn n_vertices(&self) -> usize {
        self.vv_offsets.len() - 1
    }

    /// Neighbours of a vertex along mesh edges, sorted ascending.
    pub fn neighbors(&self, vertex_idx: usize) -> &[u32] {
        &self.vv_neighbors
            [self.vv_offsets[vertex_idx] as usize..self.vv_offsets[vertex_idx + 1] as usize]
    }

    /// The raw vertex->vertex CSR arrays (offsets of length n+1, neighbours) for hot loops.
    pub fn neighbor_csr(&self) -> (&[u32], &[u32]) {
        (&self.vv_offsets, &self.vv_neighbors)
    }

    /// Non-degenerate triangles incident to a vertex, ascending.
    pub fn vertex_faces(&self, vertex_idx: usize) -> &[u32] {
        &self.vf_faces
            [self.vf_offsets[vertex_idx] as usize..self.vf_offsets[vertex_idx + 1] as usize]
    }

    /// The raw vertex->face CSR arrays (offsets of length n+1, faces) for hot loops.
    pub fn face_csr(&self) -> (&[u32], &[u32]) {
        (&self.vf_offsets, &self.vf_faces)
    }

    /// Unique undirected edges as (smaller, larger) vertex index, sorted: listed from the
    /// neighbour lists on first request.
    pub fn edges(&self) -> &[[u32; 2]] {
        self.edges.get_or_init(|| self.list_edges())
    }

    /// The edges (v, u) with u > v, v ascending and u ascending within v: counted and filled
    /// by blocks of vertices side by side.
    fn list_edges(&self) -> Vec<[u32; 2]> {
        let blocks = vertex_blocks(self.n_vertices());
        let counts: Vec<usize> = blocks
            .par_iter()
            .map(|r| r.clone().map(|v| self.larger_neighbors(v).len()).sum())
            .collect();
        let mut edges = vec![[0u32; 2]; counts.iter().sum()];
        split_lengths(counts.iter().copied(), &mut edges)
            .into_par_iter()
            .zip(&blocks)
            .for_each(|(part, range)| {
                let mut slots = part.iter_mut();
                for v in range.clone() {
                    // The list first: zip would otherwise take a slot past its end.
                    for (&u, slot) in self.larger_neighbors(v).iter().zip(slots.by_ref()) {
                        *slot = [v as u32, u];
                    }
                }
            });
        edges
    }

    /// Number of unique undirected edges (without listing them).
    pub fn n_edges(&self) -> usize {
        self.edge_n_faces.len()
    }

    /// Neighbours of a vertex larger than it, ascending: the vertex's edges in the order
    /// [`Topology::edges`] lists them, for passes over every edge without the list.
    pub fn larger_neighbors(&self, vertex_idx: usize) -> &[u32] {
        let list = self.neighbors(vertex_idx);
        &list[list.partition_point(|&u| u <= vertex_idx as u32)..]
    }

    /// Per vertex: it ends an edge without exactly two faces (a rim or non-manifold edge).
    /// Walks the edges in the order of their face counts without listing them; all false at
    /// once on a closed manifold.
    pub fn on_irregular_edge(&self) -> Vec<bool> {
        let mut on = vec![false; self.n_vertices()];
        let counts = &self.edge_n_faces;
        if counts.iter().all(|&n| n == 2) {
            return on;
        }
        let mut e = 0;
        for v in 0..self.n_vertices() {
            for &u in self.larger_neighbors(v) {
                if counts[e] != 2 {
                    on[v] = true;
                    on[u as usize] = true;
                }
                e += 1;
            }
        }
        on
    }

    /// Number of triangles on each edge of [`Topology::edges`] (1 boundary, 2 manifold, more non-manifold).
    pub fn edge_n_faces(&self) -> &[u32] {
        &self.edge_n_faces
    }

    /// Boundary loops (open rims, clipped vessel ends), each walked in the direction its faces give.
    pub fn boundary_loops(&self) -> &[BoundaryLoop] {
        &self.boundary_loops
    }

    /// Edges (indices into [`Topology::edges`]) shared by more than two triangles.
    pub fn non_manifold_edges(&self) -> &[u32] {
        &self.non_manifold_edges
    }

    /// Vertices whose incident triangles form more than one edge-connected fan (pinch points).
    pub fn non_manifold_vertices(&self) -> &[u32] {
        &self.non_manifold_vertices
    }

    /// Manifold edges whose two triangles walk them in the same direction (flipped orientation).
    pub fn inconsistent_edges(&self) -> &[u32] {
        &self.inconsistent_edges
    }

    /// Triangles with a repeated vertex index; left out of all adjacency.
    pub fn degenerate_triangles(&self) -> &[u32] {
        &self.degenerate_triangles
    }

    /// Vertices used by no non-degenerate triangle (kept so vertex order survives).
    pub fn unreferenced_vertices(&self) -> &[u32] {
        &self.unreferenced_vertices
    }

    /// Component index per vertex (numbered by smallest vertex), `u32::MAX` if unreferenced.
    pub fn vertex_component(&self) -> &[u32] {
        &self.components().0
    }

    /// Number of edge-connected components among referenced vertices.
    pub fn n_components(&self) -> usize {
        self.components().1
    }

    /// The components, found once (a serial union-find over every edge).
    fn components(&self) -> &(Vec<u32>, usize) {
        self.components
            .get_or_init(|| components(self, &self.vf_offsets))
    }

    /// Whether every edge has two triangles, consistently oriented, and every vertex one fan.
    pub fn is_closed_oriented_manifold(&self) -> bool {
        self.boundary_loops.is_empty()
            && self.non_manifold_edges.is_empty()
            && self.non_manifold_vertices.is_empty()
            && self.inconsistent_edges.is_empty()
    }

    /// Euler characteristic V - E + F over referenced vertices and non-degenerate triangles
    /// (2 for a closed sphere-like surface, 2 per component).
    pub fn euler_characteristic(&self) -> i64 {
        let v = (self.n_vertices() - self.unreferenced_vertices.len()) as i64;
        let f = (self.vf_faces.len() / 3) as i64;
        v - self.n_edges() as i64 + f
    }
}

/// Exclusive-to-inclusive prefix sum over a counts array whose entry 0 is 0.
pub(super) fn prefix_sum(offsets: &mut [u32]) {
    for i in 1..offsets.len() {
        offsets[i] += offsets[i - 1];
    }
}

/// Vertex ranges of at most `VERTEX_BLOCK` vertices covering 0..n.
fn vertex_blocks(n: usize) -> Vec<Range<usize>> {
    (0..n.div_ceil(VERTEX_BLOCK))
        .map(|b| b * VERTEX_BLOCK..((b + 1) * VERTEX_BLOCK).min(n))
        .collect()
}

/// Union-find over the edges, in the order [`Topology::edges`] lists them but without the
/// list; components numbered in order of their smallest vertex.
fn components(topology: &Topology, vf_offsets: &[u32]) -> (Vec<u32>, usize) {
    let n = topology.n_vertices();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            let grand = parent[parent[x as usize] as usize];
            parent[x as usize] = grand;
            x = grand;
        }
        x
    }
    let edges = (0..n as u32)
        .flat_map(|a| (topology.larger_neighbors(a as usize).iter()).map(move |&b| (a, b)));
    for (a, b) in edges {
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        if ra != rb {
            // Smaller index becomes the root, so roots are each component's smallest vertex.
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            parent[hi as usize] = lo;
        }
    }
    let mut label = vec![u32::MAX; n];
    let mut n_components = 0usize;
    for v in 0..n {
        if vf_offsets[v] == vf_offsets[v + 1] {
            continue;
        }
        let root = find(&mut parent, v as u32) as usize;
        if label[root] == u32::MAX {
            label[root] = n_components as u32;
            n_components += 1;
        }
        label[v] = label[root];
    }
    (label, n_components)
}

/// Scratch buffers reused across the vertices a worker handles.
#[derive(Default)]
struct Spokes {
    /// Every face corner at v packed as other vertex << 32 | local face << 1 | (face walks
    /// v -> other), so one integer sort groups spokes by neighbour.
    spokes: Vec<u64>,
    /// The spokes along which faces walk out of v (lowest bit set), and those they come in by.
    outward: Vec<u64>,
    inward: Vec<u64>,
    parent: Vec<u32>,
}

/// Topology of one block of vertices; edge indices are local to the block.
#[derive(Default)]
struct BlockTopology {
    /// Running neighbour count at the end of each vertex, relative to the block.
    degree_ends: Vec<u32>,
    neighbors: Vec<u32>,
    /// Faces on each edge the block's vertices own, in order (edge indices are local).
    edge_n_faces: Vec<u32>,
    non_manifold_edges: Vec<u32>,
    inconsistent_edges: Vec<u32>,
    boundary_edges: Vec<[u32; 2]>,
    non_manifold_vertices: Vec<u32>,
}

fn block_topology(
    tris: &[[u32; 3]],
    vf_offsets: &[u32],
    vf_faces: &[u32],
    range: Range<usize>,
    scratch: &mut Spokes,
    out: &mut BlockTopology,
) {
    out.clear();
    let other = |s: u64| (s >> 32) as u32;
    let local = |s: u64| (s as u32) >> 1;
    for v in range {
        let faces = &vf_faces[vf_offsets[v] as usize..vf_offsets[v + 1] as usize];
        let Spokes {
            outward,
            inward,
            spokes,
            parent,
        } = scratch;
        // Each face's two spokes: the edge it walks out of v along, and the one it walks in by.
        outward.clear();
        inward.clear();
        for (local, &f) in faces.iter().enumerate() {
            let t = tris[f as usize];
            let k = if t[0] == v as u32 {
                0
            } else if t[1] == v as u32 {
                1
            } else {
                2
            };
            let local = (local as u64) << 1;
            outward.push((t[(k + 1) % 3] as u64) << 32 | local | 1);
            inward.push((t[(k + 2) % 3] as u64) << 32 | local);
        }
        outward.sort_unstable();
        inward.sort_unstable();
        // Most vertices are closed: every edge has one face walking out along it and one
        // walking in, so the two sorted halves name the same neighbours, each once. The face
        // leaving along an edge is then followed by the face coming in along it, a
        // permutation of the faces whose cycles are the fans: one walk from face 0 tells one
        // fan from several. Sorting the halves apart costs half of sorting them together.
        let closed = !faces.is_empty()
            && outward
                .iter()
                .zip(inward.iter())
                .all(|(&a, &b)| other(a) == other(b))
            && outward.windows(2).all(|w| other(w[0]) < other(w[1]));
        if closed {
            // The follower of each face, in `parent` (scratch).
            parent.clear();
            parent.resize(faces.len(), 0);
            for (&a, &b) in outward.iter().zip(inward.iter()) {
                let u = other(a);
                parent[local(a) as usize] = local(b);
                out.neighbors.push(u);
                if u > v as u32 {
                    out.edge_n_faces.push(2);
                }
            }
            let (mut f, mut length) = (parent[0], 1);
            while f != 0 && length <= faces.len() {
                f = parent[f as usize];
                length += 1;
            }
            if length != faces.len() {
                out.non_manifold_vertices.push(v as u32);
            }
            out.degree_ends.push(out.neighbors.len() as u32);
            continue;
        }
        // Anywhere else: all spokes sorted together, grouped by neighbour, each group an
        // edge whose faces are counted and compared, the faces sharing it joined by
        // union-find.
        spokes.clear();
        spokes.extend_from_slice(outward);
        spokes.extend_from_slice(inward);
        spokes.sort_unstable();
        parent.clear();
        parent.extend(0..faces.len() as u32);
        let mut fans = faces.len();
        let mut i = 0;
        while i < spokes.len() {
            let u = other(spokes[i]);
            let mut j = i + 1;
            while j < spokes.len() && other(spokes[j]) == u {
                let (ra, rb) = (
                    find_local(parent, local(spokes[i])),
                    find_local(parent, local(spokes[j])),
                );
                if ra != rb {
                    parent[ra.max(rb) as usize] = ra.min(rb);
                    fans -= 1;
                }
                j += 1;
            }
            out.neighbors.push(u);
            if u > v as u32 {
                let run = &spokes[i..j];
                let edge = out.edge_n_faces.len() as u32;
                out.edge_n_faces.push(run.len() as u32);
                match run {
                    // Keep the direction the single face walks the edge in.
                    [s] => out.boundary_edges.push(if s & 1 == 1 {
                        [v as u32, u]
                    } else {
                        [u, v as u32]
                    }),
                    [a, b] => {
                        if a & 1 == b & 1 {
                            out.inconsistent_edges.push(edge);
                        }
                    }
                    _ => out.non_manifold_edges.push(edge),
                }
            }
            i = j;
        }
        if fans > 1 {
            out.non_manifold_vertices.push(v as u32);
        }
        out.degree_ends.push(out.neighbors.len() as u32);
    }
}

impl BlockTopology {
    /// Empties every list, keeping the buffers.
    fn clear(&mut self) {
        self.degree_ends.clear();
        self.neighbors.clear();
        self.edge_n_faces.clear();
        self.non_manifold_edges.clear();
        self.inconsistent_edges.clear();
        self.boundary_edges.clear();
        self.non_manifold_vertices.clear();
    }
}

/// The blocks' lists joined in vertex order: the global neighbour CSR and edge face counts,
/// edge indices global.
struct Joined {
    vv_offsets: Vec<u32>,
    vv_neighbors: Vec<u32>,
    edge_n_faces: Vec<u32>,
    non_manifold_edges: Vec<u32>,
    inconsistent_edges: Vec<u32>,
    boundary_edges: Vec<[u32; 2]>,
    non_manifold_vertices: Vec<u32>,
}

impl Joined {
    /// Room for `n` vertices with `n_corners` face corners: a vertex has at most two
    /// neighbours per face, and every edge owns at least one of the two spokes of a corner, so
    /// the lists never move (pages, huge where the kernel offers them, are touched only as
    /// they fill, about half of this on a closed manifold).
    fn with_capacity(n: usize, n_corners: usize) -> Joined {
        let mut vv_offsets = crate::hugepages::with_capacity(n + 1);
        vv_offsets.push(0);
        Joined {
            vv_offsets,
            vv_neighbors: crate::hugepages::with_capacity(2 * n_corners),
            edge_n_faces: crate::hugepages::with_capacity(n_corners),
            non_manifold_edges: Vec::new(),
            inconsistent_edges: Vec::new(),
            boundary_edges: Vec::new(),
            non_manifold_vertices: Vec::new(),
        }
    }

    /// Appends the blocks that follow the vertices joined so far, in order.
    fn append(&mut self, blocks: &[BlockTopology]) {
        for b in blocks {
            let start = self.vv_neighbors.len() as u32;
            let first_edge = self.edge_n_faces.len() as u32;
            self.vv_offsets
                .extend(b.degree_ends.iter().map(|&d| start + d));
            self.vv_neighbors.extend_from_slice(&b.neighbors);
            self.edge_n_faces.extend_from_slice(&b.edge_n_faces);
            self.non_manifold_edges
                .extend(b.non_manifold_edges.iter().map(|e| first_edge + e));
            self.inconsistent_edges
                .extend(b.inconsistent_edges.iter().map(|e| first_edge + e));
            self.boundary_edges.extend_from_slice(&b.boundary_edges);
            self.non_manifold_vertices
                .extend_from_slice(&b.non_manifold_vertices);
        }
    }
}

fn find_local(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let grand = parent[parent[x as usize] as usize];
        parent[x as usize] = grand;
        x = grand;
    }
    x
}

/// Chains boundary half-edges into loops, preferring the faces' direction at each step.
fn boundary_loops(boundary: &[[u32; 2]]) -> Vec<BoundaryLoop> {
    if boundary.is_empty() {
        return Vec::new();
    }
    // Incidence list: (vertex, edge index, is the vertex the edge's start), sorted by vertex.
    let mut incidence: Vec<(u32, u32, bool)> = Vec::with_capacity(boundary.len() * 2);
    for (e, &[a, b]) in boundary.iter().enumerate() {
        incidence.push((a, e as u32, true));
        incidence.push((b, e as u32, false));
    }
    // Outgoing incidences sort first for a vertex, so the walk follows face direction when it can.
    incidence.sort_unstable_by_key(|&(v, e, start)| (v, !start, e));
    let incident = |v: u32| {
        let lo = incidence.partition_point(|&(w, _, _)| w < v);
        let hi = incidence.partition_point(|&(w, _, _)| w <= v);
        &incidence[lo..hi]
    };
    let mut used = vec![false; boundary.len()];
    let mut loops = Vec::new();
    for start in 0..boundary.len() {
        if used[start] {
            continue;
        }
        used[start] = true;
        let [first, mut current] = boundary[start];
        let mut vertices = vec![first, current];
        let mut closed = false;
        loop {
            let next = incident(current)
                .iter()
                .find(|&&(_, e, _)| !used[e as usize])
                .map(|&(_, e, is_start)| {
                    let [a, b] = boundary[e as usize];
                    (e, if is_start { b } else { a })
                });
            let Some((e, other)) = next else { break };
            used[e as usize] = true;
            if other == first {
                closed = true;
                break;
            }
            vertices.push(other);
            current = other;
        }
        loops.push(BoundaryLoop { vertices, closed });
    }
    loops
}
