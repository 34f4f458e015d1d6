//! The last step of remeshing: where the remeshed surface passes further from the input than
//! a sixth of the target (a dimple or a bump narrower than two edges that no vertex happened
//! to land in), a remeshed vertex is put onto the input vertex that stands off. Remeshed
//! vertices all lie on the input, so the Hausdorff distance between the two surfaces is the
//! input's distance from the remeshed one, and this bounds it.

use super::halfedge::{next, NONE};
use super::{dist, dot, min_angle, tri_normal, unit, Kind, Remesher};
use crate::mesh::{Mesh, Topology};
use crate::spatial::TriangleGrid;
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
            let Some((snapshot, face_of)) = self.snapshot() else {
                break;
            };
            let grid = TriangleGrid::build(&snapshot);
            let mut far: Vec<(f64, u32, u32)> = (0..p.len() as u32)
                .into_par_iter()
                .filter_map(|x| {
                    patch_of[x as usize]?;
                    let near = grid.nearest(p[x as usize])?;
                    let excess = near.distance - STAND_OFF * size[x as usize];
                    (excess > 0.0).then(|| (excess, x, face_of[near.triangle as usize]))
                })
                .collect();
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
        unit(tri_normal(old[0], old[1], old[2])),
        unit(tri_normal(new[0], new[1], new[2])),
    ) {
        (Some(a), Some(b)) => {
            dot(a, b) >= 0.5 && min_angle(new) >= PLACE_FLOOR_DEG.to_radians().min(min_angle(old))
        }
        _ => false,
    }
}
