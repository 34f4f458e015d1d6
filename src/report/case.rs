//! The per-case report: `report.json` (versioned schema, deterministic: the same inputs and
//! configuration give the same bytes) and a human-readable `report.md`. Timings, which differ
//! run to run, go to `timings.json` instead.

use crate::cfd::rims::RimSmoothing;
use crate::cfd::{PatchKind, Patches, RemeshSummary, SurfaceChecks};
use crate::guard::PairTable;
use crate::report::compare::CompareReport;
use crate::report::inspect::ContextSummary;
use crate::report::label_map::{LabelMapInfo, LabelSource};
use crate::smooth::{Method, SmoothStats};
use serde::Serialize;
use std::fmt::Write;

/// Version of the report.json layout; bumped when fields change meaning.
pub const SCHEMA_VERSION: u32 = 1;

/// One input file of a case.
#[derive(Debug, Clone, Serialize)]
pub struct InputInfo {
    pub structure: String,
    pub file: String,
    pub bytes: u64,
    /// BLAKE3 hash of the file's bytes (hex).
    pub blake3: String,
}

/// What happened to one structure.
#[derive(Debug, Clone, Serialize)]
pub struct StructureReport {
    pub name: String,
    /// "ok", "skipped" (copied unchanged) or "failed".
    pub status: String,
    pub error: Option<String>,
    /// The effective settings, as the runner resolved them (its `StructureSettings`).
    pub settings: serde_json::Value,
    pub n_vertices: usize,
    pub n_triangles: usize,
    /// The smoother with every parameter as used (voxel size included).
    pub method: Option<Method>,
    pub smooth: Option<SmoothStats>,
    pub context: Option<ContextSummary>,
    /// Metrics before and after, including the distance to each reference.
    pub metrics: Option<CompareReport>,
    /// Output files written for this structure (names within the case folder).
    pub outputs: Vec<String>,
    pub warnings: Vec<String>,
    /// The label map and label this structure was extracted from (absent for mesh files).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<LabelSource>,
    /// What the cfd profile made of the structure (absent without `profile = "cfd"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cfd: Option<CfdReport>,
    /// The structure's picture sheet (a file in the case folder), when pictures are on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub picture: Option<crate::report::pictures::PictureInfo>,
    /// How far vertices moved from the input to the output (mm).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub displacement_histogram: Option<crate::report::pictures::Histogram>,
}

/// The surface the cfd profile handed over: its size, patch table, checks and quality figures.
#[derive(Debug, Clone, Serialize)]
pub struct CfdReport {
    pub n_vertices: usize,
    pub n_triangles: usize,
    /// The patches measured on the final surface (ids are its `CellEntityIds`).
    pub patches: Patches,
    pub checks: SurfaceChecks,
    /// How far the rims moved when smoothed in their planes (absent with `keep_rims`).
    pub rims: Option<RimSmoothing>,
    /// Remeshing counts and the distance it moved the surface, when remeshed.
    pub remeshed: Option<RemeshSummary>,
}

