//! Physics features of a release, computed online from the measured chamber pressure.
//!
//! What a brake engineer reads off the curve, each tied to a fault:
//!
//! - **filling slopes** in pressure bands (least-squares slope of p(t) over the samples inside
//!   the band). Below breakaway the inlet is choked and the volume fixed, so the slope is
//!   `∝ Cf·d²·(Ps + 1)/V0` and *constant*: a blocked orifice lowers it, a leak (outflow
//!   `∝ d_leak²·p`) makes it fall as p rises, a low supply lowers it a little and unchokes the
//!   inlet early (slope falls above `0.528 (Ps + 1) − 1` bar g). The slope ratios between bands
//!   are free of the locomotive's Cf/V0 spread.
//! - **times to reach levels** (0.5 … 7.6 bar g), censored at the current time.
//! - **knees** from the 1 s slope: breakaway (slope collapses as the piston starts to move) and
//!   end stop (slope recovers when the volume stops growing).
//! - **plateau**: current smoothed pressure and its deficit to the regulator, on a log scale
//!   so that a 0.05 bar deficit (0.5 mm leak) stays visible after int8 quantization.
//!
//! Every value is defined at any time since the release command, so a classifier can run on
//! partial releases (early diagnosis).
//!
//! Arithmetic is `f32` (the Cortex-M4F's hardware FPU; an `f64` tracker costs ~10 000
//! instructions a sample there in software floating point): only `+ − × ÷` (IEEE-754 correctly
//! rounded on x86-64 SSE and on the M4F, and rustc never contracts to FMA) plus `libm::logf`
//! (the same software routine on every target), so host and firmware get the same bits. Time
//! is kept as an integer sample index and turned into seconds by one division per use; line
//! fits use the numerically stable one-pass (Welford) co-moment update, so a long band loses
//! no precision to cancellation in single precision.

/// Largest start delay [`PhaseTracker::start_delay`] reports, s.
pub const MAX_START_DELAY_S: f32 = 1.0;
/// Levels (bar g) whose first crossing time is a feature.
pub const LEVELS_BAR: [f32; 10] = [0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 7.4, 7.6];
/// Pressure bands (bar g, `[lo, hi)`) whose least-squares filling slope is a feature. The
/// first four lie below breakaway (fixed volume), the last three in the stroke.
pub const BANDS_BAR: [(f32, f32); 7] =
    [(0.3, 1.0), (1.0, 2.0), (2.0, 3.0), (3.0, 3.6), (4.6, 5.4), (5.4, 6.2), (6.2, 7.0)];
/// Samples per smoothing block (0.25 s at 100 Hz).
pub const BLOCK_SAMPLES: u32 = 25;
/// Blocks spanned by the "current slope" (1 s).
const SLOPE_SPAN: usize = 4;
/// Minimum samples in a band before its slope counts.
const BAND_MIN_SAMPLES: u32 = 20;
/// Regulator reference for the plateau deficit, bar g (above every regulator setting).
pub const DEFICIT_REF_BAR: f32 = 7.8;
/// Breakaway knee: the 1 s slope falls below this fraction of the filling slope.
const KNEE_DROP: f32 = 0.6;
/// End-stop knee: the 1 s slope rises above this multiple of the slowest stroke slope.
const KNEE_RISE: f32 = 1.5;

/// Online least-squares line fit of p against t (Welford co-moments: means and centred sums).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct LineFit {
    n: u32,
    mean_t: f32,
    mean_p: f32,
    /// Σ (t − t̄)², s².
    ctt: f32,
    /// Σ (t − t̄)(p − p̄), bar s.
    ctp: f32,
}

impl LineFit {
    fn push(&mut self, t: f32, p: f32) {
        self.n = self.n.saturating_add(1);
        let n = self.n as f32;
        let dt = t - self.mean_t;
        self.mean_t += dt / n;
        let dp = p - self.mean_p;
        self.mean_p += dp / n;
        self.ctt += dt * (t - self.mean_t);
        self.ctp += dt * (p - self.mean_p);
    }

    /// Slope, bar/s (0 with too few samples).
    fn slope(&self) -> f32 {
        // `ctt` is a sum of squares: > 0, or 0 (or NaN from a bad input) when there is no slope.
        if self.n >= BAND_MIN_SAMPLES && self.ctt > 0.0 {
            self.ctp / self.ctt
        } else {
            0.0
        }
    }
}

