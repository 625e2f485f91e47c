//! `cargo xtask <task>`: developer tasks of the simrod workspace (alias in
//! `.cargo/config.toml`; built in release only when run, never by `cargo build/test`).
//!
//! `cargo xtask bench-rt [--json FILE] [--quick] [--no-host]` measures, in one go:
//!
//! 1. **host**: ns per `Model::step`, steps per second, real-time factor at 1 ms and
//!    100 µs (`host_tests::hostbench`, also `cargo bench -p host-tests --bench step`);
//! 2. **target cost**: instructions per `simrod_step` (and `simrod_profile_at`) on the
//!    Cortex-M4F over whole TP07, TP11, TP14 runs, exact under QEMU `-icount shift=7`
//!    (`firmware/src/bin/simrod-cost.rs`): min, median, p99, worst;
//! 3. **blocks**: the same runs with model-core's probe hooks (firmware feature
//!    `profile`): instructions per block of the step;
//! 4. **footprint**: flash and static RAM from the ELF sections, the stack high-water
//!    mark of the bench firmware and of the step, the largest symbols;
//! 5. **overrun sweep**: the bench loop at rising rates on a 125 M instructions/s
//!    virtual core; the highest rate without an overrun;
//!
//! then prints the tables, the aims met or missed, and writes everything as JSON.
//!
//! `cargo xtask fmu --out simrod.fmu [...]` packages the twin as an FMI 3.0 FMU
//! (`fmu.rs`).
//!
//! Why an xtask and not a `simrod` subcommand: this drives cargo builds for another
//! target and QEMU, and needs the workspace's sources and build directories; `simrod`
//! is the twin's user tool and must not depend on any of that at run time.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

mod fmu;

use host_tests::hostbench::{self, HostCase};
use host_tests::rt::{self, Footprint, LoopStats, Summary};
use model_core::Builtin;
use serde_json::{json, Value};

const USAGE: &str = "usage: cargo xtask bench-rt [--json FILE] [--quick] [--no-host]

  --json FILE   also write every number as JSON to FILE
  --quick       fewer host repetitions, coarser rate sweep
  --no-host     skip the host timing";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("fmu") => match fmu::run(&args[1..]) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::FAILURE
            }
        },
        Some("bench-rt") => match bench_rt(&args[1..]) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::FAILURE
            }
        },
        // Internal: `n` steps of one host case, for instruction counting under valgrind.
        Some("host-steps") => {
            let n = args.get(1).and_then(|v| v.parse().ok()).unwrap_or(0);
            std::hint::black_box(hostbench::fixed_point_steps(n));
            ExitCode::SUCCESS
        }
        Some("-h" | "--help" | "help") => {
            println!("{USAGE}\n\n{}", fmu::USAGE);
            ExitCode::SUCCESS
        }
        _ => {
            eprintln!("{USAGE}");
            ExitCode::from(2)
        }
    }
}

struct Opts {
    json: Option<PathBuf>,
    quick: bool,
    host: bool,
}

fn parse(args: &[String]) -> Result<Opts, String> {
    let mut o = Opts { json: None, quick: false, host: true };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--json" => o.json = Some(it.next().ok_or("--json needs a file")?.into()),
            "--quick" => o.quick = true,
            "--no-host" => o.host = false,
            other => return Err(format!("unknown argument `{other}`\n{USAGE}")),
        }
    }
    Ok(o)
}

fn summary_json(s: &Summary) -> Value {
    json!({"n": s.n, "min": s.min, "median": s.median, "p99": s.p99, "max": s.max, "mean": s.mean})
}

fn kib(b: u64) -> f64 {
    b as f64 / 1024.0
}

fn stage(name: &str) {
    eprintln!("bench-rt: {name}...");
}

/// Rates of the sweep [tick µs]: 1, 2, 5, 10, 20, 25, 40, 50 kHz.
const LADDER_US: [u32; 8] = [1000, 500, 200, 100, 50, 40, 25, 20];

struct Sweep {
    runs: Vec<(u32, LoopStats)>,
    /// Shortest tick without an overrun.
    no_overrun_tick_us: Option<u32>,
    /// Shortest tick with no overrun, no late start and no missed tick.
    clean_tick_us: Option<u32>,
}

fn no_overrun(s: &LoopStats) -> bool {
    s.get("overruns") == 0 && s.get("missed_ticks") == 0
}

fn clean(s: &LoopStats) -> bool {
    no_overrun(s) && s.get("late") == 0
}

