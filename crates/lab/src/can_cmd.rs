//! CAN tools: decode CAN traffic as the cab display shows it, send a log onto a bus,
//! and write a demonstration log.
//!
//! `can decode FILE` (a candump log, `-` for stdin, or `--can-iface NAME` to listen on a
//! SocketCAN interface) prints one line per fault report: time, class label, confidence %,
//! supply pressure with a bar gauge, leak, time since release, completed. Frames with a wrong
//! CRC, a repeated, skipped or out-of-order counter, an unknown identifier, a wrong length,
//! an invalid signal value, a stale, untimely or too frequent frame (freshness, see
//! [`pbm::can::decoder`]), or log lines that are not frames, are flagged (`!!` lines) and
//! skipped; lost frames are shown too. It never stops on bad input; it ends with a summary of
//! what it flagged and exits 0; with `--strict` (for CI replays) it fails with
//! [`pbm_io::error::CHECK_FAILED_EXIT_CODE`] (4) when anything was flagged or lost, a report was
//! stale, or the log held no frame at all (an unreadable file stays exit 1). A silence of the heartbeat (status frame) longer than
//! [`pbm::can::HEARTBEAT_TIMEOUT_US`] is shown as a `--` line (the report held so far is stale
//! from then on) and the next plausible heartbeat opens a new session, so the logs of several
//! releases or locomotives written one after another (`host-sim replay DATASET --can-log`)
//! decode cleanly. Every fault report line names its locomotive and release.

use crate::simulate::{simulate, Engine};
use anyhow::{bail, Context, Result};
use pbm::can::candump::LOG_EPOCH_US;
use pbm::can::codec::{decode_signals, frame_payload, status_link, MessageKind};
use pbm::can::layout::{reason, sensor_health, ESTIMATOR_STATE_LABELS};
use pbm::can::{CanFrame, Decoder, FrameError, Identity, PowerUp, Report};
use pbm::monitor::Monitor;
use pbm::report::{FaultReport, NoDiagnosis, StatusReport, Verdict};
use pbm::sensor::{adc_from_bar, SensorFault};
use pbm::{AdcCounts, BarG, FaultClass, TwinParams};
use pbm_io::can_bus::{FrameSink, FrameSource};
use pbm_io::can_log::{format_frame, read_log, CanRecorder, CandumpWriter, LogError, DEFAULT_IFACE};
use pbm_io::error::CheckFailed;
use rand_core::SeedableRng;
use std::collections::BTreeMap;
use std::io::{BufRead, Write};
use std::path::PathBuf;

/// Output format of `can decode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum DecodeFormat {
    /// Cab display lines.
    Text,
    /// One CSV row per frame with physical values (what the cantools cross-check reads).
    Csv,
}

/// Where the cab display's frames come from and how it shows them.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodeOptions {
    /// A candump log file, `-` for standard input (or `None` with `can_iface`).
    pub file: Option<PathBuf>,
    /// Listen on this SocketCAN interface instead (Linux, built with the `socketcan` feature).
    pub can_iface: Option<String>,
    /// With `can_iface`: stop after this many seconds without a frame (`None`: never).
    pub idle_timeout: Option<f64>,
    /// Also show status/heartbeat frames.
    pub status: bool,
    /// Output format.
    pub format: DecodeFormat,
    /// Fail ([`pbm_io::error::CHECK_FAILED_EXIT_CODE`]) when anything was flagged or lost, a
    /// fault report was stale, or there was no frame to check.
    pub strict: bool,
    /// Check integrity only (identifier, length, CRC, signal values), not freshness: for codec
    /// sweeps whose frames are no stream. A fault report's CRC is checked against the identity
    /// of the last status frame (locomotive 0, release 0 before one).
    pub codec_only: bool,
}

/// What to send where.
#[derive(Debug, Clone, PartialEq)]
pub struct SendOptions {
    /// A candump log file, `-` for standard input.
    pub file: PathBuf,
    /// SocketCAN interface to send on, e.g. vcan0.
    pub can_iface: String,
    /// Keep the log's timing (sleep between frames) instead of sending as fast as possible.
    pub realtime: bool,
}

/// The demonstration log to write.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoLogOptions {
    /// Output file (`None`: standard output).
    pub out: Option<PathBuf>,
    /// Interface name written in the log.
    pub iface: String,
    /// Instead of simulated releases, sweep the codec: every diagnosis, reason, sensor and
    /// estimator code with field values at and beyond the edges of their ranges.
    pub sweep: bool,
}

impl Default for DemoLogOptions {
    fn default() -> Self {
        Self { out: None, iface: DEFAULT_IFACE.to_owned(), sweep: false }
    }
}

/// `host-sim can`.
/// Decodes a log or an interface as the cab display shows it (stdout), the summary on stderr;
/// a closed output pipe (`… | head`) ends it quietly.
pub fn decode(a: &DecodeOptions) -> Result<()> {
    match run_decode(a) {
        Err(e) if is_broken_pipe(&e) => Ok(()),
        other => other,
    }
}

// ---- cab display --------------------------------------------------------------------------

/// What `can decode` counted.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DecodeSummary {
    /// Frames (and unparseable lines) seen.
    pub frames: u64,
    /// Fault reports shown.
    pub fault_reports: u64,
    /// Status frames decoded.
    pub status_reports: u64,
    /// Session frames (release counts) decoded.
    pub session_reports: u64,
    /// Flagged and skipped, by reason label ([`FrameError::label`] or `bad_log_line`).
    pub flagged: BTreeMap<&'static str, u64>,
    /// Times the heartbeat was silent for longer than [`pbm::can::HEARTBEAT_TIMEOUT_US`] (monitor
    /// lost: restart, bus-off, gap between recordings); a new session started each time.
    pub heartbeat_losses: u64,
    /// Heartbeats (status frames) the counters show were lost (deleted, or flagged here).
    pub lost_status: u64,
    /// Fault reports the sender counted that were never accepted here.
    pub lost_fault_reports: u64,
    /// Session frames a heartbeat was due to be followed by that never came.
    pub lost_session: u64,
    /// Frames accepted in a tentative session that a continuing heartbeat then showed to be
    /// replays (counted once per superseded session).
    pub superseded: u64,
    /// Fault reports that arrived while a heartbeat was overdue or lost: shown as stale, never
    /// as current ([`pbm::can::Reception::stale`]).
    pub stale_reports: u64,
    /// Fault reports accepted, then withdrawn: not counted by the monitor's heartbeat,
    /// attributed to a release the heartbeat shows had not begun, or conflicting with a report
    /// of the same counter ([`pbm::can::Reception::withdrawn`]).
    pub withdrawn: u64,
    /// Status frames whose `FaultReportCount` the reports and counts around them showed to be
    /// corrupt (a corruption the CRC missed; [`pbm::can::Reception::count_corrupt`]).
    pub corrupt_counts: u64,
}

