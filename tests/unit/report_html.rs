//! Tests of `src/report/html/mod.rs`.

use destair::report::html::*;

#[test]
fn escaping_and_links() {
    assert_eq!(escape("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
    assert_eq!(href("case 1/tumor_views.png"), "case%201/tumor_views.png");
    assert_eq!(href("a\"><script>"), "a%22%3E%3Cscript%3E");
    let p = page("t<", "<p>x</p>");
    assert!(p.starts_with("<!DOCTYPE html>"));
    assert!(p.contains("<title>t&lt;</title>"));
    assert!(!p.contains("http"), "no network");
}
