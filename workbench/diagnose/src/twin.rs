//! The twins a diagnosis runs: the twin on the measured run (through
//! [`simrod_twin::MeasuredTwin`], the same path `simrod compare` takes) and the twin on
//! built-in profiles (to find a separating experiment).

use std::sync::{Arc, OnceLock};

use model_core::{Builtin, Channel, Effects, Inputs, Profile, SetPoints};
use simrod_io::datadir::ModelData;

use super::engine::{ProbeRate, ProfileProbe, Twin};
use simrod_twin::{Keep, MeasuredTwin, ModelOptions, Physical};

/// The twin on a measured run, restricted to the channels the diagnosis fits.
pub struct RecordedTwin {
    /// The measured run on the comparison grid, with the model options.
    pub twin: MeasuredTwin,
    /// Channels to return.
    pub channels: Vec<Channel>,
    /// The physical values of one run ([`Twin::hold_physics`]): effects that change only
    /// the measurement chain from it are replayed over them, not simulated.
    physics: OnceLock<Physical>,
    /// Per channel, the noise σ stated for each sample (`None`: not stated).
    stated: Vec<Option<Vec<f64>>>,
}

impl RecordedTwin {
    /// The twin on `twin`'s run, returning `channels`, with the noise stated for them
    /// from the run's measured channels ([`MeasuredTwin::stated_sigma`]).
    pub fn new(twin: MeasuredTwin, channels: Vec<Channel>) -> Self {
        let stated = twin.stated_sigma(&channels);
        Self::with_stated(twin, channels, stated)
    }

    /// As [`RecordedTwin::new`] with the stated noise per channel and sample given: when
    /// the run's measured channels were taken out of `twin` (`simrod diagnose` holds a
    /// long run once), it was computed from them while they were there.
    pub fn with_stated(twin: MeasuredTwin, channels: Vec<Channel>, stated: Vec<Option<Vec<f64>>>) -> Self {
        Self { twin, channels, physics: OnceLock::new(), stated }
    }

    /// The samples `keep` names with `fx`: replayed when only the chain differs from the
    /// held physics, else simulated.
    fn record(&self, fx: &Effects, keep: Keep) -> Result<Vec<Vec<f32>>, String> {
        let model = &self.twin.model;
        if let Some(r) = self.physics.get().and_then(|ph| model.replay(ph, fx, &self.channels, keep)) {
            return r.map_err(|e| e.to_string());
        }
        self.run_kept(model, fx, keep)
    }

    /// The twin `model` on this run, the samples `keep` names.
    fn run_kept(&self, model: &ModelOptions, fx: &Effects, keep: Keep) -> Result<Vec<Vec<f32>>, String> {
        model
            .run_kept(self.twin.grid.dt_us, *fx, &self.twin.inputs, &self.channels, keep)
            .map_err(|e| e.to_string())
    }

    /// This run's model options on other model data.
    fn with_data(&self, data: &Arc<ModelData>) -> ModelOptions {
        ModelOptions { data: Some(data.clone()), ..self.twin.model.clone() }
    }
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
        self.record(fx, Keep::ALL)
    }

    fn run_every(&self, fx: &Effects, stride: usize) -> Result<Vec<Vec<f32>>, String> {
        self.record(fx, Keep { first: 0, stride })
    }

    fn hold_physics(&self, fx: &Effects) -> Result<(), String> {
        if self.physics.get().is_none() {
            let t = &self.twin;
            let ph = t.model.run_physical(t.grid.dt_us, fx, &t.inputs).map_err(|e| e.to_string())?;
            let _ = self.physics.set(ph);
        }
        Ok(())
    }

    fn resolution(&self) -> Vec<f64> {
        self.channels.iter().map(|c| self.twin.model.sensors.counting_step(*c).unwrap_or(0.0)).collect()
    }

    fn stated_sigma(&self) -> Vec<Option<Vec<f64>>> {
        self.stated.clone()
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
        self.run_kept(&self.with_data(data), fx, Keep { first: 0, stride })
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
    /// What each run keeps of the joined sequence's every `stride`-th sample.
    fn keeps(&self, stride: usize) -> Vec<Keep> {
        let stride = stride.max(1);
        let mut offset = 0;
        self.runs
            .iter()
            .map(|r| {
                let keep = Keep { first: (stride - offset % stride) % stride, stride };
                offset += r.samples();
                keep
            })
            .collect()
    }

    /// Every `stride`-th sample of the joined runs, from the first: run `i` gives the
    /// samples it holds of that sequence (`each(i, run, keep)`), and the runs simulate
    /// side by side.
    fn joined_every(
        &self,
        stride: usize,
        each: impl Fn(usize, &RecordedTwin, Keep) -> Result<Vec<Vec<f32>>, String> + Sync,
    ) -> Result<Vec<Vec<f32>>, String> {
        use rayon::prelude::*;
        let keeps = self.keeps(stride);
        let parts: Vec<Vec<Vec<f32>>> = (0..self.runs.len())
            .into_par_iter()
            .map(|i| each(i, &self.runs[i], keeps[i]))
            .collect::<Result<_, _>>()?;
        Ok(joined(parts, self.channels().len()))
    }
}

