//! `host-sim demo`: the project's main job in one command, from nothing to a brake engineer's
//! report (issue 10).
//!
//! On an embedded default seed ([`DEFAULT_SEED`]) and with no other input it
//!
//! 1. generates the paper-size fleet data set (SPEC §6: 5 × 1100 training + 5 × 50 test
//!    traces, six locomotives, the last two held out for test) into `data/demo-fleet` with
//!    the generator's API, computing every trace's classifier features in the same pass — or
//!    reuses the directory when its stamp file ([`STAMP`]) says it was written by this demo
//!    with the same seed, version and options;
//! 2. trains the paper's three classifiers and ours and quantizes ours to int8
//!    ([`pbm_ml::train::train_all`]); at the same time (the trainer of `ours` keeps one core
//!    busy, the rest uses the other) it draws a hidden plant effect from the seed
//!    ([`pbm_lab::audit_sweep::draw_case`]), synthesises noisy releases with it and runs the
//!    discrepancy audit on them, runs the same audit on the real MetroPT-3 record
//!    ([`pbm_lab::metro::audit_metro_file`]), and builds the fleet history: a generated fleet
//!    (the slow-degradation scenario, [`DemoOptions::fleet_options`]: two healthy locomotives, a
//!    growing leak, a clogging orifice, a failing transducer) ingested into a fresh SQLite
//!    history, with its fleet table and a page per locomotive ([`pbm_fleet::report`]);
//! 3. evaluates every classifier on the test split: accuracy, confusion matrices, accuracy
//!    against time since the release command ([`pbm_ml::evaluate`]);
//! 4. replays a sample of test traces (two per class by default) through the core pipeline
//!    with CAN logging ([`pbm_lab::replay::replay_to_can_log`], the firmware's per-sample
//!    path), decodes the candump log with the core's decoder and tabulates the fault reports
//!    as the cab display shows them; the same traces give the release curves measured vs twin;
//! 5. scores the online estimator against the generator's truth on the test split (scatter
//!    plots, error table);
//! 6. writes `report/index.html` (self-contained: inline CSS and SVG, no script, no network),
//!    leading with the fleet table, and each locomotive's page next to it (`loco-….html`),
//!    with the firmware cost figures read from `bench/firmware.md` when that file exists
//!    (labelled as read from it — everything else in the page is computed in the run), checks
//!    the page's structure, and prints a summary table.
//!
//! `--quick` is the same pipeline on a small data set (40 + 10 traces per class) for tests.

use anyhow::{bail, Context, Result};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use pbm::can::{Decoder, Report};
use pbm::mechanism::Mechanism;
use pbm::{AdcCounts, FaultClass};
use pbm_fleet::scenario::{DegradationOptions, Wear};
use pbm_io::dataset::{Dataset, TraceItem, MANIFEST, TRUTH};
use pbm_lab::audit_sweep::{check_case, draw_case, CaseResult as AuditCase};
use pbm_lab::estimate::{self, CaseResult as EstimateCase, Param};
use pbm_lab::generate::{generate_with, GenerateOptions};
use pbm_lab::metro::{MetroOutcome, MetroRow};
use pbm_lab::replay::{replay_trace, summarise};
use pbm_ml::evaluate::{accuracy_vs_time, score_all, stable_by, Score};
use pbm_ml::nn::Mlp;
use pbm_ml::train::{dataset_features, features_from_adc, train_all, Kind, TraceFeatures, Trained, SNAPSHOT_TIMES_S};
use pbm_report::chart::{write_line_chart, ChartLabels, Series, OKABE_ITO};
use pbm_report::report_html::{check, render, utc_text, Block, Cell, Page, Section, Table};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The seed of a demo run when none is given (the year of the paper).
pub const DEFAULT_SEED: u64 = 2023;
/// Training traces per class with `--quick`.
pub const QUICK_PER_CLASS: usize = 40;
/// Test traces per class with `--quick`.
pub const QUICK_TEST_PER_CLASS: usize = 10;
/// Stamp file in the data directory: what wrote it, with which seed, version and options.
pub const STAMP: &str = "demo-stamp.txt";
/// Section ids every report has (the tests look for them), in page order: the fleet first.
pub const REQUIRED_SECTIONS: [&str; 12] = [
    "fleet",
    "run",
    "summary",
    "data",
    "classifiers",
    "confusion",
    "early",
    "release",
    "can",
    "estimator",
    "audit",
    "firmware",
];
/// Releases per locomotive of the demo's fleet history (`--quick`: [`QUICK_FLEET_RELEASES`]).
pub const FLEET_RELEASES: usize = 150;
/// Releases per locomotive of the quick demo's fleet history.
pub const QUICK_FLEET_RELEASES: usize = 70;
/// Stamp file of the demo's fleet history directory (it is regenerated on every run).
pub const FLEET_STAMP: &str = "demo-fleet-history.txt";
/// Test accuracies the paper reports for its three classifiers on its real data (SPEC §6), %.
/// These are the paper's published figures, shown beside this run's for comparison.
pub const PAPER_REPORTED_PCT: [(&str, f64); 3] = [("paper_raw", 72.0), ("paper_residual", 81.2), ("paper_theta", 96.0)];

/// Options of the demo run.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoOptions {
    /// Seed of everything: data set, training, the hidden audit effect.
    pub seed: u64,
    /// Report directory (index.html, svg/, can/).
    pub out: PathBuf,
    /// Data set directory (`None`: `data/demo-fleet`, or `OUT/fleet` when `quick`).
    pub data: Option<PathBuf>,
    /// Small, fast variant (40 + 10 traces per class) for tests.
    pub quick: bool,
    /// Firmware figures (`cargo xtask fw-bench` writes them) to include if present (read, not
    /// computed, and labelled so).
    pub firmware_report: PathBuf,
    /// Test traces per class replayed with CAN logging.
    pub can_per_class: usize,
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// The MetroPT-3 record for the real-data audit.
    pub metro: PathBuf,
}

impl Default for DemoOptions {
    /// The full demo into `report/`, seed [`DEFAULT_SEED`].
    fn default() -> Self {
        Self {
            seed: DEFAULT_SEED,
            out: PathBuf::from("report"),
            data: None,
            quick: false,
            firmware_report: PathBuf::from("bench/firmware-figures.env"),
            can_per_class: 2,
            threads: 0,
            metro: PathBuf::from(pbm_lab::metro::DEFAULT_PATH),
        }
    }
}

impl DemoOptions {
    /// The data set directory.
    pub fn data_dir(&self) -> PathBuf {
        match (&self.data, self.quick) {
            (Some(d), _) => d.clone(),
            (None, true) => self.out.join("fleet"),
            (None, false) => PathBuf::from("data/demo-fleet"),
        }
    }

    /// The generator options of the demo's data set.
    pub fn generate_options(&self) -> GenerateOptions {
        let mut g = GenerateOptions::new(self.data_dir());
        g.seed = self.seed;
        g.threads = self.threads;
        if self.quick {
            g.per_class = QUICK_PER_CLASS;
            g.test_per_class = QUICK_TEST_PER_CLASS;
        }
        g
    }

    /// The fleet history's scenario: two healthy locomotives, one whose leak grows, one whose
    /// release orifice clogs, and one whose pressure transducer fails (its brake is healthy).
    pub fn fleet_options(&self) -> DegradationOptions {
        let wear = vec![Wear::Healthy, Wear::Healthy, Wear::Leak, Wear::Clog, Wear::Sensor];
        let mut o = DegradationOptions::new(self.seed, wear);
        if self.quick {
            o.releases = QUICK_FLEET_RELEASES;
            o.onset = 25;
        }
        o
    }
}

/// The stamp file's text for a data set generated with `g`.
pub fn stamp_text(g: &GenerateOptions) -> String {
    format!(
        "host-sim demo data set\nversion {}\nseed {}\nlocomotives {}\nper_class {}\ntest_per_class {}\nclasses {}\n\
         split {:?}\ntest_locomotives {}\neffects {:?}\n",
        env!("CARGO_PKG_VERSION"),
        g.seed,
        g.locomotives,
        g.per_class,
        g.test_per_class,
        g.classes.iter().map(|c| c.label()).collect::<Vec<_>>().join(","),
        g.split,
        g.test_locomotives,
        g.effects.active().map(|(m, v)| format!("{m}={v}")).collect::<Vec<_>>()
    )
}

// ---------------------------------------------------------------------------------------------
// Stages and progress

/// Wall time of one stage.
#[derive(Debug, Clone)]
pub struct StageTime {
    /// Stage name.
    pub name: String,
    /// Wall time.
    pub elapsed: Duration,
    /// CPU time of the whole process (all threads) during the stage, where the OS tells it.
    pub cpu: Option<Duration>,
    /// One line on what it did.
    pub detail: String,
}

struct Progress {
    multi: MultiProgress,
    total: usize,
    times: Vec<StageTime>,
    cpu_mark: Option<Duration>,
}

/// CPU time (user + system, all threads) of this process so far: Linux `/proc/self/stat`
/// fields 14 and 15, in clock ticks of 10 ms (USER_HZ = 100, fixed by the kernel ABI).
/// `None` elsewhere. The wall time of a run on a shared machine depends on the other load;
/// the CPU time does not, so the report gives both.
pub fn process_cpu_time() -> Option<Duration> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let after = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
    Some(Duration::from_millis(ticks * 10))
}

