//! The self-contained HTML page of `host-sim demo` (issue 10): a small document model
//! (sections of paragraphs, tables, inline SVG figures, preformatted text), its renderer, a
//! reader for the subset of Markdown the project's bench reports use, and a structural checker
//! that the tests (and the demo itself, before it says it is done) run on the page.
//!
//! The page needs nothing from outside: CSS is inline, plots are inline SVG, there is no
//! script and no link to another file or host. Everything that is text is escaped here, so
//! a label from a data set cannot break the page.

use std::fmt::Write as _;

/// One table cell: text and an optional inline background colour (e.g. a confusion matrix).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Cell {
    /// Text shown (escaped when rendered).
    pub text: String,
    /// Background colour as `#rrggbb`, if any.
    pub background: Option<String>,
    /// Bold (e.g. a total or the diagonal of a confusion matrix).
    pub strong: bool,
    /// Monospace (e.g. a cab display line or a CAN frame).
    pub mono: bool,
    /// A link target relative to the page (another page of the same report, or `#id`); an
    /// absolute or external address is rendered as plain text.
    pub link: Option<String>,
    /// An inline SVG drawn after the text (e.g. a sparkline); only its `<svg>` element is kept.
    pub svg: Option<String>,
}

impl Cell {
    /// A plain text cell.
    pub fn text(text: impl Into<String>) -> Self {
        Self { text: text.into(), ..Self::default() }
    }

    /// A bold cell.
    pub fn strong(text: impl Into<String>) -> Self {
        Self { text: text.into(), strong: true, ..Self::default() }
    }

    /// A monospace cell.
    pub fn mono(text: impl Into<String>) -> Self {
        Self { text: text.into(), mono: true, ..Self::default() }
    }

    /// This cell as a link to `href`, a file next to the page or an `#id` on it.
    pub fn with_link(mut self, href: impl Into<String>) -> Self {
        self.link = Some(href.into());
        self
    }

    /// This cell with an inline SVG after its text.
    pub fn with_svg(mut self, svg: impl Into<String>) -> Self {
        self.svg = Some(svg.into());
        self
    }

    /// This cell with a background colour.
    pub fn with_background(mut self, rgb: (u8, u8, u8)) -> Self {
        self.background = Some(format!("#{:02x}{:02x}{:02x}", rgb.0, rgb.1, rgb.2));
        self
    }
}

impl From<&str> for Cell {
    fn from(s: &str) -> Self {
        Self::text(s)
    }
}

impl From<String> for Cell {
    fn from(s: String) -> Self {
        Self::text(s)
    }
}

/// A table with a caption, a header row and body rows.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Table {
    /// Caption above the table.
    pub caption: String,
    /// Column headings.
    pub header: Vec<String>,
    /// Body rows.
    pub rows: Vec<Vec<Cell>>,
}

impl Table {
    /// An empty table with a caption and column headings.
    pub fn new(caption: impl Into<String>, header: &[&str]) -> Self {
        Self { caption: caption.into(), header: header.iter().map(|h| (*h).to_owned()).collect(), rows: Vec::new() }
    }

    /// Appends a row.
    pub fn row(&mut self, cells: Vec<Cell>) {
        self.rows.push(cells);
    }
}

/// A piece of a section.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Block {
    /// A paragraph of plain text.
    Para(String),
    /// A smaller, grey paragraph (method notes).
    Note(String),
    /// A boxed, highlighted paragraph (where figures come from when not from this run).
    Callout(String),
    /// A table.
    Table(Table),
    /// An inline SVG figure (the SVG document as produced by plotters) with a caption.
    Figure {
        /// The SVG markup.
        svg: String,
        /// Caption under the figure.
        caption: String,
    },
    /// Several figures side by side (they wrap on narrow screens).
    Gallery(Vec<(String, String)>),
    /// Preformatted text (escaped).
    Pre(String),
    /// A subheading inside a section.
    Heading(String),
    /// A line of links to other pages of the same report or to sections, as (text, target);
    /// targets that are not [relative](Cell::with_link) are shown as plain text.
    Links(Vec<(String, String)>),
}

