//! `host-sim evaluate`: accuracy and confusion matrices of the trained classifiers on the test
//! split of a data set, accuracy of ours against time since the release command, optional
//! leave-one-locomotive-out accuracy, JSON and SVG output.
//!
//! Every classifier is judged at the end of the trace (60 s); `ours_int8` runs the core's
//! integer inference ([`pbm::classifier::QuantModel`]) on the model file written by `train`,
//! and `core_compiled` is the verdict of the model compiled into the core
//! ([`pbm::classifier::diagnose`]), including its 'cannot diagnose' rules.

use crate::nn::Mlp;
use crate::train::{
    classes_of, dataset_features, read_mlp, read_quant, Kind, QuantParams, TraceFeatures, SNAPSHOT_TIMES_S,
};
use anyhow::{bail, Context, Result};
use pbm::report::Verdict;
use pbm::FaultClass;
use pbm_io::error::Skipped;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Options of the evaluate run.
#[derive(Debug, Clone, PartialEq)]
pub struct EvaluateOptions {
    /// Data set directory; rows with split `test` are evaluated.
    pub dataset: PathBuf,
    /// Directory of the trained models.
    pub models: PathBuf,
    /// Write the results as JSON.
    pub json: Option<PathBuf>,
    /// Write SVG plots (confusion matrices, accuracy vs time) into this directory.
    pub plot: Option<PathBuf>,
    /// Also run leave-one-locomotive-out for ours (retrains once per locomotive on all splits).
    pub lolo: bool,
    /// Also print the confusion matrix of ours (int8) at every snapshot time.
    pub verbose: bool,
    /// Seed for the leave-one-locomotive-out training.
    pub seed: u64,
}

impl EvaluateOptions {
    /// Evaluates `dataset` with the models in `models/`.
    pub fn new(dataset: PathBuf) -> Self {
        Self { dataset, models: PathBuf::from("models"), json: None, plot: None, lolo: false, verbose: false, seed: 1 }
    }
}

/// Outcome of one classifier on one trace: a class index, or 'cannot diagnose'.
pub type Outcome = Option<usize>;

/// Accuracy and confusion matrix of one classifier.
#[derive(Debug, Clone, PartialEq)]
pub struct Score {
    /// Classifier name.
    pub name: String,
    /// Correct / total.
    pub correct: usize,
    /// Traces evaluated.
    pub total: usize,
    /// Traces with 'cannot diagnose'.
    pub undiagnosed: usize,
    /// `confusion[true][predicted]`; the last column counts 'cannot diagnose'.
    pub confusion: Vec<Vec<usize>>,
}

impl Score {
    /// Scores outcomes against truths (`n` classes).
    pub fn new(name: &str, n: usize, truth: &[usize], outcome: &[Outcome]) -> Self {
        let mut confusion = vec![vec![0; n + 1]; n];
        for (&t, o) in truth.iter().zip(outcome) {
            if let Some(row) = confusion.get_mut(t) {
                row[o.unwrap_or(n).min(n)] += 1;
            }
        }
        let correct = truth.iter().zip(outcome).filter(|(t, o)| **o == Some(**t)).count();
        let undiagnosed = outcome.iter().filter(|o| o.is_none()).count();
        Self { name: name.to_owned(), correct, total: truth.len(), undiagnosed, confusion }
    }
    /// Accuracy, %.
    pub fn accuracy_pct(&self) -> f64 {
        100.0 * self.correct as f64 / self.total.max(1) as f64
    }
}

fn class_index(classes: &[FaultClass], c: FaultClass) -> Option<usize> {
    classes.iter().position(|k| *k == c)
}

fn int8_outcome(q: &QuantParams, row: &[f64]) -> Outcome {
    q.with_model(|m| m.classify(row).ok().map(|inf| inf.index))
}

/// Accuracy (%) of ours at each snapshot time, f64 and int8.
pub fn accuracy_vs_time(
    net: &Mlp,
    q: &QuantParams,
    classes: &[FaultClass],
    data: &[TraceFeatures],
) -> Vec<(f64, f64, f64)> {
    SNAPSHOT_TIMES_S
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            let (mut n, mut ok_f, mut ok_q) = (0usize, 0usize, 0usize);
            for d in data {
                let (Some(s), Some(truth)) = (d.snapshots.get(k), class_index(classes, d.class)) else { continue };
                n += 1;
                ok_f += usize::from(net.predict(s) == truth);
                ok_q += usize::from(int8_outcome(q, s) == Some(truth));
            }
            let pct = |c: usize| 100.0 * c as f64 / n.max(1) as f64;
            (t, pct(ok_f), pct(ok_q))
        })
        .collect()
}

