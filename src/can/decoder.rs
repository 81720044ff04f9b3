//! Receiver side: a stream decoder that checks integrity (CRC), then freshness — that every
//! frame is new, belongs to the sender it is attributed to, and arrived when its freshness says
//! it was sent — against the receive time it is given.
//!
//! Checks, in order: remote frame, identifier, length, CRC (the fault report's against the
//! session's locomotive and release number, which its CRC covers), signal values, then the
//! freshness rules below. A frame that fails any check is flagged with a [`FrameError`] and
//! yields no report; **a flagged frame is never accepted and moves nothing** (its phase alone is
//! kept, as evidence of a latency step the next genuine frame must confirm; and a session frame
//! flagged for its count or its unit only withholds: it puts the session's count in doubt, or
//! takes away the word of a session none vouched for), so the genuine frames after a replayed,
//! delayed or inserted one are judged against genuine data only. The decoder never panics on
//! any input. `can/README.md` explains the choice of scheme, what it detects and what it cannot.
//!
//! # Session (status frame = heartbeat, 1 Hz)
//!
//! The first status frame opens a session: locomotive, release number, 12-bit heartbeat
//! counter `n`, fault reports sent. Each later status frame of the session must
//! - come from the same locomotive, else [`FrameError::ForeignSender`];
//! - come at least 1 s − [`TOLERANCE_US`] after the last accepted one, else
//!   [`FrameError::RateExceeded`] (a flood, an inserted or replayed frame);
//! - carry a newer counter (`d = n − n_last mod 4096` in `1..2048`), else [`FrameError::Stale`];
//! - have come `d` seconds after the session clock, within [`TOLERANCE_US`] plus 200 ppm
//!   clock drift late or half a second early, else [`FrameError::Untimely`] (delayed, or a
//!   replay at the wrong moment);
//! - not go back in release number, nor rise further than one release a second allows (the
//!   sender running on counts release commands only), else [`FrameError::WrongRelease`]
//!   (unless it goes back to the release before a rise that rests on one heartbeat: that rise
//!   was a corruption the CRC missed, and is undone; after a silence long enough, a number
//!   32–63 "behind" is that many releases on).
//!
//! The session clock (when the next heartbeat is due) is the earliest receive time the
//! accepted heartbeats imply; one early heartbeat does not move it, the next one early the
//! same way does. A heartbeat late within the tolerance moves it to itself while the session's
//! lag stays within [`MAX_LATENCY_STEP_US`] (a latency that wanders slowly is followed), and the
//! release start of the reports of the release under way moves with it. A late heartbeat is flagged, but its phase is kept: when the next one is
//! late the same way the latency rose (a latency step) and the clock follows, up to
//! [`MAX_LATENCY_STEP_US`] after the earliest phase. A sender that restarts before its
//! heartbeat times out (a newer release number, a counter not above the time since the last
//! heartbeat) opens a new tentative session at once.
//!
//! A step of the phase beyond that (a clock step of the receiver, a gateway latency that
//! began, or one that set the session clock and ended) is re-locked onto: [`RELOCK_RUN`]
//! consecutive newer heartbeats at one new phase, each consistent with the session (counter
//! chain, release number, `FaultReportCount`) and within [`MAX_RELOCK_US`], move the session
//! clock and every receive time the session holds to the new phase ([`Reception::relocked_ms`];
//! the heartbeats before the last are flagged). A heartbeat back at the phase the session was
//! first locked onto re-locks at once. This works on the session the step made time out too,
//! so the release number the receiver remembers follows the sender.
//!
//! A recording of the same locomotive running ahead of the live monitor moves the clock the
//! same way (a re-lock while two genuine heartbeats are lost, or two early heartbeats). So after
//! any move the receiver watches the old phase for [`TWO_STREAMS_HOLD_US`]: a heartbeat that
//! continues the session from before the move, on time there and not newer than the stream
//! followed, means two streams of the locomotive ([`Reception::two_streams`]), and no fault
//! report is current until that stream has been silent for the hold; the reports of the
//! heartbeat period right after a move are not current either
//! ([`Reception::relock_unconfirmed`]).
//!
//! A frame stamped more than [`HEARTBEAT_TIMEOUT_US`] after every frame before it ends a silence
//! of the receive clock; the receiver keeps what it knew before that frame for
//! [`TWO_STREAMS_HOLD_US`] of the new time. Two frames in a row stamped more than
//! [`CLOCK_BACK_SLACK_US`] before it, each continuing what it knew before (accepted against it),
//! show that the stamps since the silence were wrong (a logger whose clock glitched ahead for a
//! frame or a few) or that the receive clock went back: the receiver returns to that knowledge
//! with both frames ([`Reception::clock_back_us`]; the first of the two was judged, and flagged,
//! on the new time line). One such frame alone — a frame of an outage logged late, an old frame
//! inserted — changes nothing. Without this rule one heartbeat stamped 4096 s ahead (its 12-bit
//! counter then fits) was taken as the end of a silence, and every genuine frame after it was
//! flagged as a flood to the end of the log; with it on a single frame, one genuine frame of an
//! outage logged late erased the genuine frames after the outage (fifth black-box attacker).
//!
//! `d − 1` heartbeats were lost ([`Reception::lost_status`]; a fault report that arrives when a
//! heartbeat is overdue reports it at once); fault reports the sender counted but this receiver
//! never accepted are reported as lost too ([`Reception::lost_fault_reports`]), except the last
//! one counted, which the status frame may have overtaken: owed until another frame comes
//! ([`Decoder::owed_fault_reports`]).
//!
//! When no status frame was accepted for more than [`HEARTBEAT_TIMEOUT_US`] the session is lost
//! (power cycle, bus-off, a gap between recordings): the held fault report is stale from then
//! on. The next status frame reopens it only if it is plausible: the same sender continuing
//! (counter advanced as the time did), or a restart, which comes with a newer release number
//! than any this receiver saw from that locomotive (the sender counts each power-up as a
//! release) and a counter not above the seconds of silence, or a locomotive not seen before.
//! The newest release seen is remembered per locomotive: a frame of that release that does
//! not continue it is [`FrameError::Stale`], of an older one [`FrameError::WrongRelease`]. A
//! session reopened after a silence is tentative: a status frame that continues the lost
//! session replaces it ([`Reception::superseded`]: the tentative frames were replays).
//!
//! # Fault reports
//!
//! A fault report is attributed to the session's release, or to the next one when its time
//! since release says the release began after the last heartbeat (or to the release before a
//! rise that rests on one heartbeat); its CRC must match that locomotive and release. Then:
//! - at least 100 ms after the last accepted fault report, 0.75 s when its content is unchanged
//!   and its counter the next (the sender's 1 s less the latency step followed), else
//!   [`FrameError::RateExceeded`];
//! - within its release, a larger time since release than the last accepted report, else
//!   [`FrameError::Stale`], and that time must match the receive time since the release began
//!   (within [`TOLERANCE_US`] and the field's 50 ms rounding), else [`FrameError::Untimely`]
//!   (two reports late the same way move the release start, as for the heartbeat);
//! - the first report of a release must place the release command between the last heartbeat
//!   of the previous release and the first of its own, else [`FrameError::Untimely`];
//! - its counter may jump ahead (fault reports lost), not back ([`FrameError::Stale`]): it
//!   must be explained by a number of reports sent since the receiver last learnt the sender's
//!   count (the last status frame's `FaultReportCount` or the last accepted report) that the
//!   rate bound allows in the time since, else [`FrameError::Stale`] (behind the count: sent
//!   before that frame) or [`FrameError::RateExceeded`] (further ahead than the time allows);
//! - a first report whose release began before the monitor powered up (its session's first
//!   heartbeat counter says when), with no heartbeat of the previous release seen, cannot be
//!   vouched for: accepted but stale until a second report agrees; a report the session can
//!   vouch for that contradicts it replaces it ([`Reception::withdrawn`]).
//!
//! A status frame whose `FaultReportCount` leaves out reports this receiver accepted (longer
//! after them than any latency difference allowed, so not the report of its own tick) says
//! the monitor never sent them — or its count is a corruption the CRC missed. One frame's word
//! decides nothing (`CountClaim`): the reports are not current from then on, and the next
//! report that continues the count, or the next status frame, decides; the count winning
//! withdraws them ([`Reception::withdrawn`]) and the receiver goes back to what it held before
//! them, the chain winning shows the count corrupt ([`Reception::count_corrupt`]). That is what
//! catches a fault report of another locomotive whose CRC happens to pass (one of the CRC's 15
//! identity collisions, or a corruption that kept the CRC) when its time since release fits.
//!
//! A report whose time places it earlier than the release start the reports before it set,
//! beyond the tolerance, does not move that start: accepted but not current
//! ([`Reception::early`]); the genuine report after it, with a time not larger, replaces it.
//! A session whose heartbeats came later than its first one's clock by a fraction of a period
//! beyond [`MAX_LATENCY_STEP_US`] follows a delayed stream: its reports are not current
//! ([`Reception::delayed_stream`]). Two heartbeats of another locomotive, one continuing the
//! other, outvote a session that rests on one frame.
//!
//! # Release count (session frame, layout 3)
//!
//! The session frame gives the full 32-bit release count, of which the release number is the
//! low 6 bits (`can/README.md` lists its checks). Once the receiver knows a
//! locomotive's count, a session of that locomotive is current only while a session frame has
//! given its count ([`Reception::release_unconfirmed`]): not after a restart or a silence of the
//! heartbeat until the next session frame, nor after a re-lock, a session frame with another
//! count ([`FrameError::WrongReleaseCount`]) or a lost one ([`Reception::lost_session`]). So a
//! recording of a session 64 (128, …) releases old, which the 6-bit number cannot tell, is never
//! shown current for longer than one period of the session frames. A count newer than any seen
//! shows a restart genuine however far its release number moved.
//!
//! Before any heartbeat a fault report cannot be attributed: [`FrameError::NoHeartbeat`]. After
//! a silence (or in a session resting on one frame) a report whose CRC fits the locomotive only
//! at another release is held as unattributed, not current, until the next accepted heartbeat
//! attributes or drops it ([`Reception::unattributed`]). One
//! that comes while a heartbeat is overdue, or after the heartbeat timed out (judged against
//! the lost session), is accepted but stale ([`Reception::stale`]): not current.

use super::codec::{
    check_crc, decode_signals, frame_payload, session_link, status_link, Binding, FrameError, Identity, MessageKind,
    Report, StatusLink,
};
use super::layout::{self as l, STATUS};

/// Fault reports a status frame can come after without having counted them: those sent in its
/// own tick and within the latency step followed after it (a status frame delayed by up to
/// [`MAX_LATENCY_STEP_US`] against the reports; the sender sends at most one per 100 ms).
const OVERTAKEN_MAX: usize = 4;

/// Silence of the heartbeat after which the release number no longer gives a session's release
/// count (64 releases at one a second, less the power-up and one): the next session frame must.
const RELEASE_COUNT_SILENCE_US: u64 = 62 * STATUS.cycle_ms as u64 * 1000;

/// Silence of the heartbeat (no accepted status frame) after which the session counts as lost:
/// three status cycles (3 s).
pub const HEARTBEAT_TIMEOUT_US: u64 = 3 * STATUS.cycle_ms as u64 * 1000;
/// How much earlier or later than its freshness says a genuine frame may arrive (bus latency,
/// queueing, a gateway): 50 ms.
pub const TOLERANCE_US: u64 = 50_000;
const STATUS_PERIOD_US: u64 = STATUS.cycle_ms as u64 * 1000;
/// The sender's minimum gap between fault reports, and between unchanged ones.
const FAULT_MIN_GAP_US: u64 = 100_000;
const FAULT_REPEAT_US: u64 = 1_000_000;
/// Half the 0.1 s step of `TimeSinceRelease` (the sender rounds to nearest).
const TAU_ROUNDING_US: u64 = 50_000;
const TAU_STEP_US: u64 = 100_000;
const TAU_SATURATED: u16 = 4095;
/// How much earlier than its release start predicts a fault report may come (the start was
/// estimated from a delayed report).
const FAULT_EARLY_US: u64 = 500_000;
/// The shortest time between two release commands the receiver assumes when a silence may have
/// hidden half the release number's range or more (a release command, the valve opening and
/// its report take longer than this).
const MIN_RELEASE_US: u64 = STATUS_PERIOD_US;
/// Heartbeat counter modulus (12 bits).
const COUNTER_MOD: u16 = 4096;
/// How far the receiver follows a lasting rise of the bus latency (a latency step, a gateway
/// that starts queueing): the phase of the heartbeats, or of a release's fault reports, may move
/// up to this much later than the earliest phase the session has seen, once two consecutive
/// frames show the new phase (the first of them is flagged: one delayed frame looks the same).
/// A larger step is re-locked onto after [`RELOCK_RUN`] heartbeats at the new phase.
pub const MAX_LATENCY_STEP_US: u64 = 250_000;

/// How long after its status frame a session frame may come: until the next status frame is
/// due. It is sent last in its tick with the lowest priority, so bus load delays it most; at
/// 55 ms it had been flagged `untimely` and the count put in doubt for 10 s (eighth black-box
/// attacker, F3). Later than this it reads as lost ([`Reception::lost_session`]); a copy within
/// the period is refused (`rate_exceeded`).
pub const SESSION_LATE_MAX_US: u64 = STATUS_PERIOD_US - TOLERANCE_US;
/// How many unattributed fault reports ([`Reception::unattributed`]) the receiver holds until a
/// heartbeat attributes them: the sender sends at most 11 in a heartbeat period. Beyond it they
/// are flagged.
const UNATTRIBUTED_MAX: usize = 12;
/// How far the receiver re-locks onto a heartbeat phase that stepped beyond
/// [`MAX_LATENCY_STEP_US`] (a logger or display clock step, a gateway latency that starts or
/// ends): up to this much later or earlier than the session clock, after [`RELOCK_RUN`]
/// consecutive heartbeats at the new phase. Beyond it the counter (seconds since power-up) and
/// the receive clock disagree by more than any clock step or gateway explains.
pub const MAX_RELOCK_US: u64 = 10_000_000;
/// Consecutive heartbeats at one new phase, each consistent with the session (counter chain,
/// release number, `FaultReportCount`), that re-lock the session clock onto that phase: the
/// first `RELOCK_RUN - 1` are flagged (a delayed or early frame looks the same), the last is
/// accepted and moves the clock.
pub const RELOCK_RUN: u8 = 3;
/// The largest counter step between two heartbeats of a re-lock run (one lost between them).
const RELOCK_MAX_STEP: u16 = 2;

