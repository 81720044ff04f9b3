//! The recorded sensor-fault traces of `tests/data/sensor_fault` (valid releases with a broken
//! transducer or ADC, see its README) through the pipeline the firmware runs: every one must end
//! in *cannot diagnose: sensor fault* of the expected kind, and none may put a brake class on
//! the bus.

use pbm::can::{Binding, FrameError, Report};

/// Decodes a frame of the pipeline (locomotive 0) in whichever release it belongs to.
fn decode_frame(f: &pbm::can::CanFrame) -> Result<(Report, u16), FrameError> {
    let any = |release: u32| pbm::can::decode_frame(f, Binding { fleet: 0, release_count: release });
    (1..64).map(any).find(Result::is_ok).unwrap_or_else(|| any(0))
}
use pbm::pipeline::Pipeline;
use pbm::report::{NoDiagnosis, Verdict};
use pbm::sensor::SensorFault;
use pbm::AdcCounts;

mod common;

fn codes(name: &str) -> Vec<u16> {
    common::adc_codes(&format!("sensor_fault/{name}"))
}

#[test]
fn every_recorded_sensor_fault_is_refused_with_its_kind() {
    for (name, want) in [
        ("normal_open_circuit.csv", SensorFault::Dropouts),
        ("normal_frozen.csv", SensorFault::Frozen),
        ("air_leak_spikes.csv", SensorFault::Spikes),
        ("orifice_block_lost_bits.csv", SensorFault::LostResolution),
        ("low_supply_noisy.csv", SensorFault::Noisy),
        ("normal_clipped.csv", SensorFault::Frozen),
    ] {
        let mut pipe = Pipeline::nominal().expect("nominal");
        let mut closed = None;
        for c in codes(name) {
            let s = pipe.step(AdcCounts(c), true);
            for f in s.frames.as_slice() {
                if let Ok((Report::Fault(r), _)) = decode_frame(f) {
                    assert!(!matches!(r.verdict, Verdict::Class { .. }), "{name}: sent {:?}", r.verdict);
                }
            }
            closed = closed.or(s.closed);
        }
        let report = closed.or_else(|| pipe.close().map(|(r, _)| r)).expect("a diagnosis closes");
        assert_eq!(report.verdict, Verdict::CannotDiagnose(NoDiagnosis::SensorFault(want)), "{name}");
    }
}
