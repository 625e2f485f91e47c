//! `simrod identify <what> RUNS... --out DIR`: rebuild the model's maps and parameters
//! from measured campaigns (thesis chapter 5), improving on the thesis where it says
//! its procedure was weak.
//!
//! Every steady-state identification goes through [`plateau`] (automatic plateau
//! detection, mean, rms, rejection with reasons), fits by weighted least squares with
//! uncertainties ([`simrod_numerics::linalg::wls`]), and hands back an [`Identification`]: the
//! base data set with the identified files replaced (so the output directory is a
//! complete model data directory for `--data-dir` or `model-core/data`) and a
//! [`report::Report`].
//!
//! - [`maps`]: `speed-map`, `load-maps`, `power-maps` (grids of the base model's files,
//!   least squares on the interpolation basis, unobserved cells keep the base value and
//!   are marked);
//! - [`friction`]: per side, odd cubic/linear law with the threshold optimised;
//! - [`resistance`]: connector resistance from the plateaus' voltage drop;
//! - [`campaign`]: virtual campaigns (runs measured by the virtual bench from any data
//!   set), for the proofs and for planning a campaign.
//!
//! Chaining: run `friction` first and pass its output as `--data-dir` to `load-maps`
//! (the load torque is the flange torque minus the friction at the plateau's speed).

/// Virtual-bench campaigns for the identification proofs (tests only, not the
/// public library).
#[cfg(any(test, feature = "proof"))]
pub mod campaign;
pub mod friction;
pub mod maps;
pub mod plateau;
pub use simrod_io::progress;
pub mod report;
pub mod resistance;
pub mod run;
// The transient identifications: inertia, inverter-rates, stiffness.
pub mod estimate;
pub mod inertia;
pub mod rates;
pub mod stiffness;
#[cfg(test)]
mod transient_proofs;
pub mod transients;

use model_core::{CouplingStiffness, Params, RateSet};

use plateau::{Extraction, PlateauOptions};
use progress::Progress;
use report::Report;
use run::Run;
use simrod_io::datadir::ModelData;
use simrod_io::error::CmdError;
use simrod_io::uncertainty_file::{format_uncertainty, Dist, Target, Uncertain};

/// The file [`Identification::write`] puts the identified values' uncertainties in.
pub const UNCERTAINTY_FILE: &str = "uncertainty.toml";

/// What to identify.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum What {
    SpeedMap,
    LoadMaps,
    PowerMaps,
    Friction,
    Resistance,
    Inertia,
    InverterRates,
    Stiffness,
}

impl What {
    /// The subcommand name.
    pub fn name(self) -> &'static str {
        match self {
            What::SpeedMap => "speed-map",
            What::LoadMaps => "load-maps",
            What::PowerMaps => "power-maps",
            What::Friction => "friction",
            What::Resistance => "resistance",
            What::Inertia => "inertia",
            What::InverterRates => "inverter-rates",
            What::Stiffness => "stiffness",
        }
    }
}

/// What every identification gets.
pub struct Context<'a> {
    pub runs: &'a [Run],
    /// The model identified against: its grids, and its values where the data say nothing.
    pub base: &'a ModelData,
    pub rates: RateSet,
    pub coupling: CouplingStiffness,
    pub plateau: PlateauOptions,
    pub progress: &'a Progress,
}

impl<'a> Context<'a> {
    /// Defaults: identified rates, identified coupling, default plateau options with the
    /// base model's gear ratio for the encoder cross-check.
    pub fn new(runs: &'a [Run], base: &'a ModelData, progress: &'a Progress) -> Self {
        let mut c = Self {
            runs,
            base,
            rates: RateSet::Identified,
            coupling: CouplingStiffness::Identified,
            plateau: PlateauOptions::default(),
            progress,
        };
        c.plateau.gear_ratio = Some(f64::from(c.params().sut_gear_ratio));
        c
    }

    /// The base model's scalar parameters.
    pub fn params(&self) -> Params {
        self.base.params(self.rates, self.coupling)
    }

    /// Plateaus of every run for `channels`, with a progress bar.
    pub fn extract(&self, channels: &[&str]) -> Extraction {
        let p = self.progress.phase("plateaus", self.runs.len());
        plateau::extract(self.runs, channels, &self.plateau, &p)
    }
}

/// The result of one identification.
#[derive(Debug, Clone)]
pub struct Identification {
    /// The base data with the identified files or values replaced.
    pub data: ModelData,
    /// Files (or `parameters.toml` keys) that changed.
    pub changed: Vec<String>,
    pub report: Report,
    /// Per fitted map file: which grid values the data determined, and their standard
    /// deviations (NaN where the base value was kept).
    pub fits: Vec<MapFit>,
    /// Scalar results with their standard uncertainty (friction law, resistance, ...).
    pub values: Vec<Value>,
}

/// An identified number.
#[derive(Debug, Clone, PartialEq)]
pub struct Value {
    /// E.g. `connector_resistance`, `friction_L.f_t`.
    pub name: String,
    pub value: f64,
    /// One standard deviation.
    pub sd: f64,
    pub unit: String,
}

