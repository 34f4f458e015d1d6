//! Normal curvature as the papers define it (Moench 2010, §4; Moench et al. 2010, §4): per
//! vertex, the largest angle in degrees between the vertex normal and its incident face normals.
//! Flat regions give 0; terrace edges of a staircase give large values.

use crate::mesh::geometry::face_and_vertex_normals;
use crate::mesh::{Mesh, Topology};
use crate::parallel::REDUCE_BLOCK;
use rayon::prelude::*;

/// Normal curvature per vertex in degrees; `None` where the vertex has no incident face with
/// area or its normal cancels out (unreferenced or degenerate neighbourhoods).
///
/// The same values as [`vertex_normal_turn`]'s `deg`, found with one arctangent per vertex:
/// the widest of a vertex's angles is picked by comparing (cos, sin) pairs
/// ([`wider_angle`](super::wider_angle)), and only its arctangent is taken.
pub fn vertex_normal_curvature(mesh: &Mesh, topology: &Topology) -> Vec<Option<f32>> {
    let angles = FaceAngles::new(mesh, topology);
    (0..mesh.n_vertices())
        .into_par_iter()
        .map(|v| angles.widest_deg(v))
        .collect()
}

/// A mesh's face and vertex normals, for folds over the angles between each vertex's normal
/// and its faces'.
struct FaceAngles<'a> {
    topology: &'a Topology,
    fnormals: Vec<[f32; 3]>,
    vnormals: Vec<[f32; 3]>,
}

impl<'a> FaceAngles<'a> {
    fn new(mesh: &Mesh, topology: &'a Topology) -> Self {
        let (fnormals, vnormals) = face_and_vertex_normals(mesh, topology);
        FaceAngles {
            topology,
            fnormals,
            vnormals,
        }
    }

    /// `fold` over v's incident faces with area, in order: the vertex, the face and the sine
    /// and cosine of the angle between the two normals. `None` where the vertex normal cancels
    /// out or no face has area.
    #[inline]
    fn fold<T>(
        &self,
        v: usize,
        fold: impl Fn(Option<T>, usize, u32, f64, f64) -> Option<T>,
    ) -> Option<T> {
        let n = self.vnormals[v];
        if n == [0.0; 3] {
            return None;
        }
        let mut acc = None;
        for &f in self.topology.vertex_faces(v) {
            let m = self.fnormals[f as usize];
            if m != [0.0; 3] {
                let (sin, cos) = sin_cos_between(n, m);
                acc = fold(acc, v, f, sin, cos);
            }
        }
        acc
    }

    /// The normal curvature of vertex v (degrees), with one arctangent.
    #[inline]
    fn widest_deg(&self, v: usize) -> Option<f32> {
        let widest = self.fold(
            v,
            |widest: Option<(f64, f64)>, _, _, sin, cos| match widest {
                Some((s, c)) if !super::wider_angle(sin, cos, s, c) => widest,
                _ => Some((sin, cos)),
            },
        );
        widest.map(|(sin, cos)| sin.atan2(cos).to_degrees() as f32)
    }
}

/// How much the surface turns at a vertex: the normal curvature, and the same angle per mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalTurn {
    /// Largest angle between the vertex normal and an incident face normal (degrees).
    pub deg: f32,
    /// Largest such angle divided by the distance from the vertex to that face's centroid
    /// (degrees per mm): about 57.3 / radius of curvature, whatever the edge length, so that a
    /// finely sampled round surface is not taken for a flat one.
    pub deg_per_mm: f32,
}

/// [`NormalTurn`] per vertex; `None` where the normal curvature is undefined.
pub fn vertex_normal_turn(mesh: &Mesh, topology: &Topology) -> Vec<Option<NormalTurn>> {
    let (p, triangles) = (mesh.positions(), mesh.triangles());
    let angles = FaceAngles::new(mesh, topology);
    (0..mesh.n_vertices())
        .into_par_iter()
        .map(|v| {
            let largest = angles.fold(v, |largest: Option<(f64, f64)>, v, f, sin, cos| {
                // Accurate near 0, unlike the arccosine of the cosine.
                let angle = sin.atan2(cos);
                let distance = centroid_distance(p, triangles[f as usize], v);
                let rate = if distance > 0.0 {
                    angle / distance
                } else {
                    f64::INFINITY
                };
                Some(largest.map_or((angle, rate), |(a, r)| (a.max(angle), r.max(rate))))
            });
            largest.map(|(a, r)| NormalTurn {
                deg: a.to_degrees() as f32,
                deg_per_mm: r.to_degrees() as f32,
            })
        })
        .collect()
}