/// Clock drift allowed between sender and receiver over `dt`: 200 ppm (crystal oscillators
/// stay within 100 ppm).
const fn drift(dt: u64) -> u64 {
    dt / 5000
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FaultTrack {
    /// Receive time of the last accepted fault report.
    at_us: u64,
    /// Its release number.
    release: u8,
    /// Its time since release, raw (0.1 s).
    tau: u16,
    /// Receive time at which its release began (estimated from the first accepted report).
    start_us: i64,
    /// Its payload without CRC, counter and time: the content.
    key: u64,
    /// Its counter.
    counter: u8,
    /// The release start rests on this one report (the release's first accepted).
    single: bool,
    /// The release start lies before anything the session can vouch for: before the monitor's
    /// power-up as its heartbeat counter tells it, with no heartbeat of the previous release
    /// seen. Shown stale until a second report agrees; a report that contradicts it and fits
    /// replaces it (it was a CRC-passing report of another locomotive or a corruption).
    unverified: bool,
    /// How much later than first estimated the release start was moved by a latency step.
    lag_us: i64,
    /// Release start implied by the last report flagged as late (for a latency step) or as
    /// early (for a release start set by a delayed first report), or accepted as early
    /// ([`Self::pending`]: for a latency that fell).
    late_start_us: Option<i64>,
    /// Its time since release placed it more than the field's rounding earlier than the release
    /// start the reports before it set: sent before it could have been. A genuine report after
    /// it never carries a time not larger than its own (the sender's reports are at least one
    /// 0.1 s step apart); one that does, is the next counter and fits the release start of the
    /// reports before, shows this one was the odd one (a corruption of its time that kept the
    /// CRC) and replaces it ([`Session::fault_before`]).
    early: bool,
    /// Early beyond the tolerance against a release start more than one report set: accepted
    /// but not current ([`Reception::early`]); one frame does not move the reference. The next
    /// report early the same way moves the release start (the latency fell); one that
    /// contradicts it replaces it.
    pending: bool,
}

impl FaultTrack {
    /// The first accepted report of a release.
    const fn first(at_us: u64, release: u8, tau: u16, start_us: i64, key: u64, counter: u8, unverified: bool) -> Self {
        Self {
            at_us,
            release,
            tau,
            start_us,
            key,
            counter,
            single: true,
            unverified,
            lag_us: 0,
            late_start_us: None,
            early: false,
            pending: false,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Session {
    identity: Identity,
    /// Counter and receive time of the last accepted status frame.
    counter: u16,
    at_us: u64,
    /// When a frame with `counter` was due: the earliest receive time the accepted frames
    /// imply (a frame that arrives early moves it earlier; a late one within the tolerance
    /// moves it later only while the session's lag stays within the latency step followed,
    /// so a delayed frame cannot pull the session's clock further after it).
    anchor_us: i64,
    /// Receive time of the first accepted status frame with this release number.
    release_since_us: u64,
    /// When the monitor powered up, as the first heartbeat of the session tells it (its receive
    /// time less its counter in seconds; later if the counter had wrapped).
    power_up_us: i64,
    /// Receive time of the last accepted status frame of the previous release, if seen.
    release_before_us: Option<u64>,
    /// The counter the next fault report should carry.
    next_fault: u8,
    /// `FaultReportCount` of the last accepted status frame.
    status_count: u8,
    /// Opened as a restart whose release number jumped by this much (more than the power-up and
    /// a release command, 1 or 2) over the newest this receiver saw from the locomotive; 0 when
    /// not. Such a session cannot be told from a recording of an old start-up replayed (the 6-bit
    /// release number wraps), so its reports are never current.
    restart_jump: u8,
    /// Counter of the last accepted fault report.
    last_fault_counter: Option<u8>,
    fault: Option<FaultTrack>,
    /// The fault track before the last accepted report: what an early report
    /// ([`FaultTrack::early`]) that the next report contradicts is replaced by.
    fault_before: Option<FaultTrack>,
    /// Opened as a restart after a silence, not yet confirmed by a second heartbeat.
    tentative: bool,
    /// Heartbeats found overdue (lost) by fault reports since the last accepted status frame.
    overdue_reported: u16,
    /// How much later than the earliest phase seen the session clock was moved by latency steps.
    lag_us: i64,
    /// A newer heartbeat whose phase did not match the session clock (flagged late, or
    /// accepted early): counter and receive time. The next heartbeat at the same phase confirms
    /// it and the clock follows (a latency step, or a clock set by a delayed frame).
    off_phase: Option<(u16, u64)>,
    /// The release before the last rise of the release number, while that rise rests on one
    /// heartbeat: (release, its `release_before_us`, its `release_since_us`). A genuine frame
    /// of that release undoes the rise (it was a corruption that kept the CRC).
    release_prev: Option<(u8, Option<u64>, u64)>,
    /// A fault report the last status frame counted (`FaultReportCount`) that has not arrived:
    /// a status frame may overtake the report of its own tick. Lost if anything else comes first.
    owed_fault: Option<u8>,
    /// The fault-report state before the first report accepted that no status frame has counted
    /// yet, and how many such reports there are: a later status frame whose count does not
    /// include them shows they were not sent by this monitor, and they are withdrawn.
    unconfirmed: Option<Unconfirmed>,
    /// The last status frame's `FaultReportCount` contradicted the reports this receiver
    /// accepted, and rests on that one frame's word: see [`CountClaim`].
    count_claim: Option<CountClaim>,
    /// The release and release start of the last first report of a release flagged as late
    /// for the release's first heartbeat: a latency step that began at that report shows the
    /// same start in the next one, which is then accepted (else every report of the release's
    /// first second was flagged, up to 11).
    first_late: Option<(u8, i64)>,
    /// While the session is tentative: the last heartbeat of another locomotive, flagged
    /// (`foreign_sender`): locomotive, counter, receive time. The next one of that locomotive
    /// that continues it in time outvotes the one frame the session rests on (a corruption of
    /// its locomotive that kept the CRC, or a stray frame), and replaces the session.
    rival: Option<(u8, u16, u64)>,
    /// Consecutive newer heartbeats flagged at one phase other than the session clock's (see
    /// [`PhaseRun`]); cleared by an accepted heartbeat.
    phase_run: Option<PhaseRun>,
    /// How far the re-locks since the session opened moved its clock, µs: a heartbeat back at
    /// the phase before them (a latency that ended) re-locks at once.
    relocked_us: i64,
    /// The full release count of this session as a session frame gave it: (count, the release
    /// number it was the count of). The count of a later release of the session follows from
    /// the release number (at most 63 on: the sender sends a session frame at every new
    /// release number and every 10 s). `None` until a session frame of this session is
    /// accepted, and again after a silence of the heartbeat long enough for 64 releases.
    count_base: Option<(u32, u8)>,
    /// Heartbeat counter whose session frame was accepted (one per heartbeat).
    count_at: Option<u16>,
    /// The fleet number (12 bits) the session frame that gave the count carried: with the count,
    /// what the session's fault reports are sealed with ([`Decoder::binding`]).
    fleet: Option<u16>,
    /// The count the session had before it was put in doubt (as `count_base`; see
    /// [`Session::doubt_count`]): the next session frame must carry exactly the count it implies
    /// before the session's reports are current again.
    count_to_confirm: Option<(u32, u8)>,
    /// Session frames of the unit that carried the count the session has (`count_base` or
    /// `count_to_confirm`), one after the other.
    count_votes: u8,
    /// A fault report passed its CRC sealed with that count (layout 3.2): the unit seals with
    /// it, so no corruption of a session frame gave it.
    count_proven: bool,
    /// The count of the last session frames of the unit refused because they disagreed with the
    /// session's count (as `count_base`), and how many of them in a row carried it. When more
    /// carry it than carried the session's count, and at least two, and no fault report proved
    /// the session's count (`count_proven`), it replaces it: the session's count rested on a
    /// session frame whose count a corruption changed and the CRC missed (one frame's word
    /// decides nothing against the frames around it). A recording that carries on the session
    /// with its own session frames cannot do this: the live unit's reports proved its count.
    /// Until then the fault reports whose CRC fits the rival, and not the session's count, are
    /// accepted but not current ([`Decoder::rival_fits`]).
    rival_count: Option<(u32, u8)>,
    rival_votes: u8,
    /// Receive times of the last accepted fault reports, newest first (0: none): a status frame
    /// delayed by up to the latency step followed comes after the reports sent in that time,
    /// which its count does not include yet ([`OVERTAKEN_MAX`]).
    recent_reports_us: [u64; OVERTAKEN_MAX],
    /// No session frame has given this session a count, and one of its session frames was
    /// refuted (another unit's, or a count the locomotive's known count rules out): its
    /// heartbeats do not speak for the locomotive's newest release ([`Decoder::refute_unvouched`]).
    refuted: bool,
    /// A heartbeat after which the sender sends a session frame passed without one, while this
    /// receiver had heard no count of the locomotive and had accepted a report as a young
    /// unit's: a unit of layout 2, whose reports are sealed so ([`Binding::young`]).
    young_shown: bool,
    /// The fault-report state before the first report attributed to the next release by its
    /// time alone (that release began after the last heartbeat), and how many were accepted
    /// since: the heartbeat after them either carries that release or, received after it
    /// began, shows no such release had begun ([`Decoder::check_next_release`]).
    next_release_from: Option<Unconfirmed>,
}

/// A status frame's `FaultReportCount` that contradicts the chain of the accepted reports'
/// counters: it leaves out reports accepted since the status frame before (they would be
/// withdrawn), or it is more than one ahead (reports lost). Either the reports are not the
/// monitor's (a CRC-passing report of another locomotive) or they were lost, or the count is
/// a corruption the CRC missed (about 1 in 256 corrupted frames). One frame's word does not
/// decide it. A fault report that continues the count with fewer reports lost than the chain
/// decides for the count at once; one that continues the chain is accepted on the chain's
/// word, provisionally (not current), and the next status frame decides — the monitor's own
/// word, which a second sender's reports at a colliding identity cannot give — by whichever of
/// the two needs fewer lost reports to reach its count (the monitor's count only grows, and
/// genuine frames are rarely lost). The count winning withdraws the reports it leaves out and
/// the provisional ones; the chain winning shows the status frame was corrupt
/// ([`Reception::count_corrupt`]) and confirms them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct CountClaim {
    /// The count the status frame gave (the next `FaultCounter`, by its word).
    count: u8,
    /// The next `FaultCounter` by the accepted reports when the status frame came.
    chain_next: u8,
    /// The count leaves out accepted reports ([`Session::unconfirmed`]): withdrawing them is
    /// pending, and they are not current meanwhile.
    withdraws: bool,
    /// Reports lost by the count's word (reported once the count is confirmed).
    lost: u8,
    /// Reports accepted since on the chain's word ([`Session::unconfirmed`]).
    provisional: u8,
}

impl CountClaim {
    /// Reports accepted that the claim, should it win, withdraws: not current meanwhile.
    const fn pending_reports(&self) -> bool {
        self.withdraws || self.provisional > 0
    }
}

impl Session {
    /// When the receiver last learnt the sender's fault-report count: the last accepted status
    /// frame (`FaultReportCount`) or fault report (its counter), whichever came later.
    /// The count is in doubt (after a silence of the heartbeat or a re-lock, a session frame
    /// with another count, or a due one missing): its reports are not current until a session
    /// frame gives it again, which must be the count it implies ([`Self::count_to_confirm`]).
    fn doubt_count(&mut self) {
        self.count_to_confirm = self.count_base.or(self.count_to_confirm);
        self.count_base = None;
    }

    /// A session frame after the heartbeat with counter `counter` gave the count of `release`.
    fn give_count(&mut self, count: u32, release: u8, counter: u16, fleet: u16) {
        let same = self.count_base.or(self.count_to_confirm).is_some_and(|b| count_at_release(b, release) == count);
        self.count_votes = if same { self.count_votes.saturating_add(1) } else { 1 };
        self.count_proven &= same;
        self.count_base = Some((count, release));
        self.fleet = Some(fleet);
        self.count_at = Some(counter);
    }

    /// The full release count of the session's release, if a session frame gave it.
    fn release_count(&self) -> Option<u32> {
        self.count_of_release(self.identity.release)
    }

    /// The full release count of `release` (a release number within 32 of the one whose count a
    /// session frame gave), if one did.
    fn count_of_release(&self, release: u8) -> Option<u32> {
        self.count_base.map(|base| count_at_release(base, release))
    }

    fn count_learnt_us(&self) -> u64 {
        self.fault.map_or(self.at_us, |f| f.at_us.max(self.at_us))
    }

    /// Could the sender have sent 16 reports or more since the last one accepted? The 4-bit
    /// counter may then have gone round: the chain of accepted reports cannot contradict a
    /// status frame's count that says reports were lost (a burst of 16 lost reports looks like
    /// no loss).
    fn chain_wrapped(&self, now: u64) -> bool {
        self.fault.is_none_or(|f| reports_possible(f.at_us, now) >= 16)
    }

    /// The chain of the accepted reports was right and the status frame's count `claim` was
    /// corrupt: the receiver's counters go back to the chain, and the reports the count left
    /// out, and those accepted since on the chain's word, are confirmed.
    fn revert_claim(&mut self, claim: CountClaim) {
        self.unconfirmed = None;
        self.next_fault = claim.chain_next;
        self.status_count = claim.chain_next;
        self.owed_fault = None;
    }

    /// Whether the status frame's count `claim` wins against the chain of accepted reports, for
    /// a frame that continues the count with `by_claim` reports lost and the chain with
    /// `by_chain`: whichever needs fewer lost reports was right, and a count ahead of the chain
    /// wins whenever the chain may have gone round ([`Self::chain_wrapped`]).
    fn count_wins(&self, claim: &CountClaim, by_claim: u8, by_chain: u8, now: u64) -> bool {
        by_claim < by_chain || (!claim.withdraws && self.chain_wrapped(now))
    }

    /// The status frame's count `claim` was right: the reports it left out, and those accepted
    /// since on the chain's word, are withdrawn, and the counters follow the count. Returns how
    /// many were withdrawn and how many reports its word says were lost (less those that
    /// arrived late). A count ahead of the chain (reports lost by its word) contradicts no
    /// report accepted on the chain's word since: those are the reports it counted, arriving
    /// late (a jitter that reorders frames), and are confirmed, not lost.
    fn accept_claim(&mut self, claim: CountClaim) -> (u8, u8) {
        let withdrawn = if claim.withdraws {
            self.withdraw_unconfirmed()
        } else {
            if claim.provisional > 0 {
                self.unconfirmed = None;
            }
            0
        };
        self.next_fault = claim.count;
        self.status_count = claim.count;
        (withdrawn, claim.lost.saturating_sub(claim.provisional))
    }

    /// Takes back the fault reports no status frame has counted: the fault-report state goes
    /// back to what it was before the first of them. Returns how many (0: none).
    fn withdraw_unconfirmed(&mut self) -> u8 {
        let Some(u) = self.unconfirmed.take() else { return 0 };
        self.fault = u.fault;
        self.fault_before = None;
        self.last_fault_counter = u.last_fault_counter;
        self.next_fault = u.next_fault;
        self.owed_fault = u.owed_fault;
        u.reports
    }
}

/// How many fault reports the sender can have sent between `since` and `now` at its rate bound
/// (one per 100 ms), allowing each of the two receive times the latency tolerance.
fn reports_possible(since: u64, now: u64) -> u64 {
    now.saturating_sub(since).saturating_add(2 * TOLERANCE_US) / FAULT_MIN_GAP_US
}

/// What [`Session::unconfirmed`] restores.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Unconfirmed {
    fault: Option<FaultTrack>,
    last_fault_counter: Option<u8>,
    next_fault: u8,
    owed_fault: Option<u8>,
    /// Reports accepted since (saturating).
    reports: u8,
}

/// What [`Decoder::receive`] made of one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reception {
    /// The report, or why the frame was flagged and skipped.
    pub result: Result<Report, FrameError>,
    /// `Some(silence in µs)` when the heartbeat had been silent for longer than
    /// [`HEARTBEAT_TIMEOUT_US`] before this frame: the session was lost (the held report is
    /// stale) and this frame was judged as the start of a new one.
    pub heartbeat_lost_us: Option<u64>,
    /// Heartbeats (status frames) lost before this one (an accepted status frame only).
    pub lost_status: u16,
    /// Fault reports the sender sent that this receiver never accepted (lost or deleted), found
    /// by this frame's counter (fault report) or fault-report count (status frame).
    pub lost_fault_reports: u8,
    /// Which locomotive and release an accepted frame belongs to.
    pub identity: Option<Identity>,
    /// This status frame continued a session lost to a silence and replaced a tentative
    /// session opened meanwhile: the frames accepted in that tentative session were replays.
    pub superseded: bool,
    /// A fault report accepted while a heartbeat is overdue (more than a period and the
    /// tolerance since the last accepted status frame) or lost (judged against the session lost
    /// to the silence): no heartbeat on time vouches for it, so it is not current and a display
    /// shows it as stale, until an accepted heartbeat comes.
    pub stale: bool,
    /// Fault reports accepted earlier that this status frame's `FaultReportCount` shows the
    /// monitor never sent (the count stays below them a full tick and more after they came): a
    /// report of another locomotive whose CRC happened to match, or a corruption that kept the
    /// CRC. They are withdrawn: a display stops showing them and goes back to the report it
    /// held before them. Also the reports attributed to the next release by their time alone
    /// when this heartbeat, received after that release began, still carries the release
    /// before ([`Self::withdrawn_next_release`]).
    pub withdrawn: u8,
    /// The [`Self::withdrawn`] reports were attributed to the next release, which this
    /// heartbeat shows had not begun: reports of another sender whose CRC happens to fit it.
    pub withdrawn_next_release: bool,
    /// The session this frame belongs to was opened as a restart whose release number jumped by
    /// this much (more than 2) over the newest seen from the locomotive: it cannot be told from
    /// an old start-up recording replayed (the release number wraps at 64), so its fault reports
    /// are stale, never current. 0 when not.
    pub restart_jump: u8,
    /// The `FaultReportCount` of the status frame before this frame contradicted the reports
    /// accepted before and after it (and the counts around it): it was corrupted in a way the
    /// CRC missed, and the receiver ignored it (the reports it left out are kept, the loss it
    /// claimed was none).
    pub count_corrupt: bool,
    /// This fault report's time since release places it earlier than the release start the
    /// reports before it set, beyond the tolerance: one frame does not move that reference, so
    /// it is accepted but not current (also [`Self::stale`]) until the next report shows the
    /// latency fell (early the same way) — or contradicts it (a later report with a time not
    /// larger, at the right moment), which replaces it: a corruption of the time that kept the
    /// CRC.
    pub early: bool,
    /// This fault report came after a silence, before any heartbeat, and its CRC fits the lost
    /// session's locomotive only with a release number further on (the sender ran on while this
    /// receiver heard nothing), or in a session resting on one frame (tentative: an old frame
    /// heard first) only with another release: no live heartbeat attributes it yet. Accepted but not current
    /// (also [`Self::stale`]); the next accepted heartbeat decides
    /// ([`Self::unattributed_fitting`], [`Self::unattributed_rejected`]).
    pub unattributed: bool,
    /// This fault report's CRC cannot be checked yet, and it does not fit as a unit's whose
    /// fleet number and count are below 64 (layout 3.2 binds both in full; the status frames
    /// carry their low 6 bits): the receiver has heard no release count of its locomotive (a
    /// display that joined a session under way), or the session's count rests on one session
    /// frame that no report has proved. Accepted but not current (also [`Self::stale`]); the
    /// next session frame, at most 10 s on, decides ([`Self::unattributed_fitting`],
    /// [`Self::unattributed_rejected`]), or a heartbeat when the report fits a young unit's.
    pub awaiting_count: bool,
    /// Unattributed fault reports (above) that this accepted status frame attributes: its
    /// locomotive and its release (or the one before), a counter its `FaultReportCount` has
    /// counted, a release that began before it.
    pub unattributed_fitting: u8,
    /// Unattributed fault reports that this accepted status frame does not attribute: not the
    /// monitor's (a CRC that passed for a release the sender never reached); a display stops
    /// showing them and counts them as flagged.
    pub unattributed_rejected: u8,
    /// The session follows a stream delayed beyond [`MAX_LATENCY_STEP_US`] against its first
    /// heartbeat (the heartbeats after it came later than that one's clock, which no genuine or
    /// replayed frame does): this fault report is late by that much, so not current (also
    /// [`Self::stale`]).
    pub delayed_stream: bool,
    /// This status frame re-locked the session clock onto a heartbeat phase that stepped by
    /// this many ms (positive: later) beyond what the clock follows: a clock step of the
    /// receiver, or a bus latency that began or ended ([`RELOCK_RUN`] heartbeats in a row at the
    /// new phase; the frames before at the old one were flagged). `None` when not.
    pub relocked_ms: Option<i32>,
    /// Two streams of this locomotive are on the bus: after a move of the session clock (a
    /// re-lock, or two early heartbeats), heartbeats still continue the session from before it
    /// on time at its old phase, behind the stream followed (a recording running ahead of the
    /// live monitor moved the receiver onto it, or a second path with another latency). A receiver cannot tell which is live: a status frame of the
    /// old stream is marked so (and judged as before: flagged), and every fault report until
    /// [`TWO_STREAMS_HOLD_US`] after the last of them is accepted but not current (also
    /// [`Self::stale`]).
    pub two_streams: bool,
    /// This fault report came within a heartbeat period after a move of the session clock (a
    /// re-lock, or two early heartbeats), before a heartbeat at the old phase could show a second
    /// stream ([`Self::two_streams`]): accepted, not current
    /// (also [`Self::stale`]).
    pub relock_unconfirmed: bool,
    /// This frame ended a silence of the receive clock (stamped more than
    /// [`HEARTBEAT_TIMEOUT_US`] after every frame before it): the receiver keeps its state from
    /// before it for [`TWO_STREAMS_HOLD_US`], so that a display can keep what it showed then too
    /// ([`Self::clock_back_us`]).
    pub clock_jumped: bool,
    /// `Some(µs)`: this frame is stamped that much before the frame that ended the last silence
    /// of the receive clock, within [`TWO_STREAMS_HOLD_US`] of it, and it and the frame before it
    /// both continue what the receiver knew before the silence: the stamps since the silence
    /// were wrong (a logger glitch) or the receive clock went back. The receiver returned to
    /// that knowledge (with the frame before) and judged this one from there; what it accepted
    /// since the silence is undone, and a display goes back to what it showed before it.
    pub clock_back_us: Option<u64>,
    /// The full release count of the release this accepted frame belongs to, when a session
    /// frame of its session gave it ([`l::RELEASE_COUNT`]).
    pub release_count: Option<u32>,
    /// This fault report belongs to a session whose release count no session frame has given
    /// yet, while the receiver knows this locomotive's count from before: a restart, or a
    /// session heard after a silence, that cannot be told from a recording of the session 64
    /// (or 128, …) releases earlier until its session frame comes (at power-up, at every new
    /// release number and every 10 s). Accepted but not current (also [`Self::stale`]).
    pub release_unconfirmed: bool,
    /// The session frame due after the heartbeat before this one (its counter a multiple of
    /// [`l::SESSION_EVERY_STATUS_FRAMES`], or the first of a new release number) never came,
    /// from a locomotive that sends them: lost (an accepted status frame only).
    pub lost_session: bool,
    /// This accepted frame belongs to a session that no session frame has vouched for and
    /// whose session frame was refuted (another unit with the same number modulo 64, or a
    /// count the locomotive's known count rules out: an old recording). Its status is not the
    /// locomotive's live state and its reports are not current, until a session frame of the
    /// locomotive's own unit gives the session its count.
    pub refuted: bool,
}

impl Reception {
    /// `result` for a frame of `identity`, with nothing else to say of it (no loss, not stale,
    /// nothing withdrawn or held): what a stateless check returns, and where
    /// [`Decoder::receive`] starts.
    pub fn plain(result: Result<Report, FrameError>, identity: Option<Identity>) -> Self {
        Self {
            result,
            heartbeat_lost_us: None,
            lost_status: 0,
            lost_fault_reports: 0,
            identity,
            superseded: false,
            stale: false,
            withdrawn: 0,
            restart_jump: 0,
            count_corrupt: false,
            withdrawn_next_release: false,
            early: false,
            unattributed: false,
            awaiting_count: false,
            unattributed_fitting: 0,
            unattributed_rejected: 0,
            delayed_stream: false,
            relocked_ms: None,
            two_streams: false,
            relock_unconfirmed: false,
            clock_jumped: false,
            clock_back_us: None,
            release_count: None,
            release_unconfirmed: false,
            lost_session: false,
            refuted: false,
        }
    }
}

/// Stream decoder of the monitor's frames.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Decoder {
    /// What the receiver knows now.
    st: Knowledge,
    /// What it knew before the frame that ended the last silence of the receive clock
    /// ([`Reception::clock_back_us`]).
    before_jump: Option<Jump>,
}

