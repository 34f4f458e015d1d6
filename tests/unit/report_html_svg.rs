//! Tests of `src/report/html/svg.rs`.

use destair::report::html::svg::*;
use destair::report::pictures::Histogram;

#[test]
fn plots_are_svg_with_one_mark_per_value() {
    let h = Histogram {
        bin_mm: 0.1,
        counts: vec![3, 0, 1],
        max_mm: 0.25,
    };
    let s = histogram("d", "mm", &h);
    assert!(s.starts_with("<svg") && s.ends_with("</svg>"));
    assert_eq!(s.matches("<rect x=").count(), 3);
    assert!(s.contains("0.2 - 0.3 mm: 1"));
    let b = before_after_bars(
        "r",
        "mm",
        &[("a".into(), 1.0, 0.5), ("b<".into(), 2.0, 2.0)],
    );
    assert_eq!(b.matches("height=\"10\"").count(), 4 + 2);
    assert!(b.contains("b&lt;"));
    let p = scatter_with_diagonal(
        "c",
        "x",
        "y",
        &[(1.0, 0.5, "a".into()), (f64::NAN, 1.0, "n".into())],
    );
    assert_eq!(p.matches("<circle").count(), 1);
    assert_eq!(short(0.25), "0.25");
    assert_eq!(short(12.5), "12.5");
    assert_eq!(short(250.0), "250");
}