/// The 1, 5 and 15 minute load averages (Linux `/proc/loadavg`), as text.
pub fn load_average() -> Option<String> {
    let s = std::fs::read_to_string("/proc/loadavg").ok()?;
    let v: Vec<&str> = s.split_whitespace().take(3).collect();
    (v.len() == 3).then(|| v.join(" "))
}

impl Progress {
    fn new(total: usize) -> Self {
        Self { multi: MultiProgress::new(), total, times: Vec::new(), cpu_mark: process_cpu_time() }
    }

    fn spinner(&self, k: usize, name: &str) -> ProgressBar {
        let bar = self.multi.add(ProgressBar::new_spinner());
        bar.set_style(
            ProgressStyle::with_template("{spinner} {msg} {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar.set_message(format!("[{k}/{}] {name}", self.total));
        bar.enable_steady_tick(Duration::from_millis(120));
        bar
    }

    fn done(&mut self, bar: &ProgressBar, k: usize, name: &str, elapsed: Duration, detail: String) {
        bar.finish_and_clear();
        let now = process_cpu_time();
        let cpu = now.zip(self.cpu_mark).map(|(n, m)| n.saturating_sub(m));
        self.cpu_mark = now;
        let cpu_text = cpu.map_or_else(String::new, |c| format!(" (CPU {:.1} s)", c.as_secs_f64()));
        self.multi.suspend(|| {
            eprintln!("[{k}/{}] {name}: {:.1} s{cpu_text} — {detail}", self.total, elapsed.as_secs_f64());
        });
        self.times.push(StageTime { name: name.to_owned(), elapsed, cpu, detail });
    }
}

// ---------------------------------------------------------------------------------------------
// Stage 1: data

/// The data set of a run and every trace's features.
#[derive(Debug, Clone)]
pub struct DataStage {
    /// Directory.
    pub dir: PathBuf,
    /// Reused from an earlier run (stamp matched) rather than generated.
    pub reused: bool,
    /// Training traces' features.
    pub train: Vec<TraceFeatures>,
    /// Test traces' features.
    pub test: Vec<TraceFeatures>,
}

fn data_stage(g: &GenerateOptions) -> Result<DataStage> {
    let dir = g.out.clone();
    let stamp_path = dir.join(STAMP);
    let want = stamp_text(g);
    let stamp = std::fs::read_to_string(&stamp_path).ok();
    let complete = dir.join(MANIFEST).is_file() && dir.join(TRUTH).is_file();
    let (features, reused) = if stamp.as_deref() == Some(want.as_str()) && complete {
        let (features, skipped) = dataset_features(&dir, None)?;
        if !skipped.is_empty() {
            bail!("the demo's own data set {} is damaged; remove it to regenerate\n{skipped}", dir.display());
        }
        (features, true)
    } else {
        let non_empty = std::fs::read_dir(&dir).map(|mut d| d.next().is_some()).unwrap_or(false);
        if non_empty && stamp.is_none() {
            bail!(
                "{} exists and was not written by `host-sim demo` (no {STAMP}); remove it or pass --data DIR",
                dir.display()
            );
        }
        std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
        // Marks the directory as the demo's while it is incomplete, so an interrupted run is
        // regenerated next time rather than refused or reused.
        std::fs::write(&stamp_path, "incomplete\n")
            .with_context(|| format!("cannot write {}", stamp_path.display()))?;
        let mut g = g.clone();
        g.force = true;
        let (_, features) = generate_with(&g, true, |row, adc| {
            let class = FaultClass::from_label(&row.label).with_context(|| format!("label {}", row.label))?;
            let adc: Vec<AdcCounts> = adc.iter().map(|&c| AdcCounts(c)).collect();
            features_from_adc(row, class, &adc)
        })?;
        std::fs::write(&stamp_path, &want).with_context(|| format!("cannot write {}", stamp_path.display()))?;
        (features, false)
    };
    let (train, test): (Vec<TraceFeatures>, Vec<TraceFeatures>) = features
        .into_iter()
        .filter(|f| f.row.split == "train" || f.row.split == "test")
        .partition(|f| f.row.split == "train");
    if train.is_empty() || test.is_empty() {
        bail!("{}: the data set needs both a train and a test split", dir.display());
    }
    Ok(DataStage { dir, reused, train, test })
}

// ---------------------------------------------------------------------------------------------
// Stage 3: evaluation

/// Scores of the classifiers on the test split.
#[derive(Debug, Clone)]
pub struct EvalStage {
    /// Classes (model output order).
    pub classes: Vec<FaultClass>,
    /// paper_raw, paper_residual, paper_theta, ours_f64, ours_int8, core_compiled.
    pub scores: Vec<Score>,
    /// Test traces where ours f64 and int8 give the same class at 60 s.
    pub int8_agree: usize,
    /// (t, f64 %, int8 %) of ours.
    pub curve: Vec<(f64, f64, f64)>,
    /// Share of test traces diagnosed correctly (int8) and stably from some t ≤ 10 s, %.
    pub stable10: f64,
    /// Expected calibration error of the int8 confidence at the end of the test traces (0..1).
    pub ece: f64,
    /// Its reliability bins.
    pub reliability: Vec<pbm_ml::evaluate::ReliabilityBin>,
}

fn eval_stage(trained: &Trained, test: &[TraceFeatures]) -> Result<EvalStage> {
    let nets: Vec<(Kind, Mlp)> = trained.models.iter().map(|(k, m, _)| (*k, m.clone())).collect();
    let (scores, int8_agree) = score_all(&nets, &trained.quant, &trained.classes, test)?;
    let ours = &nets.iter().find(|(k, _)| *k == Kind::Ours).context("no `ours` model")?.1;
    let curve = accuracy_vs_time(ours, &trained.quant, &trained.classes, test);
    let stable10 = stable_by(&trained.quant, &trained.classes, test, 10.0);
    let (ece, reliability) =
        pbm_ml::evaluate::calibration(&pbm_ml::evaluate::final_confidences(&trained.quant, &trained.classes, test));
    Ok(EvalStage { classes: trained.classes.clone(), scores, int8_agree, curve, stable10, ece, reliability })
}

// ---------------------------------------------------------------------------------------------
// Stage 4: replay with CAN logging, decode

/// One fault report decoded from the log.
#[derive(Debug, Clone)]
pub struct DecodedReport {
    /// Trace it belongs to.
    pub file: String,
    /// True class of the trace.
    pub label: String,
    /// Log time since the log's epoch, µs.
    pub time_us: u64,
    /// Locomotive and release it belongs to.
    pub identity: Option<pbm::can::Identity>,
    /// The report.
    pub report: pbm::report::FaultReport,
}

/// What the CAN stage produced.
#[derive(Debug, Clone, Default)]
pub struct CanStage {
    /// Path of the candump log.
    pub log: PathBuf,
    /// Traces replayed.
    pub traces: usize,
    /// Frames in the log.
    pub frames: u64,
    /// Status frames decoded.
    pub status: usize,
    /// Session frames (release counts) decoded.
    pub sessions: usize,
    /// Fault reports decoded.
    pub reports: Vec<DecodedReport>,
    /// Frames the decoder flagged (CRC, counter, id, …) with the reason.
    pub flagged: Vec<String>,
    /// First lines of the log.
    pub head: Vec<String>,
    /// Release curves: (file, label, locomotive, NMSE %, t, measured, twin) per replayed trace.
    pub curves: Vec<ReleaseCurve>,
}

/// Measured and twin pressure of one replayed trace.
#[derive(Debug, Clone)]
pub struct ReleaseCurve {
    /// Trace file.
    pub file: String,
    /// True class.
    pub label: String,
    /// Locomotive.
    pub locomotive: String,
    /// NMSE of the nominal twin against the measurement, %.
    pub nmse_pct: Option<f64>,
    /// (t, measured bar g, twin bar g), decimated to 20 Hz.
    pub points: Vec<(f64, f64, f64)>,
}

/// The first `per_class` test traces of every class present, in class order.
pub fn sample_items(dir: &Path, per_class: usize) -> Result<Vec<TraceItem>> {
    let data = Dataset::open(dir)?;
    let mut out = Vec::new();
    for class in FaultClass::ALL {
        for r in data.rows().iter().filter(|r| r.split == "test" && r.label == class.label()).take(per_class) {
            out.push(TraceItem::from_row(&data, r)?);
        }
    }
    Ok(out)
}

/// Decodes a candump log with the core decoder; reports are attributed to `items` in order,
/// a new trace starting at every gap of more than half [`pbm_lab::replay::TRACE_GAP_US`]
/// (where the decoder finds the heartbeat lost and follows the restarted sender).
pub fn decode_log(log: &Path, items: &[TraceItem]) -> Result<CanStage> {
    let file = std::fs::File::open(log).with_context(|| format!("cannot open {}", log.display()))?;
    let mut st = CanStage { log: log.to_owned(), ..CanStage::default() };
    let mut decoder = Decoder::new();
    let mut segment = 0usize;
    let mut last_us: Option<u64> = None;
    for rec in pbm_io::can_log::read_log(std::io::BufReader::new(file)) {
        let rec = match rec {
            Ok(r) => r,
            Err(e) => {
                st.flagged.push(format!("line {}: {}", e.line, e.reason));
                continue;
            }
        };
        st.frames += 1;
        if st.head.len() < 12 {
            st.head.push(pbm_io::can_log::format_line(rec.time_us, &rec.iface, &rec.frame));
        }
        if last_us.is_some_and(|t| rec.time_us > t + pbm_lab::replay::TRACE_GAP_US / 2) {
            // Each trace is a fresh pipeline (a controller restarted for the next release):
            // its counters start again, which the display's decoder must not flag.
            segment += 1;
        }
        last_us = Some(rec.time_us);
        let reception = decoder.receive(rec.time_us, &rec.frame);
        match reception.result {
            Ok(Report::Status(_)) => st.status += 1,
            Ok(Report::Session(_)) => st.sessions += 1,
            Ok(Report::Fault(report)) => {
                let item = items.get(segment);
                st.reports.push(DecodedReport {
                    file: item.map_or_else(|| "?".to_owned(), |i| i.name.clone()),
                    label: item.and_then(|i| i.label.clone()).unwrap_or_default(),
                    // Seconds since the log's epoch (the replay's clock starts there).
                    time_us: rec.time_us.saturating_sub(pbm::can::candump::LOG_EPOCH_US),
                    identity: reception.identity,
                    report,
                });
            }
            Err(e) => {
                st.flagged.push(format!("{}: {e}", pbm_io::can_log::format_line(rec.time_us, &rec.iface, &rec.frame)))
            }
        }
    }
    Ok(st)
}

fn release_curve(item: &TraceItem) -> Result<ReleaseCurve> {
    let trace = pbm_io::trace::read_trace(&item.path)?;
    let samples = replay_trace(&trace)?;
    let label = item.label.clone().unwrap_or_default();
    let locomotive = item.locomotive.clone().unwrap_or_default();
    let summary = summarise(&item.name, &label, &locomotive, &samples);
    let points = samples
        .iter()
        .step_by(5)
        .map(|s| (s.t_s, if s.step.measured.is_ok() { s.measured_bar() } else { f64::NAN }, s.twin_bar()))
        .collect();
    Ok(ReleaseCurve { file: item.name.clone(), label, locomotive, nmse_pct: summary.nmse_pct, points })
}

fn can_stage(dir: &Path, out: &Path, per_class: usize) -> Result<CanStage> {
    let items = sample_items(dir, per_class.max(1))?;
    if items.is_empty() {
        bail!("{}: no test traces to replay", dir.display());
    }
    let can_dir = out.join("can");
    std::fs::create_dir_all(&can_dir).with_context(|| format!("cannot create {}", can_dir.display()))?;
    let log = can_dir.join("replay.log");
    let (frames, skipped) = pbm_lab::replay::replay_to_can_log(&log, &items)?;
    if !skipped.is_empty() {
        bail!("the demo's own traces could not be replayed\n{skipped}");
    }
    let mut st = decode_log(&log, &items)?;
    st.traces = items.len();
    if st.frames != frames {
        bail!("{}: wrote {frames} frames, read back {}", log.display(), st.frames);
    }
    // Release curves: the first replayed trace of each class.
    let mut firsts: Vec<&TraceItem> = Vec::new();
    for it in &items {
        if !firsts.iter().any(|f| f.label == it.label) {
            firsts.push(it);
        }
    }
    st.curves = firsts.par_iter().map(|it| release_curve(it)).collect::<Result<_>>()?;
    Ok(st)
}

// ---------------------------------------------------------------------------------------------
// Stage 5: estimator

fn estimator_stage(dir: &Path, test: &[TraceFeatures]) -> Result<Vec<EstimateCase>> {
    let data = Dataset::open(dir)?;
    let truth = estimate::read_truth(&data)?;
    test.par_iter()
        .map(|f| {
            let t = truth.get(&f.row.file).with_context(|| format!("{}: no row in {TRUTH}", f.row.file))?;
            let trace = data.read_trace(&f.row)?;
            estimate::evaluate(t.clone(), &trace.adc_counts(), 0)
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Stage 2b: audit

fn audit_stage(seed: u64) -> Result<AuditCase> {
    let case = draw_case(seed, &Mechanism::ALL)?;
    check_case(&case)
}

// ---------------------------------------------------------------------------------------------
// Stage 0: the fleet history

/// The fleet history of a run: the fleet table and every locomotive's page.
#[derive(Debug, Clone)]
pub struct FleetStage {
    /// The scenario the releases were drawn from.
    pub options: DegradationOptions,
    /// The history's directory (data set and database).
    pub dir: PathBuf,
    /// Releases stored.
    pub releases: usize,
    /// Ingest rate, releases per second (replay through the monitor included).
    pub per_second: f64,
    /// The fleet table (section `fleet`) with links to the pages.
    pub section: Section,
    /// Each locomotive's page: file name next to `index.html`, HTML.
    pub pages: Vec<(String, String)>,
}

/// Generates the fleet's releases (the slow-degradation scenario with a failing transducer),
/// ingests them into a fresh history and builds its pages. The directory is the demo's own: it
/// is replaced on every run, and refused when something else is there.
fn fleet_stage(a: &DemoOptions) -> Result<FleetStage> {
    let dir = a.out.join("fleet-history");
    let stamp = dir.join(FLEET_STAMP);
    if dir.exists() {
        if !stamp.is_file() {
            bail!("{} exists and was not written by `host-sim demo` (no {FLEET_STAMP}); remove it", dir.display());
        }
        std::fs::remove_dir_all(&dir).with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    let options = a.fleet_options();
    let data = dir.join("releases");
    pbm_fleet::scenario::write(&options, &data)?;
    std::fs::write(&stamp, format!("host-sim demo fleet history, seed {}\n", options.seed))
        .with_context(|| format!("cannot write {}", stamp.display()))?;
    let mut db = pbm_fleet::db::FleetDb::open(&dir.join("fleet.sqlite"))?;
    let ingested =
        pbm_fleet::ingest::ingest(&mut db, &[&data], &pbm_fleet::ingest::IngestOptions { threads: a.threads })?;
    if !ingested.skipped.is_empty() {
        bail!("the demo's own fleet releases could not all be stored\n{}", ingested.skipped);
    }
    let rule = pbm_fleet::trend::WarningRule::default();
    let (section, pages) = pbm_fleet::report::fleet_pages(&db, &rule, "index.html")?;
    let secs = ingested.elapsed.as_secs_f64();
    Ok(FleetStage {
        options,
        dir,
        releases: ingested.releases,
        per_second: if secs > 0.0 { ingested.releases as f64 / secs } else { 0.0 },
        section,
        pages,
    })
}

/// The real-data audit: the MetroPT-3 record's rows and the audit's outcome.
pub type MetroAudit = (Vec<MetroRow>, MetroOutcome);

// ---------------------------------------------------------------------------------------------
// Provenance

/// Facts that make the run reproducible.
#[derive(Debug, Clone)]
pub struct RunInfo {
    /// Seed.
    pub seed: u64,
    /// host-sim crate version.
    pub version: String,
    /// `git rev-parse HEAD` (with `+ uncommitted changes` when the tree differs), if available.
    pub git: Option<String>,
    /// `rustc --version` of the toolchain on PATH, if available.
    pub rustc: Option<String>,
    /// The command line.
    pub command: String,
    /// Start time (UTC).
    pub started: String,
    /// Worker threads.
    pub threads: usize,
    /// Load averages at the start (Linux).
    pub load: Option<String>,
}

fn command_output(cmd: &str, args: &[&str]) -> Option<String> {
    let out = std::process::Command::new(cmd).args(args).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_owned()).filter(|s| !s.is_empty())
}

fn run_info(a: &DemoOptions) -> RunInfo {
    let git = command_output("git", &["rev-parse", "HEAD"]).map(|c| {
        let dirty = command_output("git", &["status", "--porcelain", "--untracked-files=no"]).is_some();
        if dirty {
            format!("{c} + uncommitted changes")
        } else {
            c
        }
    });
    let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let args: Vec<String> = std::env::args().skip(1).collect();
    RunInfo {
        seed: a.seed,
        version: env!("CARGO_PKG_VERSION").to_owned(),
        git,
        rustc: command_output("rustc", &["--version"]),
        command: format!("host-sim {}", args.join(" ")),
        started: utc_text(now),
        threads: rayon::current_num_threads(),
        load: load_average(),
    }
}

// ---------------------------------------------------------------------------------------------
// Report

/// Everything the report is made of.
#[derive(Debug, Clone)]
pub struct DemoResults {
    /// Provenance.
    pub info: RunInfo,
    /// Generator options of the data set.
    pub generate: GenerateOptions,
    /// Data.
    pub data: DataStage,
    /// Trained models.
    pub trained: Trained,
    /// Evaluation.
    pub eval: EvalStage,
    /// CAN replay.
    pub can: CanStage,
    /// Estimator results on the test split.
    pub estimates: Vec<EstimateCase>,
    /// The audit case (or why it failed).
    pub audit: Result<AuditCase, String>,
    /// The real-data audit (or why it could not run).
    pub metro: Result<MetroAudit, String>,
    /// The fleet history.
    pub fleet: FleetStage,
    /// Firmware report: (path, modified time, text), if present.
    pub firmware: Option<(PathBuf, String, String)>,
    /// Stage wall times.
    pub stages: Vec<StageTime>,
    /// Wall time up to the report.
    pub total: Duration,
    /// CPU time of the process up to the report.
    pub cpu: Option<Duration>,
}

fn chart_svg(dir: &Path, name: &str, labels: ChartLabels<'_>, series: &[Series<'_>]) -> Result<String> {
    let path = dir.join(format!("{name}.svg"));
    write_line_chart(&path, labels, series)?;
    std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))
}

fn pct(v: f64) -> String {
    format!("{v:.1} %")
}

fn paper_pct(name: &str) -> Option<f64> {
    PAPER_REPORTED_PCT.iter().find(|(n, _)| *n == name).map(|p| p.1)
}

fn describe(name: &str) -> &'static str {
    match name {
        "paper_raw" => "21 statistics of the measured pressure; 8×8 sigmoid (paper protocol)",
        "paper_residual" => "21 statistics of measured − twin; 8×8 sigmoid (paper protocol)",
        "paper_theta" => "online-estimator parameters at 60 s; 8×8 sigmoid (paper protocol)",
        "ours_f64" => "online features at 18 times since the command; 32×32 ReLU, f64",
        "ours_int8" => "the same network quantized to int8, core integer inference",
        "core_compiled" => "the int8 model compiled into the core (trained earlier), with its cannot-diagnose rules",
        _ => "",
    }
}

fn confusion_table(s: &Score, classes: &[FaultClass]) -> Table {
    let mut header: Vec<&str> = vec!["truth \\ predicted"];
    header.extend(classes.iter().map(|c| c.label()));
    header.push("cannot diagnose");
    header.push("recall");
    let paper = paper_pct(&s.name).map_or_else(String::new, |p| format!("; paper reported {p} %"));
    let mut t = Table::new(format!("{}: {} this run{paper}", s.name, pct(s.accuracy_pct())), &header);
    for (ti, row) in s.confusion.iter().enumerate() {
        let total = row.iter().sum::<usize>().max(1) as f64;
        let mut cells = vec![Cell::strong(classes.get(ti).map_or("?", |c| c.label()))];
        for (pi, &v) in row.iter().enumerate() {
            let frac = v as f64 / total;
            let shade = (255.0 * (1.0 - 0.75 * frac)).round() as u8;
            let cell = Cell::text(v.to_string());
            cells.push(if v == 0 {
                cell
            } else if pi == ti {
                cell.with_background((shade, 255, shade))
            } else {
                cell.with_background((255, shade, shade))
            });
        }
        cells.push(Cell::text(pct(100.0 * row.get(ti).copied().unwrap_or(0) as f64 / total)));
        t.row(cells);
    }
    t
}

fn quantile(v: &mut [f64], q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    v.get(((v.len() - 1) as f64 * q).round() as usize).copied()
}

fn opt_num(v: Option<f64>, decimals: usize) -> String {
    v.map_or_else(|| "–".to_owned(), |x| format!("{x:.decimals$}"))
}

fn section_run(r: &DemoResults) -> Section {
    let i = &r.info;
    let mut s = Section::new("run", "Run");
    let mut t = Table::new("How to reproduce this page", &["item", "value"]);
    for (k, v) in [
        ("command", i.command.clone()),
        ("seed", i.seed.to_string()),
        ("host-sim version", i.version.clone()),
        ("git commit", i.git.clone().unwrap_or_else(|| "not available (no git checkout)".into())),
        ("rustc", i.rustc.clone().unwrap_or_else(|| "not available".into())),
        ("started", i.started.clone()),
        ("worker threads", i.threads.to_string()),
        ("load average at start (1, 5, 15 min)", i.load.clone().unwrap_or_else(|| "not available".into())),
        ("wall time (this run, up to the report)", format!("{:.1} s", r.total.as_secs_f64())),
        (
            "CPU time (this run, all threads)",
            r.cpu.map_or_else(|| "not available".to_owned(), |c| format!("{:.1} s", c.as_secs_f64())),
        ),
    ] {
        t.row(vec![Cell::text(k), Cell::mono(v)]);
    }
    s.push(Block::Table(t));
    let mut st = Table::new("Stages of this run", &["stage", "wall time", "CPU time", "what it did"]);
    for x in &r.stages {
        st.row(vec![
            Cell::text(&*x.name),
            Cell::text(format!("{:.1} s", x.elapsed.as_secs_f64())),
            Cell::text(x.cpu.map_or_else(|| "–".to_owned(), |c| format!("{:.1} s", c.as_secs_f64()))),
            Cell::text(&*x.detail),
        ]);
    }
    s.push(Block::Table(st));
    s.push(Block::Note(
        "Every number, table and plot on this page was computed by the run above, except the firmware cost \
         figures (read from the file named in that section) and the paper's reported accuracies (published \
         figures), which are labelled where they appear. Training and the audit run concurrently \
         (training ours keeps one core busy). Wall times depend on what else the machine runs; CPU times \
         (the whole process, all threads) do not."
            .into(),
    ));
    s
}

fn score<'a>(r: &'a DemoResults, name: &str) -> Option<&'a Score> {
    r.eval.scores.iter().find(|s| s.name == name)
}