impl DecodeSummary {
    /// All flagged items.
    pub fn flagged_total(&self) -> u64 {
        self.flagged.values().sum()
    }

    /// Everything `--strict` fails on: flagged frames, lost frames, superseded sessions, and
    /// fault reports shown stale (no heartbeat on time vouched for them: a replay of an old
    /// session's reports after the live one ended is stale, not flagged).
    pub fn problems(&self) -> u64 {
        self.flagged_total()
            + self.lost_status
            + self.lost_fault_reports
            + self.lost_session
            + self.superseded
            + self.stale_reports
            + self.withdrawn
            + self.corrupt_counts
    }
}

impl std::fmt::Display for DecodeSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "summary: {} frames, {} fault reports, {} status frames, {} flagged and skipped",
            self.frames,
            self.fault_reports,
            self.status_reports,
            self.flagged_total()
        )?;
        if !self.flagged.is_empty() {
            let parts: Vec<String> = self.flagged.iter().map(|(k, v)| format!("{k} {v}")).collect();
            write!(f, " ({})", parts.join(", "))?;
        }
        if self.lost_status + self.lost_fault_reports > 0 {
            write!(f, "; lost: {} status frames, {} fault reports", self.lost_status, self.lost_fault_reports)?;
        }
        if self.lost_session > 0 {
            write!(f, "; lost: {} session frames", self.lost_session)?;
        }
        if self.superseded > 0 {
            write!(f, "; {} replayed sessions superseded", self.superseded)?;
        }
        if self.withdrawn > 0 {
            write!(
                f,
                "; {} fault reports withdrawn (not this monitor's: not counted by its heartbeat, or contradicted)",
                self.withdrawn
            )?;
        }
        if self.corrupt_counts > 0 {
            write!(f, "; {} status frames with a corrupt fault-report count (ignored)", self.corrupt_counts)?;
        }
        if self.stale_reports > 0 {
            write!(
                f,
                "; {} fault reports shown stale (heartbeat overdue or not yet heard, a time earlier than the reports before, or a restart that cannot be vouched for)",
                self.stale_reports
            )?;
        }
        if self.heartbeat_losses > 0 {
            write!(f, "; heartbeat lost {} times", self.heartbeat_losses)?;
        }
        if self.session_reports > 0 {
            write!(f, "; {} session frames (release counts)", self.session_reports)?;
        }
        Ok(())
    }
}

/// Label of a verdict as shown on the display (the DBC value labels).
pub fn verdict_label(v: &Verdict) -> String {
    match v {
        Verdict::Class { class, .. } => class.label().to_owned(),
        Verdict::CannotDiagnose(why) => format!("cannot_diagnose ({})", reason_label(*why)),
    }
}

fn reason_label(why: NoDiagnosis) -> &'static str {
    let code = pbm::can::codec::reason_code(why);
    reason::LABELS.get(usize::from(code)).copied().unwrap_or("?")
}

fn sensor_label(s: Option<SensorFault>) -> &'static str {
    let code = s.map_or(sensor_health::OK, SensorFault::code);
    sensor_health::LABELS.get(usize::from(code)).copied().unwrap_or("?")
}

/// Calibrated confidence in percent.
pub fn confidence_pct(v: &Verdict) -> Option<f64> {
    match v {
        Verdict::Class { confidence_pct, .. } => Some(f64::from(*confidence_pct)),
        Verdict::CannotDiagnose(_) => None,
    }
}

/// A 10-cell gauge of the supply pressure over 0..10 bar g.
pub fn supply_gauge(bar: f64) -> String {
    let cells = (bar.clamp(0.0, 10.0)).round() as usize;
    format!("[{}{}]", "#".repeat(cells), ".".repeat(10 - cells))
}

/// Seconds (relative to the start of the input, see [`CabDisplay`]) as `  SSSS.mmm`.
fn time_text(time_us: u64) -> String {
    format!("{:>6}.{:03}", time_us / 1_000_000, (time_us % 1_000_000) / 1000)
}

/// Which locomotive and release a report belongs to, as the display shows it.
pub fn identity_text(id: Option<Identity>) -> String {
    match id {
        Some(id) => format!("loco {:>2} release {:>2}", id.locomotive, id.release),
        None => "loco  ? release  ?".to_owned(),
    }
}

/// One cab display line for a fault report of locomotive and release `id`.
pub fn fault_line(time_us: u64, id: Option<Identity>, r: &FaultReport) -> String {
    let supply = f64::from(r.supply_mbar) / 1000.0;
    let conf = confidence_pct(&r.verdict).map_or_else(|| " --".to_owned(), |p| format!("{p:>3.0}"));
    // 0 means "not estimated yet" (FaultReport::supply_mbar).
    let supply_txt = if r.supply_mbar == 0 { "  --  ".to_owned() } else { format!("{supply:>6.3}") };
    format!(
        "{} s  {}  {:<38} conf {conf} %  supply {supply_txt} bar {}  leak {:>5.3} mm  release +{:>5.1} s  {}",
        time_text(time_us),
        identity_text(id),
        verdict_label(&r.verdict),
        supply_gauge(supply),
        f64::from(r.leak_um) / 1000.0,
        f64::from(r.time_since_release_cs) / 100.0,
        if r.release_completed { "completed" } else { "in progress" }
    )
}

