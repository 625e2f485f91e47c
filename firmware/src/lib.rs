//! # SimRod twin firmware (Cortex-M4F; Cortex-M3 without an FPU)
//!
//! The `model-core` twin at the bench rate on a microcontroller: a periodic tick runs
//! one step, set points come from the built-in profile in flash or from a serial
//! stream (XiL), outputs go out on the serial stream, a status pin flags late or
//! overrunning steps. Two binaries share this library:
//!
//! - `firmware` (`src/main.rs`): the real-time bench loop.
//! - `simrod-trace` (`src/bin/simrod-trace.rs`): runs the named profiles flat out and
//!   streams every channel's bits to the host, the proof that the target computes
//!   the very same bits as the host simulation.
//!
//! Default board: QEMU `mps2-an386` ([`board`]). Logging: defmt over semihosting
//! (feature `qemu`) or RTT (feature `rtt`). Effects, profile and rate set are fixed at
//! build time (see `build.rs`).
//!
//! The same crate builds for an FPU-less Cortex-M3 (`--target thumbv7m-none-eabi`, QEMU
//! `mps2-an385`, memory layout `firmware/m3/memory.x`): with feature `fixed` the twin
//! runs in fixed point ([`Scalar`] = `model_core::Fx`), without it in soft-float f32
//! (the cost comparison). The bench loop, trace and cost modes are the same code for
//! every build; `simrod-xil` (the f32 xDT) is built for the f32 twin only.

#![no_std]

#[cfg(all(feature = "qemu", feature = "rtt"))]
compile_error!("features `qemu` and `rtt` are exclusive: pick one log transport");
#[cfg(not(any(feature = "qemu", feature = "rtt")))]
compile_error!("enable feature `qemu` (default) or `rtt`");

#[cfg(feature = "rtt")]
use defmt_rtt as _;
#[cfg(feature = "qemu")]
use defmt_semihosting as _;

pub mod bench;
pub mod board;
pub mod clock;
pub mod hostio;
pub mod icount;
pub mod io;
pub mod protocol;
pub mod step;

use model_core::{Config, ConfigError, CouplingStiffness, Effects, Model, Params, RateSet, SpeedTarget};

/// The twin's scalar in this build: f32 (the M4F's FPU, or soft-float on the M3).
#[cfg(not(feature = "fixed"))]
pub type Scalar = f32;
/// The twin's scalar in this build: fixed point (feature `fixed`, the M3 build).
#[cfg(feature = "fixed")]
pub type Scalar = model_core::Fx;

/// Bytes of one value in the trace and cost streams: an f32's bits, or an `Fx`'s.
pub const VALUE_BYTES: usize = core::mem::size_of::<Scalar>();

/// The trace file's magic for this build's scalar.
#[cfg(not(feature = "fixed"))]
pub const TRACE_MAGIC: [u8; 8] = protocol::TRACE_MAGIC;
/// The trace file's magic for this build's scalar.
#[cfg(feature = "fixed")]
pub const TRACE_MAGIC: [u8; 8] = protocol::TRACE_MAGIC_FX;

/// A value's little-endian bits (an f32's `to_bits`, an `Fx`'s I17F15 bits).
#[inline]
pub fn value_le(v: Scalar) -> [u8; VALUE_BYTES] {
    v.to_bits().to_le_bytes()
}

/// FNV-1a 64 over the little-endian bits of `values` (for f32 exactly
/// `Fnv1a64::write_f32s`).
pub fn hash_values(h: &mut protocol::Fnv1a64, values: &[Scalar]) {
    for v in values {
        h.write(&value_le(*v));
    }
}

/// The twin of this build on its built-in maps: f32, or fixed point (`fixed`).
pub fn new_model(cfg: &Config) -> Result<Model<'static, Scalar>, ConfigError> {
    #[cfg(not(feature = "fixed"))]
    return Model::new(cfg);
    #[cfg(feature = "fixed")]
    return Model::new_fx(cfg);
}

mod generated {
    include!(concat!(env!("OUT_DIR"), "/build_effects.rs"));
}
pub use generated::{BUILD_EFFECTS, BUILD_EFFECTS_FILE, BUILD_PROFILE, BUILD_RATES};