/// Bins of the reliability diagram and of the expected calibration error.
pub const CALIBRATION_BINS: usize = 15;

/// One bin of a reliability diagram: releases whose confidence falls in it, their mean
/// confidence and their accuracy (both 0..1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReliabilityBin {
    /// Releases in the bin.
    pub n: usize,
    /// Mean confidence.
    pub confidence: f64,
    /// Share correct.
    pub accuracy: f64,
}

/// The int8 model's verdict on each release at the end of its trace, as the core sends it: the
/// confidence (per cent, capped at `MAX_CONFIDENCE_PCT`) and whether the class is right. Releases
/// the core refuses (unfamiliar inputs) have no confidence and are left out.
pub fn final_confidences(q: &QuantParams, classes: &[FaultClass], data: &[TraceFeatures]) -> Vec<(f64, bool)> {
    data.iter()
        .filter_map(|d| {
            let row = d.snapshots.last()?;
            let inf = q.with_model(|m| m.classify(row).ok())?;
            let pct = inf.confidence_pct.min(pbm::classifier::MAX_CONFIDENCE_PCT);
            Some((f64::from(pct) / 100.0, Some(inf.index) == class_index(classes, d.class)))
        })
        .collect()
}

/// Expected calibration error (Naeini et al. 2015; Guo et al. 2017): Σ over equal-width
/// confidence bins of (bin share) × |accuracy − mean confidence|, with the bins.
pub fn calibration(pairs: &[(f64, bool)]) -> (f64, Vec<ReliabilityBin>) {
    let mut bins = vec![(0usize, 0.0f64, 0usize); CALIBRATION_BINS];
    for &(c, ok) in pairs {
        let k = ((c * CALIBRATION_BINS as f64) as usize).min(CALIBRATION_BINS - 1);
        bins[k].0 += 1;
        bins[k].1 += c;
        bins[k].2 += usize::from(ok);
    }
    let total = pairs.len().max(1) as f64;
    let mut ece = 0.0;
    let out = bins
        .iter()
        .map(|&(n, sum_c, ok)| {
            let (conf, acc) = if n > 0 { (sum_c / n as f64, ok as f64 / n as f64) } else { (0.0, 0.0) };
            ece += n as f64 / total * (acc - conf).abs();
            ReliabilityBin { n, confidence: conf, accuracy: acc }
        })
        .collect();
    (ece, out)
}

/// Share (%) of traces whose int8 class is correct at every snapshot from `t` on, for the
/// earliest such `t` ≤ `by_s` (i.e. diagnosed correctly and stably by `by_s`).
pub fn stable_by(q: &QuantParams, classes: &[FaultClass], data: &[TraceFeatures], by_s: f64) -> f64 {
    let last_k = SNAPSHOT_TIMES_S.iter().rposition(|&t| t <= by_s).unwrap_or(0);
    let ok = data
        .iter()
        .filter(|d| {
            let truth = class_index(classes, d.class);
            let correct: Vec<bool> = d.snapshots.iter().map(|s| int8_outcome(q, s) == truth).collect();
            (0..=last_k).any(|k| correct.get(k..).is_some_and(|c| !c.is_empty() && c.iter().all(|&b| b)))
        })
        .count();
    100.0 * ok as f64 / data.len().max(1) as f64
}

