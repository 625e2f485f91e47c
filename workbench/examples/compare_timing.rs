//! How long `simrod compare` takes on a 70 s run at 1 kHz (TP11, every channel, bench
//! noise and a hidden effect so every analysis has work to do). Not a test: timings
//! depend on the machine. Run with
//! `cargo run --release -p workbench --example compare_timing`.

use std::path::Path;
use std::time::Instant;

use model_core::{Builtin, Config, Effects, Profile, Simulation};
use workbench::compare::{compare, CompareOptions};
use workbench::report::{html, json, table};
use workbench::vbench::chain::{measure, ChainOptions, Recorded};
use workbench::vbench::noise::NoiseModel;

fn main() {
    let mut effects = Effects::NONE;
    effects.regen_loss = 0.3;
    let cfg = Config { effects, ..Config::default() };
    let Ok(profile) = Profile::builtin(Builtin::TP11, 1.0, 1.0) else {
        eprintln!("TP11 is not a valid profile");
        return;
    };
    let Ok(sim) = Simulation::new(&cfg, profile, 24.0) else {
        eprintln!("the twin refused the configuration");
        return;
    };
    let chain = ChainOptions { noise: Some(NoiseModel::default()), seed: 1, miscount: false };
    let meas = measure(&Recorded::run(sim), &chain, Path::new("TP11-virtual"));
    println!("run: {} samples x {} signals", meas.time_s.len(), meas.signals.len());
    let opts = CompareOptions::default();
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..5 {
        let t = Instant::now();
        match compare(&meas, &opts) {
            Ok(r) => last = Some(r),
            Err(e) => {
                eprintln!("compare failed: {e}");
                return;
            }
        }
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let Some(r) = last else { return };
    println!(
        "compare (twin + analysis, {} channels): min {:.3} s, median {:.3} s (twin {:.3} s, analysis {:.3} s in the last run)",
        r.channels.len(),
        times[0],
        times[times.len() / 2],
        r.timing.0,
        r.timing.1
    );
    let t = Instant::now();
    let text = table::render(&r);
    let js = json::to_json(&r).to_string();
    let page = html::render(&r);
    println!(
        "rendering: table {} B, JSON {} B, HTML {} B in {:.3} s",
        text.len(),
        js.len(),
        page.len(),
        t.elapsed().as_secs_f64()
    );
}