fn audit_line(a: &AuditCase) -> (String, String) {
    let truth =
        a.truth.iter().map(|(e, v)| format!("{} = {v:.4} {}", e.name(), e.unit())).collect::<Vec<_>>().join(" + ");
    let truth = if truth.is_empty() { "none".to_owned() } else { truth };
    let terms = a.outcome.chosen.terms_text();
    let named = if terms.is_empty() { a.outcome.cause.clone() } else { terms.join(" + ") };
    (truth, named)
}

fn section_summary(r: &DemoResults) -> Section {
    let mut s = Section::new("summary", "Summary");
    let mut t = Table::new("Key results of this run", &["what", "this run", "reference"]);
    let n_test = r.data.test.len();
    for name in ["paper_raw", "paper_residual", "paper_theta", "ours_int8"] {
        if let Some(sc) = score(r, name) {
            let reference = paper_pct(name).map_or_else(
                || "paper's best: 96 % (reported)".to_owned(),
                |p| format!("paper reported {p} % (its real data)"),
            );
            t.row(vec![
                Cell::text(format!("test accuracy, {name} ({n_test} traces, held-out locomotives)")),
                Cell::strong(format!("{} ({}/{})", pct(sc.accuracy_pct()), sc.correct, sc.total)),
                Cell::text(reference),
            ]);
        }
    }
    t.row(vec![
        Cell::text("ours: int8 and f64 give the same class at 60 s"),
        Cell::strong(format!("{}/{n_test}", r.eval.int8_agree)),
        Cell::text("aim ≥ 249/250"),
    ]);
    t.row(vec![
        Cell::text("ours int8: correct and stable from some t ≤ 10 s on"),
        Cell::strong(pct(r.eval.stable10)),
        Cell::text("aim ≥ 95 %"),
    ]);
    t.row(vec![
        Cell::text("CAN: fault reports decoded from the replay log (core decoder)"),
        Cell::strong(format!(
            "{} reports, {} status frames, {} session frames, {} flagged",
            r.can.reports.len(),
            r.can.status,
            r.can.sessions,
            r.can.flagged.len()
        )),
        Cell::text(format!("{} frames in {}", r.can.frames, r.can.log.display())),
    ]);
    let correct_reports = r.can.reports.iter().filter(|d| verdict_class(&d.report) == Some(d.label.as_str())).count();
    t.row(vec![
        Cell::text("CAN: decoded diagnosis = true class"),
        Cell::strong(format!("{correct_reports}/{}", r.can.reports.len())),
        Cell::text("compiled-in core model"),
    ]);
    match &r.audit {
        Ok(a) => {
            let (truth, named) = audit_line(a);
            t.row(vec![
                Cell::text("audit: hidden effect → named cause"),
                Cell::strong(format!("{truth} → {named}")),
                Cell::text(if a.hit() { "hit (name, magnitude ±20 %, NMSE gain ≥ 5×)" } else { "MISS" }),
            ]);
            t.row(vec![
                Cell::text("audit: NMSE base → extended twin"),
                Cell::strong(format!(
                    "{:.3} % → {:.3} % ({:.0}×)",
                    a.outcome.base.nmse_pct,
                    a.outcome.chosen.nmse_pct,
                    a.outcome.base.nmse_pct / a.outcome.chosen.nmse_pct
                )),
                Cell::text("required gain ≥ 5×"),
            ]);
        }
        Err(e) => t.row(vec![Cell::text("audit"), Cell::strong("failed"), Cell::text(e.clone())]),
    }
    s.push(Block::Table(t));
    s
}

