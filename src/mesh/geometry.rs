//! Per-face and per-vertex geometry: normals, areas, enclosed volume, bounding box.
//!
//! Sums accumulate in f64 over fixed blocks ([`crate::parallel`]) so results are the same for
//! any thread count.

use crate::mesh::{Mesh, Topology};
use crate::parallel::deterministic_sum;
use rayon::prelude::*;

/// Axis-aligned bounding box in mm.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BoundingBox {
    pub min: [f32; 3],
    pub max: [f32; 3],
}

impl BoundingBox {
    /// Edge lengths along x, y, z in mm.
    pub fn extent(&self) -> [f32; 3] {
        [
            self.max[0] - self.min[0],
            self.max[1] - self.min[1],
            self.max[2] - self.min[2],
        ]
    }

    /// Length of the box diagonal in mm.
    pub fn diagonal(&self) -> f64 {
        let e = self.extent();
        e.iter()
            .map(|&x| (x as f64) * (x as f64))
            .sum::<f64>()
            .sqrt()
    }

    /// Centre of the box in mm.
    pub fn center(&self) -> [f64; 3] {
        std::array::from_fn(|k| 0.5 * (self.min[k] as f64 + self.max[k] as f64))
    }
}

/// Bounding box of all vertices (unreferenced included); `None` for a mesh without vertices.
pub fn bounding_box(mesh: &Mesh) -> Option<BoundingBox> {
    let p = mesh.positions();
    let first = *p.first()?;
    let (min, max) = p.iter().fold((first, first), |(mut lo, mut hi), q| {
        for k in 0..3 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
        (lo, hi)
    });
    Some(BoundingBox { min, max })
}

/// a - b.
#[inline]
pub fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// a x b.
#[inline]
pub fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// a . b.
#[inline]
pub fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
fn to_f64(a: [f32; 3]) -> [f64; 3] {
    [a[0] as f64, a[1] as f64, a[2] as f64]
}

/// Unit vector along `v`, or zero when `v` has no length.
#[inline]
pub(crate) fn normalize(v: [f32; 3]) -> [f32; 3] {
    let len = dot(v, v).sqrt();
    if len > 0.0 && len.is_finite() {
        [v[0] / len, v[1] / len, v[2] / len]
    } else {
        [0.0; 3]
    }
}

/// Cross product of a triangle's edges: normal direction with length twice the area (mm²).
#[inline]
pub fn triangle_area_vector(mesh: &Mesh, triangle: [u32; 3]) -> [f32; 3] {
    let p = mesh.positions();
    let (a, b, c) = (
        p[triangle[0] as usize],
        p[triangle[1] as usize],
        p[triangle[2] as usize],
    );
    cross(sub(b, a), sub(c, a))
}

/// Unit normal per triangle (right-hand rule); zero for triangles without area.
pub fn face_normals(mesh: &Mesh) -> Vec<[f32; 3]> {
    mesh.triangles()
        .par_iter()
        .map(|&t| normalize(triangle_area_vector(mesh, t)))
        .collect()
}

/// [`face_normals`] and [`vertex_normals`] together, bit for bit the same, with each
/// triangle's area vector computed once instead of once per corner.
pub fn face_and_vertex_normals(mesh: &Mesh, topology: &Topology) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let mut faces: Vec<[f32; 3]> = mesh
        .triangles()
        .par_iter()
        .map(|&t| triangle_area_vector(mesh, t))
        .collect();
    let vertices = (0..mesh.n_vertices())
        .into_par_iter()
        .map(|v| {
            let mut sum = [0.0f32; 3];
            for &f in topology.vertex_faces(v) {
                let n = faces[f as usize];
                for k in 0..3 {
                    sum[k] += n[k];
                }
            }
            normalize(sum)
        })
        .collect();
    faces.par_iter_mut().for_each(|n| *n = normalize(*n));
    (faces, vertices)
}

/// Area-weighted unit vertex normals; zero for unreferenced vertices or cancelling normals.
pub fn vertex_normals(mesh: &Mesh, topology: &Topology) -> Vec<[f32; 3]> {
    let tris = mesh.triangles();
    (0..mesh.n_vertices())
        .into_par_iter()
        .map(|v| {
            let mut sum = [0.0f32; 3];
            for &f in topology.vertex_faces(v) {
                let n = triangle_area_vector(mesh, tris[f as usize]);
                for k in 0..3 {
                    sum[k] += n[k];
                }
            }
            normalize(sum)
        })
        .collect()
}

/// Total surface area in mm² (f64 accumulation).
pub fn area(mesh: &Mesh) -> f64 {
    let p = mesh.positions();
    let tris = mesh.triangles();
    deterministic_sum(tris.len(), |i| {
        let t = tris[i];
        let (a, b, c) = (
            to_f64(p[t[0] as usize]),
            to_f64(p[t[1] as usize]),
            to_f64(p[t[2] as usize]),
        );
        let n = cross64(sub64(b, a), sub64(c, a));
        0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
    })
}

/// Signed enclosed volume in mm³ by the divergence theorem, positive for outward-oriented
/// closed meshes. Computed about the bounding-box centre, which for a closed mesh gives the
/// same value with less cancellation; for an open mesh the value depends on that choice.
pub fn signed_volume(mesh: &Mesh) -> f64 {
    let Some(bbox) = bounding_box(mesh) else {
        return 0.0;
    };
    let o = bbox.center();
    let p = mesh.positions();
    let tris = mesh.triangles();
    let rel = |v: u32| {
        let q = p[v as usize];
        [q[0] as f64 - o[0], q[1] as f64 - o[1], q[2] as f64 - o[2]]
    };
    deterministic_sum(tris.len(), |i| {
        let t = tris[i];
        let (a, b, c) = (rel(t[0]), rel(t[1]), rel(t[2]));
        let n = cross64(b, c);
        (a[0] * n[0] + a[1] * n[1] + a[2] * n[2]) / 6.0
    })
}

/// Signed enclosed volume of each connected piece of a closed mesh (mm³, in the order of
/// [`Topology::vertex_component`]): an object's outer shell encloses positive volume, the wall
/// of a cavity inside it negative, so the positive entries count the objects.
pub fn shell_volumes(mesh: &Mesh, topology: &Topology) -> Vec<f64> {
    let component = topology.vertex_component();
    let mut volumes = vec![0.0; topology.n_components()];
    let Some(bbox) = bounding_box(mesh) else {
        return volumes;
    };
    let o = bbox.center();
    let p = mesh.positions();
    let rel = |v: u32| {
        let q = p[v as usize];
        [q[0] as f64 - o[0], q[1] as f64 - o[1], q[2] as f64 - o[2]]
    };
    for t in mesh.triangles() {
        let (a, b, c) = (rel(t[0]), rel(t[1]), rel(t[2]));
        if let Some(v) = volumes.get_mut(component[t[0] as usize] as usize) {
            *v += dot64(a, cross64(b, c)) / 6.0;
        }
    }
    volumes
}

/// a - b in f64.
#[inline]
pub(crate) fn sub64(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// a x b in f64.
#[inline]
pub fn cross64(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// a . b in f64.
#[inline]
pub fn dot64(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `v` scaled to length 1 in f64; None for a zero or non-finite vector.
#[inline]
pub fn unit64(v: [f64; 3]) -> Option<[f64; 3]> {
    let len = dot64(v, v).sqrt();
    (len > 0.0 && len.is_finite()).then(|| v.map(|x| x / len))
}
