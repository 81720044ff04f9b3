//! Injection test of the CAN link to the cab (issue 18): the EN 50159 threats — repetition,
//! deletion, insertion, resequencing, delay — injected into genuine logs the project's pipeline
//! produces, as an attacker or a faulty gateway would. Requirements: every injected frame is
//! flagged, every deletion and resequenced pair is detected, and no genuine frame is rejected
//! (the receiver resynchronises on genuine data only). Run with `--nocapture` for the table.
//!
//! Genuine logs:
//! - `small`: `host-sim replay tests/data/small --can-log` (18 recorded releases, six
//!   locomotives, a restarted monitor per trace, 10 s apart; one fault report per release);
//! - `session`: one pipeline (the firmware's per-sample path) running six recorded releases one
//!   after another with 5 s of vented chamber between them (one session, six releases);
//! - `demo`: `host-sim can demo-log` (one monitor, nine releases, reports repeated at 1 Hz).
//!
//! A frame injected "at" a genuine frame gets that frame's receive time (the moment it would
//! collide with it); "between" places it half-way to the previous frame; "verbatim" keeps its
//! original time stamp (a log line copied as is).

use embedded_can::Frame as _;
use pbm::can::candump::LOG_EPOCH_US;
use pbm::can::layout::{FAULT_REPORT, STATUS};
use pbm::can::{CanFrame, Decoder, MessageKind, PowerUp};
use pbm::pipeline::Pipeline;
use pbm::AdcCounts;
use pbm_io::can_bus::MockBus;
use pbm_io::can_log::read_log;
use std::collections::BTreeMap;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    Genuine,
    /// Must be flagged.
    Injected,
    /// A genuine frame taking part in a resequenced pair: the pair must show a flag or a loss.
    Paired,
}

#[derive(Debug, Clone, Copy)]
struct Entry {
    t: u64,
    f: CanFrame,
    role: Role,
}

type Log = Vec<(u64, CanFrame)>;

fn genuine(log: &Log) -> Vec<Entry> {
    log.iter().map(|&(t, f)| Entry { t, f, role: Role::Genuine }).collect()
}

fn is_status(f: &CanFrame) -> bool {
    f.raw_id() == STATUS.raw_id()
}