fn verdict_class(r: &pbm::report::FaultReport) -> Option<&'static str> {
    match r.verdict {
        pbm::report::Verdict::Class { class, .. } => Some(class.label()),
        pbm::report::Verdict::CannotDiagnose(_) => None,
    }
}

fn section_data(r: &DemoResults) -> Section {
    let g = &r.generate;
    let mut s = Section::new("data", "Fleet data set");
    s.push(Block::Para(format!(
        "{} traces in {} ({}): {} locomotives with their own manufacturing spread (±5 %), {} training and {} test \
         traces per class, test traces only from the {} held-out locomotives; 60 s at 100 Hz, 12-bit ADC with σ = 0.01 bar \
         noise, generator seed {}.",
        r.data.train.len() + r.data.test.len(),
        r.data.dir.display(),
        if r.data.reused { "reused: its stamp matched this seed, version and options" } else { "generated in this run" },
        g.locomotives,
        g.per_class,
        g.test_per_class,
        g.test_locomotives,
        g.seed
    )));
    let mut locos: Vec<String> =
        r.data.train.iter().chain(&r.data.test).map(|f| f.row.locomotive.clone()).collect::<Vec<_>>();
    locos.sort();
    locos.dedup();
    let mut header = vec!["class", "split"];
    header.extend(locos.iter().map(String::as_str));
    header.push("total");
    let mut t = Table::new("Traces per class, split and locomotive", &header);
    for class in &r.trained.classes {
        for (split, set) in [("train", &r.data.train), ("test", &r.data.test)] {
            let mine: Vec<&TraceFeatures> = set.iter().filter(|f| f.class == *class).collect();
            let mut row = vec![Cell::text(class.label()), Cell::text(split)];
            row.extend(
                locos.iter().map(|l| Cell::text(mine.iter().filter(|f| &f.row.locomotive == l).count().to_string())),
            );
            row.push(Cell::strong(mine.len().to_string()));
            t.row(row);
        }
    }
    s.push(Block::Table(t));
    s
}

