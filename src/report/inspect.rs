//! The `inspect` report: what a mesh file holds and whether it is fit for smoothing.

use crate::analysis::{voxel_size, AxisSpacing, VoxelSizeEstimate};
use crate::io::{LoadedMesh, SourceFormat};
use crate::mesh::geometry::{area, bounding_box, signed_volume, BoundingBox};
use crate::mesh::Topology;
use crate::metrics::average_normal_curvature;
use crate::weights::Context;
use serde::Serialize;
use std::fmt::Write;
use std::path::Path;

/// Boundary loops listed individually; the count is always complete.
const MAX_LISTED_LOOPS: usize = 100;

/// One boundary loop in the report.
#[derive(Debug, Clone, Serialize)]
pub struct LoopSummary {
    pub n_vertices: usize,
    /// Loop length in mm.
    pub length_mm: f64,
    /// False when the rim runs into a non-manifold vertex and cannot be closed.
    pub closed: bool,
}

/// Everything `destair inspect` reports about one mesh.
#[derive(Debug, Clone, Serialize)]
pub struct InspectReport {
    pub path: String,
    pub format: SourceFormat,
    pub n_vertices: usize,
    pub n_triangles: usize,
    pub n_edges: usize,
    pub bounding_box: Option<BoundingBox>,
    /// Surface area in mm².
    pub area_mm2: f64,
    /// Signed enclosed volume in mm³ (meaningful only for closed meshes; negative = inward normals).
    pub volume_mm3: f64,
    /// Closed, 2-manifold and consistently oriented.
    pub closed_oriented_manifold: bool,
    pub n_boundary_loops: usize,
    pub boundary_loops: Vec<LoopSummary>,
    pub n_non_manifold_edges: usize,
    pub n_non_manifold_vertices: usize,
    /// Edges whose two triangles disagree on orientation.
    pub n_inconsistent_edges: usize,
    pub n_components: usize,
    pub euler_characteristic: i64,
    pub n_unreferenced_vertices: usize,
    pub n_degenerate_triangles: usize,
    /// Mean over vertices of the largest angle between vertex and incident face normals (degrees).
    pub average_normal_curvature_deg: f64,
    /// Grid spacing reconstructed from edge offsets (Bade 2007, §3.2).
    pub voxel_size: VoxelSizeEstimate,
    pub comments: Vec<String>,
    pub warnings: Vec<String>,
}

/// One detected cap in the report.
#[derive(Debug, Clone, Serialize)]
pub struct CapSummary {
    pub n_faces: usize,
    pub area_mm2: f64,
    pub normal: [f32; 3],
    /// Why it is a cap: its extent, and how the wall behind it runs on (a clipped end).
    pub evidence: crate::analysis::CapEvidence,
}

/// Summary statistics of per-vertex weights.
#[derive(Debug, Clone, Serialize)]
pub struct WeightStats {
    pub min: f32,
    pub max: f32,
    pub mean: f64,
    /// Vertices with weight 0 (they will not move).
    pub n_zero: usize,
    /// Vertices with weight 1.
    pub n_one: usize,
}

