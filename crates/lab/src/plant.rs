//! The "measured-like" plant's mechanisms beyond the base twin, as the host tools name them.
//!
//! Every mechanism is described once, in the core's table [`pbm::mechanism::MECHANISMS`]: name,
//! unit, off value, plain-language description, the range each model supports, the range the
//! audits search and the plausible range of a hidden effect. The f64 plant
//! ([`crate::reference::ReferenceTwin`]) and the fixed-point twin implement the same
//! definitions. This module parses `--effect NAME=VALUE` and prints the table for `--help` and
//! reports.

use anyhow::{bail, Result};
use pbm::mechanism::{Extensions, Mechanism, MECHANISMS};

/// One line per mechanism (name, unit, plausible range, what it is), for `--effect` help.
pub fn effect_help() -> String {
    let mut out = String::from(
        "NAME=VALUE adds a mechanism the base model lacks. NAME (unit; plausible values):
",
    );
    for d in &MECHANISMS {
        let ranges: Vec<String> = d.brake.plausible.iter().map(|(lo, hi)| format!("{lo}–{hi}")).collect();
        out.push_str(&format!(
            "  {} ({}; {}): {}
",
            d.name,
            d.unit,
            ranges.join(" or "),
            d.description
        ));
    }
    out
}

/// Parses `NAME=VALUE` (as accepted by `--effect`).
pub fn parse_effect(s: &str) -> Result<(Mechanism, f64), String> {
    let (name, value) = s.split_once('=').ok_or_else(|| format!("expected NAME=VALUE, got `{s}`"))?;
    let effect = effect_by_name(name.trim()).map_err(|e| e.to_string())?;
    let value: f64 = value.trim().parse().map_err(|_| format!("effect `{name}`: `{value}` is not a number"))?;
    if !value.is_finite() {
        return Err(format!("effect `{name}`: value must be finite"));
    }
    Ok((effect, value))
}

/// Looks a mechanism up by name; the error lists the known names.
pub fn effect_by_name(name: &str) -> Result<Mechanism> {
    match Mechanism::from_name(name) {
        Some(m) => Ok(m),
        None => {
            let known: Vec<_> = Mechanism::ALL.iter().map(|m| m.name()).collect();
            bail!("unknown mechanism `{name}` (known: {})", known.join(", "))
        }
    }
}

/// Builds the [`Extensions`] of a list of `(name, value)` pairs; a name given twice, an unknown
/// name or a value outside what the twin supports is an error.
pub fn extensions_from_pairs(pairs: &[(String, f64)]) -> Result<Extensions> {
    let mut ext = Extensions::NONE;
    let mut seen = Vec::new();
    for (name, value) in pairs {
        let mechanism = effect_by_name(name)?;
        if seen.contains(&mechanism) {
            bail!("mechanism `{name}` given twice");
        }
        seen.push(mechanism);
        ext[mechanism] = *value;
    }
    ext.validate().map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(ext)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_rejects_bad_input() {
        assert_eq!(parse_effect("transport_delay=0.3"), Ok((Mechanism::TransportDelay, 0.3)));
        assert!(parse_effect("nope=1").is_err());
        assert!(parse_effect("valve_lag").is_err());
        assert!(parse_effect("valve_lag=abc").is_err());
        assert!(parse_effect("valve_lag=inf").is_err());
        assert!(extensions_from_pairs(&[("valve_lag".into(), 0.1), ("valve_lag".into(), 0.2)]).is_err());
        let e = extensions_from_pairs(&[("sensor_gain".into(), 9.0)]).expect_err("out of range");
        assert!(e.to_string().contains("sensor_gain") && e.to_string().contains("0.5..=1.5"), "{e}");
    }

    #[test]
    fn help_lists_every_mechanism_with_its_unit() {
        let help = effect_help();
        for d in &MECHANISMS {
            assert!(help.contains(&format!("  {} ({};", d.name, d.unit)), "{}", d.name);
        }
    }
}