fn small_log() -> Log {
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data/small");
    let (items, _) = pbm_lab::replay::items(std::path::Path::new(data), None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("small.log");
    pbm_lab::replay::replay_to_can_log(&path, &items).unwrap();
    let text = std::fs::read(&path).unwrap();
    read_log(&text[..]).map(|r| r.map(|r| (r.time_us, r.frame)).unwrap()).collect()
}

fn demo_log() -> Log {
    let (_, bus) = pbm_lab::can_cmd::write_demo_log(MockBus::new()).unwrap();
    bus.queue.into_iter().collect()
}

/// Six recorded releases through one pipeline, 5 s of vented chamber between them.
fn session_log() -> Log {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data/small/traces/test");
    let mut pipe = Pipeline::nominal().unwrap();
    pipe.set_identity(PowerUp { locomotive: 12, release_count: 40 });
    let mut out = Vec::new();
    let mut n = 0u64;
    let mut push = |frames: &[CanFrame], n: u64| {
        out.extend(frames.iter().map(|f| (LOG_EPOCH_US + n * 10_000, *f)));
    };
    for class in ["normal", "air_leak", "orifice_block", "leak_and_block", "low_supply", "orifice_missing"] {
        let trace = pbm_io::trace::read_trace(std::path::Path::new(&format!("{dir}/{class}_0000.csv"))).unwrap();
        let adc: Vec<u16> = match &trace.samples {
            pbm_io::trace::Samples::Adc(v) => v.clone(),
            pbm_io::trace::Samples::Bar(v) => v.iter().map(|&p| pbm::sensor::adc_from_bar(pbm::BarG(p)).0).collect(),
        };
        for &a in &adc {
            push(pipe.step(AdcCounts(a), true).frames.as_slice(), n);
            n += 1;
        }
        // Vented: the reading at the command, with a little noise.
        for i in 0..500u64 {
            let a = adc[0].saturating_add([0, 2, 1, 3, 1][(i % 5) as usize]);
            push(pipe.step(AdcCounts(a), false).frames.as_slice(), n);
            n += 1;
        }
    }
    out
}

/// What decoding one stream gave.
#[derive(Debug, Default, Clone, Copy)]
struct Outcome {
    injected: usize,
    flagged: usize,
    genuine: usize,
    rejected: usize,
    events: usize,
    detected: usize,
}

impl std::ops::AddAssign for Outcome {
    fn add_assign(&mut self, o: Self) {
        self.injected += o.injected;
        self.flagged += o.flagged;
        self.genuine += o.genuine;
        self.rejected += o.rejected;
        self.events += o.events;
        self.detected += o.detected;
    }
}

/// Decodes a stream. `event`: the stream holds one deletion or resequenced pair, which must
/// show as a flag on a paired frame or a loss/superseded notice.
fn decode(stream: &[Entry], event: bool, what: &str) -> Outcome {
    let mut d = Decoder::new();
    let mut o = Outcome { events: usize::from(event), ..Outcome::default() };
    let mut noticed = false;
    // Roles of the last accepted fault reports: a withdrawal (the heartbeat's count shows the
    // monitor never sent them) flags an injected one after the fact, and rejects a genuine one.
    let mut accepted = std::collections::VecDeque::new();
    for e in stream {
        let r = d.receive(e.t, &e.f);
        noticed |= r.lost_status > 0 || r.lost_fault_reports > 0 || r.lost_session || r.superseded;
        for _ in 0..r.withdrawn {
            match accepted.pop_back() {
                Some(Role::Injected) => {
                    o.flagged += 1;
                    eprintln!("{what}: injected report withdrawn at {}", e.t.saturating_sub(LOG_EPOCH_US));
                }
                Some(_) => {
                    o.rejected += 1;
                    eprintln!("{what}: genuine report withdrawn at {}", e.t.saturating_sub(LOG_EPOCH_US));
                }
                None => {}
            }
        }
        if matches!(r.result, Ok(pbm::can::Report::Fault(_))) {
            if accepted.len() == 16 {
                accepted.pop_front();
            }
            accepted.push_back(e.role);
        }
        match e.role {
            Role::Injected => {
                o.injected += 1;
                o.flagged += usize::from(r.result.is_err());
                if r.result.is_ok() {
                    eprintln!(
                        "{what}: injected frame accepted (unless withdrawn later) at {}: {r:?}",
                        e.t.saturating_sub(LOG_EPOCH_US)
                    );
                }
            }
            Role::Genuine | Role::Paired => {
                o.genuine += 1;
                if r.result.is_err() {
                    if e.role == Role::Paired {
                        noticed = true;
                    } else {
                        o.rejected += 1;
                        eprintln!("{what}: genuine frame rejected at {}: {r:?}", e.t.saturating_sub(LOG_EPOCH_US));
                    }
                }
            }
        }
    }
    if event {
        if !noticed {
            eprintln!("{what}: not detected");
        }
        o.detected += usize::from(noticed);
    }
    o
}

/// The three messages, status frame first.
const KINDS: [MessageKind; 3] = [MessageKind::Status, MessageKind::Fault, MessageKind::Session];

fn kind_name(kind: MessageKind) -> &'static str {
    match kind {
        MessageKind::Status => "status",
        MessageKind::Fault => "fault report",
        MessageKind::Session => "session",
    }
}

/// Indices of the frames of one message.
fn of_kind(log: &Log, kind: MessageKind) -> Vec<usize> {
    (0..log.len()).filter(|&i| MessageKind::of(&log[i].1) == Ok(kind)).collect()
}

#[derive(Debug, Clone, Copy)]
enum Timing {
    /// Right before the genuine frame, with its time.
    At,
    /// Right after the genuine frame, with its time.
    After,
    /// Half-way between the previous frame and the genuine one.
    Between,
    /// Right before the genuine frame, with its own original time stamp.
    Verbatim,
}

const TIMINGS: [Timing; 4] = [Timing::At, Timing::After, Timing::Between, Timing::Verbatim];

