//! The editable triangle mesh the remesher works on: implicit half-edges (half-edge `3f + i`
//! runs from corner i of face f to corner i + 1), a twin per half-edge, and the three local
//! operations of isotropic remeshing (split, collapse, flip) done in place. Removed faces and
//! vertices are only marked; [`HalfEdgeMesh::compact`] drops them at the end.

use rayon::prelude::*;

/// No twin (a boundary half-edge) or no outgoing half-edge.
pub(super) const NONE: u32 = u32::MAX;

#[inline]
pub(super) fn next(h: u32) -> u32 {
    if h % 3 == 2 {
        h - 2
    } else {
        h + 1
    }
}

#[inline]
pub(super) fn prev(h: u32) -> u32 {
    if h % 3 == 0 {
        h + 2
    } else {
        h - 1
    }
}

/// Why a mesh cannot be turned into half-edges.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum BuildError {
    /// An edge used twice in the same direction or by more than two faces.
    NonManifoldEdge(u32, u32),
}

#[derive(Debug, Clone)]
pub(super) struct HalfEdgeMesh {
    pub pos: Vec<[f64; 3]>,
    pub tri: Vec<[u32; 3]>,
    pub twin: Vec<u32>,
    pub face_alive: Vec<bool>,
    pub face_id: Vec<u32>,
    pub vert_alive: Vec<bool>,
    /// One half-edge leaving each vertex (any; rotations go both ways at borders).
    pub out: Vec<u32>,
}

impl HalfEdgeMesh {
    pub fn build(
        pos: Vec<[f64; 3]>,
        tri: Vec<[u32; 3]>,
        face_id: Vec<u32>,
    ) -> Result<HalfEdgeMesh, BuildError> {
        let n_he = tri.len() * 3;
        let mut out = vec![NONE; pos.len()];
        for (f, t) in tri.iter().enumerate() {
            for (i, &a) in t.iter().enumerate() {
                out[a as usize] = (3 * f + i) as u32;
            }
        }
        // Half-edges sorted by their undirected edge pair up with their twins; a pair in the
        // same direction or three on one edge is not a 2-manifold. Sorting instead of hashing:
        // 0.3 s instead of 4 s for 4 M half-edges.
        let ends = |h: usize| {
            let t = tri[h / 3];
            (t[h % 3], t[(h % 3 + 1) % 3])
        };
        let mut keyed: Vec<(u64, u32)> = (0..n_he)
            .into_par_iter()
            .map(|h| {
                let (a, b) = ends(h);
                ((u64::from(a.min(b)) << 32) | u64::from(a.max(b)), h as u32)
            })
            .collect();
        keyed.par_sort_unstable();
        let mut twin = vec![NONE; n_he];
        let mut i = 0;
        while i < keyed.len() {
            let mut j = i + 1;
            while j < keyed.len() && keyed[j].0 == keyed[i].0 {
                j += 1;
            }
            let group = &keyed[i..j];
            let (a, b) = ends(group[0].1 as usize);
            match *group {
                [_] => {}
                [(_, h), (_, g)] if ends(g as usize) != (a, b) => {
                    twin[h as usize] = g;
                    twin[g as usize] = h;
                }
                _ => return Err(BuildError::NonManifoldEdge(a, b)),
            }
            i = j;
        }
        let vert_alive = out.iter().map(|&h| h != NONE).collect();
        Ok(HalfEdgeMesh {
            face_alive: vec![true; tri.len()],
            pos,
            tri,
            twin,
            face_id,
            vert_alive,
            out,
        })
    }

    #[inline]
    pub fn from(&self, h: u32) -> u32 {
        self.tri[(h / 3) as usize][(h % 3) as usize]
    }

    #[inline]
    pub fn to(&self, h: u32) -> u32 {
        self.tri[(h / 3) as usize][((h + 1) % 3) as usize]
    }

    #[inline]
    pub fn twin(&self, h: u32) -> u32 {
        self.twin[h as usize]
    }

    #[inline]
    fn link(&mut self, h: u32, g: u32) {
        if h != NONE {
            self.twin[h as usize] = g;
        }
        if g != NONE {
            self.twin[g as usize] = h;
        }
    }

