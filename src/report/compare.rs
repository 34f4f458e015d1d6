//! The `compare` report: what smoothing did to a mesh, in the papers' measures.

use crate::analysis::voxel_size;
use crate::mesh::{Mesh, Topology};
use crate::metrics::{
    average_normal_curvature, displacement_stats, displacements, enclosed_volume,
    min_triangle_angle, minimum_distance, surface_distance, DisplacementStats, SurfaceDistance,
};
use crate::spatial::TriangleBvh;
use serde::Serialize;
use std::fmt::Write;

/// Minimum distance to one reference structure before and after.
#[derive(Debug, Clone, Serialize)]
pub struct ReferenceDistance {
    pub name: String,
    pub before_mm: f64,
    pub after_mm: f64,
    pub change_mm: f64,
}

/// Everything `destair compare` reports.
#[derive(Debug, Clone, Serialize)]
pub struct CompareReport {
    pub n_vertices_original: usize,
    pub n_vertices_smoothed: usize,
    /// Hausdorff and mean minimum distances between the two surfaces.
    pub distance: SurfaceDistance,
    pub volume_original_mm3: f64,
    pub volume_smoothed_mm3: f64,
    /// Smoothed volume in % of the original.
    pub volume_percent: f64,
    /// Boundary loops closed by centroid fans to compute the volumes.
    pub loops_closed_by_fans: usize,
    pub normal_curvature_original_deg: f64,
    pub normal_curvature_smoothed_deg: f64,
    pub min_triangle_angle_original_deg: f64,
    pub min_triangle_angle_smoothed_deg: f64,
    /// Per-vertex displacement, when both meshes have the same vertices and triangles.
    pub displacement: Option<DisplacementStats>,
    /// Voxel size (given, or reconstructed from the original), mm.
    pub voxel_size_mm: Option<[f64; 3]>,
    /// Hausdorff distance as a fraction of the voxel diagonal (Bade 2007's maxD).
    pub max_d_voxel_diagonals: Option<f64>,
    pub references: Vec<ReferenceDistance>,
}

/// Compares a smoothed mesh with its original (and with reference structures).
pub fn compare(
    original: &Mesh,
    smoothed: &Mesh,
    references: &[(String, Mesh)],
    voxel: Option<[f64; 3]>,
) -> CompareReport {
    let trees: Vec<TriangleBvh> = references
        .iter()
        .map(|(_, m)| TriangleBvh::build(m))
        .collect();
    let refs: Vec<(&str, &Mesh, &TriangleBvh)> = references
        .iter()
        .zip(&trees)
        .map(|((n, m), g)| (n.as_str(), m, g))
        .collect();
    compare_measured(original, None, None, smoothed, &refs, voxel)
}

/// [`compare`] reusing what the caller already has: the original's topology (topology depends
/// only on the triangles, so it also serves a smoothed mesh with the same triangles), the
/// original's average normal curvature when a context analysis found it (degrees:
/// [`Context::average_normal_curvature_deg`](crate::weights::Context), the same bits as
/// measuring it here) and the references' hierarchies.
pub fn compare_prepared(
    original: &Mesh,
    topo_o: &Topology,
    original_curvature_deg: Option<f64>,
    smoothed: &Mesh,
    references: &[(&str, &Mesh, &TriangleBvh)],
    voxel: Option<[f64; 3]>,
) -> CompareReport {
    compare_measured(
        original,
        Some(topo_o),
        original_curvature_deg,
        smoothed,
        references,
        voxel,
    )
}

/// The measures a report is made of, one pair per mesh.
struct MeshMeasures {
    volume_mm3: [f64; 2],
    loops_closed_by_fans: usize,
    normal_curvature_deg: [f64; 2],
    min_triangle_angle_deg: [f64; 2],
    voxel_size_mm: Option<[f64; 3]>,
    displacement: Option<DisplacementStats>,
}

