//! The 295 runs of `twin::tests::extended_path_equals_the_reference_bit_for_bit` (same generator,
//! same parameters, same valve switching), each run by the fixed-point twin and the `f64`
//! reference (0.1 ms step): one line per run, `case NMSE_% max_abs_deviation_bar mechanisms`
//! (NMSE of the twin's reading against the reference's, SPEC §6). A change of the extended twin's
//! arithmetic (a new digest in that test) is checked against the reference with this, before
//! and after: `cargo run --release -p pbm-lab --example ext_vs_reference > out.txt`.
//!
//! `PBM_ONLY=heat_transfer,regulator_droop` runs only the runs with one of these mechanisms;
//! `PBM_DUMP=CASE` writes that run sample by sample to `fwmech-dump-CASE.txt` in the temporary
//! directory: `i valve twin_bar_g reference_bar_g twin_theta reference_theta` (θ = T/T_wall; the
//! twin's from its pressure, volume and gas content).
use pbm::twin::DigestCases;
use pbm::Twin;
use pbm_lab::reference::ReferenceTwin;
use rayon::prelude::*;

fn main() {
    let mut cases = DigestCases::default();
    let mut runs = Vec::new();
    while let Some((case, p)) = cases.next_params() {
        let Ok(twin) = Twin::new(&p) else { continue };
        if !twin.coeffs().ext_active() {
            continue;
        }
        let samples = DigestCases::samples(&p);
        let mut open = true;
        let mut valve = Vec::with_capacity(samples);
        for i in 0..samples {
            if i > 0 && cases.unit() < 0.002 {
                open = !open;
            }
            valve.push(open);
        }
        runs.push((case, p, valve));
    }
    assert_eq!(runs.len(), 295);
    // PBM_ONLY=heat_transfer,regulator_droop: only the runs with one of these mechanisms.
    let only: Vec<String> =
        std::env::var("PBM_ONLY").map(|v| v.split(',').map(str::to_owned).collect()).unwrap_or_default();
    let out: Vec<String> = runs
        .par_iter()
        .filter(|(_, p, _)| only.is_empty() || p.ext.active().any(|(m, _)| only.iter().any(|o| o == m.name())))
        .map(|(case, p, valve)| {
            let mut twin = Twin::new(p).expect("valid");
            let mut reference = ReferenceTwin::new(p).expect("valid").with_step(1e-4);
            let (mut a, mut b) = (Vec::new(), Vec::new());
            let mut th = Vec::new();
            for &open in valve {
                a.push(twin.update(open).pressure.to_bar_g().0);
                reference.advance(0.01, open);
                b.push(reference.sensor_bar_g());
                th.push((
                    (twin.state().p.to_bar_g().0 + 1.0)
                        * (1.0 + p.piston_area_m2 / p.dead_volume_m3 * twin.state().x.to_m().0)
                        / (twin.ext_state().gas.0 as f64 / (1u64 << 40) as f64 / pbm::params::KAPPA),
                    reference.ext_state.gas_k / pbm::params::TEMPERATURE_K,
                ));
            }
            if std::env::var("PBM_DUMP").ok().and_then(|v| v.parse::<usize>().ok()) == Some(*case) {
                let mut text = String::new();
                for (i, (((x, y), o), t)) in a.iter().zip(&b).zip(valve).zip(&th).enumerate() {
                    text.push_str(&format!("{i} {} {x:.7} {y:.7} {:.7} {:.7}\n", u8::from(*o), t.0, t.1));
                }
                let path = std::env::temp_dir().join(format!("fwmech-dump-{case}.txt"));
                std::fs::write(&path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            }
            let nmse = pbm::metrics::nmse_pct(&b, &a).unwrap_or(f64::NAN);
            let maxdev = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
            let names: Vec<String> = p.ext.active().map(|(m, v)| format!("{m}={v:.4}")).collect();
            format!("{case} {nmse:.6} {maxdev:.6} {}", names.join(","))
        })
        .collect();
    for l in out {
        println!("{l}");
    }
}
