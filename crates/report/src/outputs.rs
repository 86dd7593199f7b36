//! The report's files: `report.json`, `report.csv`, `report.md` and `index.html` (the page:
//! the Markdown body as HTML under the viewer and the interactive charts).

use crate::data::ReportData;
use crate::error::ReportError;
use crate::markdown::markdown;
use crate::viewer::ViewerImage;
use std::fmt::Write as _;
use std::path::Path;

/// Writes `report.json`, `report.csv`, `report.md` and `index.html` (with the viewer's
/// `images`, `w × h`) into `out_dir`.
pub(crate) fn write_outputs(
    out_dir: &Path,
    data: &ReportData,
    w: u32,
    h: u32,
    images: &[ViewerImage],
) -> Result<(), ReportError> {
    write_text(
        &out_dir.join("report.json"),
        &serde_json::to_string_pretty(data).map_err(|e| ReportError::Invalid(e.to_string()))?,
    )?;
    write_text(&out_dir.join("report.csv"), &csv(data))?;
    write_text(&out_dir.join("report.md"), &markdown(data, false))?;
    write_text(&out_dir.join("index.html"), &html(data, w, h, images))
}

/// Writes `text` to `path` atomically.
fn write_text(path: &Path, text: &str) -> Result<(), ReportError> {
    prt_tracer::output::write_atomically(path, |w| {
        std::io::Write::write_all(w, text.as_bytes()).map_err(|e| e.to_string())
    })
    .map_err(|e| ReportError::Write {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })
}

/// The per-order rows, the error budget and the convergence series as CSV tables.
fn csv(d: &ReportData) -> String {
    let mut s = String::from("order,coefficients,full_ms,adaptive_ms,speedup,psnr_adaptive_vs_full,psnr_full_vs_reference,psnr_adaptive_vs_reference,rel_l2_full,rel_l2_adaptive,roi_diffuse,roi_specular,full_ms_min,full_ms_max,adaptive_ms_min,adaptive_ms_max,target_psnr,target_ms,target_threshold,target_psnr_estimate,target_psnr_actual\n");
    for r in &d.orders {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.order,
            r.coefficients,
            r.full_ms,
            r.adaptive_ms,
            r.speedup,
            r.psnr_adaptive_vs_full,
            r.psnr_full_vs_reference,
            r.psnr_adaptive_vs_reference,
            r.rel_l2_full,
            r.rel_l2_adaptive,
            r.roi_diffuse.map_or(String::new(), |v| v.to_string()),
            r.roi_specular.map_or(String::new(), |v| v.to_string()),
            r.full_ms_range[0],
            r.full_ms_range[1],
            r.adaptive_ms_range[0],
            r.adaptive_ms_range[1],
            r.target.as_ref().map_or(",,,,".to_string(), |t| format!(
                "{},{},{},{},{}",
                t.target_psnr, t.ms, t.threshold, t.psnr_estimate, t.psnr_actual
            ))
        );
    }
    if !d.error_budget.is_empty() {
        let _ = writeln!(
            s,
            "\norder,total_mse,{},unaccounted,{},cross_terms",
            crate::budget::TERMS.join(","),
            crate::budget::TERMS
                .map(|t| format!("direct_{t}"))
                .join(",")
        );
        for b in &d.error_budget {
            let _ = write!(s, "{},{}", b.order, b.total_mse);
            for t in crate::budget::TERMS {
                let _ = write!(s, ",{}", b.term(t));
            }
            let _ = write!(s, ",{}", b.unaccounted);
            for t in crate::budget::TERMS {
                let _ = write!(s, ",{}", b.direct(t));
            }
            let _ = writeln!(s, ",{}", b.cross_terms);
        }
    }
    s.push_str("\nspp,ms,psnr_ldr,rel_l2\n");
    for c in &d.convergence {
        let _ = writeln!(s, "{},{},{},{}", c.spp, c.ms, c.psnr_ldr, c.rel_l2);
    }
    s
}

/// The page: the Markdown body as HTML, after the viewer, the interactive charts and the
/// settings list of `viewer::page`.
fn html(d: &ReportData, w: u32, h: u32, images: &[ViewerImage]) -> String {
    let (title, body) = markdown_to_html(&markdown(d, true));
    let load = d.machine.timing_load.as_ref().map_or_else(
        || {
            (
                "Machine load while timing: not measured on this system.".to_owned(),
                false,
            )
        },
        |l| (l.sentence(d.machine.cores), l.noisy()),
    );
    let json = serde_json::to_value(d).unwrap_or(serde_json::Value::Null);
    crate::viewer::page(&title, (&load.0, load.1), &json, w, h, images, &body)
}

