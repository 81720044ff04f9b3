//! Hidden-effect tests of the model-discrepancy audit (issue 9).
//!
//! A case draws a mechanism and a magnitude from its seed (uniformly over all ten mechanisms,
//! magnitude uniform in [`Mechanism::plausible`]), a locomotive with the SPEC §5 spread, and
//! [`RELEASES_PER_CASE`] noisy releases from the f64 plant (σ = 0.01 bar, 12-bit ADC); the audit
//! must name the mechanism, estimate its magnitude within 20 % and cut the NMSE at least 5×.
//! A null case (clean plant) must give `none`.
//!
//! The default seeds are fixed so CI is reproducible; `AUDIT_TEST_SEED=N` moves the window
//! (seeds N, N+1, …) to check others. The larger sweep is `#[ignore]`d:
//! `cargo test -p pbm-lab --test audit -- --ignored` (≈ 3 min on 2 cores), and the full one is
//! `host-sim audit-sweep --cases 200 --pairs 40 --null-cases 20` (bench/audit_sweep.md).

use pbm::mechanism::Extensions;
use pbm::mechanism::Mechanism;
use pbm_lab::audit::{audit, audit_dir, AuditOptions, NoiseColour};
use pbm_lab::audit_plot::write_outputs;
use pbm_lab::audit_sweep::{check_case, draw_case, draw_case_with, synth_data, RELEASES_PER_CASE};
use pbm_lab::generate::{generate, GenerateOptions, SplitMode};

fn first_seed(default: u64) -> u64 {
    std::env::var("AUDIT_TEST_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

fn run_seeds(seeds: impl Iterator<Item = u64>, count: usize) {
    let mut misses = Vec::new();
    for seed in seeds {
        let case = draw_case_with(seed, &Mechanism::ALL, count, None).expect("case");
        let r = check_case(&case).expect("audit runs");
        let line = r.line(seed);
        eprintln!("{line}");
        if !r.hit() {
            misses.push(line);
        }
    }
    assert!(misses.is_empty(), "missed hidden effects:\n{}", misses.join("\n"));
}

/// `n` releases of the pressure curve `p` (bar g) through the transducer's noise and the ADC
/// (noise drawn from `seed`), the k-th read `shift(k)` bar high, documented as `config`.
fn noisy_releases(
    p: &[f64],
    seed: u64,
    n: usize,
    config: pbm::TwinParams,
    shift: impl Fn(usize) -> f64,
) -> pbm_lab::audit::AuditData {
    use rand_core::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let traces = (0..n)
        .map(|k| {
            let bar = pbm_lab::generate::sense(p, &mut rng)
                .iter()
                .map(|&c| pbm::sensor::bar_from_adc(pbm::AdcCounts(c)).0 + shift(k))
                .collect();
            (format!("release_{k:02}.csv"), config, bar)
        })
        .collect();
    pbm_lab::audit::data_from_traces("synthetic", traces).expect("data")
}

#[test]
fn hidden_effect_is_named_with_magnitude_and_gain() {
    let s = first_seed(1);
    run_seeds(s..s + 3, 1);
}

#[test]
fn clean_plant_gives_none() {
    let seed = first_seed(1) + pbm_lab::audit_sweep::NULL_SEED_OFFSET;
    let data = synth_data(seed, &[], RELEASES_PER_CASE).expect("data");
    let out = audit(&data, AuditOptions::default()).expect("audit runs");
    eprint!("{}", out.summary());
    assert_eq!(out.cause, "none", "clean data must not be blamed on a mechanism");
    assert!(out.cause_effects.is_empty());
    assert_eq!(out.to_json()["cause"], "none");
}

/// The documented workflow: `host-sim generate` one locomotive's releases with a hidden effect,
/// then `host-sim audit` the directory; JSON, plots and report are written.
#[test]
fn generate_then_audit_directory() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let mut g = GenerateOptions::new(data.clone());
    g.locomotives = 1;
    g.split = SplitMode::Shared;
    g.classes = vec![pbm::FaultClass::Normal];
    g.per_class = 12;
    g.test_per_class = 0;
    g.seed = 5;
    g.effects = Extensions::NONE.with(Mechanism::ValveLag, 0.45);
    generate(&g, false).expect("generate");

    // A trace with no samples and a locomotive name with a quote: the empty trace is skipped
    // with its reason, the rest is audited, and the JSON stays valid.
    let manifest = std::fs::read_to_string(data.join("manifest.csv")).unwrap().replace("loco-01", "loco \"\"1\"\"");
    let manifest = manifest.replacen("\n", "\n\"empty.csv\",normal,\"loco \"\"1\"\"\",train\n", 1);
    std::fs::write(data.join("manifest.csv"), manifest).unwrap();
    std::fs::write(data.join("empty.csv"), "t_s,adc\n").unwrap();

    let (out, skipped) = audit_dir(&data).expect("audit");
    assert_eq!(skipped.len(), 1, "{skipped}");
    assert!(skipped.errors()[0].to_string().contains("empty.csv"), "{skipped}");
    eprint!("{}", out.summary());
    assert_eq!(out.cause, "valve_lag");
    let m = out.magnitude();
    assert!((m - 0.45).abs() <= 0.2 * 0.45, "valve_lag estimate {m}");
    assert!(out.base.nmse_pct >= 5.0 * out.chosen.nmse_pct);

    let json = dir.path().join("audit.json");
    let plots = dir.path().join("plots");
    let report = dir.path().join("report.html");
    write_outputs(&out, Some(&json), Some(&plots), Some(&report)).expect("outputs");
    let text = std::fs::read_to_string(&json).expect("json");
    let parsed: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    assert_eq!(parsed["cause"], "valve_lag");
    for key in
        ["\"cause\": \"valve_lag\"", "\"magnitude\": 0.4", "\"nmse_base_pct\"", "\"nmse_extended_pct\"", "\"ranking\""]
    {
        assert!(text.contains(key), "JSON lacks {key}:\n{text}");
    }
    for f in ["curves_0.svg", "residual_0.svg", "acf.svg"] {
        let svg = std::fs::read_to_string(plots.join(f)).expect("plot");
        assert!(svg.starts_with("<svg") && svg.contains("</svg>"), "{f} is not an SVG");
    }
    let html = std::fs::read_to_string(&report).expect("report");
    assert!(html.contains("<svg") && html.contains("valve_lag"));
}

#[test]
fn bad_data_set_is_a_clear_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let err = audit_dir(dir.path()).expect_err("no manifest");
    assert!(format!("{err:#}").contains("manifest"), "{err:#}");
}

