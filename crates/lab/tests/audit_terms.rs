//! Each extension term of the fixed-point core twin against the same mechanism in the f64 plant
//! (NMSE < 0.1 %, like the base model), and the base model's bits unchanged when all are off.

use pbm::mechanism::Extensions;
use pbm::mechanism::Mechanism;
use pbm::metrics::nmse_pct;
use pbm::{Twin, TwinParams};
use pbm_lab::generate::simulate_plant;
use pbm_lab::simulate::{simulate, Engine};

/// Step of the f64 plant here: 0.1 ms, 10× finer than `host-sim generate` uses (whose error at
/// 1 ms is < 0.003 % NMSE) and 5× coarser than the 20 µs reference, to keep the test fast.
const PLANT_STEP_S: f64 = 1e-4;

fn pressures(engine: Engine, params: &TwinParams) -> Vec<f64> {
    match engine {
        Engine::Fixed => simulate(engine, params, 60.0).expect("valid parameters").iter().map(|s| s.p_bar).collect(),
        Engine::F64 => simulate_plant(params, PLANT_STEP_S, 6000).expect("valid parameters").0,
    }
}

/// Representative magnitudes: the top of each plausible range (largest deviation from base).
fn magnitudes(e: Mechanism) -> Vec<f64> {
    e.descriptor().brake.plausible.iter().flat_map(|&(lo, hi)| [lo, hi]).collect()
}

#[test]
fn every_core_term_matches_the_f64_plant() {
    let cases: Vec<(Mechanism, f64)> =
        Mechanism::ALL.iter().flat_map(|&e| magnitudes(e).into_iter().map(move |m| (e, m))).collect();
    let results: Vec<(Mechanism, f64, f64, f64)> = std::thread::scope(|s| {
        let handles: Vec<_> = cases
            .chunks(cases.len().div_ceil(2))
            .map(|chunk| {
                s.spawn(move || {
                    chunk
                        .iter()
                        .map(|&(e, m)| {
                            let mut p = TwinParams::nominal();
                            p.ext[e] = m;
                            let fixed = pressures(Engine::Fixed, &p);
                            let plant = pressures(Engine::F64, &p);
                            let base = pressures(Engine::Fixed, &TwinParams::nominal());
                            let nmse = nmse_pct(&plant, &fixed).expect("pressure rises");
                            let effect = nmse_pct(&plant, &base).expect("pressure rises");
                            (e, m, nmse, effect)
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().expect("thread")).collect()
    });
    for (e, m, nmse, effect) in &results {
        eprintln!("{e}={m}: fixed vs f64 NMSE {nmse:.4} %, effect vs base {effect:.3} %");
    }
    for (e, m, nmse, effect) in results {
        assert!(nmse < 0.1, "{e}={m}: fixed-point term vs f64 plant NMSE {nmse} %");
        assert!(effect > 0.3, "{e}={m}: the mechanism must change the release ({effect} %)");
    }
}

/// With every mechanism off, also when set to its off value by name, the twin is the base twin
/// bit for bit: the golden checkpoints shared with the firmware still hold.
#[test]
fn base_bits_unchanged_with_extensions_off() {
    let golden = include_str!("../../../tests/golden/nominal_checkpoints.csv");
    let rows: Vec<(usize, i32, i32)> = golden
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].parse().expect("updates"), f[1].parse().expect("p_q24"), f[2].parse().expect("x_q32"))
        })
        .collect();
    assert!(rows.len() >= 5, "golden file has checkpoints");
    let mut variants = vec![TwinParams::nominal()];
    for e in Mechanism::ALL {
        let mut p = TwinParams::nominal();
        p.ext[e] = e.off();
        assert_eq!(p.ext, Extensions::NONE, "{e} off value");
        variants.push(p);
    }
    for p in variants {
        let mut twin = Twin::new(&p).expect("valid");
        assert!(!twin.coeffs().ext_active(), "no mechanism on");
        let mut done = 0;
        for &(updates, p_q24, x_q32) in &rows {
            let mut last = None;
            while done < updates {
                last = Some(twin.update(true));
                done += 1;
            }
            let s = last.expect("increasing checkpoints");
            assert_eq!((s.pressure.0, s.travel.0), (p_q24, x_q32), "checkpoint at {updates} updates");
        }
    }
}
