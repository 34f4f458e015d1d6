//! Surfaces from label volumes, all labels at once (thesis ch. 6.2): every point of a cell
//! belongs to the label whose interpolated indicator is largest, so touching structures share
//! one interface and nothing overlaps or gaps.
//!
//! The cell triangulation is derived, not typed in. Each cube face is decided on its own from
//! its four corner labels by the largest-indicator rule (bilinear on the face): segments join
//! the midpoints of edges whose corners differ, and where three or four labels meet on a face
//! a branching point is placed where their bilinear indicators tie. The one ambiguous face, two
//! labels on diagonal corners, connects the label with the lower index (background before any
//! structure, as the phantoms' binary table does). Because a face is decided only from its own
//! corners, both cells that share it see the same segments and points. Inside a cell, each
//! connected set of face segments bounds a membrane: a simple loop is filled as a polygon (a
//! triangle, a quad, or a fan around its centroid), a set with branching points as a fan from
//! its centroid, where the interior curves of three labels meet. Each triangle separates two
//! labels and belongs, with opposite orientations, to both structures' surfaces.

pub mod report;

use crate::mesh::Mesh;
use crate::volume::LabelVolume;
use rustc_hash::FxHashMap;

/// One structure's surface from a label volume.
#[derive(Debug, Clone)]
pub struct LabelSurface {
    /// Dense label index in the volume (1-based).
    pub label: u16,
    pub mesh: Mesh,
}

/// All interfaces of a label volume: one triangle per interface piece, with the labels on its
/// two sides (`inner` is the side its normal points away from; 0 is background).
#[derive(Debug, Clone, Default)]
pub struct Interfaces {
    /// Vertex positions in voxel index coordinates (the volume's grid maps them to mm).
    pub positions: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// (inner, outer) label per triangle.
    pub sides: Vec<[u16; 2]>,
    /// The third vertex as the outer label's surface uses it: the same as `triangles[t][2]`,
    /// except where a label meets itself at a cell's branching point, which then has a copy
    /// per part of that label so that each surface stays a 2-manifold.
    pub outer_apex: Vec<u32>,
}

/// A segment on a cube face: endpoints (vertex keys), the labels on its two sides, and a
/// witness point (a corner) inside the first label's part of the face.
#[derive(Clone, Copy)]
struct Segment {
    ends: [u64; 2],
    labels: [u16; 2],
    witness: [f64; 3],
}

/// Where the per-cell work collects vertices: key -> index, with positions.
struct Vertices {
    index: FxHashMap<u64, u32>,
    positions: Vec<[f64; 3]>,
}

impl Vertices {
    fn get(&mut self, key: u64, position: impl FnOnce() -> [f64; 3]) -> u32 {
        let next = self.positions.len() as u32;
        *self.index.entry(key).or_insert_with(|| {
            self.positions.push(position());
            next
        })
    }
}

const KIND_EDGE: u64 = 0;
const KIND_FACE: u64 = 1;
const KIND_APEX: u64 = 2;

/// Slabs of cells (along z) per parallel task. Fixed, so results do not depend on the thread
/// count.
const SLAB: i64 = 4;

/// What one slab of cells produced: its vertices (global keys, first-seen order) and triangles
/// over them.
struct SlabOutput {
    keys: Vec<u64>,
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    outer_apex: Vec<u32>,
    sides: Vec<[u16; 2]>,
}

/// Extracts every interface of `volume` (labels outside the volume count as background, so
/// structures that reach the border are closed there by a flat cap). Slabs of cells run in
/// parallel; merging them in order gives the same vertex order as one sequential scan.
pub fn interfaces(volume: &LabelVolume) -> Interfaces {
    use rayon::prelude::*;
    let nz = volume.dims[2] as i64;
    let n_slabs = (nz + 1 + SLAB - 1) / SLAB;
    let slabs: Vec<SlabOutput> = (0..n_slabs)
        .into_par_iter()
        .map(|s| {
            let k0 = -1 + s * SLAB;
            slab(volume, k0..(k0 + SLAB).min(nz))
        })
        .collect();
    let mut index: FxHashMap<u64, u32> = FxHashMap::default();
    let mut out = Interfaces::default();
    for slab in slabs {
        let map: Vec<u32> = slab
            .keys
            .iter()
            .zip(&slab.positions)
            .map(|(&key, &p)| {
                let next = out.positions.len() as u32;
                *index.entry(key).or_insert_with(|| {
                    out.positions.push(p);
                    next
                })
            })
            .collect();
        out.triangles
            .extend(slab.triangles.iter().map(|t| t.map(|v| map[v as usize])));
        out.outer_apex
            .extend(slab.outer_apex.iter().map(|&v| map[v as usize]));
        out.sides.extend(slab.sides);
    }
    out
}