/// A mesh's face and vertex normals, to ask which vertices turn within limits (flat-vertex
/// tests of cap and stack-axis detection) without computing every turn.
pub struct TurnLimits<'a> {
    mesh: &'a Mesh,
    topology: &'a Topology,
    fnormals: Vec<[f32; 3]>,
    vnormals: Vec<[f32; 3]>,
    /// Limits given to [`TurnLimits::remember`] (as bits), and per vertex the flags found for
    /// them (bit k for limit k).
    remembered_limits: Vec<(u32, u32)>,
    remembered: Vec<u8>,
}

impl<'a> TurnLimits<'a> {
    /// Computes the face and vertex normals once, for any number of [`TurnLimits::within`].
    pub fn new(mesh: &'a Mesh, topology: &'a Topology) -> Self {
        let (fnormals, vnormals) = face_and_vertex_normals(mesh, topology);
        Self {
            mesh,
            topology,
            fnormals,
            vnormals,
            remembered_limits: Vec::new(),
            remembered: Vec::new(),
        }
    }

    /// The unit face normals (zero for triangles without area), as [`face_normals`] gives
    /// them to the bit: computed once for every analysis of the same mesh.
    ///
    /// [`face_normals`]: crate::mesh::geometry::face_normals
    pub fn face_normals(&self) -> &[[f32; 3]] {
        &self.fnormals
    }

