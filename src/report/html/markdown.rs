//! The subset of Markdown destair's `report.md` uses (headings, paragraphs, `- ` lists, pipe
//! tables, `code` and **bold** spans) as HTML, so `report.html` shows exactly the same text.

use super::escape;

/// Converts report Markdown to HTML.
pub fn markdown_to_html(md: &str) -> String {
    let mut out = String::new();
    let lines: Vec<&str> = md.lines().collect();
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i].trim_end();
        if line.trim().is_empty() {
            i += 1;
            continue;
        }
        if let Some(level) = heading_level(line) {
            let text = line[level..].trim();
            out.push_str(&format!("<h{level}>{}</h{level}>\n", inline(text)));
            i += 1;
        } else if line.starts_with('|') {
            let start = i;
            while i < lines.len() && lines[i].trim_start().starts_with('|') {
                i += 1;
            }
            out.push_str(&table(&lines[start..i]));
        } else if line.starts_with("- ") {
            out.push_str("<ul>\n");
            while i < lines.len() && lines[i].starts_with("- ") {
                out.push_str(&format!("<li>{}</li>\n", inline(&lines[i][2..])));
                i += 1;
            }
            out.push_str("</ul>\n");
        } else {
            let start = i;
            while i < lines.len()
                && !lines[i].trim().is_empty()
                && heading_level(lines[i]).is_none()
                && !lines[i].starts_with('|')
                && !lines[i].starts_with("- ")
            {
                i += 1;
            }
            let text: Vec<String> = lines[start..i].iter().map(|l| inline(l.trim())).collect();
            out.push_str(&format!("<p>{}</p>\n", text.join("\n")));
        }
    }
    out
}

/// 1 to 6 for `# ` to `###### `.
fn heading_level(line: &str) -> Option<usize> {
    let n = line.bytes().take_while(|&b| b == b'#').count();
    ((1..=6).contains(&n) && line[n..].starts_with(' ')).then_some(n)
}

/// A pipe table: header row, `|---|` separator, body rows. Number cells align right.
fn table(rows: &[&str]) -> String {
    let cells = |row: &str| -> Vec<String> {
        let row = row.trim();
        let row = row.strip_prefix('|').unwrap_or(row);
        let row = row.strip_suffix('|').unwrap_or(row);
        row.split('|').map(|c| c.trim().to_string()).collect()
    };
    let mut out = String::from("<table>\n");
    for (k, row) in rows.iter().enumerate() {
        let cs = cells(row);
        if cs
            .iter()
            .all(|c| !c.is_empty() && c.chars().all(|ch| "-: ".contains(ch)))
        {
            continue;
        }
        let tag = if k == 0 { "th" } else { "td" };
        out.push_str("<tr>");
        for c in cs {
            let numeric = tag == "td" && c.parse::<f64>().is_ok();
            let class = if numeric { " class=\"num\"" } else { "" };
            out.push_str(&format!("<{tag}{class}>{}</{tag}>", inline(&c)));
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</table>\n");
    out
}

/// Escapes text and turns `code` and **bold** spans into elements.
pub fn inline(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while !rest.is_empty() {
        let code = rest.find('`');
        let bold = rest.find("**");
        match (code, bold) {
            (Some(c), b) if b.is_none_or(|b| c < b) => {
                if let Some(end) = rest[c + 1..].find('`') {
                    out.push_str(&escape(&rest[..c]));
                    out.push_str(&format!(
                        "<code>{}</code>",
                        escape(&rest[c + 1..c + 1 + end])
                    ));
                    rest = &rest[c + 2 + end..];
                    continue;
                }
                out.push_str(&escape(rest));
                break;
            }
            (_, Some(b)) => {
                if let Some(end) = rest[b + 2..].find("**") {
                    out.push_str(&escape(&rest[..b]));
                    out.push_str(&format!("<b>{}</b>", inline(&rest[b + 2..b + 2 + end])));
                    rest = &rest[b + 4 + end..];
                    continue;
                }
                out.push_str(&escape(rest));
                break;
            }
            _ => {
                out.push_str(&escape(rest));
                break;
            }
        }
    }
    out
}
