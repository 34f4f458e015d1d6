//! Tests of `src/report/html/markdown.rs`.

use destair::report::html::markdown::*;

#[test]
fn the_report_subset_converts() {
    let md = "# destair report: case `a<b`\n\nstatus: **ok**\n\n- error: x & y\n- warning: z\n\n| s | n |\n|---|---|\n| `tumor` | 1.5 |\n\nline one\nline two\n";
    let html = markdown_to_html(md);
    assert!(
        html.contains("<h1>destair report: case <code>a&lt;b</code></h1>"),
        "{html}"
    );
    assert!(html.contains("<p>status: <b>ok</b></p>"));
    assert!(html.contains("<ul>\n<li>error: x &amp; y</li>\n<li>warning: z</li>\n</ul>"));
    assert!(html.contains("<tr><th>s</th><th>n</th></tr>"));
    assert!(html.contains("<tr><td><code>tumor</code></td><td class=\"num\">1.5</td></tr>"));
    assert!(!html.contains("---"));
    assert!(html.contains("<p>line one\nline two</p>"));
    // Unclosed spans stay text.
    assert_eq!(inline("a `b"), "a `b");
    assert_eq!(inline("**x"), "**x");
}