/// A section of the page with a stable `id` (the tests look sections up by it).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Section {
    /// HTML id (letters, digits, `-`).
    pub id: String,
    /// Heading.
    pub title: String,
    /// Content.
    pub blocks: Vec<Block>,
}

impl Section {
    /// An empty section.
    pub fn new(id: &str, title: impl Into<String>) -> Self {
        Self { id: id.to_owned(), title: title.into(), blocks: Vec::new() }
    }

    /// Appends a block.
    pub fn push(&mut self, b: Block) -> &mut Self {
        self.blocks.push(b);
        self
    }
}

/// The whole page.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Page {
    /// Title (also the `<h1>`).
    pub title: String,
    /// One line under the title.
    pub subtitle: String,
    /// Sections in order.
    pub sections: Vec<Section>,
}

/// Escapes text for HTML content and attribute values.
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

/// The `<svg …>…</svg>` element of an SVG document (drops an XML prolog or anything around it),
/// or `None` when there is none.
pub fn svg_element(doc: &str) -> Option<&str> {
    let start = doc.find("<svg")?;
    let end = doc.rfind("</svg>")? + "</svg>".len();
    (end > start).then(|| &doc[start..end])
}

const CSS: &str = "\
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;margin:0;color:#1d2329;background:#f6f7f9}\
main{max-width:1180px;margin:0 auto;padding:16px 24px 48px}\
h1{font-size:1.7em;margin:.4em 0 .1em}h2{border-bottom:2px solid #c9d1da;padding-bottom:.2em;margin-top:1.8em}\
h3{margin:1.2em 0 .4em}.subtitle{color:#4a5663;margin:0 0 1em}\
nav{display:flex;flex-wrap:wrap;gap:4px 16px;background:#fff;border:1px solid #d6dce3;border-radius:6px;padding:8px 12px;margin:12px 0}\
nav a{color:#1f5fa8;text-decoration:none;white-space:nowrap}\
section{background:#fff;border:1px solid #d6dce3;border-radius:6px;padding:4px 18px 14px;margin:18px 0}\
table{border-collapse:collapse;margin:8px 0 14px;font-size:.92em}\
caption{text-align:left;font-weight:600;padding:4px 0;color:#2c3a47}\
th,td{border:1px solid #cfd6de;padding:3px 8px;text-align:left;vertical-align:top}\
th{background:#eef2f6}td.num{text-align:right}.mono{font-family:ui-monospace,Consolas,monospace;font-size:.9em;white-space:pre-wrap}\
td{overflow-wrap:break-word}table{max-width:100%}\
figure{margin:10px 0 16px}figcaption{color:#4a5663;font-size:.9em;margin-top:2px}\
figure svg{max-width:100%;height:auto;border:1px solid #e1e6eb}\
.gallery{display:flex;flex-wrap:wrap;gap:12px}.gallery figure{flex:0 1 auto;margin:4px 0}\
td svg{display:block;margin-top:2px}\
td a,p a{color:#1f5fa8}\
pre{background:#f3f5f7;border:1px solid #dde3e9;padding:8px;overflow-x:auto;font-size:.85em}\
.note{color:#56636f;font-size:.9em}\
.callout{background:#fff8db;border:1px solid #e6d28a;border-radius:4px;padding:8px 12px}";

fn looks_numeric(s: &str) -> bool {
    let t = s.trim().trim_end_matches('%').trim_end_matches(" s").trim();
    !t.is_empty() && t.parse::<f64>().is_ok()
}

/// Whether `href` stays inside the report: a file name next to the page (letters, digits, `-`,
/// `_`, `.`, no `..`) or an `#id`.
fn relative_link(href: &str) -> bool {
    let ok = |c: char| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | '#');
    !href.is_empty() && href.chars().all(ok) && !href.contains("..")
}

