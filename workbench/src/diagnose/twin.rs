//! Twins for the diagnosis: the model driven by recorded set points (a measured run) or
//! by a built-in profile (to find a separating experiment).

use model_core::{Builtin, Channel, Config, Effects, Inputs, Model, Profile, Simulation};

use super::engine::{ProfileProbe, Twin};
use crate::sensor_model::{half_width, window_average, SPEED_CHANNELS};

/// Apply the bench's speed-counting window to the simulated speed channels.
fn sense(out: &mut [Vec<f32>], channels: &[Channel], dt: f64, window_s: f64) {
    let half = half_width(window_s, dt);
    for (v, c) in out.iter_mut().zip(channels) {
        if SPEED_CHANNELS.contains(c) {
            *v = window_average(v, dt, half);
        }
    }
}

/// The model driven, one step per sample, by the set points recorded with a run.
///
/// Row `k` of a run holds the set points applied during step `k` and the outputs at the
/// end of it (the convention of `simrod bench` and `simrod simulate`).
pub struct RecordedTwin {
    /// Configuration (its effects are replaced per run).
    pub config: Config,
    /// Inputs per sample.
    pub inputs: Vec<Inputs>,
    /// Channels to return.
    pub channels: Vec<Channel>,
    /// [s] the bench's speed-counting window (0: speeds as simulated).
    pub speed_window_s: f64,
}

impl Twin for RecordedTwin {
    fn channels(&self) -> &[Channel] {
        &self.channels
    }
    fn samples(&self) -> usize {
        self.inputs.len()
    }
    fn dt_s(&self) -> f64 {
        f64::from(self.config.dt_us) * 1e-6
    }
    fn run(&self, fx: &Effects) -> Result<Vec<Vec<f32>>, String> {
        let cfg = Config { effects: *fx, ..self.config };
        let mut m = Model::new(&cfg).map_err(|e| format!("model: {e:?}"))?;
        let mut out: Vec<Vec<f32>> =
            self.channels.iter().map(|_| Vec::with_capacity(self.inputs.len())).collect();
        for inp in &self.inputs {
            let o = m.step(inp);
            for (v, c) in out.iter_mut().zip(&self.channels) {
                v.push(o.get(*c));
            }
        }
        sense(&mut out, &self.channels, self.dt_s(), self.speed_window_s);
        Ok(out)
    }
}

/// Set points of a profile run, as a recorded run would carry them.
pub fn profile_inputs(profile: &Profile, dt_us: u32, supply_v: f32) -> Vec<Inputs> {
    let n = profile.duration_us().div_ceil(u64::from(dt_us));
    (0..n).map(|k| Inputs { sp: profile.at(k * u64::from(dt_us)), supply_v }).collect()
}

/// The built-in profiles at a few scalings: the experiments a user could run next.
pub struct BuiltinProbe {
    /// Configuration (its effects are replaced per run).
    pub config: Config,
    /// Channels to return.
    pub channels: Vec<Channel>,
    /// (profile, throttle scale, load scale) candidates.
    pub candidates: Vec<(Builtin, f32, f32)>,
    /// [s] the bench's speed-counting window.
    pub speed_window_s: f64,
}

impl BuiltinProbe {
    /// Forward and reverse, with and without loads, every built-in profile.
    pub fn standard(config: Config, channels: Vec<Channel>, speed_window_s: f64) -> Self {
        let mut candidates = Vec::new();
        for b in Builtin::ALL {
            for (ts, ls) in [(1.0, 1.0), (0.79, 0.0), (-1.0, 0.0), (0.79, -1.0)] {
                candidates.push((b, ts, ls));
            }
        }
        Self { config, channels, candidates, speed_window_s }
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
        let cfg = Config { effects: *fx, ..self.config };
        let sim = Simulation::new(&cfg, Profile::builtin(b, ts, ls).ok()?, 24.0).ok()?;
        let mut out: Vec<Vec<f32>> = self.channels.iter().map(|_| Vec::new()).collect();
        let dt = f64::from(self.config.dt_us) * 1e-6;
        for o in sim {
            for (v, c) in out.iter_mut().zip(&self.channels) {
                v.push(o.get(*c));
            }
        }
        sense(&mut out, &self.channels, dt, self.speed_window_s);
        // Every 10th step is plenty to compare shapes.
        Some(out.into_iter().map(|v| v.into_iter().step_by(10).collect()).collect())
    }
}

/// Channels the diagnosis fits: the bench's measured channels except the throttle
/// voltage (it is an input, not a response).
pub fn fitted_channels() -> Vec<Channel> {
    model_core::MEASURED.iter().copied().filter(|c| *c != Channel::Throttle).collect()
}