/// The context analysis (`inspect --context`): axis, staircases, caps, weights.
#[derive(Debug, Clone, Serialize)]
pub struct ContextSummary {
    /// The stack axis used (unit), if any.
    pub axis: Option<[f32; 3]>,
    /// Where the axis came from: "given", "label_map_header", "grid" (the coarse axis of the
    /// voxel grid the mesh lies on), "estimate_on_grid" (the Gauss-map estimate set to the
    /// nearest axis of an isotropic grid), "estimated" (the Gauss-map estimate), "too_weak"
    /// (no grid and too little flat area) or "off".
    pub axis_source: String,
    /// Share of the surface area supporting the Gauss-map estimate (its support).
    pub axis_confidence: Option<f64>,
    /// What the Gauss-map estimate was found from: "terraces" or "small_flat_area" (one flat
    /// area alone in its direction, paper 004 Table 5's weak case).
    pub axis_evidence: Option<crate::analysis::AxisEvidence>,
    /// Support share of the best other direction (at least 10 degrees from the estimate): how
    /// clearly the estimate stands out.
    pub axis_runner_up: Option<f64>,
    /// Angle (degrees) between the estimate and that other direction.
    pub axis_runner_up_deg: Option<f64>,
    /// The voxel size (mm along x, y, z, or along `grid_axes`) of the grid the mesh lies on,
    /// known or reconstructed: one value per axis, or the two it may be (h/2 and h steps not
    /// both seen).
    pub voxel_mm: Option<[Vec<f64>; 3]>,
    /// The grid's unit axes when it is turned off x, y, z (found from the mesh's flat faces).
    pub grid_axes: Option<[[f64; 3]; 3]>,
    /// The Gauss-map estimate, when it found an axis (whether or not it was used).
    pub estimated_axis: Option<[f64; 3]>,
    /// Angle (degrees) between the axis used and the Gauss-map estimate, when the grid gave
    /// the axis; over 5 degrees it is a warning.
    pub estimate_off_deg: Option<f64>,
    pub n_staircase_vertices: usize,
    /// Staircase vertices as a share of all vertices.
    pub staircase_share: f64,
    /// The orientation-change threshold used (absent when no axis was used).
    pub tau: Option<f32>,
    /// Whether `tau = "auto"` chose it.
    pub tau_auto: bool,
    /// False when caps were not looked for (`smooth` with caps smoothed): the counts below are
    /// then 0 and say nothing.
    #[serde(skip)]
    pub caps_searched: bool,
    pub n_flat_regions: usize,
    pub n_terraces: usize,
    /// Caps found only on the smoothed copy (ends clipped obliquely, terraced on the mesh).
    pub n_caps_from_smoothed_copy: usize,
    pub caps: Vec<CapSummary>,
    /// Smallest distance to the reference structures (mm), when references were given.
    pub reference_distance_min_mm: Option<f64>,
    pub weights: WeightStats,
    /// What a user should know, e.g. a clear stack axis with no staircase vertex on it.
    pub warnings: Vec<String>,
}

/// Angle (degrees) between a grid's slice axis and the Gauss-map estimate above which a report
/// warns.
pub const AXIS_DISAGREEMENT_DEG: f64 = 5.0;

/// An estimated axis whose runner-up has at least this share of its support is a warning.
pub const AXIS_CLOSE_RUNNER_UP: f64 = 0.5;

