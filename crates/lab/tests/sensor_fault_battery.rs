//! Issue 15: a generated battery of every sensor-fault kind of `host-sim generate
//! --sensor-fault` on valid releases of every class, at several onsets, through the core's
//! pipeline (`replay`). No release may be reported as a wrong brake class; the faults the
//! plausibility checks are built for must be refused as sensor faults. A clean run of the same
//! releases must not raise a single sensor fault. (The larger battery of the README is
//! `cargo xtask sensor-fault-battery`.)

use pbm::report::{NoDiagnosis, Verdict};
use pbm::FaultClass;
use pbm_io::dataset::Dataset;
use pbm_lab::generate::{generate, GenerateOptions};
use pbm_lab::replay::replay_trace_with_diagnosis;
use pbm_lab::sensor_faults::parse_spec;
use std::path::Path;

/// Verdicts of every trace of a data set: (true class, verdict at the close).
fn verdicts(dir: &Path) -> Vec<(FaultClass, Verdict)> {
    let data = Dataset::open(dir).unwrap();
    data.rows()
        .iter()
        .map(|row| {
            let trace = data.read_trace(row).unwrap();
            let (_, report) = replay_trace_with_diagnosis(&trace).unwrap();
            (FaultClass::from_label(&row.label).unwrap(), report.expect("a diagnosis closes").verdict)
        })
        .collect()
}

fn battery(spec: Option<&str>, seed: u64) -> Vec<(FaultClass, Verdict)> {
    let tmp = tempfile::tempdir().unwrap();
    let mut a = GenerateOptions::new(tmp.path().join("d"));
    a.locomotives = 3;
    a.test_locomotives = 1;
    a.per_class = 0;
    a.test_per_class = 1;
    a.seed = seed;
    a.threads = 2;
    a.sensor_faults = spec.map(|s| vec![parse_spec(s).unwrap()]).unwrap_or_default();
    generate(&a, false).unwrap();
    verdicts(&a.out)
}

#[test]
fn no_sensor_fault_gives_a_wrong_brake_class() {
    let mut seed = 900;
    let (mut total, mut refused) = (0, 0);
    for kind in [
        "frozen",
        "dead",
        "noisy",
        "spikes",
        "dropouts",
        "lost_resolution",
        "clipped",
        "impossible_rate",
        "implausible_level",
        "offset",
        "open_circuit",
        "short_circuit",
    ] {
        for onset in ["0", "4", "30"] {
            seed += 1;
            for (truth, verdict) in battery(Some(&format!("{kind}@{onset}")), seed) {
                total += 1;
                match verdict {
                    Verdict::Class { class, confidence_pct } => assert_eq!(
                        class, truth,
                        "{kind}@{onset}: a {truth} release with a broken sensor read as {class} ({confidence_pct} %)"
                    ),
                    Verdict::CannotDiagnose(_) => refused += 1,
                }
            }
        }
    }
    eprintln!("sensor-fault battery: {total} releases, {refused} refused, none a wrong class");
    assert_eq!(total, 12 * 3 * 5);
    // Every kind the checks target is refused; only the level faults (gain, offset) that the
    // signal alone cannot reveal may pass with the right class.
    assert!(refused >= total - 2 * 3 * 5, "{refused} of {total} refused");
}

#[test]
fn clean_releases_raise_no_sensor_fault() {
    for (truth, verdict) in battery(None, 990) {
        assert!(
            !matches!(verdict, Verdict::CannotDiagnose(NoDiagnosis::SensorFault(_))),
            "a clean {truth} release: {verdict}"
        );
    }
}
