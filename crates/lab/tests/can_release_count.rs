//! The session frame (layout 3) and its full release count, against the fourth black-box
//! attacker's two findings that the 6-bit release number could not answer (can/README.md):
//! - H1: the monitor stops, and a recording of an old session of the same locomotive whose
//!   release number is 1 or 2 ahead modulo 64 is played onto the bus: it was taken as a restart
//!   and its reports shown current;
//! - H2: a man in the middle replaces a whole session by the session 64 releases earlier, at
//!   the right moments: every frame was accepted and its reports shown current.
//!
//! The streams are built here from the core's own reporter (one power-up per session, as
//! `host-sim replay` numbers a locomotive's traces), so the test needs no recorded file.

use embedded_can::Frame as _;
use pbm::can::{CanFrame, CanReporter, Decoder, FrameError, MessageKind, PowerUp, Report};
use pbm::report::{EstimatorState, FaultReport, StatusReport, Verdict};
use pbm::FaultClass;

/// One frame of a built stream: receive time, frame, and the session it was recorded in.
#[derive(Debug, Clone, Copy)]
struct Timed {
    t: u64,
    f: CanFrame,
    session: usize,
    injected: bool,
}

const LOCO: u16 = 1;
/// Seconds of one session (one release, the valve open throughout).
const SESSION_S: u64 = 12;
/// Seconds between two sessions (a power cycle).
const GAP_S: u64 = 5;

/// The frames of session `k` of the locomotive (the controller kept `k` releases before it),
/// starting at `start_us`: a power-up and a release command at the first sample, a report
/// from 2.3 s on whose content depends on `k`.
fn session(k: usize, start_us: u64) -> Vec<Timed> {
    session_of(k, start_us, SESSION_S)
}

/// [`session`] lasting `seconds`.
fn session_of(k: usize, start_us: u64, seconds: u64) -> Vec<Timed> {
    session_of_unit(LOCO, k, start_us, seconds)
}

/// [`session_of`] of the locomotive with fleet number `fleet`.
fn session_of_unit(fleet: u16, k: usize, start_us: u64, seconds: u64) -> Vec<Timed> {
    let mut rep = CanReporter::new();
    rep.set_identity(PowerUp { locomotive: fleet, release_count: k as u32 });
    rep.new_release();
    let status =
        StatusReport { sensor_fault: None, estimator: EstimatorState::Settled, pressure_mbar: 7_000, version: (0, 1) };
    let class = [FaultClass::Normal, FaultClass::AirLeak, FaultClass::OrificeBlock][k % 3];
    let mut out = Vec::new();
    for n in 0..(seconds * 100) as u32 {
        let fault = FaultReport {
            verdict: Verdict::Class { class, confidence_pct: 90 },
            time_since_release_cs: (n + 1) as u16,
            supply_mbar: 7_700,
            leak_um: 0,
            release_completed: false,
        };
        let report = (n >= 230).then_some(&fault);
        for f in rep.step(&status, report, true).as_slice() {
            out.push(Timed { t: start_us + u64::from(n) * 10_000, f: *f, session: k, injected: false });
        }
    }
    out
}

fn start_of(k: usize) -> u64 {
    1_000_000 + k as u64 * (SESSION_S + GAP_S) * 1_000_000
}

/// Sessions `0..n`, one after another.
fn sessions(n: usize) -> Vec<Timed> {
    (0..n).flat_map(|k| session(k, start_of(k))).collect()
}

/// One power-up of the locomotive (count 40 before it) with two releases, the second from tick
/// `second_at` (10 ms ticks, `ticks` in all), a report at 1 Hz from 2.3 s into each.
fn two_releases(ticks: u32, second_at: u32) -> Vec<Timed> {
    let mut rep = CanReporter::new();
    rep.set_identity(PowerUp { locomotive: LOCO, release_count: 40 });
    rep.new_release();
    let status =
        StatusReport { sensor_fault: None, estimator: EstimatorState::Settled, pressure_mbar: 7_000, version: (0, 1) };
    let mut out = Vec::new();
    for n in 0..ticks {
        if n == second_at {
            rep.new_release();
        }
        let fault = FaultReport {
            verdict: Verdict::Class { class: FaultClass::AirLeak, confidence_pct: 90 },
            time_since_release_cs: (n % second_at + 1) as u16,
            supply_mbar: 7_700,
            leak_um: 0,
            release_completed: false,
        };
        let report = (n % second_at >= 230).then_some(&fault);
        for f in rep.step(&status, report, true).as_slice() {
            out.push(Timed { t: 1_000_000 + u64::from(n) * 10_000, f: *f, session: 0, injected: false });
        }
    }
    out
}

fn is_kind(f: &CanFrame, kind: MessageKind) -> bool {
    MessageKind::of(f) == Ok(kind)
}

