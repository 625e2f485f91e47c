//! The twin on a measurement: the one path that runs the model on a measured run.
//!
//! A measurement and the model options (data directory, effects, rate set, speed target,
//! coupling, supply voltage and the bench's sensor model) go in; out come the set points
//! on the comparison grid, the twin's channels *as the bench would record them* (speed
//! channels through the encoder counting window, [`sensors`]) and the pairs of measured
//! and simulated samples. `compare`, `diagnose`, the history's baseline, `demo` and the
//! report all go through [`MeasuredTwin`]; nothing else steps the model on a file, so
//! two commands given the same file and flags see the same residuals.

pub mod args;
pub mod measured;
pub mod plausible;
pub mod replay;
pub mod sensors;
pub mod spans;

use std::sync::Arc;

use model_core::{
    Builtin, Channel, Config, CouplingStiffness, Effects, Inputs, Maps, Model, Params, ProfileSet, RateSet,
    Snapshot, SpeedTarget,
};

pub use measured::{
    check_budget, grid_samples, Aligned, InputSource, MeasuredTwin, Paired, Power, RunGrid, TwinError,
    FALLBACK_DT_US, POWERS,
};
pub use replay::Physical;
pub use sensors::{Keep, SensorModel};
use simrod_io::datadir::ModelData;

/// What the twin is: model data, effects, parameter choices, supply and the bench's
/// sensors. Built once from the command line ([`args::ModelArgs`]) and shared by every
/// run of the twin a command makes.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelOptions {
    /// Model data (`--data-dir`): maps, parameters and profiles instead of the built-in
    /// ones. `None`: the twin compiled into the binary.
    pub data: Option<Arc<ModelData>>,
    /// Effects switched on in the twin (the "current" effects of a diagnosis).
    pub effects: Effects,
    pub rates: RateSet,
    pub speed_target: SpeedTarget,
    pub coupling: CouplingStiffness,
    /// [V] DPU set point (the busbar voltage is an output, not an input).
    pub supply_v: f32,
    /// How the bench records what the twin computes.
    pub sensors: SensorModel,
}

impl Default for ModelOptions {
    /// The thesis model as the SimRod bench records it (0.1 s speed window).
    fn default() -> Self {
        Self {
            data: None,
            effects: Effects::NONE,
            rates: RateSet::Identified,
            speed_target: SpeedTarget::Map,
            coupling: CouplingStiffness::Identified,
            supply_v: 24.0,
            sensors: SensorModel::bench(),
        }
    }
}

impl ModelOptions {
    /// The scalar parameters (from the data directory when there is one).
    pub fn params(&self) -> Params {
        match &self.data {
            Some(d) => d.params(self.rates, self.coupling),
            None => Params::thesis(self.rates, self.coupling),
        }
    }

    /// The model's configuration at step `dt_us` with `effects`.
    pub fn config(&self, dt_us: u32, effects: Effects) -> Config {
        Config { dt_us, params: self.params(), speed_target: self.speed_target, effects }
    }