fn render_table(out: &mut String, t: &Table) {
    out.push_str("<table>");
    if !t.caption.is_empty() {
        let _ = write!(out, "<caption>{}</caption>", escape(&t.caption));
    }
    if !t.header.is_empty() {
        out.push_str("<thead><tr>");
        for h in &t.header {
            let _ = write!(out, "<th>{}</th>", escape(h));
        }
        out.push_str("</tr></thead>");
    }
    out.push_str("<tbody>");
    for r in &t.rows {
        out.push_str("<tr>");
        for c in r {
            let mut classes = Vec::new();
            if c.mono {
                classes.push("mono");
            } else if looks_numeric(&c.text) {
                classes.push("num");
            }
            out.push_str("<td");
            if !classes.is_empty() {
                let _ = write!(out, " class=\"{}\"", classes.join(" "));
            }
            if let Some(bg) = &c.background {
                let _ = write!(out, " style=\"background:{}\"", escape(bg));
            }
            out.push('>');
            let text = if c.strong { format!("<strong>{}</strong>", escape(&c.text)) } else { escape(&c.text) };
            match c.link.as_deref().filter(|h| relative_link(h)) {
                Some(href) => {
                    let _ = write!(out, "<a href=\"{}\">{text}</a>", escape(href));
                }
                None => out.push_str(&text),
            }
            if let Some(svg) = c.svg.as_deref().and_then(svg_element) {
                out.push_str(svg);
            }
            out.push_str("</td>");
        }
        out.push_str("</tr>");
    }
    out.push_str("</tbody></table>\n");
}

/// Smallest text in an inlined plot, px: readable when printed.
pub const MIN_PLOT_TEXT_PX: f64 = 12.0;

