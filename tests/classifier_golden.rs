//! The int8 classifier compiled into the core reproduces the shared golden vectors exactly
//! (`tests/golden/classifier_golden.txt`, written by `host-sim train --golden`). The firmware
//! checks the same file on thumbv7em in QEMU (`classifier-check`, run by `cargo xtask fw-qemu`):
//! identical integers on both targets.
//!
//! The file is read and checked with the firmware's own code (one implementation, included by
//! path).

#[path = "../firmware/src/classifier_golden.rs"]
#[allow(dead_code)]
mod classifier_golden;

use classifier_golden::{check, vectors, Expected, Mismatch};
use pbm::classifier::model_weights::MODEL;

const GOLDEN: &str = include_str!("golden/classifier_golden.txt");

#[test]
fn compiled_model_matches_golden_vectors() {
    MODEL.validate().expect("compiled model is consistent");
    let summary = classifier_golden::check_all(&MODEL, GOLDEN, |_| {});
    match summary.first_failure {
        Some((line, Some(why))) => panic!("line {line}: {why} ({} failures)", summary.failures),
        Some((line, None)) => panic!("line {line}: not a golden vector"),
        None => {}
    }
    assert!(summary.matched >= 100, "only {} golden vectors", summary.matched);
    assert!(summary.implausible >= 1, "the golden file must exercise the implausible path");
}

/// The shared check sees every kind of difference (it is what the firmware runs in QEMU).
#[test]
fn golden_check_detects_each_mismatch() {
    let first = |f: fn(&Expected<'_>) -> bool| vectors(GOLDEN).flatten().find(|v| f(&v.expected)).unwrap();
    let output = first(|e| matches!(e, Expected::Output { .. }));
    let implausible = first(|e| matches!(e, Expected::Implausible));
    assert_eq!(check(&MODEL, &output), Ok(()));
    assert_eq!(check(&MODEL, &implausible), Ok(()));
    let perturbed = |change: fn(&mut Expected<'_>)| {
        let mut v = output;
        change(&mut v.expected);
        check(&MODEL, &v)
    };
    assert_eq!(
        perturbed(|e| if let Expected::Output { q, .. } = e {
            q.as_mut_slice().iter_mut().for_each(|x| *x = x.wrapping_add(1))
        }),
        Err(Mismatch::Inputs)
    );
    assert_eq!(
        perturbed(|e| if let Expected::Output { logits, .. } = e {
            logits.as_mut_slice()[0] += 1
        }),
        Err(Mismatch::Logits)
    );
    assert_eq!(
        perturbed(|e| if let Expected::Output { class, .. } = e {
            *class = "no_such_class"
        }),
        Err(Mismatch::Class)
    );
    assert_eq!(
        perturbed(|e| if let Expected::Output { confidence_pct, .. } = e {
            *confidence_pct ^= 1
        }),
        Err(Mismatch::Confidence)
    );
    assert_eq!(perturbed(|e| *e = Expected::Implausible), Err(Mismatch::NotImplausible(None)));
    let mut plausible = implausible;
    plausible.expected = output.expected;
    assert!(matches!(check(&MODEL, &plausible), Err(Mismatch::Quantize(_))));
    // Lines that are not vectors are failures, never panics.
    let s = classifier_golden::check_all(&MODEL, "# comment\n\nx 12 | q 1\nnonsense\n", |_| {});
    assert_eq!((s.failures, s.first_failure), (2, Some((3, None))));
    assert!(!s.passed(0));
}

/// The pipeline carries the classifier: a simulated healthy release is diagnosed `normal`, a
/// blocked orifice `orifice_block`, a leak `air_leak`, a low supply `low_supply`, through
/// `Pipeline::step` alone (the diagnosis the 60 s window closes, and `Pipeline::diagnosis` after
/// the valve closed).
#[test]
fn pipeline_diagnoses_simulated_releases() {
    use pbm::pipeline::Pipeline;
    use pbm::report::Verdict;
    use pbm::sensor::adc_from_bar;
    use pbm::{FaultClass, Twin, TwinParams};
    for (plant, want) in [
        (TwinParams::nominal(), FaultClass::Normal),
        (TwinParams::nominal().with_orifice_mm(0.6), FaultClass::OrificeBlock),
        (TwinParams::nominal().with_leak_mm(0.9), FaultClass::AirLeak),
        (TwinParams::nominal().with_supply_bar_g(5.0), FaultClass::LowSupply),
    ] {
        let mut twin = Twin::new(&plant).unwrap();
        let mut pipeline = Pipeline::new(&TwinParams::nominal()).unwrap();
        // Transducer noise (SPEC §5: σ = 0.01 bar; a sum of four uniforms from a fixed LCG):
        // a noise-free reading is a frozen sensor to the monitor's plausibility checks.
        let mut lcg = 7u32;
        let mut noise = move || {
            (0..4).fold(0.0, |acc, _| {
                lcg = lcg.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                acc + f64::from(lcg >> 8) / f64::from(1u32 << 24) - 0.5
            }) * 0.01
                * 3f64.sqrt()
        };
        let mut closed = None;
        for _ in 0..6000 {
            let p = twin.state().p.to_bar_g();
            closed = pipeline.step(adc_from_bar(pbm::BarG(p.0 + noise())), true).closed.or(closed);
            twin.update(true);
        }
        assert_eq!(pipeline.report(), closed.as_ref(), "{want}: closed by the 60 s window");
        pipeline.step(adc_from_bar(pbm::BarG(0.0)), false); // valve closed: verdict kept
        let report = pipeline.diagnosis();
        assert_eq!(Some(report.verdict), closed.map(|r| r.verdict), "{want}");
        match report.verdict {
            Verdict::Class { class, confidence_pct } => {
                assert_eq!(class, want, "{plant:?}");
                assert!(confidence_pct > 50, "{want}: confidence {confidence_pct} %");
            }
            v => panic!("{want}: {v:?}"),
        }
    }
}