/// Leave-one-locomotive-out accuracy of ours (f64 and int8) at the end of the trace.
pub fn leave_one_locomotive_out(all: &[TraceFeatures], seed: u64) -> Result<Vec<(String, usize, f64, f64)>> {
    let mut locos: Vec<String> = all.iter().map(|d| d.row.locomotive.clone()).collect();
    locos.sort();
    locos.dedup();
    let mut out = Vec::new();
    for loco in &locos {
        let train: Vec<TraceFeatures> = all.iter().filter(|d| &d.row.locomotive != loco).cloned().collect();
        let test: Vec<&TraceFeatures> = all.iter().filter(|d| &d.row.locomotive == loco).collect();
        let trained = train_all_ours(&train, seed)?;
        let (net, q, classes) = (&trained.0, &trained.1, &trained.2);
        let (mut ok_f, mut ok_q) = (0, 0);
        for d in &test {
            let truth = class_index(classes, d.class);
            let row = Kind::Ours.final_row(d);
            ok_f += usize::from(Some(net.predict(&row)) == truth);
            ok_q += usize::from(int8_outcome(q, &row) == truth);
        }
        let n = test.len().max(1) as f64;
        out.push((loco.clone(), test.len(), 100.0 * ok_f as f64 / n, 100.0 * ok_q as f64 / n));
    }
    Ok(out)
}

fn train_all_ours(train: &[TraceFeatures], seed: u64) -> Result<(Mlp, QuantParams, Vec<FaultClass>)> {
    let classes = classes_of(train);
    let (net, _) = crate::train::train_kind(Kind::Ours, train, &classes, seed);
    let calib: Vec<Vec<f64>> = train.iter().flat_map(|d| Kind::Ours.rows(d)).collect();
    let mut q = crate::train::quantize(&net, &classes, &calib)?;
    crate::train::set_class_region(&mut q, train);
    Ok((net, q, classes))
}

/// Scores of the float models (in `nets` order), `ours_int8` and `core_compiled` (the model
/// compiled into the core) at the end of each test trace, and how many traces ours gets the
/// same class from in f64 and int8. `nets` must hold [`Kind::Ours`].
pub fn score_all(
    nets: &[(Kind, Mlp)],
    quant: &QuantParams,
    classes: &[FaultClass],
    test: &[TraceFeatures],
) -> Result<(Vec<Score>, usize)> {
    let truth: Vec<usize> = test
        .iter()
        .map(|d| {
            class_index(classes, d.class)
                .with_context(|| format!("{}: class {} not in the models", d.row.file, d.class))
        })
        .collect::<Result<_>>()?;
    let n = classes.len();
    let mut scores = Vec::new();
    for (k, net) in nets {
        let out: Vec<Outcome> = test.iter().map(|d| Some(net.predict(&k.final_row(d)))).collect();
        scores.push(Score::new(k.name(), n, &truth, &out));
    }
    let ours = &nets.iter().find(|(k, _)| *k == Kind::Ours).context("no `ours` model")?.1;
    let ours_f: Vec<Outcome> = test.iter().map(|d| Some(ours.predict(&Kind::Ours.final_row(d)))).collect();
    let ours_q: Vec<Outcome> = test.iter().map(|d| int8_outcome(quant, &Kind::Ours.final_row(d))).collect();
    scores.push(Score::new("ours_int8", n, &truth, &ours_q));
    let core: Vec<Outcome> = test
        .iter()
        .map(|d| match d.core_verdict {
            Verdict::Class { class, .. } => class_index(classes, class),
            Verdict::CannotDiagnose(_) => None,
        })
        .collect();
    scores.push(Score::new("core_compiled", n, &truth, &core));
    let agree = ours_f.iter().zip(&ours_q).filter(|(f, q)| f == q).count();
    Ok((scores, agree))
}