/// The cells whose lower corner lies in the z range `ks` (from -1: the pad below the volume).
fn slab(volume: &LabelVolume, ks: std::ops::Range<i64>) -> SlabOutput {
    let [nx, ny, nz] = volume.dims.map(|d| d as i64);
    // A row of voxels along x, or none outside the volume (background).
    let row = |j: i64, k: i64| -> Option<&[u16]> {
        if j < 0 || k < 0 || j >= ny || k >= nz {
            None
        } else {
            let at = (nx * (j + ny * k)) as usize;
            Some(&volume.voxels[at..at + nx as usize])
        }
    };
    let at = |r: Option<&[u16]>, i: i64| -> u16 {
        match r {
            Some(r) if i >= 0 && i < nx => r[i as usize],
            _ => 0,
        }
    };
    // Grid points with a one-voxel pad, numbered for vertex keys.
    let (px, py) = (nx + 2, ny + 2);
    let point_id =
        |i: i64, j: i64, k: i64| -> u64 { ((i + 1) + px * ((j + 1) + py * (k + 1))) as u64 };
    let mut verts = Vertices {
        index: FxHashMap::default(),
        positions: Vec::new(),
    };
    let mut out = Interfaces::default();
    let mut templates: FxHashMap<u32, Template> = FxHashMap::default();
    let mut ids: Vec<u32> = Vec::with_capacity(32);
    for k in ks {
        for j in -1..ny {
            let rows = [row(j, k), row(j + 1, k), row(j, k + 1), row(j + 1, k + 1)];
            if rows.iter().all(Option::is_none) {
                continue;
            }
            // Inside the volume, cells whose four rows hold one label are skipped without
            // building their corners.
            let full = match rows {
                [Some(a), Some(b), Some(c), Some(d)] => Some([a, b, c, d]),
                _ => None,
            };
            for i in -1..nx {
                if let Some(r) = full {
                    if i >= 0 && i + 1 < nx {
                        let (x, y) = (i as usize, i as usize + 1);
                        let v = r[0][x];
                        if r.iter().all(|row| row[x] == v && row[y] == v) {
                            continue;
                        }
                    }
                }
                // Corner c = dx + 2 dy + 4 dz: row dy + 2 dz, position i + dx.
                let labels: [u16; 8] =
                    std::array::from_fn(|c| at(rows[c >> 1], i + (c & 1) as i64));
                if labels.iter().all(|&l| l == labels[0]) {
                    continue;
                }
                // The configuration up to the labels' values: each corner's rank among the
                // cell's distinct labels (the order decides the diagonal faces).
                let mut distinct = labels;
                distinct.sort_unstable();
                let n_distinct = dedup_sorted(&mut distinct);
                let distinct = &distinct[..n_distinct];
                let key = labels.iter().fold(0u32, |acc, l| {
                    acc << 3 | distinct.iter().position(|d| d == l).unwrap_or(0) as u32
                });
                let template = templates.entry(key).or_insert_with(|| Template::of(key));
                let gid = |c: u64| {
                    point_id(
                        i + (c & 1) as i64,
                        j + ((c >> 1) & 1) as i64,
                        k + ((c >> 2) & 1) as i64,
                    )
                };
                let cell_key = point_id(i, j, k);
                ids.clear();
                for &(local, p) in &template.vertices {
                    let global = match local & 3 {
                        KIND_EDGE | KIND_FACE => {
                            let v = local >> 2;
                            (((gid(v / 3) * 3) + v % 3) << 2) | (local & 3)
                        }
                        _ => (cell_key << 12) | (local >> 2) << 2 | KIND_APEX,
                    };
                    let at = [p[0] + i as f64, p[1] + j as f64, p[2] + k as f64];
                    ids.push(verts.get(global, || at));
                }
                for t in &template.triangles {
                    out.triangles.push(t.corners.map(|x| ids[x as usize]));
                    out.outer_apex.push(ids[t.outer_apex as usize]);
                    out.sides.push(t.sides.map(|r| distinct[r as usize]));
                }
            }
        }
    }
    let mut keys = vec![0u64; verts.positions.len()];
    for (&key, &at) in &verts.index {
        keys[at as usize] = key;
    }
    SlabOutput {
        keys,
        positions: verts.positions,
        triangles: out.triangles,
        outer_apex: out.outer_apex,
        sides: out.sides,
    }
}

