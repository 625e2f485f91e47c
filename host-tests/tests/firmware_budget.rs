//! CI guard of the firmware's real-time budget (generous limits, not a timing test):
//!
//! - worst instructions per `simrod_step` call over whole TP07, TP11 and TP14 runs on
//!   the Cortex-M4F <= `rt::BUDGET_STEP_INSNS` (5,000), counted exactly by QEMU
//!   (`-icount shift=7` through the SysTick, see `firmware/src/bin/simrod-cost.rs`;
//!   calibration regions of known `nop` counts prove the counts exact, and every run's
//!   outputs must hash to the host's bits);
//! - the bench firmware's flash <= 64 KiB and RAM (`.data` + `.bss` + stack high-water
//!   mark of a whole run) <= 16 KiB.
//!
//! The aims (worst <= 3,000 instructions, RAM <= 8 KiB, host >= 5 M steps/s) are
//! reported by `cargo xtask bench-rt`, not enforced here. Reuses the other firmware
//! tests' build (`target/firmware-tests/plain`).
//!
//! The FPU-less Cortex-M3 (issue 15): the same cost binary counts the fixed-point twin
//! and, for comparison, the f32 twin in soft-float on the same core; the table is
//! printed, the fixed-point build's worst step is held to `rt::BUDGET_M3_STEP_INSNS`, its
//! mean step to `rt::MIN_M3_SOFT_OVER_FIXED` times cheaper than soft-float's, and its
//! bench firmware to `rt::BUDGET_M3_FLASH` and `rt::BUDGET_M3_RAM`.

mod firmware_support;

use firmware_support as fw;
use host_tests::rt::{self, Summary};
use model_core::Builtin;