/// Running physics features of one release.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PhaseTracker {
    t_now: f32,
    block_sum: f32,
    block_t_sum: f32,
    block_n: u32,
    block_index: u32,
    /// Last block means and times, newest at `ring_head`.
    ring_p: [f32; SLOPE_SPAN + 1],
    ring_t: [f32; SLOPE_SPAN + 1],
    ring_head: usize,
    blocks_seen: u32,
    cross: [Option<f32>; LEVELS_BAR.len()],
    bands: [LineFit; BANDS_BAR.len()],
    p_now: f32,
    slope_now: f32,
    p_max: f32,
    fill_slope_max: f32,
    breakaway: Option<(f32, f32)>,
    stroke_slope_min: f32,
    end_stop: Option<(f32, f32)>,
    /// Largest fall of a block mean below the highest block mean before it, bar.
    max_drop: f32,
}

/// Index in [`PhaseTracker::values`] of the first value after the times and band slopes.
const AFTER_BANDS: usize = 1 + LEVELS_BAR.len() + BANDS_BAR.len();
/// Index of `p_max` in [`PhaseTracker::values`] (and in the classifier's features).
pub const INDEX_P_MAX: usize = AFTER_BANDS + 2;
/// Index of `ratio_1_2_over_0.3_1` in [`PhaseTracker::values`] (and in the classifier's features).
pub const INDEX_FILL_RATIO: usize = AFTER_BANDS + 9;

/// How much faster the chamber filled from 1 to 2 bar g than from 0.3 to 1 bar g (the ratio of
/// the two band slopes, read from the feature vector `v`), once the pressure has passed 2 bar g;
/// `None` before. Below breakaway the volume is fixed and a steady supply's inlet is choked, so
/// the inflow is constant and the fill can only slow down (a leak) or keep its pace: measured at
/// most 1.04 on clean releases with three times the transducer noise. A fill that speeds up was
/// fed by a supply still rising.
pub fn fill_speed_up(v: &[f32]) -> Option<f32> {
    let (p_max, ratio) = (*v.get(INDEX_P_MAX)?, *v.get(INDEX_FILL_RATIO)?);
    (p_max > BANDS_BAR[1].1 && ratio > 0.0).then_some(ratio)
}

/// Number of physics features in [`PhaseTracker::values`].
pub const N_PHYSICS: usize = 1 + LEVELS_BAR.len() + BANDS_BAR.len() + 4 + 3 + 3;

/// Names of the physics features, in the order of [`PhaseTracker::values`].
pub const PHYSICS_NAMES: [&str; N_PHYSICS] = [
    "t_now",
    "t_0.5bar",
    "t_1bar",
    "t_2bar",
    "t_3bar",
    "t_4bar",
    "t_5bar",
    "t_6bar",
    "t_7bar",
    "t_7.4bar",
    "t_7.6bar",
    "slope_0.3_1.0",
    "slope_1.0_2.0",
    "slope_2.0_3.0",
    "slope_3.0_3.6",
    "slope_4.6_5.4",
    "slope_5.4_6.2",
    "slope_6.2_7.0",
    "p_now",
    "slope_now",
    "p_max",
    "log_deficit",
    "p_breakaway",
    "t_breakaway",
    "t_end_stop",
    "ratio_2_3_over_1_2",
    "ratio_3_3.6_over_1_2",
    "ratio_1_2_over_0.3_1",
];

impl PhaseTracker {
    /// A tracker at the release command.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the sample taken at `t_s` since the release command; `p_bar_g` is `None` for a
    /// sensor-fault sample (time advances, nothing else changes).
    pub fn push(&mut self, t_s: f32, p_bar_g: Option<f32>) {
        self.t_now = t_s;
        if let Some(p) = p_bar_g.filter(|p| p.is_finite()) {
            for (band, &(lo, hi)) in self.bands.iter_mut().zip(BANDS_BAR.iter()) {
                if p >= lo && p < hi {
                    band.push(t_s, p);
                }
            }
            self.block_sum += p;
            self.block_t_sum += t_s;
            self.block_n += 1;
        }
        self.block_index += 1;
        if self.block_index >= BLOCK_SAMPLES {
            self.block_index = 0;
            if self.block_n > BLOCK_SAMPLES / 2 {
                let n = self.block_n as f32;
                self.close_block(self.block_sum / n, self.block_t_sum / n);
            }
            self.block_sum = 0.0;
            self.block_t_sum = 0.0;
            self.block_n = 0;
        }
    }

