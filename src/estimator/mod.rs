//! Online estimation of the brake's physical parameters from the chamber pressure alone.
//!
//! The controller knows the valve command and measures one pressure; piston travel is not
//! measured. [`ReleaseEstimator`] runs, sample by sample, phase-aware recursive least squares
//! ([`rls::Rls`], exponential forgetting and a covariance windup guard) on regression models
//! derived from SPEC §2, and turns the parameters into the quantities a brake engineer and the
//! fault report use: supply pressure, equivalent inlet orifice, equivalent leak.
//!
//! # Signal path
//!
//! Samples (Q7.24 bar abs) are summed in blocks of [`BLOCK_SAMPLES`] = 10 (0.1 s). The rate of a
//! block pair is `(Σₖ − Σₖ₋₁) · 2⁻²⁴` bar/s (exact: the 1/10 of the mean and the 1/0.1 s of the
//! rate cancel), taken at the pair's mean pressure. Averaging cuts the 0.01 bar sensor noise to
//! ≈ 0.045 bar/s on the rate, removes the need for a differentiating filter, and runs the
//! regression once per 10 samples. A sample that is a sensor fault discards its block and the
//! link to the previous one, so no rate spans a gap.
//!
//! # Regressors and why each parameter is identifiable
//!
//! At rest (piston against its applied stop, `V = V0`) the chamber obeys, in bar and seconds,
//!
//! ```text
//! dp/dt = g_in · Ps · φ(p/Ps) − g_leak · ψ(p),   g = k R T Cf A C1 / (√T · V0)  per orifice
//! ```
//!
//! with φ the normalised orifice flow (1 when choked, 0 at r = 1) and `ψ(p) = p · φ(P0/p)` the
//! leak shape, a known function of the measured pressure.
//!
//! 1. **Choked fill** ([`model::ChokedFillModel`]): while `p ≤ 0.528 · Ps` the inlet is choked and
//!    `φ(p/Ps) = 1`, so `dp/dt = a − g_leak · ψ(p)` with φ = `[1, −ψ(p)]`, θ = `[a, g_leak]`:
//!    * `a = g_in · Ps` (bar/s) is the rate at which the chamber fills with the leak closed —
//!      the product of inlet conductance (Cf·A of the orifice over V0) and supply pressure. It is
//!      the intercept, identifiable from any stretch of the fill.
//!    * `g_leak` (1/s) is the leak conductance. Identifiable because ψ(p) varies along the fill
//!      (from 0 at atmosphere to ≈ 4.6 bar at the end of the choked window), so the slope of
//!      `dp/dt` against ψ separates it from `a`; without a leak the slope is 0.
//!
//!    Where choke ends depends on the unknown Ps, so [`FILL_CUTOFFS_BAR_ABS`] runs one RLS per
//!    upper pressure cutoff (2.3 … 4.55 bar abs, the choke limits of Ps = 4.36 … 8.6 bar abs),
//!    each fed only the blocks below its cutoff. Once the plateau bounds Ps from below
//!    (Ps ≥ P∞), the RLS with the highest cutoff ≤ 0.528 · Ps is the one whose data were all
//!    choked (the *selected* window, whose estimates are reported); before that, the highest cutoff (choked for
//!    any supply ≥ 7.6 bar g, the regulator setting) is reported. The top cutoff 4.55 bar abs is
//!    below the lowest breakaway of the fleet (F0 − 5 % + Fs ≈ 4.8 bar abs), so the piston is at
//!    rest in every window. As a safety net for brakes outside the SPEC ranges, a one-sided
//!    CUSUM of the a-priori innovation (normalised by its predicted standard deviation
//!    `σ·√(1 + φᵀPφ)`) ends the fill when `dp/dt` falls below the model (breakaway); regressions
//!    reach the RLS [`FILL_DELAY_BLOCKS`] blocks late so the blocks between the change and its
//!    detection are dropped rather than learnt. The fill also ends when the pressure settles
//!    below the last cutoff (low supply, or a choked equilibrium of a large leak with a blocked
//!    orifice).
//! 2. **Plateau** ([`model::PlateauModel`]): once the 1 s mean pressure changes by less than
//!    `plateau_tolerance_bar` per second, the block pressures feed a one-parameter RLS whose θ is
//!    the plateau `P∞` (an exponentially weighted mean). At the plateau inflow equals leak:
//!    `a · φ(P∞/Ps) = g_leak · ψ(P∞)`. With `a` and `g_leak` from phase 1 this gives
//!    `φ(P∞/Ps)`, which [`model::inverse_flow_shape`] inverts to `r = P∞/Ps`, hence **Ps**.
//!    Without a leak `r = 1` and `Ps = P∞` exactly. The volume (piston position) does not enter
//!    an equilibrium, which is why the plateau, not the stroke, carries the supply. If
//!    `g_leak · ψ(P∞) ≥ a` the plateau is a choked equilibrium that does not depend on Ps, and
//!    close to it φ is so flat that Ps is ill-conditioned: above `g_leak · ψ(P∞) / a = 0.8` the
//!    supply is reported as not identifiable (`None`).
//! 3. **Derived**: `g_in = a / Ps`; equivalent orifice and leak diameters
//!    `d = √(4 g V0 √T / (π k R T Cf C1))` with the nominal Cf and V0 (the per-locomotive
//!    ±5 % spread of Cf and V0 is not separable from the orifice area by any pressure-only
//!    method: only the product Cf·A/V0 enters the equations). Until a plateau gives Ps, the
//!    orifice uses the nominal supply.
//!
//! The stroke phase (breakaway pressure, spring rate from the pressure rise between breakaway
//! and the end stop) is not estimated yet: the fault classes of SPEC §4 do not change it.
//!
//! # Why `f32`
//!
//! The Cortex-M4F has a single-precision FPU: `VADD`/`VMUL` take 1 cycle, `VDIV`/`VSQRT` 14, and
//! no Q-format bookkeeping is needed for a covariance that spans 1e-6..1e4. A fixed-point RLS of
//! the same accuracy needs 64-bit products and per-entry scaling (several times the cycles on
//! the M4) and risks overflow exactly where the windup guard matters. f32's 24-bit mantissa
//! (6e-8 relative) is far below the 1e-3 the estimates need. The regression runs once per
//! 10 samples, so per-sample cost is one 64-bit add. Determinism: only correctly rounded IEEE
//! `+ − × ÷`, `libm::sqrtf` and integer tables are used (no FMA contraction in Rust), so the host
//! and the target produce identical bits and identical CAN frames.
//!
//! # Per-sample cost: the window updates are spread
//!
//! A block regression is learnt by up to [`FILL_WINDOWS`] RLS (one per window whose cutoff lies
//! above its pressure), the end of the fill flushes up to [`FILL_DELAY_BLOCKS`] delayed
//! regressions at once, and a plateau block solves for the supply (two bisections). Done in the
//! block's sample, that is a burst of up to 25 RLS updates, or ≈ 3400 instructions of supply
//! solution, every 10th sample. Instead:
//!
//! - learnt regressions are queued and the queue advances by [`WINDOW_UPDATES_PER_SAMPLE`]
//!   window update per sample, every sample (valve open or not), after the sample's own block
//!   work. The reported (selected) window goes first, so it learns
//!   a block's regression in the block's own sample and the reported estimates are those of the
//!   burst (except for ≤ 0.05 s after the fill's flush); the other windows follow, oldest
//!   regression first, within the next block. Every window learns its regressions in the same
//!   order as in the burst, so its state once the queue is empty is bit-identical. The CUSUM of
//!   the next fill block finishes the queue first (a no-op in practice: it drains within a block).
//! - the supply of a plateau block is solved over the following samples,
//!   [`SUPPLY_STEPS_PER_SAMPLE`] bisection steps per sample (≈ 7 samples), from the block's
//!   plateau level and the (then constant) fill windows, and published when done: the same value,
//!   up to 0.07 s later. It starts at the first plateau block with an empty queue.

