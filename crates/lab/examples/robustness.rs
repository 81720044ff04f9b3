//! Releases the compiled-in model was not trained on, through the core pipeline: the README's
//! table of shifted sets and the sensor-fault battery. Each set is generated with its own fresh
//! seed into a temporary directory, replayed, and counted as right class / refused / wrong class.
//!
//! ```text
//! cargo run --release -p pbm-lab --example robustness -- shifted-sets
//! cargo run --release -p pbm-lab --example robustness -- sensor-fault-battery [SEED]
//! ```
//! (`cargo xtask shifted-sets` and `cargo xtask sensor-fault-battery [SEED]` run the same.)
//! The battery exits 1 if any release is reported as a wrong brake class.

use anyhow::{bail, Context, Result};
use pbm::mechanism::{Extensions, Mechanism};
use pbm::report::Verdict;
use pbm::FaultClass;
use pbm_lab::generate::{generate, Conditions, GenerateOptions};
use pbm_lab::replay::{items, replay_all, ReplayOptions};
use pbm_lab::sensor_faults::{parse_spec, FaultKind};
use std::collections::BTreeMap;
use std::process::ExitCode;

/// One replayed release: its true class and the verdict closed by the pipeline.
struct Outcome {
    label: String,
    verdict: Option<Verdict>,
}

/// Generates `opts` (test split only) in a temporary directory and replays it.
fn run_set(mut opts: GenerateOptions) -> Result<Vec<Outcome>> {
    let tmp = tempfile::tempdir()?;
    opts.out = tmp.path().join("set");
    opts.per_class = 0;
    generate(&opts, false)?;
    let (items, skipped) = items(&opts.out, Some("test"))?;
    if !skipped.is_empty() {
        bail!("generated set refused: {skipped}");
    }
    replay_all(&items, &ReplayOptions::default())?
        .into_iter()
        .map(|r| {
            let r = r?;
            Ok(Outcome { label: r.summary.label, verdict: r.summary.diagnosis.map(|d| d.verdict) })
        })
        .collect()
}

/// (right, refused, wrong); with `any_is_wrong` every named class counts as wrong.
fn count(outcomes: &[Outcome], any_is_wrong: bool) -> (usize, usize, usize) {
    let (mut right, mut refused, mut wrong) = (0, 0, 0);
    for o in outcomes {
        match o.verdict {
            Some(Verdict::Class { class, .. }) if !any_is_wrong && class.label() == o.label => right += 1,
            Some(Verdict::Class { .. }) => wrong += 1,
            Some(Verdict::CannotDiagnose(_)) | None => refused += 1,
        }
    }
    (right, refused, wrong)
}

fn base(seed: u64, test_per_class: usize) -> GenerateOptions {
    let mut o = GenerateOptions::new(Default::default());
    o.seed = seed;
    o.test_per_class = test_per_class;
    o
}