fn section_classifiers(r: &DemoResults) -> Section {
    let mut s = Section::new("classifiers", "Classifiers: accuracy on the test split");
    let mut t = Table::new(
        format!("Accuracy at the end of the trace (60 s), {} test traces", r.data.test.len()),
        &["classifier", "inputs", "accuracy", "correct", "cannot diagnose", "paper reported", "epochs (best)"],
    );
    for sc in &r.eval.scores {
        let log = r.trained.models.iter().find(|(k, _, _)| k.name() == sc.name).map(|m| &m.2);
        t.row(vec![
            Cell::strong(&*sc.name),
            Cell::text(describe(&sc.name)),
            Cell::strong(pct(sc.accuracy_pct())),
            Cell::text(format!("{}/{}", sc.correct, sc.total)),
            Cell::text(sc.undiagnosed.to_string()),
            Cell::text(paper_pct(&sc.name).map_or_else(|| "–".to_owned(), |p| format!("{p} %"))),
            Cell::text(log.map_or_else(|| "–".to_owned(), |l| format!("{} ({})", l.epochs, l.best_epoch))),
        ]);
    }
    s.push(Block::Table(t));
    s.push(Block::Note(
        "Paper figures: the test accuracies the paper reports on its measured data (72 / 81.2 / 96 %). \
         This run's figures are on generated data from held-out locomotives. paper_theta uses the online \
         estimator's parameters (the project's substitute for the paper's batch θ fit)."
            .into(),
    ));
    s
}

fn section_confusion(r: &DemoResults) -> Section {
    let mut s = Section::new("confusion", "Confusion matrices");
    s.push(Block::Para(
        "Rows: true class; columns: predicted class and 'cannot diagnose'. Green: correct; red: confused. The paper \
         gives its three matrices only as images (its Fig. 8a–c); its reported accuracies are shown in each caption."
            .into(),
    ));
    for name in ["ours_int8", "paper_raw", "paper_residual", "paper_theta"] {
        if let Some(sc) = score(r, name) {
            s.push(Block::Table(confusion_table(sc, &r.eval.classes)));
        }
    }
    s
}

fn section_early(r: &DemoResults, svg_dir: &Path) -> Result<Section> {
    let mut s = Section::new("early", "Early diagnosis: accuracy vs time since the release command");
    let f: Vec<(f64, f64)> = r.eval.curve.iter().map(|c| (c.0, c.1)).collect();
    let q: Vec<(f64, f64)> = r.eval.curve.iter().map(|c| (c.0, c.2)).collect();
    let svg = chart_svg(
        svg_dir,
        "accuracy_vs_time",
        ChartLabels { title: "ours: test accuracy vs time since release command", x: "t, s", y: "accuracy, %" },
        &[
            Series { label: "ours f64", points: f, color: OKABE_ITO[0] },
            Series { label: "ours int8", points: q, color: OKABE_ITO[1] },
        ],
    )?;
    s.push(Block::Figure {
        svg,
        caption: format!(
            "Correct and stable (int8) from some t ≤ 10 s on: {}. Snapshot times: {} s.",
            pct(r.eval.stable10),
            SNAPSHOT_TIMES_S.iter().map(|t| format!("{t}")).collect::<Vec<_>>().join(", ")
        ),
    });
    let mut t = Table::new("Accuracy of ours at each snapshot", &["t since command", "f64", "int8"]);
    for (tt, f, q) in &r.eval.curve {
        t.row(vec![Cell::text(format!("{tt:.2} s")), Cell::text(pct(*f)), Cell::text(pct(*q))]);
    }
    s.push(Block::Table(t));
    // Calibration: the confidence sent on CAN against how often the class is right.
    let used: Vec<&pbm_ml::evaluate::ReliabilityBin> = r.eval.reliability.iter().filter(|b| b.n > 0).collect();
    let svg = chart_svg(
        svg_dir,
        "reliability",
        ChartLabels { title: "reliability of the confidence sent (int8)", x: "confidence, %", y: "accuracy, %" },
        &[
            Series { label: "perfectly calibrated", points: vec![(0.0, 0.0), (100.0, 100.0)], color: OKABE_ITO[2] },
            Series {
                label: "observed",
                points: used.iter().map(|b| (100.0 * b.confidence, 100.0 * b.accuracy)).collect(),
                color: OKABE_ITO[1],
            },
        ],
    )?;
    s.push(Block::Figure {
        svg,
        caption: format!(
            "Expected calibration error {} over the test releases (15 equal-width bins; the softmax temperature \
             is fitted on releases held out of training; the monitor sends at most 99 %).",
            pct(100.0 * r.eval.ece)
        ),
    });
    let mut t = Table::new("Reliability bins", &["mean confidence", "accuracy", "releases"]);
    for b in used {
        t.row(vec![
            Cell::text(pct(100.0 * b.confidence)),
            Cell::text(pct(100.0 * b.accuracy)),
            Cell::text(b.n.to_string()),
        ]);
    }
    s.push(Block::Table(t));
    Ok(s)
}

fn section_release(r: &DemoResults, svg_dir: &Path) -> Result<Section> {
    let mut s = Section::new("release", "Release curves per class: measured vs twin");
    s.push(Block::Para(
        "One test trace per class replayed sample by sample through the core monitor (the firmware's code): the \
         measured chamber pressure (ADC counts → bar) and the nominal twin driven by the same valve command."
            .into(),
    ));
    let mut figs = Vec::new();
    for c in &r.can.curves {
        let m: Vec<(f64, f64)> = c.points.iter().map(|p| (p.0, p.1)).collect();
        let tw: Vec<(f64, f64)> = c.points.iter().map(|p| (p.0, p.2)).collect();
        let title = format!("{} ({})", c.label, c.locomotive);
        let svg = chart_svg(
            svg_dir,
            &format!("release_{}", c.label),
            ChartLabels { title: &title, x: "t, s", y: "pressure, bar g" },
            &[
                Series { label: "measured", points: m, color: OKABE_ITO[0] },
                Series { label: "nominal twin", points: tw, color: OKABE_ITO[1] },
            ],
        )?;
        let nmse = c.nmse_pct.map_or_else(|| "n/a".to_owned(), |v| format!("{v:.2} %"));
        figs.push((svg, format!("{}: {} — NMSE of the nominal twin {nmse}", c.label, c.file)));
    }
    s.push(Block::Gallery(figs));
    Ok(s)
}

fn section_can(r: &DemoResults) -> Section {
    let c = &r.can;
    let mut s = Section::new("can", "CAN fault reports as the cab display shows them");
    s.push(Block::Para(format!(
        "{} test traces replayed through the monitor exactly as the controller runs it (twin, estimator, \
         diagnosis policy, CAN transmit schedule) into the candump log {}; the log read back and decoded with the core's \
         decoder (CRC, rolling counter, signal ranges): {} frames, {} status frames, {} session frames, {} fault reports, {} flagged.",
        c.traces,
        c.log.display(),
        c.frames,
        c.status,
        c.sessions,
        c.reports.len(),
        c.flagged.len()
    )));
    let mut t = Table::new(
        "Decoded fault reports",
        &[
            "trace",
            "true class",
            "log time",
            "diagnosis",
            "confidence",
            "supply",
            "leak",
            "since command",
            "release",
            "cab display line",
        ],
    );
    for d in &c.reports {
        let rep = &d.report;
        let ok = verdict_class(rep) == Some(d.label.as_str());
        let diag = Cell::strong(pbm_lab::can_cmd::verdict_label(&rep.verdict));
        t.row(vec![
            Cell::text(&*d.file),
            Cell::text(&*d.label),
            Cell::text(format!("{:.2} s", d.time_us as f64 / 1e6)),
            if ok { diag.with_background((214, 245, 214)) } else { diag.with_background((250, 214, 214)) },
            Cell::text(
                pbm_lab::can_cmd::confidence_pct(&rep.verdict).map_or_else(|| "–".to_owned(), |p| format!("{p:.0} %")),
            ),
            Cell::text(if rep.supply_mbar == 0 {
                "–".to_owned()
            } else {
                format!("{:.3} bar", f64::from(rep.supply_mbar) / 1000.0)
            }),
            Cell::text(format!("{:.3} mm", f64::from(rep.leak_um) / 1000.0)),
            Cell::text(format!("{:.1} s", f64::from(rep.time_since_release_cs) / 100.0)),
            Cell::text(if rep.release_completed { "completed" } else { "in progress" }),
            Cell::mono(pbm_lab::can_cmd::fault_line(d.time_us, d.identity, rep).trim().to_owned()),
        ]);
    }
    s.push(Block::Table(t));
    if !c.flagged.is_empty() {
        s.push(Block::Pre(format!("flagged frames:\n{}", c.flagged.join("\n"))));
    }
    s.push(Block::Heading("First lines of the log".into()));
    s.push(Block::Pre(c.head.join("\n")));
    s
}

