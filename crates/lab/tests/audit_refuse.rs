//! Inputs that are no release are refused by the audit with a clear reason (issue 17, item 3):
//! no pressure rise, a sensor fault that destroys the signal, NaN, too short; metadata keys match
//! exactly and an unknown key is a warning; the audit never reports non-finite figures. The
//! sensor mechanisms the audit must find (offset, gain, lag) are *not* refused.

use pbm::mechanism::{Extensions, Mechanism};
use pbm::TwinParams;
use pbm_lab::audit::{audit, config_from_meta, data_from_traces, load_dataset, AuditOptions, MIN_SAMPLES};
use pbm_lab::generate::{generate, GenerateOptions, SplitMode};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Writes a data set of `(file, text)` traces (one locomotive, all `normal`).
fn data_set(dir: &Path, traces: &[(&str, String)]) -> PathBuf {
    let mut manifest = "file,label,locomotive,split\n".to_owned();
    for (name, text) in traces {
        std::fs::write(dir.join(name), text).unwrap();
        let _ = writeln!(manifest, "{name},normal,loco-01,train");
    }
    std::fs::write(dir.join("manifest.csv"), manifest).unwrap();
    dir.to_path_buf()
}

/// A 20 s ADC trace from `adc(i)`.
fn adc_trace(meta: &str, adc: impl Fn(usize) -> u16) -> String {
    let mut s = format!("{meta}t_s,adc\n");
    for i in 0..2000 {
        let _ = writeln!(s, "{:.2},{}", i as f64 * 0.01, adc(i));
    }
    s
}

