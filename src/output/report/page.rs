//! The look every caveflow report shares (`run`, `reconcile`, `study`): one self-contained
//! HTML page, built top to bottom with [`Page`].
//!
//! Self-contained means the page fetches nothing: its style is inline, SVG charts are
//! inlined as elements and PNG charts embedded as `data:` URIs. A Content-Security-Policy
//! meta tag (`default-src 'none'`, images from `data:` only, inline style only, no script)
//! makes the browser refuse any other request, so a page opened on a site's intranet, or
//! mailed, shows exactly what the run wrote and nothing leaves the file.

use std::fmt::Write as _;
use std::path::Path;

use base64::Engine as _;

/// The page's style (and the whole of its look).
const STYLE: &str = "body{font-family:sans-serif;margin:24px auto;max-width:1400px;color:#222;\
padding:0 16px}h1{margin-bottom:4px}h2{margin-top:32px;border-bottom:1px solid #ddd}\
.src{color:#666;font-size:13px}.verdict{font-size:17px;line-height:1.5}\
.cards{display:flex;flex-wrap:wrap;gap:12px;margin:16px 0}\
.card{border:1px solid #ddd;border-radius:6px;padding:8px 14px;min-width:110px}\
.card b{display:block;font-size:22px}.card span{color:#666;font-size:12px}\
.row{display:flex;flex-wrap:wrap;gap:16px;align-items:flex-start}\
.row>div{flex:1 1 300px;max-width:100%}svg,img{max-width:100%;height:auto}\
.warn{color:#a35200}table{border-collapse:collapse;font-size:13px}\
td,th{border-bottom:1px solid #eee;padding:3px 8px;text-align:right}th{background:#f6f6f6}\
td:first-child,th:first-child{text-align:left}";

/// The browser may load images from `data:` URIs and apply inline style; nothing else.
const POLICY: &str = "default-src 'none'; img-src data:; style-src 'unsafe-inline'";

/// A report page under construction.
pub struct Page {
    html: String,
}

/// A failure to read a chart the page embeds, naming the chart.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {source}")]
pub struct EmbedError {
    /// The chart.
    pub path: std::path::PathBuf,
    /// Why it could not be read.
    #[source]
    pub source: std::io::Error,
}