impl CfdReport {
    /// The patch table and quality figures as Markdown.
    fn to_markdown(&self, name: &str) -> String {
        let mut s = format!(
            "\n`{name}` (cfd profile): {} vertices, {} triangles; checks passed: watertight{}, oriented, no self-intersection, no degenerate face\n\n",
            self.n_vertices,
            self.n_triangles,
            if self.checks.open_ends_allowed { " but for the open ends" } else { "" }
        );
        s.push_str("| id | patch | kind | centre (mm) | normal | area (mm²) | diameter (mm) | off-plane (mm) | extension (mm) |\n|---|---|---|---|---|---|---|---|---|\n");
        for p in &self.patches.patches {
            let (c, n) = (p.centre_mm, p.normal);
            let kind = match p.kind {
                PatchKind::Cap => "cap",
                PatchKind::OpenEnd => "open end",
                PatchKind::ClosedEnd => "closed end",
            };
            let _ = writeln!(
                s,
                "| {} | {} | {kind} | {:.3}, {:.3}, {:.3} | {:.3}, {:.3}, {:.3} | {:.3} | {:.3} | {:.1e} | {:.2} |",
                p.id, p.name, c[0], c[1], c[2], n[0], n[1], n[2], p.area_mm2, p.diameter_mm, p.planarity_mm, p.extension_mm
            );
        }
        let _ = writeln!(s, "| 1 | wall | wall | | | | | | |");
        let q = &self.checks.quality;
        let _ = write!(
            s,
            "\nangles: min {:.1} deg, 1st percentile {:.1} deg",
            q.min_angle_deg, q.p1_angle_deg
        );
        if let Some(e) = &self.checks.edges {
            let _ = write!(
                s,
                "; edges {:.3}-{:.3} mm (mean {:.3}), {:.1} % within 20 % of the target",
                e.min_mm,
                e.max_mm,
                e.mean_mm,
                100.0 * e.within_20_percent
            );
        }
        if let Some(r) = &self.rims {
            let _ = write!(
                s,
                "; rims smoothed in their planes by {:.4} mm at most",
                r.max_moved_mm
            );
            if !r.kept.is_empty() {
                let _ = write!(s, " (kept as they were at patches {:?})", r.kept);
            }
        }
        if let Some(r) = &self.remeshed {
            let _ = write!(
                s,
                "; remeshing moved the surface by {:.4} mm at most ({:.4} mm mean)",
                r.hausdorff_mm, r.mean_distance_mm
            );
        }
        if let Some(n) = &self.checks.narrowing {
            let _ = write!(
                s,
                "; narrowest lumen {:.3} -> {:.3} mm",
                n.before_mm, n.after_mm
            );
        }
        s.push('\n');
        s
    }
}

/// Everything about one case.
#[derive(Debug, Clone, Serialize)]
pub struct CaseReport {
    pub schema_version: u32,
    pub case: String,
    /// "ok" or "failed" (some structure failed or the case could not be read).
    pub status: String,
    /// Mesh files read.
    pub inputs: Vec<InputInfo>,
    /// Label maps read, with the structure each label became.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub label_maps: Vec<LabelMapInfo>,
    pub structures: Vec<StructureReport>,
    /// Every near pair of structures before and after, and self-intersections (absent when
    /// no structure was processed).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub guard: Option<PairTable>,
    pub warnings: Vec<String>,
    pub errors: Vec<String>,
}

impl CaseReport {
    /// The report as Markdown.
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "# destair report: case `{}`\n\nstatus: **{}**\n\n",
            self.case, self.status
        );
        for e in &self.errors {
            let _ = writeln!(s, "- error: {e}");
        }
        for w in &self.warnings {
            let _ = writeln!(s, "- warning: {w}");
        }
        for m in &self.label_maps {
            let sp = m.spacing_mm;
            let _ = writeln!(
                s,
                "- label map `{}`: {} x {} x {} voxels of {:.4} x {:.4} x {:.4} mm, {} label(s), surfaces in {}",
                m.file,
                m.dims[0],
                m.dims[1],
                m.dims[2],
                sp[0],
                sp[1],
                sp[2],
                m.labels.len(),
                m.space.tag()
            );
        }
        s.push_str("\n| structure | status | method | vertices | Hausdorff (mm) | mean dist. (mm) | volume (%) | curvature (deg) | caps | staircase share |\n|---|---|---|---|---|---|---|---|---|---|\n");
        for st in &self.structures {
            let m = st.metrics.as_ref();
            let num =
                |v: Option<f64>, digits: usize| v.map_or("-".into(), |x| format!("{x:.digits$}"));
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                st.name,
                st.status,
                st.method.map_or("-", |m| m.name()),
                st.n_vertices,
                num(m.map(|m| m.distance.hausdorff_mm), 4),
                num(m.map(|m| m.distance.mean_mm), 4),
                num(m.map(|m| m.volume_percent), 2),
                m.map_or("-".into(), |m| format!(
                    "{:.2} -> {:.2}",
                    m.normal_curvature_original_deg, m.normal_curvature_smoothed_deg
                )),
                st.context
                    .as_ref()
                    .map_or("-".into(), |c| c.caps.len().to_string()),
                st.context.as_ref().map_or("-".into(), |c| format!(
                    "{:.2} %",
                    100.0 * c.staircase_share
                )),
            );
        }
        for st in &self.structures {
            if let Some(e) = &st.error {
                let _ = writeln!(s, "\n`{}` failed: {e}", st.name);
            }
            if let Some(m) = &st.metrics {
                for r in &m.references {
                    let _ = writeln!(
                        s,
                        "\n`{}`: distance to `{}` {:.4} -> {:.4} mm ({:+.4})",
                        st.name, r.name, r.before_mm, r.after_mm, r.change_mm
                    );
                }
            }
            if let Some(src) = &st.source {
                let v = src.voxel_mm;
                let _ = writeln!(
                    s,
                    "\n`{}`: label {} of `{}` ({} voxels, {:.1} mm³), grid voxel {:.4} x {:.4} x {:.4} mm; voxel size and stack axis from {}",
                    st.name,
                    src.label,
                    src.label_map,
                    src.n_voxels,
                    src.voxel_volume_mm3,
                    v[0],
                    v[1],
                    v[2],
                    src.geometry
                );
                let e = &src.extraction;
                let how = match e.sigma_mm {
                    Some(sigma) => format!(
                        "constrained (sigma {sigma:.3} mm, noise {}, thin {}): {} noise voxels relaxed ({} left pinned), {} thin voxels protected; metrics measure the change from the binary extraction",
                        e.noise.map_or("", |n| n.name()),
                        e.thin.map_or("", |t| t.name()),
                        e.counts.noise_voxels,
                        e.counts.noise_unsolved,
                        e.counts.thin_voxels
                    ),
                    None => "binary (vertices at cell-edge midpoints)".into(),
                };
                let _ = writeln!(s, "\n`{}`: surface {how}", st.name);
            }
            if let Some(c) = &st.cfd {
                s.push_str(&c.to_markdown(&st.name));
            }
            for w in &st.warnings {
                let _ = writeln!(s, "\n`{}`: {w}", st.name);
            }
        }
        if let Some(g) = &self.guard {
            s.push_str(&guard_markdown(g));
        }
        s
    }
}

