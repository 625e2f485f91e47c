//! Every limit evaluated on every step of one run, online: no run is held in memory,
//! only each limit's worst point and its margin over time in [`BINS`] time bins (what
//! the HTML page draws).

use model_core::drivetrain::SideParams;
use model_core::{Config, Outputs};

use crate::limits::{Limit, Rule};
use crate::quantity::{Dynamics, Estimator};
use crate::run::{Scales, StepSink, TestRun};

/// Time bins of a margin trace.
pub const BINS: usize = 1200;

/// One limit over one run.
#[derive(Debug, Clone, PartialEq)]
pub struct LimitRun {
    /// [unit] smallest margin: the distance to the limit, negative beyond it.
    pub margin: f64,
    /// [unit] the value there (a thermal limit: the equivalent continuous value).
    pub peak: f64,
    /// [s] when (end of the step).
    pub t_s: f64,
    /// Beyond the bound longer than its `for_s`, or heated beyond the rating.
    pub crossed: bool,
    /// [s] the first time beyond the bound, if ever.
    pub first_beyond_s: Option<f64>,
    /// [s] the longest stretch beyond the bound.
    pub longest_beyond_s: f64,
    /// [unit] the smallest margin in each of [`BINS`] equal time bins.
    pub trace: Vec<f32>,
}

/// How a limit is judged, unpacked once so the step does not re-read the rule.
#[derive(Debug, Clone, Copy)]
enum Judge {
    /// Bounds (±∞ where absent) and the time allowed beyond them.
    Bound { min: f64, max: f64, allowed_s: f64 },
    /// Rating and the exact per-step heating weight `1 − e^{−dt/τ}`.
    Thermal { rated: f64, decay: f64 },
}

/// The per-limit state of a run.
#[derive(Debug, Clone)]
struct State {
    est: Estimator,
    judge: Judge,
    /// [unit] how far beyond counts as at the limit ([`AT_LIMIT`] of its size).
    tol: f64,
    run: LimitRun,
    /// [s] the current stretch beyond the bound.
    beyond_s: f64,
    /// Per-unit heating state of a thermal rule.
    heat: f64,
    /// Smallest margin in the current time bin.
    bin_min: f64,
}

/// Evaluates limits step by step.
#[derive(Debug, Clone)]
pub struct Monitor {
    states: Vec<State>,
    dt_s: f64,
    total_steps: u64,
    k: u64,
    /// The current time bin and the step that starts the next.
    bin: usize,
    next_bin_at: u64,
}

impl Monitor {
    /// For `limits` on a run of `total_steps` steps of `dt_us`.
    pub fn new(limits: &[Limit], dynamics: &Dynamics, dt_us: u32, total_steps: u64) -> Self {
        let dt_s = f64::from(dt_us) * 1e-6;
        let states = limits
            .iter()
            .map(|l| {
                let (judge, heat) = match l.rule {
                    Rule::Bound { min, max, for_s } => (
                        Judge::Bound {
                            min: min.unwrap_or(f64::NEG_INFINITY),
                            max: max.unwrap_or(f64::INFINITY),
                            allowed_s: for_s,
                        },
                        0.0,
                    ),
                    Rule::Thermal { rated, tau_s, initial } => {
                        (Judge::Thermal { rated, decay: 1.0 - (-dt_s / tau_s).exp() }, initial)
                    }
                };
                State {
                    est: Estimator::new(l.quantity, dt_s, dynamics),
                    judge,
                    tol: AT_LIMIT * l.size(),
                    run: LimitRun {
                        margin: f64::INFINITY,
                        peak: f64::NAN,
                        t_s: 0.0,
                        crossed: false,
                        first_beyond_s: None,
                        longest_beyond_s: 0.0,
                        trace: vec![f32::NAN; BINS],
                    },
                    beyond_s: 0.0,
                    heat,
                    bin_min: f64::INFINITY,
                }
            })
            .collect();
        let total_steps = total_steps.max(1);
        let mut m = Self { states, dt_s, total_steps, k: 0, bin: 0, next_bin_at: 0 };
        m.next_bin_at = m.bin_start(1);
        m
    }

