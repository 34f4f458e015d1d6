//! Small inline SVG plots for the HTML pages: a histogram, paired before/after bars, and a
//! scatter plot against the diagonal. Coordinates are written with fixed decimals, so the
//! same data give the same text.

use super::escape;
use crate::report::pictures::Histogram;

const W: f64 = 420.0;
const H: f64 = 220.0;
/// Plot margins: left, right, top, bottom (px).
const ML: f64 = 52.0;
const MR: f64 = 12.0;
const MT: f64 = 24.0;
const MB: f64 = 40.0;
const BAR: &str = "#3b528b";
const BAR2: &str = "#5cc863";

fn open(title: &str, height: f64) -> String {
    format!(
        "<svg width=\"{W}\" height=\"{height}\" viewBox=\"0 0 {W} {height}\" role=\"img\"><title>{t}</title><rect width=\"{W}\" height=\"{height}\" fill=\"#fff\"/><text x=\"{ML}\" y=\"15\" font-size=\"12\" font-weight=\"600\">{t}</text>",
        t = escape(title)
    )
}

fn axes(x_label: &str, y_label: &str) -> String {
    let (x0, y0, x1, y1) = (ML, H - MB, W - MR, MT);
    format!(
        "<line x1=\"{x0}\" y1=\"{y0}\" x2=\"{x1}\" y2=\"{y0}\" stroke=\"#444\"/><line x1=\"{x0}\" y1=\"{y0}\" x2=\"{x0}\" y2=\"{y1}\" stroke=\"#444\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"middle\">{}</text><text x=\"12\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"middle\" transform=\"rotate(-90 12 {:.1})\">{}</text>",
        0.5 * (x0 + x1),
        H - 6.0,
        escape(x_label),
        0.5 * (y0 + y1),
        0.5 * (y0 + y1),
        escape(y_label)
    )
}

fn tick_x(x: f64, label: &str) -> String {
    format!(
        "<text x=\"{x:.1}\" y=\"{:.1}\" font-size=\"10\" text-anchor=\"middle\">{}</text>",
        H - MB + 13.0,
        escape(label)
    )
}

fn tick_y(y: f64, label: &str) -> String {
    format!(
        "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"10\" text-anchor=\"end\">{}</text>",
        ML - 4.0,
        y + 3.0,
        escape(label)
    )
}

/// Short number for axis labels.
pub fn short(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let s = if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.4}")
    };
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// A histogram with bin edges in mm on x and counts on y.
pub fn histogram(title: &str, x_label: &str, h: &Histogram) -> String {
    let mut s = open(title, H);
    s.push_str(&axes(x_label, "count"));
    let n = h.counts.len().max(1) as f64;
    let max = h.counts.iter().copied().max().unwrap_or(0).max(1) as f64;
    let bw = (W - ML - MR) / n;
    for (k, &c) in h.counts.iter().enumerate() {
        let bh = (H - MB - MT) * c as f64 / max;
        s.push_str(&format!(
            "<rect x=\"{:.2}\" y=\"{:.2}\" width=\"{:.2}\" height=\"{bh:.2}\" fill=\"{BAR}\"><title>{} - {} mm: {c}</title></rect>",
            ML + k as f64 * bw + 0.5,
            H - MB - bh,
            (bw - 1.0).max(0.5),
            short(k as f64 * h.bin_mm),
            short((k + 1) as f64 * h.bin_mm)
        ));
    }
    s.push_str(&tick_x(ML, "0"));
    s.push_str(&tick_x(W - MR, &short(n * h.bin_mm)));
    s.push_str(&tick_y(MT, &(max as u64).to_string()));
    s.push_str(&tick_y(H - MB, "0"));
    s.push_str("</svg>");
    s
}

/// Paired horizontal bars (before, after) per labelled item, e.g. distances to references (mm).
pub fn before_after_bars(title: &str, unit: &str, items: &[(String, f64, f64)]) -> String {
    let row = 30.0;
    let height = MT + 8.0 + row * items.len().max(1) as f64 + 28.0;
    let mut s = open(title, height);
    let left = 150.0;
    let span = W - left - 60.0;
    let max = items
        .iter()
        .flat_map(|(_, a, b)| [*a, *b])
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max)
        .max(1e-9);
    for (k, (label, before, after)) in items.iter().enumerate() {
        let y = MT + 8.0 + k as f64 * row;
        s.push_str(&format!(
            "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"end\">{}</text>",
            left - 6.0,
            y + 14.0,
            escape(label)
        ));
        for (j, (v, colour)) in [(before, BAR), (after, BAR2)].into_iter().enumerate() {
            let w = if v.is_finite() {
                span * v.max(0.0) / max
            } else {
                0.0
            };
            let yy = y + j as f64 * 11.0;
            s.push_str(&format!(
                "<rect x=\"{left}\" y=\"{yy:.1}\" width=\"{w:.2}\" height=\"10\" fill=\"{colour}\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"9\">{} {unit}</text>",
                left + w + 4.0,
                yy + 8.5,
                short(*v),
                unit = escape(unit)
            ));
        }
    }
    let ly = height - 12.0;
    s.push_str(&format!(
        "<rect x=\"{left}\" y=\"{:.1}\" width=\"10\" height=\"10\" fill=\"{BAR}\"/><text x=\"{:.1}\" y=\"{ly:.1}\" font-size=\"10\">before</text><rect x=\"{:.1}\" y=\"{:.1}\" width=\"10\" height=\"10\" fill=\"{BAR2}\"/><text x=\"{:.1}\" y=\"{ly:.1}\" font-size=\"10\">after</text>",
        ly - 9.0,
        left + 14.0,
        left + 70.0,
        ly - 9.0,
        left + 84.0
    ));
    s.push_str("</svg>");
    s
}

/// Points (x, y, label) with the diagonal y = x, both axes from 0 to the largest value.
pub fn scatter_with_diagonal(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[(f64, f64, String)],
) -> String {
    let mut s = open(title, H);
    s.push_str(&axes(x_label, y_label));
    let max = points
        .iter()
        .flat_map(|(x, y, _)| [*x, *y])
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max)
        .max(1e-9);
    let (pw, ph) = (W - ML - MR, H - MB - MT);
    let side = pw.min(ph);
    let px = |v: f64| ML + side * v / max;
    let py = |v: f64| H - MB - side * v / max;
    s.push_str(&format!(
        "<line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"#aaa\" stroke-dasharray=\"4 3\"/>",
        px(0.0),
        py(0.0),
        px(max),
        py(max)
    ));
    for (x, y, label) in points
        .iter()
        .filter(|(x, y, _)| x.is_finite() && y.is_finite())
    {
        s.push_str(&format!(
            "<circle cx=\"{:.2}\" cy=\"{:.2}\" r=\"3.5\" fill=\"{BAR}\" fill-opacity=\"0.75\"><title>{}: {} -&gt; {}</title></circle>",
            px(*x),
            py(*y),
            escape(label),
            short(*x),
            short(*y)
        ));
    }
    s.push_str(&tick_x(px(0.0), "0"));
    s.push_str(&tick_x(px(max), &short(max)));
    s.push_str(&tick_y(py(max), &short(max)));
    s.push_str("</svg>");
    s
}
