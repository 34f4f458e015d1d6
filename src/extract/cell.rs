//! The derived case table of multi-label extraction: one cube cell's triangulation from its
//! eight corner labels. Faces are decided from their own four corners by the largest-indicator
//! rule; inside the cell each connected set of face segments bounds a membrane, filled as a
//! polygon or as a fan from a branching point. A [`Template`] holds the result for one
//! configuration (the corners' ranks) and is reused for every cell that has it.

use super::Interfaces;
use rustc_hash::FxHashMap;

/// A segment on a cube face: endpoints (vertex keys), the labels on its two sides, and a
/// witness point (a corner) inside the first label's part of the face.
#[derive(Clone, Copy)]
pub(super) struct Segment {
    ends: [u64; 2],
    labels: [u16; 2],
    witness: [f64; 3],
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
    /// Derives the template of the configuration `key` (3 bits of rank per corner, corner 0
    /// in the highest bits).
    pub(super) fn of(key: u32) -> Template {
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
