//! Issue 7 item 5: no input reaches a panic on the per-sample path.
//!
//! Arbitrary ADC streams (every `u16`, not only 12-bit codes: a wrong driver or a bit flip must
//! not crash the monitor) and arbitrary valve command patterns go through
//! [`Pipeline::step`] and [`Pipeline::close`], the exact code the firmware's monitor task runs.
//! The test profile has overflow checks on (Cargo.toml `[profile.test]`), so any arithmetic
//! overflow on these inputs would panic here; slice indexing is bounds checked as always.
//! Besides not panicking, the outputs must stay sane: at most two frames per sample, every
//! frame decodes, a diagnosis is closed exactly when the policy says, fault reports never come
//! faster than the documented 10 Hz, and no fault report names a brake class while a sensor
//! fault is known whose evidence began before the diagnosis closed (issue 15).

use pbm::can::reporter::FAULT_MIN_GAP_SAMPLES;
use pbm::can::{FrameError, Report};

/// Decodes a frame `pipe` sent in its last step (sealed with its binding now).
fn decode_frame(pipe: &Pipeline, f: &pbm::can::CanFrame) -> Result<(Report, u16), FrameError> {
    pbm::can::decode_frame(f, pipe.binding())
}
use pbm::pipeline::{Pipeline, DIAGNOSIS_WINDOW_SAMPLES};
use pbm::report::Verdict;
use pbm::sensor::adc_from_bar;
use pbm::{AdcCounts, BarG};
use proptest::prelude::*;

/// A stretch of input with one valve command level.
#[derive(Debug, Clone)]
enum Shape {
    /// Uniformly random codes over the whole `u16` range.
    Noise(Vec<u16>),
    /// Random codes within the 12-bit range.
    Noise12(Vec<u16>),
    /// One code held (0, 4095, `u16::MAX`, a plausible pressure…).
    Constant(u16, usize),
    /// A linear ramp between two codes.
    Ramp(u16, u16, usize),
    /// A ramp between two codes with transducer-like noise (±4 codes from a seeded LCG): the
    /// kind of input on which the classifier names classes.
    NoisyRamp(u16, u16, usize, u32),
}

impl Shape {
    fn codes(&self) -> Vec<u16> {
        match self {
            Shape::Noise(v) | Shape::Noise12(v) => v.clone(),
            Shape::Constant(c, n) => vec![*c; *n],
            Shape::Ramp(a, b, n) => (0..*n)
                .map(|i| {
                    let t = i as f64 / (*n).max(1) as f64;
                    (f64::from(*a) + (f64::from(*b) - f64::from(*a)) * t) as u16
                })
                .collect(),
            Shape::NoisyRamp(a, b, n, seed) => {
                let mut s = *seed;
                Shape::Ramp(*a, *b, *n)
                    .codes()
                    .into_iter()
                    .map(|c| {
                        s = s.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                        c.saturating_add(((s >> 16) % 9) as u16).saturating_sub(4)
                    })
                    .collect()
            }
        }
    }
}

fn shape() -> impl Strategy<Value = Shape> {
    prop_oneof![
        prop::collection::vec(any::<u16>(), 1..400).prop_map(Shape::Noise),
        prop::collection::vec(0u16..4096, 1..400).prop_map(Shape::Noise12),
        (prop_oneof![Just(0u16), Just(4095), Just(u16::MAX), Just(410), Just(3000), any::<u16>()], 1usize..700)
            .prop_map(|(c, n)| Shape::Constant(c, n)),
        (any::<u16>(), any::<u16>(), 1usize..700).prop_map(|(a, b, n)| Shape::Ramp(a, b, n)),
        (300u16..3500, 300u16..3500, 1usize..3000, any::<u32>()).prop_map(|(a, b, n, s)| Shape::NoisyRamp(a, b, n, s)),
    ]
}

/// Runs segments through a fresh pipeline, checking the outputs; returns the closed reports.
fn run(segments: &[(bool, Shape)]) -> usize {
    run_codes(segments.iter().flat_map(|(open, shape)| shape.codes().into_iter().map(move |c| (*open, c))))
}

/// Checks every frame of one sample (at most three: fault report, status, session): decodes, at most 10 Hz of fault reports, and no brake
/// class while a sensor fault is known whose onset lies at or before the closing sample.
fn check_frames(pipe: &Pipeline, frames: &[pbm::can::CanFrame], sample: u64, last_fault: &mut Option<u64>) {
    assert!(frames.len() <= 3, "{} frames in one sample", frames.len());
    for f in frames {
        let report = decode_frame(pipe, f).unwrap_or_else(|e| panic!("frame {f:?} does not decode: {e}"));
        if let (Report::Fault(r), _) = report {
            if let Some(last) = last_fault.replace(sample) {
                assert!(sample - last >= u64::from(FAULT_MIN_GAP_SAMPLES), "fault reports {last} and {sample}");
            }
            if matches!(r.verdict, Verdict::Class { .. }) {
                if let Some(d) = pipe.monitor().sensor_fault() {
                    assert!(d.onset > pipe.closed_at(), "class {:?} sent with {d:?} at sample {sample}", r.verdict);
                }
            }
        }
    }
}