/// Summarises a context analysis.
pub fn context_summary(ctx: &Context, n_vertices: usize) -> ContextSummary {
    use crate::analysis::StackAxis;
    use crate::weights::AxisSource;
    let axis_confidence = match ctx.estimated_axis {
        Some(StackAxis::Found { confidence, .. }) => Some(confidence),
        Some(StackAxis::TooWeak { best_share }) => Some(best_share),
        None => None,
    };
    let (axis_evidence, axis_runner_up, axis_runner_up_deg) = match ctx.estimated_axis {
        Some(StackAxis::Found {
            evidence,
            runner_up,
            runner_up_deg,
            ..
        }) => (Some(evidence), Some(runner_up), Some(runner_up_deg)),
        _ => (None, None, None),
    };
    let axis_source = ctx.axis_source.name();
    let n_staircase_vertices = ctx.staircase.as_ref().map_or(0, |s| s.n_staircase());
    let mut warnings = Vec::new();
    if let (Some(s), Some(a)) = (&ctx.staircase, ctx.axis) {
        if n_staircase_vertices == 0 {
            let how = if s.tau_auto {
                "chosen from this mesh; the surface has no staircase that stands out from its own variation".to_string()
            } else {
                "try tau = \"auto\" for surfaces from smoothed images or smoothed at export"
                    .to_string()
            };
            warnings.push(format!(
                "the stack axis ({:.3}, {:.3}, {:.3}) is clear, but no vertex changes orientation by more than tau = {:.3} ({how}): staircase weighting leaves only the floor beta_min",
                a[0], a[1], a[2], s.tau
            ));
        }
    }
    // On an isotropic grid the estimate only picks an axis: no disagreement to warn about.
    if let (Some(off), Some(a), AxisSource::Grid) =
        (ctx.estimate_off_deg, ctx.axis, ctx.axis_source)
    {
        if off > AXIS_DISAGREEMENT_DEG {
            warnings.push(format!(
                "the voxel grid's slice axis ({:.3}, {:.3}, {:.3}) is used, but the flat faces point {off:.1} degrees away from it (the Gauss-map estimate): the surface may have been edited, or its largest flat parts are not slices",
                a[0], a[1], a[2]
            ));
        }
    }
    // Used as the axis with another direction close behind: a tube along the slices off its
    // grid shows its walls, not slices, and the estimate may be 90 degrees off.
    if let (
        Some(StackAxis::Found {
            confidence,
            runner_up,
            runner_up_deg,
            ..
        }),
        Some(a),
        AxisSource::Estimated,
    ) = (ctx.estimated_axis, ctx.axis, ctx.axis_source)
    {
        if runner_up >= AXIS_CLOSE_RUNNER_UP * confidence {
            warnings.push(format!(
                "the stack axis ({:.3}, {:.3}, {:.3}) is estimated from {:.2} % of the area, but a direction {runner_up_deg:.0} degrees away has {:.2} %: the larger flat parts may be the walls of a structure running along the slices, not slices; give the axis or the voxel size if they are known",
                a[0], a[1], a[2], 100.0 * confidence, 100.0 * runner_up
            ));
        }
    }
    let w = ctx.weights.as_slice();
    let weights = WeightStats {
        min: w.iter().copied().fold(f32::INFINITY, f32::min),
        max: w.iter().copied().fold(f32::NEG_INFINITY, f32::max),
        mean: crate::parallel::deterministic_sum(w.len(), |i| w[i] as f64) / w.len().max(1) as f64,
        n_zero: w.iter().filter(|&&x| x == 0.0).count(),
        n_one: w.iter().filter(|&&x| x == 1.0).count(),
    };
    ContextSummary {
        axis: ctx.axis,
        axis_source: axis_source.to_string(),
        axis_confidence,
        axis_evidence,
        axis_runner_up,
        axis_runner_up_deg,
        voxel_mm: ctx
            .grid_mm
            .map(|g| g.map(|(lo, hi)| if lo == hi { vec![lo] } else { vec![lo, hi] })),
        grid_axes: ctx.grid_axes,
        estimated_axis: ctx.estimated_axis.and_then(|e| e.axis()),
        estimate_off_deg: ctx.estimate_off_deg,
        n_staircase_vertices,
        staircase_share: n_staircase_vertices as f64 / n_vertices.max(1) as f64,
        tau: ctx.staircase.as_ref().map(|s| s.tau),
        tau_auto: ctx.staircase.as_ref().is_some_and(|s| s.tau_auto),
        caps_searched: ctx.caps.searched,
        n_flat_regions: ctx.caps.n_regions,
        n_terraces: ctx.caps.n_terraces,
        n_caps_from_smoothed_copy: ctx.caps.n_from_smoothed_copy,
        caps: ctx
            .caps
            .caps
            .iter()
            .map(|c| CapSummary {
                n_faces: c.faces.len(),
                area_mm2: c.area_mm2,
                normal: c.normal,
                evidence: c.evidence,
            })
            .collect(),
        reference_distance_min_mm: ctx
            .reference_distance_mm
            .as_ref()
            .map(|d| d.iter().copied().fold(f64::INFINITY, f64::min)),
        weights,
        warnings,
    }
}

