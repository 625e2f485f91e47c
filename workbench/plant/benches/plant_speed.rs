//! Speed of the physics plant: wall time of each built-in profile at a 1 kHz output,
//! one core, no effects and with every bench-only effect on, printed per 60 s of bench
//! time. Target (issue 11): a 60 s run in at most 2 s. Run:
//! `cargo bench -p simrod-plant --bench plant_speed` (`-- --quick`: TP07 only;
//! `-- --guard S`: exit 1 if any run takes more than S s per 60 s, CI's generous guard).

use std::time::Instant;

use model_core::{Builtin, CouplingStiffness, Effects, Maps, Params, RateSet, SpeedTarget};
use simrod_plant::{step_for, Plant, PlantEffects, Setup, PLANT_EFFECTS};

fn all_bench_effects() -> PlantEffects {
    let mut fx = PlantEffects::default();
    for e in PLANT_EFFECTS {
        for p in e.params {
            fx.set(e.id, p.name, 0.5 * (p.realistic.0 + p.realistic.1)).expect("declared");
        }
    }
    fx
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    let guard: Option<f64> =
        args.iter().position(|a| a == "--guard").and_then(|i| args.get(i + 1)).and_then(|v| v.parse().ok());
    let mut worst: f64 = 0.0;
    let profiles: &[Builtin] = if quick { &[Builtin::TP07] } else { &Builtin::ALL };
    println!("{:<6} {:>8} {:>12} {:>12} {:>14}", "", "bench s", "wall s", "wall/60 s", "effects");
    for &b in profiles {
        for (label, bench) in [("none", PlantEffects::default()), ("all bench", all_bench_effects())] {
            let setup = Setup {
                params: Params::thesis(RateSet::Identified, CouplingStiffness::Identified),
                maps: Maps::builtin(),
                speed_target: SpeedTarget::Map,
                sets: b.sets(),
                throttle_scale: 1.0,
                load_scale: 1.0,
                supply_v: 24.0,
                library: Effects::NONE,
                bench,
            };
            let plant =
                Plant::new(&setup, step_for(1000, simrod_plant::plant::BENCH_STEP_NS)).expect("valid setup");
            let bench_s = plant.duration_us() as f64 * 1e-6;
            let start = Instant::now();
            let out = plant.run(1000).expect("finite run");
            let wall = start.elapsed().as_secs_f64();
            assert!(!out.is_empty());
            let per_60 = wall * 60.0 / bench_s;
            worst = worst.max(per_60);
            println!("{:<6} {bench_s:>8.1} {wall:>12.3} {per_60:>12.3} {label:>14}", b.name());
        }
    }
    if let Some(g) = guard {
        if worst > g {
            eprintln!("plant speed guard: {worst:.2} s per 60 s of bench time, above {g} s");
            std::process::exit(1);
        }
        println!("plant speed guard: worst {worst:.2} s per 60 s, within {g} s");
    }
}
