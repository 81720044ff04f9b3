//! Fuzz target: the SPEC §7 trace reader must never panic, and whatever it accepts must hold
//! its invariants (strictly increasing finite time, finite pressures, ADC within 12 bits).
#![no_main]

use pbm_io::trace::{parse_trace, Samples};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(t) = parse_trace("fuzz.csv", data) {
        assert!(!t.t_s.is_empty());
        assert_eq!(t.t_s.len(), t.samples.len());
        assert!(t.t_s.windows(2).all(|w| w[0].is_finite() && w[1] > w[0]));
        match &t.samples {
            Samples::Adc(v) => assert!(v.iter().all(|&c| c <= 4095)),
            Samples::Bar(v) => assert!(v.iter().all(|p| p.is_finite())),
        }
        for (_, column) in &t.extra {
            assert_eq!(column.len(), t.t_s.len());
        }
        // The period check must not panic either.
        let _ = t.check_sample_period(0.01, 1e-3);
    }
});