/// Deterministic pseudo-random white noise in [−1, 1] (no RNG crate needed).
fn noise(i: usize) -> f64 {
    let x = (i as u64).wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
    ((x >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

/// One locomotive's healthy releases from the generator (with an optional hidden mechanism).
fn generated(dir: &Path, per_class: usize, seed: u64, effects: Extensions) -> PathBuf {
    let data = dir.join("gen");
    let mut g = GenerateOptions::new(data.clone());
    g.locomotives = 1;
    g.split = SplitMode::Shared;
    g.classes = vec![pbm::FaultClass::Normal];
    g.per_class = per_class;
    g.test_per_class = 0;
    g.seed = seed;
    g.effects = effects;
    generate(&g, false).expect("generate");
    data
}

fn no_usable_release(dir: &Path) -> String {
    let err = load_dataset(dir).expect_err("nothing to audit");
    let msg = format!("{err:#}");
    assert!(msg.contains("no usable release to audit"), "{msg}");
    msg
}

#[test]
fn white_noise_around_zero_is_no_release() {
    let tmp = tempfile::tempdir().unwrap();
    let mut s = "t_s,p_bar\n".to_owned();
    for i in 0..3000 {
        let _ = writeln!(s, "{:.2},{:.4}", i as f64 * 0.01, 0.01 * noise(i));
    }
    let dir = data_set(tmp.path(), &[("noise.csv", s)]);
    let msg = no_usable_release(&dir);
    assert!(msg.contains("noise.csv") && msg.contains("no release to audit: the pressure rises 0.0"), "{msg}");
}

#[test]
fn all_zero_and_constant_adc_are_sensor_faults() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = data_set(tmp.path(), &[("zero.csv", adc_trace("", |_| 0)), ("const.csv", adc_trace("", |_| 2000))]);
    let msg = no_usable_release(&dir);
    assert!(msg.contains("zero.csv:") && msg.contains("sensor fault `open_circuit` at t = 0.00 s"), "{msg}");
    assert!(msg.contains("const.csv:") && msg.contains("sensor fault `dead`"), "{msg}");
}

#[test]
fn nan_and_too_short_traces_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let nan = "t_s,p_bar\n0.00,0.0\n0.01,NaN\n0.02,0.1\n".to_owned();
    let one = "t_s,adc\n0.00,410\n".to_owned();
    let dir = data_set(tmp.path(), &[("nan.csv", nan), ("one.csv", one)]);
    let msg = no_usable_release(&dir);
    assert!(msg.contains("nan.csv:3") && msg.contains("NaN"), "{msg}");
    assert!(msg.contains("one.csv: only 1 samples; the audit needs ≥ 2 s"), "{msg}");
    assert_eq!(MIN_SAMPLES, 200);
}

#[test]
fn metadata_keys_match_exactly_and_unknown_keys_are_warnings() {
    let meta = |kv: &[(&str, &str)]| kv.iter().map(|(k, v)| ((*k).to_owned(), (*v).to_owned())).collect::<Vec<_>>();
    let nominal = TwinParams::nominal();
    // A 5 V sensor supply is no 5 bar brake supply.
    let (p, unknown) = config_from_meta(&meta(&[("sensor_supply_v", "5"), ("label", "normal")])).unwrap();
    assert_eq!(p, nominal);
    assert_eq!(unknown, ["sensor_supply_v"]);
    // The documented keys are used.
    let (p, unknown) = config_from_meta(&meta(&[("supply_bar_g", "6.0"), ("orifice_mm", "0.8")])).unwrap();
    assert!(unknown.is_empty());
    assert_eq!(p.supply.0, 6.0);
    assert!((p.orifice.mm() - 0.8).abs() < 1e-12);
    assert_eq!(p.leak, nominal.leak);
    // Near misses are neither used nor silent.
    let (p, unknown) =
        config_from_meta(&meta(&[("Supply_bar_g", "6.0"), ("laminar_leak_mm", "1"), ("note", "x")])).unwrap();
    assert_eq!(p, nominal);
    assert_eq!(unknown, ["Supply_bar_g", "laminar_leak_mm"]);
    // Everything the generator writes is information.
    let info = ["label", "locomotive", "split", "seed", "trace", "source", "sensor_fault", "truth", "note"];
    let (_, unknown) = config_from_meta(&meta(&info.map(|k| (k, "1")))).unwrap();
    assert!(unknown.is_empty(), "{unknown:?}");
    // A documented key with no number is an error.
    assert!(config_from_meta(&meta(&[("supply_bar_g", "high")])).is_err());
    // A number in another unit is an error, not read as the key's (a sixth independent tester's
    // `0.6 MPa` had been audited as a 0.6 bar g supply); the key's own unit is accepted.
    for bad in ["0.6 MPa", "6.0 psi", "7.7 bar abs", "7.7bar"] {
        let e = config_from_meta(&meta(&[("supply_bar_g", bad)])).expect_err(bad);
        assert!(format!("{e:#}").contains("supply_bar_g"), "{e:#}");
    }
    assert_eq!(config_from_meta(&meta(&[("supply_bar_g", "7.2 bar g")])).unwrap().0.supply.0, 7.2);
    assert!((config_from_meta(&meta(&[("orifice_mm", "1.1 mm")])).unwrap().0.orifice.mm() - 1.1).abs() < 1e-12);
    assert!(config_from_meta(&meta(&[("orifice_mm", "1.1 in")])).is_err());
    // In the twin's range but no release: refused.
    for (key, value) in [("supply_bar_g", "0"), ("supply_bar_g", "0.5"), ("orifice_mm", "0")] {
        let e = config_from_meta(&meta(&[(key, value)])).expect_err(value);
        assert!(format!("{e:#}").contains("no release") || format!("{e:#}").contains("cannot release"), "{e:#}");
    }
}

/// Copies of one release (a file copied under other names, or listed twice in the manifest)
/// are audited once, each copy skipped with the reason; pressures written rounded to 0.05 bar
/// are refused (the noise cannot be estimated under the rounding). A sixth independent tester's
/// eight copies of a healthy release were `unexplained` at 3.1×, and 0.05–0.1 bar steps gave a
/// noise of 0.0000 bar and `unexplained` at 55–143×.
#[test]
fn copies_of_a_release_and_coarsely_rounded_pressures_are_not_audited_as_measurements() {
    let tmp = tempfile::tempdir().unwrap();
    let gen = generated(tmp.path(), 3, 17, Extensions::NONE);
    let (data, skipped) = load_dataset(&gen).unwrap();
    let releases: usize = data.groups.iter().map(|g| g.traces.len()).sum();
    assert!(skipped.is_empty(), "{skipped}");
    // The manifest lists its first trace twice more.
    let manifest = std::fs::read_to_string(gen.join("manifest.csv")).unwrap();
    let first = manifest.lines().nth(1).unwrap().to_owned();
    std::fs::write(gen.join("manifest.csv"), format!("{manifest}{first}\n{first}\n")).unwrap();
    let (data, skipped) = load_dataset(&gen).unwrap();
    assert_eq!(data.groups.iter().map(|g| g.traces.len()).sum::<usize>(), releases);
    assert_eq!(skipped.len(), 2, "{skipped}");
    assert!(format!("{skipped}").contains("an exact copy of"), "{skipped}");

    // A release written in p_bar rounded to 0.05 bar, and the same to 0.01 bar (audited).
    let dir = tempfile::tempdir().unwrap();
    let file = first.split(',').next().unwrap();
    let trace = pbm_io::trace::read_trace(&gen.join(file)).unwrap();
    let rounded = |step: f64| {
        let mut s = "t_s,p_bar\n".to_owned();
        for (t, p) in trace.t_s.iter().zip(trace.pressures_bar()) {
            let _ = writeln!(s, "{t:.2},{:.4}", (p / step).round() * step);
        }
        s
    };
    let set = data_set(dir.path(), &[("coarse.csv", rounded(0.05))]);
    let msg = no_usable_release(&set);
    assert!(msg.contains("steps of 0.050 bar"), "{msg}");
    let fine = tempfile::tempdir().unwrap();
    let set = data_set(fine.path(), &[("fine.csv", rounded(0.01))]);
    assert!(load_dataset(&set).is_ok());
}

/// Healthy releases with one open-circuit channel, one `# sensor_supply_v: 5` and one
/// `# supply_bar_g: 6.0` trace: the open circuit is skipped, the unknown key is a warning in the
/// loaded data and the JSON, the supply stays nominal for it and is 6 bar for the documented one.
#[test]
fn open_circuit_is_skipped_and_unknown_key_is_a_warning_in_the_json() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = generated(tmp.path(), 6, 11, Extensions::NONE);
    let manifest = std::fs::read_to_string(dir.join("manifest.csv")).unwrap();
    let files: Vec<String> = manifest.lines().skip(1).map(|l| l.split(',').next().unwrap().to_owned()).collect();
    // Open circuit from 10 s on.
    let text = std::fs::read_to_string(dir.join(&files[0])).unwrap();
    let mut open = String::new();
    for line in text.lines() {
        match line.split_once(',') {
            Some((t, _)) if t.parse::<f64>().is_ok_and(|t| t >= 10.0) => {
                let _ = writeln!(open, "{t},0");
            }
            _ => {
                let _ = writeln!(open, "{line}");
            }
        }
    }
    std::fs::write(dir.join(&files[0]), open).unwrap();
    let text = std::fs::read_to_string(dir.join(&files[1])).unwrap();
    std::fs::write(dir.join(&files[1]), format!("# sensor_supply_v: 5\n{text}")).unwrap();
    let text = std::fs::read_to_string(dir.join(&files[2])).unwrap();
    std::fs::write(dir.join(&files[2]), format!("# supply_bar_g: 6.0\n{text}")).unwrap();

    let (data, skipped) = load_dataset(&dir).expect("load");
    assert_eq!(skipped.len(), 1, "{skipped}");
    let why = skipped.errors()[0].to_string();
    assert!(why.contains(files[0].as_str()) && why.contains("sensor fault `open_circuit` at t = 10.00 s"), "{why}");
    assert_eq!(data.warnings.len(), 1, "{:?}", data.warnings);
    assert!(data.warnings[0].contains(files[1].as_str()) && data.warnings[0].contains("`sensor_supply_v`"));
    let group_of = |f: &str| data.groups.iter().find(|g| g.files.iter().any(|x| x == f)).unwrap();
    assert_eq!(group_of(&files[1]).config, TwinParams::nominal());
    assert_eq!(group_of(&files[2]).config.supply.0, 6.0);
    assert_eq!(data.groups.len(), 2);

    // One audit run: the warning is in the outcome and the JSON; every figure is finite.
    let only_nominal = pbm_lab::audit::AuditData {
        groups: data.groups.iter().filter(|g| g.config == TwinParams::nominal()).cloned().collect(),
        ..data.clone()
    };
    let out = audit(&only_nominal, AuditOptions { pairs: false, ..AuditOptions::default() }).expect("audit");
    let json = out.to_json();
    assert_eq!(json["warnings"].as_array().map(Vec::len), Some(1), "{json}");
    assert!(json["warnings"][0].as_str().unwrap().contains("sensor_supply_v"));
    assert!(out.base.nmse_pct.is_finite() && out.chosen.nmse_pct.is_finite());
}