impl Page {
    /// A page titled `title`, with one small line per entry of `sources` under the title
    /// (what the page was made from).
    pub fn new(title: &str, sources: &[String]) -> Page {
        let mut html = format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
             <meta http-equiv=\"Content-Security-Policy\" content=\"{POLICY}\">\
             <meta name=\"viewport\" content=\"width=device-width\">\
             <title>{t}</title><style>{STYLE}</style></head><body>\n<h1>{t}</h1>\n",
            t = esc(title)
        );
        for s in sources {
            let _ = writeln!(html, "<div class=\"src\">{}</div>", esc(s));
        }
        Page { html }
    }

    /// The opening verdict: one or two sentences in bold type.
    pub fn verdict(&mut self, text: &str) {
        let _ = writeln!(self.html, "<p class=\"verdict\"><b>{}</b></p>", esc(text));
    }

    /// A row of key figures: (value as shown, what it is).
    pub fn cards(&mut self, cards: &[(String, String)]) {
        self.html.push_str("<div class=\"cards\">");
        for (value, what) in cards {
            let _ = write!(
                self.html,
                "<div class=\"card\"><b>{}</b><span>{}</span></div>",
                esc(value),
                esc(what)
            );
        }
        self.html.push_str("</div>\n");
    }

    /// A section heading.
    pub fn heading(&mut self, text: &str) {
        let _ = writeln!(self.html, "<h2>{}</h2>", esc(text));
    }

    /// A paragraph of plain text.
    pub fn para(&mut self, text: &str) {
        let _ = writeln!(self.html, "<p>{}</p>", esc(text));
    }

    /// A small grey note (how to read what follows).
    pub fn note(&mut self, text: &str) {
        let _ = writeln!(self.html, "<p class=\"src\">{}</p>", esc(text));
    }

    /// A bulleted list; `warn` sets the items in the warning colour.
    pub fn list(&mut self, items: &[String], warn: bool) {
        let class = if warn { " class=\"warn\"" } else { "" };
        let _ = write!(self.html, "<ul{class}>");
        for i in items {
            let _ = write!(self.html, "<li>{}</li>", esc(i));
        }
        self.html.push_str("</ul>\n");
    }

    /// Charts side by side (wrapping on narrow screens): SVG files inlined, PNG files
    /// embedded.
    pub fn charts(&mut self, paths: &[&Path]) -> Result<(), EmbedError> {
        self.html.push_str("<div class=\"row\">");
        for p in paths {
            let figure = figure(p)?;
            let _ = write!(self.html, "<div>{figure}</div>");
        }
        self.html.push_str("</div>\n");
        Ok(())
    }

    /// A table: a header row, then one row of cells per entry (already formatted).
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) {
        self.html.push_str("<table><tr>");
        for h in header {
            let _ = write!(self.html, "<th>{}</th>", esc(h));
        }
        self.html.push_str("</tr>");
        for r in rows {
            self.html.push_str("<tr>");
            for c in r {
                let _ = write!(self.html, "<td>{}</td>", esc(c));
            }
            self.html.push_str("</tr>");
        }
        self.html.push_str("</table>\n");
    }

    /// A definition list of terms and what they mean ("What the numbers mean").
    pub fn glossary(&mut self, terms: &[(&str, &str)]) {
        self.html.push_str("<ul>");
        for (term, meaning) in terms {
            let _ = write!(self.html, "<li><b>{}</b>: {}</li>", esc(term), esc(meaning));
        }
        self.html.push_str("</ul>\n");
    }

    /// The finished page.
    pub fn finish(mut self) -> String {
        self.html.push_str("</body></html>\n");
        self.html
    }
}

/// A chart file as page content: an SVG file's `<svg …>…</svg>` element, or a PNG file as an
/// `<img>` with a `data:` URI.
fn figure(path: &Path) -> Result<String, EmbedError> {
    let err = |source| EmbedError {
        path: path.to_path_buf(),
        source,
    };
    let bytes = std::fs::read(path).map_err(err)?;
    let alt = path
        .file_stem()
        .map_or(String::new(), |s| s.to_string_lossy().replace('_', " "));
    if path.extension().is_some_and(|e| e == "svg") {
        let s = String::from_utf8_lossy(&bytes);
        Ok(s.find("<svg")
            .map_or(s.to_string(), |at| s[at..].to_string()))
    } else {
        Ok(format!(
            "<img alt=\"{}\" src=\"data:image/png;base64,{}\">",
            esc(&alt),
            base64::engine::general_purpose::STANDARD.encode(&bytes)
        ))
    }
}

/// Escapes text for HTML.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A number for a table cell: whole numbers from 1000 up, 4 decimals below, "–" when
/// missing.
pub fn num(v: f64) -> String {
    if !v.is_finite() {
        "–".into()
    } else if v.abs() >= 1000.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.4}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Text is escaped everywhere it is set, and the page asks the browser to load nothing
    /// but its own `data:` images.
    #[test]
    fn text_is_escaped_and_the_page_loads_nothing() {
        let mut p = Page::new("a<b", &["x & y".into()]);
        p.verdict("\"q\"");
        p.table(&["<h>"], &[vec!["<td>".into()]]);
        let html = p.finish();
        assert!(html.contains("<h1>a&lt;b</h1>") && html.contains("x &amp; y"));
        assert!(html.contains("&quot;q&quot;") && html.contains("&lt;td&gt;"));
        assert!(html.contains("default-src 'none'; img-src data:"));
        assert!(html.ends_with("</body></html>\n"));
    }
}
