//! The fleet figures of the README: early-warning lead time on the slow-degradation scenario,
//! false warnings on healthy locomotives per 1000 releases, ingest throughput and database
//! size per 1000 releases.
//!
//! `cargo run --release -p pbm-fleet --example fleet_figures [-- SEED_DEGRADE SEED_HEALTHY]`

use anyhow::{Context, Result};
use pbm_fleet::db::FleetDb;
use pbm_fleet::ingest::{ingest, IngestOptions};
use pbm_fleet::measure::{measure, observe};
use pbm_fleet::scenario::{write, DegradationOptions, Wear};
use pbm_fleet::trend::WarningRule;

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let seed_degrade: u64 = args.next().map_or(Ok(101), |s| s.parse()).context("SEED_DEGRADE")?;
    let seed_healthy: u64 = args.next().map_or(Ok(202), |s| s.parse()).context("SEED_HEALTHY")?;
    let mut rule = WarningRule::default();
    if let Some(h) = std::env::var("FLEET_H").ok().and_then(|v| v.parse().ok()) {
        rule.h = h;
    }
    if let Some(b) = std::env::var("FLEET_BASELINE").ok().and_then(|v| v.parse().ok()) {
        rule.baseline = b;
    }
    if let Some(a) = std::env::var("FLEET_ORIFICE_ALLOWANCE").ok().and_then(|v| v.parse().ok()) {
        rule.min_shift[1] = a;
    }
    if let Some(a) = std::env::var("FLEET_LEAK_ALLOWANCE").ok().and_then(|v| v.parse().ok()) {
        rule.min_shift[0] = a;
    }
    println!(
        "warning rule: CUSUM k = {} σ, h = {} σ, baseline {} releases, |z| ≤ {}, allowance {:?}; in-control ARL ≈ {:.0} releases per parameter",
        rule.k,
        rule.h,
        rule.baseline,
        rule.z_clip,
        rule.min_shift,
        rule.arl0()
    );

    let wear = [Wear::Leak, Wear::Clog].repeat(4);
    let degrade = DegradationOptions::new(seed_degrade, wear);
    let m = measure(&degrade, &observe(&degrade)?, &rule);
    println!(
        "\nslow degradation (seed {seed_degrade}, {} releases per locomotive, wear from release {}):",
        degrade.releases, degrade.onset
    );
    println!("  loco     parameter  truth past edge  first fault call  first warning  lead (releases)");
    let mut leads = Vec::new();
    for l in &m.lead_times {
        let lead = l.lead(m.releases);
        leads.extend(lead);
        let o = |v: Option<usize>| v.map_or_else(|| "never".to_owned(), |v| v.to_string());
        println!(
            "  {:<8} {:<10} {:>15}  {:>16}  {:>13}  {:>15}",
            l.locomotive,
            l.parameter.name(),
            o(l.truth_fault_release),
            o(l.first_call),
            o(l.first_warning),
            lead.map_or_else(|| "-".to_owned(), |v| v.to_string())
        );
    }
    leads.sort_unstable();
    if let (Some(min), Some(max)) = (leads.first(), leads.last()) {
        println!("  lead time: median {} releases (min {min}, max {max})", leads[leads.len() / 2]);
    }
    println!("  false warnings on these degrading locomotives' other parameters are not counted");

    let healthy = DegradationOptions::new(seed_healthy, vec![Wear::Healthy; 20]);
    let h = measure(&healthy, &observe(&healthy)?, &rule);
    println!(
        "\nhealthy fleet (seed {seed_healthy}, {} locomotives × {} releases): {} false warnings in {} watched releases = {:.2} per 1000 releases",
        healthy.wear.len(),
        healthy.releases,
        h.false_warnings,
        h.healthy_releases,
        h.false_per_1000()
    );
    println!("  by parameter (leak, orifice, supply): {:?}", h.false_by_parameter);
    if std::env::var_os("FLEET_FIGURES_NO_INGEST").is_some() {
        return Ok(());
    }

    // Ingest: the degradation set written as a data set, then into a fresh database.
    let dir = tempfile::tempdir()?;
    let set = dir.path().join("set");
    let small = DegradationOptions { wear: vec![Wear::Healthy, Wear::Leak, Wear::Clog, Wear::Healthy], ..degrade };
    let written = write(&small, &set)?;
    let db_path = dir.path().join("fleet.sqlite");
    let mut db = FleetDb::open(&db_path)?;
    let s = ingest(&mut db, &[&set], &IngestOptions::default())?;
    println!(
        "\ningest: {} releases (data set of {} traces) in {:.2} s = {:.0} releases/s (replay through the monitor included, {} threads)",
        s.releases,
        written.len(),
        s.elapsed.as_secs_f64(),
        s.releases as f64 / s.elapsed.as_secs_f64(),
        rayon::current_num_threads()
    );
    let again = ingest(&mut db, &[&set], &IngestOptions::default())?;
    println!("re-ingest: {} releases, {} new, {} rows in the database", again.releases, again.new, db.count()?);
    // The database alone: the replayed releases stored again under new keys, one file (one
    // transaction) each, so the figure is the history's cost without the monitor's.
    let records: Vec<_> = db.releases("loco-01")?.iter().map(pbm_fleet::status::to_record).collect();
    let t = std::time::Instant::now();
    let mut n = 0usize;
    for round in 0..20 {
        for r in &records {
            let mut r = r.clone();
            r.origin = format!("{}#{round}", r.origin);
            // New releases, not copies of stored ones (those would be refused as duplicates).
            r.release_no += 1000 * (round + 1);
            r.content_hash = r.content_hash.map(|h| format!("{h}#{round}"));
            n += db.store_file([Ok(r)])?.map_err(anyhow::Error::msg)?.releases;
        }
    }
    println!(
        "database only: {n} releases stored one transaction each in {:.3} s = {:.0} releases/s",
        t.elapsed().as_secs_f64(),
        n as f64 / t.elapsed().as_secs_f64()
    );
    let fresh_dir = tempfile::tempdir()?;
    let fresh = fresh_dir.path().join("fleet.sqlite");
    let mut db = FleetDb::open(&fresh)?;
    ingest(&mut db, &[&set], &IngestOptions::default())?;
    db.checkpoint()?;
    let bytes = std::fs::metadata(&fresh)?.len();
    println!(
        "database: {bytes} bytes for {} releases = {:.0} kB per 1000 releases",
        db.count()?,
        bytes as f64 / db.count()? as f64
    );
    Ok(())
}