/// The pair table as Markdown.
fn guard_markdown(g: &PairTable) -> String {
    let mut s = String::from("\n## Structures near each other\n\n");
    if g.pairs.is_empty() {
        s.push_str("No two structures come within 10 mm of each other.\n");
    } else {
        s.push_str("| pair | min. distance before (mm) | after (mm) | change (mm) | contact before | contact after |\n|---|---|---|---|---|---|\n");
        for p in &g.pairs {
            let contact = |c: bool, new: bool| match (c, new) {
                (false, _) => "no",
                (true, true) => "**new**",
                (true, false) => "yes",
            };
            // A pair that touched before is not measured after.
            let (after, change, contact_after) = match (p.min_distance_after_mm, p.contact_after) {
                (Some(d), Some(c)) => (
                    format!("{d:.4}"),
                    format!("{:+.4}", p.change_mm),
                    contact(c, p.new_contact),
                ),
                _ => ("-".into(), "-".into(), "(touched before)"),
            };
            let _ = writeln!(
                s,
                "| `{}` - `{}` | {:.4} | {after} | {change} | {} | {contact_after} |",
                p.a,
                p.b,
                p.min_distance_before_mm,
                contact(p.contact_before, false),
            );
        }
    }
    if g.n_far_pairs > 0 {
        let _ = writeln!(
            s,
            "\n{} pair(s) further than 10 mm apart are not measured.",
            g.n_far_pairs
        );
    }
    if g.repair_rounds > 0 {
        let held: Vec<String> = g
            .held
            .iter()
            .map(|h| format!("`{}` {}", h.structure, h.n_vertices))
            .collect();
        let _ = writeln!(
            s,
            "\nThe guard repaired in {} round(s), holding vertices in place: {}.",
            g.repair_rounds,
            held.join(", ")
        );
    }
    for v in &g.violations {
        let _ = writeln!(s, "\n- **guard failed**: {v}");
    }
    let crossing: Vec<String> = g
        .structures
        .iter()
        .filter(|r| r.self_intersections_before + r.self_intersections_after > 0)
        .map(|r| {
            format!(
                "`{}` {} -> {}",
                r.structure, r.self_intersections_before, r.self_intersections_after
            )
        })
        .collect();
    if crossing.is_empty() {
        s.push_str("\nNo structure intersects itself, before or after.\n");
    } else {
        let _ = writeln!(
            s,
            "\nSelf-intersecting triangle pairs (before -> after): {}",
            crossing.join(", ")
        );
    }
    s
}
