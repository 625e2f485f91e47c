//! `simrod bench --plant physics`: the physics plant (`simrod-plant`) run to make the
//! exact channels a measurement chain then records ([`crate::chain::Recorded`]).

use model_core::{Maps, Params, Profile, ProfileSet, SpeedTarget, MEASURED};
use simrod_plant::plant::BENCH_STEP_NS;
use simrod_plant::{step_for, Plant, PlantEffects, Setup};

use crate::chain::Recorded;

/// What the plant runs: the bench's data (maps and parameters, possibly perturbed), the
/// profile, the supply and the effects.
pub struct PlantRun<'a> {
    pub params: Params,
    pub maps: Maps<'a>,
    pub speed_target: SpeedTarget,
    pub profile: &'a Profile,
    pub supply_v: f32,
    /// [µs] output interval (the file's rows).
    pub every_us: u32,
    pub library: model_core::Effects,
    pub plant: PlantEffects,
}

/// Run the plant to the end of the profile and keep what the bench records. Errors
/// (effects out of range, a diverging or collapsing run) are messages for the user.
pub fn record(run: &PlantRun<'_>) -> Result<Recorded, String> {
    let sets: Vec<ProfileSet> = run.profile.sets().collect();
    let (ts, ls) = run.profile.scales();
    let setup = Setup {
        params: run.params,
        maps: run.maps,
        speed_target: run.speed_target,
        sets: &sets,
        throttle_scale: f64::from(ts),
        load_scale: f64::from(ls),
        supply_v: f64::from(run.supply_v),
        library: run.library,
        bench: run.plant,
    };
    let every = u64::from(run.every_us);
    let plant = Plant::new(&setup, step_for(every, BENCH_STEP_NS)).map_err(|e| e.to_string())?;
    let (samples, setpoints) = plant.run_logged(every).map_err(|e| e.to_string())?;
    let n = samples.len();
    let mut rec = Recorded {
        t_us: samples.iter().map(|s| s.t_us).collect(),
        dt_s: every as f64 * 1e-6,
        measured: vec![Vec::with_capacity(n); MEASURED.len()],
        setpoints: std::array::from_fn(|_| Vec::with_capacity(n)),
    };
    for (series, c) in rec.measured.iter_mut().zip(MEASURED) {
        series.extend(samples.iter().map(|s| s.get(*c).unwrap_or(f64::NAN) as f32));
    }
    for sp in &setpoints {
        rec.setpoints[0].push(sp.throttle as f32);
        rec.setpoints[1].push(sp.load[0] as f32);
        rec.setpoints[2].push(sp.load[1] as f32);
    }
    Ok(rec)
}