fn section_estimator(r: &DemoResults, svg_dir: &Path) -> Result<Section> {
    let mut s = Section::new("estimator", "Online estimator: parameters vs truth");
    s.push(Block::Para(format!(
        "The core's recursive-least-squares estimator run over each of the {} test traces (valve open, 100 Hz); \
         its final estimates of the effective inlet orifice, leak and supply, coloured by true class, and their \
         errors against the generator's truth (diameters against the effective truth for the nominal Cf and V0).",
        r.estimates.len()
    )));
    let mut figs = Vec::new();
    for (x, y) in [(Param::Orifice, Param::Leak), (Param::Orifice, Param::Supply), (Param::Leak, Param::Supply)] {
        let path = svg_dir.join(format!("scatter_{}_{}.svg", x.name(), y.name()));
        let n = estimate::scatter_svg(&path, &r.estimates, x, y)?;
        let svg = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
        figs.push((svg, format!("{} vs {} ({n} traces)", y.name(), x.name())));
    }
    s.push(Block::Gallery(figs));
    let mut t = Table::new(
        "|estimate − truth| at 60 s and settling time within 10 %",
        &["class", "parameter", "n", "median error", "90th pct error", "no estimate", "median settle", "never settled"],
    );
    for class in &r.trained.classes {
        let rs: Vec<&EstimateCase> = r.estimates.iter().filter(|c| c.truth.label == class.label()).collect();
        for (i, p) in Param::ALL.into_iter().enumerate() {
            let mut err: Vec<f64> = rs.iter().filter_map(|c| c.rls(p).map(|v| (v - c.truth.value(p)).abs())).collect();
            let none = rs.len() - err.len();
            let mut settle: Vec<f64> = rs.iter().filter_map(|c| c.settle_s[i]).collect();
            let unset = rs.len() - settle.len();
            let unit = if p == Param::Supply { "bar" } else { "mm" };
            t.row(vec![
                Cell::text(class.label()),
                Cell::text(p.name()),
                Cell::text(rs.len().to_string()),
                Cell::text(format!("{} {unit}", opt_num(quantile(&mut err, 0.5), 4))),
                Cell::text(format!("{} {unit}", opt_num(quantile(&mut err, 0.9), 4))),
                Cell::text(none.to_string()),
                Cell::text(format!("{} s", opt_num(quantile(&mut settle, 0.5), 1))),
                Cell::text(unset.to_string()),
            ]);
        }
    }
    s.push(Block::Table(t));
    Ok(s)
}

/// A metro mechanism and its magnitude in words, with its unit.
fn metro_effect_words(m: Mechanism, v: f64, u: f64) -> String {
    let what = match m {
        Mechanism::HeatTransfer => "heat exchange between the compressed air and the reservoir wall, time constant",
        Mechanism::TransportDelay => "a delay before the compressor's air reaches the reservoir of",
        Mechanism::ValveLag => "the compressor's delivery building up after it loads, time constant",
        Mechanism::SensorLag => "a lag of the pressure transducer of",
        Mechanism::SensorOffset => "a zero offset of the pressure transducer of",
        Mechanism::SensorGain => "a gain error of the pressure transducer, factor",
        Mechanism::LaminarLeak => "an extra leak growing with the pressure, at 7 bar g",
        _ => "an effect of magnitude",
    };
    let unit = if m.unit() == "1" { String::new() } else { format!(" {}", m.unit()) };
    format!("{what} {v:.2} ± {u:.2}{unit}")
}

/// A brake mechanism and its magnitude in words, with its unit (the library's own name with
/// spaces; a ratio has no unit).
fn effect_words(m: Mechanism, v: f64) -> String {
    let unit = if m.unit() == "1" { " (ratio)".to_owned() } else { format!(" {}", m.unit()) };
    format!("{} {v:.4}{unit}", m.name().replace('_', " "))
}

/// The synthetic and the real-data audit side by side, in words and physical units.
fn audits_side_by_side(r: &DemoResults) -> Table {
    let mut t = Table::new(
        "The two audits side by side",
        &["", "Synthetic brake releases with a hidden effect", "Real record: MetroPT-3 air production unit"],
    );
    let (mut syn, mut real): (Vec<String>, Vec<String>) = (Vec::new(), Vec::new());
    let rows = [
        "data",
        "model audited",
        "verdict",
        "residual of the base → the chosen model, in transducer noise",
        "noise of the measurement",
        "error common to every cycle vs the variation between cycles",
        "what is still missing",
    ];
    match &r.audit {
        Ok(a) => {
            let o = &a.outcome;
            let truth = a.truth.iter().map(|(m, v)| effect_words(*m, *v)).collect::<Vec<_>>().join(" and ");
            let named = if o.cause_effects.is_empty() {
                o.cause.replace('_', " ")
            } else {
                o.cause_effects
                    .iter()
                    .map(|(m, v, _)| effect_words(*m, *v))
                    .chain(o.cause_parameter.map(|(p, v, _)| format!("{} at {v:.2} × documented", p.replace('_', " "))))
                    .collect::<Vec<_>>()
                    .join(" and ")
            };
            syn.push(format!(
                "{} noisy releases of one brake, generated with a hidden {truth}",
                pbm_lab::audit_sweep::RELEASES_PER_CASE
            ));
            syn.push("the brake twin: spring chamber, piston and valve, adiabatic air".to_owned());
            syn.push(format!(
                "names {named}{}",
                if a.hit() { " — the hidden effect, right size" } else { " — a miss" }
            ));
            syn.push(format!(
                "{:.1}× → {:.1}× (at the noise floor up to {})",
                o.residual_to_noise.0,
                o.residual_to_noise.1,
                pbm_lab::audit::NOISE_FLOOR_RATIO
            ));
            syn.push(format!("{:.4} bar per sample (estimated)", o.diagnostics.sigma_trace_bar));
            syn.push("not applicable: the releases are repeats of one brake".to_owned());
            syn.push(if o.residual_to_noise.1 <= pbm_lab::audit::NOISE_FLOOR_RATIO {
                "nothing beyond the noise".to_owned()
            } else {
                "part of the discrepancy stays unexplained".to_owned()
            });
        }
        Err(e) => syn.extend(rows.iter().map(|_| format!("failed: {e}"))),
    }
    match &r.metro {
        Ok((data, m)) => {
            let hours = data.last().map_or(0.0, |x| x.t_s / 3600.0);
            real.push(format!(
                "{:.1} h of the reservoir pressure of a Porto metro train's air production unit, one sample about every 10 s ({} samples), with the compressor's load signal",
                hours,
                data.len()
            ));
            real.push(
                "the reservoir model built from the twin's parts: the compressor as an air source while it is loaded, consumption and leakage as an orifice to atmosphere, adiabatic air; candidates add the library's effects and a wall that stores heat"
                    .to_owned(),
            );
            let named = if m.chosen.effects.is_empty() {
                match m.cause.as_str() {
                    "none" => "no missing effect".to_owned(),
                    _ => "a discrepancy no effect of the library explains".to_owned(),
                }
            } else {
                m.chosen
                    .effects
                    .iter()
                    .map(|(e, v, u)| metro_effect_words(*e, *v, *u))
                    .chain(m.chosen.wall.map(|(w, [ue, ut])| {
                        format!(
                            "a reservoir wall that stores the heat and gives it back: its heat capacity {:.1} ± {:.1} \
                             times the air's, cooling with a time constant of {:.0} ± {:.0} s",
                            1.0 / w.capacity_ratio,
                            ue / w.capacity_ratio.powi(2),
                            w.cooling_s,
                            ut
                        )
                    }))
                    .collect::<Vec<_>>()
                    .join("; and ")
            };
            let part = if m.residual_to_noise.1 <= pbm_lab::audit::NOISE_FLOOR_RATIO {
                "explains the discrepancy"
            } else {
                "explains part of the discrepancy"
            };
            real.push(format!("names {named}: {part}"));
            real.push(format!(
                "{:.1}× → {:.1}× (at the noise floor up to {}){}",
                m.residual_to_noise.0,
                m.residual_to_noise.1,
                pbm_lab::audit::NOISE_FLOOR_RATIO,
                match (m.base.held_out, m.chosen.held_out, m.record_floor) {
                    (Some(b), Some(c), Some(f)) => format!(
                        "; on compressor cycles it was not fitted to, the error falls from {:.3} % to {:.3} %, where \
                         this record allows {:.3} % at best",
                        b.nmse_pct, c.nmse_pct, f.nmse_pct
                    ),
                    _ => String::new(),
                }
            ));
            real.push(format!("{:.4} bar per sample (estimated)", m.sigma));
            real.push(match &m.cycle_floor {
                Some(f) => format!(
                    "the {} compressor cycles differ from each other by {:.3} bar RMS ({:.0}× the noise: air consumption the record does not hold, which no model driven by the load signal alone can follow); the error common to all cycles is {:.3} bar RMS, {}",
                    f.cycles,
                    f.spread_bar,
                    f.spread_bar / m.sigma,
                    f.systematic_bar,
                    if f.systematic() {
                        format!(
                            "beyond that variation at {:.0} % of the times (chance at most {:.1} %): the model still errs the same way in every cycle",
                            100.0 * f.share_beyond,
                            100.0 * f.p_at_most()
                        )
                    } else {
                        "within that variation: the rest changes from cycle to cycle".to_owned()
                    }
                ),
                None => "fewer than three complete compressor cycles: not measured".to_owned(),
            });
            let mut missing = pbm_lab::metro::describe_aligned(&m.missing);
            for e in &m.events {
                missing.push_str(&format!("; not a missing effect but {}", e.describe()));
            }
            real.push(missing);
        }
        Err(e) => real.extend(rows.iter().map(|_| format!("not run: {e}"))),
    }
    for ((what, a), b) in rows.iter().zip(syn).zip(real) {
        t.row(vec![Cell::strong(*what), Cell::text(a), Cell::text(b)]);
    }
    t
}

