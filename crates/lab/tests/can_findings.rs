//! The third black-box tester's reproducers (candump logs in `tests/data/can_findings/`, as
//! the tester left them; can/README.md lists the findings): each is decoded frame by frame and
//! only the lines the tester disturbed may be flagged, and no genuine report may be shown stale
//! or withdrawn.

use pbm::can::{Decoder, Report};
use pbm_io::can_log::read_log;

/// What became of each line (1-based line numbers).
#[derive(Debug, Default)]
struct Outcome {
    flagged: Vec<usize>,
    stale: Vec<usize>,
    withdrawn: Vec<usize>,
    corrupt_counts: usize,
}

fn decode(name: &str) -> Outcome {
    let path = format!("{}/tests/data/can_findings/{name}", env!("CARGO_MANIFEST_DIR"));
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut d = Decoder::new();
    let mut o = Outcome::default();
    let mut accepted = Vec::new();
    for (i, rec) in read_log(&bytes[..]).enumerate() {
        let rec = rec.unwrap_or_else(|e| panic!("{name}: {e:?}"));
        let line = i + 1;
        let r = d.receive(rec.time_us, &rec.frame);
        for _ in 0..r.withdrawn {
            if let Some(l) = accepted.pop() {
                o.withdrawn.push(l);
            }
        }
        o.corrupt_counts += usize::from(r.count_corrupt);
        match r.result {
            Err(_) => o.flagged.push(line),
            Ok(Report::Fault(_)) => {
                accepted.push(line);
                if r.stale {
                    o.stale.push(line);
                }
            }
            Ok(Report::Status(_)) => {}
        }
    }
    o
}

/// F7: a CRC-keeping corruption of one heartbeat's `FaultReportCount` (line 21, 14 → 6) made
/// the receiver claim 8 lost reports or withdraw the genuine report before it; now the reports
/// around it and the next heartbeat's count show the count corrupt, and nothing is flagged,
/// lost or withdrawn. The one report between the corrupt heartbeat and the next (line 22) is
/// shown stale until that heartbeat decides.
#[test]
fn f7_a_corrupted_fault_report_count_withdraws_nothing() {
    let o = decode("F7_crc_passing_corruption_of_FaultReportCount_withdraws_genuine_report.log");
    assert!(o.flagged.is_empty() && o.withdrawn.is_empty(), "{o:?}");
    assert_eq!(o.stale, vec![22], "{o:?}");
    assert_eq!(o.corrupt_counts, 1, "{o:?}");
}

/// F1a / F1b: the session's second heartbeat (line 2) delayed 700 ms / 200 ms was accepted, and
/// the next genuine heartbeat flagged or the first genuine report shown stale; now the delayed
/// one alone is flagged.
#[test]
fn f1_a_delayed_second_heartbeat_alone_is_flagged() {
    for name in [
        "F1a_delayed_2nd_heartbeat_accepted_genuine_rejected.log",
        "F1b_delayed_2nd_heartbeat_makes_first_report_stale.log",
    ] {
        let o = decode(name);
        assert_eq!(o.flagged, vec![2], "{name}: {o:?}");
        assert!(o.stale.is_empty() && o.withdrawn.is_empty(), "{name}: {o:?}");
    }
}

/// F10: a receiver cut off for 1265 s while the monitor went from release 8 to 40 (32 on: the
/// 6-bit number looks 32 behind) refused every later frame as `wrong_release`. The heartbeat
/// continues the session in time (the sender never powered down), so it only counted releases
/// up: accepted. Only the report before the first heartbeat (line 1) and the reports between
/// the silence and the first heartbeat after it, which no live heartbeat attributes, may be
/// flagged.
#[test]
fn f10_a_receiver_outage_over_32_releases_resynchronises() {
    let o = decode("F10_receiver_outage_release_advanced_32_locks_out.log");
    assert!(o.flagged.iter().all(|&l| l == 1), "{o:?}");
    assert!(o.stale.is_empty() && o.withdrawn.is_empty(), "{o:?}");
}

/// F5: a latency step of 123 ms beginning at release 5's first report (line 28; every line
/// genuine) got the heartbeat at the step and the first 11 reports of the release flagged, and
/// a status frame claimed lost. Now the step is followed from the second frame of each message
/// on: the heartbeat and the report at the step (lines 28, 29: a delayed frame looks the same)
/// are flagged, nothing else; no status frame is claimed lost and no report shown stale.
#[test]
fn f5_a_latency_step_at_a_releases_first_report_flags_one_frame_of_each_message() {
    let o = decode("F5_latency_step_at_release_start_flags_11_reports.log");
    assert_eq!(o.flagged, vec![28, 29], "{o:?}");
    assert!(o.stale.is_empty() && o.withdrawn.is_empty(), "{o:?}");
}

/// F2: a status frame replayed 4096 s later (line 15, release 4 while the monitor is at 40),
/// 0.3 s before its genuine twin, was accepted and the twin flagged (and, before that, the
/// genuine frames locked out). A sender running on counts at most one release a second: the
/// replay alone is flagged.
#[test]
fn f2_a_lag_4096_replay_of_another_release_alone_is_flagged() {
    let o = decode("F2_lag4096_status_replay_other_release_locks_out.log");
    assert_eq!(o.flagged, vec![15], "{o:?}");
    assert!(o.stale.is_empty() && o.withdrawn.is_empty(), "{o:?}");
}

// The second black-box tester of 2026-11-27 (logs `R2_*`, as the tester left them): a lasting
// step of the frames' phase beyond the latency step the session clock follows locked the genuine
// monitor out for the rest of the session (and, its release number no longer followed, its next
// restart was never shown current). The receiver re-locks onto the new phase after
// `RELOCK_RUN` heartbeats at it (`pbm::can::decoder`, can/README.md "Re-locking").

