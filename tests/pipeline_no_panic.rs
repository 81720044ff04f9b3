//! Issue 7 item 5: no input reaches a panic on the per-sample path.
//!
//! Arbitrary ADC streams (every `u16`, not only 12-bit codes: a wrong driver or a bit flip must
//! not crash the monitor) and arbitrary valve command patterns go through
//! [`Pipeline::step`] and [`Pipeline::close`], the exact code the firmware's monitor task runs.
//! The test profile has overflow checks on (Cargo.toml `[profile.test]`), so any arithmetic
//! overflow on these inputs would panic here; slice indexing is bounds checked as always.
//! Besides not panicking, the outputs must stay sane: at most two frames per sample, every
//! frame decodes, a diagnosis is closed exactly when the policy says.

use pbm::can::{decode_frame, Report};
use pbm::pipeline::{Pipeline, DIAGNOSIS_WINDOW_SAMPLES};
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
    ]
}

/// Runs segments through a fresh pipeline, checking the outputs; returns the closed reports.
fn run(segments: &[(bool, Shape)]) -> usize {
    let mut pipe = Pipeline::nominal().expect("nominal parameters are valid");
    let mut closed = 0;
    let mut was_open = false;
    let mut since_command = 0u32;
    for (valve_open, shape) in segments {
        for code in shape.codes() {
            let rising = *valve_open && !was_open;
            if rising {
                since_command = 0;
            }
            let step = pipe.step(AdcCounts(code), *valve_open);
            let frames = step.frames.as_slice();
            assert!(frames.len() <= 2, "{} frames in one sample", frames.len());
            for f in frames {
                assert!(decode_frame(f).is_ok(), "frame {f:?} does not decode");
            }
            if *valve_open {
                assert_eq!(step.monitor.samples_since_release, since_command);
                since_command = since_command.saturating_add(1);
            }
            if step.closed.is_some() {
                closed += 1;
                // Closed by the valve falling or by the window, and then nothing is open.
                assert!(!*valve_open || since_command >= DIAGNOSIS_WINDOW_SAMPLES, "closed early");
                assert!(!pipe.diagnosing());
                let reports = frames.iter().filter(|f| matches!(decode_frame(*f), Ok((Report::Fault(_), _)))).count();
                assert_eq!(reports, 1, "the closed report is sent at once");
            }
            was_open = *valve_open;
        }
    }
    if let Some((_, frames)) = pipe.close() {
        closed += 1;
        assert!(frames.as_slice().len() <= 2);
        assert!(frames.as_slice().iter().all(|f| decode_frame(f).is_ok()));
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