/// Moves the distinct values of a sorted array to its front; returns how many there are.
fn dedup_sorted(a: &mut [u16; 8]) -> usize {
    let mut n = 1;
    for x in 1..8 {
        if a[x] != a[n - 1] {
            a[n] = a[x];
            n += 1;
        }
    }
    n
}

/// A triangle of a cell template: indices into the template's vertices, and the labels on its
/// sides as ranks among the cell's distinct labels.
#[derive(Clone, Copy)]
struct TemplateTriangle {
    corners: [u16; 3],
    outer_apex: u16,
    sides: [u8; 2],
}

/// The triangulation of one cell configuration, derived once and reused for every cell with
/// the same corner ranks: vertices as local keys (edge, face or branching point) with their
/// positions in the unit cell.
struct Template {
    vertices: Vec<(u64, [f64; 3])>,
    triangles: Vec<TemplateTriangle>,
}

impl Template {
    /// Derives the template of the configuration `key` (3 bits of rank per corner, corner 0
    /// in the highest bits).
    fn of(key: u32) -> Template {
        let labels: [u16; 8] = std::array::from_fn(|c| ((key >> (3 * (7 - c))) & 7) as u16);
        let pos = |c: usize| [(c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64];
        let gid = |c: usize| c as u64;
        let mut segments = Vec::with_capacity(24);
        let mut points = Vec::with_capacity(48);
        for axis in 0..3 {
            for side in 0..2 {
                face_segments(axis, side, &labels, &pos, &gid, &mut segments, &mut points);
            }
        }
        let mut verts = Vertices {
            index: FxHashMap::default(),
            positions: Vec::new(),
        };
        let mut out = Interfaces::default();
        cell_triangles(&segments, &points, 0, &mut verts, &mut out);
        let mut keys = vec![0u64; verts.positions.len()];
        for (&key, &at) in &verts.index {
            keys[at as usize] = key;
        }
        Template {
            vertices: keys.into_iter().zip(verts.positions).collect(),
            triangles: out
                .triangles
                .iter()
                .zip(&out.outer_apex)
                .zip(&out.sides)
                .map(|((t, &o), s)| TemplateTriangle {
                    corners: t.map(|x| x as u16),
                    outer_apex: o as u16,
                    sides: s.map(|x| x as u8),
                })
                .collect(),
        }
    }
}

/// The segments of one cube face (normal `axis`, at `side` 0 or 1), decided from its four
/// corner labels alone.
fn face_segments(
    axis: usize,
    side: usize,
    labels: &[u16; 8],
    pos: &dyn Fn(usize) -> [f64; 3],
    gid: &dyn Fn(usize) -> u64,
    out: &mut Vec<Segment>,
    points: &mut Vec<(u64, [f64; 3])>,
) {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let c = |du: usize, dv: usize| (side << axis) | (du << u) | (dv << v);
    let ring = [c(0, 0), c(1, 0), c(1, 1), c(0, 1)];
    let l: [u16; 4] = ring.map(|x| labels[x]);
    let mid = |a: usize, b: usize| -> (u64, [f64; 3]) {
        let (ca, cb) = (ring[a % 4], ring[b % 4]);
        let (pa, pb) = (pos(ca), pos(cb));
        // The edge's key: its lower grid point and its axis (the corner bit that differs).
        let axis = (ca ^ cb).trailing_zeros() as u64;
        let key = ((gid(ca.min(cb)) * 3 + axis) << 2) | KIND_EDGE;
        (
            key,
            [
                0.5 * (pa[0] + pb[0]),
                0.5 * (pa[1] + pb[1]),
                0.5 * (pa[2] + pb[2]),
            ],
        )
    };
    let face_key = {
        let lo = ring.iter().map(|&x| gid(x)).min().unwrap_or(0);
        (lo * 3 + axis as u64) << 2 | KIND_FACE
    };
    let mut push = |a: (u64, [f64; 3]), b: (u64, [f64; 3]), x: u16, y: u16, w: usize| {
        out.push(Segment {
            ends: [a.0, b.0],
            labels: [x, y],
            witness: pos(ring[w % 4]),
        });
        points.push(a);
        points.push(b);
    };
    let mut distinct = l.to_vec();
    distinct.sort_unstable();
    distinct.dedup();
    match distinct.len() {
        1 => {}
        2 => {
            let count = |x: u16| l.iter().filter(|&&y| y == x).count();
            if let Some(o) = (0..4).find(|&o| count(l[o]) == 1) {
                // One corner differs: cut it off.
                push(mid(o + 3, o), mid(o, o + 1), l[o], l[(o + 2) % 4], o);
            } else if l[0] == l[2] {
                // Diagonal: the lower label connects, the other's corners are cut off.
                let cut = if l[0] > l[1] { 0 } else { 1 };
                for o in [cut, cut + 2] {
                    push(mid(o + 3, o), mid(o, o + 1), l[o], l[(o + 1) % 4], o);
                }
            } else {
                // Two adjacent pairs: one segment across.
                let o = if l[0] == l[1] { 1 } else { 0 };
                push(mid(o, o + 1), mid(o + 2, o + 3), l[o], l[(o + 1) % 4], o);
            }
        }
        3 => {
            let twice = distinct
                .iter()
                .copied()
                .find(|&x| l.iter().filter(|&&y| y == x).count() == 2)
                .unwrap_or(l[0]);
            let first = (0..4).find(|&o| l[o] == twice).unwrap_or(0);
            if l[(first + 2) % 4] == twice {
                // The pair is diagonal and wins the middle: the other two corners are cut off.
                for (o, &lo) in l.iter().enumerate() {
                    if lo != twice {
                        push(mid(o + 3, o), mid(o, o + 1), lo, twice, o);
                    }
                }
            } else {
                // The pair is adjacent: corners o, o+1 = pair, o+2, o+3 the others; their
                // bilinear indicators tie at (1/2, 2/3) from the pair's edge.
                let o = if l[(first + 1) % 4] == twice {
                    first
                } else {
                    (first + 3) % 4
                };
                let (p0, p1, p3) = (pos(ring[o]), pos(ring[(o + 1) % 4]), pos(ring[(o + 3) % 4]));
                let t: [f64; 3] = std::array::from_fn(|a| {
                    p0[a] + 0.5 * (p1[a] - p0[a]) + (2.0 / 3.0) * (p3[a] - p0[a])
                });
                let tp = (face_key, t);
                push(mid(o + 1, o + 2), tp, twice, l[(o + 2) % 4], o + 1);
                push(mid(o + 2, o + 3), tp, l[(o + 2) % 4], l[(o + 3) % 4], o + 2);
                push(mid(o + 3, o), tp, l[(o + 3) % 4], twice, o + 3);
            }
        }
        _ => {
            // Four labels tie in the middle of the face.
            let (p0, p2) = (pos(ring[0]), pos(ring[2]));
            let centre = (face_key, std::array::from_fn(|a| 0.5 * (p0[a] + p2[a])));
            for o in 0..4 {
                push(mid(o, o + 1), centre, l[o], l[(o + 1) % 4], o);
            }
        }
    }
}

/// Triangles of one cell from its face segments.
fn cell_triangles(
    segments: &[Segment],
    points: &[(u64, [f64; 3])],
    cell_key: u64,
    verts: &mut Vertices,
    out: &mut Interfaces,
) {
    let position = |key: u64| -> [f64; 3] {
        points
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, p)| *p)
            .unwrap_or([0.0; 3])
    };
    // Components of the segment graph (union-find over segment indices by shared ends).
    let n = segments.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(p: &mut [usize], x: usize) -> usize {
        let mut r = x;
        while p[r] != r {
            r = p[r];
        }
        let mut y = x;
        while p[y] != r {
            let next = p[y];
            p[y] = r;
            y = next;
        }
        r
    }
    for a in 0..n {
        for b in a + 1..n {
            if segments[a]
                .ends
                .iter()
                .any(|e| segments[b].ends.contains(e))
            {
                let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
                if ra != rb {
                    parent[ra.max(rb)] = ra.min(rb);
                }
            }
        }
    }
    let roots: Vec<usize> = (0..n).map(|s| find(&mut parent, s)).collect();
    let mut done = vec![false; n];
    let mut component = 0u64;
    for s in 0..n {
        if done[s] {
            continue;
        }
        let root = roots[s];
        let members: Vec<usize> = (0..n).filter(|&x| roots[x] == root).collect();
        for &m in &members {
            done[m] = true;
        }
        let mut ends: Vec<u64> = members.iter().flat_map(|&m| segments[m].ends).collect();
        ends.sort_unstable();
        let simple_loop = ends.chunks(2).all(|c| c.len() == 2 && c[0] == c[1])
            && ends.windows(3).all(|w| !(w[0] == w[1] && w[1] == w[2]));
        let n_vertices = ends.len() / 2;
        if simple_loop && n_vertices <= 4 {
            // Order the loop, then fill it as a triangle or a quad.
            let mut order = vec![segments[members[0]].ends[0], segments[members[0]].ends[1]];
            let mut used = vec![false; members.len()];
            used[0] = true;
            while order.len() < n_vertices {
                let last = *order.last().unwrap_or(&0);
                let next = members
                    .iter()
                    .enumerate()
                    .find(|(x, &m)| !used[*x] && segments[m].ends.contains(&last));
                let Some((x, &m)) = next else { break };
                used[x] = true;
                let e = segments[m].ends;
                order.push(if e[0] == last { e[1] } else { e[0] });
            }
            let seg = &segments[members[0]];
            let ids: Vec<u32> = order
                .iter()
                .map(|&key| verts.get(key, || position(key)))
                .collect();
            let tris: Vec<[usize; 3]> = if n_vertices == 3 {
                vec![[0, 1, 2]]
            } else {
                vec![[0, 1, 2], [0, 2, 3]]
            };
            // Orient so that the normal of (v0, v1, v2) points away from the first label.
            let (a, b, c) = (position(order[0]), position(order[1]), position(order[2]));
            let flip = outward_dot(a, b, c, seg.witness) > 0.0;
            // The first segment joins order[0]-order[1]; its labels are constant along a loop.
            for t in tris {
                let tri = [ids[t[0]], ids[t[1]], ids[t[2]]];
                let tri = if flip { [tri[0], tri[2], tri[1]] } else { tri };
                out.triangles.push(tri);
                out.outer_apex.push(tri[2]);
                out.sides.push(seg.labels);
            }
            continue;
        }
        // A fan from the centroid of the component's vertices.
        let mut unique = ends.clone();
        unique.dedup();
        let centre: [f64; 3] = {
            let mut c = [0.0; 3];
            for &key in &unique {
                let p = position(key);
                for a in 0..3 {
                    c[a] += p[a] / unique.len() as f64;
                }
            }
            c
        };
        // The parts of each label around the branching point: its segments joined by shared
        // ends. A label with several parts gets a copy of the point per part.
        let base = verts.get(apex_key(cell_key, component, 0), || centre);
        let mut part_of: Vec<[u32; 2]> = vec![[base; 2]; members.len()];
        let mut copies = 1u64;
        let mut labels_here: Vec<u16> = members.iter().flat_map(|&m| segments[m].labels).collect();
        labels_here.sort_unstable();
        labels_here.dedup();
        for &label in &labels_here {
            let mine: Vec<usize> = (0..members.len())
                .filter(|&x| segments[members[x]].labels.contains(&label))
                .collect();
            let mut group: Vec<usize> = (0..mine.len()).collect();
            for a in 0..mine.len() {
                for b in a + 1..mine.len() {
                    let (sa, sb) = (&segments[members[mine[a]]], &segments[members[mine[b]]]);
                    if sa.ends.iter().any(|e| sb.ends.contains(e)) {
                        let (ga, gb) = (group[a], group[b]);
                        for g in group.iter_mut() {
                            if *g == gb {
                                *g = ga;
                            }
                        }
                    }
                }
            }
            let mut firsts: Vec<usize> = group.clone();
            firsts.sort_unstable();
            firsts.dedup();
            for (x, &g) in mine.iter().zip(&group) {
                let part = firsts.iter().position(|&f| f == g).unwrap_or(0);
                if part == 0 {
                    continue;
                }
                let id = verts.get(apex_key(cell_key, component, copies + part as u64), || {
                    centre
                });
                let side = if segments[members[*x]].labels[0] == label {
                    0
                } else {
                    1
                };
                part_of[*x][side] = id;
            }
            copies += firsts.len() as u64;
        }
        for (x, &m) in members.iter().enumerate() {
            let seg = &segments[m];
            let (pa, pb) = (position(seg.ends[0]), position(seg.ends[1]));
            let (a, b) = (verts.get(seg.ends[0], || pa), verts.get(seg.ends[1], || pb));
            let flip = outward_dot(pa, pb, centre, seg.witness) > 0.0;
            out.triangles.push(if flip {
                [b, a, part_of[x][0]]
            } else {
                [a, b, part_of[x][0]]
            });
            out.outer_apex.push(part_of[x][1]);
            out.sides.push(seg.labels);
        }
        component += 1;
    }
}