/// `svg` with every `font-size="…"` below [`MIN_PLOT_TEXT_PX`] raised to it (the plotting
/// library's default axis text is under 10 px).
pub fn readable_svg(svg: &str) -> String {
    const KEY: &str = "font-size=\"";
    let mut out = String::with_capacity(svg.len());
    let mut rest = svg;
    while let Some(at) = rest.find(KEY) {
        out.push_str(&rest[..at + KEY.len()]);
        rest = &rest[at + KEY.len()..];
        let end = rest.find('"').unwrap_or(rest.len());
        let value = &rest[..end];
        match value.trim_end_matches("px").parse::<f64>() {
            Ok(v) if v < MIN_PLOT_TEXT_PX => out.push_str(&MIN_PLOT_TEXT_PX.to_string()),
            _ => out.push_str(value),
        }
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

fn render_figure(out: &mut String, svg: &str, caption: &str) {
    out.push_str("<figure>");
    // Only the <svg> element is inlined; a document without one becomes a visible note.
    match svg_element(svg) {
        Some(s) => out.push_str(&readable_svg(s)),
        None => out.push_str("<p class=\"note\">(plot missing)</p>"),
    }
    if !caption.is_empty() {
        let _ = write!(out, "<figcaption>{}</figcaption>", escape(caption));
    }
    out.push_str("</figure>\n");
}

/// Renders the page as one HTML document.
pub fn render(page: &Page) -> String {
    let mut out = String::with_capacity(1 << 20);
    out.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    out.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n");
    let _ = writeln!(out, "<title>{}</title>", escape(&page.title));
    let _ = writeln!(out, "<style>{CSS}</style>\n</head>\n<body>\n<main>");
    let _ = writeln!(out, "<h1>{}</h1>", escape(&page.title));
    let _ = writeln!(out, "<p class=\"subtitle\">{}</p>", escape(&page.subtitle));
    out.push_str("<nav>");
    for s in &page.sections {
        let _ = write!(out, "<a href=\"#{}\">{}</a>", escape(&s.id), escape(&s.title));
    }
    out.push_str("</nav>\n");
    for s in &page.sections {
        let _ = writeln!(out, "<section id=\"{}\">\n<h2>{}</h2>", escape(&s.id), escape(&s.title));
        for b in &s.blocks {
            match b {
                Block::Para(t) => {
                    let _ = writeln!(out, "<p>{}</p>", escape(t));
                }
                Block::Note(t) => {
                    let _ = writeln!(out, "<p class=\"note\">{}</p>", escape(t));
                }
                Block::Callout(t) => {
                    let _ = writeln!(out, "<p class=\"callout\">{}</p>", escape(t));
                }
                Block::Heading(t) => {
                    let _ = writeln!(out, "<h3>{}</h3>", escape(t));
                }
                Block::Links(links) => {
                    let items: Vec<String> = links
                        .iter()
                        .map(|(text, href)| {
                            if relative_link(href) {
                                format!("<a href=\"{}\">{}</a>", escape(href), escape(text))
                            } else {
                                escape(text)
                            }
                        })
                        .collect();
                    let _ = writeln!(out, "<p class=\"links\">{}</p>", items.join(" · "));
                }
                Block::Pre(t) => {
                    let _ = writeln!(out, "<pre>{}</pre>", escape(t));
                }
                Block::Table(t) => render_table(&mut out, t),
                Block::Figure { svg, caption } => render_figure(&mut out, svg, caption),
                Block::Gallery(figs) => {
                    out.push_str("<div class=\"gallery\">");
                    for (svg, caption) in figs {
                        render_figure(&mut out, svg, caption);
                    }
                    out.push_str("</div>\n");
                }
            }
        }
        out.push_str("</section>\n");
    }
    out.push_str("</main>\n</body>\n</html>\n");
    out
}

// ---------------------------------------------------------------------------------------------
// Markdown (the subset of the bench reports)

// ---------------------------------------------------------------------------------------------
// Structural check

/// What [`check`] found on a page.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct PageCheck {
    /// Section ids in order.
    pub sections: Vec<String>,
    /// Inline SVG elements.
    pub svgs: usize,
    /// Tables.
    pub tables: usize,
    /// Body rows over all tables.
    pub table_rows: usize,
}

fn count(hay: &str, needle: &str) -> usize {
    hay.matches(needle).count()
}

/// The first code reference in the visible text of `html` (outside tags, `<style>` and inline
/// SVG): a Rust path (`a::b`), a source file (`x.rs`), an issue number or a specification
/// section sign. A reader of the report should see what a thing is, not where it is in the code.
pub fn code_reference(html: &str) -> Option<String> {
    let mut text = String::new();
    let mut rest = html;
    while let Some(lt) = rest.find('<') {
        text.push_str(&rest[..lt]);
        text.push(' ');
        let after = &rest[lt..];
        let skip_to = ["<style", "<svg"].iter().find(|t| after.starts_with(**t)).map(|t| format!("</{}>", &t[1..]));
        let end = match skip_to {
            Some(close) => after.find(&close).map_or(after.len(), |e| e + close.len()),
            None => after.find('>').map_or(after.len(), |e| e + 1),
        };
        rest = &after[end..];
    }
    text.push_str(rest);
    for word in text.split(|c: char| c.is_whitespace() || matches!(c, '(' | ')' | ',' | ';')) {
        let w = word.trim_matches(|c: char| matches!(c, '.' | ':' | '"' | '\'' | '`'));
        let path = w.split_once("::").is_some_and(|(a, b)| !a.is_empty() && !b.is_empty());
        if path || w.ends_with(".rs") || w == "§" || w.starts_with('§') {
            return Some(w.to_owned());
        }
    }
    let lower = text.to_ascii_lowercase();
    lower.match_indices("issue ").find_map(|(i, m)| {
        let next = lower[i + m.len()..].chars().next()?;
        let digits = lower[i + m.len()..].chars().take_while(char::is_ascii_digit).count();
        (next.is_ascii_digit()).then(|| text[i..i + m.len() + digits].to_owned())
    })
}

/// Checks a rendered page without a browser: one document, no script, no external resource,
/// every `required` section present and non-empty, every inline SVG drawing something (a
/// `path`, `polyline`, `circle`, `line` or `rect` beyond its background), every table with at
/// least one body row of non-empty cells. Returns what it counted, or the first problem.
pub fn check(html: &str, required: &[&str]) -> Result<PageCheck, String> {
    if !html.starts_with("<!DOCTYPE html>") || !html.trim_end().ends_with("</html>") {
        return Err("not a complete HTML document".into());
    }
    let lower = html.to_ascii_lowercase();
    for bad in ["<script", "<link", "<iframe", "<img", "src=\"http", "href=\"http", "@import", "url(http"] {
        if lower.contains(bad) {
            return Err(format!("external resource or script: `{bad}`"));
        }
    }
    if let Some(r) = code_reference(html) {
        return Err(format!("the page's text names code, not what it means: `{r}`"));
    }
    let mut found = PageCheck::default();
    let mut rest = html;
    while let Some(p) = rest.find("<section id=\"") {
        let after = &rest[p + "<section id=\"".len()..];
        let id_end = after.find('"').ok_or("unterminated section id")?;
        let id = &after[..id_end];
        let body_end = after.find("</section>").ok_or_else(|| format!("section {id} not closed"))?;
        let body = &after[..body_end];
        let content = body.find("</h2>").map_or("", |h| &body[h + 5..]);
        if content.trim().is_empty() {
            return Err(format!("section {id} is empty"));
        }
        found.sections.push(id.to_owned());
        rest = &after[body_end..];
    }
    for id in required {
        if !found.sections.iter().any(|s| s == id) {
            return Err(format!("section `{id}` missing"));
        }
    }
    let mut rest = html;
    while let Some(p) = rest.find("<svg") {
        let end = rest[p..].find("</svg>").ok_or("unterminated <svg>")? + p;
        let svg = &rest[p..end];
        let marks = ["<path", "<polyline", "<circle", "<line", "<polygon"].iter().map(|m| count(svg, m)).sum::<usize>()
            + count(svg, "<rect").saturating_sub(1);
        if marks == 0 {
            return Err(format!("inline SVG #{} draws nothing", found.svgs + 1));
        }
        found.svgs += 1;
        rest = &rest[end..];
    }
    let mut rest = html;
    while let Some(p) = rest.find("<table>") {
        let end = rest[p..].find("</table>").ok_or("unterminated <table>")? + p;
        let t = &rest[p..end];
        let body = t.find("<tbody>").map_or("", |b| &t[b..]);
        let rows = count(body, "<tr>");
        let cells_with_text =
            body.split("<td").skip(1).filter(|c| c.split_once('>').is_some_and(|x| !x.1.starts_with("</td>"))).count();
        if rows == 0 || cells_with_text == 0 {
            return Err(format!("table #{} has no filled body rows", found.tables + 1));
        }
        found.tables += 1;
        found.table_rows += rows;
        rest = &rest[end..];
    }
    Ok(found)
}

// ---------------------------------------------------------------------------------------------
// Time

/// UTC date and time `YYYY-MM-DD HH:MM:SS UTC` of a Unix time (proleptic Gregorian calendar).
pub fn utc_text(unix_s: u64) -> String {
    let days = (unix_s / 86_400) as i64;
    let secs = unix_s % 86_400;
    // Civil from days (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02} UTC", secs / 3600, secs / 60 % 60, secs % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escaping_and_svg_extraction() {
        assert_eq!(escape("<a href=\"x\">&'"), "&lt;a href=&quot;x&quot;&gt;&amp;&#39;");
        assert_eq!(
            svg_element("<?xml version=\"1.0\"?>\n<svg a=\"1\"><path/></svg>\n"),
            Some("<svg a=\"1\"><path/></svg>")
        );
        assert_eq!(svg_element("no svg"), None);
    }

    #[test]
    fn plot_text_is_raised_to_the_readable_minimum() {
        let svg = "<svg><text font-size=\"9.677\">a</text><text font-size=\"16\">b</text><g font-size=\"10px\"/></svg>";
        assert_eq!(
            readable_svg(svg),
            "<svg><text font-size=\"12\">a</text><text font-size=\"16\">b</text><g font-size=\"12\"/></svg>"
        );
    }

    #[test]
    fn utc_dates() {
        assert_eq!(utc_text(0), "1970-01-01 00:00:00 UTC");
        assert_eq!(utc_text(951_782_400), "2000-02-29 00:00:00 UTC");
        assert_eq!(utc_text(1_795_437_058), "2026-11-23 12:30:58 UTC");
    }
}