/// Larger seeded sweep: 24 single-mechanism cases (each a hit), 6 pairs, 3 null cases.
///
/// A pair need not be a hit (the library sweep measures 9/10, bench/audit_sweep.md), but a miss
/// must not be confidently wrong: the audit says `unexplained`, or names what it found as a
/// *part* of the discrepancy ("something else is missing too"), never a wrong pair as
/// explaining it all. At seed 101 two of the six miss that way: `sensor_offset+sensor_gain`
/// (`unexplained`, and the verdict says the right pair fits but neither term passes alone) and
/// `heat_transfer+sensor_lag` (`heat_transfer+gas_temperature` explains part, 114× → 5.8×).
#[test]
#[ignore = "≈ 3 min on 2 cores; run with --ignored"]
fn larger_hidden_effect_sweep() {
    let s = first_seed(101);
    run_seeds(s..s + 24, 1);
    let mut wrong = Vec::new();
    let mut hits = 0;
    for seed in s + 1000..s + 1006 {
        let r = check_case(&draw_case_with(seed, &Mechanism::ALL, 2, None).expect("case")).expect("audit runs");
        eprintln!("{}", r.line(seed));
        hits += usize::from(r.hit());
        if !r.hit() && r.outcome.explains_all() {
            wrong.push(r.line(seed));
        }
    }
    assert!(wrong.is_empty(), "pairs confidently misnamed:\n{}", wrong.join("\n"));
    assert!(hits >= 4, "only {hits} of 6 pairs named right");
    for k in 0..3 {
        let data = synth_data(s + 5000 + k, &[], RELEASES_PER_CASE).expect("data");
        assert_eq!(audit(&data, AuditOptions::default()).expect("audit").cause, "none");
    }
    // draw_case is the single-mechanism shorthand.
    assert_eq!(draw_case(s, &Mechanism::ALL).expect("case").truth.len(), 1);
}

/// The finding does not depend on the orifice size (issue 17: a +0.1 bar transducer offset was
/// found at 1.25 mm but reported as `none` at 3 and 4 mm, where the extended twin overflowed).
/// Releases of a locomotive whose documented orifice is 3 or 4 mm, with the offset hidden.
#[test]
fn a_sensor_offset_is_found_whatever_the_orifice() {
    use pbm::Meters;
    use pbm_lab::generate::{fleet, simulate_plant, GENERATE_STEP_S, TRACE_SAMPLES};
    for (seed, orifice_mm) in [(31, 3.0), (32, 4.0)] {
        let mut documented = fleet(seed, 1)[0].params;
        documented.orifice = Meters::from_mm(orifice_mm);
        let mut plant = documented;
        plant.ext[Mechanism::SensorOffset] = 0.1;
        let (p, _) = simulate_plant(&plant, GENERATE_STEP_S, TRACE_SAMPLES).expect("plant");
        let mut config = pbm::TwinParams::nominal();
        config.orifice = documented.orifice;
        let data = noisy_releases(&p, seed, RELEASES_PER_CASE, config, |_| 0.0);
        let out = audit(&data, AuditOptions::default()).expect("audit runs");
        eprint!("{}", out.summary());
        assert_eq!(out.cause, "sensor_offset", "orifice {orifice_mm} mm");
        assert!((out.magnitude() - 0.1).abs() <= 0.02, "orifice {orifice_mm} mm: {}", out.magnitude());
    }
}

/// Releases of a second plant written from the physics by someone who did not read this code
/// (`tests/data/independent`): a clean release is `none` at the noise floor, and effects no
/// mechanism of the library holds (a hunting regulator, a supply cut off and vented mid-fill)
/// are `unexplained`, never `none` (issue 17: such releases were called "nothing is missing").
#[test]
fn effects_outside_the_library_are_unexplained_not_none() {
    let dir = tempfile::tempdir().unwrap();
    let independent = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent");
    for (trace, want) in [
        ("clean_normal_0000", "none"),
        ("unfamiliar_regulator_hunting_00", "unexplained"),
        ("unfamiliar_supply_dropout_vent_00", "unexplained"),
    ] {
        let set = dir.path().join(trace);
        std::fs::create_dir_all(&set).unwrap();
        std::fs::copy(independent.join(format!("{trace}.csv")), set.join("r.csv")).unwrap();
        std::fs::write(set.join("manifest.csv"), "file,label,locomotive,split\nr.csv,normal,indep,test\n").unwrap();
        let (out, skipped) = audit_dir(&set).expect("audit");
        assert!(skipped.is_empty(), "{skipped}");
        eprintln!("{trace}: {}", out.verdict_text());
        assert_eq!(out.cause, want, "{trace}: {}", out.verdict_text());
        assert_eq!(out.to_json()["cause"], want);
        if want == "unexplained" {
            assert!(out.residual_to_noise.0 > 2.0 * pbm_lab::audit::NOISE_FLOOR_RATIO, "{trace}");
        }
    }
}