/// What became of the stream: reports shown current, per session and injected or not; frames
/// flagged, by label.
#[derive(Debug, Default)]
struct Seen {
    current_genuine: usize,
    current_injected: usize,
    reports_genuine: usize,
    flagged_genuine: Vec<(u64, FrameError)>,
    flagged_injected: Vec<FrameError>,
    unconfirmed_injected: usize,
    /// Fault reports held (not current) that a later frame decided were not the monitor's.
    rejected_later: usize,
}

fn decode(stream: &[Timed]) -> Seen {
    let mut d = Decoder::new();
    let mut seen = Seen::default();
    for e in stream {
        let r = d.receive(e.t, &e.f);
        seen.rejected_later += usize::from(r.unattributed_rejected);
        match (r.result, e.injected) {
            (Err(err), false) => seen.flagged_genuine.push((e.t, err)),
            (Err(err), true) => seen.flagged_injected.push(err),
            (Ok(Report::Fault(_)), injected) => {
                let current = !r.stale && d.is_current(e.t, e.t);
                if injected {
                    seen.current_injected += usize::from(current);
                    seen.unconfirmed_injected += usize::from(r.release_unconfirmed);
                } else {
                    seen.reports_genuine += 1;
                    seen.current_genuine += usize::from(current);
                }
            }
            (Ok(_), _) => {}
        }
    }
    seen
}

/// 70 power-ups of one locomotive (its release number wraps at 64): nothing flagged, every
/// report current, every report attributed to its full release count.
#[test]
fn seventy_sessions_across_the_wrap_decode_cleanly() {
    let stream = sessions(70);
    let seen = decode(&stream);
    assert!(seen.flagged_genuine.is_empty(), "{:?}", &seen.flagged_genuine[..seen.flagged_genuine.len().min(5)]);
    assert_eq!(seen.current_genuine, seen.reports_genuine);
    assert!(seen.reports_genuine > 70 * 9);
    // The count names the release: the last session's reports belong to count 71.
    let mut d = Decoder::new();
    let mut last = None;
    for e in &stream {
        let r = d.receive(e.t, &e.f);
        if matches!(r.result, Ok(Report::Fault(_))) {
            last = r.release_count;
        }
    }
    assert_eq!(last, Some(69 + 2), "power-up and release command of the 70th session");
}

/// H2: session j (64 ≤ j < 70) replaced, heartbeats and reports and session frames alike, by
/// the recording of session j − 64 (the same release number modulo 64), aligned at its start
/// (and 5 ms, 30 ms early, 200 ms late). Its session frames are flagged (`wrong_release_count`:
/// behind the count the receiver saw), and its reports are flagged (`wrong_crc`: their CRC
/// binds the old count, layout 3.2) or shown not current, with or without its session frames.
/// The genuine sessions around it are untouched.
#[test]
fn a_session_from_64_releases_earlier_is_never_current() {
    for j in [64usize, 66, 69] {
        for shift in [0i64, 5_000, -30_000, 200_000] {
            for strip in [false, true] {
                let mut stream: Vec<Timed> = sessions(70).into_iter().filter(|e| e.session != j).collect();
                let dt = start_of(j) as i64 - start_of(j - 64) as i64 + shift;
                stream.extend(
                    session(j - 64, start_of(j - 64))
                        .into_iter()
                        .filter(|e| !(strip && is_kind(&e.f, MessageKind::Session)))
                        .map(|e| Timed { t: e.t.saturating_add_signed(dt), injected: true, ..e }),
                );
                stream.sort_by_key(|e| e.t);
                let seen = decode(&stream);
                let what = format!("session {j} replaced, shift {shift} µs, session frames stripped: {strip}");
                assert_eq!(seen.current_injected, 0, "{what}: {seen:?}");
                // Layout 3.2: their CRC binds the count of session j − 64, where the receiver
                // rebuilds that of session j from the count it heard before: each of its reports
                // is flagged, or shown not current when it fits the count of the recording's own
                // session frame that was refused (as a genuine restart after more unheard
                // releases than the time allows would be).
                let reports = stream.iter().filter(|e| e.injected && is_kind(&e.f, MessageKind::Fault)).count();
                let wrong_crc = seen.flagged_injected.iter().filter(|e| e.label() == "wrong_crc").count();
                assert!(
                    reports > 5 && wrong_crc + seen.unconfirmed_injected == reports,
                    "{what}: {wrong_crc} + {} of {reports}: {seen:?}",
                    seen.unconfirmed_injected
                );
                if !strip {
                    assert!(
                        seen.flagged_injected.iter().any(|e| e.label() == "wrong_release_count"),
                        "{what}: {:?}",
                        seen.flagged_injected
                    );
                }
                assert!(seen.flagged_genuine.is_empty(), "{what}: {:?}", seen.flagged_genuine);
                // Every genuine session's reports current (the one replaced is gone).
                assert_eq!(seen.current_genuine, seen.reports_genuine, "{what}");
            }
        }
    }
}