/// Key of a cell's branching point: the cell, the component, and the copy (10 bits).
fn apex_key(cell_key: u64, component: u64, copy: u64) -> u64 {
    ((cell_key << 12) | (component.min(15) * 64 + copy.min(63)) << 2) | KIND_APEX
}

/// (b - a) x (c - a) . (w - a): positive when `w` lies on the side the normal points to.
fn outward_dot(a: [f64; 3], b: [f64; 3], c: [f64; 3], w: [f64; 3]) -> f64 {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    n[0] * (w[0] - a[0]) + n[1] * (w[1] - a[1]) + n[2] * (w[2] - a[2])
}

/// One closed surface per label (normals outward, vertices in world mm through the volume's
/// grid), made of the shared interface triangles; labels are assembled in parallel.
pub fn label_surfaces(volume: &LabelVolume, all: &Interfaces) -> Vec<LabelSurface> {
    use rayon::prelude::*;
    let n_labels = volume.labels.len();
    // Each triangle goes to the labels on its two sides (background has no surface).
    let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); n_labels + 1];
    for (t, sides) in all.sides.iter().enumerate() {
        for &l in sides {
            buckets[l as usize].push(t as u32);
        }
    }
    (1..=n_labels as u16)
        .into_par_iter()
        .map(|label| {
            let mut local = vec![u32::MAX; all.positions.len()];
            let mut positions = Vec::new();
            let mut triangles = Vec::with_capacity(buckets[label as usize].len());
            for &t in &buckets[label as usize] {
                let (tri, sides) = (all.triangles[t as usize], all.sides[t as usize]);
                let tri = if sides[0] == label {
                    tri
                } else {
                    [tri[0], all.outer_apex[t as usize], tri[1]]
                };
                triangles.push(tri.map(|v| {
                    if local[v as usize] == u32::MAX {
                        local[v as usize] = positions.len() as u32;
                        positions.push(
                            volume
                                .grid
                                .world(all.positions[v as usize])
                                .map(|x| x as f32),
                        );
                    }
                    local[v as usize]
                }));
            }
            let mesh = Mesh::new(positions, triangles).unwrap_or_default();
            LabelSurface { label, mesh }
        })
        .collect()
}