fn section_audit(r: &DemoResults) -> Result<Section> {
    let mut s = Section::new("audit", "Model-discrepancy audits: synthetic releases and a real record");
    s.push(Block::Para(
        "The audit asks whether the model misses a physical effect, and which: it fits the model with each candidate effect of its library added, keeps an effect only when the data need it, and compares what is left with the measurement noise. It ran twice: on generated brake releases with an effect hidden in them (the answer is known), and on a real compressed-air record, where it is not."
            .into(),
    ));
    s.push(Block::Table(audits_side_by_side(r)));
    if let Ok((rows, m)) = &r.metro {
        s.push(Block::Figure {
            svg: pbm_lab::metro::curves_svg(rows, m)?,
            caption: "Real record: the measured reservoir pressure, the adiabatic base model and the model with the effects the audit named, over the whole record."
                .into(),
        });
        s.push(Block::Figure {
            svg: pbm_lab::metro::residual_svg(rows, m)?,
            caption: "Real record: what each model leaves (measured − model), bar.".into(),
        });
    }
    s.push(Block::Heading("The synthetic audit in detail".into()));
    let a = match &r.audit {
        Ok(a) => a,
        Err(e) => {
            s.push(Block::Para(format!("The audit failed in this run: {e}")));
            return Ok(s);
        }
    };
    let o = &a.outcome;
    s.push(Block::Para(format!(
        "A mechanism the base twin lacks and its magnitude were drawn from seed {} (\
         uniformly over the {} mechanisms of the plant library, inside physically plausible ranges); {} noisy releases of \
         one locomotive were generated with it and audited without being told what it was.",
        r.info.seed,
        Mechanism::ALL.len(),
        pbm_lab::audit_sweep::RELEASES_PER_CASE
    )));
    let (truth, named) = audit_line(a);
    let mut t = Table::new("Hidden truth vs the audit's verdict", &["", "value"]);
    t.row(vec![Cell::text("hidden effect (truth)"), Cell::strong(truth)]);
    t.row(vec![Cell::text("named cause (audit)"), Cell::strong(named)]);
    t.row(vec![Cell::text("right name"), Cell::text(if a.name_ok { "yes" } else { "no" })]);
    t.row(vec![Cell::text("magnitude within 20 %"), Cell::text(if a.magnitude_ok { "yes" } else { "no" })]);
    t.row(vec![
        Cell::text("NMSE base → extended"),
        Cell::text(format!(
            "{:.3} % → {:.3} % (gain {:.1}×{})",
            o.base.nmse_pct,
            o.chosen.nmse_pct,
            o.base.nmse_pct / o.chosen.nmse_pct,
            if a.gain_ok { ", ≥ 5×" } else { ", below 5×" }
        )),
    ]);
    t.row(vec![
        Cell::text("noise σ per trace (estimated)"),
        Cell::text(format!("{:.4} bar", o.diagnostics.sigma_trace_bar)),
    ]);
    t.row(vec![
        Cell::text("Ljung–Box Q(20) of the base residual"),
        Cell::text(format!("{:.1} (white below 31.4)", o.diagnostics.ljung_box_q)),
    ]);
    s.push(Block::Table(t));
    let mut ph = Table::new(
        "Where the base twin's error sits (by release phase)",
        &["phase", "samples", "RMS", "bias", "share of SSE"],
    );
    for p in &o.diagnostics.phases {
        ph.row(vec![
            Cell::text(p.phase),
            Cell::text(p.samples.to_string()),
            Cell::text(format!("{:.4} bar", p.rms_bar)),
            Cell::text(format!("{:+.4} bar", p.bias_bar)),
            Cell::text(pct(p.sse_share_pct)),
        ]);
    }
    s.push(Block::Table(ph));
    let mut rk = Table::new(
        "Candidate extensions, best first (ΔBIC against the base twin)",
        &["candidate", "ΔBIC", "RSS ratio", "NMSE", "magnitudes"],
    );
    for c in o.ranking.iter().take(10) {
        rk.row(vec![
            Cell::text(&*c.name),
            Cell::text(format!("{:.1}", c.delta_bic)),
            Cell::text(format!("{:.2}", o.base.rss / c.rss)),
            Cell::text(format!("{:.3} %", c.nmse_pct)),
            Cell::text(
                c.effects
                    .iter()
                    .map(|(e, v, u)| format!("{} = {v:.4} ± {u:.4} {}", e.name(), e.unit()))
                    .collect::<Vec<_>>()
                    .join(", "),
            ),
        ]);
    }
    s.push(Block::Table(rk));
    if let Some(c) = o.curves.first() {
        s.push(Block::Figure {
            svg: pbm_lab::audit_plot::residual_svg(o, c)?,
            caption: "Residual of the base and the extended twin against time (green: breakaway and end stop of the base twin)."
                .into(),
        });
        s.push(Block::Figure {
            svg: pbm_lab::audit_plot::curves_svg(o, c)?,
            caption: "Mean of the measured releases, the fitted base twin and the extended twin.".into(),
        });
    }
    s.push(Block::Figure {
        svg: pbm_lab::audit_plot::acf_svg(o)?,
        caption: "Whiteness: residual autocorrelation.".into(),
    });
    Ok(s)
}

fn section_firmware(r: &DemoResults) -> Section {
    let mut s = Section::new("firmware", "Firmware cost on the Cortex-M4F");
    let Some((path, modified, text)) = &r.firmware else {
        s.push(Block::Para(format!(
            "No firmware figures found ({} is written by the firmware benchmark, cargo xtask fw-bench, after a \
             target build); nothing to show.",
            DemoOptions::default().firmware_report.display()
        )));
        return s;
    };
    let fig: BTreeMap<&str, &str> = text
        .lines()
        .filter(|l| !l.trim_start().starts_with('#'))
        .filter_map(|l| l.split_once('='))
        .map(|(k, v)| (k.trim(), v.trim()))
        .collect();
    let get = |k: &str| fig.get(k).copied().unwrap_or("?");
    s.push(Block::Callout(format!(
        "Read from {} (last modified {modified}; measured {} in {}). These figures were not computed in this run.",
        path.display(),
        get("date"),
        get("emulator")
    )));
    let mut t = Table::new(
        "What the monitor costs the brake controller (instructions counted in the emulator, one per nanosecond)",
        &["figure", "measured", "budget"],
    );
    let rows = [
        (
            "computation per 10 ms pressure sample, mean / worst (nominal release)",
            format!("{} / {} instructions", get("instr_per_sample_mean"), get("instr_per_sample_worst_nominal")),
            format!("≤ {} instructions", get("instr_budget")),
        ),
        (
            "worst sample over every measured recording",
            format!("{} instructions", get("instr_per_sample_worst")),
            format!("≤ {} instructions", get("instr_budget")),
        ),
        ("one classification (once per release)", format!("{} instructions", get("classify_instr")), String::new()),
        (
            "the sample that closes a diagnosis and sends the report",
            format!("{} instructions", get("closing_sample_instr")),
            "< 250000 instructions (10 ms at 25 MHz)".to_owned(),
        ),
        (
            "program memory (flash)",
            format!("{} bytes", get("flash_bytes")),
            format!("≤ {} bytes", get("flash_budget_bytes")),
        ),
        (
            "working memory (static data + deepest stack)",
            format!("{} bytes ({} + {})", get("ram_bytes"), get("static_ram_bytes"), get("peak_stack_bytes")),
            format!("≤ {} bytes", get("ram_budget_bytes")),
        ),
    ];
    for (what, value, budget) in rows {
        t.row(vec![Cell::text(what), Cell::strong(value), Cell::text(budget)]);
    }
    s.push(Block::Table(t));
    s
}

/// Builds the page from a run's results (writes the charts' SVG files into `svg_dir`).
pub fn build_page(r: &DemoResults, svg_dir: &Path) -> Result<Page> {
    std::fs::create_dir_all(svg_dir).with_context(|| format!("cannot create {}", svg_dir.display()))?;
    let sections = vec![
        r.fleet.section.clone(),
        section_run(r),
        section_summary(r),
        section_data(r),
        section_classifiers(r),
        section_confusion(r),
        section_early(r, svg_dir)?,
        section_release(r, svg_dir)?,
        section_can(r),
        section_estimator(r, svg_dir)?,
        section_audit(r)?,
        section_firmware(r),
    ];
    Ok(Page {
        title: "Spring parking brake monitor — demo report".into(),
        subtitle: format!(
            "host-sim {} · seed {} · {} · {}",
            r.info.version,
            r.info.seed,
            r.info.started,
            r.info.git.as_deref().unwrap_or("no git commit")
        ),
        sections,
    })
}