/// H1: the monitor stops after session j; 5–60 s later a recording of session j − 64 + m of the
/// same locomotive is played onto the bus, its release number m ahead modulo 64 (1 and 2 were
/// taken as a restart; 5–29 were not current; 32 and more flagged). With session frames its
/// count is behind the newest seen, at every m: never current.
#[test]
fn an_old_recording_after_the_monitor_stopped_is_never_current() {
    let j = 68;
    for m in [1usize, 2, 3, 17, 40] {
        for gap_s in [5u64, 20, 60] {
            let mut stream: Vec<Timed> = sessions(j + 1);
            let end = stream.last().map_or(0, |e| e.t);
            let k = j - 64 + m;
            let dt = (end + gap_s * 1_000_000) as i64 - start_of(k) as i64;
            stream.extend(session(k, start_of(k)).into_iter().map(|e| Timed {
                t: e.t.saturating_add_signed(dt),
                injected: true,
                ..e
            }));
            let seen = decode(&stream);
            let what = format!("m {m}, {gap_s} s after the monitor stopped");
            assert_eq!(seen.current_injected, 0, "{what}: {seen:?}");
            assert!(seen.flagged_genuine.is_empty(), "{what}: {:?}", seen.flagged_genuine);
            assert_eq!(seen.current_genuine, seen.reports_genuine, "{what}");
        }
    }
}

/// The genuine counterpart of the restart rule that H1 drove: a monitor power-cycled several
/// times while this receiver heard nothing comes back with its release number several on.
/// Without a count that could not be told from an old recording (its reports were never
/// current); its session frame's count, newer than any seen, now shows it genuine.
#[test]
fn a_monitor_restarted_several_times_while_the_receiver_was_deaf_is_current() {
    let mut stream = sessions(10);
    // Sessions 10..14 unheard; 15 heard.
    stream.extend(session(15, start_of(15)));
    let seen = decode(&stream);
    assert!(seen.flagged_genuine.is_empty(), "{:?}", seen.flagged_genuine);
    assert_eq!(seen.current_genuine, seen.reports_genuine, "{seen:?}");
}

/// A session frame whose count moved far ahead while its CRC still fits (a corruption that kept
/// the CRC, or a forgery): flagged, and it locks nothing out. Its session's count is in doubt
/// until a session frame gives it again (none comes before that session ends: its last two
/// reports are not current); every report of the restarts after it is current.
#[test]
fn a_count_far_ahead_is_flagged_and_locks_nothing_out() {
    use pbm::can::codec::{decode_frame, encode_session};
    let mut stream = sessions(8);
    // The periodic session frame of session 3 (heartbeat 10), its count 1 000 000 on.
    let i = stream
        .iter()
        .position(|e| {
            e.session == 3
                && matches!(decode_frame(&e.f, pbm::can::Binding::default()), Ok((Report::Session(l), _)) if l.counter == 10)
        })
        .expect("the periodic session frame");
    let Ok((Report::Session(link), _)) = decode_frame(&stream[i].f, pbm::can::Binding::default()) else {
        unreachable!()
    };
    stream[i] = Timed {
        f: encode_session(pbm::can::SessionLink { release_count: link.release_count + 64 * 15_625, ..link }),
        injected: true,
        ..stream[i]
    };
    let seen = decode(&stream);
    assert_eq!(seen.flagged_injected.iter().map(|e| e.label()).collect::<Vec<_>>(), ["wrong_release_count"]);
    assert!(seen.flagged_genuine.is_empty(), "{:?}", seen.flagged_genuine);
    assert_eq!(seen.current_genuine + 2, seen.reports_genuine, "{seen:?}");
    let mut d = Decoder::new();
    let mut later_reports = 0;
    for e in &stream {
        let r = d.receive(e.t, &e.f);
        if e.session >= 4 && matches!(r.result, Ok(Report::Fault(_))) {
            assert!(!r.stale && d.is_current(e.t, e.t), "{}: {r:?}", e.t);
            later_reports += 1;
        }
    }
    assert!(later_reports > 0);
}