    /// The first step of time bin `b`.
    fn bin_start(&self, b: usize) -> u64 {
        (b as u64 * self.total_steps).div_ceil(BINS as u64)
    }

    /// One step's outputs.
    pub fn step(&mut self, o: &Outputs) {
        if self.k >= self.next_bin_at && self.bin + 1 < BINS {
            self.flush_bin();
            self.bin += 1;
            while self.bin + 1 < BINS && self.k >= self.bin_start(self.bin + 1) {
                self.bin += 1;
            }
            self.next_bin_at = self.bin_start(self.bin + 1);
        }
        self.k += 1;
        let (t_s, dt_s) = (o.t_s(), self.dt_s);
        for s in &mut self.states {
            let (lo, hi) = s.est.step(o);
            let (margin, value) = match s.judge {
                Judge::Bound { min, max, .. } => {
                    let (above, below) = (max - hi, lo - min);
                    if above <= below {
                        (above, hi)
                    } else {
                        (below, lo)
                    }
                }
                Judge::Thermal { rated, decay } => {
                    let u = lo.abs().max(hi.abs()) / rated;
                    s.heat += (u * u - s.heat) * decay;
                    let eq = rated * s.heat.max(0.0).sqrt();
                    (rated - eq, eq)
                }
            };
            s.observe(margin, value, t_s, dt_s);
        }
    }

    fn flush_bin(&mut self) {
        let b = self.bin;
        for s in &mut self.states {
            if let Some(x) = s.run.trace.get_mut(b) {
                *x = s.bin_min as f32;
            }
            s.bin_min = f64::INFINITY;
        }
    }

    /// The runs' results, one per limit in the limits' order. Bins no step fell in
    /// (runs shorter than [`BINS`] steps) take the previous bin's margin.
    pub fn finish(mut self) -> Vec<LimitRun> {
        self.flush_bin();
        self.states
            .into_iter()
            .map(|mut s| {
                let mut last = f32::NAN;
                for b in &mut s.run.trace {
                    if b.is_finite() {
                        last = *b;
                    } else {
                        *b = last;
                    }
                }
                s.run
            })
            .collect()
    }
}

/// Run `test` once with `config` and `scales` and evaluate `limits` on it; also gives
/// the model's dynamics (for the flange mode's step check).
pub fn evaluate(
    test: &dyn TestRun,
    limits: &[Limit],
    config: &Config,
    scales: Scales,
) -> Result<(Vec<LimitRun>, Dynamics), String> {
    struct Sink<'a> {
        limits: &'a [Limit],
        dt_us: u32,
        steps: u64,
        monitor: Option<(Monitor, Dynamics)>,
    }
    impl StepSink for Sink<'_> {
        fn begin(&mut self, sides: &[SideParams; 2]) {
            let d = Dynamics::of(sides);
            self.monitor = Some((Monitor::new(self.limits, &d, self.dt_us, self.steps), d));
        }
        fn step(&mut self, o: &Outputs) {
            if let Some((m, _)) = &mut self.monitor {
                m.step(o);
            }
        }
    }
    let steps = test.duration_us().div_ceil(u64::from(config.dt_us.max(1)));
    let mut sink = Sink { limits, dt_us: config.dt_us, steps, monitor: None };
    test.run(config, scales, &mut sink)?;
    let (m, d) = sink.monitor.ok_or("the run never started")?;
    Ok((m.finish(), d))
}

/// Relative distance to a limit that counts as at it, not beyond: the f32 rounding of a
/// channel held at its limit (a motor at its 2100 rpm speed limit reads 2100.0002).
pub const AT_LIMIT: f64 = 1e-5;

