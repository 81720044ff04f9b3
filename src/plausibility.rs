//! Sensor plausibility: is the single pressure signal one that a working transducer on this
//! pneumatic circuit can produce? Runs on every ADC sample, in integer arithmetic on the raw
//! codes, before anything is diagnosed from the signal.
//!
//! The monitor has one sensor and no redundancy, so every check is a statement about what the
//! *physics and the transducer* allow, never about which brake fault is present:
//!
//! | check | evidence | why no working sensor does this |
//! |---|---|---|
//! | [`SensorFault::Frozen`] / [`SensorFault::Dead`] | the same code [`FROZEN_RUN`] times in a row | the transducer's white noise (σ = 0.01 bar = 3.3 codes, SPEC §5) makes two consecutive codes equal with probability ≈ 0.09; 50 in a row has probability ≈ 10⁻⁵², and even at a third of the specified noise ≈ 10⁻²⁸. *Dead* when no code change was seen since the release command, *frozen* when the signal was live before |
//! | [`SensorFault::Noisy`] | mean absolute second difference over 1 s above [`NOISY_MEAN_ABS_D2`] | for white noise σ the mean \|x\[n\] − 2x\[n−1\] + x\[n−2\]\| is 1.95 σ, and the pressure's own second difference is below one code except at the knees; the bound is 4 × the transducer's noise |
//! | [`SensorFault::Spikes`] | one sample far from both neighbours, in the same direction | the chamber is a first-order pneumatic volume: it cannot jump and come back within 20 ms |
//! | [`SensorFault::Dropouts`] | an out-of-range reading followed by a valid one | a transducer does not open-circuit for a few samples and recover |
//! | [`SensorFault::LostResolution`] | a code bit never toggles over [`RESOLUTION_WINDOW`] samples although a higher bit does ([`untoggled_below_top`]): lost low bits, or a data line stuck at 0 or 1 | with 3.3 codes of noise the lowest bit toggles on about half of the samples, and a higher bit only toggles at a crossing that small steps make toggle the lower ones |
//! | [`SensorFault::Clipped`] | the largest code seen piles up: at least [`CLIP_MIN_HITS`] hits and [`CLIP_RATIO`] × more than the code below it | a noisy plateau has a thin upper tail; an amplifier that saturates maps everything above its limit onto one code |
//! | [`SensorFault::ImpossibleRate`] | a jump that stays (a step), or a change over 0.1 s faster than any orifice can fill | the fastest fill the circuit allows (a missing 4 mm orifice) is ≈ 8 bar/s, 27 codes a sample |
//! | [`SensorFault::ImplausibleLevel`] | a reading below atmosphere (0.15 bar under for 5 samples, or the first three samples of a release 0.05 bar under on average), or a non-zero reading at a release command after the chamber had time to vent | the chamber is vented to atmosphere when the brake is applied |
//!
//! A reading above 0.15 bar g at the command without a vented rest before it (a recorded trace
//! starts at the command) cannot tell a zero offset from a chamber that was not vented; either
//! way it is no release the twin can judge: [`SignalCheck::unvented_start`], which the monitor
//! reports as *unfamiliar release*.
//!
//! Open and short circuit ([`SensorFault::OpenCircuit`], [`SensorFault::ShortCircuit`]) are the
//! range check of [`crate::sensor::pressure_from_adc`]; they are reported per sample.
//!
//! # Latching and onset
//!
//! The first fault found after a release command is *latched* until the next command (a later,
//! more specific finding may rename it: a run of one code that turns out to come from a
//! converter without its low bits is lost resolution), with the sample at which its evidence
//! began (its *onset*, e.g. the first sample of a frozen run), so
//! the monitor can tell whether a diagnosis closed before the fault began (see
//! [`crate::pipeline`]). Detection comes after the onset by at most the check's window: 0.5 s
//! for a frozen run, 1 s for noise, 2.56 s for lost resolution.
//!
//! # What it cannot see
//!
//! A slow drift or a small offset step (below [`STEP_MIN_CODES`], 0.12 bar) looks like a
//! pressure change; a gain error or a stuck transducer with live noise looks like a plateau.
//! Those produce a release that no fault class explains; the classifier's out-of-distribution
//! guard refuses it as *unfamiliar* rather than naming a brake fault.

use crate::sensor::{SensorFault, ADC_MAX_VALID, ADC_MIN_VALID};
use crate::units::AdcCounts;

