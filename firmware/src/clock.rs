//! The bench tick and the cycle counters that time each step.
//!
//! SysTick fires once per model step; its handler counts ticks and stamps the tick's
//! edge with the cycle counter, so the loop can tell how late a step started. Two
//! counters: the DWT cycle counter on hardware (exact, free-running), and under QEMU,
//! which does not model the DWT, one derived from SysTick itself (tick count x period
//! + the current count).

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{DCB, DWT, SCB, SYST};

static TICKS: AtomicU32 = AtomicU32::new(0);
static TICK_EDGE: AtomicU32 = AtomicU32::new(0);

/// A free-running, wrapping count of core clock cycles.
pub trait CycleCounter {
    /// Cycles now.
    fn cycles(&self) -> u32;
}

/// Start SysTick on the core clock with one interrupt every `period_cycles`.
pub fn start_tick(syst: &mut SYST, period_cycles: u32) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(period_cycles - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// Call from the SysTick handler.
#[inline]
pub fn on_tick(clock: &impl CycleCounter) {
    TICKS.fetch_add(1, Ordering::AcqRel);
    TICK_EDGE.store(clock.cycles(), Ordering::Release);
}

/// Ticks since start.
#[inline]
pub fn ticks() -> u32 {
    TICKS.load(Ordering::Acquire)
}

/// Cycle stamp of the latest tick.
#[inline]
pub fn tick_edge() -> u32 {
    TICK_EDGE.load(Ordering::Acquire)
}

/// DWT cycle counter (hardware).
pub struct DwtCycles(());

impl DwtCycles {
    /// Enable the trace block and start the counter.
    pub fn start(dcb: &mut DCB, dwt: &mut DWT) -> Self {
        dcb.enable_trace();
        dwt.enable_cycle_counter();
        Self(())
    }
}

impl CycleCounter for DwtCycles {
    #[inline]
    fn cycles(&self) -> u32 {
        DWT::cycle_count()
    }
}

/// Cycles reconstructed from SysTick: for QEMU, which has no DWT. Resolution is the
/// core clock, like the DWT's; only valid while SysTick runs with `period` cycles.
pub struct SysTickCycles {
    period: u32,
}

impl SysTickCycles {
    /// For a SysTick started with `start_tick(_, period)`.
    pub const fn new(period: u32) -> Self {
        Self { period }
    }
}

impl CycleCounter for SysTickCycles {
    fn cycles(&self) -> u32 {
        let reload = self.period - 1;
        loop {
            let t0 = ticks();
            let pend0 = SCB::is_pendst_pending();
            let cvr = SYST::get_current();
            let pend1 = SCB::is_pendst_pending();
            if ticks() != t0 || pend0 != pend1 {
                continue; // a wrap or the handler came in between: read again
            }
            // A wrap the handler has not counted yet (it is pending: interrupts
            // masked, or the emulator delivers it late) is one more tick.
            let t = t0.wrapping_add(u32::from(pend0));
            return t.wrapping_mul(self.period).wrapping_add(reload.saturating_sub(cvr));
        }
    }
}