/// Evaluates the trained models on the data set's test split: the table on stdout, JSON and
/// plots when asked; returns the traces skipped.
pub fn run(a: &EvaluateOptions) -> Result<Skipped> {
    let (test, mut skipped) = dataset_features(&a.dataset, Some("test"))?;
    let mut nets = Vec::new();
    let mut classes: Option<Vec<FaultClass>> = None;
    for k in Kind::ALL {
        let (net, c) = read_mlp(&a.models.join(format!("{}.mlp", k.name())))?;
        if classes.as_ref().is_some_and(|prev| prev != &c) {
            bail!("models in {} disagree on the class list", a.models.display());
        }
        classes = Some(c);
        nets.push((k, net));
    }
    let classes = classes.context("no models")?;
    let quant = read_quant(&a.models.join("ours_int8.txt"))?;
    if quant.classes != classes {
        bail!("ours_int8.txt has other classes than the float models");
    }
    let (scores, agree) = score_all(&nets, &quant, &classes, &test)?;
    let n = classes.len();
    let truth: Vec<usize> = test.iter().filter_map(|d| class_index(&classes, d.class)).collect();
    let curve = accuracy_vs_time(&nets[3].1, &quant, &classes, &test);
    let stable10 = stable_by(&quant, &classes, &test, 10.0);
    let confidences = final_confidences(&quant, &classes, &test);
    let (ece, bins) = calibration(&confidences);
    // The model compiled into the core, as replay and the firmware send it.
    let core: Vec<(f64, bool)> = test
        .iter()
        .filter_map(|d| match d.core_verdict {
            pbm::report::Verdict::Class { class, confidence_pct } => {
                Some((f64::from(confidence_pct) / 100.0, class == d.class))
            }
            pbm::report::Verdict::CannotDiagnose(_) => None,
        })
        .collect();
    let (core_ece, _) = calibration(&core);
    let compiled = &pbm::classifier::model_weights::MODEL;
    let core_class = |row: &[f64]| compiled.classify(row).ok().map(|inf| inf.class);
    let core_stable10 = {
        let last_k = SNAPSHOT_TIMES_S.iter().rposition(|&t| t <= 10.0).unwrap_or(0);
        let ok = test
            .iter()
            .filter(|d| {
                let correct: Vec<bool> = d.snapshots.iter().map(|s| core_class(s) == Some(d.class)).collect();
                (0..=last_k).any(|k| correct.get(k..).is_some_and(|c| !c.is_empty() && c.iter().all(|&b| b)))
            })
            .count();
        100.0 * ok as f64 / test.len().max(1) as f64
    };
    let lolo = if a.lolo {
        let (all, more) = dataset_features(&a.dataset, None)?;
        // The test split's skipped traces are in `more` again; keep each once.
        for e in more.errors() {
            if !skipped.errors().contains(e) {
                skipped.push(e.clone());
            }
        }
        Some(leave_one_locomotive_out(&all, a.seed)?)
    } else {
        None
    };

    // Table.
    println!("{} test traces of {}; classes: {}", test.len(), a.dataset.display(), labels(&classes).join(", "));
    println!(
        "{:<16} {:>9} {:>8} {:>12}   confusion (rows: truth; columns: predicted…, cannot diagnose)",
        "classifier", "accuracy", "correct", "undiagnosed"
    );
    for s in &scores {
        let conf: Vec<String> =
            s.confusion.iter().map(|r| r.iter().map(|v| format!("{v:>3}")).collect::<Vec<_>>().join(" ")).collect();
        println!(
            "{:<16} {:>8.1}% {:>4}/{:<4} {:>11}   {}",
            s.name,
            s.accuracy_pct(),
            s.correct,
            s.total,
            s.undiagnosed,
            conf.join(" | ")
        );
    }
    println!("paper (real data): raw 72 %, residual 81.2 %, theta 96 %");
    println!("int8 vs f64 agreement at 60 s: {agree}/{}", test.len());
    println!("accuracy of ours vs time since release (f64 / int8):");
    for (t, f, q) in &curve {
        println!("  t = {t:>5.2} s  {f:>6.1} %  {q:>6.1} %");
    }
    if a.verbose {
        for (k, t) in SNAPSHOT_TIMES_S.iter().enumerate() {
            let out: Vec<Outcome> =
                test.iter().map(|d| d.snapshots.get(k).and_then(|s| int8_outcome(&quant, s))).collect();
            let sc = Score::new("", n, &truth, &out);
            let conf: Vec<String> = sc
                .confusion
                .iter()
                .map(|r| r.iter().map(|v| format!("{v:>3}")).collect::<Vec<_>>().join(" "))
                .collect();
            println!("  t = {t:>5.2} s  int8 confusion {}", conf.join(" | "));
        }
    }
    println!("traces diagnosed correctly (int8) and stably from some t <= 10 s on: {stable10:.1} %");
    println!("the same for the model compiled into the core: {core_stable10:.1} %");
    println!(
        "calibration of the confidence the core sends (int8, at the end of each trace, {} releases, {} bins): \
         expected calibration error {:.2} %",
        confidences.len(),
        CALIBRATION_BINS,
        100.0 * ece
    );
    println!(
        "calibration of the model compiled into the core (its verdicts at the end of each trace, {} named): \
         expected calibration error {:.2} %",
        core.len(),
        100.0 * core_ece
    );
    for b in bins.iter().filter(|b| b.n > 0) {
        println!(
            "  confidence {:>5.1} %  accuracy {:>5.1} %  ({} releases)",
            100.0 * b.confidence,
            100.0 * b.accuracy,
            b.n
        );
    }
    if let Some(l) = &lolo {
        println!("leave-one-locomotive-out (ours, at 60 s; f64 / int8):");
        for (loco, n, f, q) in l {
            println!("  {loco:<10} {n:>5} traces  {f:>6.2} %  {q:>6.2} %");
        }
        let tot: usize = l.iter().map(|x| x.1).sum();
        let wf: f64 = l.iter().map(|x| x.2 * x.1 as f64).sum::<f64>() / tot.max(1) as f64;
        let wq: f64 = l.iter().map(|x| x.3 * x.1 as f64).sum::<f64>() / tot.max(1) as f64;
        println!("  overall    {tot:>5} traces  {wf:>6.2} %  {wq:>6.2} %");
    }
    if let Some(path) = &a.json {
        pbm_io::table::write_json(
            path,
            &json(&classes, &scores, agree, test.len(), &curve, stable10, lolo.as_deref()),
        )?;
    }
    if let Some(dir) = &a.plot {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        plot_confusions(&dir.join("confusion.svg"), &classes, &scores)?;
        plot_curve(&dir.join("accuracy_vs_time.svg"), &curve)?;
        plot_reliability(&dir.join("reliability.svg"), &bins, ece)?;
        println!("plots written to {}", dir.display());
    }
    Ok(skipped)
}