/// One display line for a status frame of locomotive and release `id`.
pub fn status_line(time_us: u64, id: Option<Identity>, s: &StatusReport) -> String {
    format!(
        "{} s  {}  status: sensor {}  estimator {}  pressure {:.3} bar  firmware {}.{}",
        time_text(time_us),
        identity_text(id),
        sensor_label(s.sensor_fault),
        ESTIMATOR_STATE_LABELS.get(s.estimator as usize).copied().unwrap_or("?"),
        f64::from(s.pressure_mbar) / 1000.0,
        s.version.0,
        s.version.1
    )
}

/// Why a status frame or fault report of a refuted session ([`pbm::can::Reception::refuted`])
/// is not shown as the locomotive's live state.
const REFUTED_TEXT: &str = "not current: this session's session frame was refuted (another unit with this number modulo 64, an old recording, or a count further on than the time since allows: a replaced unit or a corruption) and none of the locomotive's own has vouched for it";

/// Header of the CSV output of `can decode --format csv`.
pub const CSV_HEADER: &str = "time_us,id,data,message,counter,Diagnosis,Confidence,NoDiagnosisReason,\
ReleaseCompleted,TimeSinceRelease,SupplyPressure,LeakDiameter,SensorHealth,EstimatorState,ChamberPressure,\
FirmwareMajor,FirmwareMinor,Locomotive,ReleaseNumber,FaultReportCount,ReleaseCount,flag";

fn csv_row(
    time_us: u64,
    frame: &CanFrame,
    counter: Option<u16>,
    report: Option<(&Report, Option<Identity>, Option<u8>)>,
    release_count: Option<u32>,
    flag: &str,
) -> String {
    let (id, data) = match format_frame(frame).split_once('#') {
        Some((i, d)) => (i.to_owned(), d.to_owned()),
        None => (String::new(), String::new()),
    };
    let counter = counter.map_or_else(String::new, |c| c.to_string());
    let release_count = release_count.map_or_else(String::new, |c| c.to_string());
    let ident = |id: Option<Identity>, count: Option<u8>| match id {
        Some(id) => format!(
            "{},{},{},{release_count}",
            id.locomotive,
            id.release,
            count.map_or_else(String::new, |c| c.to_string())
        ),
        None => format!(",,,{release_count}"),
    };
    let cols = match report {
        Some((Report::Fault(r), id, count)) => {
            let (diag, reason_txt) = match r.verdict {
                Verdict::Class { class, .. } => (class.label().to_owned(), "none".to_owned()),
                Verdict::CannotDiagnose(why) => ("cannot_diagnose".to_owned(), reason_label(why).to_owned()),
            };
            format!(
                "BPM_FaultReport,{counter},{diag},{},{reason_txt},{},{},{},{},,,,,,{}",
                confidence_pct(&r.verdict).unwrap_or(0.0),
                if r.release_completed { "completed" } else { "in_progress" },
                f64::from(r.time_since_release_cs) / 100.0,
                f64::from(r.supply_mbar) / 1000.0,
                f64::from(r.leak_um) / 1000.0,
                ident(id, count),
            )
        }
        Some((Report::Status(s), id, count)) => format!(
            "BPM_Status,{counter},,,,,,,,{},{},{},{},{},{}",
            sensor_label(s.sensor_fault),
            ESTIMATOR_STATE_LABELS.get(s.estimator as usize).copied().unwrap_or("?"),
            f64::from(s.pressure_mbar) / 1000.0,
            s.version.0,
            s.version.1,
            ident(id, count),
        ),
        Some((Report::Session(link), ..)) => {
            format!("BPM_Session,{counter},,,,,,,,,,,,,{},{},,{}", link.locomotive, link.release(), link.release_count)
        }
        None => format!(",{counter},,,,,,,,,,,,,,,,"),
    };
    format!("{time_us},{id},{data},{cols},{flag}")
}

/// The cab display: a [`Decoder`] plus the printing and counting of `can decode`. Times are
/// shown relative to the first frame (logs carry absolute, epoch-based stamps).
pub struct CabDisplay<W: Write> {
    decoder: Decoder,
    out: W,
    show_status: bool,
    format: DecodeFormat,
    summary: DecodeSummary,
    codec_only: bool,
    /// Identity of the last status frame (codec-only mode).
    codec_identity: Identity,
    /// Fleet number and release count of the last session frame (codec-only mode): a fault
    /// report's CRC binds them (layout 3.2).
    codec_binding: Option<pbm::can::Binding>,
    start_us: Option<u64>,
    /// Receive time, locomotive and release of the fault report held on the display.
    held: Option<(u64, Option<Identity>)>,
    /// For the last accepted fault reports (up to 16), what was held before each: a withdrawal
    /// ([`pbm::can::Reception::withdrawn`]) goes back to it.
    held_before: std::collections::VecDeque<Option<(u64, Option<Identity>)>>,
    /// Receive time of the last fault report accepted, shown stale or not (what a withdrawal
    /// names when the withdrawn report was shown stale and never held).
    last_report_us: Option<u64>,
    /// What the display held, and the losses counted, when the receive clock last jumped ahead
    /// ([`pbm::can::Reception::clock_jumped`]): back when the decoder undoes the jump.
    held_at_jump: Option<AtJump>,
}

/// The report held on the display, what was held before each of the last ones, and the lost
/// (status frames, fault reports, heartbeats) counted.
type AtJump =
    (Option<(u64, Option<Identity>)>, std::collections::VecDeque<Option<(u64, Option<Identity>)>>, (u64, u64, u64));

impl<W: Write> CabDisplay<W> {
    /// A display printing to `out`.
    pub fn new(out: W, show_status: bool, format: DecodeFormat) -> Self {
        Self {
            decoder: Decoder::new(),
            out,
            show_status,
            format,
            summary: DecodeSummary::default(),
            codec_only: false,
            codec_identity: Identity::default(),
            codec_binding: None,
            start_us: None,
            held: None,
            held_before: std::collections::VecDeque::new(),
            last_report_us: None,
            held_at_jump: None,
        }
    }