/// The runs' parts (`[run][channel][sample]`) one after another per channel.
fn joined(parts: Vec<Vec<Vec<f32>>>, channels: usize) -> Vec<Vec<f32>> {
    let n: usize = parts.iter().filter_map(|p| p.first()).map(Vec::len).sum();
    let mut out: Vec<Vec<f32>> = vec![Vec::with_capacity(n); channels];
    for part in parts {
        for (all, p) in out.iter_mut().zip(part) {
            all.extend(p);
        }
    }
    out
}

/// Steps between the states a checkpointed run keeps ([`Twin::checkpointed`]): 0.5 s
/// at the bench's 1 kHz, a few hundred kilobytes per minute of run.
const CHECKPOINT_EVERY: usize = 500;

/// A run of the twin with its state kept along each of its runs ([`Twin::checkpointed`]).
pub struct Resumable {
    runs: Vec<simrod_twin::Checkpoints>,
}

impl Resumable {
    /// The run's samples, as [`Twin::run_data`] gives them.
    pub fn out(&self) -> Vec<Vec<f32>> {
        let channels = self.runs.first().map_or(0, |r| r.out.len());
        joined(self.runs.iter().map(|r| r.out.clone()).collect(), channels)
    }
}

impl RecordedTwin {
    /// This run on `data` with `fx`, keeping `keep`, its state kept along it.
    fn checkpoints(
        &self,
        data: &Arc<ModelData>,
        fx: &Effects,
        keep: Keep,
    ) -> Result<simrod_twin::Checkpoints, String> {
        let t = &self.twin;
        self.with_data(data)
            .run_checkpointed(t.grid.dt_us, *fx, (&t.inputs, &self.channels), keep, CHECKPOINT_EVERY)
            .map_err(|e| e.to_string())
    }

    /// This run on `data` as `base` (its checkpointed run on other data), stepped from
    /// step `first` (`None`: `data` changes nothing this run reads; `base` as it is).
    fn resumed(
        &self,
        data: &Arc<ModelData>,
        fx: &Effects,
        (base, first): (&simrod_twin::Checkpoints, Option<usize>),
    ) -> Result<Vec<Vec<f32>>, String> {
        let Some(first) = first else { return Ok(base.out.clone()) };
        let t = &self.twin;
        self.with_data(data)
            .run_resumed(t.grid.dt_us, *fx, &t.inputs, (base, first))
            .map_err(|e| e.to_string())
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
        self.joined_every(1, |_, r, keep| r.record(fx, keep))
    }

    fn run_every(&self, fx: &Effects, stride: usize) -> Result<Vec<Vec<f32>>, String> {
        self.joined_every(stride, |_, r, keep| r.record(fx, keep))
    }

    fn hold_physics(&self, fx: &Effects) -> Result<(), String> {
        use rayon::prelude::*;
        self.runs.par_iter().try_for_each(|r| r.hold_physics(fx))
    }

    fn resolution(&self) -> Vec<f64> {
        self.runs.first().map_or_else(Vec::new, Twin::resolution)
    }

    /// The runs' statements one after another; a channel stated on every run or not at all.
    fn stated_sigma(&self) -> Vec<Option<Vec<f64>>> {
        let mut all = vec![Some(Vec::new()); self.channels().len()];
        for r in &self.runs {
            for (a, s) in all.iter_mut().zip(r.stated_sigma()) {
                *a = a.take().zip(s).map(|(mut a, s)| {
                    a.extend(s);
                    a
                });
            }
        }
        all
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
        self.joined_every(stride, |_, r, keep| r.run_kept(&r.with_data(data), fx, keep))
    }