/// [`compare_prepared`], building the original's topology when none is given. The distances
/// (hierarchies and queries) and the measures of each mesh on its own (volume, curvature,
/// angles, voxel size) and of the pair (displacements) run side by side: each has serial
/// stretches the other fills.
fn compare_measured(
    original: &Mesh,
    topo_o: Option<&Topology>,
    original_curvature_deg: Option<f64>,
    smoothed: &Mesh,
    references: &[(&str, &Mesh, &TriangleBvh)],
    voxel: Option<[f64; 3]>,
) -> CompareReport {
    let same_vertices = original.n_vertices() == smoothed.n_vertices()
        && original.triangles() == smoothed.triangles();
    let ((distance, references), measures) = rayon::join(
        || {
            let (tree_o, tree_s) = rayon::join(
                || TriangleBvh::build(original),
                || TriangleBvh::build(smoothed),
            );
            let distance = surface_distance(original, &tree_o, smoothed, &tree_s);
            let references: Vec<ReferenceDistance> = references
                .iter()
                .map(|&(name, r, tree_r)| {
                    let before_mm = minimum_distance(original, &tree_o, r, tree_r);
                    let after_mm = minimum_distance(smoothed, &tree_s, r, tree_r);
                    ReferenceDistance {
                        name: name.to_string(),
                        before_mm,
                        after_mm,
                        change_mm: after_mm - before_mm,
                    }
                })
                .collect();
            (distance, references)
        },
        || {
            let built;
            let topo_o = match topo_o {
                Some(t) => t,
                None => {
                    built = Topology::build(original);
                    &built
                }
            };
            let rebuilt;
            let topo_s = if same_vertices {
                topo_o
            } else {
                rebuilt = Topology::build(smoothed);
                &rebuilt
            };
            let vol_o = enclosed_volume(original, topo_o);
            let vol_s = enclosed_volume(smoothed, topo_s);
            MeshMeasures {
                volume_mm3: [vol_o.mm3, vol_s.mm3],
                loops_closed_by_fans: vol_o.loops_closed_by_fans.max(vol_s.loops_closed_by_fans),
                normal_curvature_deg: [
                    original_curvature_deg
                        .unwrap_or_else(|| average_normal_curvature(original, topo_o)),
                    average_normal_curvature(smoothed, topo_s),
                ],
                min_triangle_angle_deg: [
                    min_triangle_angle(original),
                    min_triangle_angle(smoothed),
                ],
                voxel_size_mm: voxel.or_else(|| voxel_size(original, topo_o).spacing()),
                displacement: same_vertices.then(|| {
                    displacement_stats(&displacements(original.positions(), smoothed.positions()))
                }),
            }
        },
    );
    let displacement = measures.displacement;
    let voxel_size_mm = measures.voxel_size_mm;
    let max_d_voxel_diagonals = voxel_size_mm
        .map(|h| distance.hausdorff_mm / (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt());
    let [vol_o, vol_s] = measures.volume_mm3;
    CompareReport {
        n_vertices_original: original.n_vertices(),
        n_vertices_smoothed: smoothed.n_vertices(),
        distance,
        volume_original_mm3: vol_o,
        volume_smoothed_mm3: vol_s,
        volume_percent: if vol_o != 0.0 {
            100.0 * vol_s / vol_o
        } else {
            f64::NAN
        },
        loops_closed_by_fans: measures.loops_closed_by_fans,
        normal_curvature_original_deg: measures.normal_curvature_deg[0],
        normal_curvature_smoothed_deg: measures.normal_curvature_deg[1],
        min_triangle_angle_original_deg: measures.min_triangle_angle_deg[0],
        min_triangle_angle_smoothed_deg: measures.min_triangle_angle_deg[1],
        displacement,
        voxel_size_mm,
        max_d_voxel_diagonals,
        references,
    }
}

impl CompareReport {
    /// The report as human-readable text.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let d = &self.distance;
        let _ = writeln!(
            s,
            "Hausdorff distance      {:.4} mm (original->smoothed {:.4}, smoothed->original {:.4})",
            d.hausdorff_mm, d.a_to_b_max_mm, d.b_to_a_max_mm
        );
        let _ = writeln!(
            s,
            "mean min distance       {:.4} mm (original->smoothed {:.4}, smoothed->original {:.4})",
            d.mean_mm, d.a_to_b_mean_mm, d.b_to_a_mean_mm
        );
        if let Some(m) = self.max_d_voxel_diagonals {
            let _ = writeln!(s, "maxD                    {m:.3} voxel diagonals");
        }
        let fans = if self.loops_closed_by_fans > 0 {
            format!(
                " ({} open boundary loops closed by centroid fans)",
                self.loops_closed_by_fans
            )
        } else {
            String::new()
        };
        let _ = writeln!(
            s,
            "volume                  {:.3} -> {:.3} mm³ ({:.2} %){fans}",
            self.volume_original_mm3, self.volume_smoothed_mm3, self.volume_percent
        );
        let _ = writeln!(
            s,
            "avg. normal curvature   {:.3} -> {:.3} degrees",
            self.normal_curvature_original_deg, self.normal_curvature_smoothed_deg
        );
        let _ = writeln!(
            s,
            "min. triangle angle     {:.3} -> {:.3} degrees",
            self.min_triangle_angle_original_deg, self.min_triangle_angle_smoothed_deg
        );
        if let Some(dp) = &self.displacement {
            let _ = writeln!(s, "displacement            mean {:.4}  rms {:.4}  median {:.4}  p95 {:.4}  max {:.4} mm; {} vertices unmoved", dp.mean_mm, dp.rms_mm, dp.median_mm, dp.p95_mm, dp.max_mm, dp.n_unmoved);
            let peak = dp.histogram.iter().copied().max().unwrap_or(1).max(1);
            for (i, &c) in dp.histogram.iter().enumerate() {
                let bar = "#".repeat((40 * c / peak) as usize);
                let _ = writeln!(
                    s,
                    "  {:>8.4}-{:<8.4} {c:>9} {bar}",
                    i as f64 * dp.bin_width_mm,
                    (i + 1) as f64 * dp.bin_width_mm
                );
            }
        }
        for r in &self.references {
            let _ = writeln!(
                s,
                "distance to {:<12} {:.4} -> {:.4} mm (change {:+.4})",
                r.name, r.before_mm, r.after_mm, r.change_mm
            );
        }
        s
    }
}
