//! One FMU instance: the FMI 3.0 Co-Simulation state machine, the values the importer
//! sets, and the twin it steps. Safe Rust throughout: the C API ([`crate::ffi`]) turns
//! the importer's pointers into slices and calls [`Instance::call`].
//!
//! States (FMI 3.0, Co-Simulation without Event Mode): Instantiated ->
//! (`fmi3EnterInitializationMode`) Initialization Mode -> (`fmi3ExitInitializationMode`)
//! Step Mode -> (`fmi3Terminate`) Terminated; `fmi3Reset` returns to Instantiated with
//! the start values from any state. A call that returns `fmi3Error` logs why and leaves
//! the instance Terminated (as the FMI Reference FMUs do): the standard says the
//! simulation must not be continued, and only getters, `fmi3Reset` and
//! `fmi3FreeInstance` are then allowed.

use std::fmt;
use std::path::Path;
use std::sync::Arc;

use model_core::{Effects, Inputs, Outputs, SetPoints};

use crate::description::{token, LOG_CATEGORIES};
use crate::spec::Spec;
use crate::twin::Twin;
use crate::vars::{Choices, EffectParam, Input, Type, Var, SET_POINT_RANGE};

/// `fmi3Status`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
}

/// The instance's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    Instantiated,
    Initialization,
    Step,
    Terminated,
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Mode::Instantiated => "Instantiated",
            Mode::Initialization => "Initialization Mode",
            Mode::Step => "Step Mode",
            Mode::Terminated => "Terminated",
        })
    }
}

/// Getters work in every state.
const GET: &[Mode] = &[Mode::Instantiated, Mode::Initialization, Mode::Step, Mode::Terminated];
/// Parameters are fixed: set before initialization ends.
const SET_PARAMETER: &[Mode] = &[Mode::Instantiated, Mode::Initialization];
/// Inputs: also between steps.
const SET_INPUT: &[Mode] = &[Mode::Instantiated, Mode::Initialization, Mode::Step];

/// Where log messages go: `(status, category, message)`.
pub type LogFn = Box<dyn Fn(Status, &str, &str)>;

/// The importer's logger and which categories are on.
pub struct Logger {
    sink: Option<LogFn>,
    events: bool,
    errors: bool,
}

impl Logger {
    /// `logging_on` switches the events; errors are logged unless switched off.
    pub fn new(sink: Option<LogFn>, logging_on: bool) -> Self {
        Self { sink, events: logging_on, errors: true }
    }

    /// Log an error (category `logStatusError`).
    pub fn error(&self, msg: &str) {
        if let (true, Some(s)) = (self.errors, &self.sink) {
            s(Status::Error, "logStatusError", msg);
        }
    }

    /// Log an event (category `logEvents`).
    pub fn event(&self, msg: &str) {
        if let (true, Some(s)) = (self.events, &self.sink) {
            s(Status::Ok, "logEvents", msg);
        }
    }
}

/// What the importer sets: inputs, choices, effect parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Values {
    /// [%, %, %, V] in [`Input::ALL`] order, as set (rounded to f32 at each step).
    pub inputs: [f64; 4],
    pub choices: Choices,
    /// Effect parameters (f32, as the twin holds them); an unset override keeps the
    /// model's value.
    pub effects: Effects,
}

impl Values {
    /// The start values the model description declares.
    pub fn start(spec: &Spec) -> Self {
        let mut inputs = [0.0; 4];
        inputs[Input::Supply.index()] = spec.supply_start();
        Self { inputs, choices: spec.settings.choices, effects: spec.effects }
    }

    /// An effect parameter's value: as set, or for an unset override the model's value
    /// under the current choices.
    pub fn effect(&self, spec: &Spec, p: &EffectParam) -> f64 {
        let v = match self.effects.get(p.effect.id, p.param.name) {
            Ok(Some(v)) => v,
            _ => p.param.neutral(p.effect.id, &spec.params(&self.choices)),
        };
        f64::from(v)
    }