fn run_codes(samples: impl Iterator<Item = (bool, u16)>) -> usize {
    let mut pipe = Pipeline::nominal().expect("nominal parameters are valid");
    let mut closed = 0;
    let mut was_open = false;
    let mut since_command = 0u32;
    let mut last_fault = None;
    for (sample, (valve_open, code)) in samples.enumerate() {
        let sample = sample as u64;
        let valve_open = &valve_open;
        {
            let rising = *valve_open && !was_open;
            if rising {
                since_command = 0;
            }
            let step = pipe.step(AdcCounts(code), *valve_open);
            let frames = step.frames.as_slice();
            check_frames(&pipe, frames, sample, &mut last_fault);
            if *valve_open {
                assert_eq!(step.monitor.samples_since_release, since_command);
                since_command = since_command.saturating_add(1);
            }
            if step.closed.is_some() {
                closed += 1;
                // Closed by the valve falling or by the window, and then nothing is open.
                assert!(!*valve_open || since_command >= DIAGNOSIS_WINDOW_SAMPLES, "closed early");
                assert!(!pipe.diagnosing());
                let reports =
                    frames.iter().filter(|f| matches!(decode_frame(&pipe, f), Ok((Report::Fault(_), _)))).count();
                // At once, unless a report went out less than the minimum gap ago.
                let gap_open = last_fault.is_some_and(|l| sample - l < u64::from(FAULT_MIN_GAP_SAMPLES));
                assert!(reports == 1 || gap_open, "the closed report is sent at once");
            }
            was_open = *valve_open;
        }
    }
    if let Some((_, frames)) = pipe.close() {
        closed += 1;
        assert!(frames.as_slice().len() <= 2);
        assert!(frames.as_slice().iter().all(|f| decode_frame(&pipe, f).is_ok()));
    }
    assert!(pipe.close().is_none(), "a second close has nothing to close");
    closed
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// Any ADC stream with any valve pattern: no panic, sane frames, policy respected.
    #[test]
    fn any_adc_stream_and_valve_pattern(segments in prop::collection::vec((any::<bool>(), shape()), 1..12)) {
        run(&segments);
    }

    /// A full 60 s window of arbitrary codes after a plausible start: the classifier runs on
    /// whatever features garbage produces (NaN-free or not), without panicking.
    #[test]
    fn full_window_of_garbage_reaches_the_classifier(
        head in 0usize..3000,
        noise in prop::collection::vec(any::<u16>(), 64..256),
    ) {
        let start = Shape::Ramp(adc_from_bar(BarG(0.0)).0, adc_from_bar(BarG(4.0)).0, head.max(1));
        let tail_len = DIAGNOSIS_WINDOW_SAMPLES as usize + 10 - head.max(1);
        let tail: Vec<u16> = noise.iter().copied().cycle().take(tail_len).collect();
        let closed = run(&[(true, start), (true, Shape::Noise(tail))]);
        prop_assert_eq!(closed, 1, "the window closes exactly one diagnosis");
    }
}

/// Extreme fixed inputs through whole windows (deterministic complement of the properties).
#[test]
fn extreme_codes_for_a_whole_window() {
    for code in [0u16, 1, 204, 205, 3890, 3891, 4095, 4096, 0x8000, u16::MAX] {
        let n = DIAGNOSIS_WINDOW_SAMPLES as usize + 50;
        assert_eq!(run(&[(true, Shape::Constant(code, n)), (false, Shape::Constant(code, 200))]), 1, "code {code}");
    }
}

/// 24 h of input (8.64 million samples) in one run: a plausible noisy release signal with a
/// valve command that holds for random stretches, chatters, and sensor faults of every kind the
/// generator knows mixed in at random times. Reports stay within 10 Hz and never name a class
/// over a known sensor fault; nothing panics or overflows.
#[test]
fn twenty_four_hours_of_chatter_and_sensor_faults() {
    let mut s = 0x2545_f491u32;
    let mut rnd = move |n: u32| {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s % n.max(1)
    };
    let day = 24 * 3600 * 100u64;
    let mut samples = Vec::with_capacity(1 << 16);
    let (mut valve, mut left, mut p, mut fault, mut fault_left) = (false, 0u32, 410i32, 0u32, 0u32);
    let mut total = 0u64;
    let mut classes = 0usize;
    let mut pipe = Pipeline::nominal().expect("nominal");
    let mut last_fault = None;
    while total < day {
        samples.clear();
        for _ in 0..(1 << 16) {
            if left == 0 {
                valve = !valve;
                // Mostly 5..70 s stretches, sometimes a chatter of 10..200 ms.
                left = if rnd(4) == 0 { 1 + rnd(20) } else { 500 + rnd(6500) };
            }
            left -= 1;
            if fault_left == 0 {
                fault = if rnd(6) == 0 { 1 + rnd(8) } else { 0 };
                fault_left = 100 + rnd(3000);
            }
            fault_left -= 1;
            let target = if valve { 2932 } else { 410 };
            p += (target - p).signum() * (1 + rnd(2) as i32);
            let noisy = p + rnd(9) as i32 - 4;
            let code = match fault {
                1 => 0,
                2 => noisy & !0x3F,
                3 => noisy + rnd(400) as i32 - 200,
                4 if rnd(30) == 0 => noisy + 900,
                5 => noisy.min(1500),
                6 => 1234,
                7 => noisy + 600,
                8 => 4095,
                _ => noisy,
            };
            samples.push((valve, code.clamp(0, 4095) as u16));
        }
        for &(open, code) in &samples {
            let step = pipe.step(AdcCounts(code), open);
            check_frames(&pipe, step.frames.as_slice(), total, &mut last_fault);
            if let Some(r) = step.closed {
                classes += usize::from(matches!(r.verdict, Verdict::Class { .. }));
            }
            total += 1;
        }
    }
    assert!(last_fault.is_some(), "reports were sent");
    eprintln!("24 h: {total} samples, {classes} releases named a class");
}