fn labels(classes: &[FaultClass]) -> Vec<&'static str> {
    classes.iter().map(|c| c.label()).collect()
}

/// The `--json` document of an evaluation (serde_json: every string escaped).
fn json(
    classes: &[FaultClass],
    scores: &[Score],
    agree: usize,
    total: usize,
    curve: &[(f64, f64, f64)],
    stable10: f64,
    lolo: Option<&[(String, usize, f64, f64)]>,
) -> serde_json::Value {
    use serde_json::json;
    let mut doc = json!({
        "classes": labels(classes),
        "paper_reported_pct": {"paper_raw": 72.0, "paper_residual": 81.2, "paper_theta": 96.0},
        "classifiers": scores.iter().map(|sc| json!({
            "name": sc.name,
            "accuracy_pct": sc.accuracy_pct(),
            "correct": sc.correct,
            "total": sc.total,
            "undiagnosed": sc.undiagnosed,
            "confusion": sc.confusion,
        })).collect::<Vec<_>>(),
        "int8_f64_agreement": {"agree": agree, "total": total},
        "accuracy_vs_time": curve.iter().map(|&(t, f, q)| json!({"t_s": t, "f64_pct": f, "int8_pct": q})).collect::<Vec<_>>(),
        "stable_correct_by_10s_pct": stable10,
    });
    if let Some(l) = lolo {
        doc["leave_one_locomotive_out"] = l
            .iter()
            .map(|(loco, n, f, q)| json!({"locomotive": loco, "traces": n, "f64_pct": f, "int8_pct": q}))
            .collect();
    }
    doc
}

fn plot_err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plot: {e}")
}

