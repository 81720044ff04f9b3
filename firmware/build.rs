//! Link arguments for the firmware binaries (never in .cargo/config.toml, which the host
//! workspace shares), the memory map from the repository root, and the ADC trace that the
//! QEMU "ADC" plays back, compiled into flash.
//!
//! All of it only with the feature `qemu` (the default): a board crate (`board/`) links this
//! library without it, and the root `memory.x` / `device.x` on its linker search path would
//! shadow the board's own (a library's `rustc-link-search` reaches every dependent's link).
//!
//! Trace source (one release, valve open from the first sample, 100 Hz):
//! - `PBM_FW_TRACE=<file>`: a SPEC §7 trace in raw-counts form (`t_s,adc` header, `#` comment
//!   lines allowed). Only that canonical form is accepted here, strictly; pressure traces
//!   (`t_s,p_bar`) are converted by the host tools first. The build fails with the file and line
//!   of anything else.
//! - unset: the nominal release of the core's own twin, read through the SPEC's sensor map
//!   (`pbm::sensor::adc_from_bar`) with transducer noise of σ ≈ 0.01 bar (SPEC §5) from a fixed
//!   generator, 60 s. The noise matters: a noise-free reading is a frozen sensor to the
//!   monitor's plausibility checks, and the bench must time the classification.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Samples of the default trace (60 s at 100 Hz, SPEC §5).
const DEFAULT_SAMPLES: usize = 6000;
/// Longest trace that fits the flash budget (2 bytes a sample): 10 minutes.
const MAX_SAMPLES: usize = 60_000;

fn nominal_trace() -> Vec<u16> {
    let mut twin = pbm::Twin::new(&pbm::TwinParams::nominal()).expect("nominal parameters are valid");
    let mut p = pbm::PressureQ24::ATMOSPHERE;
    // Sum of four uniforms from a fixed LCG, scaled to σ = 0.01 bar: reproducible noise.
    let mut lcg = 20_231u32;
    let mut noise = move || {
        let sum: f64 = (0..4)
            .map(|_| {
                lcg = lcg.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                f64::from(lcg >> 8) / f64::from(1u32 << 24) - 0.5
            })
            .sum();
        sum * 0.01 * 3f64.sqrt()
    };
    (0..DEFAULT_SAMPLES)
        .map(|_| {
            // Sample n is the chamber after n twin updates (the monitor's convention).
            let adc = pbm::sensor::adc_from_bar(pbm::BarG(p.to_bar_g().0 + noise())).0;
            p = twin.update(true).pressure;
            adc
        })
        .collect()
}

fn read_adc_trace(path: &Path) -> Result<Vec<u16>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut samples = Vec::new();
    let mut header_seen = false;
    let mut last_t = f64::NEG_INFINITY;
    for (i, raw) in text.lines().enumerate() {
        let at = || format!("{}:{}", path.display(), i + 1);
        let line = raw.trim().trim_start_matches('\u{feff}');
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut cols = line.split(',').map(str::trim);
        let (t, v) = (cols.next().unwrap_or(""), cols.next().unwrap_or(""));
        if !header_seen {
            if (t, v) != ("t_s", "adc") {
                return Err(format!("{}: header must start with `t_s,adc` (got `{line}`)", at()));
            }
            header_seen = true;
            continue;
        }
        let t: f64 = t.parse().map_err(|_| format!("{}: bad time `{t}`", at()))?;
        if !(t.is_finite() && t > last_t) {
            return Err(format!("{}: time must increase", at()));
        }
        last_t = t;
        let v: u16 = v.parse().map_err(|_| format!("{}: bad ADC code `{v}`", at()))?;
        if v > 4095 {
            return Err(format!("{}: ADC code {v} above 12 bits", at()));
        }
        samples.push(v);
        if samples.len() > MAX_SAMPLES {
            return Err(format!("{}: more than {MAX_SAMPLES} samples", path.display()));
        }
    }
    if samples.is_empty() {
        return Err(format!("{}: no samples", path.display()));
    }
    Ok(samples)
}

/// The twin check's schedule: a 60 s release, then 30 s venting (reverse flow through the valve).
const TWIN_CHECK_OPEN: u32 = 6000;
const TWIN_CHECK_CLOSED: u32 = 3000;