/// Audits one trace of the independent plant as a one-release data set.
fn audit_independent(trace: &str) -> pbm_lab::audit::AuditOutcome {
    let dir = tempfile::tempdir().unwrap();
    let independent = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent");
    std::fs::copy(independent.join(format!("{trace}.csv")), dir.path().join("r.csv")).unwrap();
    std::fs::write(dir.path().join("manifest.csv"), "file,label,locomotive,split\nr.csv,normal,indep,test\n").unwrap();
    let (out, skipped) = audit_dir(dir.path()).expect("audit");
    assert!(skipped.is_empty(), "{skipped}");
    eprintln!("{trace}: {}", out.verdict_text());
    out
}

/// Issue 17 items 1 and 2 on the independent plant: the audit says *where* and *what* is
/// missing when no mechanism explains it, and names a part beyond its tolerance as such.
/// Truths (the files' `# note:`): a supply vented for 1 s at 5.9 s; a relief-valve leak of
/// 1.00 mm above 5.14 bar g; a regulator hunting ± 0.45 bar at 0.18 Hz; a dead volume × 1.39.
#[test]
fn the_audit_reconstructs_what_is_missing() {
    // Supply vented: the inflow stops (and reverses) in a window around 5.9–6.9 s.
    let out = audit_independent("unfamiliar_supply_dropout_vent_00");
    assert_eq!(out.cause, "unexplained");
    let m = &out.missing[0];
    let stop = m
        .segments
        .iter()
        .find(|s| s.sign < 0 && s.inflow_ratio <= -0.7)
        .unwrap_or_else(|| panic!("no window where the inflow stops: {}", m.description));
    assert!((stop.t_s.0 - 5.9).abs() <= 0.3 && (stop.t_s.1 - 6.9).abs() <= 0.3, "{:?}", stop.t_s);
    assert!(out.verdict_text().contains("inflow stops"), "{}", out.verdict_text());
    // The evidence is not discounted by the smooth misfit: n_eff comes from the noise (it was
    // 60 of 1500 when taken from the residual).
    assert!(out.n_eff >= 0.8 * out.n as f64, "n_eff {} of {}", out.n_eff, out.n);

    // Leak above 5 bar: the sparse regression finds a leak to atmosphere that opens near 5 bar.
    let out = audit_independent("unfamiliar_leak_above_5bar_00");
    assert!(!out.explains_all(), "{}", out.verdict_text());
    let m = &out.missing[0];
    let leak = m.terms.iter().find(|t| t.name == "leak_above").unwrap_or_else(|| panic!("{}", m.description));
    assert!((leak.knot_bar - 5.14).abs() <= 0.4, "knot {} bar", leak.knot_bar);
    assert!((leak.magnitude - 1.0).abs() <= 0.35, "equivalent orifice {} mm", leak.magnitude);
    assert!(m.explained >= 0.9, "{}", m.explained);
    let json = out.to_json();
    assert_eq!(json["unmodelled_flow"][0]["terms"][0]["name"], "leak_above");

    // Hunting regulator: an oscillating flow, never `none`.
    let out = audit_independent("unfamiliar_regulator_hunting_00");
    assert_eq!(out.cause, "unexplained");
    assert!(out.missing[0].description.contains("oscillates"), "{}", out.missing[0].description);

    // Dead volume × 1.39: a parameter beyond tolerance, not heat transfer at its search bound
    // plus an air temperature of 220 K.
    let out = audit_independent("unfamiliar_big_volume_01");
    assert_eq!(out.cause, "dead_volume", "{}", out.verdict_text());
    let (_, scale, sd) = out.cause_parameter.expect("a parameter");
    assert!((scale - 1.39).abs() <= 0.06 && sd < 0.05, "{scale} ± {sd}");
    assert!(out.explains_all());
    assert_eq!(out.to_json()["causes"][0]["unit"], "× documented");
    // The incredible fit that used to be named is still reported, as not credible.
    assert!(out.ranking.iter().any(|c| c.name.contains("heat_transfer") && c.flag.is_some()));

    // And a clean release has no significant unmodelled flow.
    let out = audit_independent("clean_normal_0000");
    assert_eq!(out.cause, "none");
    assert!(!out.missing[0].significant(), "{}", out.missing[0].description);
}

/// A short event (a sticky spot mid-stroke: the pressure dips 0.05 bar for 0.4 s, 15 noise σ of
/// the mean release) barely moves the RMS over the whole release, but the audit must not call it
/// `none` (an independent tester's plant got `none` here): the worst 1 s window is above its
/// floor and the reconstruction finds the event.
#[test]
fn a_short_event_is_not_none() {
    let seed = first_seed(1) + pbm_lab::audit_sweep::NULL_SEED_OFFSET;
    let clean = synth_data(seed, &[], RELEASES_PER_CASE).expect("data");
    let out = audit(&clean, AuditOptions::default()).expect("audit runs");
    assert_eq!(out.cause, "none");
    assert!(out.window_to_noise.0 <= 2.0, "clean worst window {}", out.window_to_noise.0);
    let mut data = clean;
    let dip = |i: usize| {
        let t = i as f64 * 0.01;
        if (12.0..12.4).contains(&t) {
            -0.05 * (1.0 - ((t - 12.2) / 0.2).abs())
        } else {
            0.0
        }
    };
    for g in &mut data.groups {
        for (i, v) in g.mean.iter_mut().enumerate() {
            *v += dip(i);
        }
        for t in &mut g.traces {
            for (i, v) in t.iter_mut().enumerate() {
                *v += dip(i);
            }
        }
    }
    let out = audit(&data, AuditOptions::default()).expect("audit runs");
    eprint!("{}", out.summary());
    assert_ne!(out.cause, "none", "{}", out.verdict_text());
    assert!(!out.explains_all());
    assert!(out.window_to_noise.0 > pbm_lab::audit::WINDOW_FLOOR_RATIO, "{}", out.window_to_noise.0);
    let seg = out.missing[0].segments.iter().find(|s| s.t_s.0 <= 12.4 && s.t_s.1 >= 12.0);
    assert!(seg.is_some(), "{}", out.missing[0].description);
}