/// A jump ahead of the receive clock (a frame stamped more than [`HEARTBEAT_TIMEOUT_US`] after
/// every frame before it), kept for [`TWO_STREAMS_HOLD_US`] of the new time.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Jump {
    /// The stamp of the frame that jumped.
    at_us: u64,
    /// What the receiver knew before it.
    before: Knowledge,
    /// A frame stamped before the jump that continued `before`: that knowledge with it, and its
    /// stamp. A second one in a row that continues it shows the old time line going on.
    back: Option<(Knowledge, u64)>,
}

/// Everything a [`Decoder`] knows of the stream: one copy is followed, and one is kept from
/// before a jump of the receive clock, to judge a frame stamped before the jump against.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Knowledge {
    /// The session followed (none before the first heartbeat, and after a silence).
    session: Option<Session>,
    /// The session lost to the last silence (for the plausibility of the next one).
    lost: Option<Session>,
    /// Newest release number seen per locomotive (bit `i` of `seen`: locomotive `i` seen).
    newest_release: [u8; 64],
    seen: u64,
    /// Fault reports heard after a silence, before the heartbeat that can attribute them
    /// ([`Reception::unattributed`]): receive time and payload bits.
    unattributed: [(u64, u64); UNATTRIBUTED_MAX],
    unattributed_len: u8,
    /// Fault reports held until a session frame gives the release count their CRC binds
    /// (first contact with a unit whose numbers are not both below 64: [`Decoder::hold_for_count`]):
    /// receive time and payload bits.
    awaiting_count: [(u64, u64); UNATTRIBUTED_MAX],
    awaiting_count_len: u8,
    /// The session as it was before the last move of its clock (a re-lock, or two early
    /// heartbeats), followed at its old phase while
    /// heartbeats continue it, and until when ([`TWO_STREAMS_HOLD_US`] after the last such
    /// heartbeat) it is watched: a stream that continues it means two streams of one
    /// locomotive ([`Reception::two_streams`]).
    before_relock: Option<(Session, u64)>,
    /// Until when fault reports are not current because two streams of one locomotive were
    /// heard ([`Reception::two_streams`]).
    two_streams_until: u64,
    /// Until when fault reports after a move of the session clock are not current: the first
    /// heartbeat period after it, in which a stream still at the old phase would not have shown yet
    /// ([`Reception::relock_unconfirmed`]).
    relock_unconfirmed_until: u64,
    /// The newest receive stamp of any frame, µs (0 before the first).
    newest_us: u64,
    /// Newest release count seen per locomotive (from an accepted session frame of a session
    /// confirmed by a second heartbeat), and when: a session frame behind it is an old
    /// recording, and a session of that locomotive is current only once its own session frame
    /// gave its count ([`Reception::release_unconfirmed`]).
    newest_count: [Option<(u32, u64)>; 64],
    /// The fleet number (12 bits) a locomotive's session frames carried, once a session of it
    /// was confirmed: a session frame with another number is another unit whose number is the
    /// same modulo 64 (`foreign_sender`).
    fleet: [Option<u16>; 64],
    /// A status frame after a silence refused only because its 6-bit release number did not
    /// look newer than the locomotive's newest (equal, or 32–63 on, which reads as behind), and
    /// when it came: a restart after 64 or more releases the receiver did not hear looks so.
    /// The session frame right after it decides by the full count ([`Decoder::session_frame`]).
    restart_candidate: Option<(StatusLink, u64)>,
}

/// How far before the frame that ended a silence of the receive clock a frame must be stamped to
/// show that clock wrong ([`Reception::clock_back_us`]): more than any reordering of a log.
pub const CLOCK_BACK_SLACK_US: u64 = 1_000_000;

/// How long after a move of the session clock (or after the last heartbeat that continued the
/// session from before it) the receiver watches for a stream at the old phase, and how long reports stay not current
/// after such a heartbeat.
pub const TWO_STREAMS_HOLD_US: u64 = 10_000_000;

impl Default for Decoder {
    fn default() -> Self {
        Self::new()
    }
}

/// `a − b` in µs as a signed number (receive clocks of logs can go backwards).
fn diff(a: u64, b: u64) -> i64 {
    (i128::from(a) - i128::from(b)).clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64
}