/// Identical consecutive codes that make a frozen (or dead) channel: 0.5 s at 100 Hz.
pub const FROZEN_RUN: u16 = 50;
/// Samples per noise window (1 s).
pub const NOISE_WINDOW: u16 = 100;
/// Per-sample cap on |second difference| in the noise sum, codes: a spike adds at most
/// 4 × this to a window instead of swamping it (≈ 8 × the second difference's σ at nominal
/// noise).
pub const D2_CAP: u16 = 64;
/// Mean |second difference| over a window above which the signal is too noisy, codes:
/// 1.954 × 4 × 3.276 codes (σ = 0.04 bar, 4 × the transducer's specified noise).
pub const NOISY_MEAN_ABS_D2: u32 = 26;
/// Smallest departure from both neighbours that counts as a spike, codes (0.15 bar).
pub const SPIKE_MIN_CODES: u16 = 49;
/// Spike threshold in units of the last window's mean |second difference| (× 4).
pub const SPIKE_PER_MEAN_D2: u32 = 4;
/// Smallest one-sample departure from the recent slope that counts as a step, codes (0.12 bar:
/// 8.7 σ of the sample-to-sample noise; the pneumatics change the slope by far less than a code
/// from one sample to the next, except at the knees, where it changes by a few codes).
pub const STEP_MIN_CODES: u16 = 40;
/// Step threshold in units of the last window's mean |second difference| (× 6).
pub const STEP_PER_MEAN_D2: u32 = 6;
/// Samples over which the 0.1 s rate is taken.
pub const RATE_SPAN: usize = 10;
/// Codes kept for the rate check (a power of two ≥ [`RATE_SPAN`] + 2, so indexing is a mask).
const RING: usize = 16;
/// Largest change over [`RATE_SPAN`] samples while the release command is on, codes: 1.2 bar in
/// 0.1 s (12 bar/s, 1.5 × the fastest fill of a missing orifice).
pub const RATE_MAX_CODES: u16 = 393;
/// Samples of the lost-resolution window.
pub const RESOLUTION_WINDOW: u16 = 256;
/// Code bits below the highest bit that toggled in a resolution window that never toggled:
/// the converter lost its low bits, or a data line is stuck at 0 or 1. A higher bit `k` only
/// toggles where the codes cross a multiple of 2^k, and a crossing by a step of at most 2^b
/// codes toggles bit `b` too; a transducer's noise makes such steps on most samples (3.3 codes
/// of noise toggle the lowest bit on about half of them), so a working converter leaves no gap
/// in 256 samples. An independent tester's bit 3 stuck at 1 had been diagnosed `normal 99 %`.
pub const fn untoggled_below_top(toggled: u16) -> u16 {
    match u16::MAX.checked_shr(toggled.leading_zeros() + 1) {
        Some(below_top) => !toggled & below_top,
        None => 0,
    }
}

/// Hits on the largest code before clipping is considered.
pub const CLIP_MIN_HITS: u16 = 20;
/// Separate arrivals at the largest code before clipping is considered (one long run is a
/// frozen signal, not a clipped one).
pub const CLIP_MIN_ARRIVALS: u16 = 5;
/// Hits on the largest code must exceed this multiple of the hits on the code below it.
pub const CLIP_RATIO: u16 = 3;
/// Code of 0 bar g (409.5 rounds to 410).
pub const CODE_AT_ZERO: u16 = 410;
/// Codes below which the chamber would be under atmosphere: −0.15 bar g.
pub const BELOW_ATMOSPHERE_CODE: u16 = CODE_AT_ZERO - 49;
/// Consecutive samples under atmosphere that make an implausible level.
pub const BELOW_ATMOSPHERE_RUN: u16 = 5;
/// A reading this far above 0 bar g at a release command is not a vented chamber, codes (0.15 bar).
pub const VENTED_TOLERANCE_CODES: u16 = 49;
/// Samples the valve must have been closed before a command for the chamber to be vented (3 s).
pub const VENT_SAMPLES: u32 = 300;
/// Samples at the command whose mean must not lie below atmosphere by more than
/// [`START_BELOW_CODES`] (the chamber is vented then: a lower reading is a zero offset).
pub const START_SAMPLES: u32 = 3;
/// Tolerance below 0 bar g of the mean of the first samples, codes (0.05 bar, 8 σ of a
/// three-sample mean at the specified noise).
pub const START_BELOW_CODES: u32 = 16;

