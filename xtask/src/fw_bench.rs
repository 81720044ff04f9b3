//! `cargo xtask fw-bench [--check]`: the cost of the firmware on the Cortex-M4F, measured in
//! QEMU (mps2-an386, `-icount shift=0`: one instruction = 1 ns of virtual time, deterministic).
//!
//! - Instructions per sample of `Pipeline::step` (everything the monitor task does per sample),
//!   of the twin, the estimator and the release features alone, of one classification and of
//!   the sample that closes a diagnosis, from the `bench` binary (SysTick brackets around each
//!   call, calibrated on a loop of known length) on the compiled-in nominal release and on
//!   recorded traces (`PBM_FW_TRACE`, one relink each: the worst sample is trace dependent).
//! - Flash and static RAM of the `monitor` image from its ELF (`llvm-size`), the compiled-in
//!   test trace counted separately, and flash by component (`llvm-nm`).
//! - Peak stack of the `monitor` image by stack painting (its own end-of-run report).
//!
//! Without `--check` the figures are written to `bench/firmware.md` (and the headline figures to
//! `bench/firmware-figures.env`, which the demo report shows); with it nothing is written
//! and a figure past its bound in `bench/firmware-bounds.env` fails the task.

use crate::util::{cargo_bin, output, require, run, stdout_of, Result};
use std::collections::BTreeMap;
use std::process::Command;

const TARGET: &str = crate::firmware::TARGET;
const ELF: &str = "firmware/target/thumbv7em-none-eabihf/release/monitor";
const BOUNDS: &str = "bench/firmware-bounds.env";
const REPORT: &str = "bench/firmware.md";
/// The headline figures as `KEY=VALUE` lines, for the demo report.
const FIGURES: &str = "bench/firmware-figures.env";
/// Budgets of the controller: instructions per sample (10 ms at 25 MHz with margin), flash, RAM.
const TARGET_INSTR: u64 = 5000;
const TARGET_FLASH: u64 = 32 * 1024;
const TARGET_RAM: u64 = 8 * 1024;
/// Recorded (noisy) traces the bench also runs.
const RECORDED: [&str; 4] = [
    "tests/data/small/traces/test/low_supply_0000.csv",
    "tests/data/small/traces/test/orifice_missing_0000.csv",
    "tests/data/small/traces/test/leak_and_block_0000.csv",
    "tests/data/sensor_fault/normal_open_circuit.csv",
];

/// The extended twin's images (issue 19 item 4): one mechanism each, chosen at build time (the
/// mechanism's feature and `PBM_FW_MECHANISM`), at a magnitude inside its plausible range.
const EXTENDED: [&str; 10] = [
    "sensor_offset=0.1",
    "sensor_gain=1.05",
    "sensor_lag=0.2",
    "transport_delay=0.2",
    "valve_lag=0.5",
    "laminar_leak=0.3",
    "progressive_spring=0.3",
    "gas_temperature=390",
    "heat_transfer=20",
    "regulator_droop=0.8",
];

/// `KEY=VALUE` lines a run printed.
struct Figures(BTreeMap<String, String>);

impl Figures {
    fn parse(text: &str) -> Self {
        Self(
            text.lines()
                .filter_map(|l| l.split_once('='))
                .map(|(k, v)| (k.trim().to_owned(), v.trim().to_owned()))
                .collect(),
        )
    }
    fn get(&self, key: &str) -> Result<u64> {
        let v = self.0.get(key).ok_or_else(|| format!("the bench printed no `{key}`"))?;
        v.parse().map_err(|_| format!("`{key}={v}` is not a count"))
    }
}

fn firmware_cargo(args: &[&str], trace: Option<&str>) -> Command {
    let mut cmd = Command::new(cargo_bin());
    cmd.args(args).args(["--quiet", "--manifest-path", "firmware/Cargo.toml", "--target", TARGET, "--release"]);
    match trace {
        Some(t) => cmd.env("PBM_FW_TRACE", t),
        None => cmd.env_remove("PBM_FW_TRACE"),
    };
    // The nominal image unless a mechanism's image sets it (with the mechanism's feature).
    cmd.env_remove("PBM_FW_MECHANISM");
    cmd
}