/// A third independent plant (`tests/data/independent2`, issue 17): a 2 L volume behind a 0.4 mm
/// restriction fits a library mechanism at the noise floor (the tester's sets got `laminar_leak`
/// or `heat_transfer`, by seed). Whatever is named, the verdict must not claim it alone: the
/// look-alike outside the library is listed with how to tell them apart.
#[test]
fn a_second_volume_is_not_named_without_its_look_alike() {
    let set = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent2/second_volume");
    let (out, skipped) = audit_dir(&set).expect("audit");
    assert!(skipped.is_empty(), "{skipped}");
    eprintln!("{}", out.verdict_text());
    assert_ne!(out.cause, "none", "{}", out.verdict_text());
    if out.cause.contains("laminar_leak") || out.cause.contains("heat_transfer") {
        assert!(
            out.alternatives.iter().any(|a| a.contains("a volume filling through a restriction")),
            "{}",
            out.verdict_text()
        );
        assert!(out.verdict_text().contains("a long hold at the plateau tells them apart"));
    }
}

/// A transducer whose offset alternates ± 0.05 bar from release to release (a seventh independent
/// tester's case): the mean release fits the base model, but the releases do not agree with each
/// other, so `none` ("consistent with the noise") is not earned; it was given. The same releases
/// without the offsets are `none`.
#[test]
fn releases_that_disagree_with_each_other_are_never_none() {
    use pbm_lab::generate::{fleet, simulate_plant, GENERATE_STEP_S, TRACE_SAMPLES};
    let plant = fleet(41, 1)[0].params;
    let (p, _) = simulate_plant(&plant, GENERATE_STEP_S, TRACE_SAMPLES).expect("plant");
    for offset in [0.0, 0.05] {
        let data = noisy_releases(&p, 41, 8, pbm::TwinParams::nominal(), |k| if k % 2 == 0 { offset } else { -offset });
        let out = audit(&data, AuditOptions::default()).expect("audit runs");
        let text = out.verdict_text();
        eprintln!("± {offset} bar: {text}");
        if offset == 0.0 {
            assert_eq!(out.cause, "none", "{text}");
        } else {
            assert_eq!(out.cause, "unexplained", "{text}");
            assert!(text.contains("the releases are not consistent with each other"), "{text}");
        }
    }
}

/// Releases logged by a clock 15 % slow (a release that takes 1.15 s is stamped 1 s): the data
/// cannot tell it from more flow, so a named discharge coefficient or gas temperature must list
/// the clock. A seventh independent tester's clocks 9–20 % off, and a 50 Hz logger written as
/// 100 Hz, were named with no clock listed (the look-alike was listed only within ± 10 % of the
/// flow factor).
#[test]
fn a_logger_clock_off_is_listed_with_the_flow_it_looks_like() {
    use pbm_lab::generate::{fleet, simulate_plant, GENERATE_STEP_S, TRACE_SAMPLES};
    let plant = fleet(43, 1)[0].params;
    let stretch = 1.15;
    let samples = (TRACE_SAMPLES as f64 * stretch) as usize + 2;
    let (p, _) = simulate_plant(&plant, GENERATE_STEP_S, samples).expect("plant");
    // Sample k of the log is true time k · 10 ms · 1.15: linear interpolation of the plant.
    let logged: Vec<f64> = (0..TRACE_SAMPLES)
        .map(|k| {
            let x = k as f64 * stretch;
            let (i, f) = (x.floor() as usize, x.fract());
            p[i] * (1.0 - f) + p[i + 1] * f
        })
        .collect();
    let data = noisy_releases(&logged, 43, 6, pbm::TwinParams::nominal(), |_| 0.0);
    let out = audit(&data, AuditOptions::default()).expect("audit runs");
    let text = out.verdict_text();
    eprintln!("{text}");
    assert_ne!(out.cause, "none", "{text}");
    if out.cause.contains("discharge_coefficient") || out.cause == "gas_temperature" {
        assert!(out.alternatives.iter().any(|a| a.contains("time stamps ×") && a.contains("logger clock")), "{text}");
    }
}

/// A spring 1.2× stiffer than documented, from a sixth independent plant (tests/data/independent3):
/// the spring rate alone fits to the noise (1.13, its 1 σ too wide to be beyond tolerance by
/// 2 σ), and `gas_temperature` with the spring rate fits no better, the gas temperature standing
/// in for a discharge coefficient at its bound. The pair was named "explains the discrepancy"; it
/// must not be named.
#[test]
fn a_pair_whose_part_alone_fits_as_well_is_not_named() {
    let set = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent3/stiff_spring");
    let (out, skipped) = audit_dir(&set).expect("audit");
    assert!(skipped.is_empty(), "{skipped}");
    let text = out.verdict_text();
    eprintln!("{text}");
    assert!(!out.cause.contains("gas_temperature"), "{text}");
    assert!(!(out.explains_all() && out.cause_parameter.is_none() && !out.cause.contains("spring")), "{text}");
    // Since an eighth tester's spring 1.25× stiff (fitted 1.24 ± 0.23): the spring rate alone
    // takes the residual to the floor, 4× below the base within tolerance, and nothing else
    // alone fits as well, so it is named with its wide 1 σ said.
    assert_eq!(out.cause, "spring_rate", "{text}");
    let (_, scale, sd) = out.cause_parameter.expect("a part beyond tolerance");
    assert!((scale - 1.2).abs() < 2.0 * sd, "{text}");
    assert!(text.contains("the 1 σ is wide because parts at the edge of their tolerance trade with it"), "{text}");
}

