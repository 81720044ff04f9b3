//! `host-sim generate`: determinism (seed, thread count, class subset), the SPEC §4/§5
//! distributions of the drawn parameters, the held-out locomotive split, and argument errors.

use pbm::mechanism::{Extensions, Mechanism};
use pbm::FaultClass;
use pbm_io::dataset::{read_manifest, MANIFEST, TRUTH};
use pbm_io::trace::{read_trace, Samples};
use pbm_lab::generate::{generate, parse_classes, GenerateOptions, SplitMode};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

fn args(out: &Path) -> GenerateOptions {
    let mut a = GenerateOptions::new(out.to_owned());
    a.per_class = 2;
    a.test_per_class = 1;
    a.seed = 11;
    a
}

/// Every file under `dir`, relative path → bytes.
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).unwrap().display().to_string();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

#[test]
fn same_seed_same_bytes_for_any_thread_count() {
    let tmp = tempfile::tempdir().unwrap();
    let mut runs = Vec::new();
    for (name, threads) in [("a", 1), ("b", 2), ("c", 3)] {
        let mut a = args(&tmp.path().join(name));
        a.threads = threads;
        let s = generate(&a, false).unwrap();
        assert_eq!(s.traces, 5 * 3);
        runs.push(snapshot(&a.out));
    }
    assert_eq!(runs[0].len(), 15 + 2, "15 traces + manifest + truth");
    assert!(runs[0] == runs[1], "1 vs 2 threads differ");
    assert!(runs[0] == runs[2], "1 vs 3 threads differ");

    let mut other = args(&tmp.path().join("d"));
    other.seed = 12;
    generate(&other, false).unwrap();
    let d = snapshot(&other.out);
    let key = "traces/train/normal_0000.csv";
    assert_ne!(d[key], runs[0][key], "another seed must give other noise");
}

#[test]
fn a_trace_does_not_depend_on_the_other_classes_or_counts() {
    let tmp = tempfile::tempdir().unwrap();
    let full = args(&tmp.path().join("full"));
    generate(&full, false).unwrap();
    let mut one = args(&tmp.path().join("one"));
    one.classes = vec![FaultClass::AirLeak];
    one.per_class = 1;
    one.test_per_class = 1;
    generate(&one, false).unwrap();
    for f in ["traces/train/air_leak_0000.csv", "traces/test/air_leak_0000.csv"] {
        assert_eq!(std::fs::read(full.out.join(f)).unwrap(), std::fs::read(one.out.join(f)).unwrap(), "{f}");
    }
}

/// `truth.csv` as (header name → column index, rows).
fn read_truth(dir: &Path) -> (BTreeMap<String, usize>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(dir.join(TRUTH)).unwrap();
    let mut lines = text.lines();
    let cols = lines.next().unwrap().split(',').enumerate().map(|(i, n)| (n.to_owned(), i)).collect();
    (cols, lines.map(|l| l.split(',').map(str::to_owned).collect()).collect())
}