    fn checkpointed(&self, data: &Arc<ModelData>, fx: &Effects, stride: usize) -> Option<Resumable> {
        use rayon::prelude::*;
        let keeps = self.keeps(stride);
        let runs: Result<Vec<_>, String> =
            self.runs.par_iter().zip(keeps).map(|(r, keep)| r.checkpoints(data, fx, keep)).collect();
        Some(Resumable { runs: runs.ok()? })
    }

    fn run_data_from(
        &self,
        data: &Arc<ModelData>,
        fx: &Effects,
        base: &Resumable,
        first: &[Option<usize>],
    ) -> Result<Vec<Vec<f32>>, String> {
        if base.runs.len() != self.runs.len() || first.len() != self.runs.len() {
            return Err("the checkpointed run is not this campaign's".into());
        }
        self.joined_every(1, |i, r, _| r.resumed(data, fx, (&base.runs[i], first[i])))
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

/// Model step of the probe runs [µs] and the stride that keeps a sample every 10 ms.
fn probe_step(rate: ProbeRate) -> (u32, usize) {
    match rate {
        ProbeRate::Screen => (5_000, 2),
        ProbeRate::Bench => (1_000, 10),
    }
}

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
    fn run(&self, i: usize, fx: &Effects, rate: ProbeRate) -> Option<Vec<Vec<f32>>> {
        let (b, ts, ls) = *self.candidates.get(i)?;
        let profile = Profile::new(self.model.profile_sets(b), ts, ls).ok()?;
        let (dt_us, stride) = probe_step(rate);
        let inputs = profile_inputs(&profile, dt_us, self.model.supply_v);
        // A sample every 10 ms is plenty to compare shapes.
        self.model.run_kept(dt_us, *fx, &inputs, &self.channels, Keep { first: 0, stride }).ok()
    }
}

/// Channels the diagnosis fits: every channel the bench measures. The throttle voltage
/// too: the twin runs on the recorded set points, so the recorded voltage is a response
/// of the throttle's measurement chain, and a chain fault on it (a channel recorded
/// 40 ms late) is found there or nowhere; no physical effect moves it.
pub fn fitted_channels() -> Vec<Channel> {
    model_core::MEASURED.to_vec()
}

/// A recorded run of TP07 at `throttle` and `load` scales (no measurement: the tests'
/// twin on a real profile), recording `channels`.
#[cfg(test)]
pub(crate) fn tp07_run(throttle: f32, load: f32, channels: Vec<Channel>) -> RecordedTwin {
    use simrod_twin::{MeasuredTwin, RunGrid};
    let profile = Profile::builtin(Builtin::TP07, throttle, load).expect("a built-in profile");
    let inputs = profile_inputs(&profile, 1000, 24.0);
    let n = inputs.len();
    let grid = RunGrid {
        time_s: (0..n).map(|k| k as f64 * 1e-3).collect(),
        dt_us: 1000,
        resampled: false,
        step_note: String::new(),
        set_points: [vec![], vec![], vec![]],
        gaps: vec![false; n],
        data_notes: Vec::new(),
    };
    let twin = MeasuredTwin { model: ModelOptions::default(), grid, inputs, measured: Vec::new() };
    let none = vec![None; channels.len()];
    RecordedTwin::with_stated(twin, channels, none)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The screening run and the bench-rate run of a profile give a sample at the same
    /// instants (every 10 ms), so the cosine that ranks the profiles and the one the user
    /// is told compare the same samples; and the coarse step stays close to the bench's
    /// on the nominal twin (SuTMotorEnc within 2 % of its span at every sample of TP07:
    /// 13 rpm of 2,156 when written).
    #[test]
    fn screening_and_bench_runs_of_a_profile_sample_the_same_instants() {
        let probe = BuiltinProbe::standard(ModelOptions::default(), vec![Channel::SuTMotorEnc]);
        let screen = probe.run(0, &Effects::NONE, ProbeRate::Screen).expect("screening run");
        let bench = probe.run(0, &Effects::NONE, ProbeRate::Bench).expect("bench-rate run");
        assert_eq!(screen[0].len(), bench[0].len());
        let span = bench[0].iter().fold(0.0_f32, |m, v| m.max(v.abs()));
        let worst = screen[0].iter().zip(&bench[0]).fold(0.0_f32, |m, (a, b)| m.max((a - b).abs()));
        assert!(span > 100.0 && worst < 0.02 * span, "worst {worst} rpm of {span}");
    }
}