impl ContextSummary {
    /// The summary as human-readable text.
    pub fn to_text(&self) -> String {
        let mut s = String::from("context\n");
        match (self.axis, self.axis_source.as_str()) {
            (Some(a), src) => {
                let mut conf = self.axis_confidence.map_or(String::new(), |c| {
                    format!(", {:.2} % of the area supports it", 100.0 * c)
                });
                if let (Some(e), Some(r)) = (self.axis_evidence, self.axis_runner_up) {
                    let next = if r > 0.0 {
                        format!("next direction {:.2} %", 100.0 * r)
                    } else {
                        "no other direction".to_string()
                    };
                    let _ = write!(conf, " ({}; {next})", e.describe());
                }
                let _ = writeln!(
                    s,
                    "  stack axis ({src}) ({:.4}, {:.4}, {:.4}){conf}",
                    a[0], a[1], a[2]
                );
                if let (Some(axes), Some(mm)) = (self.grid_axes, &self.voxel_mm) {
                    let along: Vec<String> = (0..3)
                        .map(|k| {
                            let h: Vec<String> = mm[k].iter().map(|h| format!("{h:.4}")).collect();
                            let [x, y, z] = axes[k];
                            format!("{} mm along ({x:.4}, {y:.4}, {z:.4})", h.join(" or "))
                        })
                        .collect();
                    let _ = writeln!(s, "  voxel grid turned off the axes: {}", along.join(", "));
                }
            }
            (None, "too_weak") => {
                let _ = writeln!(s, "  stack axis: no staircases found (best direction has {:.2} % of the area; too weak to call an axis)", 100.0 * self.axis_confidence.unwrap_or(0.0));
            }
            (None, _) => {
                let _ = writeln!(s, "  stack axis: not used");
            }
        }
        let tau = match self.tau {
            Some(t) if self.tau_auto => format!(", tau {t:.3} (auto)"),
            Some(t) => format!(", tau {t:.3}"),
            None => String::new(),
        };
        let _ = writeln!(
            s,
            "  staircase vertices {} ({:.2} %){tau}",
            self.n_staircase_vertices,
            100.0 * self.staircase_share
        );
        if self.caps_searched {
            let _ = writeln!(
                s,
                "  flat regions {} (terraces {}), caps {} ({} found on the smoothed copy)",
                self.n_flat_regions,
                self.n_terraces,
                self.caps.len(),
                self.n_caps_from_smoothed_copy
            );
        } else {
            let _ = writeln!(s, "  caps: not looked for (smoothed like the rest)");
        }
        for c in &self.caps {
            let _ = writeln!(
                s,
                "    cap: {} faces, {:.2} mm², normal ({:.3}, {:.3}, {:.3}): a clipped end {:.1} x {:.1} mm, the wall behind it runs on past {:.1} mm with its cross-section x{:.2} at {:.1} mm, x{:.2} more at {:.1} mm",
                c.n_faces,
                c.area_mm2,
                c.normal[0],
                c.normal[1],
                c.normal[2],
                c.evidence.width_mm,
                c.evidence.length_mm,
                c.evidence.run_depth_mm,
                c.evidence.span,
                0.5 * c.evidence.section_depth_mm,
                c.evidence.growth,
                c.evidence.section_depth_mm,
            );
        }
        if let Some(d) = self.reference_distance_min_mm {
            let _ = writeln!(
                s,
                "  distance to references: {d:.4} mm at the closest vertex"
            );
        }
        let w = &self.weights;
        let _ = writeln!(s, "  weights min {:.3} max {:.3} mean {:.3}; {} vertices fixed (0), {} fully smoothed (1)", w.min, w.max, w.mean, w.n_zero, w.n_one);
        for w in &self.warnings {
            let _ = writeln!(s, "  warning: {w}");
        }
        s
    }
}

/// Builds the inspect report for a loaded mesh.
pub fn inspect(path: &Path, loaded: &LoadedMesh, topology: &Topology) -> InspectReport {
    inspect_but_curvature(path, loaded, topology)
        .with_curvature(average_normal_curvature(&loaded.mesh, topology))
}

