//! The last step of remeshing: where the remeshed surface passes further from the input than
//! a sixth of the target (a dimple or a bump narrower than two edges that no vertex happened
//! to land in), a remeshed vertex is put onto the input vertex that stands off. Remeshed
//! vertices all lie on the input, so the Hausdorff distance between the two surfaces is the
//! input's distance from the remeshed one, and this bounds it.

use super::halfedge::{next, NONE};
use super::{dist, dot, min_angle, tri_normal, Kind, Remesher};
use crate::mesh::geometry::unit64;
use crate::mesh::{Mesh, Topology};
use crate::spatial::{closest_point_and_region, TriangleBvh, TriangleRegion};
use rayon::prelude::*;

/// Input vertices further than this share of their target from the remeshed surface get a
/// vertex of their own.
const STAND_OFF: f64 = 1.0 / 6.0;
/// Smallest angle (degrees) a placed vertex may leave in its faces, unless they had less.
const PLACE_FLOOR_DEG: f64 = 25.0;

impl Remesher {
    /// Puts remeshed vertices onto the input vertices (inside a patch) that stand off the
    /// remeshed surface, moving the nearest corner of the nearest face, or a vertex split
    /// into that face's longest edge, when its faces keep their orientation and shape.
    /// Returns how many were placed.
    pub(super) fn cover_input(
        &mut self,
        input: &Mesh,
        topology: &Topology,
        face_ids: &[u32],
        size: &[f64],
    ) -> usize {
        let p = input.positions();
        let patch_of: Vec<Option<u32>> = (0..input.n_vertices())
            .into_par_iter()
            .map(|v| {
                let faces = topology.vertex_faces(v);
                let id = face_ids[*faces.first()? as usize];
                faces
                    .iter()
                    .all(|&f| face_ids[f as usize] == id)
                    .then_some(id)
            })
            .collect();
        let mut pinned = vec![false; self.he.pos.len()];
        let mut placed = 0;
        for _round in 0..3 {
            let mut far = self.standing_off(p, &patch_of, size);
            far.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            let mut changed = 0;
            for (_, x, f) in far {
                if !self.he.face_alive[f as usize] {
                    continue;
                }
                let (Some(id), target) = (patch_of[x as usize], p[x as usize].map(f64::from))
                else {
                    continue;
                };
                let face = self.reference.start_face[x as usize];
                let mut corners = self.he.tri[f as usize];
                corners.sort_by(|&a, &b| {
                    dist(self.he.pos[a as usize], target)
                        .total_cmp(&dist(self.he.pos[b as usize], target))
                });
                let mut done = corners
                    .into_iter()
                    .find(|&v| !pinned[v as usize] && self.try_place(v, id, target, face));
                if done.is_none() {
                    let longest = (0..3)
                        .map(|i| 3 * f + i)
                        .filter(|&h| !self.he.is_feature(h))
                        .max_by(|&a, &b| self.len(a).total_cmp(&self.len(b)));
                    if let Some(h) = longest.filter(|&h| self.split_fits(h, target)) {
                        if let Some(m) = self.split_edge(h) {
                            self.he.pos[m as usize] = target;
                            self.hint[m as usize] = face;
                            pinned.resize(self.he.pos.len(), false);
                            done = Some(m);
                        }
                    }
                }
                if let Some(v) = done {
                    pinned[v as usize] = true;
                    changed += 1;
                }
            }
            placed += changed;
            if changed == 0 {
                break;
            }
        }
        placed
    }

    /// Input vertices (inside a patch) further than `STAND_OFF` of their target from the
    /// remeshed surface: (excess mm, input vertex, remeshed face nearest it). The distance is
    /// found by walking the remeshed surface from a remeshed vertex projected near the input
    /// vertex (a walk ends at a local nearest face, so it may only overstate the distance);
    /// input vertices with no remeshed vertex within two rings ask a tree over the result.
    fn standing_off(
        &self,
        p: &[[f32; 3]],
        patch_of: &[Option<u32>],
        size: &[f64],
    ) -> Vec<(f64, u32, u32)> {
        // A remeshed vertex on each input face that has one (per patch, local face index).
        let ids = self.reference.patch_ids();
        let index_of = |id: u32| ids.binary_search(&id).ok();
        let mut owner: Vec<Vec<u32>> = (0..ids.len())
            .map(|k| vec![NONE; self.reference.patch_faces(k)])
            .collect();
        for v in 0..self.he.pos.len() {
            if let (Kind::Interior(id), face, true) =
                (self.kind[v], self.hint[v], self.he.vert_alive[v])
            {
                let slot = index_of(id).and_then(|k| owner[k].get_mut(face as usize));
                if let Some(slot) = slot {
                    *slot = v as u32;
                }
            }
        }
        let excess_of = |x: u32, d: f64| {
            let e = d - STAND_OFF * size[x as usize];
            (e > 0.0).then_some(e)
        };
        // Walked where a start is near; `None` marks the input vertices left to the tree.
        let walked: Vec<Option<(f64, u32, u32)>> = (0..p.len() as u32)
            .into_par_iter()
            .map_init(Vec::new, |ring, x| {
                let id = patch_of[x as usize]?;
                let Some(k) = index_of(id) else {
                    return Some((0.0, x, NONE));
                };
                let near = |f: u32| owner[k][f as usize];
                let around = self.reference.faces_around_input(k, x);
                let start = around
                    .iter()
                    .map(|&f| near(f))
                    .chain(
                        around
                            .iter()
                            .flat_map(|&f| self.reference.faces_touching(k, f))
                            .map(near),
                    )
                    .find(|&v| v != NONE);
                let v = start?; // none near: left to the tree
                let q = p[x as usize].map(f64::from);
                let (d, face) = self.walk_output(v, q, ring);
                Some(match excess_of(x, d) {
                    Some(e) => (e, x, face),
                    None => (0.0, x, NONE),
                })
            })
            .collect();
        let mut far: Vec<(f64, u32, u32)> = walked
            .iter()
            .flatten()
            .filter(|w| w.2 != NONE)
            .copied()
            .collect();
        let left: Vec<u32> = (0..p.len() as u32)
            .filter(|&x| patch_of[x as usize].is_some() && walked[x as usize].is_none())
            .collect();
        if !left.is_empty() {
            if let Some((snapshot, face_of)) = self.snapshot() {
                let tree = TriangleBvh::build(&snapshot);
                far.par_extend(left.into_par_iter().filter_map(|x| {
                    let near = tree.nearest(p[x as usize])?;
                    let e = excess_of(x, near.distance)?;
                    Some((e, x, face_of[near.triangle as usize]))
                }));
            }
        }
        far
    }

