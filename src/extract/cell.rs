//! The derived case table of multi-label extraction: one cube cell's triangulation from its
//! eight corner labels. Faces are decided from their own four corners by the largest-indicator
//! rule; inside the cell each connected set of face segments bounds a membrane, filled as a
//! polygon or as a fan from a branching point. A [`Template`] holds the result for one
//! configuration (the corners' ranks) and is reused for every cell that has it.

use super::Interfaces;
use rustc_hash::FxHashMap;

/// A segment on a cube face: endpoints (vertex keys), the labels on its two sides, a witness
/// point (a corner) inside the first label's part of the face, and a corner of each side's
/// part.
#[derive(Clone, Copy)]
pub(super) struct Segment {
    ends: [u64; 2],
    labels: [u16; 2],
    witness: [f64; 3],
    corners: [usize; 2],
}

/// Where the per-cell work collects vertices: key -> index, with positions.
pub(super) struct Vertices {
    pub(super) index: FxHashMap<u64, u32>,
    pub(super) positions: Vec<[f64; 3]>,
}

impl Vertices {
    pub(super) fn get(&mut self, key: u64, position: impl FnOnce() -> [f64; 3]) -> u32 {
        let next = self.positions.len() as u32;
        *self.index.entry(key).or_insert_with(|| {
            self.positions.push(position());
            next
        })
    }
}

pub(super) const KIND_EDGE: u64 = 0;
pub(super) const KIND_FACE: u64 = 1;
pub(super) const KIND_APEX: u64 = 2;

/// A triangle of a cell template: indices into the template's vertices, and the labels on its
/// sides as ranks among the cell's distinct labels.
#[derive(Clone, Copy)]
pub(super) struct TemplateTriangle {
    pub(super) corners: [u16; 3],
    pub(super) outer_apex: u16,
    pub(super) sides: [u8; 2],
}

/// The triangulation of one cell configuration, derived once and reused for every cell with
/// the same corner ranks: vertices as local keys (edge, face or branching point) with their
/// positions in the unit cell.
pub(super) struct Template {
    pub(super) vertices: Vec<(u64, [f64; 3])>,
    pub(super) triangles: Vec<TemplateTriangle>,
}

