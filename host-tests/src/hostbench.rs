//! Host timing of the twin: one `Model::step` at a fixed operating point, and whole
//! TP07 runs (profile + step) at 1 ms and 100 µs, on one thread. Used by
//! `cargo bench -p host-tests --bench step` and `cargo xtask bench-rt`; numbers are only
//! meaningful from an optimised build.
//!
//! Two numbers per case, because this machine is shared: the **median** over
//! repetitions (what a run took here and now) and an **undisturbed** estimate. Other
//! processes only ever add time, and a short interval is rarely interrupted, so every
//! run is timed in segments of [`SEGMENT`] steps (well under a scheduler time slice);
//! the undisturbed time is the sum over segments of each segment's fastest repetition.

use std::hint::black_box;
use std::time::Instant;

use model_core::{
    Builtin, Config, CouplingStiffness, Effects, Inputs, Model, Params, Profile, RateSet, SetPoints,
    Simulation, SpeedTarget,
};

/// Steps per timed segment (~0.3 ms).
pub const SEGMENT: u64 = 2000;

/// One measured case.
#[derive(Debug, Clone)]
pub struct HostCase {
    /// What was timed.
    pub name: String,
    /// Model step [µs].
    pub dt_us: u32,
    /// Steps per repetition.
    pub steps: u64,
    /// Repetitions timed.
    pub reps: usize,
    /// Median over the repetitions [ns per step].
    pub ns_median: f64,
    /// Undisturbed estimate: per segment the fastest repetition, summed [ns per step].
    pub ns_min: f64,
}

impl HostCase {
    /// Steps per second at the median.
    pub fn steps_per_s(&self) -> f64 {
        1e9 / self.ns_median
    }

    /// Real-time factor at the median: simulated time per wall time.
    pub fn rt_factor(&self) -> f64 {
        f64::from(self.dt_us) * 1e3 / self.ns_median
    }

    /// Steps per second, undisturbed.
    pub fn steps_per_s_min(&self) -> f64 {
        1e9 / self.ns_min
    }

    /// Real-time factor, undisturbed.
    pub fn rt_factor_min(&self) -> f64 {
        f64::from(self.dt_us) * 1e3 / self.ns_min
    }
}

/// The firmware's configuration at step `dt_us`.
pub fn config(dt_us: u32) -> Config {
    Config {
        dt_us,
        params: Params::thesis(RateSet::Identified, CouplingStiffness::Identified),
        speed_target: SpeedTarget::Map,
        effects: Effects::NONE,
    }
}

/// Time `reps` repetitions of a run (after one warm-up) in segments: `run` calls
/// `lap()` after every [`SEGMENT`] steps and at its end, and returns its step count.
fn case(name: &str, dt_us: u32, reps: usize, mut run: impl FnMut(&mut dyn FnMut()) -> u64) -> HostCase {
    let mut one = || {
        let mut laps = Vec::new();
        let mut t = Instant::now();
        let steps = run(&mut || {
            let now = Instant::now();
            laps.push((now - t).as_nanos() as f64);
            t = now;
        });
        (steps, laps)
    };
    let (steps, _) = one();
    let runs: Vec<Vec<f64>> = (0..reps).map(|_| one().1).collect();
    let n = steps.max(1) as f64;
    let totals: Vec<f64> = runs.iter().map(|l| l.iter().sum::<f64>() / n).collect();
    let segments = runs.iter().map(Vec::len).min().unwrap_or(0);
    let fastest: f64 =
        (0..segments).map(|i| runs.iter().map(|l| l[i]).fold(f64::INFINITY, f64::min)).sum::<f64>() / n;
    HostCase {
        name: name.to_string(),
        dt_us,
        steps,
        reps,
        ns_median: simrod_numerics::stats::median(&totals).unwrap_or(f64::NAN),
        ns_min: fastest,
    }
}

/// A whole TP07 run at `dt_us`, lapping every [`SEGMENT`] steps: the steps taken.
fn tp07_run(dt_us: u32, lap: &mut dyn FnMut()) -> u64 {
    let profile = Profile::builtin(Builtin::TP07, 1.0, 1.0).expect("TP07");
    let sim = Simulation::new(&config(dt_us), profile, 24.0).expect("valid config");
    let mut n = 0u64;
    for o in sim {
        black_box(&o);
        n += 1;
        if n.is_multiple_of(SEGMENT) {
            lap();
        }
    }
    if !n.is_multiple_of(SEGMENT) {
        lap();
    }
    n
}

/// The fixed operating point of the single-step case: mid throttle, both loads
/// regenerating, settled for 5 s.
fn fixed_point() -> (Model<'static>, Inputs) {
    let mut model = Model::new(&config(1000)).expect("valid config");
    let inputs = Inputs { sp: SetPoints { throttle_pct: 60.0, load_pct: [20.0, 20.0] }, supply_v: 24.0 };
    for _ in 0..5000 {
        black_box(model.step(&inputs));
    }
    (model, inputs)
}

/// `n` steps at the fixed operating point (for counting instructions): the last
/// output's bits of the motor speed.
pub fn fixed_point_steps(n: u64) -> u32 {
    let (mut model, inputs) = fixed_point();
    let mut last = 0;
    for _ in 0..n {
        last = black_box(model.step(black_box(&inputs))).values[1].to_bits();
    }
    last
}

/// Run the cases; `quick` takes fewer repetitions.
pub fn run(quick: bool) -> Vec<HostCase> {
    let reps = |full: usize| if quick { (full / 3).max(3) } else { full };

    let (mut model, inputs) = fixed_point();
    // 50 segments of one step each repetition's worth: 100 000 steps.
    let step = case("Model::step (60 % throttle, 20 % loads)", 1000, reps(15), |lap| {
        for _ in 0..50 {
            for _ in 0..SEGMENT {
                black_box(model.step(black_box(&inputs)));
            }
            lap();
        }
        50 * SEGMENT
    });
    let tp07 = case("TP07 run, profile + step, dt 1 ms", 1000, reps(15), |lap| tp07_run(1000, lap));
    let tp07_100 = case("TP07 run, profile + step, dt 100 us", 100, reps(6), |lap| tp07_run(100, lap));
    vec![step, tp07, tp07_100]
}

/// The cases as a text table.
pub fn table(cases: &[HostCase]) -> String {
    let mut s = format!(
        "{:<40} {:>7} | {:>8} {:>9} {:>9} | {:>8} {:>9} {:>9}\n",
        "host case (one thread)", "dt", "median", "steps/s", "RT", "undist.", "steps/s", "RT"
    );
    for c in cases {
        s.push_str(&format!(
            "{:<40} {:>5}us | {:>6.1}ns {:>8.2}M {:>8.0}x | {:>6.1}ns {:>8.2}M {:>8.0}x\n",
            c.name,
            c.dt_us,
            c.ns_median,
            c.steps_per_s() / 1e6,
            c.rt_factor(),
            c.ns_min,
            c.steps_per_s_min() / 1e6,
            c.rt_factor_min()
        ));
    }
    s.push_str(&format!(
        "(median over repetitions as loaded now; undisturbed = per {SEGMENT}-step segment the fastest \
         repetition, summed)\n"
    ));
    s
}