/// The log with `frame` (original time `orig_t`) injected at genuine frame `k`.
fn inject_at(log: &Log, k: usize, frame: CanFrame, orig_t: u64, timing: Timing) -> Vec<Entry> {
    let mut s = genuine(log);
    let (tk, prev) = (log[k].0, if k > 0 { log[k - 1].0 } else { log[k].0 });
    let (at, t) = match timing {
        Timing::At => (k, tk),
        Timing::After => (k + 1, tk),
        Timing::Between => (k, prev + (tk - prev) / 2),
        Timing::Verbatim => (k, orig_t),
    };
    s.insert(at, Entry { t, f: frame, role: Role::Injected });
    s
}

/// How late a frame of `kind` may come and still be on time: the status frame's 50 ms and the
/// fault report's 100 ms tolerance (with their fields' rounding), and for a session frame the
/// rest of its heartbeat period ([`pbm::can::decoder::SESSION_LATE_MAX_US`]: it is sent last,
/// with the lowest priority, and bus load delays it most; its content is the count of the
/// heartbeat it follows, which a delay within the period does not make old).
fn tolerance(kind: MessageKind) -> u64 {
    match kind {
        MessageKind::Fault => 150_000,
        MessageKind::Status => 60_000,
        MessageKind::Session => pbm::can::decoder::SESSION_LATE_MAX_US,
    }
}

/// Spread positions in `0..n` (up to `count`).
fn spread(n: usize, count: usize) -> Vec<usize> {
    if n == 0 {
        return Vec::new();
    }
    let mut v: Vec<usize> = (0..count).map(|q| q * (n - 1) / count.max(1)).collect();
    v.dedup();
    v
}

/// The first frame of each recording (the first of the log and the first after a silence):
/// the receiver has no reference for it yet, so its own delay or deletion cannot be seen (it
/// is judged by the frames after it; see can/README.md).
fn session_starts(log: &Log) -> Vec<usize> {
    std::iter::once(0).chain((1..log.len()).filter(|&i| log[i].0 - log[i - 1].0 > 3_000_000)).collect()
}

/// Receive time gaps longer than the heartbeat timeout end a session (a recording ends).
fn session_ends(log: &Log) -> Vec<usize> {
    (1..log.len()).filter(|&i| log[i].0 - log[i - 1].0 > 3_000_000).map(|i| i - 1).chain([log.len() - 1]).collect()
}

fn table_row(table: &mut BTreeMap<String, Outcome>, key: &str, o: Outcome) {
    *table.entry(key.to_owned()).or_default() += o;
}

fn print_table(title: &str, table: &BTreeMap<String, Outcome>) {
    let total = print_rows(title, table);
    assert_eq!(total.flagged, total.injected, "every injected frame flagged");
    assert_eq!(total.detected, total.events, "every deletion and resequenced pair detected");
    assert_eq!(total.rejected, 0, "no genuine frame rejected");
}

/// Prints the table; returns its total.
fn print_rows(title: &str, table: &BTreeMap<String, Outcome>) -> Outcome {
    println!("\n{title}");
    println!("{:<58} {:>9} {:>9} {:>8} {:>9}", "injection", "injected", "flagged", "events", "genuine rejected");
    let mut total = Outcome::default();
    for (k, o) in table {
        println!(
            "{k:<58} {:>9} {:>9} {:>8} {:>9}",
            o.injected,
            o.flagged,
            format!("{}/{}", o.detected, o.events),
            format!("{}/{}", o.rejected, o.genuine)
        );
        total += *o;
    }
    println!(
        "{:<58} {:>9} {:>9} {:>8} {:>9}",
        "total",
        total.injected,
        total.flagged,
        format!("{}/{}", total.detected, total.events),
        format!("{}/{}", total.rejected, total.genuine)
    );
    total
}

fn logs() -> Vec<(&'static str, Log)> {
    vec![("small", small_log()), ("session", session_log()), ("demo", demo_log())]
}

/// The genuine logs decode without a flag or a loss.
#[test]
fn genuine_logs_decode_cleanly() {
    for (name, log) in logs() {
        let o = decode(&genuine(&log), false, name);
        assert_eq!((o.rejected, o.genuine), (0, log.len()), "{name}");
        let mut d = Decoder::new();
        let lost: u32 = log
            .iter()
            .map(|(t, f)| {
                let r = d.receive(*t, f);
                u32::from(r.lost_status)
                    + u32::from(r.lost_fault_reports)
                    + u32::from(r.superseded)
                    + u32::from(r.stale)
            })
            .sum();
        assert_eq!(lost, 0, "{name}: no loss and no stale report in a genuine log");
        assert_eq!(d.owed_fault_reports(), 0, "{name}: no report owed at the end");
    }
}

