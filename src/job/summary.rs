//! The cohort summary: one row per case and structure, built from the per-case `report.json`
//! files (so `destair summarize` can rebuild it from any set of output folders, e.g. shards),
//! written as `summary.csv` and `summary.json`.

use crate::io::write_atomically;
use serde::Serialize;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One row of the summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SummaryRow {
    pub case: String,
    pub structure: String,
    pub status: String,
    pub method: String,
    pub n_vertices: u64,
    pub hausdorff_mm: Option<f64>,
    pub mean_distance_mm: Option<f64>,
    pub volume_percent: Option<f64>,
    pub curvature_before_deg: Option<f64>,
    pub curvature_after_deg: Option<f64>,
    pub max_d_voxel_diagonals: Option<f64>,
    /// Smallest distance to any reference before and after (mm).
    pub reference_distance_before_mm: Option<f64>,
    pub reference_distance_after_mm: Option<f64>,
    pub staircase_share: Option<f64>,
    pub n_caps: Option<u64>,
    /// cfd profile: the patches as "id name diameter" (mm), inlet first.
    pub patches: String,
    /// cfd profile: smallest triangle angle of the surface handed over (degrees).
    pub min_angle_deg: Option<f64>,
    /// cfd profile: share of edges within 20 % of the remeshing target (0..1).
    pub edges_within_20_percent: Option<f64>,
    /// cfd profile: Hausdorff distance remeshing moved the surface (mm).
    pub remesh_hausdorff_mm: Option<f64>,
    /// cfd profile: narrowest lumen after / before smoothing.
    pub lumen_ratio: Option<f64>,
    /// Most negative change of the minimum distance to any structure near this one (mm; the
    /// case's pair table); the case's worst is the smallest over its rows.
    pub gap_change_mm: Option<f64>,
    /// Structures this one touches after smoothing and did not before.
    pub new_contacts: Option<u64>,
    pub error: String,
    /// The structure's picture sheet (not in summary.csv).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub picture: Option<crate::report::pictures::PictureInfo>,
    /// Folder of the case's report.json (for links; not written).
    #[serde(skip)]
    pub report_dir: PathBuf,
}

/// The summary of a set of cases.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Summary {
    pub n_cases: usize,
    pub n_ok: usize,
    pub failed: Vec<String>,
    /// Cases expected (from the config) but without a report.
    pub missing: Vec<String>,
    /// Cases with more than one report among the folders given.
    pub duplicates: Vec<String>,
    /// Reports of cases the config no longer finds (left out of the rows and counts).
    pub not_in_cohort: Vec<String>,
    /// Folders that look like cases but hold no mesh, with the reason.
    pub skipped_folders: Vec<String>,
    /// Structures with several files, as "case: name (file, file)".
    pub duplicate_structures: Vec<String>,
    pub rows: Vec<SummaryRow>,
}

/// What discovery found besides the cases, for the summary.
#[derive(Debug, Clone, Default)]
pub struct CohortNotes {
    pub skipped_folders: Vec<String>,
    pub duplicate_structures: Vec<String>,
}

impl CohortNotes {
    /// The notes of a discovery.
    pub fn of(found: &crate::job::Discovery) -> CohortNotes {
        CohortNotes {
            skipped_folders: found.skipped_folders.clone(),
            duplicate_structures: found
                .cases
                .iter()
                .flat_map(|c| c.duplicates.iter().map(move |d| format!("{}: {d}", c.id)))
                .collect(),
        }
    }

    /// Puts the notes into a summary.
    pub fn apply(&self, summary: &mut Summary) {
        summary.skipped_folders = self.skipped_folders.clone();
        summary.duplicate_structures = self.duplicate_structures.clone();
    }
}