/// A sensor fault and the sample (counted from the last release command) at which its
/// evidence began.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Detected {
    /// What is wrong.
    pub fault: SensorFault,
    /// Samples since the release command at which the evidence began (0 at the command, or
    /// for evidence older than the command).
    pub onset: u32,
}

/// The plausibility checks' state: a few counters, no sample buffer beyond the last
/// [`RATE_SPAN`] codes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SignalCheck {
    /// Samples since the last release command (saturating).
    index: u32,
    /// Samples the valve has been closed (saturating).
    closed_for: u32,
    valve_was_open: bool,
    /// The last valid codes, newest at `ring[head]`.
    ring: [u16; RING],
    head: usize,
    /// Valid codes in `ring` (up to its length).
    filled: usize,
    /// The previous sample was out of range.
    last_out_of_range: bool,
    /// Sample at which the current loss of the reading began.
    lost_since: u32,
    /// Length of the current run of identical codes, and the sample it began at.
    run: u16,
    run_start: u32,
    /// A code change was seen since the release command.
    live_since_command: bool,
    /// Noise window: Σ min(|d2|, cap) and sample count; last completed window's mean.
    d2_sum: u32,
    d2_n: u16,
    window_start: u32,
    mean_abs_d2: u32,
    /// A noise window has completed since the command.
    noise_window_done: bool,
    /// Bits that toggled between consecutive codes in the resolution window, and its length.
    toggled: u16,
    toggle_n: u16,
    toggle_start: u32,
    /// Largest code since the command, its hits, the hits on the code below, and when it was set.
    max_code: u16,
    max_hits: u16,
    max_arrivals: u16,
    below_max_hits: u16,
    max_since: u32,
    /// The lowest code bit toggled since the command (a converter that lost it cannot clip-test).
    low_bit_live: bool,
    /// Consecutive samples under atmosphere.
    below_run: u16,
    /// A sample that jumped by a step and is waiting for the next one to tell step from spike.
    /// (departure from the slope, sample, slope before it).
    pending_jump: Option<(i32, u32, i32)>,
    /// The first fault of this release (latched until the next command).
    latched: Option<Detected>,
    /// Sum of the first [`START_SAMPLES`] codes after the command.
    start_sum: u32,
    /// Valid samples in `start_sum`.
    start_n: u32,
    /// The reading at the command was above a vented chamber's and the valve had not been
    /// closed long enough to tell a zero offset from a chamber that was not vented.
    unvented_start: bool,
}

impl Default for SignalCheck {
    fn default() -> Self {
        Self::new()
    }
}

impl SignalCheck {
    /// Checks with no history (nothing seen yet).
    pub const fn new() -> Self {
        Self {
            index: 0,
            closed_for: 0,
            valve_was_open: false,
            ring: [0; RING],
            head: 0,
            filled: 0,
            last_out_of_range: false,
            lost_since: 0,
            run: 0,
            run_start: 0,
            live_since_command: false,
            d2_sum: 0,
            d2_n: 0,
            window_start: 0,
            mean_abs_d2: 0,
            noise_window_done: false,
            toggled: 0,
            toggle_n: 0,
            toggle_start: 0,
            max_code: 0,
            max_hits: 0,
            max_arrivals: 0,
            below_max_hits: 0,
            max_since: 0,
            low_bit_live: false,
            below_run: 0,
            pending_jump: None,
            latched: None,
            start_sum: 0,
            start_n: 0,
            unvented_start: false,
        }
    }

    /// The fault latched since the last release command, if any.
    pub fn latched(&self) -> Option<Detected> {
        self.latched
    }

    /// The release did not start from a vented chamber as far as the reading tells (above
    /// 0.15 bar g at the command) and nothing shows it is a sensor offset: not a release the
    /// twin and the classifier can judge (the pipeline says *unfamiliar release*).
    pub fn unvented_start(&self) -> bool {
        self.unvented_start
    }

    /// The code `back` samples before the newest (0 = newest); `None` if not yet seen.
    fn code(&self, back: usize) -> Option<u16> {
        if back >= self.filled {
            return None;
        }
        self.ring.get(self.head.wrapping_sub(back) & (RING - 1)).copied()
    }

    fn latch(&mut self, fault: SensorFault, onset: u32) {
        if self.latched.is_none() {
            self.latched = Some(Detected { fault, onset: onset.min(self.index) });
        }
    }