/// A receiver deaf for the first 4.5 s of a session of a locomotive whose count it knows: it
/// hears the session from its fifth heartbeat on, with no session frame until the periodic one
/// at heartbeat 10. The reports before that are shown, not current ("cannot tell yet": a
/// recording 64 releases old looks the same); from the session frame on they are current.
/// Nothing is flagged.
#[test]
fn a_receiver_joining_a_session_late_waits_for_its_session_frame() {
    let joined = start_of(4) + 4_500_000;
    let stream: Vec<Timed> = sessions(6).into_iter().filter(|e| e.session != 4 || e.t >= joined).collect();
    let mut d = Decoder::new();
    let (mut waiting, mut current_after) = (0, 0);
    let confirmed_at = start_of(4) + 10_000_000;
    for e in &stream {
        let r = d.receive(e.t, &e.f);
        assert!(r.result.is_ok(), "{}: {r:?}", e.t);
        if e.session == 4 && matches!(r.result, Ok(Report::Fault(_))) {
            if e.t < confirmed_at {
                assert!(r.release_unconfirmed && r.stale && !d.is_current(e.t, e.t), "{}: {r:?}", e.t);
                waiting += 1;
            } else {
                assert!(!r.stale && d.is_current(e.t, e.t), "{}: {r:?}", e.t);
                current_after += 1;
            }
        }
    }
    assert!(waiting >= 4 && current_after >= 2, "{waiting} {current_after}");
}

/// The sixth black-box attacker's F2 (and N1, N2 of the round after it): the monitor stops 20 s
/// into session 68, and 1–60 s later a recording of session 4 (the same release number, 64
/// releases earlier) carries on its heartbeat counter, so that every counter comes when the live
/// one would have (or 0.4 s or 4 s later: a phase step the receiver re-locks onto, N2); with or
/// without its session frames, and with or without its heartbeats at multiples of 10 (whose
/// session frames the receiver would miss, N1). It looks like the monitor heard again after a
/// receiver outage. After a silence (3 s or more), or a re-lock, the session's count must be
/// given again, and the recording's session frames carry the old count: none of its reports is
/// current. Within the heartbeat timeout nothing tells it from the monitor until its first
/// session frame (flagged) or the first one missing: its reports are current for at most that
/// long (10 s), and never after.
#[test]
fn a_recording_that_carries_on_the_heartbeat_counter_is_not_current_for_long() {
    use pbm::can::codec::status_link;
    let (j, k) = (68usize, 4usize);
    let counter = |f: &CanFrame| status_link(u64::from_le_bytes(f.data().try_into().unwrap_or([0; 8]))).counter;
    for gap_s in [1u64, 5, 30, 60] {
        for phase_us in [0u64, 400_000, 4_000_000] {
            for (strip, skip10) in [(false, false), (true, false), (true, true)] {
                let stop = start_of(j) + 20_000_000;
                let mut stream: Vec<Timed> = sessions(j);
                stream.extend(session_of(j, start_of(j), 120).into_iter().filter(|e| e.t < stop));
                let resume = stop + gap_s * 1_000_000;
                let dt = start_of(j) as i64 - start_of(k) as i64 + phase_us as i64;
                stream.extend(
                    session_of(k, start_of(k), 120)
                        .into_iter()
                        .map(|e| Timed { t: e.t.saturating_add_signed(dt), injected: true, ..e })
                        .filter(|e| e.t >= resume && !(strip && is_kind(&e.f, MessageKind::Session)))
                        .filter(|e| !(skip10 && is_kind(&e.f, MessageKind::Status) && counter(&e.f) % 10 == 0)),
                );
                let mut d = Decoder::new();
                let mut last_current = None;
                for e in &stream {
                    let r = d.receive(e.t, &e.f);
                    if e.injected && matches!(r.result, Ok(Report::Fault(_))) && !r.stale && d.is_current(e.t, e.t) {
                        last_current = Some(e.t);
                    }
                    if !e.injected {
                        assert!(r.result.is_ok(), "genuine {}: {r:?}", e.t);
                    }
                }
                let what =
                    format!("gap {gap_s} s, phase +{phase_us} µs, stripped {strip}, 10th heartbeats dropped {skip10}");
                if let Some(t) = last_current {
                    assert!(gap_s * 1_000_000 + phase_us < 3_000_000, "{what}: a report shown current at {t}");
                    assert!(
                        t < resume + 11_000_000,
                        "{what}: current {} s after the takeover",
                        (t - resume) / 1_000_000
                    );
                }
            }
        }
    }
}

/// The sixth black-box attacker's F3: a monitor restarted after 32 or more releases
/// this receiver did not hear has a 6-bit release number that reads as behind (or equal) and its
/// first heartbeat is refused; every later one was too, for good. Its session frame's count,
/// newer than any seen, now shows the restart: the session opens on it, and only that first
/// status frame stays flagged.
#[test]
fn a_monitor_restarted_after_many_unheard_releases_is_current() {
    for unheard in [31usize, 32, 40, 63, 64, 100] {
        let mut stream = sessions(10);
        let back = 10 + unheard;
        stream.extend(session_of(back, start_of(back), 30));
        let seen = decode(&stream);
        let what = format!("{unheard} sessions unheard");
        assert!(seen.flagged_genuine.len() <= 1, "{what}: {:?}", seen.flagged_genuine);
        assert_eq!(seen.current_genuine, seen.reports_genuine, "{what}: {seen:?}");
    }
}

