//! The int8 classifier compiled into the core reproduces the shared golden vectors exactly
//! (`tests/golden/classifier_golden.txt`, written by `host-sim train --golden`). The firmware
//! checks the same file on thumbv7em in QEMU: identical integers on both targets.

use pbm::classifier::model_weights::MODEL;
use pbm::classifier::ModelError;

const GOLDEN: &str = include_str!("golden/classifier_golden.txt");

fn ints<T: std::str::FromStr>(field: &str, key: &str) -> Vec<T> {
    let rest = field.trim().strip_prefix(key).unwrap_or_else(|| panic!("expected `{key}` in `{field}`"));
    rest.split_whitespace().map(|s| s.parse().ok().expect("integer")).collect()
}

#[test]
fn compiled_model_matches_golden_vectors() {
    MODEL.validate().expect("compiled model is consistent");
    let mut checked = 0;
    let mut implausible = 0;
    for (n, line) in GOLDEN.lines().enumerate().filter(|(_, l)| !l.starts_with('#') && !l.trim().is_empty()) {
        let fields: Vec<&str> = line.split('|').collect();
        let x: Vec<f64> = fields[0]
            .trim()
            .strip_prefix("x ")
            .expect("x field")
            .split_whitespace()
            .map(|h| f64::from_bits(u64::from_str_radix(h, 16).expect("hex bits")))
            .collect();
        let mut q = vec![0i8; x.len()];
        let quantized = MODEL.quantize_input(&x, &mut q);
        if fields[1].trim() == "implausible" {
            assert!(matches!(quantized, Err(ModelError::Implausible { .. })), "line {}", n + 1);
            implausible += 1;
            continue;
        }
        quantized.unwrap_or_else(|e| panic!("line {}: {e:?}", n + 1));
        assert_eq!(q, ints::<i8>(fields[1], "q"), "line {}: int8 inputs", n + 1);
        let inf = MODEL.infer(&q).expect("inference");
        assert_eq!(inf.logits[..inf.n_classes].to_vec(), ints::<i8>(fields[2], "logits"), "line {}: logits", n + 1);
        assert_eq!(inf.class.label(), fields[3].trim().strip_prefix("class ").expect("class"), "line {}", n + 1);
        assert_eq!(vec![inf.confidence_pct], ints::<u8>(fields[4], "conf"), "line {}: confidence", n + 1);
        checked += 1;
    }
    assert!(checked >= 100, "only {checked} golden vectors");
    assert!(implausible >= 1, "the golden file must exercise the implausible path");
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
            let p = pbm::PressureQ24(twin.state().p_q24).to_bar_g();
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