pub mod model;
pub mod rls;

pub use model::{BlockObservation, ChokedFillModel, PlateauModel, Regression, RegressionModel};
pub use rls::{Rls, RlsConfig, RlsError};

use crate::params::{c1, circle_area, GAS_CONSTANT, KAPPA, TEMPERATURE_K};
use crate::report::EstimatorState;
use crate::units::PressureQ24;
use crate::TwinParams;

/// Samples per regression block (0.1 s at 100 Hz).
pub const BLOCK_SAMPLES: u8 = 10;
/// Gauge pressure (bar) a block must exceed before the fill regressions start: the flow has
/// begun. 0.03 bar is 10 σ of a block mean at the transducer's noise, and 40 ms of a nominal
/// fill; blocks before it (a transport delay in the supply line) would form rates across the
/// start of the flow, which are no choked-fill rates.
pub const FLOW_START_BAR: f32 = 0.03;
/// Blocks per plateau-detection window (1 s).
pub const WINDOW_BLOCKS: u8 = 10;
/// Upper pressure cutoffs (bar abs) of the choked-fill windows, one RLS each (module docs).
pub const FILL_CUTOFFS_BAR_ABS: [f32; 5] = [2.3, 2.9, 3.5, 4.1, 4.55];
/// Number of choked-fill windows.
pub const FILL_WINDOWS: usize = FILL_CUTOFFS_BAR_ABS.len();
/// A plateau ends when the 1 s mean moves by more than this many plateau tolerances.
pub const PLATEAU_EXIT_FACTOR: f32 = 4.0;
/// Delay (blocks) between a fill regression and its use by the RLS.
pub const FILL_DELAY_BLOCKS: usize = 4;
/// RLS window updates done per sample from the queue of learnt regressions (module docs).
pub const WINDOW_UPDATES_PER_SAMPLE: usize = 1;
/// Steps of the supply solution done per sample (a pass set-up or result, or one bisection
/// step; a whole solution is 2 passes of 2 + [`model::InverseFlowShape::STEPS`]).
pub const SUPPLY_STEPS_PER_SAMPLE: usize = 6;
/// Queue of learnt fill regressions: one per block while filling, plus a flush of the delayed ones.
const LEARN_QUEUE: usize = FILL_DELAY_BLOCKS + 1;

