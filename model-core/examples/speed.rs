//! Host speed of a whole TP07 run (the bench module has the careful numbers).
use model_core::*;
use std::time::Instant;
fn main() {
    for dt in [1000u32, 100] {
        let cfg = Config { dt_us: dt, ..Config::default() };
        let t0 = Instant::now();
        let mut n = 0u64;
        let mut acc = 0.0f32;
        for _ in 0..5 {
            let sim =
                Simulation::new(&cfg, Profile::builtin(Builtin::TP07, 1.0, 1.0).unwrap(), 24.0).unwrap();
            for o in sim {
                acc += o.get(Channel::SuTMotorEnc);
                n += 1;
            }
        }
        let s = t0.elapsed().as_secs_f64();
        println!(
            "dt {dt} us: {n} steps in {s:.3} s = {:.0} ns/step, {:.2} M steps/s ({acc})",
            s * 1e9 / n as f64,
            n as f64 / s / 1e6
        );
    }
}