/// Repetitions at lags 1, 15, 16, 17, 32, 256 and 257 frames of the same identifier (status
/// frames, fault reports), several positions, four timings each.
#[test]
fn replays_at_every_lag_are_flagged() {
    let mut table = BTreeMap::new();
    for (name, log) in logs() {
        for kind in KINDS {
            let idx = of_kind(&log, kind);
            for lag in [1usize, 15, 16, 17, 32, 256, 257] {
                if idx.len() <= lag {
                    continue;
                }
                for p in spread(idx.len() - lag, 6) {
                    let (j, k) = (idx[p], idx[p + lag]);
                    for timing in TIMINGS {
                        let s = inject_at(&log, k, log[j].1, log[j].0, timing);
                        let what = format!("{name} {} lag {lag} at {k} {timing:?}", kind_name(kind));
                        let o = decode(&s, false, &what);
                        let key = format!("replay, lag {lag:>3} ({})", kind_name(kind));
                        table_row(&mut table, &key, o);
                    }
                }
            }
        }
    }
    print_table("Replays at lags (frames of the same identifier later)", &table);
}

/// A fault report of an earlier release injected into later releases (the case: a
/// fault report of the previous release shown as current), and a status frame of an earlier
/// release likewise.
#[test]
fn replays_across_releases_are_flagged() {
    let mut table = BTreeMap::new();
    for (name, log) in logs() {
        // Release boundaries: a fault report whose time since release is smaller than the
        // previous one's starts a new release; status frames carry the release number.
        let releases: Vec<u8> = log
            .iter()
            .map(|(_, f)| {
                if is_status(f) {
                    pbm::can::codec::status_link(u64::from_le_bytes(f.data().try_into().unwrap())).identity.release
                } else {
                    255
                }
            })
            .collect();
        let mut current = 255u8;
        let release_of: Vec<u8> = releases
            .iter()
            .map(|&r| {
                if r != 255 {
                    current = r;
                }
                current
            })
            .collect();
        let distinct: Vec<u8> = {
            let mut v: Vec<u8> = release_of.clone();
            v.dedup();
            v
        };
        for (ri, &r) in distinct.iter().enumerate() {
            let from: Vec<usize> = (0..log.len()).filter(|&i| release_of[i] == r).collect();
            for later in distinct.iter().skip(ri + 1).take(3) {
                let into: Vec<usize> = (0..log.len()).filter(|&i| release_of[i] == *later).collect();
                if into.len() < 4 {
                    continue;
                }
                // Every fault report and two status frames of release r, into the middle and
                // the end of the later release.
                let faults = from.iter().copied().filter(|&i| !is_status(&log[i].1));
                let statuses = from.iter().copied().filter(|&i| is_status(&log[i].1)).take(2);
                for j in faults.take(3).chain(statuses) {
                    for k in [into[into.len() / 2], into[into.len() - 1]] {
                        for timing in TIMINGS {
                            let s = inject_at(&log, k, log[j].1, log[j].0, timing);
                            let what = format!("{name} release {r} frame {j} into release {later} at {k} {timing:?}");
                            let kind = if is_status(&log[j].1) { "status" } else { "fault report" };
                            table_row(
                                &mut table,
                                &format!("{name}: {kind} of an earlier release"),
                                decode(&s, false, &what),
                            );
                        }
                    }
                }
            }
        }
    }
    print_table("Replays across releases", &table);
}