/// Releases with the sensor mechanisms the audit must name, at the ends of their plausible
/// ranges, are not refused by the plausibility screen (implausible level is not a refusal).
#[test]
fn sensor_offset_gain_and_lag_releases_are_not_refused() {
    for (k, (m, v)) in [
        (Mechanism::SensorOffset, -0.15),
        (Mechanism::SensorOffset, 0.15),
        (Mechanism::SensorGain, 0.95),
        (Mechanism::SensorGain, 1.05),
        (Mechanism::SensorLag, 0.4),
        (Mechanism::SensorLag, 0.05),
    ]
    .into_iter()
    .enumerate()
    {
        let tmp = tempfile::tempdir().unwrap();
        let dir = generated(tmp.path(), 3, 20 + k as u64, Extensions::NONE.with(m, v));
        let (data, skipped) = load_dataset(&dir).expect("load");
        assert!(skipped.is_empty(), "{m} = {v}: {skipped}");
        assert_eq!(data.groups.iter().map(|g| g.files.len()).sum::<usize>(), 3);
        assert!(data.warnings.is_empty(), "{:?}", data.warnings);
    }
}

/// The audit itself (data built without the loader's screen) fails on data with no defined NMSE
/// instead of naming a cause with NaN or infinite figures.
#[test]
fn audit_of_flat_data_fails_instead_of_reporting_nan() {
    let traces = (0..3).map(|k| (format!("flat{k}.csv"), TwinParams::nominal(), vec![0.0; 1000])).collect();
    let data = data_from_traces("flat", traces).unwrap();
    let err = audit(&data, AuditOptions { pairs: false, ..AuditOptions::default() }).expect_err("no verdict");
    assert!(format!("{err:#}").contains("non-finite"), "{err:#}");
}

