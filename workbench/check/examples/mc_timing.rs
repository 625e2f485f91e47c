//! How long a Monte Carlo check takes: TP07 at the check's default 100 µs, every
//! built-in limit, 200 samples of a realistic uncertainty (workbench/examples/
//! uncertainty.toml), on 2 threads; and one run alone, with and without the limits.
//!
//! `cargo run --release -p simrod-check --example mc_timing [-- --samples N --threads T]`

use std::time::Instant;

use model_core::{Builtin, Config, CouplingStiffness, Profile, RateSet};
use simrod_check::limits::Limits;
use simrod_check::monitor::evaluate;
use simrod_check::run::{ProfileRun, TestRun};
use simrod_check::uncertainty::{Choice, Uncertainty};
use simrod_check::{check, CheckOptions};
use simrod_io::uncertainty_file::parse_uncertainty;

const UNCERTAINTY: &str = include_str!("../../examples/uncertainty.toml");

fn arg(name: &str, default: u64) -> u64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() -> Result<(), String> {
    let samples = arg("--samples", 200);
    let threads = arg("--threads", 2) as usize;
    let config = Config { dt_us: 100, ..Config::default() };
    let profile = Profile::builtin(Builtin::TP07, 1.0, 1.0).map_err(|e| format!("{e:?}"))?;
    let test = ProfileRun::new("TP07 x1/x1, 100 µs".into(), &profile, 24.0, config, None);
    let limits = Limits::builtin().map_err(|e| e.to_string())?;

    let t = Instant::now();
    evaluate(&test, &[], test.config(), test.scales())?;
    let bare = t.elapsed().as_secs_f64();
    let t = Instant::now();
    evaluate(&test, &limits.limits, test.config(), test.scales())?;
    let with = t.elapsed().as_secs_f64();
    println!(
        "one TP07 run, {} steps of 100 µs: twin alone {bare:.3} s, with {} limits {with:.3} s",
        test.steps(),
        limits.limits.len()
    );

    let raw =
        parse_uncertainty(UNCERTAINTY, "workbench/examples/uncertainty.toml").map_err(|e| e.to_string())?;
    let choice = Choice { rates: RateSet::Identified, coupling: CouplingStiffness::Identified };
    let u = Uncertainty::resolve(raw, "workbench/examples/uncertainty.toml", test.config(), None, choice)?;
    let o = CheckOptions {
        limits: &limits,
        uncertainty: Some(&u),
        samples,
        seed: 1,
        confidence: 0.95,
        threads,
        progress: false,
        set_points: false,
        delay: None,
    };
    let t = Instant::now();
    let r = check(&test, &o).map_err(|e| format!("{e:?}"))?;
    let total = t.elapsed().as_secs_f64();
    println!(
        "Monte Carlo, {samples} samples on {threads} thread(s): {:.2} s ({:.1} ms a sample); whole check {total:.2} s",
        r.timing.monte_carlo_s,
        1e3 * r.timing.monte_carlo_s / samples.max(1) as f64
    );
    Ok(())
}