    /// The model's inputs for the next steps.
    fn model_inputs(&self) -> Inputs {
        let f = |i: Input| self.inputs[i.index()] as f32;
        Inputs {
            sp: SetPoints { throttle_pct: f(Input::Throttle), load_pct: [f(Input::LoadL), f(Input::LoadR)] },
            supply_v: f(Input::Supply),
        }
    }
}

/// One instance.
pub struct Instance {
    name: String,
    log: Logger,
    spec: Arc<Spec>,
    mode: Mode,
    values: Values,
    /// Built when initialization ends.
    twin: Option<Twin>,
    /// The last step's outputs (0 before the first step).
    out: Outputs,
    /// [s] `startTime` of `fmi3EnterInitializationMode`.
    start_time: f64,
}

impl fmt::Debug for Instance {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Instance").field("name", &self.name).field("mode", &self.mode).finish_non_exhaustive()
    }
}

impl Instance {
    /// Load the resources, check the token, start in Instantiated. The error is the
    /// reason, for the importer's log.
    pub fn new(name: &str, token_given: &str, resources: &Path, log: Logger) -> Result<Self, String> {
        let spec = Spec::load(resources)?;
        let mine = token(&spec)?;
        if token_given != mine {
            return Err(format!(
                "instantiation token {token_given} does not match this FMU's {mine} (computed from its binary \
                 and {}): the model description belongs to another build or other resources",
                resources.display()
            ));
        }
        let values = Values::start(&spec);
        let me = Self {
            name: name.to_string(),
            log,
            spec: Arc::new(spec),
            mode: Mode::Instantiated,
            values,
            twin: None,
            out: Outputs::default(),
            start_time: 0.0,
        };
        me.log.event(&format!("{name}: instantiated from {}", resources.display()));
        Ok(me)
    }

    /// The state.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Run one API function's body: on error log `func: why`, go to Terminated and
    /// return `fmi3Error`.
    pub fn call(&mut self, func: &str, body: impl FnOnce(&mut Self) -> Result<(), String>) -> Status {
        match body(self) {
            Ok(()) => Status::Ok,
            Err(why) => self.fail(func, &why),
        }
    }

    /// Log `func: why`, go to Terminated, `fmi3Error`.
    pub fn fail(&mut self, func: &str, why: &str) -> Status {
        self.log.error(&format!("{}: {func}: {why}", self.name));
        self.mode = Mode::Terminated;
        Status::Error
    }

    fn require(&self, allowed: &[Mode]) -> Result<(), String> {
        if allowed.contains(&self.mode) {
            return Ok(());
        }
        let names: Vec<String> = allowed.iter().map(Mode::to_string).collect();
        Err(format!("not allowed in {} (allowed in: {})", self.mode, names.join(", ")))
    }

    /// `fmi3SetDebugLogging`.
    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> Result<(), String> {
        if categories.is_empty() {
            self.log.events = on;
            self.log.errors = on;
        }
        for c in categories {
            match *c {
                "logEvents" => self.log.events = on,
                "logStatusError" => self.log.errors = on,
                other => {
                    let known: Vec<&str> = LOG_CATEGORIES.iter().map(|(n, _)| *n).collect();
                    return Err(format!("unknown log category `{other}`; known: {}", known.join(", ")));
                }
            }
        }
        Ok(())
    }

    /// `fmi3EnterInitializationMode`.
    pub fn enter_initialization(&mut self, start: f64, stop: Option<f64>) -> Result<(), String> {
        self.require(&[Mode::Instantiated])?;
        if !start.is_finite() {
            return Err(format!("startTime = {start} is not finite"));
        }
        if let Some(stop) = stop.filter(|s| s.is_nan() || *s < start) {
            return Err(format!("stopTime = {stop} is before startTime = {start}"));
        }
        self.start_time = start;
        self.mode = Mode::Initialization;
        Ok(())
    }