/// A noise-free `p_bar` release (`host-sim simulate`) repeats one code on its plateau: that is
/// no frozen transducer, so only raw ADC traces are judged by the noise statistics.
#[test]
fn noise_free_pressure_trace_is_not_a_frozen_sensor() {
    use pbm::sensor::SensorFault;
    use pbm_lab::audit::{refuses, twin_trace};
    let tmp = tempfile::tempdir().unwrap();
    let (p, _) = twin_trace(&TwinParams::nominal(), 3000).unwrap();
    let mut s = "# source: simulated release\nt_s,p_bar\n".to_owned();
    for (i, v) in p.iter().enumerate() {
        let _ = writeln!(s, "{:.2},{v:.6}", i as f64 * 0.01);
    }
    let dir = data_set(tmp.path(), &[("sim.csv", s)]);
    let (data, skipped) = load_dataset(&dir).expect("a release");
    assert!(skipped.is_empty() && data.warnings.is_empty(), "{skipped}");
    assert!(!refuses(SensorFault::ImplausibleLevel, true));
    assert!(refuses(SensorFault::Frozen, true) && !refuses(SensorFault::Frozen, false));
    assert!(refuses(SensorFault::OpenCircuit, false));
}

/// A piston that sticks and breaks free (the third independent plant, `tests/data/independent2/
/// stick_slip`: ≈ 0.4 bar lost within 30 ms at 12 s, then the normal fill) trips the core's
/// `impossible_rate` check. The pressure comes back to the supply, which a transducer that
/// stepped cannot do: the audit takes the releases, says what happened in a warning and answers
/// `unexplained` (the tester's 16-release sets had all been refused as sensor faults). The same
/// drop written into a healthy release's readings, kept to the end or taken back 13 s later, or
/// on the plateau and taken back (a fifth tester's transducer steps at 40–50 s had passed), is
/// still refused as a sensor fault.
#[test]
fn a_piston_breaking_free_is_audited_and_a_transducer_step_is_refused() {
    let set = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent2/stick_slip");
    let (data, skipped) = load_dataset(&set).expect("load");
    assert!(skipped.is_empty(), "{skipped}");
    assert_eq!(data.warnings.len(), 4, "{:?}", data.warnings);
    for w in &data.warnings {
        assert!(
            w.contains("comes back") && w.contains("`impossible_rate`") && w.contains("sticks and breaks free"),
            "{w}"
        );
    }
    let out = audit(&data, AuditOptions::default()).expect("audit");
    assert_eq!(out.cause, "unexplained", "{}", out.verdict_text());

    let tmp = tempfile::tempdir().unwrap();
    let dir = generated(tmp.path(), 2, 31, Extensions::NONE);
    let manifest = std::fs::read_to_string(dir.join("manifest.csv")).unwrap();
    let file = manifest.lines().nth(1).and_then(|l| l.split(',').next()).unwrap().to_owned();
    let healthy = std::fs::read_to_string(dir.join(&file)).unwrap();
    // During the rise, kept or taken back; on the plateau (the piston rests at its end stop and
    // cannot jump), taken back.
    for (from, until) in [(12.0, f64::INFINITY), (12.0, 25.0), (40.0, 50.0)] {
        let mut stepped = String::new();
        for line in healthy.lines() {
            let sample = line.split_once(',').and_then(|(t, a)| Some((t.parse::<f64>().ok()?, a.parse::<u16>().ok()?)));
            match sample {
                Some((t, adc)) if (from..until).contains(&t) => {
                    let p = pbm::sensor::bar_from_adc(pbm::AdcCounts(adc)).0 - 0.4;
                    let _ = writeln!(stepped, "{t:.2},{}", pbm::sensor::adc_from_bar(pbm::units::BarG(p)).0);
                }
                _ => {
                    let _ = writeln!(stepped, "{line}");
                }
            }
        }
        std::fs::write(dir.join(&file), stepped).unwrap();
        let (_, skipped) = load_dataset(&dir).expect("load");
        assert_eq!(skipped.len(), 1, "until {until} s: {skipped}");
        let why = skipped.errors()[0].to_string();
        assert!(why.contains(file.as_str()) && why.contains("sensor fault `impossible_rate` at t = "), "{why}");
    }
}