/// The cargo arguments and environment of an extended twin's image: `features` (a mechanism's
/// name, or `extensions` for all ten) and the mechanisms it runs (`None`: build.rs's default).
#[derive(Clone, Copy)]
struct Image<'a> {
    features: &'a str,
    spec: Option<&'a str>,
}

impl Image<'_> {
    /// The image of the one mechanism `spec` (`NAME=VALUE`) names.
    fn mechanism(spec: &str) -> Image<'_> {
        Image { features: spec.split_once('=').map_or(spec, |(name, _)| name), spec: Some(spec) }
    }

    fn apply(self, cmd: &mut Command) {
        cmd.args(["--features", self.features]);
        if let Some(spec) = self.spec {
            cmd.env("PBM_FW_MECHANISM", spec);
        }
    }
}

/// The `bench` binary's figures: `key=value` lines of its defmt log, which the runner
/// (`firmware/qemu-run.sh`) decodes onto standard error.
fn bench_run(trace: Option<&str>) -> Result<Figures> {
    let mut cmd = firmware_cargo(&["run"], trace);
    cmd.args(["--bin", "bench"]);
    bench_figures(&mut cmd)
}

/// The bench of an extended twin's image.
fn extended_bench_run(image: Image) -> Result<Figures> {
    let mut cmd = firmware_cargo(&["run"], None);
    cmd.args(["--bin", "bench"]);
    image.apply(&mut cmd);
    bench_figures(&mut cmd)
}

/// Runs a bench command; its decoded log's figures.
fn bench_figures(cmd: &mut Command) -> Result<Figures> {
    let out = output(cmd)?;
    let log = String::from_utf8_lossy(&out.stderr).into_owned();
    if !out.status.success() {
        return Err(format!("bench run failed ({}):\n{log}", out.status));
    }
    Ok(Figures::parse(&log))
}

/// The `monitor` image's peak stack and the verdict it closed (its stderr report): the nominal
/// image, or an extended twin's.
fn monitor_run(image: Option<Image>) -> Result<(u64, String)> {
    let mut cmd = firmware_cargo(&["run"], None);
    cmd.args(["--bin", "monitor"]);
    if let Some(image) = image {
        image.apply(&mut cmd);
    }
    let out = output(&mut cmd)?;
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    if !out.status.success() {
        return Err(format!("monitor run failed ({}):\n{err}", out.status));
    }
    let stack = err
        .split("peak stack ")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .ok_or_else(|| format!("monitor reported no peak stack:\n{err}"))?;
    let verdict = err.lines().filter_map(|l| l.strip_prefix("monitor: diagnosis closed ")).next_back().unwrap_or("");
    Ok((stack, verdict.to_owned()))
}

/// (text, data, bss) of the ELF (Berkeley format of `llvm-size`).
fn sizes() -> Result<(u64, u64, u64)> {
    let out = stdout_of(Command::new("llvm-size").arg(ELF))?;
    let last = out.lines().last().unwrap_or("");
    let v: Vec<u64> = last.split_whitespace().take(3).filter_map(|x| x.parse().ok()).collect();
    match v.as_slice() {
        [t, d, b] => Ok((*t, *d, *b)),
        _ => Err(format!("cannot read llvm-size output: {out}")),
    }
}

