//! Shape of the response in one effect parameter: weighted RMS distance between the
//! noise-free truth and the twin at nearby values. `objective EFFECT PARAM TRUTH V1 V2 ...`
use workbench::diagnose::{proof::*, Twin};
fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let (e, p, t) = (a[0].clone(), a[1].clone(), a[2].parse::<f32>().unwrap());
    let mut truth = model_core::Effects::NONE;
    truth.set(&e, &p, t).unwrap();
    let run = bench_run(&truth, (model_core::Builtin::TP07, 1.0, 1.0), 3);
    let clean = run.twin.run(&truth).unwrap();
    let sig = [3.0f64, 1.0, 1.0, 3.0, 3.0, 1.5, 0.9, 0.9, 0.9, 1.8, 0.05, 0.3, 0.02];
    for v in a[3..].iter().map(|s| s.parse::<f32>().unwrap()) {
        let mut fx = model_core::Effects::NONE;
        fx.set(&e, &p, v).unwrap();
        let y = run.twin.run(&fx).unwrap();
        let tot: f64 = y
            .iter()
            .zip(&clean)
            .zip(sig)
            .map(|((a, b), s)| a.iter().zip(b).map(|(x, y)| (f64::from(x - y) / s).powi(2)).sum::<f64>())
            .sum();
        println!("{v:8.4}: weighted SSE {tot:12.2}");
    }
}
