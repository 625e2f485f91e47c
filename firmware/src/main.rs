//! The real-time bench loop: the twin at the bench rate from SysTick.
//!
//! Basic mode runs the build's profile from flash and ends (under QEMU: exits) with
//! it; XiL mode (feature `xil`) takes set points from UART0 until an end frame.
//! Outputs of the measured channels go out on UART0 every 10th step, then a
//! statistics frame; the status LED flags late/overrunning steps.
//!
//! Under QEMU the semihosting command line may override, for tests: `profile=TP12`,
//! `mode=xil|profile`, `tick_us=N` (wall-clock tick; the model step stays 1 ms, so a
//! short tick forces overruns to exercise their handling).

#![no_std]
#![no_main]

use cortex_m_rt::{entry, exception, ExceptionFrame};
use firmware::bench::{self, LoopConfig};
use firmware::board::{self, UartRx};
use firmware::clock::{self, CycleCounter};
use firmware::io::{ProfileSource, SerialSink, SerialSource, SetPointSource};
use firmware::protocol;
use model_core::{Builtin, ConfigError, Inputs, Model, Profile, MEASURED};

/// UART speed of the serial stream.
const BAUD: u32 = 115_200;
/// Send every 10th step: 14 channels at 100 Hz fit 115200 baud.
const OUTPUT_EVERY: u32 = 10;
/// Core cycles per microsecond.
const CYCLES_PER_US: u32 = board::SYSCLK_HZ / 1_000_000;

/// Cycles per tick, shared with the SysTick handler's clock.
static PERIOD: core::sync::atomic::AtomicU32 =
    core::sync::atomic::AtomicU32::new(CYCLES_PER_US * firmware::STEP_US);

fn period() -> u32 {
    PERIOD.load(core::sync::atomic::Ordering::Relaxed)
}

/// The step-timing clock: SysTick-derived under QEMU (no DWT there), DWT on hardware.
#[cfg(feature = "qemu")]
fn step_clock(_cp: &mut cortex_m::Peripherals) -> impl CycleCounter {
    clock::SysTickCycles::new(period())
}
#[cfg(feature = "rtt")]
fn step_clock(cp: &mut cortex_m::Peripherals) -> impl CycleCounter {
    clock::DwtCycles::start(&mut cp.DCB, &mut cp.DWT)
}

/// The same counter, for the SysTick handler.
fn isr_clock() -> impl CycleCounter {
    #[cfg(feature = "qemu")]
    {
        clock::SysTickCycles::new(period())
    }
    #[cfg(feature = "rtt")]
    {
        struct Dwt;
        impl CycleCounter for Dwt {
            fn cycles(&self) -> u32 {
                cortex_m::peripheral::DWT::cycle_count()
            }
        }
        Dwt
    }
}

/// Basic mode or XiL, chosen at start.
// One instance, living in `main`'s frame for the whole run; no heap to box into.
#[allow(clippy::large_enum_variant)]
enum Source {
    Profile(ProfileSource),
    Serial(SerialSource<UartRx>),
}

impl SetPointSource for Source {
    fn next_inputs(&mut self, t_us: u64) -> Option<Inputs> {
        match self {
            Source::Profile(s) => s.next_inputs(t_us),
            Source::Serial(s) => s.next_inputs(t_us),
        }
    }
}

#[entry]
fn main() -> ! {
    firmware::paint_stack();
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        defmt::panic!("core peripherals taken twice");
    };
    let (profile, xil, tick_us) = options();
    PERIOD.store(CYCLES_PER_US * tick_us, core::sync::atomic::Ordering::Relaxed);

    // The model is used where it was built: moving it out of the `Result` would cost
    // a second copy of its ~3.4 KB on the stack.
    let mut built = build_model();
    let model = match &mut built {
        Ok(m) => m,
        Err(e) => defmt::panic!("model config rejected: {}", e),
    };
    serve(model, &mut cp, profile, xil, tick_us)
}