    /// Half-edges leaving v, into `buf` (cleared); true if v is on an open border.
    pub fn outgoing(&self, v: u32, buf: &mut Vec<u32>) -> bool {
        buf.clear();
        let h0 = self.out[v as usize];
        if h0 == NONE {
            return false;
        }
        let mut h = h0;
        loop {
            buf.push(h);
            let t = self.twin(prev(h));
            if t == NONE {
                break;
            }
            h = t;
            if h == h0 {
                return false;
            }
            if buf.len() > self.tri.len() * 3 {
                return false; // corrupt fan; cannot happen on a manifold
            }
        }
        // Hit the border: go round the other way from the start.
        let mut h = h0;
        loop {
            let t = self.twin(h);
            if t == NONE {
                break;
            }
            h = next(t);
            if h == h0 || buf.len() > self.tri.len() * 3 {
                break;
            }
            buf.push(h);
        }
        true
    }

    /// Whether the edge of h separates different patches or is on an open border.
    #[inline]
    pub fn is_feature(&self, h: u32) -> bool {
        let t = self.twin(h);
        t == NONE || self.face_id[(h / 3) as usize] != self.face_id[(t / 3) as usize]
    }

    /// Splits the edge of h at `p`, returning the new vertex. Faces on each side become two.
    pub fn split(&mut self, h: u32, p: [f64; 3]) -> u32 {
        let t = self.twin(h);
        let (a, b) = (self.from(h), self.to(h));
        let f = h / 3;
        let c = self.to(next(h));
        let m = self.pos.len() as u32;
        self.pos.push(p);
        self.vert_alive.push(true);
        self.out.push(NONE);
        let hn = next(h);
        let t_bc = self.twin(hn);
        // f becomes (a, m, c); f2 = (m, b, c).
        let f2 = self.tri.len() as u32;
        let slot = (h % 3) as usize;
        self.tri[f as usize][(slot + 1) % 3] = m;
        self.tri.push([m, b, c]);
        self.face_alive.push(true);
        self.face_id.push(self.face_id[f as usize]);
        self.twin.extend_from_slice(&[NONE; 3]);
        let (e0, e1, e2) = (3 * f2, 3 * f2 + 1, 3 * f2 + 2);
        self.link(hn, e2);
        self.link(e1, t_bc);
        if self.out[b as usize] == hn {
            self.out[b as usize] = e1;
        }
        self.out[m as usize] = e0;
        if t == NONE {
            self.twin[h as usize] = NONE;
            self.twin[e0 as usize] = NONE;
        } else {
            let g = t / 3;
            let d = self.to(next(t));
            let tn = next(t);
            let t_ad = self.twin(tn);
            // g becomes (b, m, d); g2 = (m, a, d).
            let g2 = self.tri.len() as u32;
            let gslot = (t % 3) as usize;
            self.tri[g as usize][(gslot + 1) % 3] = m;
            self.tri.push([m, a, d]);
            self.face_alive.push(true);
            self.face_id.push(self.face_id[g as usize]);
            self.twin.extend_from_slice(&[NONE; 3]);
            let (k0, k1, k2) = (3 * g2, 3 * g2 + 1, 3 * g2 + 2);
            self.link(tn, k2);
            self.link(k1, t_ad);
            if self.out[a as usize] == tn {
                self.out[a as usize] = k1;
            }
            self.link(h, k0);
            self.link(t, e0);
        }
        m
    }

    /// Flips the interior edge of h: faces (a, b, c) and (b, a, d) become (c, d, b), (d, c, a).
    pub fn flip(&mut self, h: u32) {
        let t = self.twin(h);
        debug_assert!(t != NONE);
        let (f, g) = (h / 3, t / 3);
        let (a, b) = (self.from(h), self.to(h));
        let c = self.to(next(h));
        let d = self.to(next(t));
        let t_bc = self.twin(next(h));
        let t_ca = self.twin(prev(h));
        let t_ad = self.twin(next(t));
        let t_db = self.twin(prev(t));
        self.tri[f as usize] = [c, d, b];
        self.tri[g as usize] = [d, c, a];
        let (f0, g0) = (3 * f, 3 * g);
        self.link(f0, g0);
        self.link(f0 + 1, t_db);
        self.link(f0 + 2, t_bc);
        self.link(g0 + 1, t_ca);
        self.link(g0 + 2, t_ad);
        self.out[a as usize] = g0 + 2;
        self.out[b as usize] = f0 + 2;
        self.out[c as usize] = f0;
        self.out[d as usize] = g0;
    }

