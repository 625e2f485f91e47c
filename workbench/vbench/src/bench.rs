//! One virtual-bench run, the one path every caller takes (`simrod bench`, `simrod
//! demo`, the diagnose proofs, the random-case generator): a plant (the physics plant
//! or the twin) makes the exact channels, the acquisition's effects act on them, the
//! measurement chain records them, the converter clips and quantises.

use std::path::Path;

use model_core::{Config, Maps, Model, Params, Profile, Simulation, SpeedTarget};
use simrod_io::measure::Measurement;

use crate::bench_effects::BenchEffects;
use crate::chain::{measure, pulse_channels, ChainOptions, Recorded};
use crate::physics::{record, PlantRun};

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
            PlantKind::Physics => record(&PlantRun {
                params: self.params,
                maps: self.maps,
                speed_target: self.speed_target,
                profile: self.profile,
                supply_v: self.supply_v,
                every_us: self.dt_us,
                library: self.effects.library,
                plant: self.effects.plant,
            }),
            PlantKind::Twin => {
                if !self.effects.plant.is_none() {
                    let ids: Vec<&str> = self.effects.plant.entries().iter().map(|e| e.0).collect();
                    return Err(format!(
                        "{} is physics the twin does not have: run it with --plant physics",
                        ids.join(", ")
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
        }
    }

    /// The measurement file's content; `source` names it.
    pub fn measure(&self, source: &Path) -> Result<Measurement, String> {
        let mut rec = self.exact()?;
        self.effects.daq.apply_before_noise(&mut rec);
        let mut m = measure(&rec, &self.chain, source);
        if self.pulses {
            m.signals.extend(pulse_channels(&rec, &self.chain));
        }
        self.effects.daq.apply_after_noise(&mut m);
        Ok(m)
    }
}

/// Why a recorded run is not a result: the earliest non-finite value, with its time
/// and channel (`None`: every value is finite).
fn diverged(rec: &Recorded) -> Option<String> {
    let first = rec
        .measured
        .iter()
        .zip(model_core::MEASURED)
        .filter_map(|(series, c)| series.iter().position(|v| !v.is_finite()).map(|k| (k, *c, series[k])))
        .min_by_key(|(k, _, _)| *k)?;
    let (k, c, v) = first;
    let t = rec.t_us.get(k).map_or(f64::NAN, |t| *t as f64 * 1e-6);
    Some(format!("the twin diverged at t = {t:.6} s: {} is {v}", c.name()))
}