/// d² (mm²) per unit conductance of [`TwinParams::nominal`] (see [`ReleaseEstimator::nominal`]).
/// (≈ 17.171457 mm² s; exact bits of the `f64` computation narrowed to `f32`).
const NOMINAL_MM2_PER_CONDUCTANCE: f32 = f32::from_bits(0x4189_5f25);
/// Supply of [`TwinParams::nominal`], bar abs.
const NOMINAL_SUPPLY_ABS_BAR: f32 = 8.7;

/// Tuning of the release estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorConfig {
    /// RLS of the choked-fill model.
    pub fill_rls: RlsConfig,
    /// RLS of the plateau level.
    pub plateau_rls: RlsConfig,
    /// Standard deviation of the block rate noise, bar/s (0.01 bar sensor noise → ≈ 0.045).
    pub rate_noise_bar_s: f32,
    /// CUSUM drift, in units of `rate_noise_bar_s`.
    pub cusum_drift: f32,
    /// CUSUM alarm threshold, in units of `rate_noise_bar_s`.
    pub cusum_threshold: f32,
    /// Fill blocks before the CUSUM is armed.
    pub fill_warmup_blocks: u32,
    /// Largest change of the 1 s mean pressure per second that counts as a plateau, bar.
    pub plateau_tolerance_bar: f32,
    /// Plateau blocks (and fill blocks) after which the estimates count as settled.
    pub settle_blocks: u32,
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        Self {
            fill_rls: RlsConfig { forgetting: 0.999, initial_covariance: 100.0, trace_max: 1.0e4 },
            plateau_rls: RlsConfig { forgetting: 0.98, initial_covariance: 100.0, trace_max: 1.0e4 },
            rate_noise_bar_s: 0.05,
            cusum_drift: 1.0,
            cusum_threshold: 8.0,
            fill_warmup_blocks: 8,
            plateau_tolerance_bar: 0.005,
            settle_blocks: 10,
        }
    }
}

/// Why the estimator could not be built or an update was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EstimatorError {
    /// An RLS refused its configuration or an update.
    Rls(RlsError),
    /// A configuration value out of range (noise or CUSUM settings not positive and finite).
    Config,
}

impl From<RlsError> for EstimatorError {
    fn from(e: RlsError) -> Self {
        Self::Rls(e)
    }
}

impl core::fmt::Display for EstimatorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Rls(e) => write!(f, "estimator: {e}"),
            Self::Config => f.write_str("estimator configuration out of range"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for EstimatorError {}

/// Phase of the release as the estimator sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Phase {
    /// Valve closed: no release.
    Idle,
    /// Filling at rest with a choked inlet (model 1 active).
    ChokedFill,
    /// After the choked fill: unchoked fill, stroke or end stop, pressure still moving.
    Transit,
    /// Pressure settled (model 2 active).
    Plateau,
}

/// Current estimates (`None`: not identifiable yet or at all, see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimates {
    /// Choked inflow rate `a = g_in · Ps`, bar/s.
    pub inflow_rate_bar_s: Option<f32>,
    /// Leak conductance `g_leak`, 1/s.
    pub leak_conductance_per_s: Option<f32>,
    /// Equivalent leak orifice diameter, mm (nominal Cf and V0).
    pub leak_mm: Option<f32>,
    /// Equivalent inlet orifice diameter, mm (nominal Cf and V0; nominal supply until `supply_bar_g`).
    pub orifice_mm: Option<f32>,
    /// Plateau pressure, bar g.
    pub plateau_bar_g: Option<f32>,
    /// Supply pressure, bar g.
    pub supply_bar_g: Option<f32>,
    /// Phase of the release.
    pub phase: Phase,
    /// Estimator state for the status report.
    pub state: EstimatorState,
}

impl Estimates {
    /// Nothing estimated.
    pub const NONE: Self = Self {
        inflow_rate_bar_s: None,
        leak_conductance_per_s: None,
        leak_mm: None,
        orifice_mm: None,
        plateau_bar_g: None,
        supply_bar_g: None,
        phase: Phase::Idle,
        state: EstimatorState::Idle,
    };

    /// Supply for the fault report, mbar g (0 = not estimated), saturated to `u16`.
    pub fn supply_mbar(&self) -> u16 {
        self.supply_bar_g.map_or(0, |p| (p * 1000.0 + 0.5).clamp(0.0, 65_535.0) as u16)
    }