    /// Collapses the edge of h (a → b): a disappears into b, which moves to `p`; the one or two
    /// faces of the edge are removed. The caller checks the link condition first.
    pub fn collapse(&mut self, h: u32, p: [f64; 3], buf: &mut Vec<u32>) {
        let t = self.twin(h);
        let (a, b) = (self.from(h), self.to(h));
        let f = h / 3;
        let c = self.to(next(h));
        self.outgoing(a, buf);
        for &e in buf.iter() {
            let face = (e / 3) as usize;
            if face as u32 == f || (t != NONE && face as u32 == t / 3) {
                continue;
            }
            self.tri[face][(e % 3) as usize] = b;
        }
        // Stitch across the removed faces.
        let t_bc = self.twin(next(h));
        let t_ca = self.twin(prev(h));
        self.link(t_ca, t_bc);
        self.face_alive[f as usize] = false;
        let mut out_b = [t_ca, NONE, NONE];
        let out_c = if t_bc != NONE { t_bc } else { next(t_ca) };
        self.out[c as usize] = out_c;
        if t != NONE {
            let g = t / 3;
            let d = self.to(next(t));
            let t_ad = self.twin(next(t));
            let t_db = self.twin(prev(t));
            self.link(t_ad, t_db);
            self.face_alive[g as usize] = false;
            out_b[1] = t_db;
            self.out[d as usize] = if t_ad != NONE { t_ad } else { next(t_db) };
        }
        if t_bc != NONE {
            out_b[2] = next(t_bc);
        }
        self.out[b as usize] = out_b.into_iter().find(|&e| e != NONE).unwrap_or(NONE);
        self.vert_alive[a as usize] = false;
        self.out[a as usize] = NONE;
        self.pos[b as usize] = p;
    }

    /// The alive faces and vertices as plain arrays (vertices renumbered in order).
    pub fn compact(&self) -> (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<u32>) {
        let mut index = vec![NONE; self.pos.len()];
        let mut pos = Vec::new();
        for (v, &alive) in self.vert_alive.iter().enumerate() {
            if alive {
                index[v] = pos.len() as u32;
                pos.push(self.pos[v]);
            }
        }
        let mut tri = Vec::new();
        let mut ids = Vec::new();
        for (f, t) in self.tri.iter().enumerate() {
            if self.face_alive[f] {
                tri.push(t.map(|v| index[v as usize]));
                ids.push(self.face_id[f]);
            }
        }
        (pos, tri, ids)
    }
}

impl HalfEdgeMesh {
    /// Consistency of twins, fans and faces; for tests.
    pub fn validate(&self) -> Result<(), String> {
        let mut faces_at = vec![0usize; self.pos.len()];
        for f in 0..self.tri.len() {
            if !self.face_alive[f] {
                continue;
            }
            let t = self.tri[f];
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                return Err(format!("face {f} repeats a vertex: {t:?}"));
            }
            for i in 0..3 {
                let h = (3 * f + i) as u32;
                faces_at[t[i] as usize] += 1;
                if !self.vert_alive[t[i] as usize] {
                    return Err(format!("face {f} uses dead vertex {}", t[i]));
                }
                let g = self.twin(h);
                if g == NONE {
                    continue;
                }
                if !self.face_alive[(g / 3) as usize] {
                    return Err(format!("half-edge {h} twins a dead face"));
                }
                if self.twin(g) != h || self.from(g) != self.to(h) || self.to(g) != self.from(h) {
                    return Err(format!("half-edge {h} and twin {g} disagree"));
                }
            }
        }
        let mut buf = Vec::new();
        for (v, &n_faces) in faces_at.iter().enumerate() {
            if !self.vert_alive[v] {
                continue;
            }
            let h = self.out[v];
            if h == NONE || !self.face_alive[(h / 3) as usize] || self.from(h) != v as u32 {
                return Err(format!("vertex {v} has a bad outgoing half-edge {h}"));
            }
            self.outgoing(v as u32, &mut buf);
            if buf.len() != n_faces {
                return Err(format!(
                    "vertex {v}: fan of {} faces, {} faces use it",
                    buf.len(),
                    n_faces
                ));
            }
        }
        Ok(())
    }
}
