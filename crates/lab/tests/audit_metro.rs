//! The audit on real pneumatic data (SPEC §8, MetroPT-3 head) and the reader's errors.

use pbm::mechanism::Mechanism;
use pbm_lab::metro::{audit_metro_file, read_metro, write_metro_outputs};
use std::path::Path;

const METRO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data/metropt3/metropt3_head.csv");

/// The adiabatic model misses the thermal relaxation after each compressor cycle: the audit must
/// name heat transfer and cut the NMSE at least 2× (on the extract kept in the repository).
#[test]
fn metro_audit_names_heat_transfer() {
    let path = Path::new(METRO);
    let (rows, out) = audit_metro_file(path).expect("audit runs");
    eprint!("{}", out.summary());
    assert!(out.cause.split('+').any(|c| c == "heat_transfer"), "cause {}", out.cause);
    assert!(out.base.nmse_pct >= 2.0 * out.chosen.nmse_pct, "gain {} → {}", out.base.nmse_pct, out.chosen.nmse_pct);
    let dir = tempfile::tempdir().expect("tempdir");
    let json = dir.path().join("metro.json");
    write_metro_outputs(&rows, &out, Some(&json), Some(dir.path())).expect("outputs");
    let text = std::fs::read_to_string(&json).expect("json");
    assert!(text.contains("\"nmse_base_pct\"") && text.contains("\"ranking\"") && text.contains("\"uncertainty\": ["));
    // Each named magnitude is determined to better than ± 25 % (1 σ).
    for (e, v, u) in &out.chosen.effects {
        assert!(u.is_finite() && *u < 0.25 * v.abs(), "{} = {v} ± {u}", e.name());
    }
    assert!(dir.path().join("metro_curves.svg").exists() && dir.path().join("metro_residual.svg").exists());
}

/// Issue 17: the real-data model is not at the noise floor, and the audit must say so instead
/// of presenting heat transfer + delay as the whole story, and say what is still missing: an
/// extra outflow one to three minutes after each unloading (the chosen model leaves
/// −0.022 bar/min there, ≈ 12 standard errors) and less outflow than modelled late in the decay
/// (8.1–8.4 bar). The compressor switches are estimated inside their 10 s sampling intervals,
/// which halves the loading phase's error; the cycles, taken as replicates, differ by ≈ 8× the
/// transducer noise (consumption the record does not hold), and the model's error common to all
/// cycles is beyond that variation.
#[test]
fn metro_audit_says_what_the_real_data_model_still_misses() {
    let (_, out) = audit_metro_file(Path::new(METRO)).expect("audit runs");
    let (base, chosen) = out.residual_to_noise;
    assert!(chosen > pbm_lab::audit::NOISE_FLOOR_RATIO && chosen < 0.5 * base, "{base} → {chosen}");
    let text = out.verdict_text();
    assert!(text.contains("explains part"), "{text}");
    let after_unloading: Vec<_> =
        out.missing.iter().filter(|a| a.phase == "unloaded" && a.significant() && a.from_s < 240.0).collect();
    assert!(
        !after_unloading.is_empty() && after_unloading.iter().all(|a| a.mean_bar_per_min < 0.0),
        "{:?}",
        out.missing
    );
    assert!(text.contains("extra outflow from 60 to 180 s after the compressor unloads"), "{text}");
    assert!(text.contains("less outflow than modelled from 1500 to 2100 s after the compressor unloads"), "{text}");
    // With the switches estimated, the loaded phase's error is well under what the switch
    // timing alone leaves at the midpoints (it was 0.058 bar, now 0.028 bar).
    let loaded_rms = out.chosen_phase_rms[0].1;
    assert!(loaded_rms <= 0.5 * out.switch_timing_floor_bar, "{loaded_rms} vs {}", out.switch_timing_floor_bar);
    assert!(chosen < 0.25 * base, "{base} → {chosen}");
    // The cycles as replicates: they differ well beyond the transducer noise, and the model's
    // common error is beyond that.
    let floor = out.cycle_floor.expect("the extract holds four complete cycles");
    assert_eq!(floor.cycles, 4);
    assert!(floor.spread_bar > 3.0 * out.sigma && floor.systematic(), "{floor:?}");
    assert!(text.contains("the model still errs the same way in every cycle"), "{text}");
    let json = out.to_json();
    assert_eq!(json["explains_all"], false);
    assert!(json["unmodelled_rate"].as_array().is_some_and(|a| !a.is_empty()));
    assert_eq!(json["cycle_floor"]["systematic"], true);
    assert_eq!(json["switch_s"].as_array().map(Vec::len), Some(10));
}

