//! The cohort's `index.html`: one sortable row per case and structure with a thumbnail of its
//! displacement picture, failed cases first, outliers flagged (largest Hausdorff distance,
//! volume change and loss of distance to references), and two plots: curvature before vs
//! after, and the distribution of Hausdorff distances.

use super::summary::{Summary, SummaryRow};
use crate::report::html::{escape, href, page, status_class, svg};
use std::fmt::Write;
use std::path::{Component, Path, PathBuf};

/// Thumbnail size on the page (px).
const THUMB_PX: u32 = 96;
/// Modified z-score (Iglewicz and Hoaglin) above which a value is flagged.
const OUTLIER_Z: f64 = 3.5;

/// A measure whose large values need a second look.
pub struct Measure {
    name: &'static str,
    value: fn(&SummaryRow) -> Option<f64>,
    /// Below this (in the measure's unit) nothing is flagged, however unusual.
    floor: f64,
}

/// The measures flagged on the index page: Hausdorff distance, volume change, reference
/// distance loss.
pub const MEASURES: [Measure; 3] = [
    Measure {
        name: "Hausdorff distance",
        value: |r| r.hausdorff_mm,
        floor: 0.05,
    },
    Measure {
        name: "volume change",
        value: |r| r.volume_percent.map(|v| (v - 100.0).abs()),
        floor: 0.5,
    },
    Measure {
        name: "reference distance loss",
        value: |r| match (
            r.reference_distance_before_mm,
            r.reference_distance_after_mm,
        ) {
            (Some(b), Some(a)) => Some(b - a),
            _ => None,
        },
        floor: 0.05,
    },
];

/// Which rows are outliers of `measure`: modified z-score above 3.5 among the ok rows (with
/// no spread at all, anything above the median), and above the measure's floor.
pub fn outliers(rows: &[SummaryRow], measure: &Measure) -> Vec<bool> {
    let mut values: Vec<f64> = rows
        .iter()
        .filter(|r| r.status == "ok")
        .filter_map(|r| (measure.value)(r))
        .filter(|v| v.is_finite())
        .collect();
    if values.is_empty() {
        return vec![false; rows.len()];
    }
    let mid = median(&mut values);
    let mut deviations: Vec<f64> = values.iter().map(|v| (v - mid).abs()).collect();
    let mad = median(&mut deviations);
    rows.iter()
        .map(|r| {
            let Some(v) = (measure.value)(r).filter(|v| v.is_finite()) else {
                return false;
            };
            if r.status != "ok" || v <= measure.floor {
                return false;
            }
            if mad > 0.0 {
                0.6745 * (v - mid) / mad > OUTLIER_Z
            } else {
                v > mid + measure.floor
            }
        })
        .collect()
}

/// The median of `values` (sorted in place); 0 for none.
pub fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n == 0 {
        return 0.0;
    }
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// `to` as a relative link from the folder `from` (both made absolute first); `None` when no
/// relative path exists (another drive).
pub fn relative_link(from: &Path, to: &Path) -> Option<String> {
    let abs = |p: &Path| std::fs::canonicalize(p).ok();
    let (from, to) = (abs(from)?, abs(to)?);
    let a: Vec<Component> = from.components().collect();
    let b: Vec<Component> = to.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return None;
    }
    let mut out = PathBuf::new();
    for _ in common..a.len() {
        out.push("..");
    }
    for c in &b[common..] {
        out.push(c);
    }
    let s = out.to_str()?.replace('\\', "/");
    Some(if s.is_empty() { ".".into() } else { s })
}

/// A number cell: `data-v` for sorting, the text with `digits` decimals, flagged or not.
fn num_cell(v: Option<f64>, digits: usize, flagged: bool) -> String {
    let class = if flagged { "num flag" } else { "num" };
    match v {
        Some(x) if x.is_finite() => {
            format!("<td class=\"{class}\" data-v=\"{x}\">{x:.digits$}</td>")
        }
        _ => format!("<td class=\"{class}\" data-v=\"\">-</td>"),
    }
}

/// Writes `index.html` into `dir` (beside the summary), atomically; with `html` off, removes
/// one an earlier run wrote (it would show old results).
pub fn write_index_page(dir: &Path, summary: &Summary, html: bool) -> std::io::Result<()> {
    let path = dir.join("index.html");
    if !html {
        return match std::fs::remove_file(&path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e),
            _ => Ok(()),
        };
    }
    let page = index_page(dir, summary);
    crate::io::write_atomically(&path, |w| w.write_all(page.as_bytes()))
}

