//! Cost mode: instructions per step on the Cortex-M4F, counted exactly by QEMU.
//!
//! Runs TP07, TP11 and TP14 (the build's rate set) flat out and writes, for every step,
//! the instructions of `simrod_profile_at` and of `simrod_step`, and the stack the step
//! used, to `simrod-cost.bin` over semihosting (format in `protocol`). Built with
//! feature `profile`, it also times every block of the step through model-core's probe
//! hooks.
//!
//! **How instructions are counted.** QEMU has no DWT. Under `-icount shift=S` every
//! instruction advances virtual time by exactly 2^S ns, and the SysTick counter (here
//! free-running on the 25 MHz core clock, no interrupt) is read at an exact instruction
//! boundary. With S >= 7 an instruction moves the counter by at least 3.2 counts, so
//! `round(counts x 40 ns / 2^S ns)` is the exact instruction count of any interval.
//! The host passes S on the semihosting command line (`shift=S`); calibration regions
//! of known `nop` counts, written first, prove the conversion (and the shift) right.
//!
//! **Stack of the step.** Before each step the 2 KiB below the stack pointer are
//! painted; afterwards the deepest overwritten word gives the step's stack use.

#![no_std]
#![no_main]

use cortex_m_rt::{entry, exception, ExceptionFrame};
use firmware::hostio::{HostFile, HostOut};
use firmware::icount::{between, counts, stamp};
use firmware::nop_region;
use firmware::protocol::{self, Fnv1a64};
use firmware::step::{simrod_profile_at, simrod_step};
use model_core::{Builtin, Inputs, Outputs, Profile, RateSet};

/// The profiles measured.
const PROFILES: [Builtin; 3] = [Builtin::TP07, Builtin::TP11, Builtin::TP14];
/// Blocks recorded: the call, then model-core's probe blocks (feature `profile`).
const N_BLOCKS: usize = if cfg!(feature = "profile") { protocol::COST_BLOCKS.len() } else { 0 };
/// Words per step record.
const RECORD_WORDS: usize = protocol::COST_FIXED_WORDS + 2 * N_BLOCKS;
/// Steps buffered per semihosting write.
const BATCH: usize = 128;
/// Bytes painted below the stack pointer before each step.
const STACK_WINDOW: usize = 4096;
const STACK_PAINT: u32 = 0x5354_4b21;
type Out = HostOut<{ 4 * RECORD_WORDS * BATCH }>;

/// Per-block timing through model-core's probe (feature `profile`).
#[cfg(feature = "profile")]
mod blocks {
    use core::sync::atomic::{AtomicU32, Ordering::Relaxed};

    use model_core::probe::Block;

    use firmware::icount::{between, counts, stamp};

    use super::N_BLOCKS;

    static LAST: AtomicU32 = AtomicU32::new(0);
    static CUR: AtomicU32 = AtomicU32::new(0);
    static INSNS: [AtomicU32; N_BLOCKS] = [const { AtomicU32::new(0) }; N_BLOCKS];
    static MARKS: [AtomicU32; N_BLOCKS] = [const { AtomicU32::new(0) }; N_BLOCKS];

    fn close(now: u32) {
        let c = CUR.load(Relaxed) as usize;
        if let (Some(i), Some(m)) = (INSNS.get(c), MARKS.get(c)) {
            i.fetch_add(between(counts(LAST.load(Relaxed), now)), Relaxed);
            m.fetch_add(1, Relaxed);
        }
    }

    /// The probe: the block that starts now.
    pub fn mark(b: Block) {
        let now = stamp();
        close(now);
        CUR.store(b as u32 + 1, Relaxed);
        LAST.store(now, Relaxed);
    }

    /// A step starts at stamp `t` (the "call" block, index 0).
    pub fn begin(t: u32) {
        for (i, m) in INSNS.iter().zip(&MARKS) {
            i.store(0, Relaxed);
            m.store(0, Relaxed);
        }
        CUR.store(0, Relaxed);
        LAST.store(t, Relaxed);
    }

    /// The step ended at stamp `t`: the words of the record.
    pub fn end(t: u32, words: &mut [u32]) {
        close(t);
        let (ins, marks) = words.split_at_mut(N_BLOCKS);
        for (d, s) in ins.iter_mut().zip(&INSNS) {
            *d = s.load(Relaxed);
        }
        for (d, s) in marks.iter_mut().zip(&MARKS) {
            *d = s.load(Relaxed);
        }
    }

    /// Instructions between the timer reads of two back-to-back probe calls through a
    /// function pointer, as the model makes them.
    pub fn mark_overhead() -> u32 {
        let f: fn(Block) = core::hint::black_box(mark);
        begin(stamp());
        f(Block::Tables);
        f(Block::Tables);
        let v = INSNS.get(Block::Tables as usize + 1).map_or(0, |v| v.load(Relaxed));
        begin(0);
        v
    }
}

/// Paint the `STACK_WINDOW` bytes below `sp`.
#[inline(always)]
fn paint_below(sp: usize) {
    let mut p = sp - STACK_WINDOW;
    while p < sp {
        // SAFETY: below the stack pointer, inside the stack region (`main` checks the
        // window fits), with no frame live there and no interrupt enabled.
        unsafe { core::ptr::write_volatile(p as *mut u32, STACK_PAINT) };
        p += 4;
    }
}