#[test]
fn parameters_follow_the_spec_distributions() {
    let tmp = tempfile::tempdir().unwrap();
    let mut a = args(&tmp.path().join("set"));
    a.per_class = 12;
    a.test_per_class = 4;
    a.classes = parse_classes(
        &["normal", "air_leak", "orifice_block", "leak_and_block", "low_supply", "orifice_missing"].map(str::to_owned),
    )
    .unwrap();
    generate(&a, false).unwrap();

    let manifest = read_manifest(&a.out).unwrap();
    assert_eq!(manifest.len(), 6 * 16);
    let (cols, rows) = read_truth(&a.out);
    assert_eq!(rows.len(), manifest.len());
    let get = |r: &Vec<String>, name: &str| -> f64 { r[cols[name]].parse().unwrap() };

    // Held-out split: test traces only from loco-05/06, training only from loco-01..04, and
    // every locomotive carries the same number of traces of each class.
    let mut per_loco_class: BTreeMap<(String, String), usize> = BTreeMap::new();
    for m in &manifest {
        let held_out = m.locomotive == "loco-05" || m.locomotive == "loco-06";
        assert_eq!(m.split == "test", held_out, "{m:?}");
        *per_loco_class.entry((m.locomotive.clone(), m.label.clone())).or_default() += 1;
    }
    for ((loco, _), n) in &per_loco_class {
        assert_eq!(*n, if loco == "loco-05" || loco == "loco-06" { 2 } else { 3 });
    }

    // Per-locomotive spread: drawn once per locomotive, within ±5 % / 7.7 ± 0.03 bar.
    let nominal = pbm::TwinParams::nominal();
    let mut loco_params: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (m, r) in manifest.iter().zip(&rows) {
        assert_eq!((&r[0], &r[1], &r[2], &r[3]), (&m.file, &m.label, &m.locomotive, &m.split));
        let spread = vec![
            r[cols["v0_l"]].clone(),
            r[cols["f0_n"]].clone(),
            r[cols["k_n_per_m"]].clone(),
            r[cols["cf"]].clone(),
            r[cols["fc_n"]].clone(),
            r[cols["fs_n"]].clone(),
            r[cols["regulator_bar_g"]].clone(),
        ];
        let prev = loco_params.entry(m.locomotive.clone()).or_insert_with(|| spread.clone());
        assert_eq!(*prev, spread, "locomotive parameters must not vary between traces");
        for (name, nom) in [
            ("v0_l", nominal.dead_volume_m3 * 1e3),
            ("f0_n", nominal.preload_n),
            ("k_n_per_m", nominal.spring_rate_n_per_m),
            ("cf", nominal.discharge_coeff),
            ("fc_n", nominal.coulomb_n),
            ("fs_n", nominal.static_n),
        ] {
            let rel = get(r, name) / nom;
            assert!((0.95 - 1e-6..=1.05 + 1e-6).contains(&rel), "{name} ratio {rel}");
        }
        let reg = get(r, "regulator_bar_g");
        assert!((7.67 - 1e-6..=7.73 + 1e-6).contains(&reg), "regulator {reg}");

        // Faults: exactly the SPEC §4 ranges; everything else is the locomotive's.
        let (supply, orifice, leak) = (get(r, "supply_bar_g"), get(r, "orifice_mm"), get(r, "leak_mm"));
        let within = |v: f64, lo: f64, hi: f64| (lo - 1e-6..=hi + 1e-6).contains(&v);
        let ok = match m.label.as_str() {
            "normal" => orifice == 1.25 && leak == 0.0 && supply == reg,
            "air_leak" => orifice == 1.25 && within(leak, 0.5, 1.2) && supply == reg,
            "orifice_block" => within(orifice, 0.35, 1.0) && leak == 0.0 && supply == reg,
            "leak_and_block" => within(orifice, 0.35, 1.0) && within(leak, 0.5, 1.2) && supply == reg,
            "low_supply" => orifice == 1.25 && leak == 0.0 && within(supply, 3.5, 7.2),
            "orifice_missing" => within(orifice, 2.5, 4.0) && leak == 0.0 && supply == reg,
            other => panic!("unexpected label {other}"),
        };
        assert!(ok, "{}: supply {supply} orifice {orifice} leak {leak}", m.file);
    }
    assert_eq!(loco_params.len(), 6);
    let distinct: BTreeSet<_> = loco_params.values().collect();
    assert_eq!(distinct.len(), 6, "each locomotive draws its own spread");

    // Traces: 6000 ADC samples at t = 0.00 … 59.99 with the metadata of the manifest.
    let m = &manifest[0];
    let t = read_trace(&a.out.join(&m.file)).unwrap();
    assert_eq!(t.t_s.len(), 6000);
    assert_eq!(t.t_s[0], 0.0);
    assert!((t.t_s[5999] - 59.99).abs() < 1e-9);
    assert_eq!(t.meta("label"), Some(m.label.as_str()));
    assert_eq!(t.meta("locomotive"), Some(m.locomotive.as_str()));
    assert!(matches!(t.samples, Samples::Adc(_)));
}

#[test]
fn shared_split_uses_every_locomotive_in_both_splits() {
    let tmp = tempfile::tempdir().unwrap();
    let mut a = args(&tmp.path().join("set"));
    a.split = SplitMode::Shared;
    a.classes = vec![FaultClass::Normal];
    a.per_class = 6;
    a.test_per_class = 6;
    generate(&a, false).unwrap();
    let manifest = read_manifest(&a.out).unwrap();
    for split in ["train", "test"] {
        let locos: BTreeSet<_> = manifest.iter().filter(|m| m.split == split).map(|m| &m.locomotive).collect();
        assert_eq!(locos.len(), 6, "{split}");
    }
}

#[test]
fn bad_arguments_are_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let check = |a: &GenerateOptions, needle: &str| {
        let e = generate(a, false).expect_err("must fail").to_string();
        assert!(e.contains(needle), "{e:?} should mention {needle:?}");
    };
    let mut a = args(&tmp.path().join("x"));
    a.effects = Extensions::NONE.with(Mechanism::TransportDelay, 99.0);
    check(&a, "transport_delay");
    let e = parse_classes(&["broken_spring".to_owned()]).expect_err("unknown class").to_string();
    assert!(e.contains("unknown class `broken_spring`"), "{e}");
    let mut a = args(&tmp.path().join("x"));
    a.test_locomotives = 6;
    check(&a, "--test-locomotives");
    let mut a = args(&tmp.path().join("x"));
    a.locomotives = 0;
    check(&a, "--locomotives");

    // An existing non-empty directory is not overwritten without --force.
    let dir = tmp.path().join("full");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join(MANIFEST), "keep me").unwrap();
    let a = args(&dir);
    check(&a, "not empty");
    assert_eq!(std::fs::read_to_string(dir.join(MANIFEST)).unwrap(), "keep me");
    let mut a = args(&dir);
    a.force = true;
    generate(&a, false).unwrap();
    assert!(std::fs::read_to_string(dir.join(MANIFEST)).unwrap().starts_with("file,label,locomotive,split\n"));
}

/// Two sensor faults on one trace: the trace stays readable (one `# sensor_fault:` line with
/// both, as in truth.csv) and every tool can open it.
#[test]
fn two_sensor_faults_make_a_readable_trace() {
    let tmp = tempfile::tempdir().unwrap();
    let mut a = args(&tmp.path().join("two"));
    a.classes = vec![FaultClass::Normal];
    a.per_class = 0;
    a.sensor_faults = ["frozen@3", "noisy@10"].iter().map(|s| pbm_lab::sensor_faults::parse_spec(s).unwrap()).collect();
    generate(&a, false).unwrap();
    let manifest = read_manifest(&a.out).unwrap();
    let t = read_trace(&a.out.join(&manifest[0].file)).expect("readable");
    assert_eq!(t.meta("sensor_fault"), Some("frozen@3.00;noisy=0.1@10.00"));
}