    /// Forgets the per-release statistics at a release command; the code history (last codes,
    /// current run) is kept because the sensor did not change.
    fn new_release(&mut self) {
        let vented_rest = self.closed_for >= VENT_SAMPLES;
        self.index = 0;
        self.lost_since = 0;
        self.latched = None;
        self.live_since_command = false;
        self.run_start = 0;
        self.d2_sum = 0;
        self.d2_n = 0;
        self.window_start = 0;
        self.noise_window_done = false;
        self.mean_abs_d2 = 0;
        self.toggled = 0;
        self.toggle_n = 0;
        self.toggle_start = 0;
        self.max_code = 0;
        self.max_hits = 0;
        self.max_arrivals = 0;
        self.below_max_hits = 0;
        self.max_since = 0;
        self.low_bit_live = false;
        self.below_run = 0;
        self.pending_jump = None;
        self.start_sum = 0;
        self.start_n = 0;
        self.unvented_start = false;
        // The chamber had time to vent: the reading at the command must be 0 bar g.
        if let Some(c) = self.code(0).filter(|_| vented_rest) {
            if c > CODE_AT_ZERO + VENTED_TOLERANCE_CODES {
                self.latch(SensorFault::ImplausibleLevel, 0);
            }
        }
    }

    /// The first samples after a command: a vented chamber reads 0 bar g.
    fn check_start(&mut self, c: u16) {
        if self.index == 0 && self.latched.is_none() && c > CODE_AT_ZERO + VENTED_TOLERANCE_CODES {
            self.unvented_start = true;
        }
        // Only when the first samples are all valid (an out-of-range start is its own fault).
        if self.index < START_SAMPLES {
            self.start_sum += u32::from(c);
            self.start_n += 1;
            if self.start_n == START_SAMPLES
                && self.start_sum + START_SAMPLES * START_BELOW_CODES < START_SAMPLES * u32::from(CODE_AT_ZERO)
            {
                self.latch(SensorFault::ImplausibleLevel, 0);
            }
        }
    }

    /// The release command ended without a sample showing it (the input stopped): the next
    /// sample with the command on starts a new release, as after a falling edge.
    pub fn end_release(&mut self) {
        self.valve_was_open = false;
    }

    /// One 100 Hz sample: the raw ADC code and the release command. Returns the fault that makes
    /// the signal untrustworthy now: this sample's range fault, else the fault latched since
    /// the last command.
    pub fn update(&mut self, adc: AdcCounts, valve_open: bool) -> Option<SensorFault> {
        if valve_open && !self.valve_was_open {
            self.new_release();
        } else {
            self.index = self.index.saturating_add(1);
        }
        self.closed_for = if valve_open { 0 } else { self.closed_for.saturating_add(1) };
        self.valve_was_open = valve_open;
        let c = adc.0;
        if !(ADC_MIN_VALID..=ADC_MAX_VALID).contains(&c) {
            if !self.last_out_of_range {
                self.lost_since = self.index;
            }
            self.last_out_of_range = true;
            self.run = 0;
            self.pending_jump = None;
            return Some(if c < ADC_MIN_VALID { SensorFault::OpenCircuit } else { SensorFault::ShortCircuit });
        }
        if self.last_out_of_range {
            // Valid again after a loss: an intermittent signal.
            self.last_out_of_range = false;
            if self.filled > 0 {
                // Dated to the first lost sample (at the command if the loss began before it).
                self.latch(SensorFault::Dropouts, self.lost_since.min(self.index));
            }
        }
        if valve_open {
            self.check_start(c);
        }
        self.push(c, valve_open);
        self.latched.map(|d| d.fault)
    }