/// Decodes `name` and returns the outcome and the receive times (µs) at which the session clock
/// was re-locked, with the step (ms).
fn decode_relocks(name: &str) -> (Outcome, Vec<(usize, i32)>) {
    let path = format!("{}/tests/data/can_findings/{name}", env!("CARGO_MANIFEST_DIR"));
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut d = Decoder::new();
    let mut relocks = Vec::new();
    for (i, rec) in read_log(&bytes[..]).enumerate() {
        let rec = rec.unwrap_or_else(|e| panic!("{name}: {e:?}"));
        if let Some(step_ms) = d.receive(rec.time_us, &rec.frame).relocked_ms {
            relocks.push((i + 1, step_ms));
        }
    }
    (decode(name), relocks)
}

/// F1a / F1b / F1c: a logger clock step of −500 ms or +300 ms at 214 s, or a gateway latency
/// step of +300 ms at 100 s, got every later frame flagged or shown stale (265 of 265; 683 of
/// 683 in F1c, across six later releases). Now the two heartbeats at the new phase (and, in
/// F1c, the fault reports of those two seconds) are flagged, the third re-locks, and nothing
/// after it is flagged, stale or withdrawn; the reports flagged meanwhile are not claimed lost.
#[test]
fn r2_f1_a_phase_step_beyond_the_followed_window_re_locks() {
    for (name, flagged, relock) in [
        ("R2_F1a_clock_step_back_500ms_locks_out.log", vec![593, 594], (595, -500)),
        ("R2_F1b_clock_step_fwd_300ms_locks_out.log", vec![592, 593], (594, 300)),
        ("R2_F1c_latency_step_300ms_locks_out.log", (174..=182).collect(), (183, 300)),
    ] {
        let (o, relocks) = decode_relocks(name);
        assert_eq!(o.flagged, flagged, "{name}: {o:?}");
        assert_eq!(relocks, vec![relock], "{name}");
        assert!(o.stale.iter().all(|&l| l < relock.0) && o.withdrawn.is_empty(), "{name}: {o:?}");
    }
}

/// F1f: 600 ms of gateway latency from the start of the log that drains at 30 s (the session
/// clock was set by the delayed frames): every later frame was refused (802 of 802). Now the
/// frames of the two seconds after the drop are flagged and the third heartbeat re-locks.
#[test]
fn r2_f1f_a_latency_that_ends_re_locks() {
    let name = "R2_F1f_latency_600ms_drains_at_30s.log";
    let (o, relocks) = decode_relocks(name);
    assert_eq!(o.flagged, vec![55, 56, 57, 58], "{o:?}");
    assert_eq!(relocks, vec![(59, -600)]);
    assert!(o.stale.iter().all(|&l| l < relocks[0].0) && o.withdrawn.is_empty(), "{o:?}");
}

/// F1d: a 1.23 s gateway delay over the first 10 s of a monitor's session (one of several
/// restarted monitors in the log) refused the rest of that session. Now only frames of the
/// delayed window are flagged: the session opened on the delayed frames, and when the delay
/// ends the frames at the true phase re-lock it (lines 864 and 866–868, between which the last
/// delayed heartbeat came: three flagged, the fourth re-locks).
#[test]
fn r2_f1d_a_delay_at_a_sessions_start_does_not_lock_out_the_session() {
    let (o, relocks) = decode_relocks("R2_F1d_latency_bump_1230ms_at_session_start.log");
    assert_eq!(o.flagged, vec![864, 866, 867], "{o:?}");
    assert_eq!(relocks, vec![(868, -1230)]);
    assert!(o.stale.is_empty() && o.withdrawn.is_empty(), "{o:?}");
}

/// F1e: F1b, then the monitor power-cycled with its correct next release number (11): all 494
/// reports of the new session were "not current: a restart 5 releases on", the receiver's
/// record of the newest release having stopped at the lock-out. Now the record follows the
/// re-locked stream, and the restart is a restart: no report of it stale.
#[test]
fn r2_f1e_a_proper_restart_after_a_phase_step_is_current() {
    let (o, relocks) = decode_relocks("R2_F1e_restart_after_lockout_not_current.log");
    assert_eq!(o.flagged, vec![592, 593], "{o:?}");
    assert_eq!(relocks, vec![(594, 300)]);
    assert!(o.stale.is_empty() && o.withdrawn.is_empty(), "{o:?}");
}

/// F3 (text): a status frame turned into a CRC-passing fault report by a 3-bit error (line 363)
/// is shown stale and withdrawn at the next heartbeat; the withdrawal line said "up to - s"
/// because the report withdrawn had been shown stale, never held. It now names its time.
/// (The 15 fault reports it makes the receiver claim lost are left: can/README.md.)
#[test]
fn r2_f3_a_withdrawal_names_the_time_of_a_report_shown_stale() {
    use pbm_lab::can_cmd::{decode_log, CabDisplay, DecodeFormat};
    let path = format!(
        "{}/tests/data/can_findings/R2_F3_status_morphed_into_crc_passing_report.log",
        env!("CARGO_MANIFEST_DIR")
    );
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut out = Vec::new();
    let mut d = CabDisplay::new(&mut out, false, DecodeFormat::Text);
    decode_log(&bytes[..], &mut d).unwrap();
    let summary = d.finish().unwrap();
    let text = String::from_utf8(out).unwrap();
    let withdrawn: Vec<&str> = text.lines().filter(|l| l.contains("!! withdrawn")).collect();
    assert_eq!(summary.withdrawn, 1, "{text}");
    assert_eq!(withdrawn.len(), 1, "{text}");
    assert!(withdrawn[0].contains("up to 406.950 s"), "{}", withdrawn[0]);
}
