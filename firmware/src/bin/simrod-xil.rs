//! XiL closed-loop mode: the whole loop on the MCU. The bench twin (model-core) and the
//! vehicle-and-road twin (simrod-xdt) run together through the RT platform's delay and
//! sample time (`simrod_xdt::XilLoop`, the very code `simrod xil` runs on the host), on
//! built-in drive cycles, flat out. Every step's channel bits and the xDT's values are
//! written to `simrod-xil.bin` over semihosting, with the instructions the step took:
//! `host-tests/tests/firmware_xil.rs` compares the bits with the host's loop and reports
//! the cost.
//!
//! **Cost.** As in `simrod-cost` (see there): under QEMU's `-icount shift=S` (S >= 7,
//! passed as `shift=S` on the semihosting command line) the free-running SysTick, read
//! around a call, converts exactly to instructions; calibration regions of known `nop`
//! counts prove it. Without -icount the counts are meaningless and the test ignores them.
//! For a comparison in the same build, the plain twin (`simrod_step` on TP07) is timed
//! first.
//!
//! File (little-endian):
//!   XIL_MAGIC | n_channels: u16 | n_signals: u16 | step_us: u32 | ns_per_insn: u32
//!   | n_cal: u32 | (nops: u32, insns: u32) x n_cal
//!   | TWIN_MAGIC | n_steps: u32 | insns: u32 x n_steps | fnv1a64 of the channel bits: u64
//!   | runs ... | DONE_MAGIC | n_runs: u32
//!   run: RUN_MAGIC | cycle name: [u8; 8] (NUL padded) | period: u32 | delay: u32
//!        | n_steps: u32 | (t_us: u64, channel bits: u32 x n_channels,
//!          signal bits: u32 x n_signals, insns: u32) x n_steps
//!        | END_MAGIC | fnv1a64 over the channel and signal bits: u64

#![no_std]
#![no_main]

use cortex_m_rt::{entry, exception, ExceptionFrame};
use firmware::hostio::{HostFile, HostOut};
use firmware::icount::{between, counts, stamp};
use firmware::nop_region;
use firmware::protocol::{self, Fnv1a64};
use firmware::step::{simrod_profile_at, simrod_step};
use model_core::{Builtin, Inputs, Model, Outputs, Profile, N_CHANNELS};
use simrod_xdt::{Cycle, Timing, XilLoop, SIGNALS};

/// File magic.
const XIL_MAGIC: [u8; 8] = *b"SRXIL01\0";
/// The plain twin's section.
const TWIN_MAGIC: [u8; 4] = *b"TWIN";
/// The loops run: (cycle, sample period in steps, delay in steps). ECE-15 at the loop's
/// defaults (1 ms, 2 ms); the hill at 5 ms / 7 ms, so the sample-and-hold and the delay
/// line run with values other than the defaults, and a step with an xDT sample can be
/// told from one without.
const RUNS: [(Cycle, u32, u32); 2] = [(Cycle::Ece15, 1, 2), (Cycle::Hill, 5, 7)];
/// Bytes per step record.
const RECORD: usize = 8 + 4 * (N_CHANNELS + SIGNALS.len()) + 4;
/// Steps buffered per semihosting write.
const BATCH: usize = 64;
type Out = HostOut<{ RECORD * BATCH }>;

/// One step of the closed loop, under a fixed symbol name (the cost is this call).
#[inline(never)]
#[no_mangle]
pub fn simrod_xil_step(lp: &mut XilLoop<'static>) -> bool {
    lp.step().is_some()
}

fn put_u32(out: &mut Out, v: u32) {
    out.put(&v.to_le_bytes());
}