/// The report's Markdown as HTML by a tiny converter (pipes → sortable tables, `## ` →
/// headings, indented lines → `<pre>`, `- ` → list items, other lines → paragraphs): the
/// title (from `# `, "prt report" without one) and the body.
fn markdown_to_html(md: &str) -> (String, String) {
    let mut body = String::new();
    let mut in_table = false;
    let mut title = String::from("prt report");
    for line in md.lines() {
        if line.starts_with('|') {
            if line.contains("---") {
                continue;
            }
            let cells: Vec<&str> = line.trim_matches('|').split('|').map(str::trim).collect();
            if !in_table {
                body.push_str("<table class=\"sortable\"><tr>");
                for c in &cells {
                    let _ = write!(body, "<th>{}</th>", escape(c));
                }
                body.push_str("</tr>\n");
                in_table = true;
            } else {
                body.push_str("<tr>");
                for c in &cells {
                    let _ = write!(body, "<td>{}</td>", escape(c));
                }
                body.push_str("</tr>\n");
            }
            continue;
        }
        if in_table {
            body.push_str("</table>\n");
            in_table = false;
        }
        if let Some(t) = line.strip_prefix("## ") {
            let _ = writeln!(body, "<h2>{}</h2>", escape(t));
        } else if let Some(t) = line.strip_prefix("# ") {
            title = t.replace('`', "");
        } else if let Some(t) = line.strip_prefix("    ") {
            let _ = writeln!(body, "<pre>{}</pre>", escape(t));
        } else if let Some(t) = line.strip_prefix("- ") {
            let _ = writeln!(body, "<li>{}</li>", links(&escape(t)));
        } else if !line.is_empty() {
            let _ = writeln!(body, "<p>{}</p>", links(&escape(line)));
        }
    }
    if in_table {
        body.push_str("</table>\n");
    }
    (title, body)
}

/// Markdown links `[text](file)` as HTML links, for plain relative file names only (letters,
/// digits, `.`, `_`, `-`, `/`): the report links to its own files.
fn links(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(open) = rest.find('[') {
        let Some(mid) = rest[open..].find("](").map(|m| open + m) else {
            break;
        };
        let Some(close) = rest[mid..].find(')').map(|c| mid + c) else {
            break;
        };
        let (label, href) = (&rest[open + 1..mid], &rest[mid + 2..close]);
        let plain = |c: char| c.is_ascii_alphanumeric() || "._-/".contains(c);
        if href.is_empty() || !href.chars().all(plain) || label.contains('[') {
            out.push_str(&rest[..=open]);
            rest = &rest[open + 1..];
            continue;
        }
        let _ = write!(out, "{}<a href=\"{href}\">{label}</a>", &rest[..open]);
        rest = &rest[close + 1..];
    }
    out.push_str(rest);
    out
}

/// Escapes HTML's special characters and drops Markdown's backticks.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('`', "")
}

#[cfg(test)]
mod tests {
    use super::{links, markdown_to_html};

    /// Links to the report's own files become anchors; anything else stays text.
    #[test]
    fn links_to_plain_file_names_become_anchors() {
        assert_eq!(
            links("see [live.html](live.html) now"),
            "see <a href=\"live.html\">live.html</a> now"
        );
        assert_eq!(
            links("[x](javascript:alert(1))"),
            "[x](javascript:alert(1))"
        );
        assert_eq!(links("a [b] c (d)"), "a [b] c (d)");
        assert_eq!(
            links("[a](b.png) and [c](d/e.html)"),
            "<a href=\"b.png\">a</a> and <a href=\"d/e.html\">c</a>"
        );
    }

    #[test]
    fn the_markdown_converter_makes_sortable_tables_headings_and_escaped_text() {
        let md = "# Speed against error: `a<b>.toml`\n\n## Per order\n\n| order | PSNR |\n|---:|---:|\n| 2 | ∞ |\n\n    prt relight x & y\n- a `note`\nplain\n| last | table |\n";
        let (title, body) = markdown_to_html(md);
        assert_eq!(title, "Speed against error: a<b>.toml");
        assert_eq!(
            body,
            "<h2>Per order</h2>\n\
             <table class=\"sortable\"><tr><th>order</th><th>PSNR</th></tr>\n\
             <tr><td>2</td><td>∞</td></tr>\n\
             </table>\n\
             <pre>prt relight x &amp; y</pre>\n\
             <li>a note</li>\n\
             <p>plain</p>\n\
             <table class=\"sortable\"><tr><th>last</th><th>table</th></tr>\n\
             </table>\n"
        );
        // Without a title line the page is "prt report".
        assert_eq!(markdown_to_html("text").0, "prt report");
    }
}