/// A release cut off before its plateau (the independent tester's 3, 5 and 12 s traces were
/// `none`, "the base model is consistent", though the phases where a leak shows were missing) is
/// refused with the reason; the whole release of the same file is audited.
#[test]
fn a_release_cut_off_before_its_plateau_is_refused() {
    let independent = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent");
    let text = std::fs::read_to_string(independent.join("clean_air_leak_0000.csv")).unwrap();
    for (seconds, refused) in [(3.0, true), (12.0, true), (20.0, true), (f64::INFINITY, false)] {
        let dir = tempfile::tempdir().unwrap();
        let kept: String = text
            .lines()
            .filter(|l| l.split(',').next().and_then(|t| t.parse::<f64>().ok()).is_none_or(|t| t < seconds))
            .map(|l| format!("{l}\n"))
            .collect();
        std::fs::write(dir.path().join("r.csv"), kept).unwrap();
        std::fs::write(dir.path().join("manifest.csv"), "file,label,locomotive,split\nr.csv,normal,indep,test\n")
            .unwrap();
        match audit_dir(dir.path()) {
            Err(e) if refused => {
                let e = format!("{e:#}");
                assert!(e.contains("release too short to audit"), "{e}");
            }
            Ok((out, _)) if !refused => assert_ne!(out.cause, "none", "{}", out.verdict_text()),
            other => panic!("{seconds} s: {:?}", other.map(|(o, _)| o.verdict_text())),
        }
    }
}

/// Noisy releases (the generator's transducer and ADC) of plants `plant(k)` for release `k`, all
/// documented as the nominal brake.
fn plant_set(releases: usize, seed: u64, plant: impl Fn(usize) -> pbm::TwinParams) -> pbm_lab::audit::AuditData {
    plant_set_read(releases, seed, plant, |p| p.to_vec())
}

/// [`plant_set`] through a transducer that reads `reading(p)` of the true pressures (bar g, 100
/// Hz) before its noise and ADC.
fn plant_set_read(
    releases: usize,
    seed: u64,
    plant: impl Fn(usize) -> pbm::TwinParams,
    reading: impl Fn(&[f64]) -> Vec<f64>,
) -> pbm_lab::audit::AuditData {
    use rand_core::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let traces = (0..releases)
        .map(|k| {
            let (p, _) = pbm_lab::generate::simulate_plant(
                &plant(k),
                pbm_lab::generate::GENERATE_STEP_S,
                pbm_lab::generate::TRACE_SAMPLES,
            )
            .unwrap();
            let adc = pbm_lab::generate::sense(&reading(&p), &mut rng);
            let bar = adc.iter().map(|&c| pbm::sensor::bar_from_adc(pbm::AdcCounts(c)).0).collect();
            (format!("r{k:02}.csv"), pbm::TwinParams::nominal(), bar)
        })
        .collect();
    pbm_lab::audit::data_from_traces("plant_set", traces).unwrap()
}

/// A fourth independent tester's findings (2026-11-27): a fatigued spring (0.8 × its rate) was
/// named a progressive spring with a negative ratio (no candidate for the rate beyond
/// tolerance); a partly blocked orifice (1.15 mm documented as 1.25 mm) was named a discharge
/// coefficient with nothing said of the orifice, and a brake at −40 °C the same; releases that
/// differ from each other (a leak on every other one) were fitted through their mean and a
/// cause named for a mean that is no release.
#[test]
fn a_weak_spring_a_blocked_orifice_and_releases_that_differ_are_told_honestly() {
    let options = AuditOptions { pairs: false, ..AuditOptions::default() };
    let nominal = pbm::TwinParams::nominal();

    let weak =
        plant_set(8, 41, |_| pbm::TwinParams { spring_rate_n_per_m: 0.8 * nominal.spring_rate_n_per_m, ..nominal });
    let out = audit(&weak, options).expect("audit");
    eprintln!("weak spring: {}", out.verdict_text());
    assert_eq!(out.cause, "spring_rate", "{}", out.verdict_text());
    let (_, scale, _) = out.cause_parameter.expect("a part beyond tolerance");
    assert!((scale - 0.8).abs() < 0.03, "{scale}");

    let blocked = plant_set(8, 42, |_| pbm::TwinParams { orifice: pbm::units::Meters(1.15e-3), ..nominal });
    let out = audit(&blocked, options).expect("audit");
    eprintln!("blocked orifice: {}", out.verdict_text());
    assert!(matches!(out.cause.as_str(), "discharge_coefficient" | "gas_temperature"), "{}", out.verdict_text());
    assert!(
        out.alternatives.iter().any(|a| a.contains("an orifice of 1.1") && a.contains("1.25 mm is documented")),
        "{:?}",
        out.alternatives
    );

    let leaky = plant_set(8, 43, |k| pbm::TwinParams {
        leak: pbm::units::Meters(if k % 2 == 0 { 0.8e-3 } else { 0.0 }),
        ..nominal
    });
    let out = audit(&leaky, options).expect("audit");
    eprintln!("leak on every other release: {}", out.verdict_text());
    assert_eq!(out.cause, "unexplained", "{}", out.verdict_text());
    assert!(out.verdict_text().contains("differ from each other"), "{}", out.verdict_text());
    assert!(out.to_json()["release_spread"]["matters"].as_bool().unwrap());

    // One cause acting on every release alike: the releases' own spread does not matter.
    let spread = out.release_spread.clone().unwrap();
    assert!(spread.spread_bar > 0.1, "{spread:?}");
    let weak_again =
        audit(&plant_set(8, 44, |_| pbm::TwinParams { leak: pbm::units::Meters(0.8e-3), ..nominal }), options)
            .expect("audit");
    assert!(!weak_again.verdict_text().contains("differ from each other"), "{}", weak_again.verdict_text());
}