impl State {
    #[inline]
    fn observe(&mut self, margin: f64, value: f64, t_s: f64, dt_s: f64) {
        self.bin_min = self.bin_min.min(margin);
        let r = &mut self.run;
        if margin < r.margin || r.peak.is_nan() {
            r.margin = margin;
            r.peak = value;
            r.t_s = t_s;
        }
        if margin >= -self.tol {
            self.beyond_s = 0.0;
            return;
        }
        r.first_beyond_s.get_or_insert(t_s);
        self.beyond_s += dt_s;
        r.longest_beyond_s = r.longest_beyond_s.max(self.beyond_s);
        let allowed = match self.judge {
            Judge::Bound { allowed_s, .. } => allowed_s,
            Judge::Thermal { .. } => 0.0,
        };
        // Half a step of slack: `for_s` counted in whole steps is not cut by rounding.
        if allowed == 0.0 || self.beyond_s > allowed + 0.5 * dt_s {
            r.crossed = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::parse_limits;
    use model_core::Channel;

    fn dyn_() -> Dynamics {
        Dynamics { j_f: [0.0023; 2], omega_h: [12_350.0; 2] }
    }

    fn run(text: &str, values: &[f32], dt_us: u32) -> LimitRun {
        let l = parse_limits(text, "t.toml").unwrap();
        let mut m = Monitor::new(&l.limits, &dyn_(), dt_us, values.len() as u64);
        for (k, v) in values.iter().enumerate() {
            let mut o = Outputs { t_us: (k as u64 + 1) * u64::from(dt_us), ..Outputs::default() };
            o.values[Channel::IDpu27 as usize] = *v;
            m.step(&o);
        }
        m.finish().remove(0)
    }

    const BOUND: &str =
        "[[limit]]\nid = \"i\"\nquantity = \"I_DPU 2.7\"\nunit = \"A\"\nmax = 10\nmin = -4\norigin = \"o\"\n";

    #[test]
    fn bound_reports_peak_time_and_margin() {
        let r = run(BOUND, &[1.0, 4.0, 12.0, 3.0, -7.0, 0.0], 1000);
        assert_eq!((r.margin, r.peak, r.t_s), (-3.0, -7.0, 0.005));
        assert!(r.crossed);
        assert_eq!(r.first_beyond_s, Some(0.003));
        assert!((r.longest_beyond_s - 0.001).abs() < 1e-12);
        let ok = run(BOUND, &[1.0, 10.0, -4.0], 1000);
        assert_eq!((ok.margin, ok.crossed), (0.0, false), "at the limit is inside");
    }

    #[test]
    fn time_at_level_allows_short_excursions() {
        let t = BOUND.replace("min = -4\n", "for_s = 0.003\n");
        let short = run(&t, &[11.0, 11.0, 11.0, 0.0, 11.0], 1000);
        assert!(!short.crossed && short.margin == -1.0, "{short:?}");
        let long = run(&t, &[11.0, 11.0, 11.0, 11.0, 0.0], 1000);
        assert!(long.crossed && (long.longest_beyond_s - 0.004).abs() < 1e-12, "{long:?}");
    }

    #[test]
    fn thermal_state_follows_the_first_order_law() {
        // A constant load at twice the rating heats as 4 (1 − e^{−t/τ}): the state reaches
        // 1 (the equivalent continuous value the rating) at t = τ ln(4/3).
        let t = "[[limit]]\nid = \"h\"\nquantity = \"I_DPU 2.7\"\nunit = \"A\"\n\
                 thermal = { rated = 10, tau_s = 2 }\norigin = \"o\"\n";
        let n = 1000; // 1 s at 1 ms
        let r = run(t, &vec![20.0; n], 1000);
        let want = 10.0 * (4.0 * (1.0 - (-1.0f64 / 2.0).exp())).sqrt();
        assert!((r.peak - want).abs() < 1e-9, "{} vs {want}", r.peak);
        assert!(r.crossed);
        let cross = 2.0 * (4.0f64 / 3.0).ln();
        assert!((r.first_beyond_s.unwrap() - cross).abs() < 1.5e-3, "{:?} vs {cross}", r.first_beyond_s);
        assert_eq!(r.trace.len(), BINS);
    }
}