fn ms(us: i64) -> i32 {
    (us / 1000).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

/// A count `got` newer than or equal to the locomotive's newest `known` (last heard at `heard`),
/// by no more than the time since allows: the power-up and one release a second (as the release
/// rules assume; a corruption far ahead is refused and locks nothing out).
fn count_within_time(known: u32, heard: u64, got: u32, now: u64) -> bool {
    count_ahead(known, got).is_some_and(|d| u64::from(d) <= 2 + now.saturating_sub(heard) / STATUS_PERIOD_US)
}

/// How far count `got` is ahead of `known`, in serial-number arithmetic (RFC 1982): the 32-bit
/// count wraps, and a controller whose non-volatile count started at an erased 0xFFFF_FFFF
/// wraps at its second power-up (eighth black-box attacker, F1: every later session had been
/// refused as an old recording). `None` when `got` is behind (more than 2³¹ ahead reads as
/// behind).
fn count_ahead(known: u32, got: u32) -> Option<u32> {
    let d = got.wrapping_sub(known);
    (d < 1 << 31).then_some(d)
}

/// The full count of release number `release`, from the count of release number `base`
/// (`(count, base)`, `base` its low 6 bits): within 32 releases of it either way.
fn count_at_release((count, _base): (u32, u8), release: u8) -> u32 {
    Binding { fleet: 0, release_count: count }.for_release(release).release_count
}

/// The counter of the last heartbeat from `before`'s (the last accepted) up to the one before
/// `next` that the sender sends a session frame after: a multiple of
/// [`l::SESSION_EVERY_STATUS_FRAMES`], or `before`'s when it was the first heartbeat of a new
/// release number. Over at most 64 heartbeats (a longer gap is a silence: the count must be
/// given again anyway).
fn last_due_session(before: &Session, next: u16) -> Option<u16> {
    let d = next.wrapping_sub(before.counter) % COUNTER_MOD;
    let first_of_release = before.release_before_us.is_some() && before.release_since_us == before.at_us;
    (0..d.min(64))
        .rev()
        .map(|k| before.counter.wrapping_add(k) % COUNTER_MOD)
        .find(|&c| c % l::SESSION_EVERY_STATUS_FRAMES == 0 || (c == before.counter && first_of_release))
}

/// Release `b` is `a` or later (6-bit numbers, less than half the range ahead).
fn release_not_before(b: u8, a: u8) -> bool {
    (b.wrapping_sub(a) & 0x3F) < 32
}

impl Decoder {
    /// A decoder that has seen nothing yet.
    pub const fn new() -> Self {
        Self {
            st: Knowledge {
                session: None,
                lost: None,
                newest_release: [0; 64],
                seen: 0,
                unattributed: [(0, 0); UNATTRIBUTED_MAX],
                unattributed_len: 0,
                awaiting_count: [(0, 0); UNATTRIBUTED_MAX],
                awaiting_count_len: 0,
                before_relock: None,
                two_streams_until: 0,
                relock_unconfirmed_until: 0,
                newest_us: 0,
                newest_count: [None; 64],
                fleet: [None; 64],
                restart_candidate: None,
            },
            before_jump: None,
        }
    }

    /// Judges a frame stamped more than [`CLOCK_BACK_SLACK_US`] before the last jump of the
    /// receive clock against what the receiver knew before the jump: when it continues that and
    /// the frame before it did too (two in a row: the old time line goes on, the jump was a
    /// logger's glitch or the clock went back), the receiver returns to that knowledge and this is
    /// its verdict ([`Reception::clock_back_us`]). One such frame alone (a frame of an outage
    /// logged late, a replay) changes nothing: the current knowledge judges it.
    fn judge_before_jump(&mut self, now_us: u64, frame: &impl embedded_can::Frame) -> Option<Reception> {
        let mut jump = self.before_jump.take()?;
        if now_us.saturating_add(CLOCK_BACK_SLACK_US) >= jump.at_us {
            // On the new time line: a run of frames before the jump is broken.
            jump.back = None;
            if now_us <= jump.at_us.saturating_add(TWO_STREAMS_HOLD_US) {
                self.before_jump = Some(jump);
            }
            return None;
        }
        let (old, continues) = match jump.back.take() {
            Some((k, t)) if now_us >= t => (k, true),
            _ => (jump.before.clone(), false),
        };
        let now = core::mem::replace(&mut self.st, old);
        let rec = self.judge(now_us, frame);
        let old = core::mem::replace(&mut self.st, now);
        if rec.result.is_err() {
            self.before_jump = Some(jump);
            return None;
        }
        if continues {
            self.st = old;
            return Some(Reception { clock_back_us: Some(jump.at_us - now_us), ..rec });
        }
        jump.back = Some((old, now_us));
        self.before_jump = Some(jump);
        None
    }

    /// Forgets everything (for example after a bus-off of the receiver).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// The sender and release followed now, if a session is open.
    pub fn identity(&self) -> Option<Identity> {
        self.st.session.map(|s| s.identity)
    }

    /// Whether a report accepted at `accepted_us` is still current at `now_us`: the session is
    /// open, its heartbeat not silent for longer than [`HEARTBEAT_TIMEOUT_US`], no heartbeat
    /// was overdue when it came or one came since, no newer fault report was accepted since, and
    /// no second stream of the locomotive was heard around it ([`Reception::two_streams`]). A
    /// display shows anything else as stale.
    pub fn is_current(&self, accepted_us: u64, now_us: u64) -> bool {
        match self.st.session {
            Some(s) => {
                now_us.saturating_sub(s.at_us) <= HEARTBEAT_TIMEOUT_US
                    && s.fault.is_some_and(|f| f.at_us == accepted_us && !f.pending)
                    // Not a session that follows a stream delayed beyond the latency step.
                    && s.lag_us <= MAX_LATENCY_STEP_US as i64
                    // Not accepted while a heartbeat was overdue (`Reception::stale`; a heartbeat
                    // received late within the latency step followed is not overdue).
                    && accepted_us.saturating_sub(s.at_us)
                        < STATUS_PERIOD_US + TOLERANCE_US + late_heartbeat(&s).map_or(0, |l| STATUS_PERIOD_US + l)
                    // Not left out by the last status frame's count (pending: `CountClaim`).
                    && !s.count_claim.is_some_and(|c| c.pending_reports())
                    // Not accepted before the end of a hold for two streams of the locomotive
                    // (`Reception::two_streams`).
                    && accepted_us > self.st.two_streams_until
                    && accepted_us > self.st.relock_unconfirmed_until
                    // Its session's release count is known, when the locomotive's is
                    // (`Reception::release_unconfirmed`).
                    && !self.count_unconfirmed(&s)
            }
            None => false,
        }
    }

    /// Fault reports the last status frame counted that have not arrived (0 or 1): a status
    /// frame may overtake the report of its own tick, so that report is lost only when another
    /// frame comes first. At the end of a stream (or when the bus goes quiet) they are lost.
    pub fn owed_fault_reports(&self) -> u8 {
        self.st.session.or(self.st.lost).map_or(0, |s| u8::from(s.owed_fault.is_some()))
    }

    /// Decodes one frame received at `now_us` (µs of the receive clock, e.g. a log's time
    /// stamps): the rules of the module doc. Frames that are not the monitor's (other
    /// identifiers, remote frames) come back as errors too, so the caller can count or ignore
    /// them.
    pub fn receive(&mut self, now_us: u64, frame: &impl embedded_can::Frame) -> Reception {
        if let Some(rec) = self.judge_before_jump(now_us, frame) {
            return rec;
        }
        let jumped = self.st.newest_us > 0 && now_us > self.st.newest_us.saturating_add(HEARTBEAT_TIMEOUT_US);
        if jumped {
            self.before_jump = Some(Jump { at_us: now_us, before: self.st.clone(), back: None });
        }
        Reception { clock_jumped: jumped, ..self.judge(now_us, frame) }
    }

    /// [`Self::receive`] on the current knowledge.
    fn judge(&mut self, now_us: u64, frame: &impl embedded_can::Frame) -> Reception {
        let mut rec = Reception::plain(Err(FrameError::NoHeartbeat), None);
        self.st.newest_us = self.st.newest_us.max(now_us);
        if let Some(mut s) = self.st.session {
            let silence = now_us.saturating_sub(s.at_us);
            if silence > HEARTBEAT_TIMEOUT_US {
                rec.heartbeat_lost_us = Some(silence);
                // The monitor's last count left out reports and nothing came to contradict it:
                // its word stands.
                if s.count_claim.take().is_some_and(|c| c.pending_reports()) {
                    rec.withdrawn = s.withdraw_unconfirmed();
                }
                // A tentative session never confirmed is not worth remembering over the one
                // before it.
                if !s.tentative || self.st.lost.is_none() {
                    self.st.lost = Some(s);
                }
                self.st.session = None;
            }
        }
        rec.result = match frame_payload(frame) {
            Err(e) => Err(e),
            Ok((MessageKind::Status, bits)) => {
                let r = self.status_or_relock(now_us, bits, &mut rec);
                if r.is_ok() {
                    self.attribute_held(now_us, bits, &mut rec);
                }
                r
            }
            Ok((MessageKind::Fault, bits)) => self.fault(now_us, bits, &mut rec),
            Ok((MessageKind::Session, bits)) => self.session_frame(now_us, bits, &mut rec),
        };
        if rec.result.is_ok() {
            rec.release_count = self.count_of(rec.identity);
            rec.refuted = self
                .st
                .session
                .is_some_and(|s| s.refuted && rec.identity.is_some_and(|id| id.locomotive == s.identity.locomotive));
        }
        rec
    }

    fn status(&mut self, now: u64, bits: u64, rec: &mut Reception) -> Result<Report, FrameError> {
        check_crc(MessageKind::Status, bits, Binding::default())?;
        let report = decode_signals(MessageKind::Status, bits)?;
        let link = status_link(bits);
        let loco = link.identity.locomotive;
        let lost_same = self.st.lost.filter(|p| p.identity.locomotive == loco);
        let continues_lost = lost_same.and_then(|p| continuation(&p, now, &link).ok());
        match self.st.session {
            Some(s) if s.tentative && continues_lost.is_some() => {
                // The sender never restarted: what opened the tentative session was a replay.
                rec.superseded = true;
                if let (Some(p), Some(c)) = (self.st.lost.take(), continues_lost) {
                    self.accept_status(p, now, &link, c, rec);
                }
            }
            Some(s) => {
                if loco != s.identity.locomotive {
                    // A tentative session rests on one frame: two heartbeats of another
                    // locomotive, one continuing the other in time (counter and receive time
                    // advanced alike), outvote it (else a CRC-keeping corruption of the
                    // opener's locomotive got every genuine frame flagged until a silence).
                    let outvoted = s.tentative
                        && s.rival.is_some_and(|(l, c, at)| {
                            let dp = link.counter.wrapping_sub(c) % COUNTER_MOD;
                            let span = u64::from(dp) * STATUS_PERIOD_US;
                            l == loco
                                && (1..COUNTER_MOD / 2).contains(&dp)
                                && diff(now, at).saturating_sub(span as i64).unsigned_abs()
                                    <= TOLERANCE_US + drift(span)
                        });
                    if !outvoted {
                        if let Some(o) = self.st.session.as_mut().filter(|o| o.tentative) {
                            o.rival = Some((loco, link.counter, now));
                        }
                        return Err(FrameError::ForeignSender { locomotive: u16::from(loco) });
                    }
                    rec.superseded = true;
                    self.open(now, &link, true, rec);
                    return Ok(report);
                }
                match continuation(&s, now, &link) {
                    Ok(c) => self.accept_status(s, now, &link, c, rec),
                    // A tentative session rests on one frame, which may itself have been early
                    // or late (or a replay): a newer heartbeat a period or more later that does
                    // not fit its clock replaces it.
                    // (Its counter may look older too: the one frame may have been a corruption
                    // of the counter that kept the CRC.)
                    // A newer heartbeat late by less than a period is what a delayed second
                    // heartbeat looks like (the opener was on time): flagged, its phase kept;
                    // only the next heartbeat at the same phase shows the opener was the odd
                    // one and replaces it (else the delayed frame was accepted and got the
                    // genuine one after it flagged, or the first report shown stale).
                    // (Or its release number rose more than the time allows: the one frame may
                    // have been a corruption of the release number.)
                    Err(
                        e @ (FrameError::Untimely { .. } | FrameError::Stale { .. } | FrameError::WrongRelease { .. }),
                    ) if s.tentative
                        && release_not_before(link.identity.release & 0x3F, s.identity.release)
                        && link.counter != s.counter
                        && diff(now, s.at_us) >= (STATUS_PERIOD_US - TOLERANCE_US) as i64
                        && (!late_within_period(e) || same_phase(&s, now, &link)) =>
                    {
                        rec.superseded = true;
                        self.open(now, &link, true, rec);
                        if let Some(o) = self.st.session.as_mut() {
                            // Keep what the receiver knows of the release and its reports.
                            o.release_before_us = s.release_before_us;
                            o.release_since_us = s.release_since_us;
                            o.fault = s.fault;
                            o.last_fault_counter = s.last_fault_counter;
                            // Later than the opener's clock by a fraction of a period: no genuine
                            // or replayed frame comes before it is due, so the stream after the
                            // opener is delayed by that much (or the opener was forged). Up to
                            // the latency step the receiver follows it is one; beyond it the
                            // session follows a delayed stream, whose fault reports are not
                            // current (else a uniform delay beginning right after a session's
                            // first heartbeat was followed and its reports shown current).
                            // Later by whole periods (within the step) is what a CRC-keeping
                            // corruption of the opener's counter looks like too: not marked
                            // (else every genuine report of such a session was shown stale).
                            if let FrameError::Untimely { off_ms } = e {
                                let late = i64::from(off_ms.max(0)) * 1000;
                                let frac = late % STATUS_PERIOD_US as i64;
                                if frac > MAX_LATENCY_STEP_US as i64 && frac < (STATUS_PERIOD_US - TOLERANCE_US) as i64
                                {
                                    o.lag_us = late;
                                }
                            }
                        }
                    }
                    // A sender that restarted before its heartbeat timed out (a power cycle
                    // shorter than 3 s): a newer release number and a counter not above the
                    // time since its last heartbeat; the next release number (one power-up),
                    // or any newer one once the old sender's heartbeat is overdue (it stopped).
                    // The session it left is kept as the lost one: should that sender go on,
                    // this one was a replay (superseded).
                    Err(_)
                        if !(1..COUNTER_MOD / 2).contains(&(link.counter.wrapping_sub(s.counter) % COUNTER_MOD))
                            && self.restart_plausible(&link, now, Some(&s))
                            && (link.identity.release & 0x3F == (s.identity.release + 1) & 0x3F
                                || now.saturating_sub(s.at_us) > STATUS_PERIOD_US + TOLERANCE_US) =>
                    {
                        self.st.lost = Some(s);
                        self.open(now, &link, true, rec);
                        self.mark_restart_jump(s.identity.release);
                    }
                    Err(e) => {
                        // A newer heartbeat late for the session clock: remember its phase (a
                        // latency step shows the same phase again in the next one).
                        if let (FrameError::Untimely { off_ms }, Some(o)) = (e, self.st.session.as_mut()) {
                            if off_ms > 0 {
                                o.off_phase = Some((link.counter, now));
                            }
                        }
                        return Err(e);
                    }
                }
            }
            None => {
                // No session (start, or after a silence): open one only if the frame is
                // plausible. The same sender still running continues its session; a sender
                // that restarted comes with a newer release number (a power-up counts as one,
                // see `CanReporter::set_identity`) and a counter not above the silence.
                if let Some(c) = continues_lost {
                    if let Some(p) = self.st.lost.take() {
                        self.accept_status(p, now, &link, c, rec);
                    }
                } else if self.st.seen & (1 << loco) != 0 {
                    let newest = self.st.newest_release[usize::from(loco)];
                    let release = link.identity.release & 0x3F;
                    if release == newest || !release_not_before(release, newest) {
                        // The session frame right after it may show a restart by its count.
                        self.st.restart_candidate = Some((link, now));
                    }
                    // Why a frame that neither continues the lost session nor restarts is refused:
                    // what continuing it lacks (a counter not newer, or the wrong moment for a
                    // newer one; "stale: 160 not newer than 159" had misnamed the latter).
                    let not_continuing = || {
                        lost_same.map_or(FrameError::Stale { last: 0, got: link.counter }, |p| {
                            continuation(&p, now, &link)
                                .err()
                                .unwrap_or(FrameError::Stale { last: p.counter, got: link.counter })
                        })
                    };
                    if release == newest {
                        // The release this receiver already followed, not continuing it: a
                        // frame from before the silence.
                        return Err(not_continuing());
                    }
                    if !release_not_before(release, newest) {
                        return Err(FrameError::WrongRelease { expected: newest, got: release });
                    }
                    if !self.restart_plausible(&link, now, lost_same.as_ref()) {
                        return Err(not_continuing());
                    }
                    self.open(now, &link, true, rec);
                    self.mark_restart_jump(newest);
                } else {
                    // First contact with this locomotive.
                    self.open(now, &link, true, rec);
                }
            }
        }
        Ok(report)
    }

    /// Is this status frame a plausible restart of its locomotive's sender: a newer release
    /// number than any seen from it (a power-up counts as a release) and, when `before` is its
    /// last session, a counter not above the seconds since that session's last heartbeat?
    fn restart_plausible(&self, link: &StatusLink, now: u64, before: Option<&Session>) -> bool {
        // A refuted session (an impostor's) is not the locomotive's sender: nothing to be newer than.
        let before = before.filter(|p| !p.refuted);
        let i = usize::from(link.identity.locomotive & 0x3F);
        let release = link.identity.release & 0x3F;
        let newest = self.st.newest_release[i];
        if self.st.seen & (1 << i) != 0 && (release == newest || !release_not_before(release, newest)) {
            return false;
        }
        // Newer than the session it would replace too (which may be a tentative one, whose
        // release is not remembered as the newest).
        if before.is_some_and(|p| {
            p.identity.locomotive == link.identity.locomotive & 0x3F
                && (release == p.identity.release || !release_not_before(release, p.identity.release))
        }) {
            return false;
        }
        before.is_none_or(|p| {
            let silence = now.saturating_sub(p.at_us);
            u64::from(link.counter) * STATUS_PERIOD_US <= silence.saturating_add(TOLERANCE_US)
        })
    }

    /// The session just opened as a restart: when its release number is more than 2 on from
    /// `before` (more than the power-up and a release command), it cannot be told from an old
    /// start-up recording and its reports are never current ([`Session::restart_jump`]).
    fn mark_restart_jump(&mut self, before: u8) {
        if let Some(o) = self.st.session.as_mut() {
            let jump = o.identity.release.wrapping_sub(before) & 0x3F;
            if jump > 2 {
                o.restart_jump = jump;
            }
        }
    }

    fn open(&mut self, now: u64, link: &StatusLink, tentative: bool, rec: &mut Reception) {
        let identity = link.identity.masked();
        self.st.session = Some(Session {
            identity,
            counter: link.counter,
            at_us: now,
            anchor_us: diff(now, 0),
            release_since_us: now,
            release_before_us: None,
            power_up_us: diff(now, u64::from(link.counter) * STATUS_PERIOD_US),
            next_fault: link.fault_count & 0xF,
            status_count: link.fault_count & 0xF,
            restart_jump: 0,
            last_fault_counter: None,
            fault: None,
            fault_before: None,
            tentative,
            overdue_reported: 0,
            lag_us: 0,
            off_phase: None,
            release_prev: None,
            owed_fault: None,
            unconfirmed: None,
            count_claim: None,
            first_late: None,
            rival: None,
            phase_run: None,
            relocked_us: 0,
            count_base: None,
            count_at: None,
            fleet: None,
            count_to_confirm: None,
            count_votes: 0,
            count_proven: false,
            rival_count: None,
            rival_votes: 0,
            recent_reports_us: [0; OVERTAKEN_MAX],
            refuted: false,
            young_shown: false,
            next_release_from: None,
        });
        // A tentative session rests on one frame, which may be a replay: what it says of the
        // locomotive's newest release is believed only once a second heartbeat confirms it
        // (else one replayed frame of a newer-looking release locked the sender out).
        if !tentative {
            self.remember(link);
        }
        rec.identity = Some(identity);
    }

    /// Accepts a status frame that continues session `s` (`c`: how, from [`continuation`]).
    fn accept_status(&mut self, mut s: Session, now: u64, link: &StatusLink, c: Continues, rec: &mut Reception) {
        let before = s;
        // The last heartbeat before this one that was due a session frame (the one before, or one
        // lost between: a stream whose heartbeats at multiples of 10 are dropped, with their
        // session frames, is no different, sixth black-box attacker N1) got none.
        // (A session frame of a later heartbeat, up to this one, gave the count too: the session
        // frame of a new release's first heartbeat logged just before it, tenth black-box tester.)
        let given_since = |due: u16| {
            before
                .count_at
                .is_some_and(|c| c.wrapping_sub(due) % COUNTER_MOD <= link.counter.wrapping_sub(due) % COUNTER_MOD)
        };
        let missed_session = last_due_session(&before, link.counter).is_some_and(|due| !given_since(due));
        rec.lost_session = missed_session && self.newest_count(before.identity.locomotive).is_some();
        // (And a report passed its CRC as a young unit's: a unit that seals otherwise, whose
        // session frames are lost, is not taken for one.)
        let young_fit = before.fault.is_some() || before.last_fault_counter.is_some();
        if missed_session && !self.count_heard(&before) && young_fit {
            s.young_shown = true;
        }
        // A session frame due after the heartbeat before did not come: the count is in doubt
        // until the next one gives it (a stream stripped of its session frames is not vouched
        // for longer than one period of them).
        if rec.lost_session {
            s.doubt_count();
        }
        // After a silence of the heartbeat the next session frame must give the count again:
        // a stream that continues the session in time may be a recording that carries on its
        // heartbeat counter (sixth black-box attacker, F2). It must carry the count
        // the session implies, unless the silence was long enough for 64 releases (one a
        // second, as the release rules assume): then the release number no longer gives it.
        let silence = now.saturating_sub(s.at_us);
        // (A session frame accepted in the silence, on time for a heartbeat lost in it and with
        // the session's count, already gave the count again.)
        let count_heard_since =
            s.count_at.is_some_and(|c| (1..COUNTER_MOD / 2).contains(&(c.wrapping_sub(s.counter) % COUNTER_MOD)));
        if silence > HEARTBEAT_TIMEOUT_US && !count_heard_since {
            s.doubt_count();
            if silence >= RELEASE_COUNT_SILENCE_US {
                s.count_to_confirm = None;
            }
        }
        let d = c.periods;
        // (The heartbeat before this one at its phase was received, flagged: not lost.)
        let received_late = u64::from(late_heartbeat(&s).is_some() && c.phase == Phase::Step);
        rec.lost_status = u16::try_from(d.saturating_sub(1).saturating_sub(received_late))
            .unwrap_or(u16::MAX)
            .saturating_sub(s.overdue_reported);
        s.overdue_reported = 0;
        let release = link.identity.release & 0x3F;
        if c.undo_release {
            // The rise of the release number rested on one heartbeat, and the sender goes on
            // with the release before it (or on from it): that heartbeat was a corruption the
            // CRC missed, or a replay.
            if let Some((r, before, since)) = s.release_prev.take() {
                s.identity.release = r;
                s.release_before_us = before;
                s.release_since_us = since;
            }
        }
        if release != s.identity.release {
            s.release_prev = Some((s.identity.release, s.release_before_us, s.release_since_us));
            s.release_before_us = Some(s.at_us);
            s.release_since_us = now;
            s.identity.release = release;
        } else if !c.undo_release {
            s.release_prev = None;
        }
        // The status frames' `FaultReportCount` against the reports accepted. The count is 4
        // bits: between two status frames one period apart the sender sends at most 11 reports
        // (one per 100 ms), so the count's step is the number sent; after a longer gap it is
        // ambiguous and the receiver believes what it accepted.
        let count = link.fault_count & 0xF;
        // The last `k` reports accepted may have been sent at or after this frame's tick, and come
        // first, not counted by it: the report of its own tick, and those of the latency step
        // followed after it when the status frame is the delayed one (a gateway queueing the
        // status identifier: 0.2–0.3 s had about 165 genuine reports withdrawn per log, fourth
        // black-box attacker). All of them within that window before this frame.
        let recent = s.recent_reports_us;
        let overtaken = |k: u8| {
            (1..=OVERTAKEN_MAX as u8).contains(&k)
                && recent
                    .get(usize::from(k) - 1)
                    .is_some_and(|&at| at > 0 && now.saturating_sub(at) <= MAX_LATENCY_STEP_US + TOLERANCE_US)
        };
        // A count of the status frame before that contradicted the reports' chain is decided
        // by this one: whichever needs fewer lost reports to reach this count was right.
        let mut claim_lost = 0;
        if let Some(claim) = s.count_claim.take() {
            let by_claim = count.wrapping_sub(claim.count) & 0xF;
            let by_chain = count.wrapping_sub(claim.chain_next) & 0xF;
            if s.count_wins(&claim, by_claim, by_chain, now) {
                (rec.withdrawn, claim_lost) = s.accept_claim(claim);
            } else {
                s.revert_claim(claim);
                rec.count_corrupt = true;
            }
        }
        // (When this heartbeat was due on the session clock: one queued by a gateway was sent
        // then, not when it came.)
        let due_us =
            s.anchor_us.saturating_add(i64::try_from(c.periods.saturating_mul(STATUS_PERIOD_US)).unwrap_or(i64::MAX));
        Self::check_next_release(&mut s, diff(now, 0).min(due_us), release, rec);
        let mut withdraws = false;
        if s.unconfirmed.is_some() {
            if reports_possible(s.at_us, now) >= 16 {
                s.unconfirmed = None;
            } else {
                // Reports accepted since the last status frame carry the counters from its count
                // on; this count must be past the last of them.
                let sent = count.wrapping_sub(s.status_count) & 0xF;
                let last = s.next_fault.wrapping_sub(1).wrapping_sub(s.status_count) & 0xF;
                if last < sent {
                    s.unconfirmed = None;
                } else if !overtaken(last.wrapping_sub(sent).wrapping_add(1) & 0xF) {
                    // The monitor never sent them, or this count is corrupt: withdrawn once the
                    // next frame agrees with this count ([`CountClaim`]).
                    withdraws = true;
                }
            }
        }
        // Fault reports the sender counted that never arrived here. The last one counted may
        // be the report of this frame's own tick, overtaken by it: owed, lost only if anything
        // else comes first. A report owed since the previous status frame is lost. A count that
        // more reports than the time allows would have to explain is behind ours: the report of
        // this frame's tick came first (nothing lost), or a count the receiver held came from a
        // status frame corrupted in a way the CRC missed (the count only grows: this one is right).
        let learnt = s.count_learnt_us();
        let mut lost = u8::from(s.owed_fault.take().is_some()).saturating_add(claim_lost);
        let behind = count.wrapping_sub(s.next_fault) & 0xF;
        let chain_next = s.next_fault;
        if withdraws {
            // Pending: the chain stays as the reports left it.
            s.count_claim = Some(CountClaim { count, chain_next, withdraws: true, lost: 0, provisional: 0 });
        } else if behind > 0 && u64::from(behind) <= reports_possible(learnt, now) && !overtaken(16 - behind) {
            s.owed_fault = Some(count.wrapping_sub(1) & 0xF);
            s.next_fault = count;
            if behind > 1 && s.last_fault_counter.is_some() {
                // Reports lost, by this frame's word alone: reported once confirmed.
                s.count_claim =
                    Some(CountClaim { count, chain_next, withdraws: false, lost: behind - 1, provisional: 0 });
            } else {
                lost += behind - 1;
            }
        } else if behind > 0 && !overtaken(16 - behind) {
            s.next_fault = count;
            if s.last_fault_counter.is_some() {
                s.count_claim = Some(CountClaim { count, chain_next, withdraws: false, lost: 0, provisional: 0 });
            }
        }
        if !withdraws {
            s.status_count = count;
        }
        rec.lost_fault_reports = lost;
        // The session clock: when a frame with this counter was due.
        let span = d.saturating_mul(STATUS_PERIOD_US);
        let due = s.anchor_us.saturating_add(i64::try_from(span).unwrap_or(i64::MAX));
        let creep = i64::try_from(drift(span)).unwrap_or(i64::MAX);
        let here = diff(now, 0);
        let anchor = match c.phase {
            // Within the tolerance: the earliest receive time the frames imply — or, late within
            // it, this heartbeat's, while the session's lag stays within the latency step
            // followed: a latency that wanders slowly (a gateway whose queue fills and drains)
            // is followed heartbeat by heartbeat instead of being flagged each time it has
            // moved by the tolerance (fourth black-box attacker: 3–4 genuine heartbeats per cycle
            // of a 0–240 ms wander). One late heartbeat moves the clock by less than the
            // tolerance, and the next on time moves it back.
            Phase::OnTime => {
                s.off_phase = None;
                let late = here.saturating_sub(due);
                if late > 0 && s.lag_us.saturating_add(late) <= MAX_LATENCY_STEP_US as i64 {
                    here
                } else {
                    here.min(due.saturating_add(creep))
                }
            }
            // Early, and the heartbeat before was early the same way: the clock was set by a
            // delayed frame (or the latency fell); it follows.
            Phase::Early { confirmed: true } => {
                s.off_phase = None;
                // A stream ahead of the live one moves the clock the same way.
                self.watch_after_move(before, now);
                here
            }
            // One early heartbeat does not move the clock (it may be an outlier or a replay
            // ahead of the genuine frame); the next one tells.
            Phase::Early { confirmed: false } => {
                s.off_phase = Some((link.counter, now));
                due.saturating_add(creep)
            }
            // Late, at the phase of the heartbeat before (flagged): a latency step.
            Phase::Step => {
                s.off_phase = None;
                here
            }
        };
        let moved = anchor.saturating_sub(due);
        if c.phase == Phase::OnTime {
            // The reports of the release under way come through the same path: their release
            // start follows the heartbeat clock (a slowly wandering latency had them flagged
            // `untimely` each time it had moved by the tolerance).
            if let Some(f) = s.fault.as_mut().filter(|f| f.release == s.identity.release) {
                f.start_us = f.start_us.saturating_add(moved);
            }
        }
        s.lag_us = s.lag_us.saturating_add(moved).max(0);
        s.anchor_us = anchor;
        s.counter = link.counter;
        s.at_us = now;
        s.tentative = false;
        s.phase_run = None;
        self.st.session = Some(s);
        self.remember(link);
        if let Some(count) = s.release_count() {
            self.note_count(s.identity.locomotive, count, now);
        }
        if (c.undo_release || c.release_wrapped) && !s.refuted {
            self.st.newest_release[usize::from(s.identity.locomotive & 0x3F)] = s.identity.release;
        }
        rec.identity = Some(s.identity);
    }

    /// A heartbeat of `release`, accepted and sent at `sent_us` (its receive time, or when it was
    /// due on the session clock if that is earlier: a gateway may have queued it), after fault
    /// reports attributed to the next release by their time alone
    /// ([`Session::next_release_from`]): carrying that release, it confirms them; still carrying
    /// this one though sent after the next began (beyond the tolerance and the time field's
    /// rounding), it shows that release had not begun. The
    /// reports were another sender's whose CRC happens to fit the next release (one in 256 of
    /// any other unit's), and they are withdrawn: the fault-report state goes back to before
    /// them, so the genuine report with the same counter is accepted. A fifteenth black-box
    /// tester's such report, 50–290 ms before a heartbeat, was shown current as "release 24"
    /// while every heartbeat said 23, never withdrawn, and the genuine one flagged stale (10 of
    /// 10 trials). Reports the heartbeat's count withdrew already leave nothing to do.
    fn check_next_release(s: &mut Session, sent_us: i64, release: u8, rec: &mut Reception) {
        let Some(from) = s.next_release_from.take() else { return };
        let next = (release + 1) & 0x3F;
        // (A heartbeat that raised the release to the reports' confirmed them: `next` is past it.)
        let Some(f) = s.fault.filter(|f| f.release == next && rec.withdrawn == 0) else { return };
        if sent_us.saturating_sub(f.start_us) <= (TOLERANCE_US + TAU_ROUNDING_US) as i64 {
            // Began just before this heartbeat was sent: the next one decides.
            s.next_release_from = Some(from);
            return;
        }
        s.fault = from.fault;
        s.fault_before = None;
        s.last_fault_counter = from.last_fault_counter;
        s.next_fault = from.next_fault;
        s.owed_fault = from.owed_fault;
        s.unconfirmed = s
            .unconfirmed
            .filter(|u| u.reports > from.reports)
            .map(|u| Unconfirmed { reports: u.reports - from.reports, ..u });
        rec.withdrawn = from.reports;
        rec.withdrawn_next_release = true;
    }

    fn remember(&mut self, link: &StatusLink) {
        let id = link.identity.masked();
        let i = usize::from(id.locomotive);
        let refuted = self.st.session.is_some_and(|s| s.refuted && s.identity.locomotive == id.locomotive);
        if !refuted && (self.st.seen & (1 << i) == 0 || release_not_before(id.release, self.st.newest_release[i])) {
            self.st.newest_release[i] = id.release;
        }
        self.st.seen |= 1 << i;
    }

    /// The locomotive's newest release count is `count` (or newer), heard at `now`.
    fn note_count(&mut self, locomotive: u8, count: u32, now: u64) {
        let i = usize::from(locomotive & 0x3F);
        if let Some(slot) = self.st.newest_count.get_mut(i) {
            if slot.is_none_or(|(newest, _)| count_ahead(newest, count).is_some()) {
                *slot = Some((count, now));
                // The count is the authority on which release is the newest (the 6-bit number
                // reads 32–63 on as behind).
                if let Some(r) = self.st.newest_release.get_mut(i) {
                    *r = (count & 0x3F) as u8;
                }
                self.st.seen |= 1 << i;
            }
        }
    }

    /// The session's release count is not known while the receiver knows its locomotive's
    /// ([`Reception::release_unconfirmed`]).
    fn count_unconfirmed(&self, s: &Session) -> bool {
        s.count_base.is_none() && self.newest_count(s.identity.locomotive).is_some()
    }

    /// Whether session frame `link` comes from the unit whose session frames this receiver
    /// confirmed for its locomotive (the same 12-bit fleet number), or none was confirmed yet.
    fn same_unit(&self, link: &super::codec::SessionLink) -> bool {
        self.st.fleet.get(usize::from(link.locomotive_slot())).copied().flatten().is_none_or(|f| f == link.locomotive)
    }

    /// A session frame of the session followed was refuted (another unit's, or a count the
    /// locomotive's known count rules out). When no session frame has vouched for the session
    /// (no count given, none to confirm), the heartbeats it rests on are not taken to be the
    /// locomotive's sender's: the newest release number goes back to that of the newest count
    /// seen, and they do not raise it until a session frame of the locomotive's own unit gives
    /// the session its count. Else an impostor after a silence (a unit with the same number
    /// modulo 64, or a forged restart) raised the newest release, and the genuine unit's
    /// restart after it read as behind it: its first heartbeat was flagged (ninth black-box
    /// tester, 13 of 18 trials). A session that had a count (the live unit's, into which
    /// another's session frame was injected) only has its count put in doubt.
    fn refute_unvouched(&mut self) {
        let Some(s) = self.st.session.as_mut() else { return };
        if s.count_base.is_some() || s.count_to_confirm.is_some() {
            return;
        }
        s.refuted = true;
        let locomotive = s.identity.locomotive;
        if let Some((count, _)) = self.newest_count(locomotive) {
            self.st.newest_release[usize::from(locomotive & 0x3F)] = (count & 0x3F) as u8;
        }
    }

    /// Whether this receiver heard a release count of session `s`'s locomotive: the session's
    /// own, the one it must confirm, or the locomotive's newest. Without one it knows the
    /// binding of the session's fault reports only for a unit whose fleet number and count are
    /// both below 64 ([`Binding::young`]).
    fn count_heard(&self, s: &Session) -> bool {
        s.count_base.or(s.count_to_confirm).is_some() || self.newest_count(s.identity.locomotive).is_some()
    }

    /// Whether this receiver cannot tell what session `s`'s fault reports are sealed with: no
    /// count heard ([`Self::count_heard`]) and the unit has not shown that it sends no session
    /// frames ([`Session::young_shown`]: a unit of layout 2, sealing as a young unit); or the
    /// session's count rests on one session frame and no report proved it (a corruption of
    /// that frame's count that kept its CRC: the next session frames decide,
    /// [`Session::rival_count`]). A report whose CRC then fails is held, not flagged. (A report
    /// that fits a young unit's binding shows nothing: one injected at first contact had the
    /// genuine reports of an older unit flagged until the session frame, twelfth black-box
    /// tester, F3.)
    fn binding_unknown(&self, s: &Session) -> bool {
        let one_frame = s.count_base.or(s.count_to_confirm).is_some() && s.count_votes <= 1 && !s.count_proven;
        (!self.count_heard(s) && !s.young_shown) || one_frame
    }

    /// The binding (layout 3.2: fleet number and full release count) a fault report of
    /// `id` (the session's locomotive, a release number) in session `s` is sealed with, as far
    /// as this receiver knows: the release number gives the count within 32 releases of the
    /// session's count (or the count it must confirm, or the locomotive's newest count heard),
    /// the confirmed session frames the fleet number. Without a count heard: a young unit's.
    fn binding(&self, s: &Session, id: Identity) -> Binding {
        let loco = id.locomotive & 0x3F;
        let newest = || self.newest_count(loco).map(|(c, _)| (c, (c & 0x3F) as u8));
        let Some(base) = s.count_base.or(s.count_to_confirm).or_else(newest) else {
            return Binding::young(id);
        };
        let fleet =
            s.fleet.or_else(|| self.st.fleet.get(usize::from(loco)).copied().flatten()).unwrap_or(u16::from(loco));
        Binding { fleet, release_count: count_at_release(base, id.release) }
    }

    /// Whether a fault report of `id` in session `s` is sealed with the rival count of the
    /// unit's session frames that disagreed with the session's ([`Session::rival_count`]).
    fn rival_fits(&self, s: &Session, bits: u64, id: Identity) -> bool {
        s.rival_count.is_some_and(|r| {
            let b = self.binding(s, id);
            check_crc(MessageKind::Fault, bits, Binding { release_count: count_at_release(r, id.release), ..b }).is_ok()
        })
    }

    /// The CRC check of a fault report of `id` in session `s` ([`Self::binding`]).
    fn fault_crc(&self, s: &Session, bits: u64, id: Identity) -> Result<(), FrameError> {
        check_crc(MessageKind::Fault, bits, self.binding(s, id))
    }

    /// A fault report whose CRC fits no release of its session while the binding is unknown
    /// ([`Self::binding_unknown`]): a display that joined a session under way, before its next
    /// session frame (at most 10 s), cannot check the CRC of a unit whose fleet number or count
    /// is 64 or more (layout 3.2 binds both in full).
    /// Held, accepted but not current ([`Reception::awaiting_count`]), until a session frame
    /// gives the count and decides it ([`Self::decide_awaiting_count`]). The hold full, it is
    /// shown not current all the same and never decided (the sender sends up to 100 reports in
    /// the 10 s before its next session frame; flagging them flagged genuine traffic of a
    /// display that joined late: twelfth black-box tester, F1 and F5). The status frames count
    /// it: the chain of counters goes on from it, so that it is not reported lost.
    fn hold_for_count(
        &mut self,
        mut s: Session,
        in_lost: bool,
        now: u64,
        bits: u64,
        rec: &mut Reception,
    ) -> Result<Report, FrameError> {
        let report = decode_signals(MessageKind::Fault, bits)?;
        if let Some(slot) = self.st.awaiting_count.get_mut(usize::from(self.st.awaiting_count_len)) {
            *slot = (now, bits);
            self.st.awaiting_count_len += 1;
        }
        // (Only while no report is in the chain: one held after accepted reports, a corruption or
        // an old report as likely as not, moves nothing.)
        if s.fault.is_none() && s.last_fault_counter.is_none() {
            let counter = l::FAULT_COUNTER.get(bits) as u8;
            s.next_fault = (counter + 1) & 0xF;
            if s.owed_fault == Some(counter) {
                s.owed_fault = None;
            }
        }
        if in_lost {
            self.st.lost = Some(s);
        } else {
            self.st.session = Some(s);
        }
        rec.awaiting_count = true;
        rec.stale = true;
        rec.identity = Some(s.identity);
        Ok(report)
    }

    /// A session frame gave the count of the session followed: the fault reports held for it
    /// ([`Self::hold_for_count`]) whose CRC fits the session's release or the one before are
    /// the monitor's (past reports, [`Reception::unattributed_fitting`]); the others are not
    /// ([`Reception::unattributed_rejected`]).
    fn decide_awaiting_count(&mut self, rec: &mut Reception) {
        let Some(s) = self.st.session else { return };
        let n = usize::from(core::mem::take(&mut self.st.awaiting_count_len));
        let id = s.identity;
        let before = Identity { release: id.release.wrapping_sub(1) & 0x3F, ..id };
        for &(_, fb) in self.st.awaiting_count.iter().take(n) {
            if self.fault_crc(&s, fb, id).is_ok() || self.fault_crc(&s, fb, before).is_ok() {
                rec.unattributed_fitting = rec.unattributed_fitting.saturating_add(1);
            } else {
                rec.unattributed_rejected = rec.unattributed_rejected.saturating_add(1);
            }
        }
    }

    /// The newest release count seen from the locomotive, and when it was last heard.
    fn newest_count(&self, locomotive: u8) -> Option<(u32, u64)> {
        self.st.newest_count.get(usize::from(locomotive & 0x3F)).copied().flatten()
    }

    /// The full release count of an accepted frame of `identity`, when a session frame gave it.
    fn count_of(&self, identity: Option<Identity>) -> Option<u32> {
        let id = identity?;
        [self.st.session, self.st.lost]
            .into_iter()
            .flatten()
            .find(|s| s.identity.locomotive == id.locomotive && s.count_base.is_some())
            .and_then(|s| s.count_of_release(id.release))
    }

    /// A session frame (layout 3): the full release count of the session followed. It is judged
    /// with the status frame it follows in the same transmit tick: it must carry that
    /// heartbeat's counter, locomotive and release number (the count's low 6 bits), come within
    /// [`TOLERANCE_US`] after it, be the only one for it, and carry the session's count when
    /// the session has one; else the locomotive's newest count seen or one further on, by no
    /// more than the time since allows (one release a second and the power-up), else
    /// [`FrameError::WrongReleaseCount`] — a recording of an old session of the locomotive
    /// (whose release number is the same modulo 64), or a corruption. A session frame of a
    /// restart that jumped over several release numbers and whose count is newer than any seen
    /// shows a genuine restart (the monitor was power-cycled while this receiver heard nothing):
    /// its reports are current again.
    fn session_frame(&mut self, now: u64, bits: u64, rec: &mut Reception) -> Result<Report, FrameError> {
        check_crc(MessageKind::Session, bits, Binding::default())?;
        let report = decode_signals(MessageKind::Session, bits)?;
        let link = session_link(bits);
        let candidate = self.st.restart_candidate.take();
        if self.st.session.is_none() {
            if let Some((status, at)) = candidate {
                self.restart_by_count(now, &link, &status, at, rec)?;
                return Ok(report);
            }
        }
        let Some(mut s) = self.st.session else {
            return Err(FrameError::NoHeartbeat);
        };
        if link.locomotive_slot() != s.identity.locomotive {
            return Err(FrameError::ForeignSender { locomotive: link.locomotive });
        }
        if !self.same_unit(&link) {
            // Another unit speaks for this locomotive (its number is the same modulo 64): the
            // session's count is in doubt until its own unit's session frame gives it again, so
            // the reports around it are not current (a ninth black-box tester's impostor that
            // carried on the heartbeat counter had its report in the same second shown current).
            if let Some(o) = self.st.session.as_mut() {
                o.doubt_count();
            }
            self.refute_unvouched();
            return Err(FrameError::ForeignSender { locomotive: link.locomotive });
        }
        // Right after the last accepted heartbeat, with its counter; or, when that heartbeat was
        // lost, on time for its own counter by the session clock (as a heartbeat would be).
        let d = link.counter.wrapping_sub(s.counter) % COUNTER_MOD;
        if d >= COUNTER_MOD / 2 {
            return Err(FrameError::Stale { last: s.counter, got: link.counter });
        }
        if s.count_at == Some(link.counter) {
            return Err(FrameError::RateExceeded { gap_ms: ms(diff(now, s.at_us)).max(0) as u32 });
        }
        let span = u64::from(d) * STATUS_PERIOD_US;
        // Right after a newer heartbeat that was flagged for its timing (a latency step, a
        // delayed frame): it comes and goes with that heartbeat, and its count is checked below.
        let flagged_at = s.off_phase.filter(|&(c, _)| d > 0 && c == link.counter).map(|(_, at)| at);
        // On time for its counter by the session clock (as its heartbeat would be: a heartbeat
        // that came early alone, or was lost), or right after its heartbeat as received.
        let due = s.anchor_us.saturating_add(i64::try_from(span).unwrap_or(i64::MAX));
        let by_clock = diff(now, 0).saturating_sub(due);
        let on_clock = (-(TOLERANCE_US as i64)..=(TOLERANCE_US + drift(span)) as i64).contains(&by_clock);
        let heard_at = flagged_at.or((d == 0).then_some(s.at_us));
        let after_heartbeat = heard_at.is_some_and(|at| (0..=SESSION_LATE_MAX_US as i64).contains(&diff(now, at)));
        if !on_clock && !after_heartbeat {
            return Err(FrameError::Untimely { off_ms: ms(heard_at.map_or(by_clock, |at| diff(now, at))) });
        }
        // Its release number: the session's, or the next when the heartbeat it follows (lost)
        // carried a new one.
        let next = (s.identity.release + 1) & 0x3F;
        if link.release() != s.identity.release && !(d > 0 && link.release() == next) {
            return Err(FrameError::WrongRelease { expected: s.identity.release, got: link.release() });
        }
        let got = link.release_count;
        let implied = s.count_base.or(s.count_to_confirm).map(|base| count_at_release(base, link.release()));
        let mut replaces = None;
        if let Some(known) = implied {
            if got != known {
                // Not this session's count: a recording that carries on the session's heartbeat
                // counter, or a corruption. The session's count is in doubt until a session
                // frame gives it again (its reports are not current meanwhile): with a refuted
                // session frame (`refute_unvouched`), the exception to "a flagged frame moves
                // nothing", and it only withholds. Unless more of the unit's session frames in
                // a row carried this count than the session's (and two at least): then the
                // session's count was the corrupt one (`Session::rival_count`).
                let votes = match s.rival_count {
                    Some(r) if count_at_release(r, link.release()) == got => s.rival_votes.saturating_add(1),
                    _ => 1,
                };
                if votes < 2 || votes <= s.count_votes || s.count_proven {
                    if let Some(o) = self.st.session.as_mut() {
                        o.doubt_count();
                        o.rival_count = Some((got, link.release()));
                        o.rival_votes = votes;
                    }
                    return Err(FrameError::WrongReleaseCount { known, got });
                }
                replaces = Some(votes);
            }
        } else if let Some((known, heard)) = self.newest_count(link.locomotive_slot()) {
            if !count_within_time(known, heard, got, now) {
                // (Its count stays the rival of the one rebuilt from the locomotive's newest: the
                // session's reports sealed with it are shown not current, not flagged — a restart
                // after more releases than the time since allows, which this receiver did not
                // hear, looks so; [`Decoder::rival_fits`].)
                if let Some(o) = self.st.session.as_mut() {
                    o.rival_count = Some((got, link.release()));
                    o.rival_votes = 1;
                }
                self.refute_unvouched();
                return Err(FrameError::WrongReleaseCount { known, got });
            }
            // A release this receiver saw begin after it last heard the locomotive's newest
            // count cannot carry that count: the monitor counts every release command. (A
            // recording that reached, after a silence aligned on the heartbeat counter's 4096 s
            // range, the release whose count the receiver had heard a day before was taken for
            // the session going on and its reports shown current: tenth black-box tester, N5.)
            if got == known && s.release_before_us.is_some() && s.release_since_us > heard {
                self.refute_unvouched();
                return Err(FrameError::WrongReleaseCount { known, got });
            }
            if count_ahead(known, got).is_some_and(|d| d > 0) {
                // Newer than any count seen: a genuine restart, however far its release number
                // jumped.
                s.restart_jump = 0;
            }
        }
        s.give_count(got, link.release(), link.counter, link.locomotive);
        if let Some(votes) = replaces {
            s.count_votes = votes;
        }
        s.rival_count = None;
        s.rival_votes = 0;
        s.refuted = false;
        self.st.session = Some(s);
        if replaces.is_some() {
            // The newest count of the locomotive was the corrupt one's: the one that replaced it
            // is the newest (else the genuine sessions after it read as behind).
            if let Some(slot) = self.st.newest_count.get_mut(usize::from(s.identity.locomotive & 0x3F)) {
                *slot = Some((got, now));
            }
        }
        if !s.tentative {
            self.note_count(s.identity.locomotive, got, now);
            if let Some(f) = self.st.fleet.get_mut(usize::from(link.locomotive_slot())) {
                *f = Some(link.locomotive);
            }
        }
        self.decide_awaiting_count(rec);
        rec.identity = Some(s.identity);
        Ok(report)
    }

    /// The session frame right after a status frame that was refused after a silence only
    /// because its 6-bit release number did not look newer (equal, or 32–63 on: it reads as
    /// behind): when it follows that status frame (its counter, locomotive and release number,
    /// within [`TOLERANCE_US`]) and its count is newer than any seen from the locomotive, by no
    /// more than the time since allows, the monitor restarted after 64 or more releases this
    /// receiver did not hear (sixth black-box attacker, F3: it had been refused until
    /// the receiver was reset). The session opens (tentative) from that status frame, with
    /// this count; the status frame stays flagged.
    fn restart_by_count(
        &mut self,
        now: u64,
        link: &super::codec::SessionLink,
        status: &StatusLink,
        at: u64,
        rec: &mut Reception,
    ) -> Result<(), FrameError> {
        let loco = status.identity.locomotive & 0x3F;
        if link.locomotive_slot() != loco
            || link.counter != status.counter
            || link.release() != status.identity.release & 0x3F
        {
            return Err(FrameError::NoHeartbeat);
        }
        if !self.same_unit(link) {
            return Err(FrameError::ForeignSender { locomotive: link.locomotive });
        }
        if !(0..=SESSION_LATE_MAX_US as i64).contains(&diff(now, at)) {
            return Err(FrameError::Untimely { off_ms: ms(diff(now, at)) });
        }
        // No count heard: a unit that showed it is of layout 2 (it sends no session frames and
        // seals its reports as a young unit, `Session::young_shown`) is taken at its release
        // number as its count, the count of a unit whose numbers are below 64. A layout-3.2 unit
        // fitted in its place after a stop, its release number reading as behind, was refused
        // frame by frame (thirteenth black-box tester: 889 genuine frames of a trial flagged).
        // Its session opens; its next session frame gives the count, as at first contact, since
        // no count of the locomotive is known.
        let young = || {
            self.st
                .lost
                .filter(|p| p.young_shown && p.identity.locomotive == loco)
                .map(|p| (u32::from(self.st.newest_release[usize::from(loco)]), p.at_us))
        };
        let Some((known, heard)) = self.newest_count(loco).or_else(young) else {
            return Err(FrameError::NoHeartbeat);
        };
        let got = link.release_count;
        if got == known || count_ahead(known, got).is_none() {
            return Err(FrameError::WrongReleaseCount { known, got });
        }
        self.open(at, status, true, rec);
        if count_within_time(known, heard, got, now) {
            if let Some(s) = self.st.session.as_mut() {
                s.give_count(got, link.release(), link.counter, link.locomotive);
            }
            return Ok(());
        }
        // Newer than any count seen, but further on than the time since allows: another unit
        // (a spare fitted while this receiver heard nothing), or a corruption. The session opens
        // refuted, as one whose session frame carried that count while its release number read
        // as newer does: its frames are shown, not current, its reports sealed with that count
        // too ([`Session::rival_count`]). Before, every later frame of a spare whose release
        // number read as behind was flagged (a thirteenth black-box tester: 901 genuine frames
        // of one unit swap).
        if let Some(s) = self.st.session.as_mut() {
            s.rival_count = Some((got, link.release()));
            s.rival_votes = 1;
        }
        self.refute_unvouched();
        Err(FrameError::WrongReleaseCount { known, got })
    }

    fn fault(&mut self, now: u64, bits: u64, rec: &mut Reception) -> Result<Report, FrameError> {
        let withdrawn_before = rec.withdrawn;
        let result = self.judge_fault(now, bits, rec);
        if let Err(FrameError::Conflicting { .. }) = result {
            // Flagged, and the report it conflicts with withdrawn.
            rec.withdrawn = withdrawn_before.saturating_add(1);
            rec.count_corrupt = false;
        } else if result.is_err() {
            // A flagged frame moves nothing: what judging it would have withdrawn stays.
            rec.withdrawn = withdrawn_before;
            rec.count_corrupt = false;
        } else if now <= self.st.two_streams_until {
            // Two streams of this locomotive were heard: no report is current until one of them
            // has been silent for the hold.
            rec.two_streams = true;
            rec.stale = true;
        } else if now <= self.st.relock_unconfirmed_until {
            rec.relock_unconfirmed = true;
            rec.stale = true;
        }
        result
    }

    fn judge_fault(&mut self, now: u64, bits: u64, rec: &mut Reception) -> Result<Report, FrameError> {
        // After a silence the report is judged against the session lost to it (the sender may
        // well be alive: a fresh report of its release shows it), but it is not current: no
        // live heartbeat vouches for it ([`Reception::stale`]). It does not reopen the session,
        // only a heartbeat does.
        let in_lost = self.st.session.is_none();
        let Some(mut s) = self.st.session.or(self.st.lost) else { return Err(FrameError::NoHeartbeat) };
        let tau = l::TIME_SINCE_RELEASE.get(bits) as u16;
        let tau_us = u64::from(tau) * TAU_STEP_US;
        // Its release: the session's, or the next one if it began after the last heartbeat,
        // or the one before a rise of the release number that rests on one heartbeat.
        let this = s.identity;
        let next = Identity { release: (this.release + 1) & 0x3F, ..this };
        let may_be_next = tau_us <= now.saturating_sub(s.at_us).saturating_add(TOLERANCE_US + TAU_ROUNDING_US);
        let prev = s.release_prev.map(|(r, ..)| Identity { release: r, ..this });
        let mut by_rival = false;
        let identity = match self.fault_crc(&s, bits, this) {
            Ok(()) => this,
            Err(e) => {
                if may_be_next && self.fault_crc(&s, bits, next).is_ok() {
                    next
                } else if let Some(p) = prev.filter(|p| self.fault_crc(&s, bits, *p).is_ok()) {
                    p
                } else if let Some(id) = [Some(this), may_be_next.then_some(next)]
                    .into_iter()
                    .flatten()
                    .find(|id| self.rival_fits(&s, bits, *id))
                {
                    by_rival = true;
                    id
                } else if self.binding_unknown(&s) {
                    // (Before the unit's count is known, a fit as a young unit's at another
                    // release is no evidence: a genuine report of an older unit fits one of the
                    // 63 with a chance of one in four, and was dropped by the next heartbeat:
                    // twelfth black-box tester, F7.)
                    return self.hold_for_count(s, in_lost, now, bits, rec);
                } else if in_lost || s.tentative {
                    // (A tentative session rests on one frame, which may be old: F3.)
                    return self.hold_unattributed(&s, now, bits, e, rec);
                } else {
                    return Err(e);
                }
            }
        };
        let report = decode_signals(MessageKind::Fault, bits)?;
        let undo_release = Some(identity) == prev && identity != this && identity != next;
        if undo_release {
            // A genuine report of the release before the rise: the rise was a corruption the
            // CRC missed. The report is judged against the release it belongs to (kept only
            // if it is accepted).
            if let Some((r, before, since)) = s.release_prev.take() {
                s.identity.release = r;
                s.release_before_us = before;
                s.release_since_us = since;
            }
        }
        let counter = l::FAULT_COUNTER.get(bits) as u8;
        // A status frame's count that contradicted the chain of accepted reports is decided by
        // this report (kept only if it is accepted): whichever of the two it continues with
        // fewer reports lost was right ([`CountClaim`]). The report the status frame overtook
        // (one before its count) continues the count.
        let mut claim_lost = 0;
        let mut provisional = false;
        if let Some(mut claim) = s.count_claim.take() {
            let overtaken = !claim.withdraws && counter == claim.count.wrapping_sub(1) & 0xF;
            let by_claim = if overtaken { 0 } else { counter.wrapping_sub(claim.count) & 0xF };
            let by_chain = counter.wrapping_sub(claim.chain_next) & 0xF;
            if s.count_wins(&claim, by_claim, by_chain, now) {
                (rec.withdrawn, claim_lost) = s.accept_claim(claim);
            } else {
                // Judged against the chain; the next status frame decides.
                s.next_fault = claim.chain_next;
                s.owed_fault = None;
                claim.provisional = claim.provisional.saturating_add(1);
                claim.chain_next = (counter + 1) & 0xF;
                s.count_claim = Some(claim);
                provisional = true;
            }
        }
        let key = bits & !(l::FAULT_CRC.mask() | l::FAULT_COUNTER.mask() | l::TIME_SINCE_RELEASE.mask());
        let slack = (TOLERANCE_US + TAU_ROUNDING_US) as i64;
        let start = diff(now, tau_us);
        let mut replaced = false;
        // The report before was early for its release start (its time since release said it was
        // sent before it could have been), and this one, the next the sender counted, carries a
        // time not larger but fits the start the reports before it set: the early one was the
        // odd one (a corruption of its time that kept the CRC), not this genuine one. Judged
        // against the reports before it, and it replaces the early one (else the genuine
        // reports after a corrupted time were flagged as not newer). A genuine report never
        // carries a time not larger than the one before (at least one 0.1 s step apart).
        let mut dropped_early = None;
        if let (Some(f), Some(b)) = (s.fault, s.fault_before) {
            let since_b = diff(now, 0).saturating_sub(b.start_us);
            let off_b = since_b.saturating_sub(tau_us as i64);
            if f.early
                && f.release == identity.release
                && b.release == identity.release
                && tau <= f.tau
                && tau > b.tau
                && counter == f.counter.wrapping_add(1) & 0xF
                && off_b.abs() <= slack + drift(since_b.unsigned_abs()) as i64
            {
                s.fault = Some(b);
                dropped_early = Some(f.pending);
            }
        }
        let track = match s.fault {
            Some(f) => {
                let gap = diff(now, f.at_us);
                // The 1 s bound holds between two unchanged reports sent one after the other (or
                // a copy); a report lost between them (counter skipped) may have been a change.
                let repeat =
                    f.release == identity.release && f.key == key && counter.wrapping_sub(f.counter) & 0xF <= 1;
                // (Less the latency steps the receiver follows: a latency that fell between two
                // repeats brings them closer.)
                let min_gap = if repeat { FAULT_REPEAT_US - MAX_LATENCY_STEP_US } else { FAULT_MIN_GAP_US };
                // A short gap after a delayed report is no flood when the sender's own times say
                // the two were sent far enough apart (this one's timing against the release start
                // is still checked below): the report after one delayed within the tolerance was
                // flagged (second independent attack test). A copy or a flood carries the same
                // time.
                let sent_apart =
                    f.release == identity.release && tau > f.tau && u64::from(tau - f.tau) * TAU_STEP_US >= min_gap;
                if gap < (min_gap - TOLERANCE_US) as i64 && !sent_apart {
                    return Err(FrameError::RateExceeded { gap_ms: ms(gap.max(0)) as u32 });
                }
                // A release start that rests on one unverified report, contradicted by this report
                // whose start the session can vouch for: this one replaces it.
                let replaces = f.release == identity.release
                    && f.single
                    && f.unverified
                    && start.saturating_sub(f.start_us).abs() > slack
                    && start >= s.power_up_us.saturating_sub(slack)
                    && self.first_of_release(&s, identity, start, slack) == Ok(false);
                if replaces {
                    replaced = true;
                    rec.withdrawn = rec.withdrawn.saturating_add(s.withdraw_unconfirmed());
                    if rec.withdrawn == 0 {
                        // The report it replaces had been counted by a status frame already.
                        rec.withdrawn = 1;
                        s.fault = None;
                        s.last_fault_counter = None;
                    }
                    FaultTrack::first(now, identity.release, tau, start, key, counter, false)
                } else if f.release == identity.release {
                    if tau < f.tau || (tau == f.tau && tau != TAU_SATURATED) {
                        if f.single && counter == f.counter.wrapping_sub(1) & 0xF && now > f.at_us {
                            // The report the release's first accepted one skipped, arriving
                            // after it: a reordered pair. The first came early by the pair's
                            // distance and set the release start that much too early.
                            let mut g = f;
                            g.start_us = g.start_us.saturating_add(i64::from(f.tau - tau) * TAU_STEP_US as i64);
                            // Or this one was delayed (by more than the pair's distance): the
                            // start before the move stays a candidate, which the next report
                            // confirms by agreeing with it.
                            g.late_start_us = Some(f.start_us);
                            self.set_fault(g, in_lost);
                        }
                        return Err(FrameError::Stale { last: f.tau, got: tau });
                    }
                    // Late: more than the tolerance and the field's rounding after its time
                    // since release says, unless the report before was late the same way (a
                    // latency step, followed up to MAX_LATENCY_STEP_US). Early (up to half a
                    // second): the release start was set by a delayed report (it is not moved:
                    // an early report may as well be the first of a reordered pair).
                    let since = diff(now, 0).saturating_sub(f.start_us);
                    let off = since.saturating_sub(tau_us as i64);
                    let limit = slack + drift(since.unsigned_abs()) as i64;
                    let saturated = tau == TAU_SATURATED;
                    let mut start_us = f.start_us;
                    let mut lag_us = f.lag_us;
                    if off > limit && !saturated {
                        let step = f.late_start_us.is_some_and(|ls| start.saturating_sub(ls).abs() <= slack)
                            && f.lag_us.saturating_add(off) <= MAX_LATENCY_STEP_US as i64;
                        if !step {
                            let mut g = f;
                            g.late_start_us = Some(start);
                            self.set_fault(g, in_lost);
                            return Err(FrameError::Untimely { off_ms: ms(off) });
                        }
                        start_us = start;
                        lag_us = lag_us.saturating_add(off);
                    } else if off < -(FAULT_EARLY_US as i64) {
                        // Early beyond what a latency change explains: the release start rests on
                        // one report that came late (a delayed first report), or this one is
                        // old. Two reports in a row that agree on the earlier start, which the
                        // heartbeats allow, move it there; one alone is flagged.
                        let agrees = f.late_start_us.is_some_and(|ls| start.saturating_sub(ls).abs() <= slack);
                        if !(f.single && agrees && self.first_of_release(&s, identity, start, slack).is_ok()) {
                            let mut g = f;
                            g.late_start_us = Some(start);
                            self.set_fault(g, in_lost);
                            return Err(FrameError::Untimely { off_ms: ms(off) });
                        }
                        start_us = start;
                    }
                    // Early beyond the tolerance against a release start more than one report
                    // set (one resting on a single report may have been set by a delayed
                    // one): one frame does not move the reference. Accepted but not current;
                    // the next report early the same way moves the start (the latency fell).
                    let mut pending = false;
                    let mut late_start_us = None;
                    if off < -limit && off >= -(FAULT_EARLY_US as i64) && !saturated && !f.single {
                        if f.late_start_us.is_some_and(|ls| start.saturating_sub(ls).abs() <= slack) {
                            lag_us = lag_us.saturating_add(start.saturating_sub(start_us)).max(0);
                            start_us = start;
                        } else {
                            pending = true;
                            late_start_us = Some(start);
                        }
                    }
                    FaultTrack {
                        at_us: now,
                        release: f.release,
                        tau,
                        start_us,
                        key,
                        counter,
                        single: false,
                        unverified: false,
                        lag_us,
                        late_start_us,
                        early: diff(now, 0).saturating_sub(start_us).saturating_sub(tau_us as i64)
                            < -(TAU_ROUNDING_US as i64),
                        pending,
                    }
                } else {
                    let unverified = self.first_report(&s, identity, start, slack, in_lost)?;
                    FaultTrack::first(now, identity.release, tau, start, key, counter, unverified)
                }
            }
            None => {
                let unverified = self.first_report(&s, identity, start, slack, in_lost)?;
                FaultTrack::first(now, identity.release, tau, start, key, counter, unverified)
            }
        };
        // Its counter must be newer than the last accepted report's, and reports the sender
        // counted in between (status frame count, or this counter) were lost; while the
        // 4-bit counter cannot have wrapped since (16 reports take at least 1.6 s).
        let recent = s.fault.is_some_and(|f| diff(now, f.at_us) < (16 * FAULT_MIN_GAP_US - TOLERANCE_US) as i64);
        if let (Some(last), true) = (s.last_fault_counter, recent) {
            let d = counter.wrapping_sub(last) & 0xF;
            if d == 0 {
                // The counter of the report held, with other content, on time for the release
                // as that one was: the sender never sends two reports with one counter, so one
                // of the two is another sender's whose CRC happens to fit (or a corruption that
                // kept it). Nothing tells which: the held one is withdrawn and this one
                // refused, and the next report decides. A fifteenth black-box tester's such
                // report, heard before the genuine one, was shown current and the genuine one
                // flagged `stale`.
                let held = s.fault.filter(|f| f.release == identity.release && f.counter == counter);
                if held.is_some_and(|f| f.key != key) && !in_lost {
                    if let Some(stored) = self.st.session.as_mut() {
                        stored.fault = stored.fault_before.take();
                        if let Some(u) = stored.unconfirmed.as_mut() {
                            u.reports = u.reports.saturating_sub(1);
                        }
                    }
                    return Err(FrameError::Conflicting { counter });
                }
                return Err(FrameError::Stale { last: u16::from(last), got: u16::from(counter) });
            }
        }
        // The counter tells how many reports the sender sent since the receiver last learnt its
        // count (the last status frame or accepted report), modulo 16; the rate bound caps how
        // many it can have sent. A counter that no count within the cap explains is flagged:
        // behind the count (a report sent before that frame: old, unless it is the report that
        // frame overtook) or further ahead than the time allows.
        let d = counter.wrapping_sub(s.next_fault) & 0xF;
        let learnt = s.count_learnt_us();
        let possible = reports_possible(learnt, now);
        let overtaken = s.owed_fault == Some(counter)
            || (d == 15 && s.last_fault_counter.is_none() && now.saturating_sub(s.at_us) <= TOLERANCE_US);
        if !replaced && !overtaken && u64::from(d) > possible {
            return Err(if d >= 8 {
                FrameError::Stale { last: u16::from(s.next_fault.wrapping_sub(1) & 0xF), got: u16::from(counter) }
            } else {
                FrameError::RateExceeded { gap_ms: ms(diff(now, learnt).max(0)) as u32 }
            });
        }
        let mut unconfirmed = s.unconfirmed.unwrap_or(Unconfirmed {
            fault: s.fault,
            last_fault_counter: s.last_fault_counter,
            next_fault: s.next_fault,
            owed_fault: s.owed_fault,
            reports: 0,
        });
        unconfirmed.reports = unconfirmed.reports.saturating_add(1);
        // A report of the next release rests on its time alone until a heartbeat carries that
        // release ([`Decoder::check_next_release`]): what to go back to.
        let mut from_next = s.next_release_from.or_else(|| {
            (identity == next).then_some(Unconfirmed {
                fault: s.fault,
                last_fault_counter: s.last_fault_counter,
                next_fault: s.next_fault,
                owed_fault: s.owed_fault,
                reports: 0,
            })
        });
        if let Some(n) = from_next.as_mut() {
            n.reports = n.reports.saturating_add(1);
        }
        // A report the last status frame counted and this is not: lost.
        let mut lost = s.owed_fault.take().map_or(0, |o| u8::from(o != counter));
        if !overtaken && u64::from(d) <= possible {
            // (A report the status frame overtook is the owed one: d = 15.)
            lost += d;
        }
        rec.lost_fault_reports = lost.saturating_add(claim_lost);
        s.next_fault = (counter + 1) & 0xF;
        s.last_fault_counter = Some(counter);
        s.recent_reports_us.rotate_right(1);
        s.recent_reports_us[0] = now;
        // Heartbeats overdue at this moment were lost (a deleted status frame is noticed even
        // when no status frame follows before the sender stops).
        let overdue = (now.saturating_sub(s.at_us).saturating_sub(TOLERANCE_US) / STATUS_PERIOD_US)
            .min(u64::from(u16::MAX)) as u16;
        // A heartbeat that came late and was flagged (the first of a latency step, or delayed)
        // was not lost, and its lateness, up to the latency step the receiver follows, delays
        // when the next one is missed (else a latency step claimed a lost status frame, and the
        // reports of the second after it were shown stale though the sender was heard).
        let missed = match late_heartbeat(&s) {
            Some(late_us) => {
                let m = now.saturating_sub(s.at_us).saturating_sub(TOLERANCE_US + late_us) / STATUS_PERIOD_US;
                (m.min(u64::from(u16::MAX)) as u16).saturating_sub(1)
            }
            None => overdue,
        };
        if missed > s.overdue_reported {
            rec.lost_status = missed - s.overdue_reported;
            s.overdue_reported = missed;
        }
        // No heartbeat on time vouches for it: accepted (it may be genuine: a status frame was
        // lost), but not current (a delayed stream, whose heartbeats are flagged, shows here).
        rec.early = track.pending;
        rec.delayed_stream = s.lag_us > MAX_LATENCY_STEP_US as i64;
        rec.release_unconfirmed = self.count_unconfirmed(&s) || by_rival;
        if !by_rival && s.count_base.or(s.count_to_confirm).is_some() {
            s.count_proven = true;
        }
        rec.stale = missed > 0
            || track.unverified
            || s.restart_jump > 0
            || provisional
            || track.pending
            || rec.delayed_stream
            || rec.release_unconfirmed;
        // The early report this one replaced: a display that showed it as current stops showing
        // it (one not shown as current was never held).
        if dropped_early == Some(false) {
            rec.withdrawn = rec.withdrawn.saturating_add(1);
        }
        if dropped_early.is_some() {
            unconfirmed.reports = unconfirmed.reports.saturating_sub(1);
        }
        s.fault_before = s.fault;
        rec.restart_jump = s.restart_jump;
        if undo_release && !s.refuted {
            self.st.newest_release[usize::from(s.identity.locomotive & 0x3F)] = s.identity.release;
        }
        s.fault = Some(track);
        // (The report the status frame overtook was counted by it already.)
        s.unconfirmed = if overtaken && s.unconfirmed.is_none() { None } else { Some(unconfirmed) };
        s.next_release_from = from_next;
        if in_lost {
            self.st.lost = Some(s);
            rec.stale = true;
        } else {
            self.st.session = Some(s);
        }
        rec.identity = Some(identity);
        Ok(report)
    }

    /// A fault report after a silence whose CRC fails for the lost session's release (and the
    /// next): the sender may have run on while this receiver heard nothing, so a release further
    /// on — no more than one a second of silence allows — is tried; in a tentative session
    /// (`lost` is then the session), whose one frame may be an old replay, every release of its
    /// locomotive. One that fits is held as
    /// unattributed (accepted, not current) until the next heartbeat decides
    /// ([`Self::attribute_held`]); none fitting, or the hold full: flagged with `e`. (It was
    /// flagged `wrong_crc` always: no live heartbeat attributed it.)
    fn hold_unattributed(
        &mut self,
        lost: &Session,
        now: u64,
        bits: u64,
        e: FrameError,
        rec: &mut Reception,
    ) -> Result<Report, FrameError> {
        let silence = now.saturating_sub(lost.at_us);
        // A tentative session's one frame may be a replay of any age: every release.
        let possible = if lost.tentative { 63 } else { (1 + silence / MIN_RELEASE_US).min(63) as u8 };
        let found = (1..=possible)
            .map(|on| Identity { release: lost.identity.release.wrapping_add(on) & 0x3F, ..lost.identity })
            .find(|id| self.fault_crc(lost, bits, *id).is_ok());
        let (Some(identity), Some(slot)) = (found, self.st.unattributed.get_mut(usize::from(self.st.unattributed_len)))
        else {
            return Err(e);
        };
        let report = decode_signals(MessageKind::Fault, bits)?;
        *slot = (now, bits);
        self.st.unattributed_len += 1;
        rec.unattributed = true;
        rec.stale = true;
        rec.identity = Some(identity);
        Ok(report)
    }

    /// The heartbeat just accepted (`bits`, at `now`) decides the unattributed fault reports
    /// held: one fits when its CRC passes for the heartbeat's locomotive and release (or the
    /// release before: a release command between the two), its counter is one the heartbeat's
    /// `FaultReportCount` counted (within the reports the rate bound allows since it came),
    /// and its release began before the heartbeat. They are not fed into the fault-report
    /// chain (they came before the frame that attributes them); a display shows the ones that
    /// fit as past reports, and drops the others. The reports held for the unit's count
    /// ([`Self::hold_for_count`]) whose CRC fits so are decided the same way (a unit that sends
    /// no session frame, layout 2); the others wait for the session frame, which alone can tell.
    fn attribute_held(&mut self, now: u64, bits: u64, rec: &mut Reception) {
        let n = usize::from(core::mem::take(&mut self.st.unattributed_len));
        let link = status_link(bits);
        let Some(s) = self.st.session else { return };
        // (CRC fits the heartbeat's release or the one before, and counted and begun in time.)
        let fits = |d: &Self, (at, fb): (u64, u64)| {
            let id = link.identity.masked();
            let before = Identity { release: id.release.wrapping_sub(1) & 0x3F, ..id };
            let crc_fits = d.fault_crc(&s, fb, id).is_ok() || d.fault_crc(&s, fb, before).is_ok();
            let counter = l::FAULT_COUNTER.get(fb) as u8;
            let count = link.fault_count & 0xF;
            let counted = u64::from(count.wrapping_sub(1).wrapping_sub(counter) & 0xF) <= reports_possible(at, now);
            let tau_us = l::TIME_SINCE_RELEASE.get(fb) * TAU_STEP_US;
            let began_before = at <= now.saturating_add(TOLERANCE_US) && tau_us.saturating_add(now) >= at;
            (crc_fits, counted && began_before)
        };
        for &held in self.st.unattributed.iter().take(n) {
            if fits(self, held) == (true, true) {
                rec.unattributed_fitting = rec.unattributed_fitting.saturating_add(1);
            } else {
                rec.unattributed_rejected = rec.unattributed_rejected.saturating_add(1);
            }
        }
        let waiting = usize::from(self.st.awaiting_count_len);
        let mut kept = 0;
        for k in 0..waiting.min(UNATTRIBUTED_MAX) {
            let held = self.st.awaiting_count[k];
            match fits(self, held) {
                (true, true) => rec.unattributed_fitting = rec.unattributed_fitting.saturating_add(1),
                (true, false) => rec.unattributed_rejected = rec.unattributed_rejected.saturating_add(1),
                // The unit sends no session frames: sealed as a young unit's, it does not fit.
                (false, _) if s.young_shown => {
                    rec.unattributed_rejected = rec.unattributed_rejected.saturating_add(1);
                }
                // (Its CRC may bind a count this receiver has not heard: the session frame tells.)
                (false, _) => {
                    self.st.awaiting_count[kept] = held;
                    kept += 1;
                }
            }
        }
        self.st.awaiting_count_len = kept as u8;
    }

    /// Updates the fault track of the session a flagged report was judged against (the
    /// reordered-pair and latency-step evidence), nothing else.
    fn set_fault(&mut self, f: FaultTrack, in_lost: bool) {
        let s = if in_lost { self.st.lost.as_mut() } else { self.st.session.as_mut() };
        if let Some(s) = s {
            s.fault = Some(f);
        }
    }

    /// [`Decoder::first_of_release`] for a report about to be accepted as the first of its
    /// release: a report flagged as late for the release's first heartbeat leaves its release
    /// start as evidence of a latency step ([`Session::first_late`]), which the next report
    /// confirms by agreeing with it.
    fn first_report(
        &mut self,
        s: &Session,
        identity: Identity,
        start: i64,
        slack: i64,
        in_lost: bool,
    ) -> Result<bool, FrameError> {
        let r = self.first_of_release(s, identity, start, slack);
        if let Err(FrameError::Untimely { off_ms }) = r {
            if off_ms < 0 {
                let held = if in_lost { self.st.lost.as_mut() } else { self.st.session.as_mut() };
                if let Some(h) = held {
                    h.first_late = Some((identity.release, start));
                }
            }
        }
        r
    }

    /// The first report of a release must place its release command in the window the
    /// heartbeats allow. `Ok(true)`: the window has no lower bound (no heartbeat of the
    /// previous release seen) and the start lies before the monitor's power-up as the session's
    /// first heartbeat counted it: the report cannot be vouched for (it may be genuine, from a
    /// monitor whose 68-minute counter had wrapped).
    fn first_of_release(&self, s: &Session, identity: Identity, start: i64, slack: i64) -> Result<bool, FrameError> {
        let (earliest, latest) = if identity.release == s.identity.release {
            (s.release_before_us, Some(s.release_since_us))
        } else {
            (Some(s.at_us), None)
        };
        if let Some(e) = earliest {
            let off = diff(e, 0).saturating_sub(start);
            if off > slack {
                // Began before the previous release's last heartbeat: an older release's report.
                return Err(FrameError::Untimely { off_ms: ms(off) });
            }
        }
        if let Some(lt) = latest {
            // (A latency step the session clock followed since lets the reports come later
            // than the release's first heartbeat did, by up to that step; so does a step the
            // report flagged before this one showed, at the same release start: a latency
            // step that began at the release's first report.)
            let off = start.saturating_sub(diff(lt, 0));
            let step_shown =
                s.first_late.is_some_and(|(r, ls)| r == identity.release && start.saturating_sub(ls).abs() <= slack)
                    && off <= slack.saturating_add(MAX_LATENCY_STEP_US as i64);
            if off > slack.saturating_add(s.lag_us) && !step_shown {
                return Err(FrameError::Untimely { off_ms: -ms(off) });
            }
        }
        Ok(earliest.is_none() && start < s.power_up_us.saturating_sub(slack))
    }
}

// ---- Re-locking onto a stepped heartbeat phase (issue 18, F1 of the second black-box tester) ----
//
// A lasting step of the frames' phase beyond what the session clock follows (a latency step
// over MAX_LATENCY_STEP_US, a latency that ends after the session clock was set by it, a step
// of the logger's or display's clock) made every later heartbeat untimely, the session time
// out, and every later frame of the sender be refused, its release number no longer followed.
// The receiver now re-locks on genuine evidence only: RELOCK_RUN consecutive heartbeats at one
// new phase, each newer than the session's last, with a release number and a fault-report
// count the session allows, and each continuing the one before in counter and time. While the
// sender's genuine heartbeats are heard at the old phase, no frame can build such a run (a copy
// or a delayed replay is never newer than the genuine heartbeat accepted): only a stream whose
// every heartbeat moved does.

/// Newer heartbeats of a session flagged one after the other at one phase other than the
/// session clock's: the last one, and how many in a row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct PhaseRun {
    /// Counter and receive time of the last heartbeat of the run.
    counter: u16,
    at_us: u64,
    /// Its release number and `FaultReportCount`.
    release: u8,
    count: u8,
    /// Heartbeats in the run.
    len: u8,
}