/// FNV-1a over every sample's pressure and travel on the check schedule (the same function is
/// in the bench binary, which runs the image's twin).
fn twin_hash(mut update: impl FnMut(bool) -> pbm::twin::TwinSample) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for i in 0..TWIN_CHECK_OPEN + TWIN_CHECK_CLOSED {
        let s = update(i < TWIN_CHECK_OPEN);
        for b in s.pressure.0.to_le_bytes().into_iter().chain(s.travel.0.to_le_bytes()) {
            h = (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

/// The mechanisms whose code the core is built with: all with feature `extensions`, else those
/// whose feature (the mechanism's name, forwarded to the core) is on.
fn compiled_mechanisms() -> Vec<pbm::mechanism::Mechanism> {
    let all = std::env::var_os("CARGO_FEATURE_EXTENSIONS").is_some();
    pbm::mechanism::Mechanism::ALL
        .into_iter()
        .filter(|m| all || std::env::var_os(format!("CARGO_FEATURE_{}", m.name().to_uppercase())).is_some())
        .collect()
}

/// `PBM_FW_MECHANISM` (a mechanism's feature, or `extensions`): `NAME=VALUE[,NAME=VALUE…]`,
/// each name a `pbm::mechanism` whose feature is on and each value in the brake twin's valid
/// range; written to `$OUT_DIR/mechanisms.rs` as the list the monitor's twin is built with.
/// Unset: `heat_transfer=20` with `extensions`; with one mechanism's feature, that mechanism at
/// the middle of its first plausible interval. Every failure stops the build with a message.
fn mechanisms(out: &Path, compiled: &[pbm::mechanism::Mechanism]) {
    let fail = |msg: String| -> ! {
        eprintln!("{msg}");
        std::process::exit(1);
    };
    let spec = match std::env::var("PBM_FW_MECHANISM") {
        Ok(spec) => spec,
        Err(_) if std::env::var_os("CARGO_FEATURE_EXTENSIONS").is_some() => "heat_transfer=20".to_owned(),
        Err(_) => match compiled {
            [m] => {
                let d = m.descriptor();
                let (lo, hi) = d.brake.plausible.first().copied().unwrap_or((d.off, d.off));
                format!("{}={}", d.name, 0.5 * (lo + hi))
            }
            _ => fail("PBM_FW_MECHANISM is unset: name the mechanisms (NAME=VALUE[,…])".to_owned()),
        },
    };
    let mut ext = pbm::mechanism::Extensions::NONE;
    let mut items = String::new();
    for item in spec.split(',').map(str::trim).filter(|i| !i.is_empty()) {
        let parsed = item.split_once('=').and_then(|(name, value)| {
            Some((pbm::mechanism::Mechanism::from_name(name.trim())?, value.trim().parse::<f64>().ok()?))
        });
        let Some((m, v)) = parsed else {
            fail(format!("PBM_FW_MECHANISM: `{item}` is not NAME=VALUE with a mechanism of pbm::mechanism"));
        };
        if !compiled.contains(&m) {
            // The image would carry coefficients for terms it does not compute.
            fail(format!("PBM_FW_MECHANISM names {m}: build with `--features {m}` (or `extensions`)"));
        }
        ext = ext.with(m, v);
        write!(items, "(pbm::mechanism::Mechanism::{m:?}, {v:?}), ").unwrap();
    }
    let mut params = pbm::TwinParams::nominal();
    params.ext = ext;
    // The coefficients are derived here, on the host, in f64: the image gets integers only
    // (`TwinCoeffs::from_raw`) and no f64 set-up code (≈ 24 KiB of soft-float and libm).
    let raw = match pbm::twin::TwinCoeffs::new(&params) {
        Ok(c) => c.to_raw(),
        Err(e) => fail(format!("PBM_FW_MECHANISM={spec}: the twin rejects it: {e}")),
    };
    // The host's extended twin (every mechanism compiled in) over the check schedule: the image's
    // own twin must give the same bits (the bench binary compares).
    let hash = match pbm::Twin::new(&params) {
        Ok(mut twin) => twin_hash(|open| twin.update(open)),
        Err(e) => fail(format!("PBM_FW_MECHANISM={spec}: the twin rejects it: {e}")),
    };
    let text = format!(
        "/// The twin's mechanisms and magnitudes (`PBM_FW_MECHANISM={spec}`).\n\
         pub const MECHANISMS: &[(pbm::mechanism::Mechanism, f64)] = &[{items}];\n\
         /// Their twin's coefficients, derived by build.rs (`pbm::twin::TwinCoeffs::to_raw`).\n\
         pub const TWIN_RAW: [i64; pbm::twin::RAW_COEFFS] = {raw:?};\n\
         /// FNV-1a hash of the host twin's samples over `TWIN_CHECK_OPEN` samples with the valve\n\
         /// open, then `TWIN_CHECK_CLOSED` closed (pressure, then travel, little-endian).\n\
         pub const TWIN_HASH: u64 = {hash};\n\
         /// Samples of the check schedule.\n\
         pub const TWIN_CHECK_OPEN: u32 = {TWIN_CHECK_OPEN};\n\
         /// Samples of the check schedule.\n\
         pub const TWIN_CHECK_CLOSED: u32 = {TWIN_CHECK_CLOSED};\n"
    );
    std::fs::write(out.join("mechanisms.rs"), text).expect("write mechanisms.rs");
}

/// The fleet number of a trace's `# locomotive:` metadata line (0 without one), as
/// `host-sim replay` reads it (`pbm::can::codec::fleet_number`).
fn trace_locomotive(path: &Path) -> u16 {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    text.lines()
        .filter_map(|l| l.trim().strip_prefix('#'))
        .filter_map(|l| l.split_once(':'))
        .find(|(k, _)| k.trim() == "locomotive")
        .map_or(0, |(_, v)| {
            pbm::can::codec::fleet_number(v).unwrap_or_else(|| {
                panic!(
                    "{}: locomotive {:?} is above 4095, the largest fleet number the CAN frames carry",
                    path.display(),
                    v.trim()
                )
            })
        })
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo:rerun-if-env-changed=PBM_FW_MECHANISM");
    // `pbm_mechanisms`: the image runs an extended twin (app.rs).
    println!("cargo::rustc-check-cfg=cfg(pbm_mechanisms)");
    let compiled = compiled_mechanisms();
    if !compiled.is_empty() {
        println!("cargo:rustc-cfg=pbm_mechanisms");
        mechanisms(&out, &compiled);
    } else if let Ok(spec) = std::env::var("PBM_FW_MECHANISM") {
        // A nominal image would silently ignore the mechanisms asked for.
        eprintln!("PBM_FW_MECHANISM={spec} needs the mechanism's feature (`--features NAME`)");
        std::process::exit(1);
    }
    if std::env::var_os("CARGO_FEATURE_QEMU").is_none() {
        return;
    }
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let root = manifest.parent().expect("firmware/ sits in the repository root");

    // cortex-m-rt's link.x INCLUDEs memory.x from the linker search path.
    println!("cargo:rustc-link-search={}", root.display());
    // device.x (cortex-m-rt `device` feature): the interrupt vectors are firmware/src/vectors.rs.
    println!("cargo:rustc-link-search={}", manifest.display());
    println!("cargo:rerun-if-changed={}", manifest.join("device.x").display());
    println!("cargo:rerun-if-changed={}", root.join("memory.x").display());
    println!("cargo:rerun-if-env-changed=PBM_FW_TRACE");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    // defmt's interned strings go to the non-allocated `.defmt` section of the ELF.
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");

    let (name, samples, locomotive) = match std::env::var_os("PBM_FW_TRACE") {
        Some(p) => {
            let path = PathBuf::from(p);
            println!("cargo:rerun-if-changed={}", path.display());
            match read_adc_trace(&path) {
                Ok(s) => (path.display().to_string(), s, trace_locomotive(&path)),
                Err(e) => {
                    eprintln!("PBM_FW_TRACE: {e}");
                    std::process::exit(1);
                }
            }
        }
        None => ("nominal release of the core twin with transducer noise".to_string(), nominal_trace(), 0),
    };
    let mut s = String::new();
    writeln!(s, "/// Where the compiled-in trace came from.").unwrap();
    writeln!(s, "pub const ADC_TRACE_NAME: &str = {name:?};").unwrap();
    writeln!(s, "/// ADC codes of one release, 100 Hz, from the release command.").unwrap();
    writeln!(s, "pub static ADC_TRACE: [u16; {}] = {samples:?};", samples.len()).unwrap();
    writeln!(s, "/// The locomotive number of the trace's `# locomotive:` line (0 without one), which the").unwrap();
    writeln!(s, "/// CAN frames carry, as `host-sim replay` takes it from the same line.").unwrap();
    writeln!(s, "pub const ADC_TRACE_LOCOMOTIVE: u16 = {locomotive};").unwrap();
    std::fs::write(out.join("adc_trace.rs"), s).expect("write adc_trace.rs");
}
