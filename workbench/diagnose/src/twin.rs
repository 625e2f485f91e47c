//! The twins a diagnosis runs: the twin on the measured run (through
//! [`simrod_twin::MeasuredTwin`], the same path `simrod compare` takes) and the twin on
//! built-in profiles (to find a separating experiment).

use std::sync::Arc;

use model_core::{Builtin, Channel, Effects, Inputs, Profile, SetPoints};
use simrod_io::datadir::ModelData;

use super::engine::{every, ProfileProbe, Twin};
use simrod_twin::{MeasuredTwin, ModelOptions};

/// The twin on a measured run, restricted to the channels the diagnosis fits.
pub struct RecordedTwin {
    /// The measured run on the comparison grid, with the model options.
    pub twin: MeasuredTwin,
    /// Channels to return.
    pub channels: Vec<Channel>,
}

impl Twin for RecordedTwin {
    fn channels(&self) -> &[Channel] {
        &self.channels
    }
    fn samples(&self) -> usize {
        self.twin.inputs.len()
    }
    fn dt_s(&self) -> f64 {
        self.twin.grid.dt_s()
    }
    fn run(&self, fx: &Effects) -> Result<Vec<Vec<f32>>, String> {
        self.twin.simulate(*fx, &self.channels).map_err(|e| e.to_string())
    }

    fn resolution(&self) -> Vec<f64> {
        self.channels.iter().map(|c| self.twin.model.sensors.counting_step(*c).unwrap_or(0.0)).collect()
    }

    fn data(&self) -> Option<Arc<ModelData>> {
        match &self.twin.model.data {
            Some(d) => Some(d.clone()),
            None => ModelData::builtin().ok().map(Arc::new),
        }
    }

    fn set_points(&self) -> Vec<SetPoints> {
        self.twin.inputs.iter().map(|i| i.sp).collect()
    }

    fn run_data(&self, data: &Arc<ModelData>, fx: &Effects, stride: usize) -> Result<Vec<Vec<f32>>, String> {
        let model = ModelOptions { data: Some(data.clone()), ..self.twin.model.clone() };
        let out = model
            .run(self.twin.grid.dt_us, *fx, &self.twin.inputs, &self.channels)
            .map_err(|e| e.to_string())?;
        Ok(out.into_iter().map(|c| every(c, stride)).collect())
    }
}

/// Several recorded runs as one twin: their samples one after another, so every fit is
/// joint (the effects are shared, the evidence is every run's). Runs with different
/// profiles, scales or supply voltages excite effects differently: a pair of effects
/// confounded on one run is told apart by the campaign when another run separates them.
pub struct Campaign {
    runs: Vec<RecordedTwin>,
}

impl Campaign {
    /// The runs must fit the same channels at the same model step.
    pub fn new(runs: Vec<RecordedTwin>) -> Result<Self, String> {
        let first = runs.first().ok_or("a campaign needs at least one run")?;
        for (i, r) in runs.iter().enumerate().skip(1) {
            if r.channels != first.channels {
                return Err(format!("run {} fits other channels than run 1", i + 1));
            }
            if r.twin.grid.dt_us != first.twin.grid.dt_us {
                return Err(format!(
                    "run {} has a {} µs model step, run 1 {} µs: record the campaign at one rate",
                    i + 1,
                    r.twin.grid.dt_us,
                    first.twin.grid.dt_us
                ));
            }
        }
        Ok(Self { runs })
    }
}

impl Campaign {
    /// Every run's channels, one run after another.
    fn joined(
        &self,
        each: impl Fn(&RecordedTwin) -> Result<Vec<Vec<f32>>, String>,
    ) -> Result<Vec<Vec<f32>>, String> {
        let mut out: Vec<Vec<f32>> = vec![Vec::with_capacity(self.samples()); self.channels().len()];
        for r in &self.runs {
            for (all, part) in out.iter_mut().zip(each(r)?) {
                all.extend(part);
            }
        }
        Ok(out)
    }
}

impl Twin for Campaign {
    fn channels(&self) -> &[Channel] {
        self.runs.first().map_or(&[], |r| r.channels.as_slice())
    }