    /// The mesh the normals are of.
    pub fn mesh(&self) -> &'a Mesh {
        self.mesh
    }

    /// The mesh's topology (vertex-face incidence).
    pub fn topology(&self) -> &'a Topology {
        self.topology
    }

    /// Per vertex: whether its normal curvature is at most `max_deg` and its turn per mm at
    /// most `max_deg_per_mm` (false where undefined). The same decision as comparing
    /// [`vertex_normal_turn`]'s values, but the arctangent is taken only for faces near a
    /// limit: below a limit by a margin far above rounding, tan(angle) (a ratio, an upper bound
    /// of the angle) already decides. Limits given to [`TurnLimits::remember`] are answered
    /// from the flags found there.
    pub fn within(&self, max_deg: f32, max_deg_per_mm: f32) -> Vec<bool> {
        let key = (max_deg.to_bits(), max_deg_per_mm.to_bits());
        if let Some(k) = self.remembered_limits.iter().position(|&l| l == key) {
            return self
                .remembered
                .iter()
                .map(|&bits| bits >> k & 1 == 1)
                .collect();
        }
        self.within_each(&[(max_deg, max_deg_per_mm)], false)
            .0
            .into_iter()
            .map(|bits| bits == 1)
            .collect()
    }

    /// Finds the flags of [`TurnLimits::within`] for up to eight pairs of limits (degrees,
    /// degrees per mm) in one walk over every vertex's faces, for the analyses that ask for
    /// them later: one angle per face instead of one per face and limit.
    pub fn remember(&mut self, limits: &[(f32, f32)]) {
        self.remember_and_measure(limits, false);
    }

    /// [`TurnLimits::remember`], and in the same walk the mesh's average normal curvature,
    /// given to the bit as [`average_normal_curvature`] gives it (an inspect report's figure,
    /// for the price of visiting every face).
    pub fn remember_with_curvature(&mut self, limits: &[(f32, f32)]) -> f64 {
        self.remember_and_measure(limits, true).unwrap_or(0.0)
    }

    fn remember_and_measure(&mut self, limits: &[(f32, f32)], widest: bool) -> Option<f64> {
        let limits = &limits[..limits.len().min(8)];
        let (flags, curvature) = self.within_each(limits, widest);
        self.remembered = flags;
        self.remembered_limits = limits
            .iter()
            .map(|&(deg, rate)| (deg.to_bits(), rate.to_bits()))
            .collect();
        curvature
    }

    /// Per vertex, bit `k` set when the vertex is within `limits[k]` (at most eight); with
    /// `widest`, also the average normal curvature (degrees) found in the same walk.
    fn within_each(&self, limits: &[(f32, f32)], widest: bool) -> (Vec<u8>, Option<f64>) {
        /// One pair of limits, with what the quick tests need.
        struct Limit {
            max_deg: f32,
            max_deg_per_mm: f32,
            quick_limit: bool,
            tan_max: f64,
            max_rate: f64,
            /// The angle limit is at least 1e-6 degrees and below 1.2 radians: a tangent
            /// above `tan_over` is then over it by far more than rounding.
            quick_over: bool,
            tan_over: f64,
            /// The rate limit is finite and at least 1e-6 degrees per mm.
            quick_rate_over: bool,
        }
        let (p, triangles) = (self.mesh.positions(), self.mesh.triangles());
        // Limits in radians, less a relative margin of 1e-6 for the quick tests (which need a
        // limit below 90 degrees and a face less than 90 degrees away).
        let safe = 1.0 - 1e-6;
        let limits: Vec<Limit> = limits
            .iter()
            .take(8)
            .map(|&(max_deg, max_deg_per_mm)| {
                let max_rad = f64::from(max_deg).to_radians();
                Limit {
                    max_deg,
                    max_deg_per_mm,
                    quick_limit: max_rad * safe < std::f64::consts::FRAC_PI_2,
                    tan_max: (max_rad * safe).tan(),
                    max_rate: f64::from(max_deg_per_mm).to_radians(),
                    quick_over: max_deg >= 1e-6 && max_rad < 1.2,
                    tan_over: max_rad.tan() * OVER,
                    quick_rate_over: max_deg_per_mm >= 1e-6 && max_deg_per_mm.is_finite(),
                }
            })
            .collect();
        /// A tangent this much over a limit's puts the angle over the limit by more than 2e-6
        /// of it (limits below 1.2 radians), far beyond the rounding of the exact test.
        const OVER: f64 = 1.0 + 1e-5;
        let all: u8 = ((1u16 << limits.len()) - 1) as u8;
        // Per vertex: the flags, and the normal curvature (degrees) when `widest` asks for it
        // (then every face is visited; otherwise the walk stops once every limit is exceeded).
        let vertex = |v: usize| -> (u8, Option<f32>) {
            let n = self.vnormals[v];
            if n == [0.0; 3] {
                return (0, None);
            }
            let mut defined = false;
            // Limits not yet exceeded by any face.
            let mut open = all;
            // The widest (sine, cosine) so far, picked as `FaceAngles::widest_deg` picks it.
            let mut wide: Option<(f64, f64)> = None;
            for &f in self.topology.vertex_faces(v) {
                let m = self.fnormals[f as usize];
                if m == [0.0; 3] {
                    continue;
                }
                defined = true;
                let (sin, cos) = sin_cos_between(n, m);
                if widest {
                    wide = match wide {
                        Some((s, c)) if !super::wider_angle(sin, cos, s, c) => wide,
                        _ => Some((sin, cos)),
                    };
                }
                let mut angle: Option<f64> = None;
                let mut distance: Option<f64> = None;
                for (k, limit) in limits.iter().enumerate() {
                    if open >> k & 1 == 0 {
                        continue;
                    }
                    let quick = limit.quick_limit && cos > 0.0;
                    // Below the angle limit for certain when tan(angle) is below tan(limit),
                    // over it when tan(angle) is clearly above.
                    if quick && limit.quick_over && sin > cos * limit.tan_over {
                        open &= !(1 << k);
                        continue;
                    }
                    if !(quick && sin <= cos * limit.tan_max) {
                        let a = *angle.get_or_insert_with(|| sin.atan2(cos));
                        if !at_most(a.to_degrees() as f32, limit.max_deg) {
                            open &= !(1 << k);
                            continue;
                        }
                    }
                    if limit.max_deg_per_mm == f32::INFINITY {
                        continue;
                    }
                    let d = *distance
                        .get_or_insert_with(|| centroid_distance(p, triangles[f as usize], v));
                    if d <= 0.0 {
                        // An infinite rate: within only an infinite limit.
                        open &= !(1 << k);
                        continue;
                    }
                    if quick && sin <= cos * limit.max_rate * safe * d {
                        continue;
                    }
                    // Over the rate for certain when tan(angle) is clearly above
                    // theta / (1 - theta^2 / 2) >= tan(theta), theta = rate x distance < 1.
                    let theta = limit.max_rate * d;
                    if quick
                        && limit.quick_rate_over
                        && theta < 1.0
                        && sin * (1.0 - 0.5 * theta * theta) > cos * theta * OVER
                    {
                        open &= !(1 << k);
                        continue;
                    }
                    let a = *angle.get_or_insert_with(|| sin.atan2(cos));
                    if !at_most((a / d).to_degrees() as f32, limit.max_deg_per_mm) {
                        open &= !(1 << k);
                    }
                }
                if open == 0 && !widest {
                    return (0, None);
                }
            }
            let curvature = wide.map(|(sin, cos)| sin.atan2(cos).to_degrees() as f32);
            (if defined { open } else { 0 }, curvature)
        };
        // Blocks of `REDUCE_BLOCK` vertices, each curvature added as `average_normal_curvature`
        // adds it: the same bits.
        let mut flags = vec![0u8; self.mesh.n_vertices()];
        let blocks: Vec<(f64, usize)> = flags
            .par_chunks_mut(REDUCE_BLOCK)
            .enumerate()
            .map(|(b, out)| {
                let mut n_defined = 0;
                let sum = (out.iter_mut().enumerate())
                    .map(|(i, slot)| {
                        let (bits, curvature) = vertex(b * REDUCE_BLOCK + i);
                        *slot = bits;
                        curvature.map_or(0.0, |c| {
                            n_defined += 1;
                            f64::from(c)
                        })
                    })
                    .sum::<f64>();
                (sum, n_defined)
            })
            .collect();
        (flags, widest.then(|| mean_of_blocks(&blocks)))
    }
}

