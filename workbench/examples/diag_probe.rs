//! Exploratory: hide effects in a virtual-bench run (realistic measurement chain) and
//! diagnose blind. `PROFILE=TP07 SEED=1 cargo run --release -p workbench --example diag_probe -- effect param value ...`
use model_core::{Builtin, Config, Effects, Profile, Simulation};
use std::time::Instant;
use workbench::diagnose::{self, twin::*, Options};
use workbench::twin::{InputSource, MeasuredTwin, ModelOptions, SensorModel};
use workbench::vbench::chain::{measure, ChainOptions, Recorded};
use workbench::vbench::noise::NoiseModel;

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let mut truth = Effects::NONE;
    for t in a.chunks(3) {
        truth.set(&t[0], &t[1], t[2].parse().unwrap()).unwrap();
    }
    let env = |k: &str, d: &str| std::env::var(k).unwrap_or(d.into());
    let b = Builtin::from_name(&env("PROFILE", "TP07")).unwrap();
    let (ts, ls): (f32, f32) = (env("TS", "1").parse().unwrap(), env("LS", "1").parse().unwrap());
    let seed: u64 = env("SEED", "1").parse().unwrap();
    let cfg = Config::default();
    let profile = Profile::builtin(b, ts, ls).unwrap();
    let rec = Recorded::run(Simulation::new(&Config { effects: truth, ..cfg }, profile, 24.0).unwrap());
    let noise = if env("NOISE", "default") == "none" { None } else { Some(NoiseModel::default()) };
    let m = measure(&rec, &ChainOptions { noise, seed, miscount: false }, std::path::Path::new("x.csv"));
    let channels = fitted_channels();
    let meas: Vec<Vec<f64>> = channels.iter().map(|c| m.signal(c.name()).unwrap().values.clone()).collect();
    let win: f64 = env("WIN", "0.1").parse().unwrap();
    let model = ModelOptions { sensors: SensorModel::counting(win), ..ModelOptions::default() };
    let twin =
        RecordedTwin::new(MeasuredTwin::new(&m, &model, &InputSource::Recorded).unwrap(), channels.clone());
    let t0 = Instant::now();
    let probe = BuiltinProbe::standard(model, channels);
    let d = diagnose::diagnose(&twin, &meas, &Options::default(), Some(&probe)).unwrap();
    println!("{:.2} s  ratio {:.2}\n{}", t0.elapsed().as_secs_f64(), d.excess_ratio, d.verdict);
    for c in d.ranking.iter().take(4) {
        let ps: Vec<String> =
            c.params.iter().map(|p| format!("{}={:.4}±{:.4}", p.name, p.value, 1.96 * p.std)).collect();
        println!(
            "  {:24} pred {:5.3} conf {:?} sig {} {}",
            c.effect,
            c.predicted_reduction,
            c.confirmed_reduction.map(|v| (v * 1000.0).round() / 1000.0),
            c.significant,
            ps.join(" ")
        );
    }
    if std::env::var("NOISEPRINT").is_ok() {
        println!("noise {:?}", d.noise);
    }
}