    fn close_block(&mut self, p: f32, t: f32) {
        // (`get`, not indexing: no panic path in the image; the head is always in the ring.)
        let head = self.ring_p.get(self.ring_head).zip(self.ring_t.get(self.ring_head)).map(|(&p, &t)| (p, t));
        let prev = if self.blocks_seen > 0 { head } else { None };
        for (level, cross) in LEVELS_BAR.iter().zip(self.cross.iter_mut()) {
            if cross.is_none() && p >= *level {
                *cross = Some(match prev {
                    Some((pp, tp)) if p > pp && pp < *level => tp + (level - pp) / (p - pp) * (t - tp),
                    _ => t,
                });
            }
        }
        self.ring_head = (self.ring_head + 1) % (SLOPE_SPAN + 1);
        self.ring_p[self.ring_head] = p;
        self.ring_t[self.ring_head] = t;
        self.blocks_seen += 1;
        self.p_now = p;
        self.p_max = if self.blocks_seen == 1 { p } else { self.p_max.max(p) };
        self.max_drop = self.max_drop.max(self.p_max - p);
        if self.blocks_seen as usize > SLOPE_SPAN {
            let old = (self.ring_head + 1) % (SLOPE_SPAN + 1);
            let dt = t - self.ring_t[old];
            self.slope_now = if dt > 0.0 { (p - self.ring_p[old]) / dt } else { 0.0 };
            self.track_knees(t, p);
        }
    }

    fn track_knees(&mut self, t: f32, p: f32) {
        let s = self.slope_now;
        match (self.breakaway, self.end_stop) {
            (None, _) => {
                if p < BANDS_BAR[3].1 {
                    self.fill_slope_max = self.fill_slope_max.max(s);
                }
                if p > 1.5 && s < KNEE_DROP * self.fill_slope_max {
                    self.breakaway = Some((t, p));
                    self.stroke_slope_min = s;
                }
            }
            (Some((_, p_knee)), None) => {
                self.stroke_slope_min = self.stroke_slope_min.min(s);
                if p > p_knee + 1.0 && s > KNEE_RISE * self.stroke_slope_min.max(0.0) + 0.02 {
                    self.end_stop = Some((t, p));
                }
            }
            _ => {}
        }
    }

    /// Time of the last sample, s.
    pub fn t_now(&self) -> f32 {
        self.t_now
    }

    /// Smoothed (0.25 s block mean) current pressure, bar g.
    pub fn p_now(&self) -> f32 {
        self.p_now
    }

    /// Largest fall of the smoothed (0.25 s block mean) pressure below its highest value so far
    /// in this release, bar. With the valve open and a steady supply the chamber pressure never
    /// falls: the inflow is positive until the chamber reaches the supply, a leak only lowers the
    /// level it settles at, and the piston's stroke slows the rise without reversing it
    /// (measured: at most 0.04 bar on clean releases, with three times the transducer noise).
    pub fn max_drop(&self) -> f32 {
        self.max_drop
    }

    /// Breakaway knee (time s, pressure bar g) if detected.
    pub fn breakaway(&self) -> Option<(f32, f32)> {
        self.breakaway
    }

    /// End-stop knee (time s, pressure bar g) if detected.
    pub fn end_stop(&self) -> Option<(f32, f32)> {
        self.end_stop
    }

    /// Least-squares slope in band `i` of [`BANDS_BAR`], bar/s (0 if not enough samples).
    pub fn band_slope(&self, i: usize) -> f32 {
        self.bands.get(i).map_or(0.0, LineFit::slope)
    }

    /// Seconds between the release command and the start of the flow into the chamber: where the
    /// filling line of the first band (0.3–1.0 bar, fixed volume, choked inlet: a straight line)
    /// extrapolates to 0 bar g, clamped to 0..=[`MAX_START_DELAY_S`]; 0 until that band has its
    /// slope. A transport delay in the supply line (the paper sees one in its measured releases)
    /// shifts every time of the release by this much and nothing else.
    pub fn start_delay(&self) -> f32 {
        let (Some(t_half), slope) = (self.cross[0], self.band_slope(0)) else { return 0.0 };
        if slope <= 0.0 {
            return 0.0;
        }
        (t_half - LEVELS_BAR[0] / slope).clamp(0.0, MAX_START_DELAY_S)
    }

