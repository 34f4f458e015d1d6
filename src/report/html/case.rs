//! `report.html` of a case: the text and tables of `report.md`, then per structure its picture
//! sheet, the displacement histogram and the distances to its references before and after.

use super::markdown::markdown_to_html;
use super::svg;
use super::{escape, href, page};
use crate::report::case::CaseReport;

/// The case page; `markdown` is the report's `to_markdown()` (made once for report.md).
pub fn case_page(report: &CaseReport, markdown: &str) -> String {
    let mut body = markdown_to_html(markdown);
    for st in &report.structures {
        let refs: Vec<(String, f64, f64)> = st
            .metrics
            .as_ref()
            .map(|m| {
                m.references
                    .iter()
                    .map(|r| (r.name.clone(), r.before_mm, r.after_mm))
                    .collect()
            })
            .unwrap_or_default();
        if st.picture.is_none() && st.displacement_histogram.is_none() && refs.is_empty() {
            continue;
        }
        body.push_str(&format!(
            "<h2 id=\"{}\">{}</h2>\n",
            escape(&st.name),
            escape(&st.name)
        ));
        if let Some(p) = &st.picture {
            body.push_str(&format!(
                "<img class=\"sheet\" src=\"{}\" width=\"{}\" height=\"{}\" alt=\"{}: {}\">\n",
                href(&p.file),
                p.width,
                p.height,
                escape(&st.name),
                escape(&p.panels.join(", "))
            ));
        }
        body.push_str("<div class=\"plots\">\n");
        if let Some(h) = &st.displacement_histogram {
            body.push_str(&svg::histogram(
                "vertex displacement",
                &format!("mm (largest {:.4})", h.max_mm),
                h,
            ));
            body.push('\n');
        }
        if !refs.is_empty() {
            body.push_str(&svg::before_after_bars(
                "smallest distance to each reference",
                "mm",
                &refs,
            ));
            body.push('\n');
        }
        body.push_str("</div>\n");
    }
    body.push_str(
        "<p class=\"note\">Written by destair; the same data are in report.json and report.md.</p>",
    );
    page(&format!("destair: {}", report.case), &body)
}