/// The 32-bit count wraps across power-ups (a controller whose non-volatile count started at an
/// erased 0xFFFF_FFFF wraps at its second power-up; eighth black-box attacker, F1): counts are
/// compared in serial-number order, so every session after the wrap is current. Before, every
/// later session frame was flagged as an old recording and no later report was current.
#[test]
fn a_count_that_wraps_at_two_to_the_32_across_power_ups_decodes_cleanly() {
    let first = 0xFFFF_FFFDu64;
    let stream: Vec<Timed> = (0..6).flat_map(|j| session((first + j) as usize, start_of(j as usize))).collect();
    assert!(stream.iter().any(|e| e.session as u64 > u64::from(u32::MAX)), "the count must cross 2³²");
    let seen = decode(&stream);
    assert!(seen.flagged_genuine.is_empty(), "{:?}", seen.flagged_genuine);
    assert_eq!(seen.current_genuine, seen.reports_genuine, "{seen:?}");
    assert!(seen.reports_genuine > 6 * 9);
}

/// A session frame alone delayed behind its status frame by bus load (it is sent last in its
/// tick, with the lowest priority), by 55 ms to 0.9 s (eighth black-box attacker, F3: from 55 ms
/// on it was flagged `untimely` and the session's reports were not current for 10 s): accepted,
/// nothing flagged, every report current.
#[test]
fn a_session_frame_delayed_by_bus_load_is_accepted() {
    for delay_ms in [55u64, 120, 400, 900] {
        let mut stream = sessions(3);
        for e in stream.iter_mut().filter(|e| is_kind(&e.f, MessageKind::Session)) {
            e.t += delay_ms * 1000;
        }
        stream.sort_by_key(|e| e.t);
        let seen = decode(&stream);
        assert!(seen.flagged_genuine.is_empty(), "{delay_ms} ms: {:?}", seen.flagged_genuine);
        assert_eq!(seen.current_genuine, seen.reports_genuine, "{delay_ms} ms: {seen:?}");
    }
}

/// Another locomotive's unit whose fleet number is the same modulo 64 (65 for 1: a spare or
/// swapped controller, or its recording), played from its power-up after the monitor stopped,
/// with a count above the monitor's (eighth black-box attacker, F2: every report of it was shown
/// current, `--strict` passing). Its session frames carry the other 12-bit number: flagged
/// `foreign_sender`, none of its reports current; the monitor's own restart after it is current.
#[test]
fn another_unit_with_the_same_locomotive_number_modulo_64_is_never_current() {
    for (gap_s, ahead) in [(4u64, 1usize), (30, 3), (60, 5)] {
        let mut stream = sessions(3);
        let t = start_of(3) - GAP_S * 1_000_000 + gap_s * 1_000_000;
        stream.extend(
            session_of_unit(LOCO + 64, 2 + ahead, t, SESSION_S).into_iter().map(|e| Timed { injected: true, ..e }),
        );
        stream.extend(session(2 + ahead + 1, t + (SESSION_S + GAP_S) * 1_000_000));
        let seen = decode(&stream);
        assert_eq!(seen.current_injected, 0, "gap {gap_s} s, +{ahead}: {seen:?}");
        assert!(
            seen.flagged_injected.iter().any(|e| matches!(e, FrameError::ForeignSender { locomotive: 65 })),
            "{:?}",
            seen.flagged_injected
        );
        assert!(seen.flagged_genuine.is_empty(), "gap {gap_s} s, +{ahead}: {:?}", seen.flagged_genuine);
        assert_eq!(seen.current_genuine, seen.reports_genuine, "gap {gap_s} s, +{ahead}: {seen:?}");
    }
}