/// A mechanism next to a part beyond tolerance (issue 17: "pairs of a mechanism and a part
/// beyond tolerance are not searched"). An independent plant's valve 0.3 s late on a brake with
/// a spring at 0.8 × its rate had been named a transport delay plus a progressive spring of
/// negative ratio, "part"; a laminar leak in a cylinder with 1.3 × its dead volume a discharge
/// coefficient, "part". Both parts and both mechanisms are now named, with their magnitudes.
#[test]
fn a_mechanism_next_to_a_part_beyond_tolerance_is_named_with_it() {
    let options = AuditOptions::default();
    let nominal = pbm::TwinParams::nominal();
    let mut late = pbm::TwinParams { spring_rate_n_per_m: 0.8 * nominal.spring_rate_n_per_m, ..nominal };
    late.ext[Mechanism::TransportDelay] = 0.3;
    let out = audit(&plant_set(8, 51, |_| late), options).expect("audit");
    eprintln!("late valve, weak spring: {}", out.verdict_text());
    assert_eq!(out.cause, "transport_delay+spring_rate", "{}", out.verdict_text());
    let (_, scale, _) = out.cause_parameter.expect("a part beyond tolerance");
    assert!((scale - 0.8).abs() < 0.03, "{scale}");
    assert!((out.magnitude() - 0.3).abs() < 0.03, "{}", out.magnitude());
    assert!(out.verdict_text().starts_with("transport_delay with spring_rate = 0.8"), "{}", out.verdict_text());
    let json = out.to_json();
    assert_eq!(json["causes"].as_array().map(Vec::len), Some(2), "{json}");

    let mut leaky = pbm::TwinParams { dead_volume_m3: 1.3 * nominal.dead_volume_m3, ..nominal };
    leaky.ext[Mechanism::LaminarLeak] = 0.3;
    let out = audit(&plant_set(8, 52, |_| leaky), options).expect("audit");
    eprintln!("leak, large dead volume: {}", out.verdict_text());
    assert_eq!(out.cause, "laminar_leak+dead_volume", "{}", out.verdict_text());
    let (_, scale, _) = out.cause_parameter.expect("a part beyond tolerance");
    assert!((scale - 1.3).abs() < 0.05, "{scale}");
}

/// Issue 17, item 6: an open-world sweep (`pbm_lab::open_world`), one case of each effect outside
/// the library (a hunting regulator, a leak above a pressure, a supply cut, an icing orifice, a
/// rough bore patch, a tearing seal, a transducer bow), some mixed with a library mechanism: the
/// verdict is never `none` while the base NMSE is ≥ 3× the noise floor's. (The 140-case sweep
/// is `host-sim audit-sweep --cases 0 --open-world 140`, bench/audit_sweep.md.)
#[test]
fn the_open_world_sweep_is_honest_on_every_kind() {
    use pbm_lab::open_world::{check_open_case, draw_open_case, Foreign, OPEN_WORLD_SEED_OFFSET};
    let seed = first_seed(1) + OPEN_WORLD_SEED_OFFSET;
    let kinds = Foreign::KINDS.len() as u64;
    let results: Vec<_> =
        (seed..seed + kinds).map(|s| (s, check_open_case(&draw_open_case(s).unwrap()).unwrap())).collect();
    let mut seen: Vec<&str> = results.iter().map(|(_, r)| r.foreign.name()).collect();
    seen.sort_unstable();
    seen.dedup();
    assert_eq!(seen.len(), Foreign::KINDS.len(), "{seen:?}");
    for (s, r) in &results {
        eprintln!("{}", r.line(*s));
        assert!(r.honest(), "{}\n{}", r.line(*s), r.outcome.summary());
    }
}

/// A fifth independent tester: a supply of 7.4 bar g where 7.7 is documented was named a
/// transducer gain of 0.962 "explaining the discrepancy", with nothing said of the supply. Within
/// the parts' tolerances the two are one: the verdict must list the supply.
#[test]
fn a_transducer_gain_is_not_named_without_the_supply_it_cannot_be_told_from() {
    let nominal = pbm::TwinParams::nominal();
    let low = plant_set(8, 45, |_| pbm::TwinParams { supply: pbm::BarG(7.4), ..nominal });
    let out = audit(&low, AuditOptions { pairs: false, ..AuditOptions::default() }).expect("audit");
    eprintln!("supply 7.4 bar g: {}", out.verdict_text());
    assert_ne!(out.cause, "none", "{}", out.verdict_text());
    if out.cause == "sensor_gain" {
        assert!(out.alternatives.iter().any(|a| a.contains("a supply of 7.4")), "{:?}", out.alternatives);
    }
}

/// A seventh independent plant (tests/data/independent4): friction 0.4× documented shows about
/// the breakaway only (the base 1.2× the noise overall, 3.4× in its worst second), so no
/// candidate could cut the RSS 1.5-fold, and the right fit (0.37 ± 0.04) was `unexplained`. A
/// single that takes the whole residual and its worst second to the floor now explains it, but
/// only when no other single fits as well: LuGre bristles 10× softer are fitted by friction 0.54×
/// and by a small droop alike, and neither may be named.
#[test]
fn a_local_discrepancy_is_named_only_when_one_cause_takes_it_to_the_floor() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent4");
    let (out, skipped) = audit_dir(&data.join("part_fric_040")).expect("audit");
    assert!(skipped.is_empty(), "{skipped}");
    let text = out.verdict_text();
    eprintln!("{text}");
    let (name, factor, sd) = out.cause_parameter.expect("a part beyond tolerance is named");
    assert!(name == "friction" && out.explains_all(), "{text}");
    assert!((factor - 0.4).abs() < 2.0 * sd, "{text}");
    let (out, _) = audit_dir(&data.join("c_s0_10")).expect("audit");
    let text = out.verdict_text();
    eprintln!("{text}");
    assert_eq!(out.cause, "unexplained", "{text}");
    assert!(text.contains("fits as well, and this close to the noise the data cannot tell them apart"), "{text}");
}

