//! Tangential relaxation: each vertex inside a patch moves towards half its neighbours'
//! weighted centroid and half a spring step that evens out its edges, within its tangent
//! plane, then back onto the input; rim vertices move to the middle of their rim neighbours
//! along the rim. Moves that would turn a face over are undone.

use super::{dot, sub, tri_normal, Kind, Placement, Remesher, NONE};
use crate::mesh::geometry::unit64;
use rayon::prelude::*;

impl Remesher {
    /// Relaxes every vertex, or those `only` marks.
    pub(super) fn relax_and_project(&mut self, only: Option<&[bool]>) {
        let n = self.he.pos.len();
        let moved: Vec<Option<Placement>> = (0..n as u32)
            .into_par_iter()
            .map_init(Vec::new, |ring, v| {
                let chosen = only.is_none_or(|m| m.get(v as usize) == Some(&true));
                if !self.he.vert_alive[v as usize] || !chosen {
                    return None;
                }
                let x = self.he.pos[v as usize];
                match self.kind[v as usize] {
                    Kind::Corner => None,
                    Kind::Rim(l) => {
                        // Midway along the line between the two rim neighbours.
                        self.edges_at(v, ring);
                        let mut ends = ring
                            .iter()
                            .filter(|&&e| self.he.is_feature(e))
                            .map(|&e| self.other(e, v));
                        let ends = match (ends.next(), ends.next(), ends.next()) {
                            (Some(u), Some(w), None) => [u, w],
                            _ => return None,
                        };
                        let s = self.arc_between(ends[0], ends[1], l);
                        let (p, size) = self.reference.lines[l as usize].eval(s);
                        Some((p, size, s, NONE))
                    }
                    Kind::Interior(_) => {
                        self.he.outgoing(v, ring);
                        let mut centre = [0.0; 3];
                        let mut weight = 0.0;
                        let mut normal = [0.0; 3];
                        for &e in ring.iter() {
                            let u = self.he.to(e);
                            let w = self.target(v, u);
                            let pu = self.he.pos[u as usize];
                            for k in 0..3 {
                                centre[k] += w * pu[k];
                            }
                            weight += w;
                            let f = self.he.tri[(e / 3) as usize].map(|y| self.he.pos[y as usize]);
                            let nf = tri_normal(f[0], f[1], f[2]);
                            for k in 0..3 {
                                normal[k] += nf[k];
                            }
                        }
                        if weight <= 0.0 {
                            return None;
                        }
                        // Half the weighted centroid, half a spring step that pulls each
                        // edge towards its target: edge lengths come out more even than with
                        // the centroid alone (96 % instead of 94 % within 20 % on a sphere).
                        let centre = centre.map(|c| c / weight);
                        let mut spring = [0.0; 3];
                        for &e in ring.iter() {
                            let u = self.he.to(e);
                            let d = sub(self.he.pos[u as usize], x);
                            let len = dot(d, d).sqrt();
                            if len > 0.0 {
                                let f = 0.5 * (len - self.target(v, u)) / len;
                                for k in 0..3 {
                                    spring[k] += f * d[k];
                                }
                            }
                        }
                        let n_ring = ring.len() as f64;
                        let centre: [f64; 3] =
                            std::array::from_fn(|k| 0.5 * (centre[k] + x[k] + spring[k] / n_ring));
                        let q = match unit64(normal) {
                            Some(nrm) => {
                                let off = dot(sub(x, centre), nrm);
                                std::array::from_fn(|k| centre[k] + off * nrm[k])
                            }
                            None => centre,
                        };
                        let (p, size, face) = self.projected(v, q);
                        Some((p, size, 0.0, face))
                    }
                }
            })
            .collect();
        let old = self.he.pos.clone();
        let old_arc = self.arc.clone();
        let mut moved_any = vec![false; n];
        for (v, m) in moved.into_iter().enumerate() {
            if let Some((p, s, a, face)) = m {
                self.he.pos[v] = p;
                self.size[v] = s;
                self.hint[v] = face;
                if let Kind::Rim(_) = self.kind[v] {
                    self.arc[v] = a;
                }
                moved_any[v] = true;
            }
        }
        // Neighbours moving at once can turn a face over (most easily in a flat cap near a
        // ragged rim): put the corners of such faces back until none is turned.
        for _ in 0..10 {
            let turned: Vec<usize> = (0..self.he.tri.len())
                .into_par_iter()
                .filter(|&f| {
                    let t = self.he.tri[f];
                    if !self.he.face_alive[f] || !t.iter().any(|&v| moved_any[v as usize]) {
                        return false;
                    }
                    let before = t.map(|v| old[v as usize]);
                    let after = t.map(|v| self.he.pos[v as usize]);
                    match (
                        unit64(tri_normal(before[0], before[1], before[2])),
                        unit64(tri_normal(after[0], after[1], after[2])),
                    ) {
                        (Some(u), Some(w)) => dot(u, w) < 0.5,
                        _ => true,
                    }
                })
                .collect();
            if turned.is_empty() {
                break;
            }
            for f in turned {
                for v in self.he.tri[f] {
                    if moved_any[v as usize] {
                        self.he.pos[v as usize] = old[v as usize];
                        self.arc[v as usize] = old_arc[v as usize];
                        moved_any[v as usize] = false;
                    }
                }
            }
        }
    }
}