    /// Integrity checks only, no freshness (see [`DecodeOptions::codec_only`]).
    pub fn codec_only(mut self, yes: bool) -> Self {
        self.codec_only = yes;
        self
    }

    /// Writes the CSV header (CSV format only).
    pub fn header(&mut self) -> std::io::Result<()> {
        if self.format == DecodeFormat::Csv {
            writeln!(self.out, "{CSV_HEADER}")?;
        }
        Ok(())
    }

    fn rel(&self, time_us: u64) -> u64 {
        time_us.saturating_sub(self.start_us.unwrap_or(time_us))
    }

    /// What the stateless codec makes of a frame (codec-only mode).
    fn codec_decode(&mut self, frame: &CanFrame) -> pbm::can::Reception {
        let result = frame_payload(frame).and_then(|(kind, bits)| {
            // The binding of the last session frame of the locomotive, at the release number the
            // last status frame carried; before any: a young unit's (numbers below 64).
            let id = self.codec_identity;
            let binding = self
                .codec_binding
                .filter(|b| b.identity().locomotive == id.locomotive)
                .map_or(pbm::can::Binding::young(id), |b| b.for_release(id.release));
            pbm::can::codec::check_crc(kind, bits, binding)?;
            let report = decode_signals(kind, bits)?;
            match kind {
                MessageKind::Status => self.codec_identity = status_link(bits).identity,
                MessageKind::Session => {
                    let link = pbm::can::codec::session_link(bits);
                    self.codec_binding =
                        Some(pbm::can::Binding { fleet: link.locomotive, release_count: link.release_count });
                }
                MessageKind::Fault => {}
            }
            Ok(report)
        });
        pbm::can::Reception::plain(result, Some(self.codec_identity))
    }