    /// `fmi3ExitInitializationMode`: build the twin from the parameters as set.
    pub fn exit_initialization(&mut self) -> Result<(), String> {
        self.require(&[Mode::Initialization])?;
        self.twin = Some(Twin::build(self.spec.clone(), &self.values.choices, self.values.effects)?);
        self.out = Outputs::default();
        self.mode = Mode::Step;
        self.log.event(&format!("{}: initialized, step {} µs", self.name, self.spec.settings.dt_us));
        Ok(())
    }

    /// `fmi3Terminate`.
    pub fn terminate(&mut self) -> Result<(), String> {
        self.require(&[Mode::Step])?;
        self.mode = Mode::Terminated;
        self.log.event(&format!("{}: terminated at t = {} s", self.name, self.time()));
        Ok(())
    }

    /// `fmi3Reset`: back to Instantiated with the start values.
    pub fn reset(&mut self) {
        self.values = Values::start(&self.spec);
        self.twin = None;
        self.out = Outputs::default();
        self.start_time = 0.0;
        self.mode = Mode::Instantiated;
        self.log.event(&format!("{}: reset", self.name));
    }

    /// [s] the FMU's time: the start time plus the steps taken.
    pub fn time(&self) -> f64 {
        let t_us = self.twin.as_ref().map_or(0, Twin::t_us);
        self.start_time + t_us as f64 / 1e6
    }