/// Run the bench loop at the ladder's rates until steps overrun, then bisect (integer
/// µs ticks) the boundaries of "no overrun" and of "clean" (no late start either).
fn sweep(dir: &std::path::Path, quick: bool) -> Result<Sweep, String> {
    let elf = dir.join("firmware");
    let mut runs: Vec<(u32, LoopStats)> = Vec::new();
    let mut run = |tick: u32| -> Result<LoopStats, String> {
        if let Some((_, s)) = runs.iter().find(|(t, _)| *t == tick) {
            return Ok(s.clone());
        }
        let t0 = Instant::now();
        let s = rt::run_loop(&elf, &dir.join(format!("sweep-{tick}us")), Builtin::TP07, tick)?;
        eprintln!("  tick {tick:>4} us: {} ({:.1} s)", s, t0.elapsed().as_secs_f64());
        runs.push((tick, s.clone()));
        Ok(s)
    };
    let mut ladder = Vec::new();
    for tick in LADDER_US {
        let s = run(tick)?;
        ladder.push((tick, no_overrun(&s), clean(&s)));
        if !no_overrun(&s) {
            break;
        }
    }
    // Shortest passing tick of the ladder, and the first failing one after it.
    let bounds = |pass: fn(&(u32, bool, bool)) -> bool| {
        let ok = ladder.iter().take_while(|r| pass(r)).last().map(|r| r.0);
        let bad = ladder.iter().find(|r| !pass(r)).map(|r| r.0);
        (ok, bad)
    };
    let mut bisect = |(ok, bad): (Option<u32>, Option<u32>), pass: fn(&LoopStats) -> bool| {
        let (Some(mut ok), Some(mut bad)) = (ok, bad) else { return Ok::<_, String>(ok) };
        while !quick && ok - bad > 1 {
            let mid = (ok + bad) / 2;
            if pass(&run(mid)?) {
                ok = mid;
            } else {
                bad = mid;
            }
        }
        Ok(Some(ok))
    };
    let no_overrun_tick_us = bisect(bounds(|r| r.1), no_overrun)?;
    let clean_tick_us = bisect(bounds(|r| r.2), clean)?;
    runs.sort_by_key(|r| std::cmp::Reverse(r.0));
    Ok(Sweep { runs, no_overrun_tick_us, clean_tick_us })
}

/// x86-64 instructions per `Model::step` at the host benchmark's fixed operating point,
/// counted by valgrind's cachegrind (deterministic, unlike wall time): the difference of
/// two runs of this binary with different step counts. `None` without valgrind.
fn host_insns() -> Option<f64> {
    let exe = std::env::current_exe().ok()?;
    let count = |n: u64| -> Option<f64> {
        let out = std::process::Command::new("valgrind")
            .args(["--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null"])
            .arg(&exe)
            .args(["host-steps", &n.to_string()])
            .output()
            .ok()?;
        let err = String::from_utf8_lossy(&out.stderr);
        let line = err.lines().find(|l| l.contains("I   refs:") || l.contains("I refs:"))?;
        line.rsplit(':').next()?.trim().replace(',', "").parse().ok()
    };
    let (a, b) = (count(20_000)?, count(120_000)?);
    Some((b - a) / 100_000.0)
}

