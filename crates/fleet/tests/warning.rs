//! The early warning on the slow-degradation scenario: it comes before the classifier calls
//! the fault, and rarely on healthy locomotives. The seeds here were not used to choose the
//! rule's constants (those were set on seed 202, `examples/fleet_figures.rs`).

use pbm_fleet::measure::{measure, observe};
use pbm_fleet::scenario::{DegradationOptions, Wear};
use pbm_fleet::trend::WarningRule;

/// Stated bound: false warnings per 1000 healthy releases.
const FALSE_PER_1000_BOUND: f64 = 2.0;

#[test]
fn warning_comes_before_the_fault_call_and_rarely_on_healthy_brakes() {
    let rule = WarningRule::default();
    let degrade = DegradationOptions::new(31337, vec![Wear::Leak, Wear::Clog, Wear::Leak, Wear::Clog]);
    let m = measure(&degrade, &observe(&degrade).unwrap(), &rule);
    assert_eq!(m.lead_times.len(), 4);
    for l in &m.lead_times {
        eprintln!("{l:?} lead {:?}", l.lead(m.releases));
    }
    for l in &m.lead_times {
        let call = l.first_call.expect("the classifier calls the fault by the end");
        let warn = l.first_warning.expect("the warning fires");
        assert!(warn < call, "{l:?}");
        assert!(warn >= degrade.onset, "no warning before the wear starts: {l:?}");
        assert!(l.lead(m.releases).unwrap() > 0);
    }
    let healthy = DegradationOptions::new(4242, vec![Wear::Healthy; 8]);
    let h = measure(&healthy, &observe(&healthy).unwrap(), &rule);
    assert_eq!(h.healthy_releases, 8 * (150 - rule.baseline));
    eprintln!(
        "healthy: {} false warnings in {} releases ({:?})",
        h.false_warnings, h.healthy_releases, h.false_by_parameter
    );
    assert!(
        h.false_per_1000() <= FALSE_PER_1000_BOUND,
        "{} false warnings in {} releases",
        h.false_warnings,
        h.healthy_releases
    );
}
