//! Golden checkpoints of the nominal release, shared with the firmware.
//!
//! The fixed-point twin must produce the same bits on the host and on the Cortex-M4F. This test
//! computes the twin's state at the checkpoints on the host and holds it to
//! `tests/golden/nominal_checkpoints.csv`; the firmware (`firmware/src/bin/twin_check.rs`)
//! embeds the same file and compares its own run in QEMU against it
//! (`cargo xtask fw-qemu`). After an intended change of the twin, regenerate the file with
//! `UPDATE_GOLDEN=1 cargo test --test golden_twin` and review the diff.
//!
//! The file is read with the firmware's own parser (one implementation, included by path).

#[path = "../firmware/src/golden.rs"]
#[allow(dead_code)]
mod golden;

use golden::{Checkpoint, GoldenError, CHECKPOINT_UPDATES};
use pbm::fixed::Q;
use pbm::{MetersQ32, PressureQ24, Twin, TwinParams};
use proptest::prelude::*;

const GOLDEN_PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/nominal_checkpoints.csv");

/// The twin's state at [`CHECKPOINT_UPDATES`], valve open from the release command.
fn host_checkpoints() -> Vec<Checkpoint> {
    let mut twin = Twin::new(&TwinParams::nominal()).expect("nominal parameters are valid");
    let mut out = Vec::new();
    let mut updates = 0;
    for &target in &CHECKPOINT_UPDATES {
        let mut sample = None;
        while updates < target {
            sample = Some(twin.update(true));
            updates += 1;
        }
        let s = sample.expect("checkpoints are increasing and > 0");
        out.push(Checkpoint { updates: target, p_q24: s.pressure.0, x_q32: s.travel.0 });
    }
    out
}

fn render(rows: &[Checkpoint]) -> String {
    let mut text = String::new();
    golden::write_csv(
        &mut text,
        &[
            "Fixed-point twin (pbm::Twin), nominal parameters (SPEC §3), valve open from the release command.",
            "updates = 10 ms samples since the command; p_q24 = Q7.24 bar abs; x_q32 = Q32 m.",
            "Written by tests/golden_twin.rs (UPDATE_GOLDEN=1); checked bit for bit in QEMU by the firmware.",
        ],
        rows,
    )
    .expect("writing to a String cannot fail");
    text
}

#[test]
fn golden_file_matches_host_twin() {
    let rows = host_checkpoints();
    let text = render(&rows);
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::write(GOLDEN_PATH, &text).expect("write golden file");
        eprintln!("golden_twin: rewrote {GOLDEN_PATH}");
    }
    let on_disk = std::fs::read_to_string(GOLDEN_PATH).expect("read golden file");
    let parsed = golden::parse(&on_disk).expect("golden file parses");
    assert_eq!(
        parsed.as_slice(),
        rows.as_slice(),
        "the twin changed: review, then regenerate with UPDATE_GOLDEN=1 cargo test --test golden_twin"
    );
    assert_eq!(on_disk, text, "golden file is not in canonical form");
}

#[test]
fn golden_checkpoints_are_plausible() {
    // Guards against regenerating the file from a broken twin: SPEC §3 landmarks.
    let rows = host_checkpoints();
    let at = |updates: u32| rows.iter().find(|c| c.updates == updates).expect("checkpoint exists");
    let bar_g = |c: &Checkpoint| PressureQ24(c.p_q24).to_bar_g().0;
    assert!(at(100).x_q32 == 0, "piston still applied at 1 s");
    let end = at(6000);
    assert!((bar_g(end) - 7.7).abs() < 0.01, "plateau at supply, got {}", bar_g(end));
    let stroke: MetersQ32 = Q(end.x_q32);
    let stroke_m = stroke.to_m().0;
    assert!((stroke_m - 0.060).abs() < 1e-6, "piston at its 60 mm end stop, got {stroke_m}");
}

#[test]
fn parser_rejects_malformed_files() {
    use GoldenError::*;
    let h = golden::HEADER;
    assert_eq!(golden::parse("").unwrap_err(), MissingHeader);
    assert_eq!(golden::parse("1,2,3\n").unwrap_err(), MissingHeader);
    assert_eq!(golden::parse(&format!("{h}\n")).unwrap_err(), Empty);
    assert_eq!(golden::parse(&format!("{h}\n1,2\n")).unwrap_err(), FieldCount { line: 2 });
    assert_eq!(golden::parse(&format!("{h}\n1,2,3,4\n")).unwrap_err(), FieldCount { line: 2 });
    assert_eq!(golden::parse(&format!("# c\n{h}\n1,x,3\n")).unwrap_err(), BadNumber { line: 3 });
    assert_eq!(golden::parse(&format!("{h}\n1,2,99999999999\n")).unwrap_err(), BadNumber { line: 2 });
    assert_eq!(golden::parse(&format!("{h}\n5,2,3\n5,2,3\n")).unwrap_err(), NotIncreasing { line: 3 });
    assert_eq!(golden::parse(&format!("{h}\n0,2,3\n")).unwrap_err(), NotIncreasing { line: 2 });
    let many: String = (1..=17).map(|i| format!("{i},0,0\n")).collect();
    assert_eq!(golden::parse(&format!("{h}\n{many}")).unwrap_err(), TooMany { line: 18 });
    let ok = golden::parse(&format!("# c\n\n{h}\n 7, -1 ,2\n")).expect("valid");
    assert_eq!(ok.as_slice(), &[Checkpoint { updates: 7, p_q24: -1, x_q32: 2 }]);
}

proptest! {
    #[test]
    fn parser_never_panics(text in ".{0,200}", rows in proptest::collection::vec((any::<u32>(), any::<i64>(), ".{0,6}"), 0..20)) {
        let _ = golden::parse(&text);
        let mut file = format!("{}\n", golden::HEADER);
        for (a, b, c) in rows {
            file.push_str(&format!("{a},{b},{c}\n"));
        }
        let _ = golden::parse(&file);
    }
}