/// Delays: a genuine frame delivered late, moved 1, 2, 8 or 14 frames later with the receive
/// time of its new place (the 8–14 positions), or held back by 0.15, 0.5 or 2 s.
#[test]
fn delayed_frames_are_flagged() {
    let mut table = BTreeMap::new();
    for (name, log) in logs() {
        let ends = session_ends(&log);
        let starts = session_starts(&log);
        for kind in KINDS {
            let idx = of_kind(&log, kind);
            for p in spread(idx.len(), 12) {
                let j = idx[p];
                if starts.contains(&j) {
                    continue;
                }
                for m in [1usize, 2, 8, 14] {
                    let k = j + m;
                    // Not past the end of its recording.
                    if ends.iter().any(|&e| j <= e && e < k) || k >= log.len() {
                        continue;
                    }
                    // Only a delay in time counts: moved past frames of the same moment it is
                    // no later (the tolerances: 50 ms status, 100 ms fault report, and a session
                    // frame until the next heartbeat is due).
                    if log[k].0 < log[j].0 + tolerance(kind) {
                        continue;
                    }
                    let mut s = genuine(&log);
                    let late = s.remove(j);
                    s.insert(k, Entry { t: log[k].0, f: late.f, role: Role::Injected });
                    let what = format!("{name} frame {j} delayed by {m} frames");
                    table_row(&mut table, &format!("delayed by {m:>2} frames"), decode(&s, false, &what));
                }
                for dt in [150_000u64, 500_000, 2_000_000] {
                    if dt < tolerance(kind) {
                        continue;
                    }
                    let t = log[j].0 + dt;
                    if ends.iter().any(|&e| j <= e && log[e].0 < t) {
                        continue;
                    }
                    let mut s = genuine(&log);
                    let late = s.remove(j);
                    let at = s.iter().position(|e| e.t > t).unwrap_or(s.len());
                    s.insert(at, Entry { t, f: late.f, role: Role::Injected });
                    let what = format!("{name} frame {j} delayed by {dt} us");
                    table_row(&mut table, &format!("delayed by {:>4} ms", dt / 1000), decode(&s, false, &what));
                }
            }
        }
    }
    print_table("Delays", &table);
}

/// Deletions: a genuine frame removed; the receiver reports the loss, the frames after it are
/// accepted. (Not the last frames of a recording: nothing follows them to tell, see
/// can/README.md.)
#[test]
fn deletions_are_detected() {
    let mut table = BTreeMap::new();
    for (name, log) in logs() {
        let ends = session_ends(&log);
        let starts = session_starts(&log);
        for kind in KINDS {
            let idx = of_kind(&log, kind);
            for p in spread(idx.len(), 25) {
                let j = idx[p];
                if ends.contains(&j) || starts.contains(&j) {
                    continue;
                }
                // The session frame after the first heartbeat of a locomotive the receiver never
                // heard: nothing yet says that this sender sends them (a layout-2 sender does
                // not), so its loss cannot be seen (can/README.md).
                if kind == MessageKind::Session && starts.contains(&(j - 1)) {
                    continue;
                }
                let mut s = genuine(&log);
                s.remove(j);
                let what = format!("{name} frame {j} deleted");
                let kind = match kind {
                    MessageKind::Status => "status frame",
                    MessageKind::Fault => "fault report",
                    MessageKind::Session => "session frame",
                };
                table_row(&mut table, &format!("deleted {kind}"), decode(&s, true, &what));
            }
        }
    }
    print_table("Deletions", &table);
}

/// Insertions: random payloads under the monitor's identifiers, and frames of another
/// locomotive's recording, at random moments.
#[test]
fn insertions_are_flagged() {
    let mut table = BTreeMap::new();
    let foreign = small_log();
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    for (name, log) in logs() {
        for i in 0..60 {
            let k = 1 + (next() as usize) % (log.len() - 1);
            let id = if i % 2 == 0 { STATUS.raw_id() } else { FAULT_REPORT.raw_id() };
            let f = CanFrame::new_extended(id, &next().to_le_bytes()).unwrap();
            let timing = TIMINGS[i % 4];
            let s =
                inject_at(&log, k, f, log[k].0, if matches!(timing, Timing::Verbatim) { Timing::At } else { timing });
            table_row(&mut table, "random payload, monitor's ids", decode(&s, false, &format!("{name} random at {k}")));
            // A frame of another locomotive (the small log's first trace is locomotive 1); inside
            // the small log itself that trace is no foreign recording.
            if name != "small" {
                let g = foreign[(next() as usize) % 60].1;
                let s = inject_at(&log, k, g, log[k].0, Timing::At);
                table_row(
                    &mut table,
                    "frame of another recording",
                    decode(&s, false, &format!("{name} foreign at {k}")),
                );
            }
        }
    }
    print_table("Insertions", &table);
}