/// A unit with another fleet number (the same modulo 64) that carries on the live unit's
/// heartbeat counter, release and count (a takeover without a gap; a ninth black-box tester):
/// its first session frame is flagged `foreign_sender` and puts the session's count in doubt,
/// so none of its reports after that frame is current (before, the report in the same second
/// was). Before its first session frame nothing tells it from the live unit (can/README.md).
#[test]
fn reports_after_a_foreign_units_session_frame_are_not_current() {
    let start = start_of(0);
    let switch = start + 12_500_000;
    let mut stream: Vec<Timed> =
        session_of_unit(LOCO + 64, 0, start, 30).into_iter().filter(|e| e.t < switch).collect();
    stream.extend(
        session_of_unit(LOCO, 0, start, 30)
            .into_iter()
            .filter(|e| e.t >= switch)
            .map(|e| Timed { injected: true, ..e }),
    );
    let mut d = Decoder::new();
    let mut flagged_at = None;
    let mut current_after = 0;
    for e in &stream {
        let r = d.receive(e.t, &e.f);
        match r.result {
            Err(FrameError::ForeignSender { locomotive }) if e.injected => {
                assert_eq!(locomotive, LOCO);
                flagged_at.get_or_insert(e.t);
            }
            Err(err) => assert!(e.injected, "genuine frame flagged at {}: {err:?}", e.t),
            Ok(Report::Fault(_)) if e.injected && flagged_at.is_some() => {
                current_after += usize::from(!r.stale && d.is_current(e.t, e.t));
            }
            Ok(_) => {}
        }
    }
    assert!(flagged_at.is_some(), "the foreign unit's session frame must be flagged");
    assert_eq!(current_after, 0, "no report of the foreign unit current after its session frame");
}

/// After a silence, another unit with the same number modulo 64 (its session frames flagged
/// `foreign_sender`) or a recording of an older power-up whose 6-bit release number reads as
/// newer (its session frame flagged as an old recording) runs for a while; then the genuine
/// monitor restarts. Its first heartbeat was flagged `wrong_release` ("went backwards"): the
/// impostor's heartbeats had raised the locomotive's newest release (ninth and tenth black-box
/// testers). Now a session whose session frame is refuted and that none vouched for does not
/// speak for the locomotive: the genuine restart is clean and current, and the impostor's
/// status frames after its refuted session frame are shown as not current (a recording whose
/// release number reads as behind is flagged frame by frame, as before).
#[test]
fn a_genuine_restart_after_a_refuted_impostor_is_not_flagged() {
    let genuine = |k: usize, i: usize| session(k, start_of(i));
    let cases: [(&str, u16, usize); 4] = [
        ("other unit, count +1", LOCO + 64, 103),
        ("other unit, +3", LOCO + 64, 105),
        ("recording 40 back", LOCO, 62),
        ("recording 13 back", LOCO, 89),
    ];
    for (what, unit, impostor_count) in cases {
        let mut stream: Vec<Timed> = (0..3).flat_map(|i| genuine(100 + i, i)).collect();
        let t = start_of(3) + 2_000_000;
        let impostor: Vec<Timed> =
            session_of_unit(unit, impostor_count, t, 8).into_iter().map(|e| Timed { injected: true, ..e }).collect();
        stream.extend(impostor);
        stream.extend(session(103, t + 14_000_000));
        let mut d = Decoder::new();
        let (mut live_status, mut flagged_impostor, mut genuine_reports, mut genuine_current) = (0, 0, 0, 0);
        for e in &stream {
            let r = d.receive(e.t, &e.f);
            match (&r.result, e.injected) {
                (Err(err), false) => panic!("{what}: genuine frame flagged at {}: {err:?}", e.t),
                (Err(_), true) => flagged_impostor += 1,
                (Ok(Report::Status(_)), true) => live_status += usize::from(!r.refuted),
                (Ok(Report::Fault(_)), true) => {
                    assert!(r.stale || !d.is_current(e.t, e.t), "{what}: impostor report current at {}", e.t)
                }
                (Ok(Report::Fault(_)), false) => {
                    genuine_reports += 1;
                    genuine_current += usize::from(!r.stale && d.is_current(e.t, e.t));
                }
                _ => {}
            }
        }
        assert!(flagged_impostor > 0, "{what}: the impostor's session frame must be flagged");
        // Only the heartbeat that opened the session, before its session frame came, is shown live.
        assert!(live_status <= 1, "{what}: {live_status} impostor status frames shown as live");
        assert_eq!(genuine_current, genuine_reports, "{what}");
    }
}

/// The session frame of a new release's first heartbeat logged just before that heartbeat
/// (the same stamp; frames of one tick in another order): it gave the count, so no session
/// frame is lost and the release's reports are current (tenth black-box tester: one genuine
/// report was not current, and a session frame reported lost, on untouched traffic).
#[test]
fn a_session_frame_logged_before_its_heartbeat_at_a_new_release_is_not_lost() {
    let mut stream: Vec<Timed> = Vec::new();
    // Every session frame logged before the status frame of its tick (the same stamp).
    for e in two_releases(3_000, 1_050) {
        match stream.iter().rposition(|p: &Timed| p.t == e.t && is_kind(&p.f, MessageKind::Status)) {
            Some(k) if is_kind(&e.f, MessageKind::Session) => stream.insert(k, e),
            _ => stream.push(e),
        }
    }
    let mut d = Decoder::new();
    let (mut lost, mut reports, mut current, mut flagged) = (0, 0, 0, Vec::new());
    for e in &stream {
        let r = d.receive(e.t, &e.f);
        lost += usize::from(r.lost_session);
        match r.result {
            Err(err) => flagged.push((e.t, err)),
            Ok(Report::Fault(_)) => {
                reports += 1;
                current += usize::from(!r.stale && d.is_current(e.t, e.t));
            }
            Ok(_) => {}
        }
    }
    // The power-up's session frame, logged before the first heartbeat of all, cannot be judged
    // (no heartbeat yet): flagged as out of order. Nothing else is.
    assert_eq!(flagged.len(), 1, "{flagged:?}");
    assert!(matches!(flagged[0].1, FrameError::NoHeartbeat), "{flagged:?}");
    // (First contact: no count known before, so nothing is owed.)
    assert_eq!(lost, 0);
    assert_eq!(current, reports, "{current} of {reports} current");
}