    /// Leak for the fault report, equivalent diameter in µm (0 = tight or not estimated).
    pub fn leak_um(&self) -> u16 {
        self.leak_mm.map_or(0, |d| (d * 1000.0 + 0.5).clamp(0.0, 65_535.0) as u16)
    }
}

/// The phase-aware online estimator of one brake (see the module docs).
#[derive(Debug, Clone)]
pub struct ReleaseEstimator {
    config: EstimatorConfig,
    /// d² (mm²) per unit conductance (1/s): `4 V0 √T / (π k R T Cf C1) · 1e6`.
    mm2_per_conductance: f32,
    nominal_supply_abs: f32,
    fills: [Rls<2>; FILL_WINDOWS],
    selected: usize,
    plateau: Rls<1>,
    phase: Phase,
    in_release: bool,
    block_sum: i64,
    block_len: u8,
    prev_block_sum: Option<i64>,
    fill_blocks: u32,
    cusum: f32,
    /// Delayed fill regressions, a ring (oldest at `pending_head`; rings, not shifts: no memmove).
    pending: [Regression<2>; FILL_DELAY_BLOCKS],
    pending_head: usize,
    pending_len: usize,
    /// Learnt regressions whose window updates are not all done yet, oldest first.
    learn_queue: [Regression<2>; LEARN_QUEUE],
    /// Per queued regression, the windows (bit i: window i) that have not learnt it yet.
    learn_windows: [u8; LEARN_QUEUE],
    learn_head: usize,
    learn_len: usize,
    /// The supply solution of the last plateau block, in progress.
    supply_solver: Option<SupplySolver>,
    window_sum: f32,
    window_len: u8,
    prev_window_mean: Option<f32>,
    plateau_blocks: u32,
    supply_abs: Option<f32>,
    last_error: Option<EstimatorError>,
}

impl ReleaseEstimator {
    /// An estimator for a brake of the given nominal design (geometry, Cf, V0, supply).
    pub fn new(nominal: &TwinParams, config: EstimatorConfig) -> Result<Self, EstimatorError> {
        nominal.validate().map_err(|_| EstimatorError::Config)?;
        let (mm2_per_conductance, nominal_supply_abs) = Self::design_constants(nominal);
        Self::with_design(mm2_per_conductance, nominal_supply_abs, config)
    }

    /// An estimator for the nominal brake ([`TwinParams::nominal`]) from precomputed design
    /// constants: no `f64` set-up (soft-float and `libm` on the Cortex-M4F). A test checks that
    /// it equals `ReleaseEstimator::new(&TwinParams::nominal(), config)`.
    #[inline(always)]
    pub fn nominal(config: EstimatorConfig) -> Result<Self, EstimatorError> {
        Self::with_design(NOMINAL_MM2_PER_CONDUCTANCE, NOMINAL_SUPPLY_ABS_BAR, config)
    }

    /// d² (mm²) per unit conductance and the nominal supply (bar abs) of a brake design.
    fn design_constants(nominal: &TwinParams) -> (f32, f32) {
        let gain_per_m2 =
            KAPPA * GAS_CONSTANT * libm::sqrt(TEMPERATURE_K) * nominal.discharge_coeff * c1() / nominal.dead_volume_m3;
        // d² = 4 A / π with A = g / gain; in mm².
        let mm2_per_conductance = (4.0 / (core::f64::consts::PI * gain_per_m2) * 1e6) as f32;
        // Sanity: the nominal orifice maps back to itself (init-time only).
        debug_assert!({
            let g = gain_per_m2 * circle_area(nominal.orifice);
            let d = libm::sqrt(g * f64::from(mm2_per_conductance));
            (d - nominal.orifice.mm()).abs() < 1e-3
        });
        (mm2_per_conductance, nominal.supply.to_abs_bar() as f32)
    }

    #[inline(always)]
    fn with_design(
        mm2_per_conductance: f32,
        nominal_supply_abs: f32,
        config: EstimatorConfig,
    ) -> Result<Self, EstimatorError> {
        let positive = |v: f32| v.is_finite() && v > 0.0;
        if !(positive(config.rate_noise_bar_s)
            && config.cusum_drift.is_finite()
            && config.cusum_drift >= 0.0
            && positive(config.cusum_threshold)
            && positive(config.plateau_tolerance_bar))
        {
            return Err(EstimatorError::Config);
        }
        let pending = [Regression { phi: [0.0; 2], y: 0.0 }; FILL_DELAY_BLOCKS];
        Ok(Self {
            config,
            mm2_per_conductance,
            nominal_supply_abs,
            fills: [Rls::new(config.fill_rls, [0.0; 2])?; FILL_WINDOWS],
            selected: FILL_WINDOWS - 1,
            plateau: Rls::new(config.plateau_rls, [0.0])?,
            phase: Phase::Idle,
            in_release: false,
            block_sum: 0,
            block_len: 0,
            prev_block_sum: None,
            fill_blocks: 0,
            cusum: 0.0,
            pending,
            pending_head: 0,
            pending_len: 0,
            learn_queue: pending_queue(),
            learn_windows: [0; LEARN_QUEUE],
            learn_head: 0,
            learn_len: 0,
            supply_solver: None,
            window_sum: 0.0,
            window_len: 0,
            prev_window_mean: None,
            plateau_blocks: 0,
            supply_abs: None,
            last_error: None,
        })
    }