fn plot_confusions(path: &Path, classes: &[FaultClass], scores: &[Score]) -> Result<()> {
    let n = classes.len();
    let cell = 34i32;
    let panel_w = cell * (n as i32 + 1) + 150;
    let panel_h = cell * n as i32 + 60;
    let width = (panel_w * 3) as u32;
    let height = (panel_h * scores.len().div_ceil(3) as i32) as u32;
    let root = SVGBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    for (k, sc) in scores.iter().enumerate() {
        let (ox, oy) = ((k % 3) as i32 * panel_w + 130, (k / 3) as i32 * panel_h + 30);
        let title = format!("{} {:.1} %", sc.name, sc.accuracy_pct());
        root.draw(&Text::new(title, (ox - 120, oy - 22), ("sans-serif", 14))).map_err(plot_err)?;
        for (t, row) in sc.confusion.iter().enumerate() {
            let total = row.iter().sum::<usize>().max(1) as f64;
            root.draw(&Text::new(classes[t].label(), (ox - 120, oy + t as i32 * cell + 10), ("sans-serif", 11)))
                .map_err(plot_err)?;
            for (p, &v) in row.iter().enumerate() {
                let frac = v as f64 / total;
                let shade = (255.0 * (1.0 - frac)) as u8;
                let color = if p == t { RGBColor(shade, 255, shade) } else { RGBColor(255, shade, shade) };
                let (x0, y0) = (ox + p as i32 * cell, oy + t as i32 * cell);
                root.draw(&Rectangle::new([(x0, y0), (x0 + cell - 2, y0 + cell - 2)], color.filled()))
                    .map_err(plot_err)?;
                root.draw(&Text::new(v.to_string(), (x0 + 6, y0 + 10), ("sans-serif", 11))).map_err(plot_err)?;
            }
        }
    }
    root.present().map_err(plot_err)
}

/// Reliability diagram: accuracy against mean confidence per bin, with the diagonal of a
/// perfectly calibrated model; the point area follows the bin's share of releases.
pub fn plot_reliability(path: &Path, bins: &[ReliabilityBin], ece: f64) -> Result<()> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (560, 520)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("Reliability (ECE {:.2} %)", 100.0 * ece), ("sans-serif", 20))
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(54)
        .build_cartesian_2d(0.0..100.0, 0.0..100.0)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("confidence sent (%)")
        .y_desc("observed accuracy (%)")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(plot_err)?;
    chart.draw_series(LineSeries::new([(0.0, 0.0), (100.0, 100.0)], BLACK.mix(0.4))).map_err(plot_err)?;
    let total = bins.iter().map(|b| b.n).sum::<usize>().max(1) as f64;
    chart
        .draw_series(bins.iter().filter(|b| b.n > 0).map(|b| {
            let r = (3.0 + 12.0 * (b.n as f64 / total).sqrt()) as i32;
            Circle::new((100.0 * b.confidence, 100.0 * b.accuracy), r, RGBColor(0, 114, 178).filled())
        }))
        .map_err(plot_err)?;
    root.present().map_err(plot_err)?;
    Ok(())
}

fn plot_curve(path: &Path, curve: &[(f64, f64, f64)]) -> Result<()> {
    let root = SVGBackend::new(path, (720, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let lo = curve.iter().map(|c| c.1.min(c.2)).fold(100.0, f64::min).floor().max(0.0);
    let mut chart = ChartBuilder::on(&root)
        .caption("ours: accuracy vs time since release command", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(0.0..60.0, lo..100.5)
        .map_err(plot_err)?;
    chart.configure_mesh().x_desc("t since release command, s").y_desc("accuracy, %").draw().map_err(plot_err)?;
    chart
        .draw_series(LineSeries::new(curve.iter().map(|c| (c.0, c.1)), &BLUE))
        .map_err(plot_err)?
        .label("f64")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLUE));
    chart
        .draw_series(LineSeries::new(curve.iter().map(|c| (c.0, c.2)), &RED))
        .map_err(plot_err)?
        .label("int8")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], RED));
    chart.configure_series_labels().border_style(BLACK).background_style(WHITE).draw().map_err(plot_err)?;
    root.present().map_err(plot_err)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A locomotive name with quotes, a backslash and a newline stays one JSON string.
    #[test]
    fn json_escapes_every_name() {
        let loco = "loco \"7\" \\ east\nline".to_owned();
        let scores = [Score {
            name: "ours \"int8\"".into(),
            correct: 1,
            total: 2,
            undiagnosed: 0,
            confusion: vec![vec![1, 1, 0]],
        }];
        let lolo = [(loco.clone(), 2, 50.0, 50.0)];
        let doc = json(&[FaultClass::Normal], &scores, 1, 2, &[(1.0, 50.0, 50.0)], 50.0, Some(&lolo));
        let text = serde_json::to_string_pretty(&doc).unwrap();
        let back: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back["leave_one_locomotive_out"][0]["locomotive"], loco.as_str());
        assert_eq!(back["classifiers"][0]["name"], "ours \"int8\"");
    }
}