    /// Feeds one received frame.
    pub fn frame(&mut self, time_us: u64, frame: &CanFrame) -> std::io::Result<Result<Report, FrameError>> {
        self.summary.frames += 1;
        let start = *self.start_us.get_or_insert(time_us);
        let t = time_us.saturating_sub(start);
        let payload = frame_payload(frame).ok();
        let counter = payload.map(|(kind, bits)| pbm::can::codec::counter_of(kind, bits));
        let count = payload.filter(|(k, _)| *k == MessageKind::Status).map(|(_, bits)| status_link(bits).fault_count);
        let reception = if self.codec_only { self.codec_decode(frame) } else { self.decoder.receive(time_us, frame) };
        let text = self.format == DecodeFormat::Text;
        if let Some(back_us) = reception.clock_back_us {
            *self.summary.flagged.entry("clock_back").or_default() += 1;
            if let Some((held, before, lost)) = self.held_at_jump.take() {
                (self.held, self.held_before) = (held, before);
                // The losses the jump claimed were none.
                (self.summary.lost_status, self.summary.lost_fault_reports, self.summary.heartbeat_losses) = lost;
            }
            if text {
                writeln!(
                    self.out,
                    "{} s  !! clock_back: this frame is stamped {:.3} s before the frame that ended the last silence: the stamps since were wrong (a logger glitch) or the receive clock went back; what was accepted since is undone, and frames are judged as before the silence",
                    time_text(t),
                    back_us as f64 / 1e6
                )?;
            }
        }
        if reception.clock_jumped {
            let lost = (self.summary.lost_status, self.summary.lost_fault_reports, self.summary.heartbeat_losses);
            self.held_at_jump = Some((self.held, self.held_before.clone(), lost));
        }
        if let Some(silence_us) = reception.heartbeat_lost_us {
            self.summary.heartbeat_losses += 1;
            if text {
                let held = match self.held.take() {
                    Some((at, id)) => format!(
                        "; the report of {} (at {} s) is stale",
                        identity_text(id),
                        time_text(self.rel(at)).trim_start()
                    ),
                    None => String::new(),
                };
                writeln!(
                    self.out,
                    "{} s  -- no heartbeat for {:.1} s: monitor lost (restart or gap){held}",
                    time_text(t),
                    silence_us as f64 / 1e6
                )?;
            }
        }
        if reception.superseded {
            self.summary.superseded += 1;
            if text {
                writeln!(
                    self.out,
                    "{} s  !! superseded: the session opened after the silence was a replay; the monitor never restarted",
                    time_text(t)
                )?;
            }
        }
        if reception.withdrawn > 0 {
            self.summary.withdrawn += u64::from(reception.withdrawn);
            let mut back = None;
            for _ in 0..reception.withdrawn {
                if let Some(h) = self.held_before.pop_back() {
                    back = Some(h);
                }
            }
            let first = self.held;
            if let Some(h) = back {
                self.held = h;
            }
            if text {
                let shown = match self.held {
                    Some((at, id)) => {
                        format!(
                            "the report of {} (at {} s) is shown again",
                            identity_text(id),
                            time_text(self.rel(at)).trim_start()
                        )
                    }
                    None => "no report is shown".to_owned(),
                };
                let why = if matches!(reception.result, Err(pbm::can::FrameError::Conflicting { .. })) {
                    "with the counter of the report just refused as conflicting (one of the two is another sender's, whose \
                     CRC happens to fit)"
                } else if reception.withdrawn_next_release {
                    "attributed to the next release, which this heartbeat shows had not begun (another sender's, whose \
                     CRC happens to fit)"
                } else {
                    "that the monitor's heartbeat does not count (not sent by it)"
                };
                writeln!(
                    self.out,
                    "{} s  !! withdrawn: {} fault report(s) up to {} s {why}; {shown}",
                    time_text(t),
                    reception.withdrawn,
                    first
                        .map(|(at, _)| at)
                        .or(self.last_report_us)
                        .map_or_else(|| "-".to_owned(), |at| time_text(self.rel(at)).trim_start().to_owned())
                )?;
            }
        }
        // Held reports are decided by a heartbeat (after a silence), or by a session frame (its
        // release count, layout 3.2).
        let decider =
            if matches!(reception.result, Ok(Report::Session(_))) { "this session frame" } else { "this heartbeat" };
        if reception.unattributed_fitting > 0 && text {
            writeln!(
                self.out,
                "{} s  -- {} fault report(s) heard before {decider} fit it ({}): past reports, not current",
                time_text(t),
                reception.unattributed_fitting,
                identity_text(reception.identity)
            )?;
        }
        if reception.unattributed_rejected > 0 {
            *self.summary.flagged.entry("unattributed").or_default() += u64::from(reception.unattributed_rejected);
            if text {
                writeln!(
                    self.out,
                    "{} s  !! unattributed: {} fault report(s) heard before {decider} do not fit it (not the monitor's): dropped",
                    time_text(t),
                    reception.unattributed_rejected
                )?;
            }
        }
        if reception.two_streams && text && matches!(reception.result, Ok(Report::Status(_)) | Err(_)) {
            writeln!(
                self.out,
                "{} s  !! two streams: this heartbeat continues the session from before the re-lock at its old phase (a recording running ahead of the live monitor, or a second path); no fault report is current until one of them stops",
                time_text(t)
            )?;
        }
        if let (Some(step_ms), true) = (reception.relocked_ms, text) {
            writeln!(
                self.out,
                "{} s  !! re-locked: the heartbeat phase stepped {step_ms:+} ms (a clock step of the receiver or a bus latency that began or ended); frames are judged at the new phase",
                time_text(t)
            )?;
        }
        if reception.count_corrupt {
            self.summary.corrupt_counts += 1;
            if text {
                writeln!(
                    self.out,
                    "{} s  !! the last status frame's fault-report count contradicted the reports before and after it: a corruption the CRC missed, ignored",
                    time_text(t)
                )?;
            }
        }
        if reception.lost_session {
            self.summary.lost_session += 1;
            if text {
                writeln!(
                    self.out,
                    "{} s  !! lost before this frame: the session frame due after the heartbeat before",
                    time_text(t)
                )?;
            }
        }
        if reception.lost_status > 0 || reception.lost_fault_reports > 0 {
            self.summary.lost_status += u64::from(reception.lost_status);
            self.summary.lost_fault_reports += u64::from(reception.lost_fault_reports);
            if text {
                let held = if reception.lost_fault_reports > 0 && self.held.is_some() {
                    "; the report shown is stale"
                } else {
                    ""
                };
                writeln!(
                    self.out,
                    "{} s  !! lost before this frame: {} status frames, {} fault reports{held}",
                    time_text(t),
                    reception.lost_status,
                    reception.lost_fault_reports
                )?;
            }
        }
        let id = reception.identity;
        let result = reception.result;
        match (&result, self.format) {
            (Ok(Report::Fault(r)), DecodeFormat::Text) if reception.stale => {
                // No live heartbeat vouches for it: shown, never as the current report.
                self.summary.fault_reports += 1;
                self.summary.stale_reports += 1;
                self.last_report_us = Some(time_us);
                let why = if reception.awaiting_count {
                    "not current: its CRC binds the locomotive's release count, not heard yet (a display that joined a session under way); the next session frame, at most 10 s on, decides"
                        .to_owned()
                } else if reception.unattributed {
                    "stale: no heartbeat attributes it yet (after a silence, or a session resting on one frame); the next heartbeat decides"
                        .to_owned()
                } else if reception.relock_unconfirmed {
                    "not current: the receiver re-locked less than a heartbeat period ago; the next heartbeat shows whether a stream is still at the old phase"
                        .to_owned()
                } else if reception.two_streams {
                    "not current: two streams of this locomotive are on the bus (see the `two streams` line); the receiver cannot tell which is live"
                        .to_owned()
                } else if reception.delayed_stream {
                    "stale: the stream is delayed beyond the latency step against its first heartbeat".to_owned()
                } else if reception.early {
                    "not current: sent earlier than the reports before it place it; the next report decides".to_owned()
                } else if reception.refuted {
                    REFUTED_TEXT.to_owned()
                } else if reception.release_unconfirmed {
                    "not current: no session frame has given this session's release count yet, and this locomotive's is known: a restart, or a session heard after a silence, cannot be told from a recording of one 64 releases earlier until it does"
                        .to_owned()
                } else if reception.restart_jump > 0 {
                    format!(
                        "not current: a restart {} releases on, which cannot be told from an old recording",
                        reception.restart_jump
                    )
                } else {
                    "stale: heartbeat overdue".to_owned()
                };
                writeln!(self.out, "{}  [{why}]", fault_line(t, id, r))?;
            }
            (Ok(Report::Fault(r)), DecodeFormat::Text) => {
                self.summary.fault_reports += 1;
                if self.held_before.len() == 16 {
                    self.held_before.pop_front();
                }
                self.held_before.push_back(self.held);
                self.held = Some((time_us, id));
                self.last_report_us = Some(time_us);
                writeln!(self.out, "{}", fault_line(t, id, r))?;
            }
            (Ok(Report::Status(s)), DecodeFormat::Text) => {
                self.summary.status_reports += 1;
                if self.show_status {
                    if reception.refuted {
                        writeln!(self.out, "{}  [{REFUTED_TEXT}]", status_line(t, id, s))?;
                    } else {
                        writeln!(self.out, "{}", status_line(t, id, s))?;
                    }
                }
            }
            (Ok(Report::Session(link)), DecodeFormat::Text) => {
                self.summary.session_reports += 1;
                if self.show_status {
                    writeln!(
                        self.out,
                        "{} s  {}  session: release count {}",
                        time_text(t),
                        identity_text(id),
                        link.release_count
                    )?;
                }
            }
            (Ok(report), DecodeFormat::Csv) => {
                match report {
                    Report::Fault(_) => self.summary.fault_reports += 1,
                    Report::Status(_) => self.summary.status_reports += 1,
                    Report::Session(_) => self.summary.session_reports += 1,
                }
                let row = csv_row(time_us, frame, counter, Some((report, id, count)), reception.release_count, "");
                writeln!(self.out, "{row}")?;
            }
            (Err(e), DecodeFormat::Text) => {
                *self.summary.flagged.entry(e.label()).or_default() += 1;
                writeln!(self.out, "{} s  !! {}: {e} [{}] skipped", time_text(t), e.label(), format_frame(frame))?;
            }
            (Err(e), DecodeFormat::Csv) => {
                *self.summary.flagged.entry(e.label()).or_default() += 1;
                writeln!(self.out, "{}", csv_row(time_us, frame, counter, None, None, e.label()))?;
            }
        }
        Ok(result)
    }