    /// Forgets the current release: all models back to their initial state.
    pub fn reset(&mut self) {
        for f in &mut self.fills {
            f.reset();
        }
        self.selected = FILL_WINDOWS - 1;
        self.plateau.reset();
        self.phase = Phase::Idle;
        self.in_release = false;
        self.block_sum = 0;
        self.block_len = 0;
        self.prev_block_sum = None;
        self.fill_blocks = 0;
        self.cusum = 0.0;
        self.pending_head = 0;
        self.pending_len = 0;
        self.learn_head = 0;
        self.learn_len = 0;
        self.supply_solver = None;
        self.window_sum = 0.0;
        self.window_len = 0;
        self.prev_window_mean = None;
        self.plateau_blocks = 0;
        self.supply_abs = None;
        self.last_error = None;
    }

    /// The choked-fill RLS of window `i` (cutoff `FILL_CUTOFFS_BAR_ABS[i]`), if it exists.
    pub fn fill_rls(&self, i: usize) -> Option<&Rls<2>> {
        self.fills.get(i)
    }

    fn fill(&self) -> &Rls<2> {
        // `selected` is always < FILL_WINDOWS; fall back to the last window defensively.
        self.fills.get(self.selected).unwrap_or(&self.fills[FILL_WINDOWS - 1])
    }

    /// The plateau RLS (for tests and reports).
    pub fn plateau_rls(&self) -> &Rls<1> {
        &self.plateau
    }

    /// Current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The last error an update reported since the release started (`None`: all clean).
    pub fn last_error(&self) -> Option<EstimatorError> {
        self.last_error
    }

    /// The release command ended without a sample showing it (the input stopped): idle, the
    /// last estimates kept for reporting, as after a falling edge; the next sample with the
    /// command on starts a new release.
    pub fn end_release(&mut self) {
        self.in_release = false;
        self.phase = Phase::Idle;
    }

    /// Processes one sample: `pressure` is the measured chamber pressure (`None` when the
    /// reading is a sensor fault), `valve_open` the release command. A rising edge of the
    /// command starts a new release and resets the estimator; while the valve is closed the
    /// last estimates are kept for reporting.
    ///
    /// An `Err` means one regression was refused or corrected (see [`RlsError`]); the
    /// estimator stays usable and the error is kept in [`Self::last_error`].
    pub fn update(&mut self, pressure: Option<PressureQ24>, valve_open: bool) -> Result<(), EstimatorError> {
        let sampled = self.sample(pressure, valve_open);
        // The queued window updates (module docs), spread over the samples; after the block, so
        // the reported window learns a block's regression in the block's own sample.
        let learnt = self.learn_step(WINDOW_UPDATES_PER_SAMPLE);
        self.last_learn_error(learnt);
        self.supply_step(SUPPLY_STEPS_PER_SAMPLE);
        sampled.and(learnt)
    }

    fn sample(&mut self, pressure: Option<PressureQ24>, valve_open: bool) -> Result<(), EstimatorError> {
        if !valve_open {
            self.in_release = false;
            self.phase = Phase::Idle;
            return Ok(());
        }
        if !self.in_release {
            self.reset();
            self.in_release = true;
            self.phase = Phase::ChokedFill;
        }
        let Some(p) = pressure else {
            // A gap: drop the partial block and do not form a rate across it.
            self.block_sum = 0;
            self.block_len = 0;
            self.prev_block_sum = None;
            return Ok(());
        };
        self.block_sum += i64::from(p.0);
        self.block_len += 1;
        if self.block_len < BLOCK_SAMPLES {
            return Ok(());
        }
        let sum = self.block_sum;
        self.block_sum = 0;
        self.block_len = 0;
        let result = self.block(sum);
        if let Err(e) = result {
            self.last_error = Some(e);
        }
        result
    }

    /// One complete block with sample sum `sum` (Q24 bar abs).
    fn block(&mut self, sum: i64) -> Result<(), EstimatorError> {
        const Q24_PER_BAR: f32 = 16_777_216.0;
        let pressure = sum as f32 * (1.0 / (Q24_PER_BAR * BLOCK_SAMPLES as f32));
        if self.phase == Phase::ChokedFill && self.fill_blocks == 0 && pressure < 1.0 + FLOW_START_BAR {
            // The air has not arrived yet (a transport delay in the supply line): a rate formed
            // across the start of the flow is no choked-fill rate.
            self.prev_block_sum = None;
            return self.plateau_block(pressure);
        }
        let prev = self.prev_block_sum.replace(sum);
        let mut result = Ok(());
        if let Some(prev) = prev {
            let obs = BlockObservation {
                pressure,
                mid_pressure: (sum + prev) as f32 * (1.0 / (Q24_PER_BAR * 2.0 * BLOCK_SAMPLES as f32)),
                rate: (sum - prev) as f32 * (1.0 / Q24_PER_BAR),
            };
            if self.phase == Phase::ChokedFill {
                result = self.fill_block(&obs);
            }
        }
        let plateau_result = self.plateau_block(pressure);
        result.and(plateau_result)
    }

