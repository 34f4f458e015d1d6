//! Explicit mean curvature flow with normalised cotangent weights (Desbrun et al. 1999):
//! v += lambda w (sum_j c_vj (v_j - v)) / sum_j c_vj, c_vj = (cot a + cot b) / 2 over the two
//! angles opposite edge vj. Cotangents are clamped to [0, COT_MAX] so obtuse triangles (negative
//! cotangents) cannot flip the operator and slivers cannot blow it up; a vertex whose weights
//! vanish falls back to the umbrella operator.

use super::{max_step, CHUNK};
use crate::mesh::umbrella::neighbour_mean;
use crate::mesh::{Mesh, Topology};
use rayon::prelude::*;

/// Largest cotangent used (an angle of about 0.06 degrees).
const COT_MAX: f32 = 1000.0;

/// Cotangents of a triangle's three angles (at corner 0, 1, 2), clamped.
#[inline]
pub fn cotangents(p: [[f32; 3]; 3]) -> [f32; 3] {
    std::array::from_fn(|k| {
        let (a, b, c) = (p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        let cross = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let sin = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
        if sin <= f32::MIN_POSITIVE {
            return if dot > 0.0 { COT_MAX } else { 0.0 };
        }
        (dot / sin).clamp(0.0, COT_MAX)
    })
}

pub(super) fn mcf(
    mesh: &Mesh,
    topology: &Topology,
    scale: &[f32],
    lambda: f32,
    iterations: usize,
) -> (Vec<[f32; 3]>, f32) {
    let tris = mesh.triangles();
    let (vf_offsets, vf_faces) = topology.face_csr();
    let (vv_offsets, neighbors) = topology.neighbor_csr();
    let mut a = mesh.positions().to_vec();
    let mut b = a.clone();
    let mut cot = vec![[0.0f32; 3]; tris.len()];
    for _ in 0..iterations {
        cot.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
            for (i, o) in out.iter_mut().enumerate() {
                let t = tris[c * CHUNK + i];
                *o = cotangents(t.map(|v| a[v as usize]));
            }
        });
        b.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
            let first = c * CHUNK;
            for (i, o) in out.iter_mut().enumerate() {
                let v = first + i;
                let p = a[v];
                let s = lambda * scale[v];
                if s == 0.0 {
                    *o = p;
                    continue;
                }
                let mut sum = [0.0f32; 3];
                let mut total = 0.0f32;
                for &f in &vf_faces[vf_offsets[v] as usize..vf_offsets[v + 1] as usize] {
                    let t = tris[f as usize];
                    let k = if t[0] as usize == v {
                        0
                    } else if t[1] as usize == v {
                        1
                    } else {
                        2
                    };
                    let (na, nb) = (t[(k + 1) % 3] as usize, t[(k + 2) % 3] as usize);
                    let cf = cot[f as usize];
                    // The angle at nb is opposite edge (v, na), and vice versa.
                    let (wa, wb) = (0.5 * cf[(k + 2) % 3], 0.5 * cf[(k + 1) % 3]);
                    let (qa, qb) = (a[na], a[nb]);
                    for d in 0..3 {
                        sum[d] += wa * (qa[d] - p[d]) + wb * (qb[d] - p[d]);
                    }
                    total += wa + wb;
                }
                let delta: [f32; 3] = if total > 1e-12 {
                    sum.map(|x| x / total)
                } else {
                    let m = neighbour_mean(
                        &a,
                        &neighbors[vv_offsets[v] as usize..vv_offsets[v + 1] as usize],
                    );
                    [m[0] - p[0], m[1] - p[1], m[2] - p[2]]
                };
                *o = [
                    p[0] + s * delta[0],
                    p[1] + s * delta[1],
                    p[2] + s * delta[2],
                ];
            }
        });
        std::mem::swap(&mut a, &mut b);
    }
    let last = if iterations > 0 {
        max_step(&a, &b)
    } else {
        0.0
    };
    (a, last)
}