    fn samples(&self) -> usize {
        self.runs.iter().map(Twin::samples).sum()
    }

    fn dt_s(&self) -> f64 {
        self.runs.first().map_or(1e-3, Twin::dt_s)
    }

    fn run(&self, fx: &Effects) -> Result<Vec<Vec<f32>>, String> {
        self.joined(|r| r.run(fx))
    }

    fn resolution(&self) -> Vec<f64> {
        self.runs.first().map_or_else(Vec::new, Twin::resolution)
    }

    fn segments(&self) -> Vec<usize> {
        self.runs.iter().map(Twin::samples).collect()
    }

    fn data(&self) -> Option<Arc<ModelData>> {
        self.runs.first().and_then(Twin::data)
    }

    fn set_points(&self) -> Vec<SetPoints> {
        self.runs.iter().flat_map(Twin::set_points).collect()
    }

    fn run_data(&self, data: &Arc<ModelData>, fx: &Effects, stride: usize) -> Result<Vec<Vec<f32>>, String> {
        // Each run strided from its own first sample, as `Twin::run_every` strides the
        // joined series only when every run's length is a multiple of the stride: join
        // whole runs, then stride, so the samples match the fits'.
        Ok(self.joined(|r| r.run_data(data, fx, 1))?.into_iter().map(|c| every(c, stride)).collect())
    }
}

/// Set points of a profile run, as a recorded run would carry them.
pub fn profile_inputs(profile: &Profile, dt_us: u32, supply_v: f32) -> Vec<Inputs> {
    let n = profile.duration_us().div_ceil(u64::from(dt_us));
    (0..n).map(|k| Inputs { sp: profile.at(k * u64::from(dt_us)), supply_v }).collect()
}

/// The built-in profiles at a few scalings: the experiments a user could run next, at
/// the bench's 1 kHz whatever the measured file's rate.
pub struct BuiltinProbe {
    /// The twin (data directory, parameters, sensors); effects are given per run.
    pub model: ModelOptions,
    /// Channels to return.
    pub channels: Vec<Channel>,
    /// (profile, throttle scale, load scale) candidates.
    pub candidates: Vec<(Builtin, f32, f32)>,
}

/// Step of the probe runs [µs]: the bench's rate.
const PROBE_DT_US: u32 = 1000;

impl BuiltinProbe {
    /// Forward and reverse, with and without loads, every built-in profile.
    pub fn standard(model: ModelOptions, channels: Vec<Channel>) -> Self {
        let mut candidates = Vec::new();
        for b in Builtin::ALL {
            for (ts, ls) in [(1.0, 1.0), (0.79, 0.0), (-1.0, 0.0), (0.79, -1.0)] {
                candidates.push((b, ts, ls));
            }
        }
        Self { model, channels, candidates }
    }
}

impl ProfileProbe for BuiltinProbe {
    fn count(&self) -> usize {
        self.candidates.len()
    }
    fn name(&self, i: usize) -> String {
        self.candidates.get(i).map_or_else(String::new, |(b, ts, ls)| {
            format!("{} --throttle-scale {ts} --load-scale {ls}", b.name())
        })
    }
    fn run(&self, i: usize, fx: &Effects) -> Option<Vec<Vec<f32>>> {
        let (b, ts, ls) = *self.candidates.get(i)?;
        let profile = Profile::new(self.model.profile_sets(b), ts, ls).ok()?;
        let inputs = profile_inputs(&profile, PROBE_DT_US, self.model.supply_v);
        let out = self.model.run(PROBE_DT_US, *fx, &inputs, &self.channels).ok()?;
        // Every 10th step is plenty to compare shapes.
        Some(out.into_iter().map(|v| v.into_iter().step_by(10).collect()).collect())
    }
}

/// Channels the diagnosis fits: the bench's measured channels except the throttle
/// voltage (it is an input, not a response).
pub fn fitted_channels() -> Vec<Channel> {
    model_core::MEASURED.iter().copied().filter(|c| *c != Channel::Throttle).collect()
}