impl Template {
    /// Derives the template of the configuration `key`: 3 bits of rank per corner in the low
    /// 24 bits (corner 0 in the highest of them), and above them one bit per rank for the
    /// labels whose voxels join across edges and corners (26-connectivity).
    pub(super) fn of(key: u32) -> Template {
        let labels: [u16; 8] = std::array::from_fn(|c| ((key >> (3 * (7 - c))) & 7) as u16);
        let joins = (key >> 24) as u8;
        let pos = |c: usize| [(c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64];
        let gid = |c: usize| c as u64;
        let mut segments = Vec::with_capacity(24);
        let mut points = Vec::with_capacity(48);
        // Where each face's segments start (faces in the order axis, side).
        let mut face_starts = [0usize; 7];
        for axis in 0..3 {
            for side in 0..2 {
                let corners = FaceCorners {
                    labels: &labels,
                    joins,
                    pos: &pos,
                    gid: &gid,
                };
                face_segments(axis, side, &corners, &mut segments, &mut points);
                face_starts[2 * axis + side + 1] = segments.len();
            }
        }
        let mut verts = Vertices {
            index: FxHashMap::default(),
            positions: Vec::new(),
        };
        let mut out = Interfaces::default();
        if let Some(c) = tunnel_corner(&labels, joins) {
            tunnel(c, &labels, &mut verts, &mut out);
        } else if let Some(x) = core_label(&labels, joins) {
            let faces = Faces {
                segments: &segments,
                starts: &face_starts,
                points: &points,
            };
            core(x, &labels, joins, &faces, &mut verts, &mut out);
        } else {
            cell_triangles(&segments, &points, 0, &mut verts, &mut out);
        }
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

/// A cell's corners as its faces see them: ranks, which ranks join diagonally, positions and
/// grid ids.
struct FaceCorners<'a> {
    labels: &'a [u16; 8],
    joins: u8,
    pos: &'a dyn Fn(usize) -> [f64; 3],
    gid: &'a dyn Fn(usize) -> u64,
}

/// Of two labels on a face's diagonals, the one whose corners connect across the face: the
/// one that joins diagonally (26-connectivity) when only one does, else the lower (the
/// background before any structure).
fn connecting(x: u16, y: u16, joins: u8) -> u16 {
    let join = |r: u16| (joins >> r) & 1 == 1;
    match (join(x), join(y)) {
        (true, false) => x,
        (false, true) => y,
        _ => x.min(y),
    }
}

/// The segments of one cube face (normal `axis`, at `side` 0 or 1), decided from its four
/// corner labels alone.
fn face_segments(
    axis: usize,
    side: usize,
    corners: &FaceCorners,
    out: &mut Vec<Segment>,
    points: &mut Vec<(u64, [f64; 3])>,
) {
    let FaceCorners {
        labels,
        joins,
        pos,
        gid,
    } = *corners;
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
            corners: [ring[w % 4], ring[(w + 1) % 4]],
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
                // Diagonal: one label connects, the other's corners are cut off.
                let cut = if connecting(l[0], l[1], joins) == l[0] {
                    1
                } else {
                    0
                };
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

/// The corner of a two-label cell whose label holds only it and the opposite corner and joins
/// diagonally: those two voxels touch only at the cell's centre, so a tube joins them.
fn tunnel_corner(labels: &[u16; 8], joins: u8) -> Option<usize> {
    (0..4).find(|&c| {
        let (own, other) = (labels[c], labels[c ^ 1]);
        let alone = (0..8).all(|d| (labels[d] == own) == (d == c || d == c ^ 7));
        let two_labels = labels.iter().all(|&l| l == own || l == other);
        alone && two_labels && (joins >> own) & 1 == 1
    })
}

/// The tube between corner `c` and the opposite corner of a cell (their label `labels[c]`,
/// the other six corners one other label): the antiprism between the two triangles that cut
/// the corners off, six triangles whose outer edges are the faces' segments.
fn tunnel(c: usize, labels: &[u16; 8], verts: &mut Vertices, out: &mut Interfaces) {
    let pos = |c: usize| [(c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64];
    // The vertex on the edge from corner `a` along `axis`.
    let mut on_edge = |a: usize, axis: usize| {
        let b = a ^ (1 << axis);
        let key = (((a.min(b) as u64) * 3 + axis as u64) << 2) | KIND_EDGE;
        let (pa, pb) = (pos(a), pos(b));
        verts.get(key, || std::array::from_fn(|x| 0.5 * (pa[x] + pb[x])))
    };
    let far = c ^ 7;
    // Around the cell's diagonal: from c along x, from far along z, from c along y, from far
    // along x, from c along z, from far along y (each next to the one before on a face).
    let ring = [
        on_edge(c, 0),
        on_edge(far, 2),
        on_edge(c, 1),
        on_edge(far, 0),
        on_edge(c, 2),
        on_edge(far, 1),
    ];
    let centre = [0.5; 3];
    let sides = [labels[c], labels[c ^ 1]];
    for i in 0..6 {
        // The normal points away from the tube's own label, which holds the centre.
        let tri = [ring[i], ring[(i + 1) % 6], ring[(i + 2) % 6]];
        push_facing_away(out, verts, tri, sides, centre);
    }
}

/// Adds triangle `tri` separating `sides` (inner, outer), turned so that its normal points
/// away from point `inner_point`, which lies on the inner label's side.
fn push_facing_away(
    out: &mut Interfaces,
    verts: &Vertices,
    tri: [u32; 3],
    sides: [u16; 2],
    inner_point: [f64; 3],
) {
    let [a, b, c] = tri.map(|v| verts.positions[v as usize]);
    let tri = if outward_dot(a, b, c, inner_point) > 0.0 {
        [tri[0], tri[2], tri[1]]
    } else {
        tri
    };
    out.triangles.push(tri);
    out.outer_apex.push(tri[2]);
    out.sides.push(sides);
}

/// The corners of face (`axis`, `side`) in ring order.
fn face_ring(axis: usize, side: usize) -> [usize; 4] {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let c = |du: usize, dv: usize| (side << axis) | (du << u) | (dv << v);
    [c(0, 0), c(1, 0), c(1, 1), c(0, 1)]
}

/// Which corners of a face's ring lie in one part of the face (a part per label piece, as
/// [`face_segments`] cuts it): ring neighbours of one label always, diagonal corners of one
/// label when that label wins the face's middle.
fn face_parts(l: &[u16; 4], joins: u8) -> [usize; 4] {
    let mut part = [0, 1, 2, 3];
    let mut distinct = l.to_vec();
    distinct.sort_unstable();
    distinct.dedup();
    for o in 0..4 {
        let diagonal_joined = l[o] == l[(o + 2) % 4]
            && l[(o + 1) % 4] != l[o]
            && (distinct.len() == 3
                || (distinct.len() == 2 && connecting(l[o], l[(o + 1) % 4], joins) == l[o]));
        for (other, joined) in [
            ((o + 1) % 4, l[o] == l[(o + 1) % 4]),
            ((o + 2) % 4, diagonal_joined),
        ] {
            if joined {
                let (a, b) = (part[o].min(part[other]), part[o].max(part[other]));
                for p in part.iter_mut() {
                    if *p == b {
                        *p = a;
                    }
                }
            }
        }
    }
    part
}

/// The lowest label joining diagonally (26-connectivity) whose corners in the cell fall into
/// more than one piece on the cell's faces: its voxels touch through the cell, so it gets a
/// core there.
fn core_label(labels: &[u16; 8], joins: u8) -> Option<u16> {
    let mut group: [usize; 8] = std::array::from_fn(|c| c);
    let mut join = |a: usize, b: usize| {
        let (ga, gb) = (group[a].min(group[b]), group[a].max(group[b]));
        for g in group.iter_mut() {
            if *g == gb {
                *g = ga;
            }
        }
    };
    for axis in 0..3 {
        for side in 0..2 {
            let ring = face_ring(axis, side);
            let parts = face_parts(&ring.map(|c| labels[c]), joins);
            for a in 0..4 {
                for b in a + 1..4 {
                    if parts[a] == parts[b] {
                        join(ring[a], ring[b]);
                    }
                }
            }
        }
    }
    let mut ranks: Vec<u16> = labels.to_vec();
    ranks.sort_unstable();
    ranks.dedup();
    ranks.into_iter().find(|&r| {
        let mut groups: Vec<usize> = (0..8)
            .filter(|&c| labels[c] == r)
            .map(|c| group[c])
            .collect();
        groups.sort_unstable();
        groups.dedup();
        (joins >> r) & 1 == 1 && groups.len() > 1
    })
}

/// A cell's face segments, per face.
struct Faces<'a> {
    segments: &'a [Segment],
    /// Face f's segments are `segments[starts[f]..starts[f + 1]]` (faces by axis, then side).
    starts: &'a [usize; 7],
    points: &'a [(u64, [f64; 3])],
}

/// A cell where label `x` touches itself only through the cell's inside: every face piece is
/// joined to a core (the cell's surface shrunk to half around its centre) by ribbons that run
/// from the faces' segments to the core, and the core belongs to `x`, so all of `x`'s pieces
/// meet in it; the other labels' pieces end on the core, each in a patch that separates it
/// from `x`.
fn core(
    x: u16,
    labels: &[u16; 8],
    joins: u8,
    faces: &Faces,
    verts: &mut Vertices,
    out: &mut Interfaces,
) {
    let pos = |c: usize| [(c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64];
    let centre = [0.5; 3];
    let position = |key: u64| -> [f64; 3] {
        (faces.points.iter())
            .find(|(k, _)| *k == key)
            .map_or([0.0; 3], |(_, p)| *p)
    };
    let shrink = |p: [f64; 3]| -> [f64; 3] { std::array::from_fn(|a| 0.5 * (p[a] + centre[a])) };
    // The core's vertices: the shrunk copy of each corner (by corner) and face vertex (by key).
    let mut sources: Vec<u64> = Vec::new();
    let mut core_vertex = |verts: &mut Vertices, source: u64, at: [f64; 3]| -> u32 {
        let index = match sources.iter().position(|&s| s == source) {
            Some(i) => i,
            None => {
                sources.push(source);
                sources.len() - 1
            }
        };
        verts.get(apex_key(0, 15, index as u64), || shrink(at))
    };
    let corner_source = |c: usize| u64::MAX - c as u64;
    // Ribbons: each segment to its shrunk copy, oriented away from its first label.
    for seg in faces.segments {
        let [pa, pb] = seg.ends.map(position);
        let (a, b) = (verts.get(seg.ends[0], || pa), verts.get(seg.ends[1], || pb));
        let (a2, b2) = (
            core_vertex(verts, seg.ends[0], pa),
            core_vertex(verts, seg.ends[1], pb),
        );
        push_facing_away(out, verts, [a, b, b2], seg.labels, seg.witness);
        push_facing_away(out, verts, [a, b2, a2], seg.labels, seg.witness);
    }
    // Patches: every face part of a label other than `x`, shrunk, fanned from one of its
    // corners, oriented away from the centre (which `x` holds).
    for axis in 0..3 {
        for side in 0..2 {
            let f = 2 * axis + side;
            let ring = face_ring(axis, side);
            let l = ring.map(|c| labels[c]);
            let parts = face_parts(&l, joins);
            let segments = &faces.segments[faces.starts[f]..faces.starts[f + 1]];
            let mid = |o: usize| -> u64 {
                let (ca, cb) = (ring[o % 4], ring[(o + 1) % 4]);
                let axis = (ca ^ cb).trailing_zeros() as u64;
                (((ca.min(cb) as u64) * 3 + axis) << 2) | KIND_EDGE
            };
            for part in 0..4 {
                let members: Vec<usize> = (0..4).filter(|&o| parts[o] == part).collect();
                let Some(&first) = members.first() else {
                    continue;
                };
                if l[first] == x {
                    continue;
                }
                let inside = |o: usize| parts[o % 4] == part;
                // The part's boundary: face edges (whole or to their midpoint), and segments.
                let mut edges: Vec<(u64, [f64; 3], u64, [f64; 3])> = Vec::new();
                let corner = |o: usize| (corner_source(ring[o % 4]), pos(ring[o % 4]));
                let midpoint = |o: usize| (mid(o), position(mid(o)));
                for o in 0..4 {
                    let (a, b) = match (inside(o), inside(o + 1)) {
                        (true, true) => (corner(o), corner(o + 1)),
                        (true, false) => (corner(o), midpoint(o)),
                        (false, true) => (midpoint(o), corner(o + 1)),
                        (false, false) => continue,
                    };
                    edges.push((a.0, a.1, b.0, b.1));
                }
                for seg in segments {
                    if seg
                        .corners
                        .iter()
                        .any(|&c| ring.iter().position(|&r| r == c).is_some_and(inside))
                    {
                        let [pa, pb] = seg.ends.map(position);
                        edges.push((seg.ends[0], pa, seg.ends[1], pb));
                    }
                }
                let (apex_source, apex_at) = corner(first);
                let apex = core_vertex(verts, apex_source, apex_at);
                for (ka, pa, kb, pb) in edges {
                    if ka == apex_source || kb == apex_source {
                        continue;
                    }
                    let (a, b) = (core_vertex(verts, ka, pa), core_vertex(verts, kb, pb));
                    push_facing_away(out, verts, [apex, a, b], [x, l[first]], centre);
                }
            }
        }
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