    /// Feeds a log line that is not a frame.
    pub fn bad_line(&mut self, e: &LogError) -> std::io::Result<()> {
        self.summary.frames += 1;
        *self.summary.flagged.entry("bad_log_line").or_default() += 1;
        match self.format {
            DecodeFormat::Text => writeln!(self.out, "           !! bad_log_line: {e} skipped"),
            DecodeFormat::Csv => writeln!(self.out, ",,,,,,,,,,,,,,,,,,,,,bad_log_line"),
        }
    }

    /// What was counted so far.
    pub fn summary(&self) -> &DecodeSummary {
        &self.summary
    }

    /// Ends the display and returns its counts.
    pub fn finish(mut self) -> std::io::Result<DecodeSummary> {
        // A fault report the last status frame counted that never came (it may have been
        // overtaken by that frame, so it was owed, not yet lost).
        let owed = self.decoder.owed_fault_reports();
        if owed > 0 && !self.codec_only {
            self.summary.lost_fault_reports += u64::from(owed);
            if self.format == DecodeFormat::Text {
                writeln!(
                    self.out,
                    "           !! lost at the end: {owed} fault reports the last status frame counted"
                )?;
            }
        }
        self.out.flush()?;
        Ok(self.summary)
    }
}

/// Decodes a candump log into a display; returns the summary.
pub fn decode_log<R: BufRead, W: Write>(reader: R, display: &mut CabDisplay<W>) -> std::io::Result<()> {
    display.header()?;
    for item in read_log(reader) {
        match item {
            Ok(rec) => {
                // Flagged frames are counted and printed by the display; only I/O errors stop.
                let _report = display.frame(rec.time_us, &rec.frame)?;
            }
            Err(e) => display.bad_line(&e)?,
        }
    }
    Ok(())
}

/// Decodes everything a frame source delivers into a display.
pub fn decode_source<W: Write>(source: &mut impl FrameSource, display: &mut CabDisplay<W>) -> std::io::Result<()> {
    display.header()?;
    while let Some((t, f)) = source.recv()? {
        let _report = display.frame(t, &f)?;
    }
    Ok(())
}

fn run_decode(a: &DecodeOptions) -> Result<()> {
    let stdout = std::io::stdout();
    let mut display =
        CabDisplay::new(std::io::BufWriter::new(stdout.lock()), a.status, a.format).codec_only(a.codec_only);
    if let Some(iface) = &a.can_iface {
        if a.file.is_some() {
            bail!("give either a FILE or --can-iface, not both");
        }
        listen(iface, a.idle_timeout, &mut display)?;
    } else {
        match a.file.as_deref() {
            Some(p) if p.as_os_str() == "-" => decode_log(std::io::stdin().lock(), &mut display)?,
            Some(p) => {
                let f = pbm_io::files::open_regular(p)?;
                decode_log(std::io::BufReader::new(f), &mut display)?;
            }
            None => bail!("give a candump log FILE (or - for stdin) or --can-iface NAME"),
        }
    }
    let summary = display.finish()?;
    eprintln!("{summary}");
    if a.strict {
        if summary.frames == 0 {
            return Err(CheckFailed("--strict: the log holds no frame, so nothing was checked".into()).into());
        }
        if summary.problems() > 0 {
            return Err(CheckFailed(format!(
                "--strict: {} frames flagged, {} status frames and {} fault reports lost, {} replayed sessions, {} stale and {} withdrawn fault reports, {} corrupt fault-report counts",
                summary.flagged_total(),
                summary.lost_status,
                summary.lost_fault_reports,
                summary.superseded,
                summary.stale_reports,
                summary.withdrawn,
                summary.corrupt_counts
            ))
            .into());
        }
    }
    Ok(())
}

/// `true` for the error a closed pipe gives (`host-sim can decode log | head`): not a failure.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| c.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe))
}

#[cfg(all(feature = "socketcan", target_os = "linux"))]
fn listen<W: Write>(iface: &str, idle_timeout: Option<f64>, display: &mut CabDisplay<W>) -> Result<()> {
    let mut bus = pbm_io::can_bus::socket::SocketBus::open(iface)?;
    if let Some(t) = idle_timeout {
        if !(t.is_finite() && t > 0.0) {
            bail!("--idle-timeout must be a positive number of seconds");
        }
        bus.idle_timeout = Some(std::time::Duration::from_secs_f64(t));
    }
    decode_source(&mut bus, display)?;
    Ok(())
}

#[cfg(not(all(feature = "socketcan", target_os = "linux")))]
fn listen<W: Write>(iface: &str, _idle_timeout: Option<f64>, _display: &mut CabDisplay<W>) -> Result<()> {
    bail!("--can-iface {iface}: this host-sim was built without SocketCAN (build with `--features socketcan` on Linux)")
}

/// Sends the frames of a candump log onto a CAN interface.
pub fn send(a: &SendOptions) -> Result<()> {
    let reader: Box<dyn BufRead> = if a.file.as_os_str() == "-" {
        Box::new(std::io::BufReader::new(std::io::stdin()))
    } else {
        let f = pbm_io::files::open_regular(&a.file)?;
        Box::new(std::io::BufReader::new(f))
    };
    let mut sink = open_sink(&a.can_iface)?;
    let (sent, bad) = send_log(reader, &mut *sink, a.realtime)?;
    eprintln!("sent {sent} frames on {}; {bad} log lines skipped", a.can_iface);
    Ok(())
}

