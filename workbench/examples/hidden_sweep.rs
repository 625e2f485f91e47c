//! Success rate of the blind diagnosis per library effect over several seeds.
//! `cargo run --release -p workbench --example hidden_sweep -- 5` (seeds 1..=5).
use std::time::Instant;
use workbench::diagnose::proof::*;

fn main() {
    let seeds: u64 = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(3);
    let only = std::env::args().nth(2);
    println!(
        "{:24} {:>5} {:>5} {:>6} {:>6}   details of failures",
        "effect", "ok", "found", "params", "fell"
    );
    let (mut inside95, mut total) = (0usize, 0usize);
    for case in library_cases() {
        let id = case.params[0].0;
        if only.as_deref().is_some_and(|o| o != id) {
            continue;
        }
        let (mut ok, mut found, mut par, mut fell) = (0, 0, 0, 0);
        let mut fails = Vec::new();
        let t0 = Instant::now();
        for seed in 1..=seeds {
            let mut truth = model_core::Effects::NONE;
            for (k, (e, p, lo, hi)) in case.params.iter().enumerate() {
                truth.set(e, p, draw(seed, k as u64, *lo, *hi)).unwrap();
            }
            let run = bench_run(&truth, case.profile, seed);
            let d = diagnose_run(&run, &model_core::Effects::NONE).unwrap();
            let j = judge(&run, &model_core::Effects::NONE, &truth, id, &d);
            ok += usize::from(j.ok());
            found += usize::from(j.found);
            par += usize::from(j.params_within);
            for (z, _) in &j.z {
                total += 1;
                inside95 += usize::from(z.abs() <= 1.96);
            }
            fell += usize::from(j.error_fell);
            if !j.ok() {
                fails.push(format!("seed {seed}: {}", j.detail));
            }
        }
        println!(
            "{id:24} {ok:>3}/{seeds} {found:>3}/{seeds} {par:>4}/{seeds} {fell:>4}/{seeds}   ({:.1} s)",
            t0.elapsed().as_secs_f64()
        );
        for f in fails {
            println!("      {f}");
        }
    }
    println!(
        "coverage of the reported 95 % intervals: {inside95}/{total} = {:.1} %",
        100.0 * inside95 as f64 / total.max(1) as f64
    );
}