fn shifted_sets() -> Result<()> {
    let with = |mut o: GenerateOptions, f: &dyn Fn(&mut GenerateOptions)| {
        f(&mut o);
        o
    };
    let cond = |noise: f64, spread: f64, reg: (f64, f64)| Conditions { noise_bar: noise, spread, regulator_bar_g: reg };
    let spec = Conditions::SPEC;
    let classes = |l: &[FaultClass]| l.to_vec();
    // (name, options, every named class is wrong)
    let sets: Vec<(&str, GenerateOptions, bool)> = vec![
        ("clean, 6 locomotives", base(99, 50), false),
        (
            "clean, 4 new locomotives",
            with(base(4242, 100), &|o| {
                o.locomotives = 8;
                o.test_locomotives = 4;
            }),
            false,
        ),
        (
            "twice the noise",
            with(base(611, 40), &|o| o.conditions = cond(0.02, spec.spread, spec.regulator_bar_g)),
            false,
        ),
        (
            "spread 8 %",
            with(base(612, 40), &|o| o.conditions = cond(spec.noise_bar, 0.08, spec.regulator_bar_g)),
            false,
        ),
        (
            "spread 10 %",
            with(base(618, 40), &|o| o.conditions = cond(spec.noise_bar, 0.10, spec.regulator_bar_g)),
            false,
        ),
        (
            "regulator 7.7 ± 0.1 bar",
            with(base(613, 40), &|o| o.conditions = cond(spec.noise_bar, spec.spread, (7.6, 7.8))),
            false,
        ),
        (
            "transport delay 0.1 s",
            with(base(614, 40), &|o| o.effects = Extensions::NONE.with(Mechanism::TransportDelay, 0.1)),
            false,
        ),
        (
            "transport delay 0.3 s",
            with(base(615, 40), &|o| o.effects = Extensions::NONE.with(Mechanism::TransportDelay, 0.3)),
            false,
        ),
        (
            "all four shifts",
            with(base(616, 40), &|o| {
                o.conditions = cond(0.02, 0.08, (7.6, 7.8));
                o.effects = Extensions::NONE.with(Mechanism::TransportDelay, 0.1);
            }),
            false,
        ),
        (
            "three times the noise",
            with(base(617, 40), &|o| o.conditions = cond(0.03, spec.spread, spec.regulator_bar_g)),
            false,
        ),
        ("orifice missing", with(base(701, 30), &|o| o.classes = classes(&[FaultClass::OrificeMissing])), true),
        (
            "supply 2.5-3.2 bar",
            with(base(702, 30), &|o| {
                o.classes = classes(&[FaultClass::Normal]);
                o.conditions = cond(spec.noise_bar, spec.spread, (2.5, 3.2));
            }),
            true,
        ),
        (
            "supply 8.5-9.5 bar",
            with(base(703, 30), &|o| {
                o.classes = classes(&[FaultClass::Normal]);
                o.conditions = cond(spec.noise_bar, spec.spread, (8.5, 9.5));
            }),
            true,
        ),
        (
            "wall heat transfer",
            with(base(705, 30), &|o| {
                o.classes = classes(&[FaultClass::Normal, FaultClass::LowSupply]);
                o.effects = Extensions::NONE.with(Mechanism::HeatTransfer, 5.0);
            }),
            false,
        ),
    ];
    println!("{:<28} {:>6} {:>6} {:>8} {:>6}", "set", "n", "right", "refused", "wrong");
    for (name, opts, any_is_wrong) in sets {
        let outcomes = run_set(opts).with_context(|| name.to_owned())?;
        let (right, refused, wrong) = count(&outcomes, any_is_wrong);
        println!("{name:<28} {:>6} {right:>6} {refused:>8} {wrong:>6}", outcomes.len());
    }
    Ok(())
}

/// Every sensor-fault kind × the five classes × onsets 0, 3, 15, 40 s, two releases per class;
/// returns the number of releases reported as a wrong brake class.
fn sensor_fault_battery(first_seed: u64) -> Result<usize> {
    let mut seed = first_seed;
    let (mut n, mut refused_total, mut right_total, mut wrong_total) = (0, 0, 0, 0);
    let mut refused_by_kind = BTreeMap::new();
    for (_, kind, _) in FaultKind::ALL {
        for onset in [0, 3, 15, 40] {
            let mut o = base(seed, 2);
            o.locomotives = 3;
            o.test_locomotives = 1;
            o.sensor_faults = vec![parse_spec(&format!("{kind}@{onset}")).map_err(anyhow::Error::msg)?];
            let outcomes = run_set(o).with_context(|| format!("{kind}@{onset}"))?;
            for out in &outcomes {
                if let Some(Verdict::Class { class, .. }) = out.verdict {
                    if class.label() != out.label {
                        println!("WRONG {kind}@{onset}: {} -> {class}", out.label);
                    }
                }
            }
            let (right, refused, wrong) = count(&outcomes, false);
            n += outcomes.len();
            right_total += right;
            refused_total += refused;
            wrong_total += wrong;
            *refused_by_kind.entry(kind).or_insert(0) += refused;
            seed += 1;
        }
    }
    println!(
        "sensor-fault battery: {n} releases, {refused_total} refused, {right_total} named their true class, \
         {wrong_total} wrong brake classes"
    );
    for (kind, r) in refused_by_kind {
        println!("  {kind:<18} refused {r}");
    }
    Ok(wrong_total)
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.iter().map(String::as_str).collect::<Vec<_>>().as_slice() {
        ["shifted-sets"] => shifted_sets().map(|()| true),
        ["sensor-fault-battery"] => sensor_fault_battery(101).map(|w| w == 0),
        ["sensor-fault-battery", seed] => match seed.parse() {
            Ok(s) => sensor_fault_battery(s).map(|w| w == 0),
            Err(_) => Err(anyhow::anyhow!("`{seed}` is not a seed")),
        },
        _ => {
            eprintln!("usage: robustness shifted-sets | sensor-fault-battery [SEED]");
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