/// The run of session `s` this status frame extends (or starts), and how far the frame's phase
/// is from the session clock (µs, positive: later); `None` when the frame cannot belong to the
/// session's sender running on (another locomotive, a counter not newer, a release number or a
/// fault-report count the time since does not allow, a phase further off than
/// [`MAX_RELOCK_US`]).
fn phase_run(s: &Session, now: u64, link: &StatusLink) -> Option<(PhaseRun, i64)> {
    let release = link.identity.release & 0x3F;
    let count = link.fault_count & 0xF;
    let d = link.counter.wrapping_sub(s.counter) % COUNTER_MOD;
    let span = u64::from(d) * STATUS_PERIOD_US;
    let consistent = |last_release: u8, last_count: u8, periods: u16, span: u64| {
        release_not_before(release, last_release)
            && u16::from(release.wrapping_sub(last_release) & 0x3F) <= 1 + periods
            && u64::from(count.wrapping_sub(last_count) & 0xF) <= reports_possible(0, span)
    };
    if link.identity.locomotive & 0x3F != s.identity.locomotive
        || !(1..COUNTER_MOD / 2).contains(&d)
        || !consistent(s.identity.release, s.status_count, d, span)
    {
        return None;
    }
    let due = s.anchor_us.saturating_add(i64::try_from(span).unwrap_or(i64::MAX));
    let shift = diff(now, 0).saturating_sub(due);
    if shift.unsigned_abs() > MAX_RELOCK_US {
        return None;
    }
    // Back at the phase the session had before it re-locked (a gateway latency that ended):
    // the phase the session was first locked onto, at once.
    // Only a frame off the session clock: one on time at it is the session going on (a
    // thirteenth black-box tester's gateway latency that began and ended, with 1 ms of time-stamp
    // jitter, left the session a few ms off its first phase, and every later heartbeat, on time,
    // "re-locked" onto it, its reports never current again).
    let tol = i64::try_from(TOLERANCE_US + drift(span)).unwrap_or(i64::MAX);
    if s.relocked_us != 0 && shift.abs() > tol && shift.saturating_add(s.relocked_us).abs() <= tol {
        return Some((PhaseRun { counter: link.counter, at_us: now, release, count, len: RELOCK_RUN }, shift));
    }
    // A frame not newer than the run's last (a copy, a replay) neither extends nor breaks it
    // (else a second path delivering every frame twice, or an injected copy, kept the receiver
    // from ever re-locking).
    if s.phase_run
        .is_some_and(|r| !(1..COUNTER_MOD / 2).contains(&(link.counter.wrapping_sub(r.counter) % COUNTER_MOD)))
    {
        return None;
    }
    let len = s.phase_run.map_or(1, |r| {
        let dc = link.counter.wrapping_sub(r.counter) % COUNTER_MOD;
        let span = u64::from(dc) * STATUS_PERIOD_US;
        let in_phase = diff(now, r.at_us).saturating_sub(span as i64).unsigned_abs() <= TOLERANCE_US + drift(span);
        if (1..=RELOCK_MAX_STEP).contains(&dc) && in_phase && consistent(r.release, r.count, dc, span) {
            r.len.saturating_add(1)
        } else {
            1
        }
    });
    Some((PhaseRun { counter: link.counter, at_us: now, release, count, len }, shift))
}

