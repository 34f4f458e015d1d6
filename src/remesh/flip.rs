//! Edge flips towards valence 6 (4 on a border), and the shape check every flip passes.

use super::halfedge::{next, NONE};
use super::{dot, min_angle, tri_normal, Remesher};
use crate::mesh::geometry::unit64;

impl Remesher {
    /// The corners [a, b, c, d] of the two faces of h (edge a-b, c and d opposite) when its
    /// edge may be flipped: alive, inside a patch, seen once (from its lower half-edge), and
    /// not between two faces that share all corners.
    pub(super) fn flippable(&self, h: u32) -> Option<[u32; 4]> {
        if !self.he.face_alive[(h / 3) as usize] {
            return None;
        }
        let t = self.he.twin(h);
        if t == NONE || t < h || self.he.is_feature(h) {
            return None;
        }
        let c = self.he.to(next(h));
        let d = self.he.to(next(t));
        (c != d).then(|| [self.he.from(h), self.he.to(h), c, d])
    }

    pub(super) fn flip_to_valence(&mut self) {
        // Valences (and border flags) once per pass, kept up to date by each flip.
        let n = self.he.pos.len();
        let mut val = vec![0i32; n];
        let mut border = vec![false; n];
        for (f, t) in self.he.tri.iter().enumerate() {
            if !self.he.face_alive[f] {
                continue;
            }
            for i in 0..3 {
                val[t[i] as usize] += 1;
                if self.he.twin[3 * f + i] == NONE {
                    // A border edge is the only edge counted at its far end too.
                    val[t[(i + 1) % 3] as usize] += 1;
                    border[t[i] as usize] = true;
                    border[t[(i + 1) % 3] as usize] = true;
                }
            }
        }
        let n_he = self.he.tri.len() as u32 * 3;
        let mut count = 0;
        let mut ring = std::mem::take(&mut self.buf);
        for h in 0..n_he {
            let Some([a, b, c, d]) = self.flippable(h) else {
                continue;
            };
            let q = [a, b, c, d];
            let v = q.map(|x| val[x as usize]);
            let tgt = q.map(|x| if border[x as usize] { 4 } else { 6 });
            if v[0] <= 3 || v[1] <= 3 {
                continue;
            }
            let before: i32 = (0..4).map(|i| (v[i] - tgt[i]).abs()).sum();
            let after = (v[0] - 1 - tgt[0]).abs()
                + (v[1] - 1 - tgt[1]).abs()
                + (v[2] + 1 - tgt[2]).abs()
                + (v[3] + 1 - tgt[3]).abs();
            if after >= before {
                continue;
            }
            self.edges_at(c, &mut ring);
            if ring.iter().any(|&e| self.other(e, c) == d) || !self.flip_keeps_shape(h) {
                continue;
            }
            self.he.flip(h);
            val[a as usize] -= 1;
            val[b as usize] -= 1;
            val[c as usize] += 1;
            val[d as usize] += 1;
            count += 1;
        }
        self.buf = ring;
        self.flips += count;
    }

    /// Whether flipping h keeps both faces facing the same way and not much sharper.
    pub(super) fn flip_keeps_shape(&self, h: u32) -> bool {
        let t = self.he.twin(h);
        let p = |v: u32| self.he.pos[v as usize];
        let (a, b) = (self.he.from(h), self.he.to(h));
        let c = self.he.to(next(h));
        let d = self.he.to(next(t));
        let old = [[p(a), p(b), p(c)], [p(b), p(a), p(d)]];
        let new = [[p(c), p(d), p(b)], [p(d), p(c), p(a)]];
        let n_old = old.map(|t| tri_normal(t[0], t[1], t[2]));
        let n_new = new.map(|t| tri_normal(t[0], t[1], t[2]));
        let (Some(o0), Some(o1), Some(n0), Some(n1)) = (
            unit64(n_old[0]),
            unit64(n_old[1]),
            unit64(n_new[0]),
            unit64(n_new[1]),
        ) else {
            return false;
        };
        let old_sum = [o0[0] + o1[0], o0[1] + o1[1], o0[2] + o1[2]];
        dot(n0, n1) > 0.7
            && dot(n0, old_sum) > 0.0
            && dot(n1, old_sum) > 0.0
            && min_angle(new[0]).min(min_angle(new[1]))
                >= 0.5 * min_angle(old[0]).min(min_angle(old[1]))
    }
}