    fn fill_block(&mut self, obs: &BlockObservation) -> Result<(), EstimatorError> {
        if self.fill_blocks == 0 && obs.mid_pressure < 1.0 + FLOW_START_BAR {
            return Ok(());
        }
        let top = FILL_CUTOFFS_BAR_ABS[FILL_WINDOWS - 1];
        if obs.mid_pressure > top {
            // Above the last cutoff: the choked fill is over (the delayed blocks are all below it).
            self.flush_pending()?;
            self.phase = Phase::Transit;
            return Ok(());
        }
        let reg = ChokedFillModel.regress(obs);
        self.fill_blocks = self.fill_blocks.saturating_add(1);
        if self.fill_blocks > self.config.fill_warmup_blocks {
            // The CUSUM reads the top window: it must have learnt everything queued (it has, the
            // queue drains within a block; this only keeps that exact should it ever not).
            let drained = self.learn_step(LEARN_QUEUE * FILL_WINDOWS);
            let top_rls = &self.fills[FILL_WINDOWS - 1];
            let innovation = reg.y - top_rls.predict(&reg.phi);
            let spread = dot2(&reg.phi, &mat_vec2(top_rls.covariance(), &reg.phi));
            let sigma = self.config.rate_noise_bar_s * libm::sqrtf(1.0 + spread.max(0.0));
            self.cusum = (self.cusum - innovation / sigma - self.config.cusum_drift).max(0.0);
            if self.cusum.is_nan() || self.cusum > self.config.cusum_threshold {
                // The piston broke away (or the inlet left choke early): drop the delayed blocks.
                self.phase = Phase::Transit;
                self.pending_len = 0;
                self.last_learn_error(drained);
                return Ok(());
            }
            self.last_learn_error(drained);
        }
        let mut result = Ok(());
        if self.pending_len >= FILL_DELAY_BLOCKS {
            // Full: the oldest is learnt and its slot takes the new regression.
            let oldest = self.pending[self.pending_head % FILL_DELAY_BLOCKS];
            self.pending[self.pending_head % FILL_DELAY_BLOCKS] = reg;
            self.pending_head = (self.pending_head + 1) % FILL_DELAY_BLOCKS;
            result = self.learn(&oldest);
        } else {
            self.pending[(self.pending_head + self.pending_len) % FILL_DELAY_BLOCKS] = reg;
            self.pending_len += 1;
        }
        result
    }

    /// Feeds the delayed regressions that are still pending (end of the fill by cutoff).
    fn flush_pending(&mut self) -> Result<(), EstimatorError> {
        let mut result = Ok(());
        for i in 0..self.pending_len.min(FILL_DELAY_BLOCKS) {
            let reg = self.pending[(self.pending_head + i) % FILL_DELAY_BLOCKS];
            result = result.and(self.learn(&reg));
        }
        self.pending_head = 0;
        self.pending_len = 0;
        result
    }

    /// Queues one fill regression for every window whose cutoff lies above its pressure
    /// ([`Self::learn_step`] does the updates).
    fn learn(&mut self, reg: &Regression<2>) -> Result<(), EstimatorError> {
        // φ = [1, −ψ(p)] and ψ is increasing, so the window test needs the pressure: ψ = p once
        // choked (p ≥ 1.9 bar abs) and all cutoffs are above that.
        let pressure = -reg.phi[1];
        let mut windows = 0u8;
        for (i, &cutoff) in FILL_CUTOFFS_BAR_ABS.iter().enumerate() {
            if pressure <= cutoff {
                windows |= 1 << i;
            }
        }
        if windows == 0 {
            return Ok(());
        }
        // Never full in practice (module docs); if it were, finish the queue first (exact, a burst).
        let result = if self.learn_len == LEARN_QUEUE { self.learn_step(LEARN_QUEUE * FILL_WINDOWS) } else { Ok(()) };
        if self.learn_len < LEARN_QUEUE {
            let slot = (self.learn_head + self.learn_len) % LEARN_QUEUE;
            self.learn_queue[slot] = *reg;
            self.learn_windows[slot] = windows;
            self.learn_len += 1;
        }
        result
    }

    /// Keeps the error of a queue step done inside a block (the block's own result is separate).
    fn last_learn_error(&mut self, result: Result<(), EstimatorError>) {
        if let Err(e) = result {
            self.last_error = Some(e);
        }
    }