fn firmware_report(path: &Path) -> Option<(PathBuf, String, String)> {
    let text = std::fs::read_to_string(path).ok()?;
    let modified = std::fs::metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or_else(|| "unknown".to_owned(), |d| utc_text(d.as_secs()));
    Some((path.to_owned(), modified, text))
}

/// The terminal summary.
pub fn summary_text(r: &DemoResults, report: &Path) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nhost-sim demo — seed {} — {} training + {} test traces",
        r.info.seed,
        r.data.train.len(),
        r.data.test.len()
    );
    let _ = writeln!(s, "{:<16} {:>9} {:>10} {:>8}", "classifier", "accuracy", "correct", "paper");
    for sc in &r.eval.scores {
        let _ = writeln!(
            s,
            "{:<16} {:>8.1}% {:>10} {:>8}",
            sc.name,
            sc.accuracy_pct(),
            format!("{}/{}", sc.correct, sc.total),
            paper_pct(&sc.name).map_or_else(String::new, |p| format!("{p} %"))
        );
    }
    let _ = writeln!(
        s,
        "ours int8 = f64 on {}/{} test traces; correct and stable by 10 s: {:.1} %",
        r.eval.int8_agree,
        r.data.test.len(),
        r.eval.stable10
    );
    let _ = writeln!(
        s,
        "CAN replay: {} frames, {} fault reports decoded, {} flagged",
        r.can.frames,
        r.can.reports.len(),
        r.can.flagged.len()
    );
    match &r.audit {
        Ok(a) => {
            let (truth, named) = audit_line(a);
            let _ = writeln!(
                s,
                "audit: hidden {truth} → named {named}; NMSE {:.3} → {:.3} % ({})",
                a.outcome.base.nmse_pct,
                a.outcome.chosen.nmse_pct,
                if a.hit() { "hit" } else { "MISS" }
            );
        }
        Err(e) => {
            let _ = writeln!(s, "audit: FAILED: {e}");
        }
    }
    let stages: Vec<String> = r.stages.iter().map(|x| format!("{} {:.1} s", x.name, x.elapsed.as_secs_f64())).collect();
    let _ = writeln!(s, "stages: {}", stages.join(", "));
    let cpu = r.cpu.map_or_else(String::new, |c| format!(" (CPU {:.1} s, all threads)", c.as_secs_f64()));
    let _ = writeln!(s, "total wall time {:.1} s{cpu}", r.total.as_secs_f64());
    let _ = writeln!(s, "report: {}", report.display());
    s
}

/// The main job: every stage, the report written to `a.out`.
pub fn run(a: &DemoOptions) -> Result<()> {
    if a.threads > 0 {
        let pool =
            rayon::ThreadPoolBuilder::new().num_threads(a.threads).build().context("cannot start worker threads")?;
        pool.install(|| run_in_pool(a))
    } else {
        run_in_pool(a)
    }
}

fn run_in_pool(a: &DemoOptions) -> Result<()> {
    let start = Instant::now();
    let info = run_info(a);
    let g = a.generate_options();
    let mut p = Progress::new(6);
    std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;

    // 1. data
    let t = Instant::now();
    eprintln!("[1/6] fleet data set {} (seed {}) …", g.out.display(), g.seed);
    let bar = p.spinner(1, "fleet data set");
    let data = data_stage(&g)?;
    let detail = format!(
        "{} {} traces with their features",
        if data.reused { "reused" } else { "generated" },
        data.train.len() + data.test.len()
    );
    p.done(&bar, 1, "fleet data set", t.elapsed(), detail);

    // 2. training ‖ audit
    let t = Instant::now();
    let bar_t = p.spinner(2, "training 4 classifiers + int8 quantization");
    let bar_a = p.spinner(2, "audits (hidden effect, real record) and the fleet history");
    // Training `ours` keeps one core busy; the audits and the fleet history share the other.
    let ((trained, t_train), ((audit, t_audit), (metro, t_metro), (fleet, t_fleet))) = rayon::join(
        || {
            let t0 = Instant::now();
            let r = train_all(&data.train, a.seed);
            bar_t.finish_and_clear();
            (r, t0.elapsed())
        },
        || {
            let t0 = Instant::now();
            let r = audit_stage(a.seed).map_err(|e| format!("{e:#}"));
            let audit = (r, t0.elapsed());
            let t0 = Instant::now();
            let m = pbm_lab::metro::audit_metro_file(&a.metro).map_err(|e| format!("{e:#}"));
            let metro = (m, t0.elapsed());
            let t0 = Instant::now();
            let f = fleet_stage(a);
            let fleet = (f, t0.elapsed());
            bar_a.finish_and_clear();
            (audit, metro, fleet)
        },
    );
    let trained = trained?;
    let fleet = fleet.context("the fleet history")?;
    let epochs =
        trained.models.iter().map(|(k, _, l)| format!("{} {}", k.name(), l.epochs)).collect::<Vec<_>>().join(", ");
    let cause = match &audit {
        Ok(c) => format!("cause {}", c.outcome.cause),
        Err(e) => format!("FAILED: {e}"),
    };
    let metro_cause = match &metro {
        Ok((_, m)) => format!("cause {}", m.cause),
        Err(e) => format!("FAILED: {e}"),
    };
    let detail = format!(
        "training {:.1} s (epochs: {epochs}) concurrently with the audit {:.1} s ({cause}), the real-data audit \
         {:.1} s ({metro_cause}) and the fleet history {:.1} s ({} releases of {} locomotives, ingested at {:.0} \
         releases/s)",
        t_train.as_secs_f64(),
        t_audit.as_secs_f64(),
        t_metro.as_secs_f64(),
        t_fleet.as_secs_f64(),
        fleet.releases,
        fleet.options.wear.len(),
        fleet.per_second
    );
    p.done(&bar_t, 2, "training ‖ audits + fleet history", t.elapsed(), detail);

    // 3. evaluation
    let t = Instant::now();
    let bar = p.spinner(3, "evaluation");
    let eval = eval_stage(&trained, &data.test)?;
    let ours = eval.scores.iter().find(|s| s.name == "ours_int8").map_or(0.0, Score::accuracy_pct);
    p.done(&bar, 3, "evaluation", t.elapsed(), format!("{} test traces, ours int8 {}", data.test.len(), pct(ours)));

    // 4. replay with CAN logging
    let t = Instant::now();
    let bar = p.spinner(4, "replay with CAN logging");
    let can = can_stage(&data.dir, &a.out, a.can_per_class)?;
    let detail =
        format!("{} frames, {} fault reports decoded, {} flagged", can.frames, can.reports.len(), can.flagged.len());
    p.done(&bar, 4, "replay + CAN decode", t.elapsed(), detail);

    // 5. estimator
    let t = Instant::now();
    let bar = p.spinner(5, "online estimator vs truth");
    let estimates = estimator_stage(&data.dir, &data.test)?;
    p.done(&bar, 5, "estimator", t.elapsed(), format!("{} test traces", estimates.len()));

    // 6. report
    let t = Instant::now();
    let bar = p.spinner(6, "report");
    let mut results = DemoResults {
        info,
        generate: g,
        data,
        trained,
        eval,
        can,
        estimates,
        audit,
        metro,
        fleet,
        firmware: firmware_report(&a.firmware_report),
        stages: p.times.clone(),
        total: start.elapsed(),
        cpu: process_cpu_time(),
    };
    let svg_dir = a.out.join("svg");
    let mut page = build_page(&results, &svg_dir)?;
    results.total = start.elapsed();
    results.cpu = process_cpu_time();
    results.stages.push(StageTime {
        name: "report".into(),
        elapsed: t.elapsed(),
        cpu: None,
        detail: "page built".into(),
    });
    // The run section states the final figures (built last, everything else is unchanged).
    page.sections[1] = section_run(&results);
    let html = render(&page);
    let found = check(&html, &REQUIRED_SECTIONS).map_err(|e| anyhow::anyhow!("the report fails its own check: {e}"))?;
    let index = a.out.join("index.html");
    // The locomotive pages first: the index links to them.
    for (name, page) in &results.fleet.pages {
        let path = a.out.join(name);
        std::fs::write(&path, page).with_context(|| format!("cannot write {}", path.display()))?;
    }
    std::fs::write(&index, &html).with_context(|| format!("cannot write {}", index.display()))?;
    let detail = format!(
        "{} sections, {} plots, {} tables, {:.1} MB; {} locomotive pages",
        found.sections.len(),
        found.svgs,
        found.tables,
        html.len() as f64 / 1e6,
        results.fleet.pages.len()
    );
    p.done(&bar, 6, "report", t.elapsed(), detail);
    results.total = start.elapsed();
    results.cpu = process_cpu_time();
    results.stages = p.times.clone();
    print!("{}", summary_text(&results, &index));
    if let Err(e) = &results.audit {
        bail!("the audit stage failed ({e}); the rest of the report was written to {}", index.display());
    }
    if let Err(e) = &results.metro {
        bail!("the real-data audit failed ({e}); the rest of the report was written to {}", index.display());
    }
    Ok(())
}
