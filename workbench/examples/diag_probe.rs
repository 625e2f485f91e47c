//! Exploratory: hide one effect in a noisy TP07 run and diagnose it blind.
//! `cargo run --release -p workbench --example diag_probe -- differential_friction coulomb_nm 4`
use model_core::{Builtin, Config, Effects, Profile};
use std::time::Instant;
use workbench::diagnose::{self, twin::*, Options};

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let mut truth = Effects::NONE;
    let mut i = 1;
    while i + 2 < a.len() + 1 && i + 2 <= a.len() - 1 + 1 && a.len() > i + 2 {
        truth.set(&a[i], &a[i + 1], a[i + 2].parse().unwrap()).unwrap();
        i += 3;
    }
    let profile = std::env::var("PROFILE").unwrap_or("TP07".into());
    let b = Builtin::from_name(&profile).unwrap();
    let cfg = Config::default();
    let inputs = profile_inputs(&Profile::builtin(b, 1.0, 1.0).unwrap(), 1000, 24.0);
    let twin = RecordedTwin { config: cfg, inputs, channels: fitted_channels() };
    let clean = diagnose::Twin::run(&twin, &truth).unwrap();
    // Gaussian noise per channel (sigma roughly as the virtual bench's defaults).
    let sig = [2.0, 0.5, 0.5, 1.0, 1.0, 1.0, 0.25, 0.25, 0.25, 1.0, 0.02, 1.0, 0.02];
    let mut s: u64 = 12345;
    let mut u = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let meas: Vec<Vec<f64>> = clean
        .iter()
        .zip(sig)
        .map(|(c, sg)| {
            c.iter()
                .map(|v| {
                    let g = (-2.0 * u().max(1e-300).ln()).sqrt() * (2.0 * std::f64::consts::PI * u()).cos();
                    f64::from(*v) + sg * g
                })
                .collect()
        })
        .collect();
    let t0 = Instant::now();
    let probe = BuiltinProbe::standard(cfg, fitted_channels());
    let d = diagnose::diagnose(&twin, &meas, &Options::default(), Some(&probe)).unwrap();
    println!("{:.2} s  ratio {:.2}\n{}", t0.elapsed().as_secs_f64(), d.excess_ratio, d.verdict);
    for c in d.ranking.iter().take(6) {
        let ps: Vec<String> =
            c.params.iter().map(|p| format!("{}={:.4}±{:.4}", p.name, p.value, 1.96 * p.std)).collect();
        println!(
            "  {:24} pred {:6.3} conf {:?} sig {} {}",
            c.effect,
            c.predicted_reduction,
            c.confirmed_reduction.map(|v| (v * 1000.0).round() / 1000.0),
            c.significant,
            ps.join(" ")
        );
    }
    println!("selected {:?}\nconfounded {:?}", d.selected, d.confounded);
}
