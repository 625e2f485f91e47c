//! Instructions counted under QEMU's `-icount shift=S`, shared by the cost modes
//! (`simrod-cost`, `simrod-xil`). QEMU has no DWT; under `-icount` every instruction
//! advances virtual time by 2^S ns, so the free-running SysTick, read around a call,
//! converts exactly to instructions. The host passes S on the semihosting command line
//! (`shift=S`); calibration regions of known `nop` counts ([`nop_region!`]), written
//! first, prove the conversion (and the shift) right.

use core::sync::atomic::{compiler_fence, AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{Peripherals, SYST};

/// SysTick's counter is 24 bits wide.
pub const SYST_MASK: u32 = 0x00ff_ffff;
/// Timer nanoseconds per count (the core clock).
const NS_PER_COUNT: u32 = 1_000_000_000 / crate::board::SYSCLK_HZ;

/// Virtual nanoseconds per instruction (2^shift), from the command line.
static NS_PER_INSN: AtomicU32 = AtomicU32::new(128);

/// Read `shift=S` from the command line `args` (7..=10, default 7), and start SysTick
/// free-running from the core clock, no interrupt. Returns the shift. Not inlined: in a
/// `main` that also holds the calibration regions' nops, its code would push the
/// literal pool out of a pc-relative load's reach.
#[inline(never)]
pub fn start(args: &str) -> u32 {
    let shift = crate::option(args, "shift").and_then(|v| v.parse::<u32>().ok()).unwrap_or(7);
    if !(7..=10).contains(&shift) {
        defmt::panic!("shift={=u32}: exact counts need -icount shift=7..10", shift);
    }
    NS_PER_INSN.store(1 << shift, Ordering::Relaxed);
    let Some(mut cp) = Peripherals::take() else {
        defmt::panic!("core peripherals taken twice");
    };
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(SYST_MASK);
    cp.SYST.clear_current();
    cp.SYST.disable_interrupt();
    cp.SYST.enable_counter();
    shift
}

/// The SysTick counter, read at an exact point of the instruction stream.
#[inline(always)]
pub fn stamp() -> u32 {
    compiler_fence(Ordering::SeqCst);
    let v = SYST::get_current();
    compiler_fence(Ordering::SeqCst);
    v
}

/// Timer counts from stamp `from` to stamp `to` (the counter counts down).
#[inline(always)]
pub fn counts(from: u32, to: u32) -> u32 {
    from.wrapping_sub(to) & SYST_MASK
}

/// Instructions in an interval of `c` timer counts, rounded to the nearest.
#[inline(always)]
pub fn insns(c: u32) -> u32 {
    let ns = NS_PER_INSN.load(Ordering::Relaxed);
    (c * NS_PER_COUNT + ns / 2) / ns
}

/// Instructions executed strictly between the two timer reads of an interval of `c`
/// counts (the first read itself excluded).
#[inline(always)]
pub fn between(c: u32) -> u32 {
    insns(c).saturating_sub(1)
}

/// Calibration: two timer reads with exactly `k` nops between them, in one `asm!` block
/// so the compiler cannot add anything; `(k, instructions between, raw counts)`.
#[macro_export]
macro_rules! nop_region {
    ($k:literal) => {{
        let (a, b): (u32, u32);
        // SAFETY: two reads of the SysTick current-value register and `nop`s.
        unsafe {
            core::arch::asm!(
                "ldr {a}, [{t}]",
                concat!(".rept ", stringify!($k)),
                "nop",
                ".endr",
                "ldr {b}, [{t}]",
                t = in(reg) 0xE000_E018u32,
                a = out(reg) a,
                b = out(reg) b,
                options(nostack, preserves_flags, readonly),
            )
        };
        let c = $crate::icount::counts(a, b);
        ($k, $crate::icount::between(c), c)
    }};
}
