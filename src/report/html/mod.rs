//! HTML pages people open in the morning: `report.html` per case ([`case`]) and the pieces the
//! cohort's `index.html` is built from. Self-contained: CSS, scripts and plots (SVG) inline,
//! pictures as relative links to the PNG files beside the page, nothing from the network.

pub mod case;
pub mod markdown;
pub mod svg;

/// Text safe in HTML element content and attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A relative link (file names with `/` between folders) made safe for an attribute:
/// characters outside the unreserved set are percent-encoded.
pub fn href(path: &str) -> String {
    let mut out = String::new();
    for b in path.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~/".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// Page styles: readable on screen and in print, no web fonts.
const STYLE: &str = "body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:24px;color:#1e1e1e;max-width:1500px}
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ddd}
table{border-collapse:collapse;margin:0.6em 0;font-size:0.9em}
th,td{border:1px solid #ccc;padding:3px 7px;text-align:left;vertical-align:middle}
th{background:#f3f3f3}table.sortable th{cursor:pointer;user-select:none}
td.num{text-align:right;font-variant-numeric:tabular-nums}
code{background:#f3f3f3;padding:0 3px;border-radius:3px}
.ok{color:#17752b;font-weight:600}.failed{color:#b3261e;font-weight:600}.skipped{color:#777}
.flag{background:#fde8e6}.flag::after{content:' \\25B2';color:#b3261e;font-size:0.8em}
img.sheet{max-width:100%;border:1px solid #eee}
.plots{display:flex;flex-wrap:wrap;gap:24px;align-items:flex-start}
.note{color:#555;font-size:0.9em}";

/// Sorts `table.sortable` by the clicked column: numbers by `data-v`, else by text; a second
/// click reverses. Rows without a value go last.
const SORT_SCRIPT: &str = "document.querySelectorAll('table.sortable').forEach(function(t){
t.querySelectorAll('th').forEach(function(th,i){th.addEventListener('click',function(){
var b=t.tBodies[0],rows=Array.from(b.rows),dir=th.dataset.dir==='asc'?-1:1;th.dataset.dir=dir===1?'asc':'desc';
rows.sort(function(x,y){var a=x.cells[i],c=y.cells[i],va=a.dataset.v,vc=c.dataset.v;
if(va!==undefined||vc!==undefined){if(va===undefined||va==='')return 1;if(vc===undefined||vc==='')return -1;return dir*(parseFloat(va)-parseFloat(vc));}
return dir*a.textContent.localeCompare(c.textContent);});rows.forEach(function(r){b.appendChild(r);});});});});";

/// A whole page around `body`.
pub fn page(title: &str, body: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>{}</title>\n<style>\n{STYLE}\n</style>\n</head>\n<body>\n{body}\n<script>\n{SORT_SCRIPT}\n</script>\n</body>\n</html>\n",
        escape(title)
    )
}

/// The CSS class of a status word.
pub fn status_class(status: &str) -> &'static str {
    match status {
        "ok" => "ok",
        "skipped" => "skipped",
        _ => "failed",
    }
}