/// Which values of a written map were identified.
#[derive(Debug, Clone, PartialEq)]
pub struct MapFit {
    /// File name, e.g. `load_torque_L.csv`.
    pub file: String,
    /// One per grid value (row-major for 2-D maps).
    pub observed: Vec<bool>,
    pub sd: Vec<f64>,
}

impl Identification {
    /// The value called `name`.
    pub fn value(&self, name: &str) -> Option<&Value> {
        self.values.iter().find(|v| v.name == name)
    }

    /// Write the complete data directory, `report.md`, the charts and
    /// `uncertainty.toml` into `dir`; returns every file written.
    pub fn write(&self, dir: &std::path::Path) -> std::io::Result<Vec<std::path::PathBuf>> {
        let mut files = self.data.write(dir)?;
        files.extend(self.report.write(dir)?);
        let p = dir.join(UNCERTAINTY_FILE);
        let text = self.uncertainty_toml();
        simrod_io::atomic::write_atomic(&p, |w| w.write_all(text.as_bytes()))?;
        files.push(p);
        Ok(files)
    }

    /// The identified parameters' standard uncertainties in the format `simrod check
    /// --from-identify` reads: a normal around each determined `parameters.toml` value.
    /// Map values and law coefficients (friction fit) are not parameters a Monte Carlo
    /// can set, so they stay in report.md only.
    pub fn uncertainty_toml(&self) -> String {
        let items: Vec<Uncertain> = self
            .values
            .iter()
            .filter(|v| v.sd.is_finite() && v.sd > 0.0 && self.data.param(&v.name).is_some())
            .map(|v| Uncertain {
                target: Target::Param(v.name.clone()),
                dist: Dist::Normal { mean: Some(v.value), sd: v.sd },
                origin: String::new(),
            })
            .collect();
        format_uncertainty(
            &items,
            "simrod identify: the identified parameters, each a normal around its value with its\n\
             standard uncertainty (simrod check --from-identify DIR reads this file).",
        )
    }
}

/// Run one identification.
pub fn identify(what: What, ctx: &Context<'_>) -> Result<Identification, CmdError> {
    if ctx.runs.is_empty() {
        return Err(CmdError::Usage("no runs given".into()));
    }
    match what {
        What::SpeedMap => maps::speed_map(ctx),
        What::LoadMaps => maps::load_maps(ctx),
        What::PowerMaps => maps::power_maps(ctx),
        What::Friction => friction::identify(ctx),
        What::Resistance => resistance::identify(ctx),
        What::Inertia | What::InverterRates | What::Stiffness => transient(what, ctx),
    }
}

/// The transient identifications: `inertia` (5.3.2), `inverter-rates` (5.6) and
/// `stiffness` (5.4). Each gives an `estimate::Outcome` (values with uncertainties, or
/// undetermined with the reason), turned into the same [`Identification`] as the maps.
fn transient(what: What, ctx: &Context<'_>) -> Result<Identification, CmdError> {
    let runs: Vec<&simrod_io::measure::Measurement> = ctx.runs.iter().map(|r| &r.meas).collect();
    let params = ctx.params();
    let maps = ctx.base.maps().map_err(|e| CmdError::Usage(format!("base data: {e}")))?;
    let bar = ctx.progress.phase(what.name(), 1);
    let outcome = match what {
        What::Inertia => inertia::identify_inertia(&runs, &inertia::InertiaOptions { params, maps })?,
        What::InverterRates => {
            rates::identify_rates(&runs, &rates::RatesOptions { params, maps, bootstrap: 200 })?
        }
        _ => {
            let o = stiffness::StiffnessOptions {
                base: f64::from(params.coupling_stiffness),
                ..stiffness::StiffnessOptions::default()
            };
            stiffness::identify_stiffness(&runs, &o)?
        }
    };
    bar.tick(what.name());
    bar.finish();
    Ok(outcome.finish(ctx))
}

#[cfg(test)]
mod tests {
    use super::*;
    use simrod_io::uncertainty_file::parse_uncertainty;

    #[test]
    fn uncertainty_file_holds_the_determined_parameters_only() {
        let v = |name: &str, value: f64, sd: f64| Value { name: name.into(), value, sd, unit: "-".into() };
        let id = Identification {
            data: ModelData::builtin().unwrap(),
            changed: Vec::new(),
            report: Report::new("t"),
            fits: Vec::new(),
            values: vec![
                v("connector_resistance", 0.0301, 0.0012),
                v("friction_L.f_t", 8.0, 0.3),
                v("ident.accel_hs_fwd_s", 3.9, 0.1),
                v("load_inertia_l", 0.45, f64::NAN),
            ],
        };
        let u = parse_uncertainty(&id.uncertainty_toml(), "u.toml").unwrap();
        let got: Vec<(String, Dist)> = u.iter().map(|x| (x.target.name(), x.dist)).collect();
        assert_eq!(
            got,
            vec![
                ("connector_resistance".into(), Dist::Normal { mean: Some(0.0301), sd: 0.0012 }),
                ("ident.accel_hs_fwd_s".into(), Dist::Normal { mean: Some(3.9), sd: 0.1 }),
            ]
        );
    }
}