/// The FPU-less Cortex-M3 (issue 15), measured as the M4F: instructions per step of the
/// fixed-point twin and of the f32 twin in soft-float on the same core (the same cost
/// binary, every run's outputs checked against the host's bits), where the fixed-point
/// step goes (block profile), and the fixed-point bench firmware's flash.
fn cortex_m3(out: &mut String, report: &mut serde_json::Map<String, Value>) -> Result<(), String> {
    stage("Cortex-M3: fixed-point and soft-float builds, cost runs");
    writeln!(
        out,
        "\n== Cortex-M3 without an FPU (QEMU mps2-an385, -icount shift={}): instructions per simrod_step",
        rt::COST_SHIFT
    )
    .ok();
    writeln!(
        out,
        "{:<28} {:<8} {:>7} | {:>30} {:>9}",
        "build", "profile", "steps", "min / median / p99 / max", "mean"
    )
    .ok();
    let mut json_rows = Vec::new();
    let mut means = Vec::new();
    for (mcu, variant) in [(rt::M3_FIXED, "bench-rt-m3-fixed"), (rt::M3_SOFT, "bench-rt-m3-soft")] {
        let dir = rt::build_firmware_on(&mcu, variant, None, &[])?;
        let cost = rt::run_cost_on(&mcu, &dir.join("simrod-cost"), &dir.join("cost-run"))?;
        let mut rows: Vec<(String, Vec<&rt::StepCost>)> =
            cost.runs.iter().map(|r| (r.profile.name().to_string(), r.steps.iter().collect())).collect();
        rows.push(("all".into(), cost.runs.iter().flat_map(|r| &r.steps).collect()));
        for (name, steps) in &rows {
            let s = Summary::of(steps.iter().map(|s| s.step)).ok_or("no steps")?;
            writeln!(
                out,
                "{:<28} {name:<8} {:>7} | {:>6} {:>7} {:>7} {:>7} {:>9.0}",
                mcu.name, s.n, s.min, s.median, s.p99, s.max, s.mean
            )
            .ok();
            json_rows.push(json!({"build": mcu.name, "profile": name, "step": summary_json(&s)}));
            if name == "all" {
                means.push(s.mean);
            }
        }
        if mcu.fixed {
            let fp = rt::footprint(&dir.join("firmware"))?;
            writeln!(
                out,
                "fixed-point bench firmware: flash {} B = vector table {} + .text {} + .rodata {} + .data {}; static RAM {} B",
                fp.flash(),
                fp.vector_table,
                fp.text,
                fp.rodata,
                fp.data,
                fp.static_ram()
            )
            .ok();
        }
    }
    let ratio = means.get(1).zip(means.first()).map(|(soft, fixed)| soft / fixed);
    if let Some(r) = ratio {
        writeln!(out, "soft-float / fixed point, mean step: {r:.2} (aim >= 3)").ok();
    }
    stage("Cortex-M3: fixed-point block profile");
    let prof = rt::build_firmware_on(&rt::M3_FIXED, "bench-rt-m3-profile", None, &["profile"])?;
    let hooked = rt::run_cost_on(&rt::M3_FIXED, &prof.join("simrod-cost"), &prof.join("cost-run"))?;
    let blocks = hooked.block_shares();
    writeln!(out, "where the fixed-point step goes (hook overhead removed):").ok();
    let mut sorted = blocks.clone();
    sorted.sort_by(|a, b| b.1.total_cmp(&a.1));
    for (n, v, share) in &sorted {
        writeln!(out, "  {n:<28} {v:>8.0} {:>7.1}%", 100.0 * share).ok();
    }
    report.insert(
        "cortex_m3".into(),
        json!({"machine": "mps2-an385", "runs": json_rows, "soft_over_fixed_mean": ratio,
               "fixed_blocks": sorted.iter().map(|(n, v, s)| json!({"block": n, "insns_per_step": v, "share": s})).collect::<Vec<_>>()}),
    );
    Ok(())
}