/// Bytes below `sp` overwritten since `paint_below(sp)`.
#[inline(always)]
fn used_below(sp: usize) -> u32 {
    let mut p = sp - STACK_WINDOW;
    // SAFETY: as in `paint_below`; reads only.
    while p < sp && unsafe { core::ptr::read_volatile(p as *const u32) } == STACK_PAINT {
        p += 4;
    }
    (sp - p) as u32
}

fn put_u32(out: &mut Out, v: u32) {
    out.put(&v.to_le_bytes());
}

fn run(out: &mut Out, which: Builtin, rates: RateSet) {
    let cfg = firmware::config(rates);
    let mut model = match firmware::new_model(&cfg) {
        Ok(m) => m,
        Err(e) => defmt::panic!("model config rejected: {}", e),
    };
    #[cfg(feature = "profile")]
    model.set_probe(blocks::mark);
    let profile = match Profile::builtin(which, 1.0, 1.0) {
        Ok(p) => p,
        Err(e) => defmt::panic!("profile: {}", e),
    };
    let n_steps = profile.duration_us().div_ceil(u64::from(firmware::STEP_US)) as u32;
    let mut name = [0u8; 8];
    for (d, s) in name.iter_mut().zip(which.name().bytes()) {
        *d = s;
    }
    out.put(&protocol::RUN_MAGIC);
    out.put(&name);
    out.put(&[u8::from(rates == RateSet::Identified)]);
    put_u32(out, n_steps);

    let mut hash = Fnv1a64::default();
    let mut o = Outputs::zero();
    let mut rec = [0u32; RECORD_WORDS];
    let (mut steps, mut worst) = (0u32, 0u32);
    while model.t_us() < profile.duration_us() {
        let t_us = model.t_us();
        let t0 = stamp();
        let sp = simrod_profile_at(&profile, t_us);
        let t1 = stamp();
        let inputs = Inputs { sp, supply_v: firmware::SUPPLY_V };
        let sp_at_call = cortex_m::register::msp::read() as usize;
        paint_below(sp_at_call);
        let t2 = stamp();
        #[cfg(feature = "profile")]
        blocks::begin(t2);
        simrod_step(&mut model, &inputs, &mut o);
        let t3 = stamp();
        #[cfg(feature = "profile")]
        blocks::end(t3, &mut rec[protocol::COST_FIXED_WORDS..]);
        rec[0] = between(counts(t0, t1));
        rec[1] = between(counts(t2, t3));
        rec[2] = used_below(sp_at_call);
        worst = worst.max(rec[1]);
        for w in rec {
            put_u32(out, w);
        }
        firmware::hash_values(&mut hash, &o.values);
        steps += 1;
    }
    out.put(&protocol::END_MAGIC);
    out.put(&hash.0.to_le_bytes());
    defmt::info!("{} {}: {=u32} steps, worst {=u32} instructions", which, rates, steps, worst);
}

#[entry]
fn main() -> ! {
    let mut args = [0u8; 160];
    let args = firmware::qemu_cmdline(&mut args);
    let shift = firmware::icount::start(args);
    let sp = cortex_m::register::msp::read() as usize;
    let bottom = core::ptr::addr_of!(_stack_end) as usize;
    if sp < bottom + 4 * STACK_WINDOW {
        defmt::panic!("stack too small for the painted window");
    }

    let Some(file) = HostFile::create(concat!("simrod-cost.bin", "\0")) else {
        defmt::panic!("cannot create {=str} on the host", protocol::COST_FILE);
    };
    let mut out = Out::new(file);
    out.put(&protocol::COST_MAGIC);
    put_u32(&mut out, 1 << shift);
    put_u32(&mut out, firmware::board::SYSCLK_HZ);
    put_u32(&mut out, N_BLOCKS as u32);
    let cal = [
        nop_region!(0),
        nop_region!(1),
        nop_region!(2),
        nop_region!(3),
        nop_region!(5),
        nop_region!(8),
        nop_region!(13),
        nop_region!(100),
        nop_region!(200),
    ];
    put_u32(&mut out, cal.len() as u32);
    for (k, n, c) in cal {
        put_u32(&mut out, k);
        put_u32(&mut out, n);
        put_u32(&mut out, c);
    }
    #[cfg(feature = "profile")]
    put_u32(&mut out, blocks::mark_overhead());
    #[cfg(not(feature = "profile"))]
    put_u32(&mut out, 0);
    put_u32(&mut out, STACK_WINDOW as u32);

    for which in PROFILES {
        run(&mut out, which, firmware::BUILD_RATES);
    }
    out.put(&protocol::DONE_MAGIC);
    put_u32(&mut out, PROFILES.len() as u32);
    out.finish();
    firmware::exit(true)
}

extern "C" {
    // cortex-m-rt's link.x: the lowest address of the stack.
    static _stack_end: u32;
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    defmt::error!("hard fault at pc {=u32:#x}", ef.pc());
    firmware::exit(false)
}