/// An inspect report but for the mesh's average normal curvature: what is measured beside a
/// context analysis, which finds that figure on its way
/// ([`Context::average_normal_curvature_deg`](crate::weights::Context)).
pub struct ReportButCurvature(InspectReport);

impl ReportButCurvature {
    /// The report, with the mesh's average normal curvature (degrees).
    pub fn with_curvature(self, average_normal_curvature_deg: f64) -> InspectReport {
        InspectReport {
            average_normal_curvature_deg,
            ..self.0
        }
    }
}

/// [`inspect`] without the average normal curvature, for [`ReportButCurvature::with_curvature`]
/// to complete.
pub fn inspect_but_curvature(
    path: &Path,
    loaded: &LoadedMesh,
    topology: &Topology,
) -> ReportButCurvature {
    let mesh = &loaded.mesh;
    let p = mesh.positions();
    let loops = topology.boundary_loops();
    let boundary_loops = loops
        .iter()
        .take(MAX_LISTED_LOOPS)
        .map(|l| {
            let n = l.vertices.len();
            let segments = if l.closed { n } else { n.saturating_sub(1) };
            let length_mm = (0..segments)
                .map(|i| {
                    let (a, b) = (
                        p[l.vertices[i] as usize],
                        p[l.vertices[(i + 1) % n] as usize],
                    );
                    (0..3)
                        .map(|k| (a[k] as f64 - b[k] as f64).powi(2))
                        .sum::<f64>()
                        .sqrt()
                })
                .sum();
            LoopSummary {
                n_vertices: n,
                length_mm,
                closed: l.closed,
            }
        })
        .collect();
    ReportButCurvature(InspectReport {
        path: path.display().to_string(),
        format: loaded.format,
        n_vertices: mesh.n_vertices(),
        n_triangles: mesh.n_triangles(),
        n_edges: topology.n_edges(),
        bounding_box: bounding_box(mesh),
        area_mm2: area(mesh),
        volume_mm3: signed_volume(mesh),
        closed_oriented_manifold: topology.is_closed_oriented_manifold(),
        n_boundary_loops: loops.len(),
        boundary_loops,
        n_non_manifold_edges: topology.non_manifold_edges().len(),
        n_non_manifold_vertices: topology.non_manifold_vertices().len(),
        n_inconsistent_edges: topology.inconsistent_edges().len(),
        n_components: topology.n_components(),
        euler_characteristic: topology.euler_characteristic(),
        n_unreferenced_vertices: topology.unreferenced_vertices().len(),
        n_degenerate_triangles: topology.degenerate_triangles().len(),
        average_normal_curvature_deg: 0.0,
        voxel_size: voxel_size(mesh, topology),
        comments: loaded.meta.comments.clone(),
        warnings: loaded.warnings.clone(),
    })
}

