//! `cargo xtask report-check`: the demo report checked as a person would see it.
//!
//! `host-sim demo --quick` writes `target/demo-test/index.html` from an empty directory; headless
//! Chromium loads it from disk with the network disabled, dumps the DOM it built and takes a
//! screenshot; `xtask/checks/report_dom_check.py` (standard library only) then checks the
//! rendered page: every required section present and non-empty, every plot drawing marks, every
//! table filled, no script and no external resource, a screenshot that is not blank.

use crate::util::{cargo, have, run, target_dir, Result};
use std::process::Command;

/// Runs the check.
pub fn check() -> Result<()> {
    let browser = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| have(b))
        .ok_or("no Chromium found: run `cargo xtask setup` first")?;
    let out = target_dir().join("demo-test");
    let _ = std::fs::remove_dir_all(&out);
    let out_s = out.to_string_lossy().into_owned();
    cargo(&["run", "--release", "-q", "-p", "host-sim", "--", "demo", "--quick", "--out", &out_s])?;
    let page = format!("file://{}", out.join("index.html").display());
    let profile = out.join("chromium-profile");
    let flags = [
        "--headless".to_owned(),
        "--no-sandbox".into(),
        "--disable-gpu".into(),
        "--hide-scrollbars".into(),
        "--no-first-run".into(),
        "--disable-extensions".into(),
        "--disable-background-networking".into(),
        "--disable-component-update".into(),
        "--disable-sync".into(),
        "--proxy-server=127.0.0.1:9".into(),
        "--proxy-bypass-list=<-loopback>".into(),
        format!("--user-data-dir={}", profile.display()),
    ];
    let dom = out.join("dom.html");
    let shot = out.join("screenshot.png");
    let browse = |extra: &[String]| -> Result<Vec<u8>> {
        let o = Command::new("timeout")
            .arg("120")
            .arg(browser)
            .args(&flags)
            .args(extra)
            .arg(&page)
            .output()
            .map_err(|e| format!("cannot start {browser}: {e}"))?;
        if o.status.success() {
            Ok(o.stdout)
        } else {
            Err(format!("{browser} failed ({}):\n{}", o.status, String::from_utf8_lossy(&o.stderr)))
        }
    };
    let dumped = browse(&["--dump-dom".to_owned()])?;
    std::fs::write(&dom, dumped).map_err(|e| format!("cannot write {}: {e}", dom.display()))?;
    browse(&["--window-size=1280,2400".to_owned(), format!("--screenshot={}", shot.display())])?;
    run(Command::new("python3").arg("xtask/checks/report_dom_check.py").arg(&dom).arg(&shot))?;
    println!("report-check: all checks passed ({})", out.join("index.html").display());
    Ok(())
}