/// Reports of another locomotive whose CRC passes for the followed identity: what one of the
/// CRC's 15 identity collisions (another locomotive *and* another release at one of 15 fixed
/// distances; can/README.md) would let through to the freshness rules, and what a random
/// corruption that keeps the CRC looks like. The other recording's reports keep their content,
/// counter and time since release and are re-encoded with the identity of the status frame
/// before the insertion point, then inserted at random moments of the followed session. The CRC
/// no longer helps; the counter and time rules must flag them. Measured, with a bound.
#[test]
fn crc_passing_foreign_reports_are_flagged_by_freshness() {
    use pbm::can::codec::{decode_signals, encode_fault, frame_payload, status_link, MessageKind, Report};
    let mut x = 0xD1B5_4A32_D192_ED03u64;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let foreign_reports = |log: &Log| -> Vec<(pbm::report::FaultReport, u8)> {
        log.iter()
            .filter_map(|(_, f)| {
                let (kind, bits) = frame_payload(f).ok()?;
                if kind != MessageKind::Fault {
                    return None;
                }
                match decode_signals(kind, bits).ok()? {
                    Report::Fault(r) => Some((r, pbm::can::codec::counter_of(kind, bits) as u8)),
                    Report::Status(_) | Report::Session(_) => None,
                }
            })
            .collect()
    };
    let (small, demo) = (small_log(), demo_log());
    let mut total = Outcome::default();
    let mut table = BTreeMap::new();
    for (name, log) in logs() {
        let foreign = foreign_reports(if name == "small" { &demo } else { &small });
        assert!(!foreign.is_empty());
        for i in 0..200 {
            // A point inside a session, after its first status frame.
            let k = 1 + (next() as usize) % (log.len() - 1);
            let Some(last_status) = log[..k].iter().rev().find(|(_, f)| is_status(f)) else { continue };
            if log[k].0 - last_status.0 > 3_000_000 {
                continue; // a silence: no session to attribute the report to
            }
            let identity = match frame_payload(&last_status.1) {
                Ok((_, bits)) => status_link(bits).identity,
                Err(_) => continue,
            };
            let (report, counter) = foreign[(next() as usize) % foreign.len()];
            let f = encode_fault(&report, counter, pbm::can::Binding::young(identity));
            let timing = if i % 2 == 0 { Timing::At } else { Timing::Between };
            let o =
                decode(&inject_at(&log, k, f, log[k].0, timing), false, &format!("{name} crc-passing foreign at {k}"));
            total += o;
            table_row(&mut table, &format!("{name}: foreign report, CRC passing"), o);
        }
    }
    print_rows("CRC-passing reports of another locomotive (identity collision)", &table);
    eprintln!(
        "CRC-passing foreign reports: {} of {} flagged (or withdrawn), {} of {} genuine frames rejected",
        total.flagged, total.injected, total.rejected, total.genuine
    );
    // Measured on another seed with 15 times the insertions (8942): 8931 flagged, 11 genuine
    // frames rejected of 7.0 million (a foreign report at the very moment of the genuine one
    // and with its time since release: the genuine one is then the one flagged). The bounds
    // leave room for such coincidences and no more.
    assert!(total.injected >= 550, "{total:?}");
    assert!(total.flagged * 1000 >= total.injected * 995, "{total:?}");
    assert!(total.rejected * 100_000 <= total.genuine, "{total:?}");
}

/// Resequenced pairs: two consecutive frames of the same identifier swapped, their time stamps
/// kept in place (the bus delivered them in the other order), and, when no other frame lies
/// between them, also with the time stamps swapped along (two log lines exchanged). Lines
/// moved past other frames with their own time stamps make a log whose time goes back, which
/// no receiver sees (see can/README.md).
#[test]
fn resequenced_pairs_are_detected() {
    let mut table = BTreeMap::new();
    for (name, log) in logs() {
        let ends = session_ends(&log);
        let starts = session_starts(&log);
        for kind in KINDS {
            let idx = of_kind(&log, kind);
            for p in spread(idx.len() - 1, 20) {
                let (a, b) = (idx[p], idx[p + 1]);
                if ends.iter().any(|&e| a <= e && e < b) || starts.contains(&a) {
                    continue;
                }
                for keep_times in [false, true] {
                    if !keep_times && b != a + 1 {
                        continue;
                    }
                    let mut s = genuine(&log);
                    let (ea, eb) = (s[a], s[b]);
                    s[a] = Entry { t: if keep_times { ea.t } else { eb.t }, f: eb.f, role: Role::Paired };
                    s[b] = Entry { t: if keep_times { eb.t } else { ea.t }, f: ea.f, role: Role::Paired };
                    let what = format!("{name} pair {a},{b} keep_times {keep_times}");
                    let key = format!(
                        "swapped {} pair, {}",
                        kind_name(kind),
                        if keep_times { "times kept" } else { "times swapped" }
                    );
                    table_row(&mut table, &key, decode(&s, true, &what));
                }
            }
        }
    }
    print_table("Resequenced pairs", &table);
}