    /// Does up to `budget` queued window updates. The reported (selected) window
    /// goes first: it learns the oldest queued regression it has not learnt yet, so the
    /// estimates are those of the burst except right after a flush. Then the other windows, oldest
    /// regression first, windows in index order. Every window learns its regressions in order.
    fn learn_step(&mut self, mut budget: usize) -> Result<(), EstimatorError> {
        let mut result = Ok(());
        while budget > 0 && self.learn_len > 0 {
            let selected = self.selected.min(FILL_WINDOWS - 1);
            let selected_bit = 1u8 << selected;
            let reported = (0..self.learn_len)
                .map(|k| (self.learn_head + k) % LEARN_QUEUE)
                .find(|&slot| self.learn_windows[slot] & selected_bit != 0);
            let (slot, window) = match reported {
                Some(slot) => (slot, selected),
                None => {
                    let slot = self.learn_head % LEARN_QUEUE;
                    (slot, self.learn_windows[slot].trailing_zeros() as usize)
                }
            };
            self.learn_windows[slot] &= !(1u8 << (window & 7));
            let reg = self.learn_queue[slot];
            if let Some(rls) = self.fills.get_mut(window) {
                if let Err(e) = rls.update(&reg.phi, reg.y) {
                    result = Err(EstimatorError::Rls(e));
                }
            }
            budget -= 1;
            // Regressions every window has learnt leave the front of the queue.
            while self.learn_len > 0 && self.learn_windows[self.learn_head % LEARN_QUEUE] == 0 {
                self.learn_head = (self.learn_head + 1) % LEARN_QUEUE;
                self.learn_len -= 1;
            }
        }
        result
    }

    fn plateau_block(&mut self, pressure: f32) -> Result<(), EstimatorError> {
        // Phases only move forward within a release: fill → transit ⇄ plateau.
        self.window_sum += pressure;
        self.window_len += 1;
        if self.window_len >= WINDOW_BLOCKS {
            let mean = self.window_sum * (1.0 / WINDOW_BLOCKS as f32);
            self.window_sum = 0.0;
            self.window_len = 0;
            let change = self.prev_window_mean.map(|m| (mean - m).abs());
            self.prev_window_mean = Some(mean);
            let tolerance = self.config.plateau_tolerance_bar;
            if self.plateau_blocks == 0 && change.is_some_and(|c| c < tolerance) {
                self.plateau.reset();
                self.plateau_blocks = 1;
                if self.phase == Phase::ChokedFill {
                    // The fill ends on a plateau below the last cutoff (low supply, or a choked
                    // equilibrium): the delayed regressions are still valid fill data.
                    if let Err(e) = self.flush_pending() {
                        self.last_error = Some(e);
                    }
                }
                self.phase = Phase::Plateau;
            } else if self.plateau_blocks > 0 && change.is_some_and(|c| c > PLATEAU_EXIT_FACTOR * tolerance) {
                // The pressure moved again (hysteresis: noise alone does not leave the plateau).
                self.plateau_blocks = 0;
                if self.phase == Phase::Plateau {
                    self.phase = Phase::Transit;
                }
            }
        }
        if self.plateau_blocks == 0 {
            return Ok(());
        }
        self.plateau_blocks = self.plateau_blocks.saturating_add(1);
        let reg = PlateauModel.regress(&BlockObservation { pressure, mid_pressure: pressure, rate: 0.0 });
        self.plateau.update(&reg.phi, reg.y)?;
        // The supply is a function of the current plateau and fill states: while the fill
        // windows still learn queued regressions it waits for the next plateau block.
        if self.learn_len == 0 {
            // Solved over the next samples ([`SUPPLY_STEPS_PER_SAMPLE`]; module docs).
            let p_inf = self.plateau.theta()[0];
            self.supply_solver =
                Some(SupplySolver { p_inf, supply_abs: None, selected: self.selected, pass: 0, search: None });
        }
        Ok(())
    }

    /// Supply from the plateau equilibrium `a · φ(P∞/Ps) = g_leak · ψ(P∞)` (module docs, 2.),
    /// with the fill window chosen from Ps ≥ P∞ and then refined once with the new Ps: does up
    /// to `budget` steps of the solution started by the last plateau block (a pass's set-up or
    /// result, or one bisection step) and publishes `selected` and `supply_abs` when it ends.
    fn supply_step(&mut self, mut budget: usize) {
        while budget > 0 {
            let Some(solver) = self.supply_solver.as_mut() else { return };
            budget -= 1;
            let p_inf = solver.p_inf;
            let finished = match solver.search.as_mut() {
                // One bisection step (a step is done only while the search is not complete).
                Some(search) if !search.done() => !search.step(),
                Some(search) => {
                    let supply = p_inf / search.ratio();
                    solver.supply_abs = Some(supply);
                    solver.search = None;
                    solver.pass += 1;
                    solver.pass >= 2
                }
                None => {
                    solver.selected = select_window(solver.supply_abs.unwrap_or(p_inf));
                    let fill = self.fills.get(solver.selected).unwrap_or(&self.fills[FILL_WINDOWS - 1]);
                    let [a, g_leak] = *fill.theta();
                    if fill.updates() == 0 || a.is_nan() || a <= 0.0 {
                        // No fill data: only the plateau; without a leak estimate assume none.
                        solver.supply_abs = Some(p_inf);
                        true
                    } else {
                        let target = g_leak * model::leak_shape(p_inf) / a;
                        // Choked plateau: Ps does not enter the equilibrium.
                        let choked = target.is_nan() || target >= CHOKED_PLATEAU_TARGET;
                        if !choked {
                            solver.search = Some(model::InverseFlowShape::new(target));
                        }
                        choked
                    }
                }
            };
            if finished {
                self.selected = solver.selected;
                self.supply_abs = solver.supply_abs;
                self.supply_solver = None;
            }
        }
    }