impl Decoder {
    /// The session clock moved away from `before`'s phase at `now` (a re-lock, or two early
    /// heartbeats): watch the old phase for a second stream ([`Self::watch_old_stream`]), and
    /// show no report current for the heartbeat period in which it could not have shown yet.
    fn watch_after_move(&mut self, before: Session, now: u64) {
        self.st.before_relock = Some((before, now.saturating_add(TWO_STREAMS_HOLD_US)));
        self.st.relock_unconfirmed_until = now.saturating_add(STATUS_PERIOD_US + TOLERANCE_US);
    }

    /// After a move of the session clock: a heartbeat that continues the session from before it,
    /// on time at the old phase ([`continuation`]) and not newer than the stream followed, is a
    /// second stream of the locomotive ([`Reception::two_streams`]). The
    /// old session follows it (so the next one is recognised too) and the watch and the hold
    /// on fault reports run on from it.
    fn watch_old_stream(&mut self, now: u64, link: &StatusLink, rec: &mut Reception) {
        let Some((mut old, until)) = self.st.before_relock else { return };
        if now > until {
            self.st.before_relock = None;
            return;
        }
        let Some(current) = self.st.session else { return };
        // A heartbeat newer than the stream followed now is that stream moving back (a latency
        // that ended, a flapping gateway): the normal rules take it. A second stream is one
        // that goes on behind the one followed.
        let ahead = link.counter.wrapping_sub(current.counter) % COUNTER_MOD;
        if link.identity.locomotive & 0x3F != old.identity.locomotive || (1..COUNTER_MOD / 2).contains(&ahead) {
            return;
        }
        // On time at the old phase (a stream that moved a little earlier is early there, not
        // a second stream).
        if let Some(c) = continuation(&old, now, link).ok().filter(|c| c.phase == Phase::OnTime) {
            let span = c.periods.saturating_mul(STATUS_PERIOD_US);
            old.anchor_us = old.anchor_us.saturating_add(i64::try_from(span).unwrap_or(i64::MAX));
            old.counter = link.counter;
            old.at_us = now;
            old.identity.release = link.identity.release & 0x3F;
            self.st.before_relock = Some((old, now.saturating_add(TWO_STREAMS_HOLD_US)));
            self.st.two_streams_until = now.saturating_add(TWO_STREAMS_HOLD_US);
            rec.two_streams = true;
        }
    }
}