    /// The model's tables (borrowing the data directory when there is one).
    pub fn maps(&self) -> Result<Maps<'_>, TwinError> {
        match &self.data {
            Some(d) => d.maps().map_err(|e| TwinError::Model(e.to_string())),
            None => Ok(Maps::builtin()),
        }
    }

    /// A model at rest, at step `dt_us` with `effects`.
    pub fn model(&self, dt_us: u32, effects: Effects) -> Result<Model<'_>, TwinError> {
        Model::with_maps(&self.config(dt_us, effects), self.maps()?)
            .map_err(|e| TwinError::Model(format!("{e:?}")))
    }

    /// The sets of a built-in profile (the data directory's own copy when it has one).
    pub fn profile_sets(&self, which: Builtin) -> &[ProfileSet] {
        self.data.as_deref().and_then(|d| d.profile(which.name())).unwrap_or(which.sets())
    }

    /// Run the twin over `inputs` (one step each) and return `channels` as the bench
    /// records them (through the one stepping loop, `drive`).
    pub fn run(
        &self,
        dt_us: u32,
        effects: Effects,
        inputs: &[Inputs],
        channels: &[Channel],
    ) -> Result<Vec<Vec<f32>>, TwinError> {
        self.run_kept(dt_us, effects, inputs, channels, Keep::ALL)
    }

    /// As [`ModelOptions::run`], keeping only the samples `keep` names (a fit that reads
    /// every 5th sample need not store the others): exactly those samples of the full run.
    pub fn run_kept(
        &self,
        dt_us: u32,
        effects: Effects,
        inputs: &[Inputs],
        channels: &[Channel],
        keep: Keep,
    ) -> Result<Vec<Vec<f32>>, TwinError> {
        let mut model = self.model(dt_us, effects)?;
        let mut rec = self.sensors.recorder(channels, f64::from(dt_us) * 1e-6, inputs.len(), keep);
        drive(&mut model, &mut rec, inputs);
        Ok(rec.finish())
    }

    /// As [`ModelOptions::run_kept`], keeping the model's state every `every` steps:
    /// the run can then be taken up again from there on other data
    /// ([`ModelOptions::run_resumed`]).
    pub fn run_checkpointed(
        &self,
        dt_us: u32,
        effects: Effects,
        (inputs, channels): (&[Inputs], &[Channel]),
        keep: Keep,
        every: usize,
    ) -> Result<Checkpoints, TwinError> {
        let mut model = self.model(dt_us, effects)?;
        let mut rec = self.sensors.recorder(channels, f64::from(dt_us) * 1e-6, inputs.len(), keep);
        let every = every.max(1);
        let mut at = Vec::with_capacity(inputs.len() / every + 1);
        for (c, chunk) in inputs.chunks(every).enumerate() {
            at.push((c * every, model.snapshot(), rec.mark()));
            drive(&mut model, &mut rec, chunk);
        }
        Ok(Checkpoints { out: rec.output(), rec, at })
    }

    /// The run of `from` (same step, effects, inputs and channels) on this model's data,
    /// stepped only from its last checkpoint at or before step `first_read`: the same
    /// bits as the whole run when this data differs from that run's only in values the
    /// model first reads at step `first_read` or later.
    pub fn run_resumed(
        &self,
        dt_us: u32,
        effects: Effects,
        inputs: &[Inputs],
        (from, first_read): (&Checkpoints, usize),
    ) -> Result<Vec<Vec<f32>>, TwinError> {
        let mut model = self.model(dt_us, effects)?;
        let Some((step, snap, mark)) = from.at.iter().rev().find(|(k, _, _)| *k <= first_read) else {
            return Err(TwinError::Model("no checkpoint before the first step".into()));
        };
        model.resume(snap);
        let mut rec = from.rec.resumed(mark);
        drive(&mut model, &mut rec, inputs.get(*step..).unwrap_or_default());
        Ok(rec.finish())
    }
}

/// A run with the model's state kept along it ([`ModelOptions::run_checkpointed`]).
pub struct Checkpoints {
    /// The run's kept samples, as [`ModelOptions::run_kept`] returns them (derivable from
    /// the recording, kept: every response a run does not read copies it).
    pub out: Vec<Vec<f32>>,
    rec: sensors::Recorder,
    at: Vec<Checkpoint>,
}

/// The model and the recording before a step (the step's index first).
type Checkpoint = (usize, Snapshot, sensors::Mark);

/// Step `model` over `inputs`, recording into `rec`: the only loop that steps the model
/// for an analysis (a checkpointed run calls it a stretch at a time, so the loop itself
/// carries nothing for the checkpoints).
fn drive(model: &mut Model<'_>, rec: &mut sensors::Recorder, inputs: &[Inputs]) {
    for inp in inputs {
        let o = model.step(inp);
        rec.record(|c| o.get(c));
    }
}