    /// The features in [`PHYSICS_NAMES`] order. Times are counted from the start of the flow
    /// ([`Self::start_delay`] after the command), so a release whose air arrives late reads as
    /// the same release. Levels not reached yet and knees not seen yet read as the current time
    /// (censored); missing slopes read 0.
    pub fn values(&self) -> [f32; N_PHYSICS] {
        let mut v = [0.0; N_PHYSICS];
        let delay = self.start_delay();
        let t = self.t_now - delay;
        v[0] = t;
        for (i, c) in self.cross.iter().enumerate() {
            v[1 + i] = c.map_or(t, |c| c - delay);
        }
        let b = 1 + LEVELS_BAR.len();
        for i in 0..BANDS_BAR.len() {
            v[b + i] = self.band_slope(i);
        }
        let o = AFTER_BANDS;
        v[o] = self.p_now;
        v[o + 1] = self.slope_now;
        v[o + 2] = self.p_max;
        v[o + 3] = libm::logf((DEFICIT_REF_BAR - self.p_now).clamp(0.01, 10.0));
        v[o + 4] = self.breakaway.map_or(0.0, |k| k.1);
        v[o + 5] = self.breakaway.map_or(t, |k| k.0 - delay);
        v[o + 6] = self.end_stop.map_or(t, |k| k.0 - delay);
        let ratio = |num: f32, den: f32| if num > 0.0 && den > 0.0 { num / den } else { 0.0 };
        let s = |i| self.band_slope(i);
        v[o + 7] = ratio(s(2), s(1));
        v[o + 8] = ratio(s(3), s(1));
        v[o + 9] = ratio(s(1), s(0));
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Piecewise-linear "release": 0.8 bar/s to 4 bar, 0.2 bar/s to 7 bar, then flat.
    fn synthetic(t: f32) -> f32 {
        if t < 5.0 {
            0.8 * t
        } else if t < 20.0 {
            4.0 + 0.2 * (t - 5.0)
        } else {
            7.0
        }
    }

    #[test]
    fn slopes_levels_and_knees_of_a_piecewise_release() {
        let mut tr = PhaseTracker::new();
        for i in 0..6000 {
            let t = i as f32 / 100.0;
            tr.push(t, Some(synthetic(t)));
        }
        let v = tr.values();
        assert!((v[0] - 59.99).abs() < 1e-5);
        assert!((v[2] - 1.25).abs() < 0.02, "t_1bar {}", v[2]); // 1 bar at 1.25 s
                                                                // A 0.25 s block straddles the knee: the interpolated crossing lags by < 0.1 s.
        assert!((v[5] - 5.0).abs() < 0.1, "t_4bar {}", v[5]);
        assert!((v[8] - 20.0).abs() < 0.15, "t_7bar {}", v[8]); // block mean reaches 7 at the plateau
        assert_eq!(v[9], 59.99, "7.4 bar never reached: censored");
        for i in 0..4 {
            assert!((tr.band_slope(i) - 0.8).abs() < 1e-4, "band {i}: {}", tr.band_slope(i));
        }
        assert!((tr.band_slope(4) - 0.2).abs() < 1e-4);
        let (tb, pb) = tr.breakaway().unwrap();
        assert!((5.0..6.0).contains(&tb) && (4.0..4.3).contains(&pb), "{tb} {pb}");
        assert!((v[25] - 1.0).abs() < 1e-4 && (v[26] - 1.0).abs() < 1e-4);
        assert!((v[18] - 7.0).abs() < 1e-5);
        assert!((v[21] - 0.8f32.ln()).abs() < 1e-5);
    }

    #[test]
    fn features_exist_at_any_time_and_sensor_faults_only_advance_time() {
        let mut tr = PhaseTracker::new();
        assert!(tr.values().iter().all(|v| v.is_finite()));
        for i in 0..300 {
            let t = i as f32 / 100.0;
            tr.push(t, if i % 2 == 0 { Some(0.8 * t) } else { None });
            assert!(tr.values().iter().all(|v| v.is_finite()));
        }
        let v = tr.values();
        assert_eq!(v[0], 2.99);
        assert!((v[1] - 0.625).abs() < 0.03, "{}", v[1]);
        assert!((v[3] - 2.5).abs() < 0.03, "{}", v[3]);
        assert_eq!(v[4], 2.99, "3 bar not reached by 3 s: censored");
        tr.push(3.0, Some(f32::NAN));
        assert!(tr.values().iter().all(|v| v.is_finite()));
    }
}
