//! Helpers shared by the integration tests.

/// The ADC codes of a recorded trace `tests/data/<rel>` (the `adc` column; metadata and header
/// lines skipped). Panics with the path on a missing file or a malformed line: a test never
/// runs on less data than it names.
pub fn adc_codes(rel: &str) -> Vec<u16> {
    let path = format!("{}/tests/data/{rel}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("t_s"))
        .map(|l| l.split(',').nth(1).and_then(|c| c.trim().parse().ok()).unwrap_or_else(|| panic!("{path}: {l}")))
        .collect()
}