/// A transducer hysteresis (a seventh independent tester's: −0.05 bar while the pressure rises,
/// fading at rest) was named a −0.050 bar `sensor_offset` "explaining the discrepancy", with
/// nothing said: within twice the supply's tolerance the plateau cannot confirm an offset. An
/// offset that small is named with the reading error it cannot be told from; a large one is not.
#[test]
fn a_small_offset_is_named_with_the_hysteresis_it_cannot_be_told_from() {
    let options = AuditOptions { pairs: false, ..AuditOptions::default() };
    let nominal = pbm::TwinParams::nominal();
    let hysteresis = |p: &[f64]| -> Vec<f64> {
        (0..p.len())
            .map(|i| {
                let rate = (p[(i + 1).min(p.len() - 1)] - p[i.saturating_sub(1)]) / 0.02;
                p[i] - 0.05 * (rate / 0.2).tanh()
            })
            .collect()
    };
    let out = audit(&plant_set_read(8, 61, |_| nominal, hysteresis), options).expect("audit");
    let text = out.verdict_text();
    eprintln!("hysteresis: {text}");
    if out.cause.contains("sensor_offset") {
        assert!(text.contains("fades at rest"), "{text}");
    }
    for (offset, look_alike) in [(-0.05, true), (-0.3, false)] {
        let out = audit(&plant_set_read(8, 62, |_| nominal, |p| p.iter().map(|v| v + offset).collect()), options)
            .expect("audit");
        let text = out.verdict_text();
        eprintln!("offset {offset} bar: {text}");
        assert_eq!(out.cause, "sensor_offset", "{text}");
        assert_eq!(text.contains("fades at rest"), look_alike, "{text}");
    }
}

/// A healthy brake logged from 0.3 s before the valve command (an eighth independent tester's
/// trigger offsets of 0.15–0.6 s) is a transport delay to the data; it was named one,
/// "explaining the discrepancy", with nothing said of the trigger. The early trigger is listed.
#[test]
fn a_transport_delay_is_named_with_the_early_trigger_it_cannot_be_told_from() {
    let options = AuditOptions { pairs: false, ..AuditOptions::default() };
    let nominal = pbm::TwinParams::nominal();
    let early =
        |p: &[f64]| -> Vec<f64> { std::iter::repeat_n(0.0, 30).chain(p.iter().copied()).take(p.len()).collect() };
    let out = audit(&plant_set_read(8, 63, |_| nominal, early), options).expect("audit");
    let text = out.verdict_text();
    eprintln!("early trigger: {text}");
    assert_eq!(out.cause, "transport_delay", "{text}");
    assert!((out.magnitude() - 0.3).abs() < 0.02, "{text}");
    assert!(
        out.alternatives
            .iter()
            .any(|a| a.contains("a trace that starts 0.3") && a.contains("before the release command")),
        "{text}"
    );
}

/// A leak through an opening to atmosphere (the `air_leak` fault of SPEC §5: turbulent, flowing
/// with the absolute pressure) on a brake documented as tight is fitted by the library's laminar
/// leak to the noise; an independently written plant's openings of 0.3–0.6 mm were named
/// `laminar_leak` "explaining" with nothing said of the opening. The opening, with its diameter,
/// is listed.
#[test]
fn an_opening_leak_is_named_with_its_diameter_as_a_look_alike() {
    let options = AuditOptions { pairs: false, ..AuditOptions::default() };
    let nominal = pbm::TwinParams::nominal();
    let leaky = pbm::TwinParams { leak: pbm::Meters::from_mm(0.45), ..nominal };
    let out = audit(&plant_set(4, 71, |_| leaky), options).expect("audit");
    let text = out.verdict_text();
    eprintln!("opening leak: {text}");
    assert_eq!(out.cause, "laminar_leak", "{text}");
    let opening = out
        .alternatives
        .iter()
        .find_map(|a| a.strip_prefix("a leak through an opening of "))
        .unwrap_or_else(|| panic!("no opening listed: {text}"));
    let mm: f64 = opening.split(' ').next().and_then(|v| v.parse().ok()).expect("a diameter");
    assert!((mm - 0.45).abs() <= 0.03, "{mm} mm for 0.45: {text}");
}

/// A ninth independent tester's plant (`tests/data/independent5`, `plant9.py`): a transducer
/// bowed by +0.08 bar at mid-range was named `sensor_gain` "explaining", with only the supply
/// listed; heat exchanged with a cylinder wall at 323 K (air at 293 K) was named heat transfer
/// with supply air at 269 K, "explaining", with nothing said of the wall. Each is now named with
/// the look-alike it cannot be told from.
#[test]
fn a_bowed_transducer_and_a_warm_wall_are_named_with_what_they_look_like() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent5");
    for (set, cause, look_alike) in [
        ("bow_0.08", "sensor_gain", "a transducer that is not linear"),
        ("hot_wall_323", "heat_transfer+gas_temperature", "a cylinder wall warmer than the supply air"),
    ] {
        let (out, skipped) = audit_dir(&data.join(set)).expect("audit");
        let text = out.verdict_text();
        eprintln!("{set}: {text}");
        assert!(skipped.is_empty(), "{set}: {skipped}");
        assert_eq!(out.cause, cause, "{set}: {text}");
        assert!(out.alternatives.iter().any(|a| a.starts_with(look_alike)), "{set}: {text}");
    }
}

