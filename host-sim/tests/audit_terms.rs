//! Each extension term of the fixed-point core twin against the same mechanism in the f64 plant
//! (NMSE < 0.1 %, like the base model), and the base model's bits unchanged when all are off.

use host_sim::plant::Effect;
use host_sim::simulate::{simulate, Engine};
use pbm::metrics::nmse_pct;
use pbm::params::Extensions;
use pbm::{Twin, TwinParams};

fn pressures(engine: Engine, params: &TwinParams) -> Vec<f64> {
    simulate(engine, params, 60.0).expect("valid parameters").iter().map(|s| s.p_bar).collect()
}

/// Representative magnitudes: the top of each plausible range (largest deviation from base).
fn magnitudes(e: Effect) -> Vec<f64> {
    e.plausible().iter().flat_map(|&(lo, hi)| [lo, hi]).collect()
}

#[test]
fn every_core_term_matches_the_f64_plant() {
    let cases: Vec<(Effect, f64)> =
        Effect::ALL.iter().flat_map(|&e| magnitudes(e).into_iter().map(move |m| (e, m))).collect();
    let results: Vec<(Effect, f64, f64, f64)> = std::thread::scope(|s| {
        let handles: Vec<_> = cases
            .chunks(cases.len().div_ceil(2))
            .map(|chunk| {
                s.spawn(move || {
                    chunk
                        .iter()
                        .map(|&(e, m)| {
                            let mut p = TwinParams::nominal();
                            e.set(&mut p.ext, m);
                            let fixed = pressures(Engine::Fixed, &p);
                            let plant = pressures(Engine::F64, &p);
                            let base = pressures(Engine::F64, &TwinParams::nominal());
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

#[test]
fn base_bits_unchanged_with_extensions_off() {
    let mut a = Twin::new(&TwinParams::nominal()).expect("valid");
    let mut p = TwinParams::nominal();
    p.ext = Extensions::NONE;
    let mut b = Twin::new(&p).expect("valid");
    for _ in 0..6000 {
        assert_eq!(a.update(true), b.update(true));
    }
}
