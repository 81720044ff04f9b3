//! `cargo xtask report-check`: the demo report checked as a person would see it.
//!
//! `host-sim demo --quick` writes `target/demo-test/index.html` (the fleet table first) and a page
//! per locomotive next to it, from an empty directory. Headless Chromium loads the index and two
//! locomotive pages from disk with the network disabled; for each it dumps the DOM it built,
//! takes a screenshot, and takes a second screenshot at 1280 px width *with* scrollbars:
//! `xtask/checks/report_dom_check.py` (standard library only) then checks the rendered page —
//! every required section present and non-empty, every plot drawing marks with its text at 11 px
//! or more and no legend (no text, no box) inside its data rectangle, every table filled, the fleet table linking pages that exist, no script and no
//! external resource, a screenshot that is not blank, and no horizontal overflow at 1280 px.
//!
//! Overflow without a script: when a page is wider than the window, Chromium draws a horizontal
//! scrollbar along the bottom of the viewport, whatever the height of the page; the check looks
//! for it in the screenshot. That the detector works is checked on every run: the same check on
//! a locomotive page with a deliberately too-wide table must fail. Likewise the legend check must
//! fail on `xtask/checks/fixtures/legend_inside_plot.svg`, a plotters plot with its legend box
//! inside the data area (as the demo's plots drew it before the legends moved above the plots).

use crate::util::{cargo, have, output, run, target_dir, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

const CHECK: &str = "xtask/checks/report_dom_check.py";
/// A plotters plot with its legend inside the data area: the legend check must flag it.
const LEGEND_INSIDE: &str = "xtask/checks/fixtures/legend_inside_plot.svg";

struct Browser {
    program: &'static str,
    profile: PathBuf,
}

impl Browser {
    fn flags(&self) -> Vec<String> {
        vec![
            "--headless".to_owned(),
            "--no-sandbox".into(),
            "--disable-gpu".into(),
            "--no-first-run".into(),
            "--disable-extensions".into(),
            "--disable-background-networking".into(),
            "--disable-component-update".into(),
            "--disable-sync".into(),
            "--proxy-server=127.0.0.1:9".into(),
            "--proxy-bypass-list=<-loopback>".into(),
            format!("--user-data-dir={}", self.profile.display()),
        ]
    }

    fn load(&self, page: &Path, extra: &[String]) -> Result<Vec<u8>> {
        let o = Command::new("timeout")
            .arg("120")
            .arg(self.program)
            .args(self.flags())
            .args(extra)
            .arg(format!("file://{}", page.display()))
            .output()
            .map_err(|e| format!("cannot start {}: {e}", self.program))?;
        if o.status.success() {
            Ok(o.stdout)
        } else {
            Err(format!("{} failed ({}):\n{}", self.program, o.status, String::from_utf8_lossy(&o.stderr)))
        }
    }

    /// The DOM, a screenshot without scrollbars (1280 × 2400) and one with them (1280 × 800,
    /// for the overflow check), written next to `page` as `NAME.dom.html`, `NAME.png`,
    /// `NAME.scroll.png`; returns their paths.
    fn capture(&self, page: &Path) -> Result<[PathBuf; 3]> {
        let base = page.with_extension("");
        let dom = base.with_extension("dom.html");
        let shot = base.with_extension("png");
        let scroll = base.with_extension("scroll.png");
        let dumped = self.load(page, &["--dump-dom".to_owned()])?;
        std::fs::write(&dom, dumped).map_err(|e| format!("cannot write {}: {e}", dom.display()))?;
        self.load(
            page,
            &[
                "--hide-scrollbars".to_owned(),
                "--window-size=1280,2400".into(),
                format!("--screenshot={}", shot.display()),
            ],
        )?;
        self.load(page, &["--window-size=1280,800".to_owned(), format!("--screenshot={}", scroll.display())])?;
        Ok([dom, shot, scroll])
    }
}

/// The first locomotive pages of a report directory (`loco-*.html`), sorted.
fn locomotive_pages(dir: &Path, n: usize) -> Result<Vec<PathBuf>> {
    let mut pages: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| format!("cannot read {}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("loco-") && n.ends_with(".html") && !n.ends_with(".dom.html"))
        })
        .collect();
    pages.sort();
    if pages.is_empty() {
        return Err(format!("no locomotive pages (loco-*.html) next to {}", dir.join("index.html").display()));
    }
    pages.truncate(n);
    Ok(pages)
}

/// Runs the check.
pub fn check() -> Result<()> {
    let program = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| have(b))
        .ok_or("no Chromium found: run `cargo xtask setup` first")?;
    let out = target_dir().join("demo-test");
    let _ = std::fs::remove_dir_all(&out);
    let out_s = out.to_string_lossy().into_owned();
    cargo(&["run", "--release", "-q", "-p", "host-sim", "--", "demo", "--quick", "--out", &out_s])?;
    let browser = Browser { program, profile: out.join("chromium-profile") };

    // The detector first: a locomotive page with a table wider than the window must fail.
    let pages = locomotive_pages(&out, 2)?;
    let probe = out.join("overflow-probe.html");
    let html = std::fs::read_to_string(&pages[0]).map_err(|e| format!("cannot read {}: {e}", pages[0].display()))?;
    let wide = format!(
        "<table><tbody><tr><td style=\"white-space:nowrap\">{}</td></tr></tbody></table></main>",
        "a deliberately too wide cell ".repeat(60)
    );
    std::fs::write(&probe, html.replacen("</main>", &wide, 1)).map_err(|e| format!("cannot write probe: {e}"))?;
    let [_, _, scroll] = browser.capture(&probe)?;
    let o = output(Command::new("python3").arg(CHECK).arg("overflow").arg(&scroll))?;
    if o.status.success() {
        return Err(format!(
            "the overflow check did not see the deliberately too-wide table of {}:\n{}",
            probe.display(),
            String::from_utf8_lossy(&o.stdout)
        ));
    }
    println!("report-check: the overflow check flags a too-wide page ({})", probe.display());
    let o = output(Command::new("python3").arg(CHECK).arg("legends").arg(LEGEND_INSIDE))?;
    if o.status.success() {
        return Err(format!(
            "the legend check did not see the legend inside the plot of {LEGEND_INSIDE}:\n{}",
            String::from_utf8_lossy(&o.stdout)
        ));
    }
    println!("report-check: the legend check flags a legend inside the data area ({LEGEND_INSIDE})");

    let index = out.join("index.html");
    let [dom, shot, scroll] = browser.capture(&index)?;
    run(Command::new("python3").arg(CHECK).arg("demo").arg(&dom).arg(&shot).arg(&scroll).arg(&out))?;
    for page in &pages {
        let [dom, shot, scroll] = browser.capture(page)?;
        run(Command::new("python3").arg(CHECK).arg("locomotive").arg(&dom).arg(&shot).arg(&scroll).arg(&out))?;
    }
    println!("report-check: all checks passed ({} and {} locomotive pages)", index.display(), pages.len());
    Ok(())
}
