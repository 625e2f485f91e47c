//! What `check` runs: anything that steps the twin and hands over its outputs per step.
//! A test profile is one such run ([`ProfileRun`]); a closed XiL loop (twin plus vehicle
//! twin) is another, plugged in by implementing [`TestRun`].

use std::sync::Arc;

use model_core::drivetrain::SideParams;
use model_core::{Config, Maps, Model, Outputs, Profile, ProfileSet, Simulation};
use simrod_io::datadir::ModelData;

/// The two set-point knobs `check` scales to find a set point that stays inside: for a
/// profile, its throttle and load scaling factors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scales {
    pub throttle: f32,
    pub load: f32,
}

/// Which knob.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Knob {
    Throttle,
    Load,
}

impl Knob {
    /// Both, in report order.
    pub const BOTH: [Knob; 2] = [Knob::Throttle, Knob::Load];

    /// `throttle` / `load`.
    pub fn name(self) -> &'static str {
        match self {
            Knob::Throttle => "throttle",
            Knob::Load => "load",
        }
    }

    /// `s` with this knob's scale multiplied by `f`.
    pub fn scaled(self, s: Scales, f: f32) -> Scales {
        match self {
            Knob::Throttle => Scales { throttle: s.throttle * f, ..s },
            Knob::Load => Scales { load: s.load * f, ..s },
        }
    }

    /// This knob's scale in `s`.
    pub fn of(self, s: Scales) -> f32 {
        match self {
            Knob::Throttle => s.throttle,
            Knob::Load => s.load,
        }
    }
}

/// Receives one run: the model's mechanics first, then every step's outputs.
pub trait StepSink {
    /// Called once, before the first step, with the model's side parameters (after
    /// effects and any drawn parameters).
    fn begin(&mut self, sides: &[SideParams; 2]);
    /// One step's outputs.
    fn step(&mut self, o: &Outputs);
}

/// A test `check` can run: the twin producing outputs per step, at any model
/// configuration (a Monte Carlo sample's parameters) and any set-point scales.
pub trait TestRun: Sync {
    /// One line naming the test, for reports.
    fn title(&self) -> String;
    /// The model configuration of the nominal run (step, parameters, effects).
    fn config(&self) -> &Config;
    /// The scales the test is asked at.
    fn scales(&self) -> Scales;
    /// [µs] the test's duration.
    fn duration_us(&self) -> u64;
    /// The part of the test running at `t_us` (a profile's set), for reports.
    fn phase(&self, t_us: u64) -> String;
    /// Run the test with `config` and `scales`, handing every step to `sink`. A run that
    /// diverges (non-finite outputs) is an error naming the time.
    fn run(&self, config: &Config, scales: Scales, sink: &mut dyn StepSink) -> Result<(), String>;

    /// Why the set-point search does not apply (`None`: it does). A closed loop has no
    /// scales to lower: its driver sets the throttle and its road the load.
    fn no_set_points(&self) -> Option<String> {
        None
    }

    /// Steps of the run.
    fn steps(&self) -> u64 {
        self.duration_us().div_ceil(u64::from(self.config().dt_us.max(1)))
    }
}

/// A test profile: sets, scales, supply voltage and the model.
#[derive(Debug, Clone)]
pub struct ProfileRun {
    pub title: String,
    pub sets: Vec<ProfileSet>,
    pub scales: Scales,
    pub supply_v: f32,
    pub config: Config,
    /// Maps from `--data-dir` (`None`: the built-in maps).
    pub data: Option<Arc<ModelData>>,
    /// [µs] where each set starts, and the end.
    starts: Vec<u64>,
}

impl ProfileRun {
    /// The run of `profile` (its sets and scales) on the model `config` with `data`.
    pub fn new(
        title: String,
        profile: &Profile,
        supply_v: f32,
        config: Config,
        data: Option<Arc<ModelData>>,
    ) -> Self {
        let sets: Vec<ProfileSet> = profile.sets().collect();
        let (throttle, load) = profile.scales();
        // The profile engine's own rounding of set durations (whole µs, at least 1).
        let mut starts = vec![0u64];
        for s in &sets {
            let d = ((f64::from(s.duration_s) * 1.0e6 + 0.5) as u64).max(1);
            starts.push(starts.last().copied().unwrap_or(0) + d);
        }
        Self { title, sets, scales: Scales { throttle, load }, supply_v, config, data, starts }
    }

    fn maps(&self) -> Result<Maps<'_>, String> {
        match &self.data {
            Some(d) => d.maps().map_err(|e| format!("--data-dir: {e}")),
            None => Ok(Maps::builtin()),
        }
    }
}

impl TestRun for ProfileRun {
    fn title(&self) -> String {
        self.title.clone()
    }

    fn config(&self) -> &Config {
        &self.config
    }

    fn scales(&self) -> Scales {
        self.scales
    }

    fn duration_us(&self) -> u64 {
        self.starts.last().copied().unwrap_or(0)
    }

    fn phase(&self, t_us: u64) -> String {
        // Outputs are stamped at the end of their step: the step ending at t ran in the
        // set that holds t − 1 µs.
        let t = t_us.saturating_sub(1);
        let n = self.sets.len();
        match self.starts.windows(2).position(|w| t >= w[0] && t < w[1]) {
            Some(i) => format!("set {}/{n}", i + 1),
            None => "after the profile".into(),
        }
    }

    fn run(&self, config: &Config, scales: Scales, sink: &mut dyn StepSink) -> Result<(), String> {
        let profile = Profile::new(&self.sets, scales.throttle, scales.load)
            .map_err(|e| format!("scales {scales:?}: {e:?}"))?;
        let model =
            Model::with_maps(config, self.maps()?).map_err(|e| format!("the model refuses: {e:?}"))?;
        sink.begin(model.side_params());
        for (k, o) in Simulation::from_model(model, profile, self.supply_v).enumerate() {
            if let Some(c) = o.non_finite() {
                return Err(format!(
                    "the model diverged at step {} (t = {:.6} s): {} is {}",
                    k + 1,
                    o.t_s(),
                    c.name(),
                    o.get(c)
                ));
            }
            sink.step(&o);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::Builtin;

    #[test]
    fn phases_follow_the_sets() {
        let p = Profile::builtin(Builtin::TP07, 1.0, 1.0).unwrap();
        let r = ProfileRun::new("t".into(), &p, 24.0, Config::default(), None);
        assert_eq!(r.duration_us(), p.duration_us());
        assert_eq!(r.phase(1000), "set 1/10");
        assert_eq!(r.phase(3_000_000), "set 1/10", "the step ending at 3 s ran in set 1");
        assert_eq!(r.phase(3_001_000), "set 2/10");
        assert_eq!(r.phase(p.duration_us()), "set 10/10");
        assert_eq!(r.phase(p.duration_us() + 1), "after the profile");
        assert_eq!(Knob::Load.scaled(r.scales(), 0.5), Scales { throttle: 1.0, load: 0.5 });
    }
}
