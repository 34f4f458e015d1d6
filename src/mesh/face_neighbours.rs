//! Faces sharing an edge with a face, through the vertex->face CSR of [`Topology`]: one face at
//! a time, or for every face at once (cap detection's flood fills and growth).

use crate::mesh::{Mesh, Topology};
use rayon::prelude::*;

/// Pads a face's neighbour slots.
const NONE: u32 = u32::MAX;

/// Edge neighbours of every face (cap detection finds them once for both its looks, the
/// smoothed copy having the same faces): up to three per face, padded with `NONE`; a face on a
/// non-manifold edge is marked and looked up again when visited.
pub(crate) struct FaceNeighbours {
    three: Vec<[u32; 3]>,
    more: Vec<bool>,
}

impl FaceNeighbours {
    /// The neighbours of every face of `mesh`, in parallel.
    pub(crate) fn build(mesh: &Mesh, topology: &Topology) -> Self {
        (0..mesh.n_triangles() as u32)
            .into_par_iter()
            .map_init(Vec::new, |scratch, f| {
                edge_neighbours(mesh, topology, f, scratch);
                let mut three = [NONE; 3];
                if scratch.len() > 3 {
                    return (three, true);
                }
                three[..scratch.len()].copy_from_slice(scratch);
                (three, false)
            })
            .unzip()
            .into()
    }

    /// Calls `visit` with each edge neighbour of face `f`, in the order [`edge_neighbours`]
    /// gives them: from the table, or (a face on a non-manifold edge) looked up again into
    /// `scratch`.
    #[inline]
    pub(crate) fn each(
        &self,
        (mesh, topology): (&Mesh, &Topology),
        f: u32,
        scratch: &mut Vec<u32>,
        mut visit: impl FnMut(u32),
    ) {
        if self.more[f as usize] {
            edge_neighbours(mesh, topology, f, scratch);
            scratch.iter().for_each(|&g| visit(g));
        } else {
            (self.three[f as usize].iter())
                .filter(|&&g| g != NONE)
                .for_each(|&g| visit(g));
        }
    }
}

impl From<(Vec<[u32; 3]>, Vec<bool>)> for FaceNeighbours {
    fn from((three, more): (Vec<[u32; 3]>, Vec<bool>)) -> Self {
        Self { three, more }
    }
}

/// Faces sharing an edge with face `f` (through the vertex->face CSR; no extra table): for
/// each edge in turn, in ascending order. The faces around the first corner give the first and
/// the last edge's neighbours, those around the second the middle edge's.
pub fn edge_neighbours(mesh: &Mesh, topology: &Topology, f: u32, out: &mut Vec<u32>) {
    out.clear();
    let tris = mesh.triangles();
    let [a, b, c] = tris[f as usize];
    // The last edge's neighbours wait here (rarely more than one).
    let mut last: [u32; 4] = [NONE; 4];
    let mut n_last = 0;
    let mut last_more: Vec<u32> = Vec::new();
    for &g in topology.vertex_faces(a as usize) {
        if g == f {
            continue;
        }
        let t = tris[g as usize];
        if t.contains(&b) {
            out.push(g);
        }
        if t.contains(&c) {
            if n_last < last.len() {
                last[n_last] = g;
                n_last += 1;
            } else {
                last_more.push(g);
            }
        }
    }
    for &g in topology.vertex_faces(b as usize) {
        if g != f && tris[g as usize].contains(&c) {
            out.push(g);
        }
    }
    out.extend_from_slice(&last[..n_last]);
    out.extend_from_slice(&last_more);
}
