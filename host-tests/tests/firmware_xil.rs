//! The whole XiL loop on the Cortex-M4F: the firmware's `simrod-xil` runs the bench twin
//! and the vehicle-and-road twin together (`simrod_xdt::XilLoop`) on QEMU (mps2-an386)
//! and streams every step's channel bits and the xDT's values; each must equal the host's
//! `XilLoop` bit for bit, at every step, on every channel. Under `-icount shift=7` it
//! also counts the instructions of every closed-loop step (exactly: calibration regions
//! of known `nop` counts prove it), printed beside the plain twin's step in the same
//! build; the worst closed-loop step must stay within the twin's CI budget
//! (`rt::BUDGET_STEP_INSNS`).
//!
//! Needs `rustup target add thumbv7em-none-eabihf` and `qemu-system-arm`; fails (does
//! not skip) without them.

mod firmware_support;

use std::fs;
use std::time::{Duration, Instant};

use firmware_support as fw;
use firmware_support::Cursor;
use host_tests::rt::{self, Summary};
use model_core::{Builtin, Effects, RateSet, N_CHANNELS};
use simrod_xdt::{Cycle, Timing, XilLoop, SIGNALS};

/// Far above the ~20 s the run takes: only a hung firmware gets near it.
const QEMU_TIMEOUT: Duration = Duration::from_secs(600);
const XIL_MAGIC: &[u8; 8] = b"SRXIL01\0";
const TWIN_MAGIC: &[u8; 4] = b"TWIN";
const XIL_FILE: &str = "simrod-xil.bin";

/// One closed-loop run of the file, compared with the host's loop step by step; its
/// instructions per step.
fn compare_run(c: &mut Cursor<'_>) -> (String, u32, Vec<u32>) {
    c.magic(&fw::protocol::RUN_MAGIC, "a run");
    let name = String::from_utf8_lossy(c.take(8)).trim_end_matches('\0').to_string();
    let cycle = Cycle::from_name(&name).unwrap_or_else(|| panic!("unknown cycle {name}"));
    let (period, delay, n_steps) = (c.u32(), c.u32(), c.u32());
    let cfg = fw::config(RateSet::Identified, Effects::NONE);
    let timing = Timing::new(period, delay).expect("the firmware's timing");
    let host = XilLoop::builtin(&cfg, cycle, timing, fw::SUPPLY_V).expect("the built-in loop");
    assert_eq!(u64::from(n_steps), host.total_steps(), "{name}: steps");
    let label = format!("{name} (sample every {period} ms, delay {delay} ms)");
    let mut insns = Vec::with_capacity(n_steps as usize);
    let mut hash = fw::protocol::Fnv1a64::default();
    let mut k = 0u32;
    for o in host {
        let t_us = c.u64();
        assert_eq!(t_us, o.bench.t_us, "{label}: step {k}: firmware t_us {t_us}, host {}", o.bench.t_us);
        let signals = o.signals();
        let want = o.bench.values.iter().chain(signals.iter());
        let names = model_core::Channel::ALL.iter().map(|ch| format!("{} [{}]", ch.name(), ch.unit()));
        let names = names.chain(SIGNALS.iter().map(|s| format!("xDT {s}")));
        for (v, what) in want.zip(names) {
            let fw_bits = c.u32();
            if fw_bits != v.to_bits() {
                panic!(
                    "{label}: first difference at step {k} (t = {t_us} us), {what}:\n  firmware {:e} \
                     (0x{fw_bits:08x})\n  host     {v:e} (0x{:08x})",
                    f32::from_bits(fw_bits),
                    v.to_bits()
                );
            }
            hash.write(&fw_bits.to_le_bytes());
        }
        insns.push(c.u32());
        k += 1;
    }
    assert_eq!(k, n_steps, "{label}: the host's loop ran {k} steps");
    c.magic(&fw::protocol::END_MAGIC, "the end of a run");
    assert_eq!(c.u64(), hash.0, "{label}: the firmware's own hash differs though every value matched");
    (label, period, insns)
}

fn line(what: &str, s: &Summary) -> String {
    format!("{what:<44} {:>6} {:>7} {:>6} {:>6} {:>8.1}", s.min, s.median, s.p99, s.max, s.mean)
}