/// Profile, XiL mode and tick [µs] of this run: the build's, or the QEMU command
/// line's (its buffer lives in this frame only, not under the model's construction).
#[inline(never)]
fn options() -> (Builtin, bool, u32) {
    let mut args = [0u8; 160];
    let args = firmware::qemu_cmdline(&mut args);
    let profile =
        firmware::option(args, "profile").and_then(Builtin::from_name).unwrap_or(firmware::BUILD_PROFILE);
    let xil = match firmware::option(args, "mode") {
        Some("xil") => true,
        Some("profile") => false,
        _ => cfg!(feature = "xil"),
    };
    let tick_us = firmware::option(args, "tick_us")
        .and_then(|v| v.parse::<u32>().ok())
        .filter(|v| (5..=100_000).contains(v))
        .unwrap_or(firmware::STEP_US);
    (profile, xil, tick_us)
}

/// The model of this build. Its own frame holds the construction's temporaries, gone
/// before [`serve`]'s buffers exist: the stack peaks here (with `SideDisc::new` below).
#[inline(never)]
fn build_model() -> Result<Model<'static, firmware::Scalar>, ConfigError> {
    firmware::new_model(&firmware::config(firmware::BUILD_RATES))
}

/// Set up the I/O, run the loop, report, exit.
#[inline(never)]
fn serve(
    model: &mut Model<'static, firmware::Scalar>,
    cp: &mut cortex_m::Peripherals,
    profile: Builtin,
    xil: bool,
    tick_us: u32,
) -> ! {
    defmt::info!(
        "simrod firmware: step {=u32} us, tick {=u32} us, rates {}, effects file {=str}",
        firmware::STEP_US,
        tick_us,
        firmware::BUILD_RATES,
        if firmware::BUILD_EFFECTS_FILE.is_empty() { "(none)" } else { firmware::BUILD_EFFECTS_FILE }
    );

    let (tx, rx) = board::uart0(BAUD);
    let mut status = board::StatusLed::new();
    let mut sink = SerialSink::new(tx, MEASURED);
    let mut source = if xil {
        defmt::info!("XiL mode: set points from UART0");
        Source::Serial(SerialSource::new(rx, firmware::SUPPLY_V))
    } else {
        let p = match Profile::builtin(profile, 1.0, 1.0) {
            Ok(p) => p,
            Err(e) => defmt::panic!("profile: {}", e),
        };
        defmt::info!("basic mode: profile {}", profile);
        Source::Profile(ProfileSource::new(p, firmware::SUPPLY_V))
    };

    let clk = step_clock(cp);
    clock::start_tick(&mut cp.SYST, period());
    let loop_cfg =
        LoopConfig { period_cycles: period(), late_budget_cycles: period() / 10, output_every: OUTPUT_EVERY };
    let stats = bench::run(model, &mut source, &mut sink, &mut status, &clk, &loop_cfg);
    cp.SYST.disable_interrupt();
    let mean = (stats.total_step_cycles / u64::from(stats.steps.max(1))) as u32;
    let (received, rejected) = match &source {
        Source::Serial(s) => (s.frames, s.rejected()),
        Source::Profile(_) => (0, 0),
    };
    defmt::info!(
        "done: {=u32} steps, {=u32} late, {=u32} overruns, {=u32} missed ticks, step mean {=u32} / max {=u32} cycles, max latency {=u32} cycles, {=u32} frames dropped",
        stats.steps,
        stats.late,
        stats.overruns,
        stats.missed_ticks,
        mean,
        stats.max_step_cycles,
        stats.max_latency_cycles,
        sink.dropped
    );
    let fields: [u32; protocol::STATS_FIELDS.len()] = [
        stats.steps,
        stats.late,
        stats.overruns,
        stats.missed_ticks,
        mean,
        stats.max_step_cycles,
        stats.max_latency_cycles,
        loop_cfg.period_cycles,
        sink.dropped,
        received,
        rejected,
        firmware::stack_high_water(),
    ];
    let mut payload = [0u8; 4 * protocol::STATS_FIELDS.len()];
    for (d, v) in payload.chunks_exact_mut(4).zip(fields) {
        d.copy_from_slice(&v.to_le_bytes());
    }
    if !sink.send_now(protocol::KIND_STATS, &payload) {
        defmt::panic!("statistics frame does not fit");
    }
    firmware::exit(true)
}

#[exception]
fn SysTick() {
    clock::on_tick(&isr_clock());
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    defmt::error!("hard fault at pc {=u32:#x}", ef.pc());
    firmware::exit(false)
}