    /// The current estimates.
    pub fn estimates(&self) -> Estimates {
        if !self.in_release && self.fill().updates() == 0 {
            return Estimates::NONE;
        }
        let fill = self.fill();
        let fill_known = fill.updates() > 0;
        let [a, g_leak] = *fill.theta();
        let diameter = |g: f32| libm::sqrtf(g.max(0.0) * self.mm2_per_conductance);
        let supply = self.supply_abs.filter(|s| s.is_finite() && *s > 0.0);
        let orifice = (fill_known && a > 0.0).then(|| diameter(a / supply.unwrap_or(self.nominal_supply_abs)));
        let plateau = (self.plateau_blocks > 0).then(|| self.plateau.theta()[0] - 1.0);
        Estimates {
            inflow_rate_bar_s: fill_known.then_some(a),
            leak_conductance_per_s: fill_known.then_some(g_leak),
            leak_mm: fill_known.then(|| diameter(g_leak)),
            orifice_mm: orifice,
            plateau_bar_g: plateau,
            supply_bar_g: supply.map(|s| s - 1.0),
            phase: self.phase,
            state: self.state(),
        }
    }

    /// State for the status report: idle outside a release, frozen while a covariance guard
    /// is active, settled once a plateau has been seen long enough, converging otherwise.
    pub fn state(&self) -> EstimatorState {
        if !self.in_release {
            EstimatorState::Idle
        } else if self.fills.iter().any(Rls::guard_active) || self.plateau.guard_active() {
            EstimatorState::Frozen
        } else if self.plateau_blocks > self.config.settle_blocks && self.fill().updates() >= self.config.settle_blocks
        {
            EstimatorState::Settled
        } else {
            EstimatorState::Converging
        }
    }
}

/// The supply solution of one plateau block (`update_supply` of the module docs, 2.), spread
/// over the samples that follow it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SupplySolver {
    /// Plateau level of the block, bar abs.
    p_inf: f32,
    /// Supply so far (`None`: not identifiable, or no pass done).
    supply_abs: Option<f32>,
    /// Fill window of the current pass.
    selected: usize,
    /// Passes done (2 in all).
    pass: u8,
    /// The bisection of the current pass, once set up.
    search: Option<model::InverseFlowShape>,
}

/// An empty queue of learnt regressions.
const fn pending_queue() -> [Regression<2>; LEARN_QUEUE] {
    [Regression { phi: [0.0; 2], y: 0.0 }; LEARN_QUEUE]
}

/// `g_leak ψ(P∞) / a` at or above which Ps counts as not identifiable: φ(r) ≥ 0.8 means
/// r ≲ 0.81, where φ is so flat near choke that noise in `a` and `g_leak` moves Ps by bars.
const CHOKED_PLATEAU_TARGET: f32 = 0.8;

/// The highest fill window whose cutoff is choked for a supply of `supply_abs` bar abs.
fn select_window(supply_abs: f32) -> usize {
    let limit = model::CRITICAL_RATIO * supply_abs;
    FILL_CUTOFFS_BAR_ABS.iter().rposition(|&c| c <= limit).unwrap_or(0)
}

#[inline]
fn dot2(a: &[f32; 2], b: &[f32; 2]) -> f32 {
    a[0] * b[0] + a[1] * b[1]
}

#[inline]
fn mat_vec2(m: &[[f32; 2]; 2], v: &[f32; 2]) -> [f32; 2] {
    [dot2(&m[0], v), dot2(&m[1], v)]
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::format;

    #[test]
    fn precomputed_nominal_design_equals_the_nominal_parameters() {
        let (mm2, supply) = ReleaseEstimator::design_constants(&TwinParams::nominal());
        assert_eq!(mm2.to_bits(), NOMINAL_MM2_PER_CONDUCTANCE.to_bits());
        assert_eq!(supply.to_bits(), NOMINAL_SUPPLY_ABS_BAR.to_bits());
        let config = EstimatorConfig::default();
        let (a, b) = (ReleaseEstimator::new(&TwinParams::nominal(), config), ReleaseEstimator::nominal(config));
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }
}