impl InspectReport {
    /// The report as human-readable text.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "{} ({})", self.path, self.format);
        let _ = writeln!(
            s,
            "  vertices {}  triangles {}  edges {}",
            self.n_vertices, self.n_triangles, self.n_edges
        );
        if let Some(b) = &self.bounding_box {
            let e = b.extent();
            let _ = writeln!(
                s,
                "  bounding box  min ({:.3}, {:.3}, {:.3})  max ({:.3}, {:.3}, {:.3})  size {:.3} x {:.3} x {:.3} mm",
                b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2], e[0], e[1], e[2]
            );
        }
        let _ = writeln!(s, "  area {:.3} mm²", self.area_mm2);
        let closed_note = if self.n_boundary_loops > 0 {
            " (open mesh: depends on how the holes are closed)"
        } else if self.volume_mm3 < 0.0 {
            " (negative: normals point inward)"
        } else {
            ""
        };
        let _ = writeln!(s, "  volume {:.3} mm³{closed_note}", self.volume_mm3);
        let _ = writeln!(
            s,
            "  components {}  Euler characteristic {}  closed oriented 2-manifold: {}",
            self.n_components,
            self.euler_characteristic,
            if self.closed_oriented_manifold {
                "yes"
            } else {
                "no"
            }
        );
        let _ = writeln!(s, "  boundary loops {}", self.n_boundary_loops);
        for l in &self.boundary_loops {
            let _ = writeln!(
                s,
                "    {} vertices, {:.3} mm{}",
                l.n_vertices,
                l.length_mm,
                if l.closed { "" } else { " (open chain)" }
            );
        }
        if self.n_boundary_loops > self.boundary_loops.len() {
            let _ = writeln!(
                s,
                "    ... {} more",
                self.n_boundary_loops - self.boundary_loops.len()
            );
        }
        let findings = [
            (self.n_non_manifold_edges, "non-manifold edges"),
            (self.n_non_manifold_vertices, "non-manifold vertices"),
            (
                self.n_inconsistent_edges,
                "edges with inconsistent orientation",
            ),
            (self.n_unreferenced_vertices, "unreferenced vertices (kept)"),
            (
                self.n_degenerate_triangles,
                "degenerate triangles (repeated vertex)",
            ),
        ];
        for (n, what) in findings {
            if n > 0 {
                let _ = writeln!(s, "  {n} {what}");
            }
        }
        let _ = writeln!(
            s,
            "  average normal curvature {:.3} degrees",
            self.average_normal_curvature_deg
        );
        let _ = writeln!(s, "  voxel size {}", describe_voxel_size(&self.voxel_size));
        for c in &self.comments {
            let _ = writeln!(s, "  comment: {c}");
        }
        for w in &self.warnings {
            let _ = writeln!(s, "  warning: {w}");
        }
        s
    }
}

/// The voxel-size reconstruction in words: the spacing, or why it cannot be had (Bade 2007 §3.2).
pub fn describe_voxel_size(v: &VoxelSizeEstimate) -> String {
    if let Some([x, y, z]) = v.spacing() {
        return format!("{x:.4} x {y:.4} x {z:.4} mm");
    }
    let axis = |a: &AxisSpacing| match a {
        AxisSpacing::Spacing { mm } => format!("{mm:.4} mm"),
        AxisSpacing::OneStep { mm } => format!("{mm:.4} or {:.4} mm (ambiguous)", 2.0 * mm),
        AxisSpacing::NoSteps => "none (flat)".into(),
        AxisSpacing::Irregular { .. } => "irregular".into(),
    };
    let detail = format!(
        "x {}, y {}, z {}",
        axis(&v.axes[0]),
        axis(&v.axes[1]),
        axis(&v.axes[2])
    );
    if v.is_irregular() {
        format!("not reconstructable: the mesh is not a marching-cubes surface on an axis-aligned grid ({detail})")
    } else {
        format!("partly reconstructable: {detail}")
    }
}

/// The patch table of `inspect --patches`: one line per patch, then the wall.
pub fn patches_text(p: &crate::cfd::Patches) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "  patches {} (CellEntityIds: wall 1, patches from 2)",
        p.patches.len()
    );
    for patch in &p.patches {
        let c = patch.centre_mm;
        let n = patch.normal;
        let kind = match patch.kind {
            crate::cfd::PatchKind::Cap => "cap",
            crate::cfd::PatchKind::OpenEnd => "open end",
            crate::cfd::PatchKind::ClosedEnd => "closed end",
        };
        let _ = writeln!(
            out,
            "    {} {:<10} {kind}: centre ({:.3}, {:.3}, {:.3}) mm, normal ({:.3}, {:.3}, {:.3}), {:.3} mm², diameter {:.3} mm, off-plane {:.2e} mm",
            patch.id, patch.name, c[0], c[1], c[2], n[0], n[1], n[2], patch.area_mm2, patch.diameter_mm, patch.planarity_mm
        );
    }
    let _ = writeln!(out, "    1 wall       {} faces", p.wall_faces);
    out
}