/// Which part of the image a symbol belongs to (inlined code counts where it was inlined).
fn component(name: &str) -> &'static str {
    let any = |prefixes: &[&str]| prefixes.iter().any(|p| name.starts_with(p));
    if any(&["pbm::twin", "pbm::params", "pbm::fixed", "pbm::sensor", "pbm::units", "pbm::mechanism"]) {
        "core: twin, parameters, sensor map"
    } else if name.starts_with("pbm::classifier") {
        "core: classifier (code + int8 model)"
    } else if any(&["pbm::estimator", "pbm::features", "pbm::monitor", "pbm::plausibility"]) {
        "core: estimator, features, monitor"
    } else if any(&["pbm::can", "pbm::pipeline"]) {
        "core: CAN codec, schedule, pipeline, candump"
    } else if name.starts_with("pbm::") {
        "core: other"
    } else if name.starts_with("__aeabi_d") || name.contains("df3") || name.contains("dfsi") || name.contains("dfdi") {
        "soft-float f64"
    } else if name.starts_with("libm::") {
        "libm (software sqrtf of the estimator and features)"
    } else if any(&[
        "embassy",
        "_embassy",
        "defmt",
        "_defmt",
        "__defmt",
        "<embassy",
        "monitor::",
        "pbm_firmware",
        "cortex_m",
        "__INTERRUPTS",
        "__EXCEPTIONS",
        "Reset",
        "SysTick",
        "DefaultHandler",
        "HardFault",
        "__pre_init",
        "main",
    ]) {
        "runtime: embassy executor + sync, tasks, vectors, defmt logger, semihosting"
    } else if name.contains("compiler_builtins") || any(&["__aeabi", "__udiv", "__divmod", "__umod", "mem"]) {
        "compiler builtins: mem*, 64-bit division, f32 helpers"
    } else if any(&["core::", "<core", "<&", "<usize", "<u32", "<u64", "__rustc"]) {
        "core::fmt and panic paths (bounds checks)"
    } else {
        "other (anonymous constants, ...)"
    }
}

/// Flash by component and the size of the compiled-in test trace.
fn flash_by_component() -> Result<(Vec<(&'static str, u64)>, u64)> {
    let out = stdout_of(Command::new("llvm-nm").args(["--print-size", "--radix=d", "--demangle", ELF]))?;
    let mut by: BTreeMap<&'static str, u64> = BTreeMap::new();
    let mut trace = 0;
    for line in out.lines() {
        let f: Vec<&str> = line.splitn(4, ' ').collect();
        let [_, size, kind, name] = f.as_slice() else { continue };
        let Ok(size) = size.parse::<u64>() else { continue };
        if !matches!(*kind, "t" | "T" | "r" | "R") {
            continue;
        }
        if name.contains("ADC_TRACE") {
            trace = trace.max(size);
            continue;
        }
        *by.entry(component(name)).or_default() += size;
    }
    let mut v: Vec<_> = by.into_iter().collect();
    v.sort_by_key(|x| std::cmp::Reverse(x.1));
    Ok((v, trace))
}

fn verdict(value: u64, target: u64) -> &'static str {
    if value <= target {
        "ok"
    } else {
        "**OVER**"
    }
}

/// Flash (without the test trace), static RAM and RAM (with `peak_stack`) of the `monitor` ELF
/// the last build left.
fn image_size(peak_stack: u64) -> Result<(u64, u64, u64)> {
    let (text, data, bss) = sizes()?;
    let (_, trace_bytes) = flash_by_component()?;
    Ok((text + data - trace_bytes, data + bss, data + bss + peak_stack))
}

/// The figures of one mechanism's image: its bench (per-sample instructions on the nominal
/// trace) and its `monitor` (flash, RAM, verdict).
struct MechanismImage {
    spec: &'static str,
    bench: Figures,
    flash: u64,
    ram: u64,
}

impl MechanismImage {
    fn measure(spec: &'static str) -> Result<Self> {
        println!("== extended twin: image of {spec} (bench, monitor)");
        let image = Image::mechanism(spec);
        let bench = extended_bench_run(image)?;
        // The image's twin against the host's (the bench exits with failure on a mismatch).
        if bench.0.get("ext_twin_check").map(String::as_str) != Some("equal") {
            return Err(format!("{spec}: the image's twin was not checked against the host's"));
        }
        let (peak_stack, closed) = monitor_run(Some(image))?;
        println!("{spec}: monitor diagnosis closed {closed}");
        let (flash, _, ram) = image_size(peak_stack)?;
        Ok(Self { spec, bench, flash, ram })
    }