    /// Distance (mm) from q to the remeshed surface near vertex v and the face it is on:
    /// from the nearest face around v, steps across the edge or round the corner where the
    /// closest point lies while that comes nearer.
    fn walk_output(&self, v: u32, q: [f64; 3], ring: &mut Vec<u32>) -> (f64, u32) {
        let closest = |f: u32| {
            let t = self.he.tri[f as usize].map(|c| self.he.pos[c as usize]);
            let (y, region) = closest_point_and_region(q, t[0], t[1], t[2]);
            (dist(y, q), region)
        };
        self.he.outgoing(v, ring);
        let mut best = (f64::INFINITY, NONE, TriangleRegion::Inside);
        for &e in ring.iter() {
            let (d, r) = closest(e / 3);
            if d < best.0 {
                best = (d, e / 3, r);
            }
        }
        for _ in 0..64 {
            let (_, f, region) = best;
            if f == NONE {
                break;
            }
            match region {
                TriangleRegion::Inside => break,
                TriangleRegion::Edge(i) => {
                    let t = self.he.twin(3 * f + u32::from(i));
                    ring.clear();
                    if t != NONE {
                        ring.push(t);
                    }
                }
                TriangleRegion::Corner(i) => {
                    self.he.outgoing(self.he.tri[f as usize][i as usize], ring);
                }
            }
            let before = best.1;
            for &e in ring.iter() {
                let (d, r) = closest(e / 3);
                if d < best.0 {
                    best = (d, e / 3, r);
                }
            }
            if best.1 == before {
                break;
            }
        }
        (best.0, best.1)
    }

    /// Moves vertex v (inside patch `id`) onto input point x on input face `face` if the
    /// faces around it keep their shape (`keeps_shape`).
    fn try_place(&mut self, v: u32, id: u32, x: [f64; 3], face: u32) -> bool {
        if self.kind[v as usize] != Kind::Interior(id) {
            return false;
        }
        let mut ring = std::mem::take(&mut self.buf);
        self.he.outgoing(v, &mut ring);
        let ok = ring.iter().all(|&e| {
            let corners = self.he.tri[(e / 3) as usize];
            let old = corners.map(|u| self.he.pos[u as usize]);
            keeps_shape(
                old,
                corners.map(|u| if u == v { x } else { self.he.pos[u as usize] }),
            )
        });
        self.buf = ring;
        if ok {
            self.he.pos[v as usize] = x;
            self.hint[v as usize] = face;
        }
        ok
    }

    /// Whether splitting the (inner) edge of h at x keeps the shape of the faces either side.
    fn split_fits(&self, h: u32, x: [f64; 3]) -> bool {
        let t = self.he.twin(h);
        if t == NONE {
            return false;
        }
        let p = |v: u32| self.he.pos[v as usize];
        let (a, b) = (self.he.from(h), self.he.to(h));
        let (c, d) = (self.he.to(next(h)), self.he.to(next(t)));
        let (old_h, old_t) = ([p(a), p(b), p(c)], [p(b), p(a), p(d)]);
        keeps_shape(old_h, [p(a), x, p(c)])
            && keeps_shape(old_h, [x, p(b), p(c)])
            && keeps_shape(old_t, [p(b), x, p(d)])
            && keeps_shape(old_t, [x, p(a), p(d)])
    }

    /// The alive faces as a mesh, and the half-edge face of each of its faces.
    fn snapshot(&self) -> Option<(Mesh, Vec<u32>)> {
        let positions = self.he.pos.iter().map(|q| q.map(|c| c as f32)).collect();
        let faces: Vec<u32> = (0..self.he.tri.len() as u32)
            .filter(|&f| self.he.face_alive[f as usize])
            .collect();
        let triangles = faces.iter().map(|&f| self.he.tri[f as usize]).collect();
        let mesh = Mesh::new(positions, triangles).ok()?;
        Some((mesh, faces))
    }
}

/// Whether a face going from `old` to `new` keeps facing the same way (within 60 degrees) and
/// has no angle under the floor, or under the smallest it had.
fn keeps_shape(old: [[f64; 3]; 3], new: [[f64; 3]; 3]) -> bool {
    match (
        unit64(tri_normal(old[0], old[1], old[2])),
        unit64(tri_normal(new[0], new[1], new[2])),
    ) {
        (Some(a), Some(b)) => {
            dot(a, b) >= 0.5 && min_angle(new) >= PLACE_FLOOR_DEG.to_radians().min(min_angle(old))
        }
        _ => false,
    }
}
