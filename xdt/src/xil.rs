//! The closed XiL loop: the bench twin (model-core), the xDT, and the RT platform
//! between them, which samples the bench every `loop_dt` and delivers the set points
//! computed from a sample `loop_delay` later (held between samples). One no_std
//! implementation, run by the host (`simrod xil`) and by the firmware (`simrod-xil`),
//! so both compute the same bits.

use model_core::{Config, ConfigError, Inputs, Maps, Model, Outputs, Params, SetPoints};

use crate::cycle::{Cycle, Route};
use crate::data as d;
use crate::vehicle::Vehicle;
use crate::xdt::{XdtConfig, XdtError, XdtSignals, XdtState, XdtTuning};

/// Most steps of loop delay the delay line holds: 250 ms at the bench's 1 ms (3 KB).
pub const DELAY_CAPACITY: usize = 250;

/// The loop's parameters; defaults from `data/xil.toml`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopParams {
    /// [ms] loop delay: set points computed from a sample reach the bench this much later.
    pub loop_delay_ms: f32,
    /// [ms] the xDT's sample time, a whole multiple of the twin's step.
    pub loop_dt_ms: f32,
    pub tuning: XdtTuning,
}

impl Default for LoopParams {
    fn default() -> Self {
        Self {
            loop_delay_ms: d::XIL_LOOP_DELAY_MS,
            loop_dt_ms: d::XIL_LOOP_DT_MS,
            tuning: XdtTuning {
                kp: d::XIL_DRIVER_KP_PCT_PER_KMH,
                ki: d::XIL_DRIVER_KI_PCT_PER_KMH_S,
                preview_s: d::XIL_DRIVER_PREVIEW_S,
                stop_mps: d::XIL_DRIVER_STOP_KMH / 3.6,
                torque_filter_hz: d::XIL_TORQUE_FILTER_HZ,
                bench_speed_margin: d::XIL_BENCH_SPEED_MARGIN,
                friction_compensation: d::XIL_FRICTION_COMPENSATION,
            },
        }
    }
}

/// Why a loop cannot be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum XilError {
    /// The twin's configuration.
    Model(ConfigError),
    /// The xDT's.
    Xdt(XdtError),
    /// The loop's timing: what is wrong.
    Timing(&'static str),
}

/// The loop's timing in twin steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Timing {
    /// Twin steps between two samples of the xDT (>= 1).
    pub period: u32,
    /// Twin steps from a sample to the step its set points first act in
    /// (0..=[`DELAY_CAPACITY`]).
    pub delay: u32,
}

impl Timing {
    /// From milliseconds, at a twin step of `dt_us`: both must be whole steps.
    pub fn from_ms(loop_dt_ms: f32, loop_delay_ms: f32, dt_us: u32) -> Result<Self, &'static str> {
        let steps = |ms: f32| -> Option<u32> {
            let s = f64::from(ms) * 1000.0 / f64::from(dt_us);
            let n = (s + 0.5) as u32;
            (s.is_finite() && s >= 0.0 && (s - f64::from(n)).abs() < 1e-6).then_some(n)
        };
        let period =
            steps(loop_dt_ms).ok_or("the loop's sample time must be a whole number of twin steps")?;
        let delay = steps(loop_delay_ms).ok_or("the loop delay must be a whole number of twin steps")?;
        Self::new(period, delay)
    }

    /// Checked: a period of at least one step, a delay the line holds.
    pub fn new(period: u32, delay: u32) -> Result<Self, &'static str> {
        if period == 0 {
            return Err("the loop's sample time must be at least one twin step");
        }
        if delay as usize > DELAY_CAPACITY {
            return Err("the loop delay exceeds the delay line (250 twin steps)");
        }
        Ok(Self { period, delay })
    }
}

/// One step of the closed loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct XilOutputs {
    /// The bench's channels.
    pub bench: Outputs,
    /// The xDT's last sample.
    pub xdt: XdtSignals,
    /// The set points the xDT computed at its last sample (the bench gets them
    /// `delay` steps later: `bench`'s `Throttle_sp`, `Load_L_sp`, `Load_R_sp`).
    pub computed: SetPoints,
}

/// Names of [`XilOutputs::signals`], in order (the firmware's trace streams these bits).
pub const SIGNALS: [&str; 13] = [
    "v [m/s]",
    "target [m/s]",
    "cycle [m/s]",
    "distance [m]",
    "grade [%]",
    "slope sine [-]",
    "road torque [N m]",
    "acceleration [m/s^2]",
    "load torque L [N m]",
    "load torque R [N m]",
    "computed throttle [%]",
    "computed load L [%]",
    "computed load R [%]",
];

