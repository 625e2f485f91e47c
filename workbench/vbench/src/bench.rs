//! One virtual-bench run, the one path every caller takes (`simrod bench`, `simrod
//! demo`, the diagnose proofs, the random-case generator): a plant (the physics plant
//! or the twin) makes the exact channels, the acquisition's effects act on them, the
//! measurement chain records them, the converter clips and quantises.

use std::path::Path;

use model_core::{Config, Maps, Model, Params, Profile, ProfileSet, Simulation, SpeedTarget, MEASURED};
use simrod_io::measure::Measurement;
use simrod_plant::plant::BENCH_STEP_NS;
use simrod_plant::profile::SetPoints;
use simrod_plant::{step_for, Plant, Setup, PLANT_EFFECTS};

use crate::bench_effects::BenchEffects;
use crate::chain::{measure, pulse_channels, ChainOptions, Recorded};

/// Which plant makes the "measurement".
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlantKind {
    /// The independent physics plant (`simrod-plant`): the default, a bench the twin did
    /// not write.
    #[default]
    Physics,
    /// The twin itself (tests that need the twin's own bits).
    Twin,
}

/// What to run.
pub struct BenchRun<'a> {
    pub plant: PlantKind,
    /// The bench's data (maps and parameters), possibly perturbed.
    pub params: Params,
    pub maps: Maps<'a>,
    pub speed_target: SpeedTarget,
    pub profile: &'a Profile,
    pub supply_v: f32,
    /// [µs] the file's sample interval (the twin's step).
    pub dt_us: u32,
    pub effects: &'a BenchEffects,
    pub chain: ChainOptions,
    /// Also export the R shaft's pulse channels.
    pub pulses: bool,
}

impl BenchRun<'_> {
    /// The exact channels the plant makes, acquisition effects not yet applied.
    pub fn exact(&self) -> Result<Recorded, String> {
        match self.plant {
            PlantKind::Physics => self.physics(),
            PlantKind::Twin => self.twin(),
        }
    }

    /// The physics plant run to the end of the profile; its errors (effects out of
    /// range, a diverging or collapsing run) are messages for the user.
    fn physics(&self) -> Result<Recorded, String> {
        let sets: Vec<ProfileSet> = self.profile.sets().collect();
        let (ts, ls) = self.profile.scales();
        let setup = Setup {
            params: self.params,
            maps: self.maps,
            speed_target: self.speed_target,
            sets: &sets,
            throttle_scale: f64::from(ts),
            load_scale: f64::from(ls),
            supply_v: f64::from(self.supply_v),
            library: self.effects.library,
            bench: self.effects.plant,
        };
        let every = u64::from(self.dt_us);
        let plant = Plant::new(&setup, step_for(every, BENCH_STEP_NS)).map_err(|e| e.to_string())?;
        let (samples, setpoints) = plant.run_logged(every).map_err(|e| e.to_string())?;
        // The plant's channels start with `MEASURED`, in its order.
        let measured =
            (0..MEASURED.len()).map(|i| samples.iter().map(|s| s.values[i] as f32).collect()).collect();
        let sp = |f: fn(&SetPoints) -> f64| setpoints.iter().map(|p| f(p) as f32).collect();
        Ok(Recorded {
            t_us: samples.iter().map(|s| s.t_us).collect(),
            dt_s: every as f64 * 1e-6,
            measured,
            setpoints: [sp(|p| p.throttle), sp(|p| p.load[0]), sp(|p| p.load[1])],
        })
    }

    /// The twin run to the end of the profile (library effects only).
    fn twin(&self) -> Result<Recorded, String> {
        let on: Vec<&str> =
            PLANT_EFFECTS.iter().map(|e| e.id).filter(|id| self.effects.plant.is_on(id)).collect();
        if !on.is_empty() {
            return Err(format!(
                "{} is physics the twin does not have: run it with --plant physics",
                on.join(", ")
            ));
        }
        let cfg = Config {
            dt_us: self.dt_us,
            params: self.params,
            speed_target: self.speed_target,
            effects: self.effects.library,
        };
        let model = Model::with_maps(&cfg, self.maps).map_err(|e| format!("{e:?}"))?;
        let rec = Recorded::run(Simulation::from_model(model, self.profile.clone(), self.supply_v));
        diverged(&rec).map_or(Ok(rec), Err)
    }

    /// The measurement file's content; `source` names it.
    pub fn measure(&self, source: &Path) -> Result<Measurement, String> {
        Ok(self.record(self.exact()?, source))
    }

    /// What the bench records of the exact channels `rec` (from [`BenchRun::exact`]):
    /// acquisition effects, measurement chain, converter.
    pub fn record(&self, mut rec: Recorded, source: &Path) -> Measurement {
        self.effects.daq.apply_before_noise(&mut rec);
        let mut m = measure(&rec, &self.chain, source);
        if self.pulses {
            m.signals.extend(pulse_channels(&rec, &self.chain));
        }
        self.effects.daq.apply_after_noise(&mut m);
        m
    }
}

/// Why a recorded run is not a result: the earliest non-finite value, with its time
/// and channel (`None`: every value is finite).
fn diverged(rec: &Recorded) -> Option<String> {
    let first = rec
        .measured
        .iter()
        .zip(MEASURED)
        .filter_map(|(series, c)| series.iter().position(|v| !v.is_finite()).map(|k| (k, *c, series[k])))
        .min_by_key(|(k, _, _)| *k)?;
    let (k, c, v) = first;
    let t = rec.t_us.get(k).map_or(f64::NAN, |t| *t as f64 * 1e-6);
    Some(format!("the twin diverged at t = {t:.6} s: {} is {v}", c.name()))
}
