//! The XiL loop's delay margin for the built-in vehicle on every built-in cycle, at
//! several loop sample times, and what instability looks like.
//!
//! ```sh
//! cargo run --release -p simrod-xdt --example xil_delay_margin
//! ```
//!
//! For each cycle and sample time: the bisection's margin (largest stable loop delay)
//! and the verdict one step above it; a coarse sweep of the delay showing the single
//! crossing the bisection assumes; and, for ECE-15 at 1 ms, the flange torques'
//! oscillation envelope window by window at half, at, just above and at twice the
//! margin (criterion in `simrod_xdt::margin`).

use std::time::Instant;

use model_core::{Config, Maps};
use simrod_xdt::margin::{delay_margin, judge, Criterion, Outcome, Verdict};
use simrod_xdt::{Cycle, LoopParams, Timing, Vehicle, XilLoop};

fn outcome(v: &Verdict) -> String {
    match v.outcome {
        Outcome::Stable => format!("stable (envelope <= {:.1} N m)", v.max_envelope_nm),
        Outcome::Growing { at_s, growth } => format!("growing at {at_s:.1} s ({growth:.0}x)"),
        Outcome::Sustained { at_s, envelope_nm } => {
            format!("sustained at {at_s:.1} s ({envelope_nm:.1} N m)")
        }
        Outcome::OverRating { at_s, torque_nm } => {
            format!("over 200 N m at {at_s:.1} s ({torque_nm:.0} N m)")
        }
        Outcome::NonFinite { at_s } => format!("diverged at {at_s:.1} s"),
    }
}

fn main() {
    let cfg = Config::default();
    let c = Criterion::default();
    let tuning = LoopParams::default().tuning;
    let veh = Vehicle::default();
    println!(
        "Delay margin of the XiL loop (twin at 1 ms, built-in DXP {} kg, torque filter {} Hz)",
        veh.mass_kg, tuning.torque_filter_hz
    );
    println!("| cycle | loop dt [ms] | margin [ms] | one step above | runs | wall [s] |");
    println!("|---|---|---|---|---|---|");
    let mut ece_margin = 0;
    for cycle in Cycle::ALL {
        for period in [1u32, 2, 5] {
            let t0 = Instant::now();
            let m = delay_margin(&cfg, Maps::builtin(), &veh, &tuning, cycle.route(), period, 24.0, c)
                .expect("the built-in loop builds");
            let margin = m.stable_steps.map_or("none".into(), |d| d.to_string());
            let above = m.unstable.map_or("-".into(), |(d, v)| format!("{d} ms: {}", outcome(&v)));
            println!(
                "| {} | {period} | {margin} | {above} | {} | {:.1} |",
                cycle.name(),
                m.runs,
                t0.elapsed().as_secs_f64()
            );
            if cycle == Cycle::Ece15 && period == 1 {
                ece_margin = m.stable_steps.unwrap_or(0);
            }
        }
    }

    println!("\nSweep, loop dt 1 ms (one crossing):");
    for cycle in Cycle::ALL {
        let row: Vec<String> = [0u32, 10, 20, 25, 30, 35, 40, 60, 100, 250]
            .iter()
            .map(|&d| {
                let v = judge(XilLoop::builtin(&cfg, cycle, Timing::new(1, d).unwrap(), 24.0).unwrap(), c);
                format!("{d}:{}", if v.is_stable() { "ok" } else { "UNSTABLE" })
            })
            .collect();
        println!("  {:9} {}", cycle.name(), row.join(" "));
    }

    println!("\nWhat instability looks like (ECE-15, loop dt 1 ms): flange-torque oscillation envelope per 0.5 s window [N m], the last {} windows of each run", simrod_xdt::margin::HISTORY);
    for d in [ece_margin / 2, ece_margin, ece_margin + 1, 2 * ece_margin] {
        let lp = XilLoop::builtin(&cfg, Cycle::Ece15, Timing::new(1, d).unwrap(), 24.0).unwrap();
        let v = judge(lp, c);
        let env: Vec<String> = v.envelopes().iter().map(|e| format!("{e:.2}")).collect();
        println!(
            "  delay {d:>3} ms: {} | peak flange {:.1} N m | from {:.1} s: {}",
            outcome(&v),
            v.peak_nm,
            v.history_start_s,
            env.join(" ")
        );
    }
}