impl Session {
    /// The session with its clock and every receive time it holds moved by `shift` µs: what it
    /// would have been had the phase been the new one from the start. The latency steps
    /// followed and the evidence of off-phase frames start afresh.
    fn shifted(mut self, shift: i64) -> Self {
        let mv = |t: u64| t.saturating_add_signed(shift);
        self.anchor_us = self.anchor_us.saturating_add(shift);
        self.at_us = mv(self.at_us);
        self.release_since_us = mv(self.release_since_us);
        self.release_before_us = self.release_before_us.map(mv);
        self.power_up_us = self.power_up_us.saturating_add(shift);
        self.release_prev = self.release_prev.map(|(r, before, since)| (r, before.map(mv), mv(since)));
        if let Some(f) = self.fault.as_mut() {
            f.at_us = mv(f.at_us);
            f.start_us = f.start_us.saturating_add(shift);
            f.lag_us = 0;
            f.late_start_us = None;
        }
        if let Some(u) = self.unconfirmed.as_mut() {
            if let Some(f) = u.fault.as_mut() {
                f.at_us = mv(f.at_us);
                f.start_us = f.start_us.saturating_add(shift);
            }
        }
        if let Some(f) = self.fault_before.as_mut() {
            f.at_us = mv(f.at_us);
            f.start_us = f.start_us.saturating_add(shift);
        }
        // A rival heartbeat heard at the old phase is no evidence at the new one.
        self.rival = None;
        self.lag_us = 0;
        self.off_phase = None;
        self.first_late = None;
        self.phase_run = None;
        self.relocked_us = self.relocked_us.saturating_add(shift);
        self
    }
}