#[test]
fn worst_step_cost_is_within_budget() {
    let dir = fw::build_firmware("plain", None);
    let cost =
        rt::run_cost(&dir.join("simrod-cost"), &dir.join("budget-cost")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(cost.n_blocks, 0, "the plain build has no block profile");
    for run in &cost.runs {
        let name = run.profile.name();
        let want = fw::host_sim(run.profile, model_core::RateSet::Identified, model_core::Effects::NONE)
            .total_steps();
        assert_eq!(run.steps.len() as u64, want, "{name}: steps measured");
        let step = Summary::of(run.steps.iter().map(|s| s.step)).expect("steps");
        let prof = Summary::of(run.steps.iter().map(|s| s.profile_at)).expect("steps");
        let stack = run.steps.iter().map(|s| s.stack).max().unwrap_or(0);
        eprintln!(
            "{name}: simrod_step instructions min {} / median {} / p99 {} / max {}; \
             profile_at max {}; step stack {stack} B",
            step.min, step.median, step.p99, step.max, prof.max
        );
        assert!(
            step.max <= rt::BUDGET_STEP_INSNS,
            "{name}: worst step takes {} instructions, over the budget of {} (median {}, p99 {}); \
             `cargo xtask bench-rt` shows which block grew",
            step.max,
            rt::BUDGET_STEP_INSNS,
            step.median,
            step.p99
        );
        // A step does the whole model: far from empty, whatever the optimiser does.
        assert!(step.min > 500, "{name}: a step of {} instructions cannot be the whole model", step.min);
        assert!(
            stack > 64 && stack < cost.stack_window,
            "{name}: step stack {stack} B outside (64, {}) B: the painted window is too small or unused",
            cost.stack_window
        );
    }
}

#[test]
fn firmware_fits_flash_and_ram_budget() {
    let dir = fw::build_firmware("plain", None);
    let elf = dir.join("firmware");
    let f = rt::footprint(&elf).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("firmware sections: {f:?}");
    assert!(
        f.flash() <= rt::BUDGET_FLASH,
        "firmware flash {} B > budget {} B ({f:?})",
        f.flash(),
        rt::BUDGET_FLASH
    );
    let stats = rt::run_loop(&elf, &dir.join("budget-loop"), Builtin::TP12, fw::STEP_US)
        .unwrap_or_else(|e| panic!("{e}"));
    let stack = u64::from(stats.get("stack_bytes"));
    assert!(stack > 1024, "stack high-water {stack} B: painting broken? {stats}");
    let ram = f.static_ram() + stack;
    eprintln!(
        "firmware: flash {} B (budget {}), RAM {ram} B = static {} + stack {stack} (budget {})",
        f.flash(),
        rt::BUDGET_FLASH,
        f.static_ram(),
        rt::BUDGET_RAM
    );
    assert!(ram <= rt::BUDGET_RAM, "firmware RAM {ram} B > budget {} B: {stats}", rt::BUDGET_RAM);
    assert_eq!(stats.get("overruns"), 0, "{stats}");
}

/// Per profile: (min, median, p99, worst) instructions of `simrod_step`, and the
/// step's stack; every run's outputs hash to the host's bits (`run_cost_on`).
fn m3_cost(mcu: &fw::Mcu, variant: &str) -> Vec<(Builtin, Summary, u32)> {
    let dir = fw::build_firmware_on(mcu, variant, None);
    let cost = rt::run_cost_on(mcu, &dir.join("simrod-cost"), &dir.join("budget-cost"))
        .unwrap_or_else(|e| panic!("{}: {e}", mcu.name));
    cost.runs
        .iter()
        .map(|run| {
            let step = Summary::of(run.steps.iter().map(|s| s.step)).expect("steps");
            let stack = run.steps.iter().map(|s| s.stack).max().unwrap_or(0);
            assert!(
                step.min > 500,
                "{}: a step of {} instructions cannot be the whole model",
                mcu.name,
                step.min
            );
            assert!(
                stack > 64 && stack < cost.stack_window,
                "{}: step stack {stack} B outside (64, {}) B",
                mcu.name,
                cost.stack_window
            );
            (run.profile, step, stack)
        })
        .collect()
}

#[test]
fn m3_fixed_point_step_cost_is_within_budget() {
    let fixed = m3_cost(&fw::M3_FIXED, "m3-fixed");
    let soft = m3_cost(&fw::M3_SOFT, "m3-soft");
    eprintln!(
        "Cortex-M3 (QEMU mps2-an385), instructions per simrod_step, min / median / p99 / worst, step stack:"
    );
    for ((p, f, fs), (_, s, ss)) in fixed.iter().zip(&soft) {
        eprintln!(
            "  {}: fixed point {} / {} / {} / {} ({fs} B); f32 soft-float {} / {} / {} / {} ({ss} B); \
             soft-float / fixed point (mean) {:.2}",
            p.name(),
            f.min,
            f.median,
            f.p99,
            f.max,
            s.min,
            s.median,
            s.p99,
            s.max,
            s.mean / f.mean
        );
    }
    for ((p, f, _), (_, s, _)) in fixed.iter().zip(&soft) {
        assert!(
            f.max <= rt::BUDGET_M3_STEP_INSNS,
            "{}: the M3's fixed-point step takes {} instructions at worst, over the budget of {}",
            p.name(),
            f.max,
            rt::BUDGET_M3_STEP_INSNS
        );
        assert!(
            s.mean >= rt::MIN_M3_SOFT_OVER_FIXED * f.mean,
            "{}: the fixed-point step ({:.0} instructions, mean) is not {}x cheaper than soft-float ({:.0})",
            p.name(),
            f.mean,
            rt::MIN_M3_SOFT_OVER_FIXED,
            s.mean
        );
    }
}

#[test]
fn m3_fixed_point_firmware_fits_flash_and_ram_budget() {
    let dir = fw::build_firmware_on(&fw::M3_FIXED, "m3-fixed", None);
    let elf = dir.join("firmware");
    let f = rt::footprint(&elf).unwrap_or_else(|e| panic!("{e}"));
    let stats = rt::run_loop_on(&fw::M3_FIXED, &elf, &dir.join("budget-loop"), Builtin::TP12, fw::STEP_US)
        .unwrap_or_else(|e| panic!("{e}"));
    let stack = u64::from(stats.get("stack_bytes"));
    assert!(stack > 1024, "stack high-water {stack} B: painting broken? {stats}");
    let ram = f.static_ram() + stack;
    eprintln!(
        "M3 fixed-point firmware: flash {} B (budget {}; {f:?}), RAM {ram} B = static {} + stack {stack} (budget {})",
        f.flash(),
        rt::BUDGET_M3_FLASH,
        f.static_ram(),
        rt::BUDGET_M3_RAM
    );
    assert!(
        f.flash() <= rt::BUDGET_M3_FLASH,
        "M3 firmware flash {} B > budget {} B",
        f.flash(),
        rt::BUDGET_M3_FLASH
    );
    assert!(ram <= rt::BUDGET_M3_RAM, "M3 firmware RAM {ram} B > budget {} B: {stats}", rt::BUDGET_M3_RAM);
    assert_eq!(stats.get("overruns"), 0, "{stats}");
}
