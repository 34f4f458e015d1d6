//! Triangle quality and vertex displacement statistics.

use crate::mesh::Mesh;
use crate::parallel::deterministic_sum;
use rayon::prelude::*;
use serde::Serialize;

/// Smallest interior angle over all triangles, in degrees (0 for degenerate triangles). The
/// narrowest corner is picked by comparing (cos, sin) pairs ([`wider_angle`](super::wider_angle),
/// which never contradicts the arctangents) and only its arctangent is taken: the value
/// [`min_triangle_angle_of_every_corner`] gives, with one arctangent in all.
pub fn min_triangle_angle(mesh: &Mesh) -> f64 {
    let p = mesh.positions();
    let narrower = |a: (f64, f64), b: (f64, f64)| {
        if super::wider_angle(a.0, a.1, b.0, b.1) {
            b
        } else {
            a
        }
    };
    // 180 degrees: wider than any corner.
    let (sin, cos) = mesh
        .triangles()
        .par_iter()
        .map(|t| {
            let q = t.map(|v| p[v as usize].map(f64::from));
            (1..3)
                .map(|k| corner_sin_cos(q, k))
                .fold(corner_sin_cos(q, 0), narrower)
        })
        .reduce(|| (0.0, -1.0), narrower);
    sin.atan2(cos).to_degrees()
}

/// [`min_triangle_angle`] with an arctangent at every corner: the reference it must equal.
pub fn min_triangle_angle_of_every_corner(mesh: &Mesh) -> f64 {
    let p = mesh.positions();
    mesh.triangles()
        .par_iter()
        .map(|t| {
            let q = t.map(|v| p[v as usize].map(f64::from));
            (0..3)
                .map(|k| {
                    let (sin, cos) = corner_sin_cos(q, k);
                    sin.atan2(cos).to_degrees()
                })
                .fold(180.0, f64::min)
        })
        .reduce(|| 180.0, f64::min)
}

/// |u x v| and u . v for the edges u, v leaving corner `k` of triangle `q`: the corner
/// angle's sine and cosine, both scaled by the product of the edge lengths.
fn corner_sin_cos(q: [[f64; 3]; 3], k: usize) -> (f64, f64) {
    let (a, b, c) = (q[k], q[(k + 1) % 3], q[(k + 2) % 3]);
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let cr = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    ((cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt(), dot)
}

/// Bins in the displacement histogram.
pub const HISTOGRAM_BINS: usize = 20;

/// How far vertices moved between two versions of a mesh.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DisplacementStats {
    pub mean_mm: f64,
    pub rms_mm: f64,
    pub max_mm: f64,
    pub median_mm: f64,
    pub p95_mm: f64,
    /// Vertices that did not move at all.
    pub n_unmoved: usize,
    /// Counts of vertices per bin of width `bin_width_mm`, from 0 to `max_mm`.
    pub histogram: Vec<u64>,
    pub bin_width_mm: f64,
}