/// Bench step [µs]: the PLC's 1 kHz.
pub const STEP_US: u32 = 1000;
/// Supply voltage of the basic mode [V].
pub const SUPPLY_V: f32 = 24.0;

/// The model configuration of this build: bench rate, thesis parameters with `rates`,
/// identified coupling, speed map, and the effects compiled in.
pub fn config(rates: RateSet) -> Config {
    let mut effects = Effects::NONE;
    for (id, key, v) in BUILD_EFFECTS {
        if let Err(e) = effects.set(id, key, *v) {
            // build.rs checked the file with the same code: unreachable unless edited.
            defmt::panic!("effect {=str}.{=str}: {}", id, key, e);
        }
    }
    if let Err(id) = effects.validate() {
        defmt::panic!("effect {=str}: invalid parameter", id);
    }
    Config {
        dt_us: STEP_US,
        params: Params::thesis(rates, CouplingStiffness::Identified),
        speed_target: SpeedTarget::Map,
        effects,
    }
}

/// QEMU's semihosting command line (`-semihosting-config ...,arg=KEY=VALUE`), read into
/// `buf`: a test hook to vary a run without another build. Hardware without a
/// debugger has no semihosting (the call would fault), so there it is always empty.
pub fn qemu_cmdline(buf: &mut [u8]) -> &str {
    #[cfg(feature = "qemu")]
    {
        use cortex_m_semihosting::{nr, syscall1};
        let mut block = [buf.as_mut_ptr() as usize, buf.len()];
        // SAFETY: SYS_GET_CMDLINE writes at most `buf.len()` bytes into `buf` and the
        // length into `block[1]`; both outlive the call.
        let r = unsafe { syscall1(nr::GET_CMDLINE, block.as_mut_ptr() as usize) };
        // SAFETY: `block` is a live local the host wrote behind the compiler's back.
        let n = unsafe { core::ptr::read_volatile(&block[1]) };
        if r == 0 {
            let n = n.min(buf.len());
            return core::str::from_utf8(buf.get(..n).unwrap_or(&[])).unwrap_or("");
        }
    }
    let _ = buf;
    ""
}

/// The value of `key=value` among the whitespace-separated words of `cmdline`.
pub fn option<'a>(cmdline: &'a str, key: &str) -> Option<&'a str> {
    cmdline
        .split_ascii_whitespace()
        .filter_map(|w| w.split_once('='))
        .find(|(k, _)| *k == key)
        .map(|(_, v)| v)
}

extern "C" {
    // From cortex-m-rt's link.x: the stack grows down from `_stack_start` towards
    // `_stack_end`, the end of the statics.
    static _stack_start: u32;
    static _stack_end: u32;
}

/// Pattern left in the unused stack by [`paint_stack`].
const STACK_PAINT: u32 = 0x5354_4b21;

/// Fill the free stack (below the current frame) with a pattern, so
/// [`stack_high_water`] can tell later how deep the stack ever went.
pub fn paint_stack() {
    let end = core::ptr::addr_of!(_stack_end) as usize;
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = end;
    // Keep clear of the live frame of this function.
    while p + 256 < sp {
        // SAFETY: `[end, sp - 256)` is RAM below every live frame: unused stack.
        unsafe { core::ptr::write_volatile(p as *mut u32, STACK_PAINT) };
        p += 4;
    }
}

/// Bytes of stack used at most since [`paint_stack`].
pub fn stack_high_water() -> u32 {
    let (end, top) = (core::ptr::addr_of!(_stack_end) as usize, core::ptr::addr_of!(_stack_start) as usize);
    let mut p = end;
    // SAFETY: `[end, top)` is the stack region, always mapped RAM.
    while p < top && unsafe { core::ptr::read_volatile(p as *const u32) } == STACK_PAINT {
        p += 4;
    }
    (top - p) as u32
}

/// Leave: under QEMU a semihosting exit with the status; on hardware a breakpoint on
/// failure (the probe stops there) and sleep on success.
pub fn exit(success: bool) -> ! {
    #[cfg(feature = "qemu")]
    {
        use cortex_m_semihosting::debug;
        debug::exit(if success { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    }
    if !success {
        cortex_m::asm::bkpt();
    }
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    match info.location() {
        Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
        None => defmt::error!("panic"),
    }
    exit(false)
}

#[defmt::panic_handler]
fn defmt_panic() -> ! {
    exit(false)
}