    fn push(&mut self, c: u16, valve_open: bool) {
        let prev = self.code(0);
        let prev2 = self.code(1);
        self.head = (self.head + 1) & (RING - 1);
        if let Some(slot) = self.ring.get_mut(self.head) {
            *slot = c;
        }
        self.filled = (self.filled + 1).min(RING);
        let now = self.index;

        // Frozen or dead: a run of identical codes.
        if prev == Some(c) {
            self.run = self.run.saturating_add(1);
        } else {
            if prev.is_some() && now > 0 {
                self.live_since_command = true;
            }
            self.run = 1;
            self.run_start = now;
        }
        if self.run >= FROZEN_RUN {
            let fault = if self.live_since_command && self.run_start > 0 {
                // A window that lost its low bits repeats codes too: say which.
                if untoggled_below_top(self.toggled) != 0 {
                    SensorFault::LostResolution
                } else {
                    SensorFault::Frozen
                }
            } else {
                SensorFault::Dead
            };
            self.latch(fault, self.run_start);
        }

        // Under atmosphere.
        if c < BELOW_ATMOSPHERE_CODE {
            self.below_run = self.below_run.saturating_add(1);
            if self.below_run >= BELOW_ATMOSPHERE_RUN {
                self.latch(SensorFault::ImplausibleLevel, now.saturating_sub(u32::from(BELOW_ATMOSPHERE_RUN) - 1));
            }
        } else {
            self.below_run = 0;
        }

        // Lost resolution: which bits toggle.
        if let Some(p) = prev {
            self.toggled |= p ^ c;
            self.low_bit_live |= (p ^ c) & 1 == 1;
            self.toggle_n = self.toggle_n.saturating_add(1);
            if self.toggle_n >= RESOLUTION_WINDOW {
                if untoggled_below_top(self.toggled) != 0 {
                    self.latch(SensorFault::LostResolution, self.toggle_start);
                    // A coarse converter holds one code for a long time on a slow signal and
                    // rounds 0 bar g below atmosphere, which the run and level checks saw first:
                    // name the more specific cause, keep the onset.
                    if let Some(d) = self.latched.as_mut() {
                        if matches!(d.fault, SensorFault::Dead | SensorFault::Frozen | SensorFault::ImplausibleLevel) {
                            d.fault = SensorFault::LostResolution;
                        }
                    }
                }
                self.toggled = 0;
                self.toggle_n = 0;
                self.toggle_start = now;
            }
        }

        // Clipping: the largest code piles up.
        if c > self.max_code {
            self.below_max_hits = if c == self.max_code.saturating_add(1) { self.max_hits } else { 0 };
            self.max_code = c;
            self.max_hits = 1;
            self.max_arrivals = 1;
            self.max_since = now;
        } else if c == self.max_code {
            self.max_hits = self.max_hits.saturating_add(1);
            if prev != Some(c) {
                self.max_arrivals = self.max_arrivals.saturating_add(1);
            }
        } else if c.saturating_add(1) == self.max_code {
            self.below_max_hits = self.below_max_hits.saturating_add(1);
        }
        if self.max_hits >= CLIP_MIN_HITS
            && self.max_arrivals >= CLIP_MIN_ARRIVALS
            && self.max_hits > self.below_max_hits.saturating_mul(CLIP_RATIO)
            && self.low_bit_live
        {
            self.latch(SensorFault::Clipped, self.max_since);
        }

        let (Some(p1), Some(p2)) = (prev, prev2) else { return };
        let (c, p1, p2) = (i32::from(c), i32::from(p1), i32::from(p2));
        let d_prev = p1 - p2;
        let d_cur = c - p1;

        // Noise: capped |second difference| over a 1 s window.
        let d2 = (d_cur - d_prev).unsigned_abs().min(u32::from(D2_CAP));
        self.d2_sum = self.d2_sum.saturating_add(d2);
        self.d2_n = self.d2_n.saturating_add(1);
        if self.d2_n >= NOISE_WINDOW {
            self.mean_abs_d2 = self.d2_sum / u32::from(self.d2_n);
            self.noise_window_done = true;
            if self.mean_abs_d2 > NOISY_MEAN_ABS_D2 {
                self.latch(SensorFault::Noisy, self.window_start);
                // Heavy noise makes large jumps and outliers before its window completes: a
                // step or spike found in this window or the one before is the noise.
                let since = self.window_start.saturating_sub(u32::from(NOISE_WINDOW));
                if let Some(d) = self.latched.as_mut() {
                    if matches!(d.fault, SensorFault::Spikes | SensorFault::ImpossibleRate) && d.onset >= since {
                        d.fault = SensorFault::Noisy;
                    }
                }
            }
            self.d2_sum = 0;
            self.d2_n = 0;
            self.window_start = now;
        }

        // The noise level the spike and step thresholds scale with: the last full window's, or
        // the current window's once it has a few samples (before the first window completes).
        // Until then the noise is unknown and neither check runs.
        let noise_known = self.noise_window_done || self.d2_n >= 16;
        let mean_now = if self.d2_n >= 16 { self.d2_sum / u32::from(self.d2_n) } else { 0 };
        let noise_ref = self.mean_abs_d2.max(mean_now);
        // Spike at the previous sample: far from both neighbours, on the same side.
        let spike_min = u32::from(SPIKE_MIN_CODES).max(SPIKE_PER_MEAN_D2 * noise_ref);
        // A converter that lost its low bits dithers between coarse codes, which looks like
        // spikes: that is the resolution check's to report.
        let is_spike = self.low_bit_live
            && noise_known
            && d_prev.unsigned_abs() > spike_min
            && d_cur.unsigned_abs() > spike_min
            && (d_prev > 0) != (d_cur > 0);
        if is_spike {
            self.latch(SensorFault::Spikes, now.saturating_sub(1));
        }

        // Step: a change at the previous sample that departs from the recent slope (the mean
        // change per sample over the 10 samples before it) and that the current one does not
        // take back. Measured against the slope, so a fast but smooth fill is no step.
        let slope = match self.code(RATE_SPAN + 1) {
            Some(old) => (p1 - i32::from(old)) / RATE_SPAN as i32,
            None => 0,
        };
        let step_min = u32::from(STEP_MIN_CODES).max(STEP_PER_MEAN_D2 * noise_ref);
        if let Some((jump, at, slope_before)) = self.pending_jump.take() {
            // Against the slope before the jump (the recent slope now contains the jump).
            let rest = d_cur - slope_before;
            let back = (jump > 0) != (rest > 0) && rest.unsigned_abs() > step_min / 2;
            if !back {
                self.latch(SensorFault::ImpossibleRate, at);
            }
        }
        // Only while the command is on: after it the chamber vents through the valve's exhaust,
        // whose rate the monitor does not know.
        let jump = d_cur - slope;
        if valve_open && noise_known && jump.unsigned_abs() > step_min && !is_spike {
            self.pending_jump = Some((jump, now, slope));
        }

        // Rate over 0.1 s while the command is on (venting after the command is not bounded),
        // on two consecutive spans so that one spike, which is the spike check's, cannot trip it.
        if valve_open && now > RATE_SPAN as u32 {
            if let (Some(old), Some(old1)) = (self.code(RATE_SPAN), self.code(RATE_SPAN + 1)) {
                let too_fast = |a: i32, b: u16| (a - i32::from(b)).unsigned_abs() > u32::from(RATE_MAX_CODES);
                if too_fast(c, old) && too_fast(p1, old1) {
                    self.latch(SensorFault::ImpossibleRate, now - RATE_SPAN as u32);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::adc_from_bar;
    use crate::units::BarG;

    /// A deterministic noisy nominal-like release: ramp to 7.7 bar with ±3-code noise from a
    /// small linear congruential generator (no dependency on the host's random crates).
    fn release(n: u32) -> impl Iterator<Item = AdcCounts> {
        let mut s: u32 = 12345;
        (0..n).map(move |i| {
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            // Sum of four uniforms: roughly normal, σ ≈ 3.2 codes.
            let mut noise = 0i32;
            for k in 0..4 {
                noise += ((s >> (8 * k)) & 0xFF) as i32 - 128;
            }
            let p = (f64::from(i) * 0.01 * 0.8).min(7.7);
            let code = i32::from(adc_from_bar(BarG(p)).0) + noise * 3 / 128;
            AdcCounts(code as u16)
        })
    }

    fn run(samples: impl Iterator<Item = AdcCounts>) -> Option<Detected> {
        let mut c = SignalCheck::new();
        for a in samples {
            c.update(a, true);
        }
        c.latched()
    }

    #[test]
    fn clean_noisy_release_passes() {
        assert_eq!(run(release(6000)), None);
    }

    #[test]
    fn frozen_and_dead() {
        let at_onset = release(1001).last().unwrap();
        let frozen = release(6000).enumerate().map(|(i, a)| if i >= 1000 { at_onset } else { a });
        let d = run(frozen).unwrap();
        assert_eq!(d.fault, SensorFault::Frozen);
        assert!((999..=1001).contains(&d.onset), "{d:?}");
        let d = run(core::iter::repeat_n(AdcCounts(1500), 200)).unwrap();
        assert_eq!((d.fault, d.onset), (SensorFault::Dead, 0));
    }

    #[test]
    fn spikes_steps_and_dropouts() {
        let spiky = release(3000).enumerate().map(|(i, a)| if i == 700 { AdcCounts(a.0 + 600) } else { a });
        assert_eq!(run(spiky).map(|d| (d.fault, d.onset)), Some((SensorFault::Spikes, 700)));
        let step = release(3000).enumerate().map(|(i, a)| if i >= 900 { AdcCounts(a.0 + 400) } else { a });
        assert_eq!(run(step).map(|d| (d.fault, d.onset)), Some((SensorFault::ImpossibleRate, 900)));
        let drop = release(3000).enumerate().map(|(i, a)| if (500..503).contains(&i) { AdcCounts(0) } else { a });
        assert_eq!(run(drop).map(|d| (d.fault, d.onset)), Some((SensorFault::Dropouts, 500)));
    }

    #[test]
    fn lost_bits_noise_clipping_and_level() {
        let coarse = release(3000).map(|a| AdcCounts(a.0 & !0x3F));
        let f = run(coarse).unwrap().fault;
        assert!(matches!(f, SensorFault::LostResolution), "{f:?}");
        // A data line stuck at 1 or at 0 (an independent tester's bit 3 stuck at 1 was
        // diagnosed `normal 99 %`); the healthy release toggles every bit its codes span.
        for (bit, stuck_at_one) in [(1, true), (2, false), (3, true), (4, false), (5, true)] {
            let m = 1u16 << bit;
            let stuck = release(6000).map(move |a| AdcCounts(if stuck_at_one { a.0 | m } else { a.0 & !m }));
            let f = run(stuck).map(|d| d.fault);
            assert_eq!(f, Some(SensorFault::LostResolution), "bit {bit} stuck at {}", u8::from(stuck_at_one));
        }
        assert_eq!((untoggled_below_top(0), untoggled_below_top(1), untoggled_below_top(0b1011)), (0, 0, 0b0100));
        let mut s = 99u32;
        let noisy = release(3000).map(move |a| {
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            AdcCounts((i32::from(a.0) + ((s >> 16) % 161) as i32 - 80) as u16)
        });
        assert_eq!(run(noisy).map(|d| d.fault), Some(SensorFault::Noisy));
        // Clipped at the plateau: half the plateau samples pile up on one code.
        let clip = adc_from_bar(BarG(7.7)).0;
        let clipped = release(6000).map(|a| AdcCounts(a.0.min(clip)));
        assert_eq!(run(clipped).map(|d| d.fault), Some(SensorFault::Clipped));
        // Clipped far below the plateau: the output is constant, a frozen signal.
        let clip = adc_from_bar(BarG(5.0)).0;
        let clipped = release(6000).map(|a| AdcCounts(a.0.min(clip)));
        assert!(matches!(run(clipped).map(|d| d.fault), Some(SensorFault::Clipped | SensorFault::Frozen)));
        let below = release(3000).enumerate().map(|(i, a)| if i >= 100 { AdcCounts(300) } else { a });
        let f = run(below).unwrap().fault;
        assert!(matches!(f, SensorFault::ImplausibleLevel | SensorFault::ImpossibleRate), "{f:?}");
    }

    #[test]
    fn offset_at_a_command_after_venting() {
        let mut c = SignalCheck::new();
        for i in 0..400u32 {
            c.update(AdcCounts(530 + (i % 3) as u16), false); // +0.37 bar while vented
        }
        assert_eq!(c.update(AdcCounts(531), true), Some(SensorFault::ImplausibleLevel));
        // Without a vented rest before the command nothing can be said about the offset.
        let mut c = SignalCheck::new();
        assert_eq!(c.update(AdcCounts(531), true), None);
    }

    #[test]
    fn range_faults_are_per_sample_and_a_new_command_clears_the_latch() {
        let mut c = SignalCheck::new();
        assert_eq!(c.update(AdcCounts(0), true), Some(SensorFault::OpenCircuit));
        assert_eq!(c.update(AdcCounts(4095), true), Some(SensorFault::ShortCircuit));
        assert_eq!(c.update(AdcCounts(410), true), None, "nothing valid before: not a dropout yet");
        assert_eq!(c.update(AdcCounts(0), true), Some(SensorFault::OpenCircuit));
        assert_eq!(c.update(AdcCounts(412), true), Some(SensorFault::Dropouts));
        c.update(AdcCounts(410), false);
        assert_eq!(c.update(AdcCounts(411), true), None);
    }
}
