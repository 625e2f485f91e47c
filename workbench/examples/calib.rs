//! Calibration of the reported uncertainty: z = (fit - truth) / std over seeds, for one
//! effect, with bench noise or plain white noise (WHITE=1).
use workbench::diagnose::{proof::*, Twin};
fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let (e, p, v, prof) = (a[0].clone(), a[1].clone(), a[2].parse::<f32>().unwrap(), a[3].clone());
    let seeds: u64 = a.get(4).map_or(8, |s| s.parse().unwrap());
    let profile =
        (model_core::Builtin::from_name(&prof).unwrap(), 1.0, if prof == "TP07" { 1.0 } else { 0.0 });
    let white = std::env::var("WHITE").is_ok();
    let mut zs = Vec::new();
    for seed in 1..=seeds {
        let mut truth = model_core::Effects::NONE;
        truth.set(&e, &p, v).unwrap();
        let mut run = bench_run(&truth, profile, seed);
        if white {
            // Replace the bench's chain by white Gaussian noise of the same base levels.
            run.twin.twin.model.sensors = workbench::twin::SensorModel::NONE;
            let clean = run.twin.run(&truth).unwrap();
            let sig = [3.0, 0.3, 0.3, 3.0, 3.0, 1.5, 0.5, 0.5, 0.5, 1.0, 0.05, 0.1, 0.02];
            let mut s: u64 = seed * 7919;
            let mut u = || {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64
            };
            for ((m, c), sg) in run.meas.iter_mut().zip(&clean).zip(sig) {
                for (x, y) in m.iter_mut().zip(c) {
                    let g = (-2.0 * u().max(1e-300).ln()).sqrt() * (2.0 * std::f64::consts::PI * u()).cos();
                    *x = f64::from(*y) + sg * g;
                }
            }
            run.twin.twin.model.sensors = workbench::twin::SensorModel::NONE;
        }
        let d = diagnose_run(&run, &model_core::Effects::NONE).unwrap();
        let c = d.ranking.iter().find(|c| c.effect == e).unwrap();
        let fp = c.params.iter().find(|f| f.name == p).unwrap();
        let z = (fp.value - f64::from(v)) / fp.std;
        println!("seed {seed}: {:.5} ± {:.5} (1σ)  z = {z:+.2}", fp.value, fp.std);
        zs.push(z);
    }
    let rms = (zs.iter().map(|z| z * z).sum::<f64>() / zs.len() as f64).sqrt();
    println!("rms z = {rms:.2} (1 for calibrated)");
}