    fn worst(&self) -> Result<u64> {
        self.bench.get("pipeline_instr_per_sample_max")
    }

    /// Within all three budgets.
    fn fits(&self) -> Result<bool> {
        Ok(self.flash <= TARGET_FLASH && self.ram <= TARGET_RAM && self.worst()? <= TARGET_INSTR)
    }

    fn row(&self) -> Result<String> {
        let f = &self.bench;
        Ok(format!(
            "| `{}` | {} | {} | {} / {} | {} | {} | {} |\n",
            self.spec,
            self.flash,
            self.ram,
            f.get("pipeline_instr_per_sample_mean")?,
            self.worst()?,
            f.get("pipeline_samples_over_budget")?,
            f.get("twin_instr_per_sample_max")?,
            if self.fits()? { "ok" } else { "**OVER**" }
        ))
    }
}

/// `fw-bench --check`: every mechanism's image within the flash, RAM and per-sample budgets.
fn check_extended() -> Result<()> {
    let mut failed = Vec::new();
    for spec in EXTENDED {
        let image = MechanismImage::measure(spec)?;
        print!("{}", image.row()?);
        if !image.fits()? {
            failed.push(spec);
        }
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("extended twin images past the budget: {}", failed.join(", ")))
    }
}

/// The extended twin's images: one per mechanism (flash, RAM, per-sample cost on the nominal
/// trace), and the image with all ten mechanisms compiled in. The report section.
fn extended_figures() -> Result<String> {
    let mut rows = String::new();
    for spec in EXTENDED {
        let row = MechanismImage::measure(spec)?.row()?;
        print!("{row}");
        rows.push_str(&row);
    }
    println!("== extended twin: monitor image with every mechanism (extensions, heat_transfer=20)");
    let (peak_stack, closed) = monitor_run(Some(Image { features: "extensions", spec: None }))?;
    let (flash, static_ram, ram) = image_size(peak_stack)?;
    let over = |v: u64, budget: u64| {
        if v <= budget {
            format!("{} B under", budget - v)
        } else {
            format!("**{} B over**", v - budget)
        }
    };
    Ok(format!(
        r#"## Extended twin images (one mechanism each)

The image for the mechanism an audit named: `PBM_FW_MECHANISM=NAME=VALUE cargo fw-monitor
--features NAME` (NAME as `pbm::mechanism` names it; firmware/README.md). The mechanism's feature
compiles only its terms into the twin's extended path (`pbm::mechanism::Mechanism::compiled`);
build.rs derives the twin's coefficients on the host (`TwinCoeffs::new` → `to_raw`) and the image
takes them with `TwinCoeffs::from_raw`: no `f64` set-up code. A term compiled out is one whose
coefficient is then zero, and skipping it is an exact identity: each image's twin gives the same
bits as the host's extended twin (`twin::tests::extended_path_equals_the_reference_bit_for_bit`
on the host; on the target, each image's `bench` hashes its twin over a 60 s release and a 30 s
vent and fails unless the hash equals the host twin's, which build.rs computed: `TWIN_HASH`).

Per image: flash of `monitor` without the test trace; RAM = static + peak stack of its `monitor`
run; `Pipeline::step` per sample over the nominal trace (instructions, mean / worst, samples over
{TARGET_INSTR}); the twin alone, worst sample. Targets: {TARGET_FLASH} B, {TARGET_RAM} B, {TARGET_INSTR} instructions.

| mechanism | flash B | RAM B | mean / worst | over {TARGET_INSTR} | twin worst | |
|---|---|---|---|---|---|---|
{rows}
Every mechanism's terms compiled in (`--features extensions`, `heat_transfer=20`, which mechanisms
run is then data): flash {flash} B ({v_flash}), RAM = static {static_ram} B + peak stack
{peak_stack} B = {ram} B ({v_ram}). Its `monitor` run: diagnosis closed {closed}.

All ten fit (`fw-bench --check` holds every one to the budget). What it took: one cargo feature
per mechanism (the image carries only that mechanism's terms); in the extended path, the base
model's step (`Twin::pressure_step`, one copy for every mechanism, the wall heat's terms in it
too), with the valve line's second path and the laminar leak passed in as one extra increment;
the 64-bit product for a valve path's share (the nominal brake's flows fit 64 bits; 128 on the
host); zero vents skipped; terms whose feature is off compiled out (the progressive spring's
term too: 132 B in every other image and the nominal one); the orifice flow out of line in these images (≈ 250 B
each use) and the twin copied from flash. All exact: the same bits as the host.

The two that did not fit (issue 19 item 4; the host twin's bits changed with them, the
`f64` reference's agreement checked run by run: `cargo run --release -p pbm-lab --example
ext_vs_reference`):

- `heat_transfer` (was 35648 B, 8880 instructions): the gas temperature was a state θ, and every
  substep took four 64-bit divisions (compiler-builtins' routine, ≈ 1.1 KiB and ≈ 150–250
  instructions each on the M4, which divides 32 bits only) and on reverse flow a 64-bit square
  root (`u64::isqrt`, ≈ 0.5 KiB). Now the state is the gas content (its mass, summed exactly)
  beside the pressure, and θ = p/p_w follows from the two: the wall heat is (p_w − p) h/τ, no
  division while the chamber fills; a venting substep takes two 32-bit divisions (a 16-bit
  reciprocal) and a 32-bit square root for √θ and 1/√θ.
- `regulator_droop` (was 37328 B, 100600 instructions): the drooped supply, the root of
  pu = Ps − droop · m(pu)/m_ref, took an eight-step bisection with an orifice flow and a 128-bit
  quotient per step, in every substep of the fill. Now droop/m_ref is a coefficient, and one
  Newton step a substep from the last substep's root (the flow table's own slope, a 32-bit
  reciprocal) solves it: the residual is concave in pu, so the steps stay in [p, Ps].
"#,
        v_flash = over(flash, TARGET_FLASH),
        v_ram = over(ram, TARGET_RAM),
    ))
}

/// Runs the bench; writes `bench/firmware.md` or checks the bounds.
pub fn bench(check: bool) -> Result<()> {
    require("llvm-size")?;
    require("llvm-nm")?;
    run(&mut firmware_cargo(&["build", "--bins"], None))?;
    println!("== bench binary in QEMU (-icount shift=0)");
    let nominal = bench_run(None)?;
    for (k, v) in &nominal.0 {
        println!("{k}={v}");
    }
    println!("== monitor application in QEMU (peak stack)");
    let (peak_stack, closed) = monitor_run(None)?;
    println!("peak stack {peak_stack} B; diagnosis closed {closed}");

    let mut rows = String::new();
    let mut worst = nominal.get("pipeline_instr_per_sample_max")?;
    for t in RECORDED {
        println!("== bench on {t}");
        let abs = std::fs::canonicalize(t).map_err(|e| format!("{t}: {e}"))?;
        let f = bench_run(Some(&abs.to_string_lossy()))?;
        let max = f.get("pipeline_instr_per_sample_max")?;
        worst = worst.max(max);
        let row = format!(
            "| `{}` | {} | {max} | {} | {} | {} |\n",
            t.trim_start_matches("tests/data/"),
            f.get("pipeline_instr_per_sample_mean")?,
            f.get("pipeline_samples_over_budget")?,
            f.get("estimator_instr_per_sample_max")?,
            f.get("classify_instr")?
        );
        print!("{row}");
        rows.push_str(&row);
    }
    // The extended twin's images: measured for the report, or (--check) held to the budget.
    let extended = if check {
        check_extended()?;
        None
    } else {
        Some(extended_figures()?)
    };

    // Leave the default build (compiled-in nominal trace) as the current artefact.
    run(&mut firmware_cargo(&["build", "--bins"], None))?;

    let (text, data, bss) = sizes()?;
    let (components, trace_bytes) = flash_by_component()?;
    let flash_total = text + data;
    let flash = flash_total - trace_bytes;
    let static_ram = data + bss;
    let ram = static_ram + peak_stack;
    let n = |k: &str| nominal.get(k);
    let (pipe, pipe_max) = (n("pipeline_instr_per_sample_mean")?, n("pipeline_instr_per_sample_max")?);
    let (closing, classify) = (n("closing_sample_instr")?, n("classify_instr")?);

    if check {
        let bounds = Figures::parse(
            &std::fs::read_to_string(BOUNDS)
                .map_err(|e| format!("cannot read {BOUNDS}: {e}"))?
                .lines()
                .filter(|l| !l.trim_start().starts_with('#'))
                .collect::<Vec<_>>()
                .join("\n"),
        );
        let checks = [
            ("pipeline instr/sample mean", pipe, "BOUND_PIPELINE_INSTR_MEAN"),
            ("pipeline instr/sample worst (nominal trace)", pipe_max, "BOUND_PIPELINE_INSTR_MAX"),
            ("pipeline instr/sample worst (all traces)", worst, "BOUND_PIPELINE_INSTR_WORST"),
            ("classification instr", classify, "BOUND_CLASSIFY_INSTR"),
            ("closing sample instr", closing, "BOUND_CLOSING_SAMPLE_INSTR"),
            ("flash bytes", flash, "BOUND_FLASH"),
            ("RAM bytes", ram, "BOUND_RAM"),
        ];
        println!("\n== bounds ({BOUNDS})");
        let mut failed = Vec::new();
        for (what, value, key) in checks {
            let bound = bounds.get(key).map_err(|_| format!("{BOUNDS} has no {key}"))?;
            if value <= bound {
                println!("  {what}: {value} <= {bound}");
            } else {
                println!("REGRESSION: {what} {value} > bound {bound}");
                failed.push(what);
            }
        }
        if !failed.is_empty() {
            return Err(format!("past the bounds of {BOUNDS}: {}", failed.join(", ")));
        }
        println!("fw-bench: within recorded bounds");
        return Ok(());
    }

    // The board image's size (built by `cargo xtask fw-board`; built here if missing).
    let (board_flash, board_ram) = match crate::board::board_size() {
        Ok(v) => v,
        Err(_) => {
            crate::board::build()?;
            crate::board::board_size()?
        }
    };
    let qemu = stdout_of(Command::new("qemu-system-arm").arg("--version"))?;
    let date = stdout_of(Command::new("date").args(["-u", "+%Y-%m-%d"]))?;
    let component_rows: String = components.iter().map(|(c, b)| format!("| {c} | {b} |\n")).collect();
    let symbol_sum: u64 = components.iter().map(|(_, b)| b).sum();
    let report = format!(
        r#"# Firmware cost (Cortex-M4F, QEMU mps2-an386)

Measured by `cargo xtask fw-bench` ({date}, {qemu}).
Instructions are counted with `qemu-system-arm -icount shift=0` (1 instruction = 1 ns of virtual
time, read through SysTick at 25 MHz = 40 instructions per count; calibration loop of 300000
instructions measured as {cal}). Over the {samples} samples of the compiled-in trace (the core
twin's nominal release with σ = 0.01 bar of transducer noise, 60 s). Profile `release` of
`firmware/Cargo.toml`: opt-level "z", the core (`parking-brake-monitor`) at "s" (at "z" the
worst sample exceeds the budget), fat LTO, codegen-units 1, panic = abort.

| figure | value | target | |
|---|---|---|---|
| **per-sample pipeline** `Pipeline::step` (twin, estimator, release features, diagnosis policy, CAN schedule), nominal release, mean / worst sample | {pipe} / {pipe_max} instr | ≤ {TARGET_INSTR} | {v_pipe} |
| worst sample over all measured traces (table below) | {worst} instr | ≤ {TARGET_INSTR} | {v_worst} |
| of which twin (`Twin::update`), mean / worst | {twin} / {twin_max} instr | | |
| of which online estimator (`ReleaseEstimator::update`, f32 RLS), mean / worst | {est} / {est_max} instr | | |
| of which release features (`ReleaseFeatures::update`, f32), mean / worst | {feat} / {feat_max} instr | | |
| **per classification** (`classifier::diagnose`, int8 network, once per release) | {classify} instr | | |
| MetroPT-3 reservoir model (`reservoir::Reservoir::update` with heat transfer + transport delay, one 0.5 s substep; bench binary only), mean / worst | {res} / {res_max} instr | | |
| the sample that closes a diagnosis (step + classification + report frame) | {closing} instr | < 250000 (10 ms at 25 MHz) | {v_closing} |
| **flash**, `monitor` app (text + rodata + data, without the {trace_bytes}-byte test trace) | {flash} B | ≤ {TARGET_FLASH} | {v_flash} |
| flash including the test trace | {flash_total} B | | |
| static RAM (data + bss; the pipeline lives in the monitor task's static storage) | {static_ram} B | | |
| peak stack (painted, `monitor` app, whole run incl. the classification) | {peak_stack} B | | |
| **RAM** = static + peak stack | {ram} B | ≤ {TARGET_RAM} | {v_ram} |

The `monitor` run on this trace: diagnosis closed {closed}.

## Per-sample cost by trace

`Pipeline::step` per sample (instructions) over a whole 60 s release; "over" = samples above
the {TARGET_INSTR}-instruction budget. The estimator spreads its block work over the samples
(`src/estimator/mod.rs`, "Per-sample cost"): one RLS window update per sample, the reported
window first, and the plateau's supply solution a few bisection steps per sample. The worst
samples are block samples (block sum, rate, CUSUM, the reported window's update, plateau level)
coinciding with twin substeps while the nominal twin's piston moves.

| trace | mean | worst | over | estimator worst | classification |
|---|---|---|---|---|---|
| nominal twin release (compiled-in default, with transducer noise) | {pipe} | {pipe_max} | {over} | {est_max} | {classify} |
{rows}
## Flash by component (`monitor` app, bytes of text + rodata symbols)

| component | bytes |
|---|---|
{component_rows}| **sum of symbols** | {symbol_sum} |

## Flash against the 32 KiB target

What was cut (2026-11-23, from 48008 B, nothing the monitor does removed):

- the twin's optional mechanisms (`pbm::mechanism`, ≈ 4.4 KiB then, ≈ 4.0 KiB today with all
  ten: "Extended twin images" below): the core's cargo feature `extensions` (default, host
  tools) is off in the firmware, which runs only the nominal twin; `Twin::update` then never
  takes the extended path and `TwinCoeffs::new` rejects parameters that use a mechanism (an
  image for one mechanism turns on only that mechanism's feature);
- `f64` soft-float and `libm` set-up: `Pipeline::nominal` builds the twin and the estimator
  from precomputed constants (`TwinCoeffs::NOMINAL`, the estimator's nominal design constants),
  each checked by a test against the `f64` computation from `TwinParams::nominal()`;
- the classifier's input map in `f32` (the same int8 inputs on every golden vector, and the
  same verdicts on the fleet data set) and its softmax table without the zero tail;
- the Stribeck table as `u16` up to its first zero (same values);
- the vector table: the AN386's 32 device interrupts instead of 240 (`firmware/src/vectors.rs`);
- `memmove` (1.5 KiB), pulled in by embassy's generic timer queue and by a send future holding a
  frame: a fixed-slot timer queue, and a send that builds the message once there is room;
- the CRC-8 table (issue 18, 2026-11-25): a 16-entry nibble table instead of the `crc` crate's
  256 bytes, same CRC (checked against the crate in the tests). It paid for the CAN freshness
  fields of layout 2 (release number, heartbeat counter, identity in the CRC): 32 668 B before
  issue 18, 32 496 B after, and the per-sample worst case went down by 40 instructions.
- the log text (2026-11-25, issue 19): defmt instead of a hand-made line builder, the format
  strings in the ELF's `.defmt` section, decoded on the host: 376 B of flash (32668 → 32292 B)
  and 1068 B of stack (no 192-byte line buffers: 3312 → 2244 B).

Still in the image and candidates if the budget tightens: `libm::sqrtf` in software (≈ 0.5 KiB;
the FPU's `VSQRT` needs an `unsafe` asm block, which the core forbids); the core at opt-level
"z" (≈ 0.8 KiB, but the worst sample then exceeds {TARGET_INSTR} instructions).

{extended}
## Board image (NUCLEO-F446RE, `firmware/board/`)

The same application with embassy-stm32's drivers (clock tree, TIM3-triggered ADC with DMA,
bxCAN, EXTI, IWDG, TIM2 time driver), defmt over RTT and panic-probe; built by
`cargo xtask fw-board` (and `test-all`). QEMU has no bxCAN and no STM32 clock tree: the board
image is checked by build, clippy and size; its cycles per sample are logged by the board itself.

| figure | QEMU `monitor` | board `pbm-board` | target |
|---|---|---|---|
| flash (text + data; QEMU without the test trace) | {flash} B | {board_flash} B | ≤ {TARGET_FLASH} |
| static RAM (data + bss) | {static_ram} B | {board_ram} B | |
| RAM = static + peak stack | {ram} B | peak stack logged by the board | ≤ {TARGET_RAM} |

The board image is {board_over} the monitor's flash budget: the HAL's drivers and the start-up
analog check on top of the same monitor (an STM32F446RE has 512 KiB of flash and 128 KiB of RAM).

Regression bounds (`cargo xtask fw-bench --check`, run in CI by `cargo xtask test-all`) are in
`bench/firmware-bounds.env`.

Reproduce: `cargo xtask fw-bench` (or `cargo fw-bench` for the raw figures).
"#,
        extended = extended.unwrap_or_default(),
        board_flash = board_flash,
        board_ram = board_ram,
        board_over = if board_flash > TARGET_FLASH {
            format!("{} B over", board_flash - TARGET_FLASH)
        } else {
            format!("{} B under", TARGET_FLASH - board_flash)
        },
        date = date.trim(),
        qemu = qemu.lines().next().unwrap_or("").trim(),
        cal = n("calibration_measured_instr")?,
        samples = n("samples")?,
        v_pipe = verdict(pipe_max, TARGET_INSTR),
        v_worst = verdict(worst, TARGET_INSTR),
        twin = n("twin_instr_per_sample_mean")?,
        twin_max = n("twin_instr_per_sample_max")?,
        est = n("estimator_instr_per_sample_mean")?,
        est_max = n("estimator_instr_per_sample_max")?,
        feat = n("features_instr_per_sample_mean")?,
        feat_max = n("features_instr_per_sample_max")?,
        res = n("reservoir_instr_per_substep_mean")?,
        res_max = n("reservoir_instr_per_substep_max")?,
        v_closing = verdict(closing, 250_000),
        v_flash = verdict(flash, TARGET_FLASH),
        v_ram = verdict(ram, TARGET_RAM),
        over = n("pipeline_samples_over_budget")?,
    );
    std::fs::write(REPORT, &report).map_err(|e| format!("cannot write {REPORT}: {e}"))?;
    let figures = format!(
        "# Headline firmware figures written by `cargo xtask fw-bench` (full table: bench/firmware.md).\n\
         date={date}\nemulator={emulator}\ninstr_per_sample_mean={pipe}\ninstr_per_sample_worst_nominal={pipe_max}\n\
         instr_per_sample_worst={worst}\ninstr_budget={TARGET_INSTR}\nclassify_instr={classify}\n\
         closing_sample_instr={closing}\nflash_bytes={flash}\nflash_budget_bytes={TARGET_FLASH}\n\
         static_ram_bytes={static_ram}\npeak_stack_bytes={peak_stack}\nram_bytes={ram}\nram_budget_bytes={TARGET_RAM}\n",
        date = date.trim(),
        emulator = qemu.lines().next().unwrap_or("").trim(),
    );
    std::fs::write(FIGURES, figures).map_err(|e| format!("cannot write {FIGURES}: {e}"))?;
    println!("\n{report}\nfw-bench: wrote {REPORT}");
    Ok(())
}