/// Patterns beyond the list: a burst of replays, a whole earlier release replayed over
/// a later one, replays after a heartbeat silence, and two recordings interleaved.
#[test]
fn further_attack_patterns() {
    let mut table = BTreeMap::new();
    for (name, log) in logs() {
        let ends = session_ends(&log);
        // Burst: 20 consecutive earlier frames injected at once, 1 ms apart.
        for k in spread(log.len() - 40, 8).into_iter().map(|k| k + 40) {
            let mut s = genuine(&log);
            for (n, j) in (k - 40..k - 20).enumerate() {
                s.insert(k + n, Entry { t: log[k].0 + n as u64 * 1000, f: log[j].1, role: Role::Injected });
            }
            table_row(&mut table, "burst of 20 replayed frames", decode(&s, false, &format!("{name} burst at {k}")));
        }
        // Replay after a silence: the genuine frames of 5 s removed (the sender held off the
        // bus), then frames from 20..40 s earlier replayed in their place at 1 s steps.
        for k in spread(log.len(), 8) {
            let t0 = log[k].0;
            if t0 < LOG_EPOCH_US + 45_000_000 || ends.iter().any(|&e| log[e].0 >= t0 && log[e].0 < t0 + 9_000_000) {
                continue;
            }
            let mut s: Vec<Entry> = genuine(&log).into_iter().filter(|e| e.t < t0 || e.t >= t0 + 5_000_000).collect();
            let old: Vec<(u64, CanFrame)> =
                log.iter().copied().filter(|(t, _)| *t >= t0 - 40_000_000 && *t < t0 - 20_000_000).collect();
            for (n, (_, f)) in old.iter().step_by(2).take(6).enumerate() {
                let t = t0 + 3_500_000 + n as u64 * 1_000_000 + 1;
                let at = s.iter().position(|e| e.t > t).unwrap_or(s.len());
                s.insert(at, Entry { t, f: *f, role: Role::Injected });
            }
            // The silence itself is a loss the receiver reports (not counted as an event).
            table_row(
                &mut table,
                "replays after a 5 s heartbeat silence",
                decode(&s, false, &format!("{name} silence at {k}")),
            );
        }
        // Two recordings interleaved: the same pipeline output of another locomotive (the
        // small log's last trace, locomotive 2), starting 3.5 s after this one.
        let other = small_log();
        let mut s = genuine(&log);
        let base = other[0].0;
        for (t, f) in other.iter().take_while(|(t, _)| *t < base + 60_000_000) {
            let t = t - base + log[0].0 + 3_500_000;
            let at = s.iter().position(|e| e.t > t).unwrap_or(s.len());
            s.insert(at, Entry { t, f: *f, role: Role::Injected });
        }
        if name != "small" {
            table_row(
                &mut table,
                "another recording interleaved (60 s)",
                decode(&s, false, &format!("{name} interleaved")),
            );
        }
    }
    // A whole earlier release replayed over a later one, aligned at its release command (the
    // same time since release), in the session log: every frame of release r shifted onto
    // release r + 1.
    let log = session_log();
    let starts: Vec<usize> = (0..log.len())
        .filter(|&i| {
            is_status(&log[i].1)
                && (i == 0 || {
                    let r = |f: &CanFrame| {
                        pbm::can::codec::status_link(u64::from_le_bytes(f.data().try_into().unwrap())).identity.release
                    };
                    let prev = (0..i).rev().find(|&p| is_status(&log[p].1)).unwrap_or(i);
                    r(&log[prev].1) != r(&log[i].1)
                })
        })
        .collect();
    for w in starts.windows(3) {
        let (a, b, c) = (w[0], w[1], w[2]);
        let shift = log[b].0 - log[a].0;
        let mut s = genuine(&log);
        for j in a..b {
            let t = log[j].0 + shift;
            if t >= log[c].0 {
                break;
            }
            // Replayed frames first among equal times (the harder case).
            let at = s.iter().position(|e| e.t >= t).unwrap_or(s.len());
            s.insert(at, Entry { t, f: log[j].1, role: Role::Injected });
        }
        table_row(&mut table, "whole earlier release replayed, aligned", decode(&s, false, &format!("release at {a}")));
    }
    print_table("Further patterns", &table);
}

