//! Releases from a plant this project did not write (`tests/data/independent`, see its README)
//! through the pipeline the firmware runs: valid releases get their class, releases outside the
//! five classes and broken sensors never get a brake class, neither at the close nor in any
//! report on the bus.

use pbm::can::{Binding, FrameError, Report};

/// Decodes a frame of the pipeline (locomotive 0) in whichever release it belongs to.
fn decode_frame(f: &pbm::can::CanFrame) -> Result<(Report, u16), FrameError> {
    let any = |release: u32| pbm::can::decode_frame(f, Binding { fleet: 0, release_count: release });
    (1..64).map(any).find(Result::is_ok).unwrap_or_else(|| any(0))
}
use pbm::pipeline::Pipeline;
use pbm::report::Verdict;
use pbm::{AdcCounts, FaultClass};

mod common;

fn codes(name: &str) -> Vec<u16> {
    common::adc_codes(&format!("independent/{name}"))
}

/// The closing verdict and every verdict sent on the bus.
fn replay(name: &str) -> (Verdict, Vec<Verdict>) {
    let mut pipe = Pipeline::nominal().expect("nominal");
    let (mut closed, mut sent) = (None, Vec::new());
    for c in codes(name) {
        let s = pipe.step(AdcCounts(c), true);
        for f in s.frames.as_slice() {
            if let Ok((Report::Fault(r), _)) = decode_frame(f) {
                sent.push(r.verdict);
            }
        }
        closed = closed.or(s.closed);
    }
    let report = closed.or_else(|| pipe.close().map(|(r, _)| r)).expect("a diagnosis closes");
    (report.verdict, sent)
}

#[test]
fn valid_releases_of_an_independent_plant_get_their_class() {
    for class in FaultClass::ALL.iter().filter(|c| **c != FaultClass::OrificeMissing) {
        let name = format!("clean_{}_0000.csv", class.label());
        let (verdict, _) = replay(&name);
        assert!(matches!(verdict, Verdict::Class { class: c, .. } if c == *class), "{name}: {verdict:?}");
    }
}

#[test]
fn releases_outside_the_classes_and_broken_sensors_get_no_brake_class() {
    for name in [
        "unfamiliar_valve_delay_00.csv",
        "unfamiliar_two_stage_regulator_00.csv",
        "unfamiliar_big_volume_01.csv",
        "unfamiliar_short_stroke_00.csv",
        "unfamiliar_regulator_hunting_00.csv",
        "unfamiliar_supply_dropout_vent_00.csv",
        "unfamiliar_supply_ramp_00.csv",
        "sensor_adc_10bit_start_normal_0.csv",
        "sensor_stuck_last_good_mid_air_leak_0.csv",
        "sensor_bit_flip_mid_low_supply_0.csv",
        "sensor_gain_step_mid_orifice_block_0.csv",
    ] {
        let (verdict, sent) = replay(name);
        assert!(matches!(verdict, Verdict::CannotDiagnose(_)), "{name}: closed with {verdict:?}");
        // A class sent before the close must have been withdrawn by a later report.
        assert!(
            !matches!(sent.last(), Some(Verdict::Class { .. })),
            "{name}: the last report on the bus names a class: {sent:?}"
        );
    }
}
