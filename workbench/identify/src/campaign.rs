//! Virtual campaigns: measured runs made by the virtual bench from a model data set
//! (an altered "true" model), in memory. The identification tests use them to check that
//! `simrod identify` recovers a model it was not given; a user can use them the same way
//! to see what a planned campaign can determine before booking the bench.

use std::path::PathBuf;

use model_core::{
    Builtin, Channel, Config, CouplingStiffness, Model, Profile, ProfileSet, RateSet, Simulation, MEASURED,
};

use super::run::Run;
use simrod_io::datadir::ModelData;
use simrod_io::error::CmdError;
use simrod_io::measure::Signal;
use simrod_numerics::stats::Rng;
use simrod_vbench::chain::{measure, ChainOptions, Recorded};
use simrod_vbench::noise::NoiseModel;

/// One run of a campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Profile sets (a built-in's or the data set's, or any other).
    pub sets: Vec<ProfileSet>,
    /// Name used for the run (e.g. `TP11_t0.8_l1`).
    pub name: String,
    pub throttle_scale: f32,
    pub load_scale: f32,
    /// Noise seed.
    pub seed: u64,
    /// The Siemens encoder loses pulses (thesis fig. 5.35/5.36).
    pub miscount: bool,
}

impl Plan {
    /// A built-in profile (from `data`'s profiles when it has them), scaled.
    pub fn builtin(
        data: &ModelData,
        which: Builtin,
        throttle_scale: f32,
        load_scale: f32,
        seed: u64,
    ) -> Self {
        Self {
            sets: data.profile(which.name()).unwrap_or(which.sets()).to_vec(),
            name: format!("{}_t{throttle_scale}_l{load_scale}", which.name()),
            throttle_scale,
            load_scale,
            seed,
            miscount: false,
        }
    }
}

/// How the runs are measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bench {
    /// `None`: exact model values.
    pub noise: Option<NoiseModel>,
    /// Also log the load drives' phase currents (`I_LML_phase`, `I_LMR_phase`) with this
    /// Gaussian noise [A]: what a bench that records the drives' own current reports.
    pub phase_current_sd: Option<f64>,
    /// DPU voltage [V].
    pub supply_v: f32,
}

impl Default for Bench {
    fn default() -> Self {
        Self { noise: Some(NoiseModel::default()), phase_current_sd: None, supply_v: 24.0 }
    }
}

/// Run the model of `data` (identified rate set and coupling) on `plan` and measure it.
pub fn bench_run(data: &ModelData, plan: &Plan, bench: &Bench) -> Result<Run, CmdError> {
    let usage = |m: String| CmdError::Usage(format!("{}: {m}", plan.name));
    let cfg = Config {
        params: data.params(RateSet::Identified, CouplingStiffness::Identified),
        ..Config::default()
    };
    let maps = data.maps().map_err(|e| usage(e.to_string()))?;
    let model = Model::with_maps(&cfg, maps).map_err(|e| usage(format!("{e:?}")))?;
    let profile = Profile::new(&plan.sets, plan.throttle_scale, plan.load_scale)
        .map_err(|e| usage(format!("profile: {e:?}")))?;
    let sim = Simulation::from_model(model, profile, bench.supply_v);
    let n = usize::try_from(sim.total_steps()).unwrap_or(0);
    let mut rec = Recorded {
        t_us: Vec::with_capacity(n),
        dt_s: f64::from(sim.model().dt_us()) * 1e-6,
        measured: vec![Vec::with_capacity(n); MEASURED.len()],
        setpoints: std::array::from_fn(|_| Vec::with_capacity(n)),
    };
    let mut phase = [Vec::with_capacity(n), Vec::with_capacity(n)];
    for o in sim {
        rec.t_us.push(o.t_us);
        for (s, c) in rec.measured.iter_mut().zip(MEASURED) {
            s.push(o.get(*c));
        }
        for (s, c) in rec.setpoints.iter_mut().zip([Channel::ThrottleSp, Channel::LoadLSp, Channel::LoadRSp])
        {
            s.push(o.get(c));
        }
        phase[0].push(o.get(Channel::ILmlPhase));
        phase[1].push(o.get(Channel::ILmrPhase));
    }
    let opts = ChainOptions { noise: bench.noise, seed: plan.seed, miscount: plan.miscount };
    let source = PathBuf::from(format!("{}.csv", plan.name));
    let mut meas = measure(&rec, &opts, &source);
    if let Some(sd) = bench.phase_current_sd {
        for (k, (c, v)) in [Channel::ILmlPhase, Channel::ILmrPhase].iter().zip(&phase).enumerate() {
            let mut rng = Rng::new(plan.seed, 300 + k as u64);
            let values = v.iter().map(|x| f64::from(*x) + sd * rng.gauss()).collect();
            meas.signals.push(Signal { name: c.name().into(), unit: c.unit().into(), values });
        }
    }
    Ok(Run::new(format!("{}.csv", plan.name), meas)?)
}

/// TP11 runs: loads at 0 for each throttle scale in `unloaded`, and every
/// `(throttle, load)` scale pair in `loaded`; seeds count up from `seed`.
pub fn tp11(data: &ModelData, unloaded: &[f32], loaded: &[(f32, f32)], seed: u64) -> Vec<Plan> {
    let pairs = unloaded.iter().map(|t| (*t, 0.0)).chain(loaded.iter().copied());
    pairs.enumerate().map(|(k, (t, l))| Plan::builtin(data, Builtin::TP11, t, l, seed + k as u64)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identify_campaign_runs_measure_the_given_model() {
        let mut data = ModelData::builtin().unwrap();
        data.speed_fwd.y.iter_mut().for_each(|v| *v *= 0.5);
        let plan = Plan::builtin(&data, Builtin::TP12, 1.0, 0.0, 3);
        let bench = Bench { noise: None, phase_current_sd: Some(0.5), supply_v: 24.0 };
        let run = bench_run(&data, &plan, &bench).unwrap();
        assert_eq!(run.name, "TP12_t1_l0.csv");
        let speed = run.signal("SuTMotorEnc").unwrap();
        // TP12 holds 50 % (mapped 33.3 %) from 2 s to 8 s: half the base map's 1023 rpm.
        let v = speed[7_900];
        assert!((v - 0.5 * 1023.33).abs() < 1.0, "{v}");
        assert!(run.signal("I_LML_phase").is_some() && run.signal("P_SuT_inv").is_some());
    }
}
