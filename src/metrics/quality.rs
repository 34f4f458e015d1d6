//! Triangle quality and vertex displacement statistics.

use crate::mesh::Mesh;
use crate::parallel::deterministic_sum;
use rayon::prelude::*;
use serde::Serialize;

/// Smallest interior angle over all triangles, in degrees (0 for degenerate triangles).
pub fn min_triangle_angle(mesh: &Mesh) -> f64 {
    let p = mesh.positions();
    mesh.triangles()
        .par_iter()
        .map(|t| {
            let q = t.map(|v| p[v as usize].map(f64::from));
            (0..3)
                .map(|k| {
                    let (a, b, c) = (q[k], q[(k + 1) % 3], q[(k + 2) % 3]);
                    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                    let dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
                    let cr = [
                        u[1] * v[2] - u[2] * v[1],
                        u[2] * v[0] - u[0] * v[2],
                        u[0] * v[1] - u[1] * v[0],
                    ];
                    let sin = (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt();
                    sin.atan2(dot).to_degrees()
                })
                .fold(180.0, f64::min)
        })
        .reduce(|| 180.0, f64::min)
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
    let mut sorted = lengths.to_vec();
    sorted.par_sort_unstable_by(f64::total_cmp);
    let max = sorted[n - 1];
    let quantile = |q: f64| sorted[((q * (n - 1) as f64).round() as usize).min(n - 1)];
    let width = if max > 0.0 {
        max / HISTOGRAM_BINS as f64
    } else {
        0.0
    };
    let mut histogram = vec![0u64; HISTOGRAM_BINS];
    for &d in &sorted {
        let bin = if width > 0.0 {
            ((d / width) as usize).min(HISTOGRAM_BINS - 1)
        } else {
            0
        };
        histogram[bin] += 1;
    }
    DisplacementStats {
        mean_mm: deterministic_sum(n, |i| lengths[i]) / n as f64,
        rms_mm: (deterministic_sum(n, |i| lengths[i] * lengths[i]) / n as f64).sqrt(),
        max_mm: max,
        median_mm: quantile(0.5),
        p95_mm: quantile(0.95),
        n_unmoved: sorted.iter().take_while(|&&d| d == 0.0).count(),
        histogram,
        bin_width_mm: width,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_and_stats_by_hand() {
        let m = Mesh::new(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2]],
        )
        .unwrap();
        assert!((min_triangle_angle(&m) - 45.0).abs() < 1e-9);
        let s = displacement_stats(&[0.0, 1.0, 2.0, 3.0]);
        assert_eq!(s.max_mm, 3.0);
        assert_eq!(s.mean_mm, 1.5);
        assert!((s.rms_mm - 3.5f64.sqrt()).abs() < 1e-12);
        assert_eq!(s.n_unmoved, 1);
        assert_eq!(s.histogram.iter().sum::<u64>(), 4);
        assert_eq!(s.histogram[HISTOGRAM_BINS - 1], 1);
    }
}
