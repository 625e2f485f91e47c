//! The real-time loop: one step per bench tick, with overrun detection.
//!
//! Each step's start latency (from its tick's edge) and duration are measured with the
//! board's cycle counter. A step that starts late (a missed tick, or later than the
//! budget after its edge) or overruns (the next tick came before it finished) is
//! counted, raises the status pin until the next clean step, and is logged. The loop
//! keeps the fixed rate: at most one step per tick, missed ticks are dropped, never
//! caught up in a burst (the model's time then lags wall time by the dropped ticks,
//! which the counters report).

use embedded_hal::digital::OutputPin;
use model_core::{Model, Outputs};

use crate::clock::{self, CycleCounter};
use crate::io::{OutputSink, SetPointSource};
use crate::step::simrod_step;
use crate::Scalar;

/// Timing of the loop.
#[derive(Debug, Clone, Copy)]
pub struct LoopConfig {
    /// Cycles per tick (one model step).
    pub period_cycles: u32,
    /// A step starting more than this after its tick's edge is late.
    pub late_budget_cycles: u32,
    /// Send every n-th step's outputs (link bandwidth).
    pub output_every: u32,
}

/// What the loop measured.
#[derive(Debug, Clone, Copy, Default, defmt::Format)]
pub struct Stats {
    /// Steps run.
    pub steps: u32,
    /// Steps that started late.
    pub late: u32,
    /// Steps that ran past the next tick.
    pub overruns: u32,
    /// Ticks dropped (no step ran for them).
    pub missed_ticks: u32,
    /// Longest step, input to output queued [cycles].
    pub max_step_cycles: u32,
    /// Longest start latency after the tick's edge [cycles].
    pub max_latency_cycles: u32,
    /// Sum of step durations [cycles], for the mean.
    pub total_step_cycles: u64,
}

/// Log the first events in full, then one in 1024, so a persistent overrun cannot
/// flood the log link (which would itself make every step late).
fn worth_logging(events: u32) -> bool {
    events <= 16 || events & 1023 == 0
}

/// Run until the source ends. SysTick must already be running with `cfg.period_cycles`
/// and its handler calling [`clock::on_tick`].
pub fn run<S, O, P, C>(
    model: &mut Model<'static, Scalar>,
    source: &mut S,
    sink: &mut O,
    status: &mut P,
    clock: &C,
    cfg: &LoopConfig,
) -> Stats
where
    S: SetPointSource,
    O: OutputSink,
    P: OutputPin,
    C: CycleCounter,
{
    let mut stats = Stats::default();
    let mut out = Outputs::zero();
    let mut expected = clock::ticks().wrapping_add(1);
    let mut flagged = false;
    let mut events = 0u32; // steps flagged late or overrun
    loop {
        // Idle until the tick, sending queued output bytes meanwhile. The check and the
        // WFI run with interrupts masked: a tick in between still wakes the WFI.
        // The sink is polled at least once per step, so output keeps flowing (as far
        // as the link takes it without blocking) even when steps overrun.
        loop {
            let queued = sink.poll();
            let now = clock::ticks();
            if now.wrapping_sub(expected) as i32 >= 0 {
                break;
            }
            if !queued {
                cortex_m::interrupt::free(|_| {
                    if clock::ticks() == now {
                        cortex_m::asm::wfi();
                    }
                });
            }
        }
        // Latest tick, its edge and the start, read with no tick in between (the
        // handler runs to completion, so an unchanged count means a consistent set).
        let (tick, edge, start) = loop {
            let t = clock::ticks();
            let e = clock::tick_edge();
            let s = clock.cycles();
            if clock::ticks() == t {
                break (t, e, s);
            }
        };
        let missed = tick.wrapping_sub(expected);
        // From the edge of the tick this step was due at.
        let latency = start.wrapping_sub(edge).wrapping_add(missed.wrapping_mul(cfg.period_cycles));

        let Some(inputs) = source.next_inputs(model.t_us()) else {
            break;
        };
        simrod_step(model, &inputs, &mut out);
        if stats.steps % cfg.output_every.max(1) == 0 {
            sink.push(&out);
        }

        let dur = clock.cycles().wrapping_sub(start);
        let overran = clock::ticks() != tick;
        let late = missed > 0 || latency > cfg.late_budget_cycles;
        stats.steps = stats.steps.wrapping_add(1);
        stats.missed_ticks = stats.missed_ticks.wrapping_add(missed);
        stats.total_step_cycles += u64::from(dur);
        stats.max_step_cycles = stats.max_step_cycles.max(dur);
        stats.max_latency_cycles = stats.max_latency_cycles.max(latency);
        if late || overran {
            stats.late = stats.late.wrapping_add(u32::from(late));
            stats.overruns = stats.overruns.wrapping_add(u32::from(overran));
            events = events.wrapping_add(1);
            if !flagged {
                let _ = status.set_high();
                flagged = true;
            }
            if worth_logging(events) {
                defmt::warn!(
                    "step {}: late={} overrun={} latency={} cycles, duration={} cycles, missed {} ticks",
                    stats.steps.wrapping_sub(1),
                    late,
                    overran,
                    latency,
                    dur,
                    missed
                );
            }
        } else if flagged {
            let _ = status.set_low();
            flagged = false;
        }
        // The next step serves the next tick; ticks missed meanwhile are dropped.
        expected = tick.wrapping_add(1);
    }
    while sink.poll() {}
    stats
}