/// The plain twin on TP07, timed per step: the reference cost in this build.
fn twin(out: &mut Out) {
    let cfg = firmware::config(firmware::BUILD_RATES);
    let mut model = match Model::new(&cfg) {
        Ok(m) => m,
        Err(e) => defmt::panic!("model config rejected: {}", e),
    };
    let profile = match Profile::builtin(Builtin::TP07, 1.0, 1.0) {
        Ok(p) => p,
        Err(e) => defmt::panic!("profile: {}", e),
    };
    let n_steps = profile.duration_us().div_ceil(u64::from(firmware::STEP_US)) as u32;
    out.put(&TWIN_MAGIC);
    put_u32(out, n_steps);
    let mut hash = Fnv1a64::default();
    let mut o = Outputs::default();
    while model.t_us() < profile.duration_us() {
        let inputs = Inputs { sp: simrod_profile_at(&profile, model.t_us()), supply_v: firmware::SUPPLY_V };
        let t0 = stamp();
        simrod_step(&mut model, &inputs, &mut o);
        let t1 = stamp();
        put_u32(out, between(counts(t0, t1)));
        hash.write_f32s(&o.values);
    }
    out.put(&hash.0.to_le_bytes());
}

fn run(out: &mut Out, cycle: Cycle, period: u32, delay: u32) {
    let cfg = firmware::config(firmware::BUILD_RATES);
    let timing = match Timing::new(period, delay) {
        Ok(t) => t,
        Err(e) => defmt::panic!("timing: {=str}", e),
    };
    let mut lp = match XilLoop::builtin(&cfg, cycle, timing, firmware::SUPPLY_V) {
        Ok(l) => l,
        Err(e) => defmt::panic!("XiL loop rejected: {}", e),
    };
    let mut name = [0u8; 8];
    for (d, s) in name.iter_mut().zip(cycle.name().bytes()) {
        *d = s;
    }
    out.put(&protocol::RUN_MAGIC);
    out.put(&name);
    put_u32(out, period);
    put_u32(out, delay);
    put_u32(out, lp.total_steps() as u32);
    let mut hash = Fnv1a64::default();
    let mut rec = [0u8; RECORD];
    let (mut steps, mut worst) = (0u32, 0u32);
    loop {
        let t0 = stamp();
        let more = simrod_xil_step(&mut lp);
        let t1 = stamp();
        if !more {
            break;
        }
        let o = lp.outputs();
        let insns = between(counts(t0, t1));
        worst = worst.max(insns);
        rec[..8].copy_from_slice(&o.bench.t_us.to_le_bytes());
        let signals = o.signals();
        let values = o.bench.values.iter().chain(signals.iter()).map(|v| v.to_bits().to_le_bytes());
        for (dst, v) in rec[8..RECORD - 4].chunks_exact_mut(4).zip(values) {
            dst.copy_from_slice(&v);
        }
        rec[RECORD - 4..].copy_from_slice(&insns.to_le_bytes());
        hash.write(&rec[8..RECORD - 4]);
        out.put(&rec);
        steps += 1;
    }
    out.put(&protocol::END_MAGIC);
    out.put(&hash.0.to_le_bytes());
    defmt::info!("{=str}: {=u32} steps, worst {=u32} instructions", cycle.name(), steps, worst);
}

#[entry]
fn main() -> ! {
    let mut args = [0u8; 160];
    let args = firmware::qemu_cmdline(&mut args);
    let shift = firmware::icount::start(args);

    let Some(file) = HostFile::create(concat!("simrod-xil.bin", "\0")) else {
        defmt::panic!("cannot create simrod-xil.bin on the host");
    };
    let mut out = Out::new(file);
    out.put(&XIL_MAGIC);
    out.put(&(N_CHANNELS as u16).to_le_bytes());
    out.put(&(SIGNALS.len() as u16).to_le_bytes());
    put_u32(&mut out, firmware::STEP_US);
    put_u32(&mut out, 1 << shift);
    let cal = [nop_region!(0), nop_region!(1), nop_region!(13), nop_region!(100), nop_region!(200)];
    put_u32(&mut out, cal.len() as u32);
    for (k, n, _) in cal {
        put_u32(&mut out, k);
        put_u32(&mut out, n);
    }
    twin(&mut out);
    for (cycle, period, delay) in RUNS {
        run(&mut out, cycle, period, delay);
    }
    out.put(&protocol::DONE_MAGIC);
    put_u32(&mut out, RUNS.len() as u32);
    out.finish();
    firmware::exit(true)
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    defmt::error!("hard fault at pc {=u32:#x}", ef.pc());
    firmware::exit(false)
}