impl XilOutputs {
    /// The xDT's values of the step, in [`SIGNALS`] order.
    pub fn signals(&self) -> [f32; SIGNALS.len()] {
        let x = &self.xdt;
        let c = &self.computed;
        [
            x.v_mps,
            x.target_mps,
            x.cycle_mps,
            x.distance_m,
            x.slope.pct,
            x.slope.sin,
            x.road_torque_nm,
            x.accel_mps2,
            x.load_torque_nm[0],
            x.load_torque_nm[1],
            c.throttle_pct,
            c.load_pct[0],
            c.load_pct[1],
        ]
    }
}

/// Twin + xDT + delay line, stepped at the twin's rate.
#[derive(Debug, Clone)]
pub struct XilLoop<'a> {
    model: Model<'a>,
    xdt: XdtConfig<'a>,
    state: XdtState,
    timing: Timing,
    supply_v: f32,
    end_us: u64,
    /// Set points in flight, a ring: `line[write]` is the newest.
    line: [SetPoints; DELAY_CAPACITY + 1],
    write: usize,
    /// Twin steps since the last sample.
    phase: u32,
    held: SetPoints,
    /// The last step's outputs; the bench's are what the next sample reads.
    out: XilOutputs,
}

impl XilLoop<'static> {
    /// On the built-in maps, vehicle and loop parameters, for a built-in cycle.
    pub fn builtin(cfg: &Config, cycle: Cycle, timing: Timing, supply_v: f32) -> Result<Self, XilError> {
        XilLoop::new(
            cfg,
            Maps::builtin(),
            &Vehicle::default(),
            &LoopParams::default().tuning,
            cycle.route(),
            timing,
            supply_v,
        )
    }
}

impl<'a> XilLoop<'a> {
    /// The loop of a twin with `cfg` on `maps`, the xDT of `vehicle` with `tuning` on
    /// `route`, the RT platform's `timing`, supply `supply_v` [V].
    pub fn new(
        cfg: &Config,
        maps: Maps<'a>,
        vehicle: &Vehicle,
        tuning: &XdtTuning,
        route: Route<'a>,
        timing: Timing,
        supply_v: f32,
    ) -> Result<Self, XilError> {
        let timing = Timing::new(timing.period, timing.delay).map_err(XilError::Timing)?;
        let model = Model::with_maps(cfg, maps).map_err(XilError::Model)?;
        let dt = (f64::from(cfg.dt_us) * 1e-6 * f64::from(timing.period)) as f32;
        let params: Params = *model.params();
        let xdt = XdtConfig::new(vehicle, tuning, route, &maps, &params, dt).map_err(XilError::Xdt)?;
        Ok(Self {
            model,
            xdt,
            state: XdtState::default(),
            timing,
            supply_v,
            end_us: route.duration_us(),
            line: [SetPoints::default(); DELAY_CAPACITY + 1],
            write: 0,
            phase: 0,
            held: SetPoints::default(),
            out: XilOutputs {
                bench: Outputs::default(),
                xdt: XdtSignals::default(),
                computed: SetPoints::default(),
            },
        })
    }

    /// One twin step: a sample of the xDT when one is due, the delay line, the twin.
    /// `None` once the cycle is over. The outputs stay in the loop (no copy of the
    /// channels per step on the target); [`Iterator`] hands out copies.
    #[inline]
    pub fn step(&mut self) -> Option<&XilOutputs> {
        let t_us = self.model.t_us();
        if t_us >= self.end_us {
            return None;
        }
        if self.phase == 0 {
            let t_s = t_us as f32 * 1e-6;
            (self.held, self.out.xdt) = self.state.step(&self.xdt, t_s, &self.out.bench);
            self.out.computed = self.held;
        }
        self.phase += 1;
        if self.phase >= self.timing.period {
            self.phase = 0;
        }
        // The ring: write the newest, read the one `delay` steps older.
        let n = self.line.len();
        if let Some(slot) = self.line.get_mut(self.write) {
            *slot = self.held;
        }
        let back = self.timing.delay as usize;
        let read = if self.write >= back { self.write - back } else { self.write + n - back };
        let applied = self.line.get(read).copied().unwrap_or_default();
        self.write += 1;
        if self.write >= n {
            self.write = 0;
        }
        self.out.bench = self.model.step(&Inputs { sp: applied, supply_v: self.supply_v });
        Some(&self.out)
    }

    /// The last step's outputs.
    pub fn outputs(&self) -> &XilOutputs {
        &self.out
    }

    /// Number of twin steps that cover the cycle.
    pub fn total_steps(&self) -> u64 {
        self.end_us.div_ceil(u64::from(self.model.dt_us()))
    }

    /// The twin.
    pub fn model(&self) -> &Model<'a> {
        &self.model
    }

    /// The xDT's configuration.
    pub fn xdt(&self) -> &XdtConfig<'a> {
        &self.xdt
    }

    /// The loop's timing.
    pub fn timing(&self) -> Timing {
        self.timing
    }
}

impl Iterator for XilLoop<'_> {
    type Item = XilOutputs;
    fn next(&mut self) -> Option<XilOutputs> {
        self.step().copied()
    }
}