/// The page, written into `dir` (links to case folders are relative to it).
pub fn index_page(dir: &Path, summary: &Summary) -> String {
    let rows = &summary.rows;
    let flags: Vec<Vec<bool>> = MEASURES.iter().map(|m| outliers(rows, m)).collect();
    let failed = |r: &SummaryRow| !matches!(r.status.as_str(), "ok" | "skipped");
    // Failed first, then rows with flags (most first), then the rest in case order.
    let mut order: Vec<usize> = (0..rows.len()).collect();
    let n_flags = |i: usize| flags.iter().filter(|f| f[i]).count();
    order.sort_by_key(|&i| (!failed(&rows[i]), std::cmp::Reverse(n_flags(i)), i));

    let mut body = String::new();
    let _ = write!(
        body,
        "<h1>destair cohort</h1>\n<p>{} case(s): <span class=\"ok\">{} ok</span>, <span class=\"{}\">{} failed</span>, {} missing.</p>\n",
        summary.n_cases,
        summary.n_ok,
        if summary.failed.is_empty() { "ok" } else { "failed" },
        summary.failed.len(),
        summary.missing.len()
    );
    for (title, list) in [
        ("Failed cases", &summary.failed),
        ("Cases without a report", &summary.missing),
        ("Cases with more than one report", &summary.duplicates),
        ("Folders skipped", &summary.skipped_folders),
        (
            "Structures with several files",
            &summary.duplicate_structures,
        ),
    ] {
        if !list.is_empty() {
            let _ = writeln!(body, "<p><b>{title}</b>: {}</p>", escape(&list.join(", ")));
        }
    }
    let flagged_rows = (0..rows.len()).filter(|&i| n_flags(i) > 0).count();
    let _ = writeln!(
        body,
        "<p class=\"note\">Flagged (&#9650;): values far above the cohort's median (modified z-score &gt; {OUTLIER_Z}) of {}; {flagged_rows} row(s). Click a column to sort.</p>",
        MEASURES.map(|m| m.name).join(", ")
    );
    // Plots.
    let curvature: Vec<(f64, f64, String)> = rows
        .iter()
        .filter_map(|r| {
            Some((
                r.curvature_before_deg?,
                r.curvature_after_deg?,
                format!("{} / {}", r.case, r.structure),
            ))
        })
        .collect();
    let hausdorff: Vec<f32> = rows
        .iter()
        .filter_map(|r| r.hausdorff_mm.map(|h| h as f32))
        .collect();
    body.push_str("<div class=\"plots\">\n");
    body.push_str(&svg::scatter_with_diagonal(
        "normal curvature: after vs before",
        "before (deg)",
        "after (deg)",
        &curvature,
    ));
    body.push_str(&svg::histogram(
        "Hausdorff distance, input to output",
        "mm",
        &crate::report::pictures::histogram(&hausdorff),
    ));
    body.push_str("\n</div>\n");
    // The table.
    body.push_str("<table class=\"sortable\">\n<thead><tr><th>picture</th><th>case</th><th>structure</th><th>status</th><th>method</th><th>vertices</th><th>Hausdorff (mm)</th><th>mean dist. (mm)</th><th>volume (%)</th><th>curvature before (deg)</th><th>after (deg)</th><th>reference dist. before (mm)</th><th>after (mm)</th><th>gap change (mm)</th><th>new contacts</th><th>flags</th><th>error</th></tr></thead>\n<tbody>\n");
    for &i in &order {
        let r = &rows[i];
        let link = relative_link(dir, &r.report_dir);
        let page_link = link.as_ref().map(|l| {
            let base = if l == "." {
                String::new()
            } else {
                format!("{l}/")
            };
            format!("{}report.html#{}", href(&base), escape(&r.structure))
        });
        let thumb = match (&r.picture, &link) {
            (Some(p), Some(l)) => {
                let panel = p
                    .panel_box("displacement")
                    .or_else(|| p.panel_box("smoothed"));
                panel.map_or(String::new(), |[x, y, w, h]| {
                    let src = if l == "." { p.file.clone() } else { format!("{l}/{}", p.file) };
                    format!(
                        "<svg width=\"{THUMB_PX}\" height=\"{THUMB_PX}\" viewBox=\"{x} {y} {w} {h}\"><image href=\"{}\" width=\"{}\" height=\"{}\"/></svg>",
                        href(&src),
                        p.width,
                        p.height
                    )
                })
            }
            _ => String::new(),
        };
        let case_cell = match &page_link {
            Some(l) => format!("<a href=\"{l}\">{}</a>", escape(&r.case)),
            None => escape(&r.case),
        };
        let thumb_cell = match (&page_link, thumb.is_empty()) {
            (Some(l), false) => format!("<a href=\"{l}\">{thumb}</a>"),
            _ => thumb,
        };
        let _ = writeln!(
            body,
            "<tr><td>{thumb_cell}</td><td>{case_cell}</td><td>{}</td><td class=\"{}\">{}</td><td>{}</td>{}{}{}{}{}{}{}{}{}{}{}<td>{}</td></tr>",
            escape(&r.structure),
            status_class(&r.status),
            escape(&r.status),
            escape(&r.method),
            num_cell(Some(r.n_vertices as f64), 0, false),
            num_cell(r.hausdorff_mm, 4, flags[0][i]),
            num_cell(r.mean_distance_mm, 4, false),
            num_cell(r.volume_percent, 2, flags[1][i]),
            num_cell(r.curvature_before_deg, 2, false),
            num_cell(r.curvature_after_deg, 2, false),
            num_cell(r.reference_distance_before_mm, 4, false),
            num_cell(r.reference_distance_after_mm, 4, flags[2][i]),
            num_cell(r.gap_change_mm, 4, false),
            num_cell(r.new_contacts.map(|c| c as f64), 0, r.new_contacts.unwrap_or(0) > 0),
            num_cell(Some(n_flags(i) as f64), 0, false),
            escape(&r.error)
        );
    }
    body.push_str("</tbody>\n</table>\n");
    page("destair cohort", &body)
}