/// A release from a chamber left at 3 bar g (not vented before the command; a fourth independent
/// tester's set) had been audited and answered with a dead volume of 0.16 × documented: it is
/// refused with the reason.
#[test]
fn a_release_from_a_chamber_not_vented_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = generated(tmp.path(), 2, 33, Extensions::NONE);
    let manifest = std::fs::read_to_string(dir.join("manifest.csv")).unwrap();
    for file in manifest.lines().skip(1).filter_map(|l| l.split(',').next()) {
        let text = std::fs::read_to_string(dir.join(file)).unwrap();
        let mut raised = String::new();
        for line in text.lines() {
            match line.split_once(',').and_then(|(t, a)| Some((t.parse::<f64>().ok()?, a.parse::<u16>().ok()?))) {
                Some((t, adc)) => {
                    // From 3 bar g to the same plateau.
                    let p = 3.0 + pbm::sensor::bar_from_adc(pbm::AdcCounts(adc)).0 * (7.7 - 3.0) / 7.7;
                    let _ = writeln!(raised, "{t:.2},{}", pbm::sensor::adc_from_bar(pbm::units::BarG(p)).0);
                }
                None => {
                    let _ = writeln!(raised, "{line}");
                }
            }
        }
        std::fs::write(dir.join(file), raised).unwrap();
    }
    let msg = no_usable_release(&dir);
    assert!(msg.contains("no release from a vented chamber: the pressure reads 3.0"), "{msg}");
}