/// A recording of a whole power-up, replayed exactly 4096 s later (the heartbeat counter's
/// range, so every heartbeat continues the session in time): its later release reaches the
/// count the receiver heard for that release before, and was taken for the session going on,
/// its reports shown current (tenth black-box tester, N5: a demonstration log replayed at 25 ×
/// 4096 s). A release the receiver saw begin after it last heard the locomotive's newest count
/// cannot carry that count: none of the replay's reports is current.
#[test]
fn a_recording_replayed_on_the_heartbeat_counters_range_is_never_current() {
    let genuine = two_releases(4_000, 2_000);
    for laps in [1u64, 3] {
        let mut stream = genuine.clone();
        stream.extend(genuine.iter().map(|e| Timed { t: e.t + laps * 4_096_000_000, injected: true, ..*e }));
        let seen = decode(&stream);
        assert!(seen.flagged_genuine.is_empty(), "{laps}: {:?}", seen.flagged_genuine);
        assert_eq!(seen.current_genuine, seen.reports_genuine, "{laps}");
        assert_eq!(seen.current_injected, 0, "{laps} × 4096 s: {seen:?}");
    }
}

/// The tenth black-box tester's O1: a man in the middle puts, in place of a genuine fault report
/// of session j, the report of session j − 64 (the same release number modulo 64) sent at the
/// same time since the release, with the same counter: layout 3.1 bound only the 6-bit release
/// number into the report's CRC, and it was shown current (8 of 10). Layout 3.2 binds the full
/// release count, which the receiver knows from the session frames: the substitute is flagged
/// `wrong_crc` (or, in place of the session's first report, held not current and dropped at the
/// next session frame), and no genuine frame is.
#[test]
fn a_report_of_the_release_64_earlier_in_place_of_the_genuine_one_is_flagged() {
    for j in [64usize, 66, 69] {
        let genuine = sessions(70);
        let old = session(j - 64, start_of(j - 64));
        let reports: Vec<usize> = (0..genuine.len())
            .filter(|&i| genuine[i].session == j && is_kind(&genuine[i].f, MessageKind::Fault))
            .collect();
        assert!(reports.len() > 5);
        for &i in [reports[0], reports[reports.len() / 2], reports[reports.len() - 1]].iter() {
            let offset = genuine[i].t - start_of(j);
            let Some(sub) = old.iter().find(|e| is_kind(&e.f, MessageKind::Fault) && e.t - start_of(j - 64) == offset)
            else {
                panic!("session {} has no report at {offset} µs", j - 64)
            };
            assert_ne!(sub.f, genuine[i].f, "the substitute says something else");
            let mut stream = genuine.clone();
            stream[i] = Timed { f: sub.f, injected: true, ..genuine[i] };
            let seen = decode(&stream);
            let what = format!("session {j}, report at {offset} µs replaced");
            assert_eq!(seen.current_injected, 0, "{what}: {seen:?}");
            // Flagged at once; or, as the session's first report (its count then rests on the
            // power-up's session frame alone, which a report has not proved yet), held not current
            // and dropped at the next session frame.
            let flagged = seen.flagged_injected.iter().map(|e| e.label()).collect::<Vec<_>>();
            let dropped = flagged.is_empty() && seen.rejected_later == 1 && i == reports[0];
            assert!(flagged == ["wrong_crc"] || dropped, "{what}: {seen:?}");
            assert!(seen.flagged_genuine.is_empty(), "{what}: {:?}", seen.flagged_genuine);
            assert_eq!(seen.current_genuine, seen.reports_genuine, "{what}");
        }
    }
}