impl Decoder {
    /// A status frame: the rules of [`Decoder::status`], and re-locking onto a stepped phase.
    /// A frame that completes a run of [`RELOCK_RUN`] heartbeats at one new phase of the open
    /// session (or of the one lost to the silence the step caused) moves the session clock to
    /// that phase and is accepted ([`Reception::relocked_ms`]); a flagged newer heartbeat of the
    /// session extends or starts its run.
    fn status_or_relock(&mut self, now: u64, bits: u64, rec: &mut Reception) -> Result<Report, FrameError> {
        if check_crc(MessageKind::Status, bits, Binding::default()).is_err() {
            return self.status(now, bits, rec);
        }
        let link = status_link(bits);
        self.watch_old_stream(now, &link, rec);
        let loco = link.identity.locomotive & 0x3F;
        let in_lost = self.st.session.is_none();
        let judged = if in_lost { self.st.lost } else { self.st.session };
        let run = judged.filter(|s| s.identity.locomotive == loco).and_then(|s| phase_run(&s, now, &link));
        if let (Some(s), Some((r, shift)), Ok(report)) = (judged, run, decode_signals(MessageKind::Status, bits)) {
            if r.len >= RELOCK_RUN {
                let mut moved = s.shifted(shift);
                // A re-lock switched the receiver onto a stream at another phase (after a
                // silence, or a recording that carries on the heartbeat counter: sixth black-box
                // attacker N2): its count must be given again by a session frame.
                moved.doubt_count();
                if let Ok(c) = continuation(&moved, now, &link) {
                    // (The heartbeats of the run before this one were received, flagged: not lost.)
                    moved.overdue_reported = moved.overdue_reported.max(u16::from(r.len - 1));
                    // Nor were the fault reports sent meanwhile, flagged at the old phase: the
                    // count of the heartbeat that re-locks, consistent with the run's, is the
                    // sender's from here on.
                    let count = link.fault_count & 0xF;
                    moved.next_fault = count;
                    moved.status_count = count;
                    moved.owed_fault = None;
                    moved.count_claim = None;
                    moved.unconfirmed = None;
                    if moved.last_fault_counter.is_some() {
                        moved.last_fault_counter = Some(count.wrapping_sub(1) & 0xF);
                    }
                    if in_lost {
                        self.st.lost = None;
                    }
                    self.accept_status(moved, now, &link, c, rec);
                    rec.relocked_ms = Some(ms(shift));
                    // The stream at the old phase may go on (a recording ahead of the live
                    // monitor re-locked the receiver while genuine heartbeats were lost).
                    self.watch_after_move(s, now);
                    return Ok(report);
                }
            }
        }
        let result = self.status(now, bits, rec);
        if result.is_err() {
            // Still the session it was judged against (a flagged frame replaces none).
            let held = if in_lost { self.st.lost.as_mut() } else { self.st.session.as_mut() };
            // (A frame that is no part of a run leaves the run as it is.)
            if let (Some(h), Some(s), Some((r, _))) = (held, judged, run) {
                if h.identity.locomotive == s.identity.locomotive && h.counter == s.counter {
                    h.phase_run = Some(r);
                }
            }
        }
        result
    }
}
// ---- end of re-locking ----

/// How a heartbeat fits the session clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Within the tolerance.
    OnTime,
    /// Early by more than the tolerance, less than half a period; `confirmed` when the last
    /// off-phase heartbeat showed the same phase.
    Early { confirmed: bool },
    /// Late, at the phase the last (flagged) off-phase heartbeat showed, within
    /// [`MAX_LATENCY_STEP_US`] of the earliest phase: a latency step.
    Step,
}

/// How a status frame continues a session.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Continues {
    /// Heartbeat periods since the session's last accepted one (the counter's advance, beyond
    /// 4095 after a silence longer than the counter's range).
    periods: u64,
    phase: Phase,
    /// It goes back to the release before a rise that rested on one heartbeat.
    undo_release: bool,
    /// Its release number looks older (modulo 64) but a silence long enough lay before it: the
    /// sender went on by more than half the release number's range.
    release_wrapped: bool,
}

/// A newer heartbeat of session `s` flagged as late ([`Session::off_phase`]) by no more than
/// the latency step the receiver follows: how late it was, µs.
fn late_heartbeat(s: &Session) -> Option<u64> {
    let (c, at) = s.off_phase?;
    let dp = c.wrapping_sub(s.counter) % COUNTER_MOD;
    if !(1..COUNTER_MOD / 2).contains(&dp) {
        return None;
    }
    let due = s.anchor_us.saturating_add(i64::from(dp) * STATUS_PERIOD_US as i64);
    let late = diff(at, 0).saturating_sub(due);
    (late > 0 && late.saturating_add(s.lag_us) <= MAX_LATENCY_STEP_US as i64).then_some(late.unsigned_abs())
}

/// A heartbeat flagged late by less than a period (less the tolerance): delayed, not a counter
/// that disagrees with the clock by whole periods.
fn late_within_period(e: FrameError) -> bool {
    matches!(e, FrameError::Untimely { off_ms } if off_ms > 0 && i64::from(off_ms) < ((STATUS_PERIOD_US - TOLERANCE_US) / 1000) as i64)
}

/// Was the last off-phase heartbeat of `s` at the phase of this one (`d` periods apart, within
/// the tolerance)?
fn same_phase(s: &Session, now: u64, link: &StatusLink) -> bool {
    s.off_phase.is_some_and(|(c, at)| {
        let dp = link.counter.wrapping_sub(c) % COUNTER_MOD;
        let span = u64::from(dp) * STATUS_PERIOD_US;
        (1..COUNTER_MOD / 2).contains(&dp)
            && diff(now, at).saturating_sub(span as i64).unsigned_abs() <= TOLERANCE_US + drift(span)
    })
}

/// Does this status frame continue session `s`: later than the rate allows, newer counter, as
/// many seconds later as the counter advanced, release not going back?
fn continuation(s: &Session, now: u64, link: &StatusLink) -> Result<Continues, FrameError> {
    let gap = diff(now, s.at_us);
    let mut d = u64::from(link.counter.wrapping_sub(s.counter) % COUNTER_MOD);
    let half_range = i64::from(COUNTER_MOD / 2) * STATUS_PERIOD_US as i64;
    if gap >= half_range {
        // After a silence of half the counter's range or more (a receiver that heard nothing
        // for 34 min while the sender ran on) the counter alone cannot say how many periods
        // passed: the silence says it, and the counter must agree with it modulo 4096 (the
        // timing test below). Without this a genuine sender stayed locked out for good.
        let periods = gap.saturating_add(STATUS_PERIOD_US as i64 / 2) / STATUS_PERIOD_US as i64;
        let modulus = i64::from(COUNTER_MOD);
        let wraps = periods.saturating_sub(d as i64).saturating_add(modulus / 2).div_euclid(modulus).max(0);
        d = d.saturating_add(wraps.unsigned_abs().saturating_mul(u64::from(COUNTER_MOD)));
    }
    if d == 0 || (gap < half_range && d >= u64::from(COUNTER_MOD / 2)) {
        // Not newer: a copy right after (a flood) or a repetition of an older frame.
        if gap < (STATUS_PERIOD_US - TOLERANCE_US) as i64 {
            return Err(FrameError::RateExceeded { gap_ms: ms(gap.max(0)) as u32 });
        }
        return Err(FrameError::Stale { last: s.counter, got: link.counter });
    }
    // Late: more than the tolerance (and clock drift) after it was due, unless the heartbeat
    // before showed the same lasting step. Early: up to half a period is a session clock set by
    // a delayed frame, or a latency that fell; more is no genuine frame.
    let span = d.saturating_mul(STATUS_PERIOD_US);
    let off = diff(now, 0).saturating_sub(s.anchor_us.saturating_add(i64::try_from(span).unwrap_or(i64::MAX)));
    let tol = (TOLERANCE_US + drift(span)) as i64;
    let phase = if off > tol {
        if same_phase(s, now, link) && s.lag_us.saturating_add(off) <= MAX_LATENCY_STEP_US as i64 {
            Phase::Step
        } else {
            return Err(FrameError::Untimely { off_ms: ms(off) });
        }
    } else if off < -((STATUS_PERIOD_US / 2) as i64) {
        if gap < (STATUS_PERIOD_US - TOLERANCE_US) as i64 {
            return Err(FrameError::RateExceeded { gap_ms: ms(gap.max(0)) as u32 });
        }
        return Err(FrameError::Untimely { off_ms: ms(off) });
    } else if off < -tol {
        Phase::Early { confirmed: same_phase(s, now, link) }
    } else {
        Phase::OnTime
    };
    let release = link.identity.release & 0x3F;
    // The same sender running on (its counter continues: it never powered down) only counts
    // its release number up, by release commands, at most one per MIN_RELEASE_US (and the one
    // of this period): `on` releases since the last heartbeat. More than the time allows is
    // no genuine frame: a lag-4096 replay of another release ahead of its genuine twin (which
    // was accepted, got the twin flagged, and its count the genuine reports withdrawn), or a
    // corruption the CRC missed.
    let on = release.wrapping_sub(s.identity.release) & 0x3F;
    let possible = 1 + gap.max(0).unsigned_abs() / MIN_RELEASE_US;
    let mut undo_release = false;
    let mut release_wrapped = false;
    // Back to the release before a rise that rests on one heartbeat, or on from it: that
    // heartbeat was a corruption the CRC missed, or a replay (of a release 4096 s old).
    if !release_not_before(release, s.identity.release)
        && s.release_prev.is_some_and(|(r, ..)| release_not_before(release, r))
    {
        undo_release = true;
    } else if u64::from(on) > possible {
        return Err(FrameError::WrongRelease { expected: s.identity.release, got: link.identity.release });
    } else if !release_not_before(release, s.identity.release) {
        // 32–63 on looks 32–63 behind modulo 64: after a silence (a receiver cut off while the
        // releases happened: else it refused the live monitor for good) it is taken as on;
        // within a session that is no genuine frame.
        if gap > HEARTBEAT_TIMEOUT_US as i64 {
            release_wrapped = true;
        } else {
            return Err(FrameError::WrongRelease { expected: s.identity.release, got: link.identity.release });
        }
    }
    Ok(Continues { periods: d, phase, undo_release, release_wrapped })
}