/// Per-vertex displacement lengths (mm) between `before` and `after` (same vertex order).
pub fn displacements(before: &[[f32; 3]], after: &[[f32; 3]]) -> Vec<f64> {
    before
        .par_iter()
        .zip(after)
        .map(|(a, b)| {
            (0..3)
                .map(|k| (b[k] as f64 - a[k] as f64).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect()
}

/// Statistics and histogram of displacement lengths.
pub fn displacement_stats(lengths: &[f64]) -> DisplacementStats {
    let n = lengths.len();
    if n == 0 {
        return DisplacementStats {
            mean_mm: 0.0,
            rms_mm: 0.0,
            max_mm: 0.0,
            median_mm: 0.0,
            p95_mm: 0.0,
            n_unmoved: 0,
            histogram: vec![0; HISTOGRAM_BINS],
            bin_width_mm: 0.0,
        };
    }
    // Order statistics without a sort: the largest, the median and the 95th percentile are the
    // values a sort (by `total_cmp`) would put there, found by selection (linear time).
    let max = (lengths.iter().copied())
        .max_by(f64::total_cmp)
        .unwrap_or(0.0);
    let mut scratch = lengths.to_vec();
    let rank = |q: f64| ((q * (n - 1) as f64).round() as usize).min(n - 1);
    let (median_rank, p95_rank) = (rank(0.5), rank(0.95));
    let (_, &mut median, above) = scratch.select_nth_unstable_by(median_rank, f64::total_cmp);
    let p95 = if p95_rank > median_rank {
        *above
            .select_nth_unstable_by(p95_rank - median_rank - 1, f64::total_cmp)
            .1
    } else {
        median
    };
    let width = if max > 0.0 {
        max / HISTOGRAM_BINS as f64
    } else {
        0.0
    };
    let mut histogram = vec![0u64; HISTOGRAM_BINS];
    for &d in lengths {
        let bin = if width > 0.0 {
            ((d / width) as usize).min(HISTOGRAM_BINS - 1)
        } else {
            0
        };
        histogram[bin] += 1;
    }
    // The zeros a sort would put first: none when anything sorts before -0 (a negative
    // value, or a NaN with its sign bit set).
    let smallest = (lengths.iter().copied()).min_by(f64::total_cmp);
    let n_unmoved = if smallest == Some(0.0) {
        lengths.iter().filter(|&&d| d == 0.0).count()
    } else {
        0
    };
    DisplacementStats {
        mean_mm: deterministic_sum(n, |i| lengths[i]) / n as f64,
        rms_mm: (deterministic_sum(n, |i| lengths[i] * lengths[i]) / n as f64).sqrt(),
        max_mm: max,
        median_mm: median,
        p95_mm: p95,
        n_unmoved,
        histogram,
        bin_width_mm: width,
    }
}

/// Upper bounds of the aspect-ratio bins of [`TriangleQuality`] (the last bin is open).
pub const ASPECT_BINS: [f64; 5] = [1.5, 2.0, 3.0, 5.0, 10.0];

/// Shape of a mesh's triangles, as meshers' quality reports give it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TriangleQuality {
    /// Smallest interior angle over all triangles (degrees).
    pub min_angle_deg: f64,
    /// 1st percentile of the triangles' smallest angles (degrees).
    pub p1_angle_deg: f64,
    /// Triangles per aspect-ratio bin (longest edge x perimeter / (4 sqrt 3 x area); 1 for an
    /// equilateral triangle): below 1.5, 2, 3, 5, 10, and 10 or more (degenerate ones there).
    pub aspect_histogram: [usize; 6],
    /// Largest aspect ratio (infinite for a degenerate triangle).
    pub max_aspect: f64,
}

/// Angles and aspect ratios of every triangle.
pub fn triangle_quality(mesh: &Mesh) -> TriangleQuality {
    let p = mesh.positions();
    let shapes: Vec<(f64, f64)> = mesh
        .triangles()
        .par_iter()
        .map(|t| {
            let q = t.map(|v| p[v as usize].map(f64::from));
            let edge = |i: usize| {
                let (a, b) = (q[i], q[(i + 1) % 3]);
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
            };
            let l = [edge(0), edge(1), edge(2)];
            let u = [q[1][0] - q[0][0], q[1][1] - q[0][1], q[1][2] - q[0][2]];
            let v = [q[2][0] - q[0][0], q[2][1] - q[0][1], q[2][2] - q[0][2]];
            let cr = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            let twice_area = (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt();
            let longest = l[0].max(l[1]).max(l[2]);
            let aspect = if twice_area > 0.0 {
                longest * (l[0] + l[1] + l[2]) / (2.0 * 3f64.sqrt() * twice_area)
            } else {
                f64::INFINITY
            };
            // Smallest angle: opposite the shortest edge, by the law of cosines' robust form.
            let angle = if twice_area > 0.0 {
                (0..3)
                    .map(|k| {
                        let (a, b, c) = (q[k], q[(k + 1) % 3], q[(k + 2) % 3]);
                        let s = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                        let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                        let d = s[0] * w[0] + s[1] * w[1] + s[2] * w[2];
                        twice_area.atan2(d).to_degrees()
                    })
                    .fold(180.0, f64::min)
            } else {
                0.0
            };
            (angle, aspect)
        })
        .collect();
    let mut angles: Vec<f64> = shapes.iter().map(|s| s.0).collect();
    angles.sort_by(|a, b| a.total_cmp(b));
    let mut aspect_histogram = [0usize; 6];
    let mut max_aspect = 0.0f64;
    for &(_, a) in &shapes {
        let bin = ASPECT_BINS.iter().position(|&b| a < b).unwrap_or(5);
        aspect_histogram[bin] += 1;
        max_aspect = max_aspect.max(a);
    }
    TriangleQuality {
        min_angle_deg: angles.first().copied().unwrap_or(0.0),
        p1_angle_deg: angles.get(angles.len() / 100).copied().unwrap_or(0.0),
        aspect_histogram,
        max_aspect,
    }
}

/// Edge lengths against a target, as a remesher's result is judged.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EdgeLengthStats {
    pub edges: usize,
    pub min_mm: f64,
    pub mean_mm: f64,
    pub max_mm: f64,
    /// Mean of length / target.
    pub mean_ratio: f64,
    /// Share of edges within 20 % of their target (0..1).
    pub within_20_percent: f64,
}

/// Length of every edge (`edges` as vertex pairs) against the mean of its two vertices'
/// targets (mm).
pub fn edge_length_stats(mesh: &Mesh, edges: &[[u32; 2]], target_mm: &[f32]) -> EdgeLengthStats {
    let p = mesh.positions();
    let measured: Vec<(f64, f64)> = edges
        .par_iter()
        .map(|&[a, b]| {
            let (x, y) = (p[a as usize], p[b as usize]);
            let len = (0..3)
                .map(|k| (x[k] as f64 - y[k] as f64).powi(2))
                .sum::<f64>()
                .sqrt();
            let target = 0.5
                * (target_mm.get(a as usize).copied().unwrap_or(f32::NAN)
                    + target_mm.get(b as usize).copied().unwrap_or(f32::NAN))
                    as f64;
            (len, len / target)
        })
        .collect();
    let n = measured.len();
    if n == 0 {
        return EdgeLengthStats {
            edges: 0,
            min_mm: 0.0,
            mean_mm: 0.0,
            max_mm: 0.0,
            mean_ratio: 0.0,
            within_20_percent: 0.0,
        };
    }
    EdgeLengthStats {
        edges: n,
        min_mm: measured.iter().map(|m| m.0).fold(f64::INFINITY, f64::min),
        mean_mm: deterministic_sum(n, |i| measured[i].0) / n as f64,
        max_mm: measured.iter().map(|m| m.0).fold(0.0, f64::max),
        mean_ratio: deterministic_sum(n, |i| measured[i].1) / n as f64,
        within_20_percent: measured.iter().filter(|m| (m.1 - 1.0).abs() <= 0.2).count() as f64
            / n as f64,
    }
}