#[test]
fn metro_reader_reports_file_and_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("m.csv");
    let mut text = String::from("timestamp,TP3,COMP,Oil_temperature\n");
    for i in 0..30 {
        text.push_str(&format!("2020-02-01 00:{:02}:{:02},9.0,1.0,50.0\n", i / 6, (i % 6) * 10));
    }
    text.push_str("2020-02-01 00:05:10,abc,1.0,50.0\n");
    std::fs::write(&p, &text).expect("write");
    let err = format!("{:#}", read_metro(&p).expect_err("bad number"));
    assert!(err.contains("m.csv:32"), "{err}");
    std::fs::write(&p, "timestamp,TP3\n").expect("write");
    let err = format!("{:#}", read_metro(&p).expect_err("missing column"));
    assert!(err.contains("COMP"), "{err}");
}

use pbm_lab::metro::{
    audit_metro, metro_params, simulate, simulate_reference, sweep_summary, synthetic_rows, synthetic_sweep,
    SYNTHETIC_BASE_U, SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR,
};

/// The audit's model is the core's fixed-point reservoir; it must agree with the `f64` reference
/// of the same equations for the base and every mechanism.
#[test]
fn fixed_point_reservoir_matches_f64_reference() {
    let u = SYNTHETIC_BASE_U;
    let rows = synthetic_rows(&metro_params(&u, &[]), SYNTHETIC_ROWS, 0.0, 1);
    let cases: Vec<Vec<(Mechanism, f64)>> = vec![
        vec![],
        vec![(Mechanism::HeatTransfer, 20.0)],
        vec![(Mechanism::TransportDelay, 9.3)],
        vec![(Mechanism::ValveLag, 15.0)],
        vec![(Mechanism::SensorLag, 12.0)],
        vec![(Mechanism::SensorOffset, -0.05), (Mechanism::SensorGain, 1.04)],
        vec![(Mechanism::LaminarLeak, 0.8)],
        vec![(Mechanism::HeatTransfer, 20.0), (Mechanism::TransportDelay, 9.3)],
    ];
    for effects in cases {
        let params = metro_params(&u, &effects);
        let fixed = simulate(&rows, &params).expect("parameters in range");
        let reference = simulate_reference(&rows, &params);
        let nmse = pbm::metrics::nmse_pct(&reference, &fixed).expect("nmse");
        let worst = fixed.iter().zip(&reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        eprintln!("{effects:?}: NMSE fixed vs f64 {nmse:.5} %, worst {worst:.5} bar");
        assert!(nmse < 0.005 && worst < 0.001, "{effects:?}: NMSE {nmse} %, worst {worst} bar");
    }
}

/// Hidden effects in synthetic records from the `f64` reference (not the model the audit fits),
/// mechanism and magnitude drawn from the seed: an identifiable mechanism must be named with its
/// magnitude within 20 % and cut the NMSE at least 5×; one that is collinear with the base
/// (transducer offset or gain, laminar leak: see `pbm::mechanism::Scope::identifiable`) may be missed but
/// never mistaken for another; a clean record gives `none`.
#[test]
fn metro_audit_finds_hidden_effects() {
    let cases = synthetic_sweep(16, 500).expect("sweep runs");
    eprint!("{}", sweep_summary(&cases));
    assert!(
        cases.iter().filter(|c| pbm_lab::metro::metro_identifiable(c.truth.0)).count() >= 6,
        "the draw covers the identifiable pool"
    );
    for c in &cases {
        if pbm_lab::metro::metro_identifiable(c.truth.0) {
            assert!(c.hit(), "{c:?}");
        } else {
            assert!(!c.wrong_name(), "{c:?}");
        }
    }
    let rows = synthetic_rows(&metro_params(&SYNTHETIC_BASE_U, &[]), SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR, 99);
    let out = audit_metro(&rows).expect("audit runs");
    eprint!("{}", out.summary());
    assert_eq!(out.cause, "none");
}