/// A display that joins a session of a unit whose fleet number and release count are 64 or
/// more, between two session frames, cannot check its fault reports' CRC (layout 3.2 binds both
/// numbers in full; the status frames carry their low 6 bits): the reports are held, shown but
/// not current, and the next session frame decides them: the genuine ones fit, a report sealed
/// for another count (an old recording's) does not. From then on the reports are current.
#[test]
fn a_receiver_joining_an_older_unit_holds_its_reports_until_the_session_frame() {
    let (fleet, kept) = (1_071u16, 5_000usize);
    let live = session_of_unit(fleet, kept, 1_000_000, 30);
    let joined = 1_000_000 + 4_500_000;
    let next_session_frame = 1_000_000 + 10_000_000;
    // A recording of the same unit 64 releases earlier, its report of 7.3 s put in at 7.8 s.
    let old = session_of_unit(fleet, kept - 64, 1_000_000, 30);
    let forged = old.iter().find(|e| is_kind(&e.f, MessageKind::Fault) && e.t == 1_000_000 + 7_300_000).map(|e| e.f);
    let Some(forged) = forged else { panic!("no report at 7.3 s") };
    let mut stream: Vec<Timed> = live.into_iter().filter(|e| e.t >= joined).collect();
    stream.push(Timed { t: 1_000_000 + 7_800_000, f: forged, session: 0, injected: true });
    stream.sort_by_key(|e| e.t);
    let mut d = Decoder::new();
    let (mut held, mut fitting, mut rejected, mut current_after) = (0, 0, 0, 0);
    for e in &stream {
        let r = d.receive(e.t, &e.f);
        assert!(r.result.is_ok(), "{}: {r:?}", e.t);
        assert_eq!(r.lost_fault_reports, 0, "{}: {r:?}", e.t);
        fitting += usize::from(r.unattributed_fitting);
        rejected += usize::from(r.unattributed_rejected);
        if matches!(r.result, Ok(Report::Fault(_))) {
            if e.t < next_session_frame {
                assert!(r.awaiting_count && r.stale && !d.is_current(e.t, e.t), "{}: {r:?}", e.t);
                held += 1;
            } else {
                assert!(!r.stale && d.is_current(e.t, e.t), "{}: {r:?}", e.t);
                assert_eq!(r.release_count, Some(kept as u32 + 2), "{}", e.t);
                current_after += 1;
            }
        }
    }
    assert!(held >= 5, "{held}");
    assert_eq!((fitting, rejected), (held - 1, 1));
    assert!(current_after >= 15, "{current_after}");
}

/// A corruption that changes the count of the first session frame a receiver hears and keeps its
/// CRC (one in 256 of those that keep the low 6 bits): the session's count rested on that one
/// frame, and every later session frame of the unit was refused against it. Layout 3.1 showed
/// none of the session's reports current; with layout 3.2, whose report CRC binds the count,
/// every report was flagged. Now two of the unit's session frames in a row that carry another
/// count outvote the one that gave the session's, which no report proved: the reports are
/// current again from the second of them (20 s), and the reports before it are shown, not
/// current, not flagged.
#[test]
fn a_corrupted_count_in_the_first_session_frame_does_not_lock_out_the_session() {
    use pbm::can::codec::{encode_session, session_link};
    use pbm::can::layout as l;
    for (kept, delta) in [(5usize, 64u32), (100, 64), (100, 128), (100, 0u32.wrapping_sub(64)), (3_000, 1 << 20)] {
        let mut stream = session_of_unit(LOCO, kept, 1_000_000, 60);
        let first = stream.iter().position(|e| is_kind(&e.f, MessageKind::Session)).expect("a session frame");
        let bits = u64::from_le_bytes(stream[first].f.data().try_into().unwrap());
        let mut link = session_link(bits);
        link.release_count = link.release_count.wrapping_add(delta);
        assert_eq!(u64::from(link.release_count & 0x3F), l::RELEASE_COUNT.get(bits) & 0x3F);
        stream[first] = Timed { f: encode_session(link), injected: true, ..stream[first] };
        let mut d = Decoder::new();
        let (mut flagged, mut not_current) = (Vec::new(), 0);
        for e in &stream {
            let r = d.receive(e.t, &e.f);
            match r.result {
                Err(err) if !e.injected => flagged.push((e.t, err)),
                Ok(Report::Fault(_)) => {
                    let current = !r.stale && d.is_current(e.t, e.t);
                    if e.t >= 1_000_000 + 20_500_000 {
                        assert!(current, "count {kept} + {delta}: {}: {r:?}", e.t);
                    } else {
                        not_current += usize::from(!current);
                    }
                }
                _ => {}
            }
        }
        // The second session frame (10 s) is refused, the third (20 s) replaces the count.
        assert_eq!(flagged.len(), 1, "count {kept} + {delta}: {flagged:?}");
        assert_eq!(flagged[0].0, 1_000_000 + 10_000_000);
        assert!(not_current <= 20, "count {kept} + {delta}: {not_current}");
    }
}
