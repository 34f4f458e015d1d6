//! The last pass of remeshing: the sharpest angles left are flipped or collapsed away.

use super::{min_angle, Kind, Remesher, SPLIT};

impl Remesher {
    /// Removes the sharpest angles left: flips an edge of a face with an angle under 30
    /// degrees when that raises the smaller minimum angle of the two faces, collapses the
    /// shortest possible edge of a face under 25 degrees when every face it changes ends up
    /// better, and relaxes again, until nothing changes.
    ///
    /// Each round relaxes only around what it changed: a whole relaxation per round cost more
    /// than the rest of the pass together and undid nothing the local one keeps. After the
    /// first round only the faces at a changed or moved vertex are looked at again (the others
    /// are as the last round left them): on 1.3 M triangles the pass took 0.5 s scanning them
    /// all every round.
    pub(super) fn improve_angles(&mut self) {
        let mut touched = Vec::new();
        let mut ring = Vec::new();
        // Faces to look at (all of them when `None`); faces made after it was set are.
        let mut scan: Option<Vec<bool>> = None;
        for _round in 0..8 {
            touched.clear();
            let changed = self.flip_sharp(30f64.to_radians(), scan.as_deref(), &mut touched);
            self.check("flip sharp");
            let changed =
                changed + self.collapse_sharp(25f64.to_radians(), scan.as_deref(), &mut touched);
            self.check("collapse sharp");
            if changed == 0 {
                break;
            }
            // The changed vertices and their neighbours.
            let mut near = vec![false; self.he.pos.len()];
            for &v in &touched {
                if !self.he.vert_alive[v as usize] {
                    continue;
                }
                near[v as usize] = true;
                self.edges_at(v, &mut ring);
                for &e in &ring {
                    near[self.other(e, v) as usize] = true;
                }
            }
            self.relax_and_project(Some(&near));
            let mut faces = vec![false; self.he.tri.len()];
            for (v, _) in near.iter().enumerate().filter(|(_, &n)| n) {
                if self.he.vert_alive[v] {
                    self.edges_at(v as u32, &mut ring);
                    for &e in &ring {
                        faces[(e / 3) as usize] = true;
                    }
                }
            }
            scan = Some(faces);
        }
    }

    /// Whether face f is to be looked at this round (see [`Self::improve_angles`]).
    fn in_scan(scan: Option<&[bool]>, f: usize) -> bool {
        scan.is_none_or(|s| s.get(f).copied().unwrap_or(true))
    }

    fn face_min_angle(&self, f: usize) -> f64 {
        min_angle(self.he.tri[f].map(|v| self.he.pos[v as usize]))
    }

    fn collapse_sharp(
        &mut self,
        limit: f64,
        scan: Option<&[bool]>,
        touched: &mut Vec<u32>,
    ) -> usize {
        let mut count = 0;
        for f in 0..self.he.tri.len() {
            if !self.he.face_alive[f] || !Self::in_scan(scan, f) {
                continue;
            }
            let worst = self.face_min_angle(f);
            if worst >= limit {
                continue;
            }
            let mut edges = [3 * f as u32, 3 * f as u32 + 1, 3 * f as u32 + 2];
            edges.sort_by(|&x, &y| self.len(x).total_cmp(&self.len(y)));
            self.collapse_floor = worst + 1e-3;
            self.collapse_stretch = 5.0 / 3.0;
            let mut done = false;
            for h in edges {
                if let Some(kept) = self.try_collapse(h) {
                    touched.push(kept);
                    count += 1;
                    done = true;
                    break;
                }
            }
            self.collapse_floor = 10f64.to_radians();
            self.collapse_stretch = SPLIT;
            if done {
                continue;
            }
            // A face whose corners all lie on feature lines (an ear at a rim): split its
            // edge that crosses the patch so an inner vertex can take the angle.
            let corners = self.he.tri[f];
            if corners
                .iter()
                .all(|&v| !matches!(self.kind[v as usize], Kind::Interior(_)))
            {
                if let Some(h) = (0..3)
                    .map(|i| 3 * f as u32 + i)
                    .find(|&h| !self.he.is_feature(h))
                {
                    if let Some(v) = self.split_edge(h) {
                        touched.push(v);
                        count += 1;
                    }
                }
            }
        }
        count
    }

    fn flip_sharp(&mut self, limit: f64, scan: Option<&[bool]>, touched: &mut Vec<u32>) -> usize {
        let n_he = self.he.tri.len() as u32 * 3;
        let mut count = 0;
        for h in 0..n_he {
            if !Self::in_scan(scan, (h / 3) as usize) {
                continue;
            }
            let Some([a, b, c, d]) = self.flippable(h) else {
                continue;
            };
            let p = |v: u32| self.he.pos[v as usize];
            let old = min_angle([p(a), p(b), p(c)]).min(min_angle([p(b), p(a), p(d)]));
            if old >= limit {
                continue;
            }
            let new = min_angle([p(c), p(d), p(b)]).min(min_angle([p(d), p(c), p(a)]));
            if new <= old {
                continue;
            }
            let mut ring = std::mem::take(&mut self.buf);
            self.edges_at(c, &mut ring);
            let exists = ring.iter().any(|&e| self.other(e, c) == d);
            let border_a = self.edges_at(a, &mut ring);
            let low_a = ring.len() <= if border_a { 2 } else { 3 };
            let border_b = self.edges_at(b, &mut ring);
            let low_b = ring.len() <= if border_b { 2 } else { 3 };
            self.buf = ring;
            if exists || low_a || low_b || !self.flip_keeps_shape(h) {
                continue;
            }
            self.he.flip(h);
            touched.extend([a, b, c, d]);
            count += 1;
        }
        self.flips += count;
        count
    }
}