/// Genuine disturbances, not attacks (the independent tester's false alarms): every single
/// fault report deleted (it found 51 of 494 such deletions getting the next unchanged report
/// rejected), one heartbeat 300 ms early, a status frame overtaking the fault report of its
/// tick, a lasting latency step of 120 ms. No genuine frame may be rejected, except the one
/// heartbeat (and at most one fault report) at a latency step, which cannot be told from a
/// delayed frame; the receiver follows the new phase from the next frame on.
#[test]
fn genuine_disturbances_reject_nothing() {
    let mut table = BTreeMap::new();
    let (mut steps, mut step_flags) = (0, 0);
    for (name, log) in logs() {
        let ends = session_ends(&log);
        let starts = session_starts(&log);
        for j in of_kind(&log, MessageKind::Fault) {
            if ends.contains(&j) || starts.contains(&j) {
                continue;
            }
            let mut s = genuine(&log);
            s.remove(j);
            table_row(&mut table, "every fault report deleted", decode(&s, true, &format!("{name} {j} deleted")));
        }
        let statuses = of_kind(&log, MessageKind::Status);
        for p in spread(statuses.len(), 40) {
            let j = statuses[p];
            if starts.contains(&j) || j + 1 >= log.len() {
                continue;
            }
            let mut s = genuine(&log);
            s[j].t = s[j].t.saturating_sub(300_000).max(if j > 0 { log[j - 1].0 } else { 0 });
            table_row(&mut table, "one heartbeat 300 ms early", decode(&s, false, &format!("{name} {j} early")));
        }
        // A status frame and the fault report of its tick swapped (the report 1 ms later).
        for j in
            (1..log.len()).filter(|&j| is_status(&log[j].1) && !is_status(&log[j - 1].1) && log[j].0 == log[j - 1].0)
        {
            let mut s = genuine(&log);
            s.swap(j - 1, j);
            s[j].t += 1_000;
            table_row(
                &mut table,
                "status frame overtakes its tick's report",
                decode(&s, false, &format!("{name} {j}")),
            );
        }
        // A latency step of 120 ms from a heartbeat on, to the end of its recording.
        for p in spread(statuses.len(), 20) {
            let j = statuses[p];
            let Some(&end) = ends.iter().find(|&&e| e >= j) else { continue };
            if starts.contains(&j) || end < j + 10 {
                continue;
            }
            let from = log[j].0;
            let mut d = Decoder::new();
            let mut o = Outcome::default();
            for (i, (t, f)) in log.iter().enumerate() {
                let t = if i >= j && i <= end { t + 120_000 } else { *t };
                let r = d.receive(t, f);
                o.genuine += 1;
                if r.result.is_err() {
                    // At most the step's heartbeat and one report, within 2.5 s of the step.
                    o.injected += 1;
                    o.flagged += 1;
                    assert!(t < from + 2_620_000, "{name} step at {j}: rejected at {t}: {r:?}");
                }
            }
            assert!(o.flagged <= 2, "{name} step at {j}: {} flagged", o.flagged);
            steps += 1;
            step_flags += o.flagged;
            o.injected = 0;
            o.flagged = 0;
            table_row(&mut table, "latency step of 120 ms (step frames not counted)", o);
        }
    }
    print_table("Genuine disturbances", &table);
    println!("latency steps: {steps}, frames flagged at the step: {step_flags} (at most 2 each)");
    let total = table.values().fold(Outcome::default(), |mut a, o| {
        a += *o;
        a
    });
    assert_eq!(total.rejected, 0, "no genuine frame rejected");
    assert_eq!(total.detected, total.events, "every deletion detected");
}