/// A ninth independent tester's healthy brakes read through a transducer whose noise is
/// correlated in time (σ 0.01 bar, τ 0.1 s; `tests/data/independent5/correlated_noise_healthy`):
/// the noise read 0.0018 bar from sample to sample, and the verdict was `unexplained` at 5.3×
/// with the releases said to differ "beyond their noise". The verdict now says the noise is
/// correlated, measures the residual against it (1.1×, the discrepancy may be that noise) and
/// claims no spread the noise can give.
#[test]
fn correlated_transducer_noise_is_said_and_no_spread_is_claimed_from_it() {
    let dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent5/correlated_noise_healthy");
    let (out, _) = audit_dir(&dir).expect("audit");
    let text = out.verdict_text();
    eprintln!("correlated noise: {text}");
    let spread = out.release_spread.as_ref().expect("four releases");
    assert!(spread.noise_correlated() && spread.fast_noise_bar > 4.0 * spread.white_noise_bar, "{spread:?}");
    assert_eq!(spread.colour, NoiseColour::Correlated, "{spread:?}");
    assert!(!spread.matters(out.residual_to_noise.0), "{spread:?}");
    assert!(!text.contains("beyond their noise"), "{text}");
    // Judged against the noise under a second, the healthy brake is what it is.
    assert_eq!(out.cause, "none", "{text}");
    assert!(text.contains("correlated in time") && text.contains("residuals are judged against the 0.009"), "{text}");
}

/// Noise correlated in time is taken for the noise only when it looks like a transducer's: the
/// project's own plant, read through white noise (σ 0.01 bar) plus noise of σ 0.03 bar and τ
/// 0.1 s, is `none` with the correlation said; the same brake whose releases swing by 0.05 bar
/// at 0.7 Hz, each in its own phase, is not taken for noise (its deviations under a second are
/// 2.3× the white noise too), and is never `none`: taken for noise, it was; nor is a vibration
/// on some of the releases only.
#[test]
fn correlated_noise_is_the_noise_and_releases_swinging_out_of_step_are_not() {
    use rand_core::SeedableRng;
    use std::cell::{Cell, RefCell};
    let rng = RefCell::new(rand_chacha::ChaCha8Rng::seed_from_u64(3901));
    let r = (-pbm::twin::SAMPLE_PERIOD_S / 0.1f64).exp();
    // `p` with AR(1) noise of σ `sigma` and τ 0.1 s added.
    let with_ar_noise = |p: &[f64], sigma: f64| -> Vec<f64> {
        let w = pbm_lab::generate::transducer_noise(p.len(), sigma, &mut *rng.borrow_mut());
        let mut x = 0.0;
        p.iter()
            .zip(w)
            .map(|(p, w)| {
                x = r * x + (1.0 - r * r).sqrt() * w;
                p + x
            })
            .collect()
    };
    let coloured = |p: &[f64]| with_ar_noise(p, 0.03);
    let data = plant_set_read(4, 3902, |_| pbm::TwinParams::nominal(), coloured);
    let out = audit(&data, AuditOptions::default()).expect("audit runs");
    let text = out.verdict_text();
    eprintln!("coloured: {text}");
    let spread = out.release_spread.as_ref().expect("four releases");
    assert_eq!(spread.colour, NoiseColour::Correlated, "{spread:?}");
    assert_eq!(out.cause, "none", "{text}");
    assert!(text.contains("the transducer's noise is not white: correlated in time"), "{text}");

    let release = Cell::new(0usize);
    let swinging = |p: &[f64]| {
        let phase = 1.7 * release.get() as f64;
        release.set(release.get() + 1);
        p.iter()
            .enumerate()
            .map(|(i, p)| {
                let t = i as f64 * pbm::twin::SAMPLE_PERIOD_S;
                p + 0.05 * (2.0 * std::f64::consts::PI * 0.7 * t + phase).sin() * (t / 5.0).min(1.0)
            })
            .collect()
    };
    let data = plant_set_read(4, 3903, |_| pbm::TwinParams::nominal(), swinging);
    let out = audit(&data, AuditOptions::default()).expect("audit runs");
    let text = out.verdict_text();
    eprintln!("swinging: {text}");
    let spread = out.release_spread.as_ref().expect("four releases");
    assert!(spread.fast_noise_bar > 1.5 * spread.white_noise_bar, "{spread:?}");
    assert_eq!(spread.colour, NoiseColour::Oscillating, "{spread:?}");
    assert_ne!(out.cause, "none", "{text}");
    assert!(text.contains("not taken for the transducer's noise"), "{text}");

    // A 10 Hz vibration of 0.025 bar on two releases of four, each in its own phase, under
    // correlated noise of σ 0.012 bar: a transducer's noise is the same on every release (an eleventh independent tester's
    // vibration on some releases only was `none` when taken for noise).
    let release = Cell::new(0usize);
    let vibrating = |p: &[f64]| {
        let k = release.get();
        release.set(k + 1);
        let with_noise = with_ar_noise(p, 0.012);
        if k % 2 == 0 {
            return with_noise;
        }
        with_noise
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let t = i as f64 * pbm::twin::SAMPLE_PERIOD_S;
                p + 0.025 * (2.0 * std::f64::consts::PI * 10.0 * t + 2.1 * k as f64).sin()
            })
            .collect()
    };
    let data = plant_set_read(4, 3904, |_| pbm::TwinParams::nominal(), vibrating);
    let out = audit(&data, AuditOptions::default()).expect("audit runs");
    let text = out.verdict_text();
    eprintln!("vibrating: {text}");
    let spread = out.release_spread.as_ref().expect("four releases");
    assert_eq!(spread.colour, NoiseColour::Unsteady, "{spread:?}");
    assert_ne!(out.cause, "none", "{text}");
}