fn bench_rt(args: &[String]) -> Result<(), String> {
    let opts = parse(args)?;
    let t_start = Instant::now();
    let mut out = String::new();
    let mut report = serde_json::Map::new();

    // 1. Host.
    let host: Vec<HostCase> = if opts.host {
        stage("host timing");
        hostbench::run(opts.quick)
    } else {
        Vec::new()
    };
    if !host.is_empty() {
        writeln!(out, "== Host (`cargo bench -p host-tests --bench step`)").ok();
        out.push_str(&hostbench::table(&host));
        report.insert(
            "host".into(),
            host.iter()
                .map(|c| {
                    json!({"case": c.name, "dt_us": c.dt_us, "steps": c.steps, "reps": c.reps,
                           "ns_per_step_median": c.ns_median, "steps_per_s_median": c.steps_per_s(),
                           "rt_factor_median": c.rt_factor(), "ns_per_step_undisturbed": c.ns_min,
                           "steps_per_s_undisturbed": c.steps_per_s_min(),
                           "rt_factor_undisturbed": c.rt_factor_min()})
                })
                .collect(),
        );
    }

    let host_insns = if opts.host {
        stage("host instructions per step (valgrind)");
        host_insns()
    } else {
        None
    };
    if let Some(n) = host_insns {
        writeln!(out, "Model::step: {n:.0} x86-64 instructions per step (cachegrind, deterministic)").ok();
        report.insert("host_insns_per_step".into(), json!(n));
    }

    // 2. Target builds.
    stage("building the firmware (plain and with the block profile)");
    let plain = rt::build_firmware("bench-rt", None, &[])?;
    let prof = rt::build_firmware("bench-rt-profile", None, &["profile"])?;

    // 3. Cost per step, plain build.
    stage("cost runs on QEMU (-icount shift=7)");
    let cost = rt::run_cost(&plain.join("simrod-cost"), &plain.join("cost-run"))?;
    let all_steps = || cost.runs.iter().flat_map(|r| &r.steps);
    let step_all = Summary::of(all_steps().map(|s| s.step)).ok_or("no steps")?;
    let step_stack = all_steps().map(|s| s.stack).max().unwrap_or(0);
    writeln!(
        out,
        "\n== Target: instructions per call on the Cortex-M4F (QEMU mps2-an386, -icount shift={}: \
         exact; calibration regions of {} nops counted exactly)",
        rt::COST_SHIFT,
        cost.calibration.iter().map(|c| c.nops.to_string()).collect::<Vec<_>>().join("/")
    )
    .ok();
    writeln!(
        out,
        "{:<8} {:>7} | {:>28} {:>7} | {:>19} | {:>14}",
        "profile", "steps", "simrod_step min/med/p99/max", "mean", "profile_at med/max", "step+profile max"
    )
    .ok();
    let mut prof_json = Vec::new();
    let mut rows: Vec<(String, Vec<&rt::StepCost>)> =
        cost.runs.iter().map(|r| (r.profile.name().to_string(), r.steps.iter().collect())).collect();
    rows.push(("all".into(), all_steps().collect()));
    for (name, steps) in &rows {
        let s = Summary::of(steps.iter().map(|s| s.step)).ok_or("no steps")?;
        let p = Summary::of(steps.iter().map(|s| s.profile_at)).ok_or("no steps")?;
        let sp = Summary::of(steps.iter().map(|s| s.step + s.profile_at)).ok_or("no steps")?;
        writeln!(
            out,
            "{name:<8} {:>7} | {:>6} {:>6} {:>6} {:>6} {:>7.1} | {:>9} {:>9} | {:>14}",
            s.n, s.min, s.median, s.p99, s.max, s.mean, p.median, p.max, sp.max
        )
        .ok();
        let worst_at = steps.iter().position(|x| x.step == s.max).unwrap_or(0);
        prof_json.push(json!({"profile": name, "step": summary_json(&s), "profile_at": summary_json(&p),
                              "step_plus_profile": summary_json(&sp),
                              "worst_step_index": worst_at}));
    }
    writeln!(out, "step stack (simrod_step and callees, painted): {step_stack} B").ok();

    // 4. Blocks.
    stage("block profile run");
    let hooked = rt::run_cost(&prof.join("simrod-cost"), &prof.join("cost-run"))?;
    if hooked.n_blocks == 0 {
        // The build directory is shared with the firmware tests: a concurrent plain
        // build may have replaced the ELFs between our build and our copy.
        return Err("the block-profile build has no blocks: replaced by a concurrent build? run again".into());
    }
    let blocks = hooked.block_shares();
    let profile_mean = Summary::of(all_steps().map(|s| s.profile_at)).map_or(0.0, |s| s.mean);
    let hooked_sum: f64 = blocks.iter().map(|b| b.1).sum();
    let whole = hooked_sum + profile_mean;
    writeln!(
        out,
        "\n== Where a step goes (feature `profile`: model-core probe hooks; hook overhead of {} \
         instructions per interval removed)",
        hooked.mark_overhead
    )
    .ok();
    writeln!(out, "{:<30} {:>10} {:>9}", "block", "instr/step", "share").ok();
    let mut rows: Vec<(String, f64)> = vec![("profile engine (profile_at)".into(), profile_mean)];
    rows.extend(blocks.iter().map(|(n, v, _)| (n.to_string(), *v)));
    let mut sorted = rows.clone();
    sorted.sort_by(|a, b| b.1.total_cmp(&a.1));
    for (n, v) in &sorted {
        writeln!(out, "{n:<30} {v:>10.0} {:>8.1}%", 100.0 * v / whole).ok();
    }
    writeln!(
        out,
        "step blocks sum {hooked_sum:.0} vs the plain build's mean step {:.0} ({:+.1} %: what the hooks \
         perturb); the tables block is every map lookup (grid search + interpolation)",
        step_all.mean,
        100.0 * (hooked_sum / step_all.mean - 1.0)
    )
    .ok();
    report.insert(
        "target".into(),
        json!({
            "method": format!("QEMU mps2-an386 -icount shift={}: {} ns of virtual time per instruction; \
                               25 MHz SysTick read around each call; exact instruction counts", rt::COST_SHIFT, cost.ns_per_insn),
            "calibration": cost.calibration.iter().map(|c| json!({"nops": c.nops, "counted": c.insns, "timer_counts": c.counts})).collect::<Vec<_>>(),
            "profiles": prof_json,
            "step_stack_bytes": step_stack,
            "blocks": sorted.iter().map(|(n, v)| json!({"block": n, "insns_per_step": v, "share": v / whole})).collect::<Vec<_>>(),
            "hook_overhead_insns": hooked.mark_overhead,
            "hooked_blocks_sum": hooked_sum,
            "plain_step_mean": step_all.mean,
        }),
    );

    // 5. Footprint and overrun sweep.
    stage("overrun sweep of the bench loop (-icount shift=3)");
    let fp: Footprint = rt::footprint(&plain.join("firmware"))?;
    let sw = sweep(&plain, opts.quick)?;
    let at_1khz = sw.runs.iter().find(|(t, _)| *t == rt::STEP_US).ok_or("no 1 kHz run")?;
    let stack = u64::from(at_1khz.1.get("stack_bytes"));
    let ram = fp.static_ram() + stack;
    let largest = rt::largest_symbols(&plain.join("firmware"), 8)?;
    writeln!(out, "\n== Footprint of the bench firmware (`firmware` ELF, release)").ok();
    writeln!(
        out,
        "flash {} B ({:.1} KiB) = vector table {} + .text {} + .rodata {} + .data {}   [budget {} KiB]",
        fp.flash(),
        kib(fp.flash()),
        fp.vector_table,
        fp.text,
        fp.rodata,
        fp.data,
        rt::BUDGET_FLASH / 1024
    )
    .ok();
    writeln!(
        out,
        "RAM   {ram} B ({:.1} KiB) = .data+.bss {} + stack high-water {stack} (whole run, init included)   \
         [budget {} KiB, aim {} KiB]",
        kib(ram),
        fp.static_ram(),
        rt::BUDGET_RAM / 1024,
        rt::AIM_RAM / 1024
    )
    .ok();
    writeln!(out, "step stack {step_stack} B; largest in flash:").ok();
    for (n, s) in &largest {
        writeln!(out, "  {s:>6} B  {n}").ok();
    }

    let ipu = rt::LOOP_INSNS_PER_US;
    writeln!(
        out,
        "\n== Overrun sweep: bench loop on TP07 (profile + step + a frame every 10th step), virtual core \
         {ipu} M instructions/s (-icount shift={}: a 168 MHz Cortex-M4F at 1.34 cycles/instruction); \
         the model step stays 1 ms",
        rt::LOOP_SHIFT
    )
    .ok();
    writeln!(
        out,
        "{:>9} {:>7} {:>12} {:>7} {:>9} {:>7} {:>8} {:>15}",
        "rate", "tick", "insns/period", "steps", "overruns", "late", "missed", "worst loop step"
    )
    .ok();
    let mut sweep_json = Vec::new();
    for (tick, s) in &sw.runs {
        let rate_hz = 1e6 / f64::from(*tick);
        // SysTick cycles (25 MHz, 40 ns) -> instructions at 2^shift ns each.
        let worst_insns = (s.get("max_step_cycles") * 40) >> rt::LOOP_SHIFT;
        writeln!(
            out,
            "{:>7.2}kHz {:>5}us {:>12} {:>7} {:>9} {:>7} {:>8} {:>15}",
            rate_hz / 1e3,
            tick,
            tick * ipu,
            s.get("steps"),
            s.get("overruns"),
            s.get("late"),
            s.get("missed_ticks"),
            worst_insns
        )
        .ok();
        sweep_json.push(json!({"tick_us": tick, "rate_hz": rate_hz, "insns_per_period": tick * ipu,
                               "steps": s.get("steps"), "overruns": s.get("overruns"), "late": s.get("late"),
                               "missed_ticks": s.get("missed_ticks"), "worst_loop_step_insns": worst_insns,
                               "mean_loop_step_insns": (s.get("mean_step_cycles") * 40) >> rt::LOOP_SHIFT,
                               "stack_bytes": s.get("stack_bytes")}));
    }
    let rate = |t: Option<u32>| t.map(|t| 1e6 / f64::from(t));
    for (what, tick) in
        [("without overrun", sw.no_overrun_tick_us), ("with no late start either", sw.clean_tick_us)]
    {
        match tick {
            Some(t) => writeln!(
                out,
                "highest rate {what}{}: {:.1} kHz (tick {t} us = {} instructions per period)",
                if opts.quick { " (ladder only)" } else { "" },
                1e3 / f64::from(t),
                t * ipu
            ),
            None => writeln!(out, "no rate {what}"),
        }
        .ok();
    }
    report.insert(
        "footprint".into(),
        json!({"vector_table": fp.vector_table, "text": fp.text, "rodata": fp.rodata, "data": fp.data,
               "bss": fp.bss, "uninit": fp.uninit, "flash": fp.flash(), "static_ram": fp.static_ram(),
               "stack_high_water": stack, "ram": ram, "step_stack": step_stack,
               "largest": largest.iter().map(|(n, s)| json!({"symbol": n, "bytes": s})).collect::<Vec<_>>()}),
    );
    report.insert(
        "sweep".into(),
        json!({"profile": "TP07", "icount_shift": rt::LOOP_SHIFT, "insns_per_us": ipu, "runs": sweep_json,
               "max_rate_hz": rate(sw.no_overrun_tick_us), "max_rate_tick_us": sw.no_overrun_tick_us,
               "max_clean_rate_hz": rate(sw.clean_tick_us), "max_clean_rate_tick_us": sw.clean_tick_us,
               "clean": "no overrun, no missed tick, no step starting later than 10 % of the period"}),
    );

    // 5b. The FPU-less Cortex-M3.
    if !opts.quick {
        cortex_m3(&mut out, &mut report)?;
    }

    // 6. Budgets and aims.
    writeln!(out, "\n== Budgets (CI guard, tests/firmware_budget.rs) and aims").ok();
    let mut verdicts = Vec::new();
    let mut verdict = |what: &str, ok: bool, detail: String| {
        writeln!(out, "{:<7} {what}: {detail}", if ok { "ok" } else { "MISSED" }).ok();
        verdicts.push(json!({"what": what, "met": ok, "detail": detail}));
    };
    let w = step_all.max;
    verdict(
        "budget: worst step <= 5000 instructions",
        w <= rt::BUDGET_STEP_INSNS,
        format!("{w} ({:.0} % of it)", 100.0 * f64::from(w) / f64::from(rt::BUDGET_STEP_INSNS)),
    );
    verdict("budget: flash <= 64 KiB", fp.flash() <= rt::BUDGET_FLASH, format!("{:.1} KiB", kib(fp.flash())));
    verdict("budget: RAM <= 16 KiB", ram <= rt::BUDGET_RAM, format!("{:.1} KiB", kib(ram)));
    let margin = |v: f64, aim: f64| 100.0 * (v / aim - 1.0);
    verdict(
        "aim: worst step <= 3000 instructions",
        w <= rt::AIM_STEP_INSNS,
        format!("{w} ({:+.1} % vs the aim)", margin(f64::from(w), f64::from(rt::AIM_STEP_INSNS))),
    );
    verdict(
        "aim: RAM <= 8 KiB including stack",
        ram <= rt::AIM_RAM,
        format!(
            "{ram} B ({:+.1} % vs the aim; peak is at init: Model::new)",
            margin(ram as f64, rt::AIM_RAM as f64)
        ),
    );
    if let Some(c) = host.first() {
        // Undisturbed: other processes only ever add time, so it is the closest to
        // "one core"; the median shows how loaded the machine was.
        let best = c.steps_per_s_min();
        verdict(
            "aim: host >= 5 M steps/s on one core (Model::step, undisturbed)",
            best >= rt::AIM_HOST_STEPS_PER_S,
            format!(
                "{:.2} M steps/s = {:.0} ns/step ({:+.1} % vs the aim); median {:.0} ns under this machine's load",
                best / 1e6,
                c.ns_min,
                margin(best, rt::AIM_HOST_STEPS_PER_S),
                c.ns_median
            ),
        );
    }

    report.insert("verdicts".into(), Value::Array(verdicts));
    report.insert("seconds".into(), json!(t_start.elapsed().as_secs_f64()));

    print!("{out}");
    if let Some(path) = &opts.json {
        let text = serde_json::to_string_pretty(&Value::Object(report)).map_err(|e| e.to_string())?;
        std::fs::write(path, text + "\n").map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("bench-rt: wrote {}", path.display());
    }
    Ok(())
}
