//! Tests of `src/job/index_page.rs`.

use destair::job::index_page::*;
use destair::job::summary::{Summary, SummaryRow};
use std::path::{Path, PathBuf};

fn row(case: &str, status: &str, hausdorff: f64) -> SummaryRow {
    let mut r = destair::job::summary::rows_of(&serde_json::json!({
        "case": case,
        "status": status,
        "structures": [{"name": "tumor", "status": status,
            "metrics": {"distance": {"hausdorff_mm": hausdorff}, "volume_percent": 100.0}}]
    }))
    .remove(0);
    r.report_dir = PathBuf::from(case);
    r
}

#[test]
fn the_outlier_and_the_failed_case_come_first_and_are_marked() {
    let mut rows: Vec<SummaryRow> = (0..12)
        .map(|k| row(&format!("c{k:02}"), "ok", 0.2 + 0.01 * k as f64))
        .collect();
    rows[5].hausdorff_mm = Some(3.0);
    rows.push(row("c99", "failed", f64::NAN));
    let flagged = outliers(&rows, &MEASURES[0]);
    assert_eq!(flagged.iter().filter(|&&f| f).count(), 1);
    assert!(flagged[5]);
    let summary = Summary {
        n_cases: 13,
        n_ok: 12,
        failed: vec!["c99".into()],
        rows,
        ..Default::default()
    };
    let html = index_page(Path::new("/nonexistent"), &summary);
    let failed_at = html.find(">c99<").unwrap();
    let outlier_at = html.find(">c05<").unwrap();
    let other_at = html.find(">c00<").unwrap();
    assert!(failed_at < outlier_at && outlier_at < other_at);
    assert!(html.contains("class=\"num flag\" data-v=\"3\">3.0000"));
    assert_eq!(
        html.matches("<tr><td>").count(),
        13,
        "one row per structure"
    );
}

#[test]
fn medians_and_relative_links() {
    assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
    assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
    let t = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(t.path().join("out/a b/c")).unwrap();
    let out = t.path().join("out");
    assert_eq!(
        relative_link(&out, &out.join("a b/c")).as_deref(),
        Some("a b/c")
    );
    assert_eq!(
        relative_link(&out.join("a b/c"), &out).as_deref(),
        Some("../..")
    );
    assert_eq!(relative_link(&out, &out).as_deref(), Some("."));
    assert_eq!(relative_link(&out, Path::new("/nonexistent/x")), None);
}