    /// `fmi3DoStep` from `t` over `h`: `h / dt` steps of the twin with the inputs held.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), String> {
        self.require(&[Mode::Step])?;
        let dt_us = self.spec.settings.dt_us;
        let dt = f64::from(dt_us) / 1e6;
        let now = self.time();
        // Clock arithmetic in f64 (k * dt against the twin's whole microseconds) may
        // differ by a few ulps; far less than a step.
        let tol = |x: f64| dt * 1e-6 + x.abs() * 4.0 * f64::EPSILON;
        if !t.is_finite() || (t - now).abs() > tol(now) {
            return Err(format!("currentCommunicationPoint = {t} s, but the FMU is at {now} s"));
        }
        let n = (h / dt).round();
        if !(h > 0.0 && n >= 1.0 && n < 2f64.powi(53)) || (h - n * dt).abs() > tol(h) {
            return Err(format!(
                "communicationStepSize = {h} s is not a whole multiple of the twin's fixed step {dt} s \
                 ({dt_us} µs; fixedInternalStepSize in the model description)"
            ));
        }
        let inputs = self.values.model_inputs();
        let Some(twin) = self.twin.as_mut() else {
            return Err("no model: initialization did not finish".into());
        };
        for _ in 0..n as u64 {
            let o = twin.step(&inputs);
            if let Some(c) = o.non_finite() {
                return Err(format!(
                    "the twin diverged at t = {} s: {} is {}",
                    self.start_time + o.t_s(),
                    c.name(),
                    o.get(c)
                ));
            }
            self.out = o;
        }
        Ok(())
    }

    /// The variable of `vr`, which must have type `ty`.
    fn var(vr: u32, ty: Type) -> Result<Var, String> {
        let v = Var::from_vr(vr).ok_or_else(|| format!("unknown value reference {vr}"))?;
        if v.ty() != ty {
            return Err(format!("{} cannot be accessed as {}", v.describe(), ty.name()));
        }
        Ok(v)
    }

    /// One value per value reference: every variable here is a scalar.
    fn counts(n_vr: usize, n_values: usize) -> Result<(), String> {
        if n_vr == n_values {
            Ok(())
        } else {
            Err(format!("nValues = {n_values}, but {n_vr} scalar value references need {n_vr} values"))
        }
    }

    /// `fmi3GetFloat64`.
    pub fn get_f64(&self, vrs: &[u32], values: &mut [f64]) -> Result<(), String> {
        self.require(GET)?;
        Self::counts(vrs.len(), values.len())?;
        for (vr, out) in vrs.iter().zip(values) {
            *out = match Self::var(*vr, Type::Float64)? {
                Var::Time => self.time(),
                Var::Input(i) => self.values.inputs[i.index()],
                Var::Output(c) => f64::from(self.out.get(c)),
                Var::Effect(p) => self.values.effect(&self.spec, &p),
                Var::Choice(_) => return Err("internal: a choice is not Float64".into()),
            };
        }
        Ok(())
    }

    /// `fmi3SetFloat64`.
    pub fn set_f64(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        Self::counts(vrs.len(), values.len())?;
        for (vr, v) in vrs.iter().zip(values) {
            let var = Self::var(*vr, Type::Float64)?;
            self.require_settable(&var)?;
            match var {
                Var::Input(i) => {
                    let (lo, hi) =
                        if i == Input::Supply { self.spec.supply_range() } else { SET_POINT_RANGE };
                    if !(v.is_finite() && (lo..=hi).contains(v)) {
                        return Err(format!(
                            "{} = {v}: expected a value in [{lo}, {hi}] {}",
                            i.name(),
                            i.unit()
                        ));
                    }
                    self.values.inputs[i.index()] = *v;
                }
                Var::Effect(p) => {
                    let f = *v as f32;
                    if !p.param.range.contains(f) {
                        return Err(format!(
                            "{} = {v}: must be {} {}",
                            p.name(),
                            p.param.range,
                            p.param.unit
                        ));
                    }
                    self.values
                        .effects
                        .set(p.effect.id, p.param.name, f)
                        .map_err(|e| e.describe(p.effect.id, p.param.name).to_string())?;
                }
                _ => return Err(format!("{} cannot be set", var.describe())),
            }
        }
        Ok(())
    }

    /// `fmi3GetInt64`: the enumerations.
    pub fn get_i64(&self, vrs: &[u32], values: &mut [i64]) -> Result<(), String> {
        self.require(GET)?;
        Self::counts(vrs.len(), values.len())?;
        for (vr, out) in vrs.iter().zip(values) {
            match Self::var(*vr, Type::Enumeration)? {
                Var::Choice(c) => *out = self.values.choices.get(c),
                _ => return Err("internal: only choices are enumerations".into()),
            }
        }
        Ok(())
    }

    /// `fmi3SetInt64`: the enumerations.
    pub fn set_i64(&mut self, vrs: &[u32], values: &[i64]) -> Result<(), String> {
        Self::counts(vrs.len(), values.len())?;
        for (vr, v) in vrs.iter().zip(values) {
            let var = Self::var(*vr, Type::Enumeration)?;
            self.require_settable(&var)?;
            match var {
                Var::Choice(c) => self.values.choices.set(c, *v)?,
                _ => return Err(format!("{} cannot be set", var.describe())),
            }
        }
        Ok(())
    }

    /// A getter or setter of a type this FMU has no variables of: fine for no value
    /// references, an error naming each one's real type otherwise.
    pub fn no_variables_of(
        &self,
        type_name: &str,
        vrs: &[u32],
        n_values: usize,
        setter: bool,
    ) -> Result<(), String> {
        self.require(if setter { SET_INPUT } else { GET })?;
        Self::counts(vrs.len(), n_values)?;
        match vrs.first() {
            None => Ok(()),
            Some(vr) => match Var::from_vr(*vr) {
                None => Err(format!("unknown value reference {vr}")),
                Some(v) => Err(format!(
                    "{} cannot be accessed as {type_name} (this FMU has only Float64 and Enumeration variables)",
                    v.describe()
                )),
            },
        }
    }

    fn require_settable(&self, var: &Var) -> Result<(), String> {
        if !var.is_settable() {
            return Err(format!("{} cannot be set", var.describe()));
        }
        let allowed = if var.is_input() { SET_INPUT } else { SET_PARAMETER };
        self.require(allowed).map_err(|m| {
            if var.is_input() {
                format!("setting {}: {m}", var.describe())
            } else {
                format!("{} is fixed after initialization: {m}", var.describe())
            }
        })
    }
}