/// Sends every frame of a candump log to a sink (optionally keeping the log's timing); bad
/// lines are reported on stderr and skipped. Returns (frames sent, lines skipped).
pub fn send_log(reader: impl BufRead, sink: &mut dyn FrameSink, realtime: bool) -> Result<(u64, u64)> {
    let (mut sent, mut bad) = (0u64, 0u64);
    let start = std::time::Instant::now();
    let mut first_us = None;
    for item in read_log(reader) {
        match item {
            Ok(rec) => {
                if realtime {
                    let t0 = *first_us.get_or_insert(rec.time_us);
                    let due = std::time::Duration::from_micros(rec.time_us.saturating_sub(t0));
                    if let Some(wait) = due.checked_sub(start.elapsed()) {
                        std::thread::sleep(wait);
                    }
                }
                sink.send(rec.time_us, &rec.frame)?;
                sent += 1;
            }
            Err(e) => {
                eprintln!("skipped: {e}");
                bad += 1;
            }
        }
    }
    Ok((sent, bad))
}

/// Opens a SocketCAN interface as a frame sink.
#[cfg(all(feature = "socketcan", target_os = "linux"))]
pub fn open_sink(iface: &str) -> Result<Box<dyn FrameSink>> {
    Ok(Box::new(pbm_io::can_bus::socket::SocketBus::open(iface)?))
}

/// Opens a SocketCAN interface as a frame sink (not available in this build).
#[cfg(not(all(feature = "socketcan", target_os = "linux")))]
pub fn open_sink(iface: &str) -> Result<Box<dyn FrameSink>> {
    bail!("--can-iface {iface}: this host-sim was built without SocketCAN (build with `--features socketcan` on Linux)")
}

// ---- demonstration log --------------------------------------------------------------------

/// One scripted release of the demonstration log.
struct DemoRelease {
    params: TwinParams,
    /// Seconds the valve stays open.
    open_s: f64,
    /// Verdict from this time on (s since the release command), if any.
    verdict: Option<(f64, Verdict)>,
    /// ADC override windows (from s, to s, counts): sensor faults.
    sensor_faults: &'static [(f64, f64, u16)],
}

fn demo_releases() -> Vec<DemoRelease> {
    let nominal = TwinParams::nominal();
    let class = |c: FaultClass, confidence_pct: u8| Some((12.0, Verdict::Class { class: c, confidence_pct }));
    vec![
        DemoRelease { params: nominal, open_s: 40.0, verdict: class(FaultClass::Normal, 98), sensor_faults: &[] },
        DemoRelease {
            params: nominal.with_leak_mm(0.8),
            open_s: 40.0,
            verdict: class(FaultClass::AirLeak, 80),
            sensor_faults: &[],
        },
        DemoRelease {
            params: nominal.with_orifice_mm(0.6),
            open_s: 60.0,
            verdict: class(FaultClass::OrificeBlock, 75),
            sensor_faults: &[],
        },
        DemoRelease {
            params: nominal.with_orifice_mm(0.7).with_leak_mm(0.9),
            open_s: 60.0,
            verdict: class(FaultClass::LeakAndBlock, 50),
            sensor_faults: &[],
        },
        DemoRelease {
            params: nominal.with_supply_bar_g(5.0),
            open_s: 40.0,
            verdict: class(FaultClass::LowSupply, 99),
            sensor_faults: &[],
        },
        DemoRelease {
            params: nominal.with_orifice_mm(3.0),
            open_s: 20.0,
            verdict: Some((4.0, Verdict::Class { class: FaultClass::OrificeMissing, confidence_pct: 1 })),
            sensor_faults: &[],
        },
        DemoRelease {
            params: nominal,
            open_s: 30.0,
            verdict: None,
            sensor_faults: &[(10.0, 12.0, 0), (20.0, 21.0, 4095)],
        },
        DemoRelease {
            params: nominal,
            open_s: 5.0,
            verdict: Some((4.5, Verdict::CannotDiagnose(NoDiagnosis::TooShort))),
            sensor_faults: &[],
        },
        DemoRelease {
            params: nominal.with_leak_mm(2.0),
            open_s: 40.0,
            verdict: Some((20.0, Verdict::CannotDiagnose(NoDiagnosis::Unfamiliar))),
            sensor_faults: &[],
        },
    ]
}

/// Locomotive number of the demonstration log's monitor.
pub const DEMO_LOCOMOTIVE: u8 = 7;

/// Seconds the valve stays closed between demonstration releases.
const DEMO_IDLE_S: f64 = 3.0;

/// Writes the demonstration log to a sink: each release simulated with the fixed-point twin,
/// read through the sensor map, fed to one [`Monitor`] and one [`CanRecorder`] (status and
/// estimates are the monitor's; verdicts are scripted, the classifier is not in this loop).
/// During a sensor fault the verdict is `cannot_diagnose (sensor_…)`. Returns frames sent.
pub fn write_demo_log<S: FrameSink>(sink: S) -> Result<(u64, S)> {
    let mut monitor = Monitor::new(&TwinParams::nominal()).map_err(|e| anyhow::anyhow!("nominal twin: {e}"))?;
    let mut rec =
        CanRecorder::with_identity(sink, PowerUp { locomotive: u16::from(DEMO_LOCOMOTIVE), release_count: 0 });
    let mut sample: u64 = 0;
    let mut frames = 0u64;
    // Transducer noise (SPEC §5, σ = 0.01 bar) from a fixed seed: a noise-free reading would
    // be a frozen sensor on the status frame.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2023);
    let mut noisy_adc = move |p: f64| adc_from_bar(BarG(p + 0.01 * crate::random::normal_pair(&mut rng).0));
    for r in demo_releases() {
        let trace = simulate(Engine::Fixed, &r.params, r.open_s).map_err(|e| anyhow::anyhow!("demo twin: {e}"))?;
        let mut verdict: Option<Verdict> = None;
        let idle = crate::simulate::sample_count(DEMO_IDLE_S);
        for i in 0..trace.len() + idle {
            let open = i < trace.len();
            let t_rel = i as f64 * pbm::twin::SAMPLE_PERIOD_S;
            let mut adc = noisy_adc(trace.get(i).map_or(0.0, |s| s.p_bar));
            if let Some(&(_, _, counts)) = r.sensor_faults.iter().find(|(a, b, _)| (*a..*b).contains(&t_rel)) {
                adc = AdcCounts(counts);
            }
            let step = monitor.update(adc, open);
            if let Err(fault) = step.measured {
                verdict = Some(Verdict::CannotDiagnose(NoDiagnosis::SensorFault(fault)));
            } else if let Some((from, v)) = r.verdict {
                if t_rel + 1e-9 >= from {
                    verdict = Some(v);
                }
            }
            // The display holds the last report after the release; nothing new is reported
            // while the valve is closed.
            let current = if open { verdict } else { None };
            frames += rec.on_sample(LOG_EPOCH_US + sample * 10_000, &monitor, current, open)? as u64;
            sample += 1;
        }
    }
    Ok((frames, rec.into_sink()))
}