/// A sine wave from 0 to 7.7 bar g and a release vented again at 40 s (an independent tester's
/// garbage, audited as `unexplained` at ≈ 1250×) are no single release; a release whose supply
/// is cut for a few seconds, or whose regulator hunts, still is.
#[test]
fn a_pressure_that_falls_back_by_half_its_rise_is_no_release() {
    use pbm::sensor::{adc_from_bar, bar_from_adc};
    use pbm::units::BarG;
    let tmp = tempfile::tempdir().unwrap();
    let dir = generated(tmp.path(), 2, 41, Extensions::NONE);
    let manifest = std::fs::read_to_string(dir.join("manifest.csv")).unwrap();
    let files: Vec<String> = manifest.lines().skip(1).filter_map(|l| l.split(',').next().map(str::to_owned)).collect();
    // Rewrites every trace's ADC codes by `f(t, p)` on its pressure p (bar g).
    let rewrite = |f: &dyn Fn(f64, f64) -> f64| {
        for file in &files {
            let text = std::fs::read_to_string(dir.join(file)).unwrap();
            let mut out = String::new();
            for line in text.lines() {
                match line.split_once(',').and_then(|(t, a)| Some((t.parse::<f64>().ok()?, a.parse::<u16>().ok()?))) {
                    Some((t, adc)) => {
                        let p = f(t, bar_from_adc(pbm::AdcCounts(adc)).0);
                        let _ = writeln!(out, "{t:.2},{}", adc_from_bar(BarG(p)).0);
                    }
                    None => {
                        let _ = writeln!(out, "{line}");
                    }
                }
            }
            std::fs::write(dir.join(file), out).unwrap();
        }
    };
    let original: Vec<String> = files.iter().map(|f| std::fs::read_to_string(dir.join(f)).unwrap()).collect();
    let restore = || {
        for (f, text) in files.iter().zip(&original) {
            std::fs::write(dir.join(f), text).unwrap();
        }
    };
    // Vented at 40 s with a 2 s time constant (the transducer's noise stays on the codes).
    let plateau = 7.7;
    rewrite(&|t, p| if t > 40.0 { p - plateau * (1.0 - (-(t - 40.0) / 2.0).exp()) } else { p });
    let msg = no_usable_release(&dir);
    assert!(msg.contains("no single release: the pressure reaches 7.") && msg.contains("by t = 4"), "{msg}");
    // A sine wave of 20 s period from 0 to 7.7 bar g, with the trace's noise from its plateau.
    restore();
    rewrite(&|t, p| {
        let noise = if t > 40.0 { p - plateau } else { 0.0 };
        3.85 - 3.85 * (2.0 * std::f64::consts::PI * t / 20.0).cos() + noise
    });
    let msg = no_usable_release(&dir);
    assert!(msg.contains("no single release"), "{msg}");
    // A regulator hunting by ± 0.4 bar and a supply that holds its pressure are still releases.
    restore();
    rewrite(&|t, p| if t > 25.0 { p + 0.4 * (2.0 * std::f64::consts::PI * 0.3 * t).sin() } else { p });
    let (data, skipped) = load_dataset(&dir).expect("a hunting regulator is a release");
    assert_eq!(
        (data.groups.iter().map(|g| g.traces.len()).sum::<usize>(), skipped.len()),
        (files.len(), 0),
        "{skipped}"
    );
}

/// An ADC data line stuck at 1 (bit 3, a seventh independent tester's healthy releases,
/// tests/data/independent4/stuck_bit3) was diagnosed `normal 99 %` by the monitor and audited;
/// it is a sensor fault of the core's plausibility check, which the audit refuses on raw codes.
#[test]
fn a_stuck_adc_bit_is_a_sensor_fault() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent4/stuck_bit3");
    let msg = no_usable_release(&dir);
    assert_eq!(msg.matches("sensor fault `lost_resolution`").count(), 2, "{msg}");
    let manifest = std::fs::read_to_string(dir.join("manifest.csv")).unwrap();
    for file in manifest.lines().skip(1).filter_map(|l| l.split(',').next()) {
        let trace = pbm_io::trace::read_trace(&dir.join(file)).unwrap();
        let fault = pbm_lab::audit::signal_destroying_fault(&trace).unwrap();
        assert_eq!(fault.map(|f| f.1), Some(pbm::sensor::SensorFault::LostResolution), "{file}");
    }
}

/// A ninth independent tester's transducer 15× as noisy as specified
/// (`tests/data/independent5/noisy_masked`): on one release the core latched `implausible_level`
/// first (a reading below atmosphere at the release command), which hid the `noisy` fault, and
/// that release was audited `none`, "consistent with the noise". The audit now refuses a trace
/// whose noise is above the core's bound itself.
#[test]
fn a_noisy_transducer_is_refused_when_another_latched_fault_hides_it() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/independent5/noisy_masked");
    let trace = pbm_io::trace::read_trace(&dir.join("rel_01.csv")).unwrap();
    let fault = pbm_lab::audit::signal_destroying_fault(&trace).unwrap();
    assert_ne!(fault.map(|f| f.1), Some(pbm::sensor::SensorFault::Noisy), "the core saw it: nothing hidden");
    let msg = no_usable_release(&dir);
    assert!(msg.contains("rel_01.csv: sensor fault `noisy`: the noise is 0.15"), "{msg}");
    assert_eq!(msg.matches("sensor fault `noisy`").count(), 2, "{msg}");
}