/// Rows of one report.json.
pub fn rows_of(report: &Value) -> Vec<SummaryRow> {
    let case = report["case"].as_str().unwrap_or("").to_string();
    let structures = report["structures"].as_array().cloned().unwrap_or_default();
    if structures.is_empty() {
        let error = report["errors"]
            .as_array()
            .map(|e| {
                e.iter()
                    .filter_map(Value::as_str)
                    .collect::<Vec<_>>()
                    .join("; ")
            })
            .unwrap_or_default();
        return vec![SummaryRow {
            case,
            structure: String::new(),
            status: report["status"].as_str().unwrap_or("failed").to_string(),
            method: String::new(),
            n_vertices: 0,
            hausdorff_mm: None,
            mean_distance_mm: None,
            volume_percent: None,
            curvature_before_deg: None,
            curvature_after_deg: None,
            max_d_voxel_diagonals: None,
            reference_distance_before_mm: None,
            reference_distance_after_mm: None,
            staircase_share: None,
            n_caps: None,
            patches: String::new(),
            min_angle_deg: None,
            edges_within_20_percent: None,
            remesh_hausdorff_mm: None,
            lumen_ratio: None,
            gap_change_mm: None,
            new_contacts: None,
            error,
            picture: None,
            report_dir: PathBuf::new(),
        }];
    }
    let pairs = report["guard"]["pairs"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    structures
        .iter()
        .map(|s| {
            let m = &s["metrics"];
            let refs = m["references"].as_array().cloned().unwrap_or_default();
            let min_of = |key: &str| refs.iter().filter_map(|r| r[key].as_f64()).reduce(f64::min);
            let cfd = &s["cfd"];
            let patches: Vec<String> = cfd["patches"]["patches"]
                .as_array()
                .map(|ps| {
                    ps.iter()
                        .map(|p| {
                            format!(
                                "{} {} {:.3} mm",
                                p["id"].as_u64().unwrap_or(0),
                                p["name"].as_str().unwrap_or(""),
                                p["diameter_mm"].as_f64().unwrap_or(f64::NAN)
                            )
                        })
                        .collect()
                })
                .unwrap_or_default();
            let name = s["name"].as_str().unwrap_or("");
            let mine: Vec<&Value> = pairs
                .iter()
                .filter(|p| p["a"].as_str() == Some(name) || p["b"].as_str() == Some(name))
                .collect();
            SummaryRow {
                case: case.clone(),
                structure: name.to_string(),
                status: s["status"].as_str().unwrap_or("").to_string(),
                method: s["method"]["method"].as_str().unwrap_or("").to_string(),
                n_vertices: s["n_vertices"].as_u64().unwrap_or(0),
                hausdorff_mm: m["distance"]["hausdorff_mm"].as_f64(),
                mean_distance_mm: m["distance"]["mean_mm"].as_f64(),
                volume_percent: m["volume_percent"].as_f64(),
                curvature_before_deg: m["normal_curvature_original_deg"].as_f64(),
                curvature_after_deg: m["normal_curvature_smoothed_deg"].as_f64(),
                max_d_voxel_diagonals: m["max_d_voxel_diagonals"].as_f64(),
                reference_distance_before_mm: min_of("before_mm"),
                reference_distance_after_mm: min_of("after_mm"),
                staircase_share: s["context"]["staircase_share"].as_f64(),
                n_caps: s["context"]["caps"].as_array().map(|c| c.len() as u64),
                patches: patches.join(", "),
                min_angle_deg: cfd["checks"]["quality"]["min_angle_deg"].as_f64(),
                edges_within_20_percent: cfd["checks"]["edges"]["within_20_percent"].as_f64(),
                remesh_hausdorff_mm: cfd["remeshed"]["hausdorff_mm"].as_f64(),
                lumen_ratio: cfd["checks"]["narrowing"]["ratio"].as_f64(),
                gap_change_mm: mine
                    .iter()
                    .filter_map(|p| p["change_mm"].as_f64())
                    .reduce(f64::min),
                new_contacts: report["guard"].is_object().then(|| {
                    mine.iter()
                        .filter(|p| p["new_contact"].as_bool() == Some(true))
                        .count() as u64
                }),
                error: s["error"].as_str().unwrap_or("").to_string(),
                picture: serde_json::from_value(s["picture"].clone()).ok(),
                report_dir: PathBuf::new(),
            }
        })
        .collect()
}

/// A case's summary rows, read from its report.json (the report itself is not kept, so
/// memory follows the number of rows, not the size of the reports).
#[derive(Debug, Clone)]
pub struct CaseRows {
    pub id: String,
    pub ok: bool,
    pub rows: Vec<SummaryRow>,
    pub path: PathBuf,
}

/// Reads one report.json into summary rows.
pub fn read_case_rows(path: &Path) -> Result<CaseRows, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let v: Value =
        serde_json::from_slice(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    if !v["schema_version"].is_u64() {
        return Err(format!("{}: not a destair case report", path.display()));
    }
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut rows = rows_of(&v);
    for r in &mut rows {
        r.report_dir = dir.clone();
    }
    Ok(CaseRows {
        id: v["case"].as_str().unwrap_or("").to_string(),
        ok: v["status"].as_str() == Some("ok"),
        rows,
        path: path.to_path_buf(),
    })
}

/// Finds every case report below the given folders.
pub fn collect_reports(dirs: &[PathBuf]) -> (Vec<CaseRows>, Vec<String>) {
    let mut found = Vec::new();
    let mut problems = Vec::new();
    for dir in dirs {
        for entry in walkdir::WalkDir::new(dir)
            .follow_links(true)
            .sort_by_file_name()
        {
            match entry {
                Ok(e) if e.file_name() == "report.json" && e.file_type().is_file() => {
                    match read_case_rows(e.path()) {
                        Ok(c) => found.push(c),
                        Err(p) => problems.push(p),
                    }
                }
                Ok(_) => {}
                Err(e) => problems.push(format!("{}: {e}", dir.display())),
            }
        }
    }
    (found, problems)
}

/// Builds the summary of the given cases; `expected` (case ids) enables the missing check.
pub fn summarize(cases: Vec<CaseRows>, expected: Option<&[String]>) -> Summary {
    let mut by_case: BTreeMap<String, Vec<CaseRows>> = BTreeMap::new();
    let known: Option<std::collections::HashSet<&str>> =
        expected.map(|e| e.iter().map(String::as_str).collect());
    let mut not_in_cohort = std::collections::BTreeSet::new();
    for c in cases {
        if known.as_ref().is_some_and(|k| !k.contains(c.id.as_str())) {
            not_in_cohort.insert(c.id);
            continue;
        }
        by_case.entry(c.id.clone()).or_default().push(c);
    }
    let mut s = Summary {
        n_cases: by_case.len(),
        not_in_cohort: not_in_cohort.into_iter().collect(),
        ..Default::default()
    };
    if let Some(expected) = expected {
        s.missing = expected
            .iter()
            .filter(|e| !by_case.contains_key(e.as_str()))
            .cloned()
            .collect();
    }
    for (id, mut copies) in by_case {
        if copies.len() > 1 {
            s.duplicates.push(id.clone());
        }
        let c = copies.swap_remove(0);
        if c.ok {
            s.n_ok += 1;
        } else {
            s.failed.push(id);
        }
        s.rows.extend(c.rows);
    }
    s
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The rows as CSV with a header line.
pub fn to_csv(rows: &[SummaryRow]) -> String {
    let mut out = String::from("case,structure,status,method,n_vertices,hausdorff_mm,mean_distance_mm,volume_percent,curvature_before_deg,curvature_after_deg,max_d_voxel_diagonals,reference_distance_before_mm,reference_distance_after_mm,staircase_share,n_caps,patches,min_angle_deg,edges_within_20_percent,remesh_hausdorff_mm,lumen_ratio,gap_change_mm,new_contacts,error\n");
    let num = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x}"));
    for r in rows {
        let fields = [
            csv_field(&r.case),
            csv_field(&r.structure),
            r.status.clone(),
            r.method.clone(),
            r.n_vertices.to_string(),
            num(r.hausdorff_mm),
            num(r.mean_distance_mm),
            num(r.volume_percent),
            num(r.curvature_before_deg),
            num(r.curvature_after_deg),
            num(r.max_d_voxel_diagonals),
            num(r.reference_distance_before_mm),
            num(r.reference_distance_after_mm),
            num(r.staircase_share),
            r.n_caps.map_or(String::new(), |c| c.to_string()),
            csv_field(&r.patches),
            num(r.min_angle_deg),
            num(r.edges_within_20_percent),
            num(r.remesh_hausdorff_mm),
            num(r.lumen_ratio),
            num(r.gap_change_mm),
            r.new_contacts.map_or(String::new(), |c| c.to_string()),
            csv_field(&r.error),
        ];
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// Writes `summary.csv` and `summary.json` into `dir`, atomically.
pub fn write_summary(dir: &Path, summary: &Summary) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    crate::io::remove_stale_temp_files(dir)?;
    let csv = to_csv(&summary.rows);
    write_atomically(&dir.join("summary.csv"), |w| w.write_all(csv.as_bytes()))?;
    let json = serde_json::to_vec_pretty(summary).map_err(std::io::Error::other)?;
    write_atomically(&dir.join("summary.json"), |w| w.write_all(&json))
}