#[test]
fn firmware_xil_loop_matches_host_bit_for_bit() {
    let t0 = Instant::now();
    let dir = fw::build_firmware("plain", None);
    let cwd = dir.join("xil-run");
    let _ = fs::remove_dir_all(&cwd);
    let run = fw::spawn_qemu(&dir.join("simrod-xil"), &cwd, &["-icount", "shift=7,sleep=off"], &["shift=7"])
        .wait(QEMU_TIMEOUT);
    let bytes = fs::read(cwd.join(XIL_FILE)).unwrap_or_else(|e| panic!("{XIL_FILE}: {e}"));
    eprintln!("QEMU XiL run {:.1} s, {:.1} MB", run.wall.as_secs_f64(), bytes.len() as f64 / 1e6);

    let mut c = Cursor::new(&bytes, XIL_FILE);
    c.magic(XIL_MAGIC, "the file magic");
    assert_eq!(usize::from(c.u16()), N_CHANNELS, "channels");
    assert_eq!(usize::from(c.u16()), SIGNALS.len(), "xDT values");
    assert_eq!(c.u32(), fw::STEP_US, "step");
    assert_eq!(c.u32(), 1 << rt::COST_SHIFT, "ns per instruction");
    let n_cal = c.u32();
    assert!(n_cal >= 3);
    for _ in 0..n_cal {
        let (nops, counted) = (c.u32(), c.u32());
        assert_eq!(nops, counted, "calibration: {nops} nops counted as {counted}: counts are not exact");
    }
    c.magic(TWIN_MAGIC, "the plain twin's section");
    let n = c.u32();
    let twin: Vec<u32> = (0..n).map(|_| c.u32()).collect();
    let (want_hash, steps) = fw::host_hash(Builtin::TP07, RateSet::Identified);
    assert_eq!((c.u64(), n), (want_hash, steps), "the plain twin's TP07 outputs");

    let mut runs = Vec::new();
    loop {
        if bytes.get(c.pos..c.pos + 4) == Some(&fw::protocol::DONE_MAGIC[..]) {
            c.take(4);
            assert_eq!(c.u32() as usize, runs.len(), "run count");
            assert_eq!(c.pos, bytes.len(), "bytes after the trailer");
            break;
        }
        runs.push(compare_run(&mut c));
    }
    assert_eq!(runs.len(), 2, "ECE-15 and the hill");

    let mut table = format!(
        "instructions per call on the Cortex-M4F        {:>6} {:>7} {:>6} {:>6} {:>8}\n",
        "min", "median", "p99", "max", "mean"
    );
    let twin_s = Summary::of(twin.iter().copied()).expect("steps");
    table += &line("simrod_step (the twin alone), TP07", &twin_s);
    table.push('\n');
    let mut worst = 0;
    for (label, period, insns) in &runs {
        let s = Summary::of(insns.iter().copied()).expect("steps");
        worst = worst.max(s.max);
        table += &line(&format!("simrod_xil_step, {label}"), &s);
        table.push('\n');
        if *period > 1 {
            // Steps with a sample of the xDT against the steps without (twin + delay line).
            let with = Summary::of(insns.iter().step_by(*period as usize).copied()).expect("steps");
            let without = Summary::of(
                insns.iter().enumerate().filter(|(k, _)| k % *period as usize != 0).map(|(_, v)| *v),
            )
            .expect("steps");
            table += &line("  steps with an xDT sample", &with);
            table.push('\n');
            table += &line("  steps without (twin and delay line)", &without);
            table.push('\n');
        }
    }
    eprintln!(
        "firmware XiL loop == host XiL loop, bit for bit ({} steps, {} channels + {} xDT values each; {:.1} s)\n{table}",
        runs.iter().map(|r| r.2.len()).sum::<usize>(),
        N_CHANNELS,
        SIGNALS.len(),
        t0.elapsed().as_secs_f64()
    );
    assert!(twin_s.min > 500, "a twin step of {} instructions cannot be the whole model", twin_s.min);
    assert!(
        worst <= rt::BUDGET_STEP_INSNS,
        "the worst closed-loop step takes {worst} instructions, over the twin's budget of {}",
        rt::BUDGET_STEP_INSNS
    );
}
