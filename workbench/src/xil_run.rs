//! The closed XiL loop as a test `simrod check` runs ([`XilRun`]): the twin and the xDT
//! on a drive cycle, at any Monte Carlo sample's model. A closed loop has no set-point
//! scales (the driver sets the throttle, the road the load), so the set-point search
//! says it does not apply. Its delay margin ([`delay_check`]) is a condition of
//! approval, and `simrod xil` appends the limits table of the same loop
//! ([`limits_table`]).

use model_core::Config;
use simrod_check::delay::DelayMargin;
use simrod_check::limits::Limits;
use simrod_check::run::{Scales, StepSink, TestRun};
use simrod_check::{check, report, CheckError, CheckOptions};
use simrod_xdt::Cycle;

use crate::cmd_xil::{outcome_text, LoopArgs, XilSpec};
use crate::error::CmdError;
use crate::simulate::ModelArgs;

/// The twin's step [µs] of `check`'s runs (its `--dt-us` default): resolves the 2 kHz
/// torque-flange mode the flange and coupling limits need.
pub const CHECK_DT_US: u32 = 100;

/// The scales a closed loop runs at: the loop's own set points, unscaled.
const UNSCALED: Scales = Scales { throttle: 1.0, load: 1.0 };

/// A closed loop on a drive cycle, as a `check` test.
#[derive(Debug, Clone)]
pub struct XilRun {
    pub spec: XilSpec,
}

impl TestRun for XilRun {
    fn title(&self) -> String {
        format!("{} | dt {} µs", self.spec.title, self.spec.config.dt_us)
    }

    fn config(&self) -> &Config {
        &self.spec.config
    }

    fn scales(&self) -> Scales {
        UNSCALED
    }

    fn duration_us(&self) -> u64 {
        self.spec.cycle.route().duration_us()
    }

    fn phase(&self, t_us: u64) -> String {
        let mut hint = 0;
        let v = self.spec.cycle.route().target(t_us as f32 * 1e-6, &mut hint);
        format!("{} at {:.0} km/h", self.spec.cycle.name(), v * 3.6)
    }

    fn run(&self, config: &Config, scales: Scales, sink: &mut dyn StepSink) -> Result<(), String> {
        if scales != UNSCALED {
            return Err(format!("a closed loop runs unscaled, not at {scales:?}"));
        }
        let maps = self.spec.maps().map_err(|e| e.to_string())?;
        let mut lp = self.spec.run(maps, config).map_err(|e| e.to_string())?;
        sink.begin(lp.model().side_params());
        let mut k = 0u64;
        while let Some(o) = lp.step() {
            k += 1;
            if let Some(c) = o.bench.non_finite() {
                return Err(format!(
                    "the loop diverged at step {k} (t = {:.6} s): {} is {}",
                    o.bench.t_s(),
                    c.name(),
                    o.bench.get(c)
                ));
            }
            sink.step(&o.bench);
        }
        Ok(())
    }

    fn no_set_points(&self) -> Option<String> {
        Some(
            "a closed loop has no set-point scales (its driver sets the throttle, its road the load): \
             change the cycle, the vehicle or the loop timing"
                .into(),
        )
    }
}

/// The delay margin of `spec`'s loop against `factor` × its loop delay.
pub fn delay_check(spec: &XilSpec, factor: f64) -> Result<DelayMargin, CmdError> {
    let (m, step_ms) = spec.margin()?;
    let ms = |steps: u32| f64::from(steps) * step_ms;
    Ok(DelayMargin {
        margin_ms: m.stable_steps.map(ms),
        at_least: m.stable_steps.is_some() && m.unstable.is_none(),
        loop_delay_ms: f64::from(spec.loop_delay_ms),
        factor,
        beyond: m.unstable.map(|(u, v)| format!("at {} ms: {}", ms(u), outcome_text(&v.outcome))),
        runs: m.runs,
    })
}

/// `simrod xil`'s table of `check` margins: the limits evaluated on the same loop
/// (nominal model) at `check`'s [`CHECK_DT_US`] step, which the flange limits need.
pub fn limits_table(
    cycle: &Cycle,
    looping: &LoopArgs,
    model: &ModelArgs,
    limits: &Limits,
) -> Result<String, CmdError> {
    let head = format!(
        "check margins (the same loop at the {CHECK_DT_US} µs twin step that resolves the flange mode; nominal model; limits {})",
        limits.source
    );
    let spec = match XilSpec::new(*cycle, looping, model, CHECK_DT_US) {
        Ok(s) => s,
        Err(e) => return Ok(format!("{head}: not evaluated: {e}\n")),
    };
    let o = CheckOptions {
        limits,
        uncertainty: None,
        samples: 0,
        seed: 0,
        confidence: 0.95,
        threads: 1,
        progress: false,
        set_points: false,
        delay: None,
    };
    let r = check(&XilRun { spec }, &o).map_err(|e| match e {
        CheckError::Usage(m) => CmdError::Usage(m),
        CheckError::Runtime(m) => CmdError::Runtime(m),
    })?;
    Ok(format!("{head}:\n{}{}\n", report::table(&r), report::verdict_line(&r)))
}
