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
    // Each named magnitude is determined to better than ± 50 % (1 σ: the larger of the
    // covariance's and the jackknife's over the held-out cycles, which is the larger here).
    for (e, v, u) in &out.chosen.effects {
        assert!(u.is_finite() && *u < 0.5 * v.abs(), "{} = {v} ± {u}", e.name());
    }
    let (w, [ue, ut]) = out.chosen.wall.expect("the wall node is named");
    assert!(ue < 0.5 * w.capacity_ratio && ut < 0.5 * w.cooling_s, "{w:?} ± {ue}, {ut}");
    assert!(dir.path().join("metro_curves.svg").exists() && dir.path().join("metro_residual.svg").exists());
}

/// Issue 17: the real-data model is not at the transducer's noise floor, and the audit must say
/// so instead of presenting its cause as the whole story, say what is still missing, and show
/// where the record's own floor lies. The one-node model left an extra outflow one to three
/// minutes after each unloading; a wall that stores heat (`wall_heat`) takes most of it. The
/// cycles, taken as replicates, differ by ≈ 5× the transducer noise (consumption the record does
/// not hold) and the loaded phases scatter by ≈ 0.02 bar from row to row; the model predicts
/// cycles it was not fitted to within 1.5× of the NMSE those two leave, and its error common to
/// all cycles is within their variation.
#[test]
fn metro_audit_says_what_the_real_data_model_still_misses() {
    let (_, out) = audit_metro_file(Path::new(METRO)).expect("audit runs");
    eprint!("{}", out.summary());
    let (base, chosen) = out.residual_to_noise;
    assert!(chosen > pbm_lab::audit::NOISE_FLOOR_RATIO && chosen < 0.2 * base, "{base} → {chosen}");
    assert_eq!(out.cause, "heat_transfer+transport_delay+wall_heat");
    let text = out.verdict_text();
    assert!(text.contains("explains part") && text.contains("what is missing"), "{text}");
    // With the switches estimated, the loaded phase's error is well under what the switch
    // timing alone leaves at the midpoints.
    let loaded_rms = out.chosen_phase_rms[0].1;
    assert!(loaded_rms <= 0.5 * out.switch_timing_floor_bar, "{loaded_rms} vs {}", out.switch_timing_floor_bar);
    // The decay after the first two minutes is within 5× the transducer noise (it was 11×).
    assert!(out.chosen_phase_rms[2].1 < 5.0 * out.sigma, "{:?}", out.chosen_phase_rms);
    let floor = out.cycle_floor.expect("the extract holds four complete cycles");
    assert_eq!(floor.cycles, 4);
    assert!(floor.spread_bar > 3.0 * out.sigma && !floor.systematic(), "{floor:?}");
    assert!(text.contains("within that variation"), "{text}");
    // The record's floor, and the held-out NMSE against it.
    let record = out.record_floor.expect("floor");
    assert!(record.loaded_jitter_bar > 10.0 * out.sigma, "{record:?}");
    let held = out.chosen.held_out.expect("held out");
    assert!(held.nmse_pct < 1.5 * record.nmse_pct, "{held:?} vs {record:?}");
    assert!(
        held.nmse_pct
            < 0.8
                * out
                    .ranking
                    .iter()
                    .find(|f| f.name == "heat_transfer+transport_delay")
                    .and_then(|f| f.held_out)
                    .expect("one node")
                    .nmse_pct
    );
    let json = out.to_json();
    assert_eq!(json["explains_all"], false);
    assert!(json["unmodelled_rate"].as_array().is_some_and(|a| !a.is_empty()));
    assert_eq!(json["cycle_floor"]["systematic"], false);
    assert!(json["record_floor"]["nmse_pct"].as_f64().is_some_and(|v| v > 0.05));
    assert!(json["held_out"].as_array().is_some_and(|a| a.len() == out.ranking.len() + 1));
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
    // The wall node (`wall_heat`), a fast small one and a slow large one, each with the spin-up
    // that puts it at its cycling temperature.
    let walls = [
        pbm::reservoir::WallNode { capacity_ratio: 0.1, cooling_s: 300.0 },
        pbm::reservoir::WallNode { capacity_ratio: 1.5, cooling_s: 15_000.0 },
    ];
    let cases = cases
        .into_iter()
        .map(|e| (e, pbm::reservoir::WallNode::OFF))
        .chain(walls.map(|w| (vec![(Mechanism::HeatTransfer, 40.0), (Mechanism::TransportDelay, 9.3)], w)));
    for (effects, wall) in cases {
        let mut params = metro_params(&u, &effects);
        params.wall = wall;
        let fixed = simulate(&rows, &params).expect("parameters in range");
        let reference = simulate_reference(&rows, &params);
        let nmse = pbm::metrics::nmse_pct(&reference, &fixed).expect("nmse");
        let worst = fixed.iter().zip(&reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        eprintln!("{effects:?} {wall:?}: NMSE fixed vs f64 {nmse:.5} %, worst {worst:.5} bar");
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

/// Issue 17: the record holds a one-off consumption event in the middle of a decay (cycle 3,
/// ≈ 1330 s after unloading: the pressure falls 0.05 bar faster than in the other cycles for two
/// minutes, then comes back over the next four). The audit reports it as an event (when, how
/// much air), leaves it out of the fits instead of bending a mechanism to it, and finds no other.
#[test]
fn metro_audit_reports_the_one_off_event_instead_of_fitting_it() {
    let (rows, out) = audit_metro_file(Path::new(METRO)).expect("audit runs");
    assert_eq!(out.events.len(), 1, "{:?}", out.events);
    let e = out.events[0];
    assert_eq!(e.cycle, 3);
    assert!((1250.0..1400.0).contains(&e.since_unload_s), "{e:?}");
    assert!((0.04..0.065).contains(&e.dip_bar) && e.recovered && e.net_bar.abs() < 0.02, "{e:?}");
    assert!(rows[e.rows.0].t_s < 6900.0 && rows[e.rows.1].t_s > 7000.0, "{e:?}");
    let text = out.verdict_text();
    assert!(text.contains("one-off event in cycle 3") && text.contains("g of air"), "{text}");
    // The event is the largest part of what looked like consumption varying from cycle to
    // cycle: without it the cycles agree to ≈ 5× the transducer noise (it was ≈ 8×).
    let floor = out.cycle_floor.expect("four cycles");
    assert!(floor.spread_bar < 6.0 * out.sigma, "{floor:?}");
    // Every fitted model is validated on cycles it was not fitted to: the chosen one predicts
    // them about as well as it fits them (no overfit), and far better than the base.
    let (b, c) = (out.base.held_out.expect("held out"), out.chosen.held_out.expect("held out"));
    assert_eq!((b.cycles, c.cycles), (4, 4));
    assert!(c.nmse_pct < 1.1 * c.in_sample_nmse_pct && c.nmse_pct < 0.3 * b.nmse_pct, "{b:?} {c:?}");
    assert!(out.ranking.iter().all(|f| f.held_out.is_some()));
}

/// The event finder on effects planted in the real record by this test (not by the audit's
/// generator): a lasting extra outflow in one cycle is an event that did not come back; the same
/// dip in every cycle is systematic (a mechanism's business), never an event; and the named cause
/// does not bend to a planted event.
#[test]
fn one_off_events_are_told_from_what_every_cycle_does() {
    use pbm_lab::metro::one_off_events;
    let rows = read_metro(Path::new(METRO)).expect("reads");
    let loads: Vec<usize> = (1..rows.len()).filter(|&i| rows[i].loaded && !rows[i - 1].loaded).collect();
    let unloads: Vec<usize> = (1..rows.len()).filter(|&i| !rows[i].loaded && rows[i - 1].loaded).collect();
    // A smooth extra outflow of `bar` from `at_s` after the unloading over 90 s, kept (`lasting`)
    // or given back over the following 4 min, in the decays `which` (0-based complete cycles).
    let plant = |which: &[usize], at_s: f64, bar: f64, lasting: bool| {
        let mut r = rows.clone();
        for &c in which {
            let (u, next) = (unloads[c], loads[c + 1]);
            for row in r.iter_mut().take(next).skip(u) {
                let s = row.t_s - rows[u].t_s - at_s;
                let down = (s / 90.0).clamp(0.0, 1.0);
                let back = if lasting { 0.0 } else { ((s - 90.0) / 240.0).clamp(0.0, 1.0) };
                row.tp3_bar -= bar * (down - back);
            }
        }
        r
    };
    // A lasting 0.04 bar loss in cycle 1, 700 s after unloading (the record's own event stays).
    let lasting = one_off_events(&plant(&[0], 700.0, 0.04, true));
    let e = lasting.iter().find(|e| e.cycle == 1).expect("the planted loss is found");
    assert!(!e.recovered && (0.03..0.05).contains(&e.net_bar) && (600.0..800.0).contains(&e.since_unload_s), "{e:?}");
    assert!(lasting.iter().any(|e| e.cycle == 3), "{lasting:?}");
    // A dip that comes back, in cycle 2 at 400 s.
    let transient = one_off_events(&plant(&[1], 400.0, 0.03, false));
    let e = transient.iter().find(|e| e.cycle == 2).expect("the planted dip is found");
    assert!(e.recovered && (0.02..0.04).contains(&e.dip_bar), "{e:?}");
    // The same dip in every cycle is no one-off event.
    let everywhere = one_off_events(&plant(&[0, 1, 2, 3], 700.0, 0.04, true));
    assert!(everywhere.iter().all(|e| e.cycle == 3 && e.since_unload_s > 1000.0), "{everywhere:?}");
    // The audit of the record with the lasting loss names the same cause, and the model it
    // fits there predicts the clean record about as well as the clean model predicts cycles it
    // was not fitted to (within 20 % of that held-out NMSE; measured 0.120 % against 0.107 %):
    // the event is not bent into a mechanism. (The wall node's τ, ε and τ_w trade off along a
    // valley, so the magnitudes themselves are compared through what they predict.)
    let (_, clean) = audit_metro_file(Path::new(METRO)).expect("audit runs");
    let planted = pbm_lab::metro::audit_metro(&plant(&[0], 700.0, 0.04, true)).expect("audit runs");
    assert_eq!(planted.cause, clean.cause);
    let curve = pbm_lab::metro::simulate_around(&rows, &planted.chosen.params, &clean.chosen.switches, &clean.events)
        .expect("runs");
    let lead = pbm_lab::metro::model_start(&rows);
    let judged = |i: &usize| *i >= lead && !clean.events.iter().any(|e| (e.rows.0..=e.rows.1).contains(i));
    let (m, c): (Vec<f64>, Vec<f64>) = (0..rows.len()).filter(judged).map(|i| (rows[i].tp3_bar, curve[i])).unzip();
    let nmse = pbm::metrics::nmse_pct(&m, &c).expect("rows");
    let held = clean.chosen.held_out.expect("held out").nmse_pct;
    assert!(nmse < 1.2 * held, "{nmse} vs {held}");
}

/// Records from the `f64` reference with noise and no event, on seeds nobody looked at: no event.
#[test]
fn clean_synthetic_records_hold_no_one_off_event() {
    for seed in 4100..4106 {
        let rows = synthetic_rows(&metro_params(&SYNTHETIC_BASE_U, &[]), SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR, seed);
        let events = pbm_lab::metro::one_off_events(&rows);
        assert!(events.is_empty(), "seed {seed}: {events:?}");
    }
}

/// Records of an independent plant (tests/data/metro_independent, written from physics by a
/// tester who did not read the audit): without a wall the audit had named `wall_heat` (7 of 37
/// records, four times as "explains the discrepancy") with its cooling time at an edge of the
/// search range or its magnitudes undetermined; a wall must now be determined, inside its
/// ranges and better on held-out cycles. With a wall it is named, within 2 σ of the truth.
#[test]
fn the_wall_node_is_named_only_where_an_independent_plant_has_one() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/metro_independent");
    for name in ["nowall_nw1.csv", "nowall_nw3.csv", "nowall_nw8.csv"] {
        let (_, out) = audit_metro_file(&dir.join(name)).expect("audit runs");
        assert!(!out.cause.contains("wall_heat"), "{name}: {}", out.cause);
        assert!(out.cause.contains("heat_transfer"), "{name}: {}", out.cause);
        assert!(
            out.verdict_text().contains("wall_heat fits better but is not named"),
            "{name}: {}",
            out.verdict_text()
        );
    }
    let (_, out) = audit_metro_file(&dir.join("wall_w1_s26.csv")).expect("audit runs");
    let (w, [ue, ut]) = out.chosen.wall.expect("the wall is named");
    assert!((w.capacity_ratio - 0.3).abs() < 2.0 * ue, "{w:?} ± {ue}");
    assert!((w.cooling_s - 1000.0).abs() < 2.0 * ut, "{w:?} ± {ut}");
}

/// Issue 17: a leak of 0.5 g/s (at 10 bar g) that opens halfway through a record of the
/// independent plant (at 5000 s) was only `unexplained`, without saying when. The audit reports
/// a lasting change of consumption, from which cycle, and an interval holding the true instant;
/// the records of that plant without one get none.
#[test]
fn a_lasting_change_of_consumption_is_reported_with_when_it_began() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/metro_independent");
    let (_, out) = audit_metro_file(&dir.join("step_leak_s33.csv")).expect("audit runs");
    let change = out.consumption_change.as_ref().unwrap_or_else(|| panic!("{}", out.summary()));
    assert_eq!(change.shape, pbm_lab::metro::ChangeShape::Step);
    assert_eq!(change.first_cycle_after, 4, "{change:?}");
    assert!(change.between_s.0 <= 5000.0 && 5000.0 <= change.between_s.1, "{change:?}");
    assert!(change.rate_bar_per_min.1 < change.rate_bar_per_min.0 - 0.02, "{change:?}");
    assert!(out.verdict_text().contains("a lasting change of the air consumption"), "{}", out.verdict_text());
    assert_eq!(out.to_json()["consumption_change"]["first_cycle_after"], 4);
    for name in ["nowall_nw1.csv", "nowall_nw3.csv", "nowall_nw8.csv", "wall_w1_s26.csv"] {
        let (_, out) = audit_metro_file(&dir.join(name)).expect("audit runs");
        assert_eq!(out.consumption_change, None, "{name}");
    }
    let (_, real) = audit_metro_file(Path::new(METRO)).expect("audit runs");
    assert_eq!(real.consumption_change, None);
}

/// Issue 17: 40 g of air drawn for 60 s at 600 s after every unloading (the independent plant)
/// acts in every cycle, so it is no one-off event; after 600 s the bins of "what is missing" are
/// 300 s wide and it was averaged away. The late part is scanned in 60 s windows as well.
#[test]
fn a_short_recurring_outflow_late_in_the_decay_is_said() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/metro_independent");
    let (_, out) = audit_metro_file(&dir.join("recurring_event_600s.csv")).expect("audit runs");
    assert!(out.events.is_empty(), "{:?}", out.events);
    let window = out
        .missing
        .iter()
        .find(|a| a.scan && a.significant() && a.mean_bar_per_min < 0.0)
        .unwrap_or_else(|| panic!("{}", out.summary()));
    assert!((540.0..=660.0).contains(&window.from_s), "{window:?}");
    assert!(
        out.verdict_text().contains("an extra outflow from 600 to 660 s after the compressor unloads"),
        "{}",
        out.verdict_text()
    );
}

/// What the audit cannot judge is refused with the reason (an independent tester's garbage,
/// planted here in the real record): no compressor switching, fewer than three complete cycles,
/// a frozen channel, a pressure in the wrong unit or sign.
#[test]
fn records_the_audit_cannot_judge_are_refused() {
    let rows = read_metro(Path::new(METRO)).expect("reads");
    let refused = |rows: Vec<pbm_lab::metro::MetroRow>, why: &str| {
        let err = pbm_lab::metro::audit_metro(&rows).expect_err("refused").to_string();
        assert!(err.contains(why), "{err}");
    };
    refused(rows.iter().map(|r| pbm_lab::metro::MetroRow { loaded: false, ..*r }).collect(), "holds 0 complete");
    refused(rows[..560].to_vec(), "holds 2 complete");
    refused(rows.iter().map(|r| pbm_lab::metro::MetroRow { tp3_bar: 9.0, ..*r }).collect(), "does not rise");
    refused(rows.iter().map(|r| pbm_lab::metro::MetroRow { tp3_bar: r.tp3_bar * 1000.0, ..*r }).collect(), "outside");
    refused(rows.iter().map(|r| pbm_lab::metro::MetroRow { tp3_bar: -r.tp3_bar, ..*r }).collect(), "outside");
}