/// `x <= limit`, false for NaN: a turn that cannot be measured is not within any limit.
fn at_most(x: f32, limit: f32) -> bool {
    x <= limit
}

/// Mean normal curvature in degrees over the vertices where it is defined; 0 if none.
pub fn average_normal_curvature(mesh: &Mesh, topology: &Topology) -> f64 {
    // The blocks and order of `deterministic_sum`, each vertex's curvature found as it is
    // added (no array of them).
    let angles = FaceAngles::new(mesh, topology);
    let n = mesh.n_vertices();
    let blocks: Vec<(f64, usize)> = (0..n.div_ceil(REDUCE_BLOCK))
        .into_par_iter()
        .map(|b| {
            let mut n_defined = 0;
            let sum = (b * REDUCE_BLOCK..((b + 1) * REDUCE_BLOCK).min(n))
                .map(|v| {
                    angles.widest_deg(v).map_or(0.0, |c| {
                        n_defined += 1;
                        f64::from(c)
                    })
                })
                .sum::<f64>();
            (sum, n_defined)
        })
        .collect();
    mean_of_blocks(&blocks)
}

/// The mean of per-block (sum, count) pairs, the sums added in block order; 0 if no count.
fn mean_of_blocks(blocks: &[(f64, usize)]) -> f64 {
    let n_defined: usize = blocks.iter().map(|b| b.1).sum();
    if n_defined == 0 {
        return 0.0;
    }
    let total: f64 = blocks.iter().map(|b| b.0).sum();
    total / n_defined as f64
}

/// |a x b| and a . b in f64: the sine and cosine of the angle between unit vectors.
fn sin_cos_between(a: [f32; 3], b: [f32; 3]) -> (f64, f64) {
    let a = [a[0] as f64, a[1] as f64, a[2] as f64];
    let b = [b[0] as f64, b[1] as f64, b[2] as f64];
    let c = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let sin = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    (sin, cos)
}

/// Distance from vertex `v` to the centroid of triangle `t` (mm, f64).
fn centroid_distance(p: &[[f32; 3]], t: [u32; 3], v: usize) -> f64 {
    (0..3)
        .map(|k| {
            let c = (t.iter().map(|&w| p[w as usize][k] as f64).sum::<f64>()) / 3.0;
            (c - p[v][k] as f64).powi(2)
        })
        .sum::<f64>()
        .sqrt()
}