/// Writes the codec sweep: fault reports for every verdict (each class at confidences 0, 1,
/// 50, 99, 100 % and every cannot-diagnose reason) with time, supply and leak at 0, one step,
/// mid-range, the top of the range and beyond (saturating); status frames for every sensor and
/// estimator code with pressures 0, 1, 7700, 16383 and 65535 mbar (saturating), locomotive,
/// release and count fields over their ranges. Counters run on per message, frames are 10 ms
/// apart: a codec sweep, not a stream (decode it with `--codec-only`). Returns frames sent.
pub fn write_codec_sweep<S: FrameSink>(mut sink: S) -> Result<(u64, S)> {
    use pbm::can::{encode_fault, encode_session, encode_status, SessionLink, StatusLink};
    use pbm::report::EstimatorState;
    let mut verdicts: Vec<Verdict> = Vec::new();
    for class in FaultClass::ALL {
        for confidence_pct in [0, 1, 50, 99, 100] {
            verdicts.push(Verdict::Class { class, confidence_pct });
        }
    }
    let reasons = SensorFault::ALL.map(NoDiagnosis::SensorFault);
    for why in reasons.into_iter().chain([NoDiagnosis::TooShort, NoDiagnosis::Unfamiliar]) {
        verdicts.push(Verdict::CannotDiagnose(why));
    }
    let times: [u16; 6] = [0, 10, 6_000, 40_950, 40_951, u16::MAX];
    let supplies: [u16; 6] = [0, 5, 7_700, 20_475, 20_478, u16::MAX];
    let leaks: [u16; 6] = [0, 1, 850, 4_095, 4_096, u16::MAX];
    let (mut n, mut fault_counter, mut status_counter) = (0u64, 0u8, 0u16);
    for (i, verdict) in verdicts.iter().enumerate() {
        for k in 0..times.len() {
            let r = FaultReport {
                verdict: *verdict,
                time_since_release_cs: times[k],
                supply_mbar: supplies[(k + i) % supplies.len()],
                leak_um: leaks[(k + 2 * i) % leaks.len()],
                release_completed: (i + k) % 2 == 1,
            };
            sink.send(LOG_EPOCH_US + n * 10_000, &encode_fault(&r, fault_counter, pbm::can::Binding::default()))?;
            fault_counter = (fault_counter + 1) & 0xF;
            n += 1;
        }
    }
    let states = [EstimatorState::Idle, EstimatorState::Converging, EstimatorState::Settled, EstimatorState::Frozen];
    let healths = core::iter::once(None).chain(SensorFault::ALL.map(Some));
    for (i, sensor_fault) in healths.enumerate() {
        for (j, estimator) in states.into_iter().enumerate() {
            for (k, pressure_mbar) in [0u16, 1, 7_700, 16_383, u16::MAX].into_iter().enumerate() {
                let version = [(0, 0), (0, 1), (15, 15), (255, 255), (12, 3)][(i + j + k) % 5];
                let s = StatusReport { sensor_fault, estimator, pressure_mbar, version };
                // Locomotive, release number and fault-report count over their whole ranges.
                let m = (i * 20 + j * 5 + k) as u8;
                let identity = Identity { locomotive: m.wrapping_mul(7) & 0x3F, release: m.wrapping_mul(13) & 0x3F };
                let link = StatusLink { counter: status_counter, identity, fault_count: m & 0xF };
                sink.send(LOG_EPOCH_US + n * 10_000, &encode_status(&s, link))?;
                n += 1;
                // A session frame after every third status frame: release counts from 0 to the
                // top of the 32-bit range, whose low 6 bits are the status frame's release.
                if m % 3 == 0 {
                    let high = [0u32, 1, 1000, 0x3FF_FFFF][usize::from(m / 3) % 4];
                    let release_count = (high << 6) | u32::from(identity.release);
                    let locomotive = u16::from(identity.locomotive) | (u16::from(m) % 64) << 6;
                    let session = SessionLink { counter: status_counter, locomotive, release_count };
                    sink.send(LOG_EPOCH_US + n * 10_000, &encode_session(session))?;
                    n += 1;
                }
                status_counter = (status_counter + 1021) & 0xFFF;
            }
        }
    }
    Ok((n, sink))
}

/// Writes the demonstration log (or the codec sweep).
pub fn demo_log(a: &DemoLogOptions) -> Result<()> {
    let write = |w| -> Result<(u64, CandumpWriter<_>)> {
        if a.sweep {
            write_codec_sweep(w)
        } else {
            write_demo_log(w)
        }
    };
    let frames = match &a.out {
        Some(path) => {
            let f = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
            let out: Box<dyn Write> = Box::new(std::io::BufWriter::new(f));
            let (n, w) = write(CandumpWriter::new(out, &a.iface))?;
            w.finish().with_context(|| format!("cannot write {}", path.display()))?;
            n
        }
        None => {
            let out: Box<dyn Write> = Box::new(std::io::BufWriter::new(std::io::stdout().lock()));
            let (n, w) = write(CandumpWriter::new(out, &a.iface))?;
            w.finish()?;
            n
        }
    };
    eprintln!("wrote {frames} frames");
    Ok(())
}
