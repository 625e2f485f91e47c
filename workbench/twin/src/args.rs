//! The model flags every command shares, declared once and flattened into each
//! command's arguments (`#[command(flatten)]`), then turned once into the typed
//! [`ModelOptions`] the libraries take.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use clap::{Args, ValueEnum};
use model_core::{CouplingStiffness, Effects, RateSet, SpeedTarget};

use super::{ModelOptions, SensorModel};
use simrod_io::datadir::ModelData;
use simrod_io::effects_file::load_effects;
use simrod_io::error::{CmdError, FileError};
use simrod_vbench::noise::NoiseModel;

/// DPU voltage range of the bench [V].
pub const SUPPLY_V_RANGE: (f32, f32) = (12.0, 30.0);

/// What the twin is: the same flags, help and defaults in every command.
#[derive(Debug, Clone, Args)]
pub struct ModelArgs {
    /// Effect file (TOML) switching on effects beyond the thesis model (for `diagnose`:
    /// the effects already in the model; it looks for what is missing on top of them).
    #[arg(long, value_name = "FILE.toml")]
    pub effects: Option<PathBuf>,

    /// Curtis rate parameters: as programmed (table 5.16) or as identified (5.17).
    #[arg(long, value_enum, default_value_t = RatesArg::Identified)]
    pub params: RatesArg,

    /// Target speed from the identified map, or from the Max Speed parameter.
    #[arg(long, value_enum, default_value_t = SpeedTargetArg::Map)]
    pub speed_target: SpeedTargetArg,

    /// Coupling stiffness: identified (4369 N m/rad) or datasheet (10310 N m/rad).
    #[arg(long, value_enum, default_value_t = CouplingArg::Identified)]
    pub coupling: CouplingArg,

    /// DPU supply voltage set point [V], 12..=30 as on the bench (an input of the twin;
    /// the busbar voltage is an output).
    #[arg(long, value_name = "V", default_value_t = 24.0, value_parser = parse_supply_v, allow_negative_numbers = true)]
    pub supply_v: f32,

    /// Model data directory (parameters.toml and the CSV maps, the format of
    /// model-core/data) to run instead of the built-in data: an altered or identified
    /// model without rebuilding. Its profiles/ (if any) replace the built-in profiles.
    #[arg(long, value_name = "DIR")]
    pub data_dir: Option<PathBuf>,
}

/// How the bench recorded the file: the commands that compare the twin with a
/// measurement flatten this next to [`ModelArgs`].
#[derive(Debug, Clone, Args)]
pub struct SensorArgs {
    /// [s] the bench's speed-counting window: encoder pulses counted over this window,
    /// centred on each sample (0.1 s on the SimRod bench); the twin's speeds get the same
    /// average. 0: the speeds are not window-counted (a `simrod simulate` file or a
    /// `simrod bench --noise none` run).
    #[arg(long, value_name = "S", default_value_t = SensorModel::bench().speed_window_s, value_parser = parse_speed_window, allow_negative_numbers = true)]
    pub speed_window_s: f64,
    /// Noise the sensors are stated to have, in the bench's noise-file format
    /// (workbench/examples/noise.toml; `default`: the SimRod bench's, that file's
    /// values). Each analog channel's residual faster than 0.25 s is then tested over
    /// each run against it, so model error that fast is not taken for noise. Without it
    /// the noise is only what the residual shows.
    #[arg(long, value_name = "default|FILE")]
    pub sensor_noise: Option<PathBuf>,
}

impl Default for ModelArgs {
    /// The flags' defaults: the built-in thesis model.
    fn default() -> Self {
        Self {
            effects: None,
            params: RatesArg::Identified,
            speed_target: SpeedTargetArg::Map,
            coupling: CouplingArg::Identified,
            supply_v: 24.0,
            data_dir: None,
        }
    }
}

impl Default for SensorArgs {
    /// The SimRod bench's counting window.
    fn default() -> Self {
        Self { speed_window_s: SensorModel::bench().speed_window_s, sensor_noise: None }
    }
}

impl SensorArgs {
    /// The sensor model these flags describe (reads the stated noise's file).
    pub fn model(&self) -> Result<SensorModel, CmdError> {
        let stated = match self.sensor_noise.as_deref() {
            None => None,
            Some(p) if p == Path::new("default") => Some(NoiseModel::default()),
            Some(p) => Some(NoiseModel::load(p).map_err(|e| file_error("--sensor-noise", e))?),
        };
        Ok(SensorModel { stated, ..SensorModel::counting(self.speed_window_s) })
    }
}

impl ModelArgs {
    /// Load the files the flags name and give the typed options (sensors: as simulated;
    /// set them from [`SensorArgs`] where a measurement is compared).
    pub fn load(&self) -> Result<ModelOptions, CmdError> {
        let data = match &self.data_dir {
            Some(dir) => Some(Arc::new(ModelData::load(dir).map_err(|e| file_error("--data-dir", e))?)),
            None => None,
        };
        let effects = match &self.effects {
            Some(path) => load_effects(path).map_err(|e| file_error("--effects", e))?,
            None => Effects::NONE,
        };
        Ok(ModelOptions {
            data,
            effects,
            rates: self.params.into(),
            speed_target: self.speed_target.into(),
            coupling: self.coupling.into(),
            supply_v: check_supply_v(self.supply_v)
                .map_err(|m| CmdError::Usage(format!("--supply-v: {m}")))?,
            sensors: SensorModel::NONE,
        })
    }

    /// The input files these flags name (effect file, data directory), for the check
    /// that no output replaces an input.
    pub fn inputs(&self) -> simrod_io::guard::Inputs {
        simrod_io::guard::Inputs::new()
            .file("--effects", self.effects.as_deref())
            .dir("--data-dir", self.data_dir.as_deref())
    }

    /// One line naming the model choices, for summaries.
    pub fn describe(&self) -> String {
        format!(
            "rates {}, speed target {}, coupling {} | effects {} | data {}",
            value_name(self.params),
            value_name(self.speed_target),
            value_name(self.coupling),
            self.effects.as_deref().map_or("none".to_string(), |p| p.display().to_string()),
            self.data_dir.as_deref().map_or("built-in".to_string(), |p| p.display().to_string()),
        )
    }
}

/// The name clap shows for a value.
pub fn value_name<T: ValueEnum>(v: T) -> String {
    v.to_possible_value().map_or_else(String::new, |p| p.get_name().to_string())
}

/// A file that cannot be read at all is named with its flag; errors inside a file keep
/// the `file:line:col:` form editors understand.
pub fn file_error(flag: &str, e: FileError) -> CmdError {
    if e.line.is_none() {
        CmdError::Usage(format!("{flag} {e}"))
    } else {
        e.into()
    }
}

/// `--params`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RatesArg {
    Programmed,
    Identified,
}

/// `--speed-target`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SpeedTargetArg {
    Map,
    Parameter,
}

/// `--coupling`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CouplingArg {
    Identified,
    Datasheet,
}

impl From<RatesArg> for RateSet {
    fn from(a: RatesArg) -> Self {
        match a {
            RatesArg::Programmed => RateSet::Programmed,
            RatesArg::Identified => RateSet::Identified,
        }
    }
}

impl From<SpeedTargetArg> for SpeedTarget {
    fn from(a: SpeedTargetArg) -> Self {
        match a {
            SpeedTargetArg::Map => SpeedTarget::Map,
            SpeedTargetArg::Parameter => SpeedTarget::Parameter,
        }
    }
}

impl From<CouplingArg> for CouplingStiffness {
    fn from(a: CouplingArg) -> Self {
        match a {
            CouplingArg::Identified => CouplingStiffness::Identified,
            CouplingArg::Datasheet => CouplingStiffness::Datasheet,
        }
    }
}

/// Checks a supply voltage against the bench's range.
pub fn check_supply_v(v: f32) -> Result<f32, String> {
    let (lo, hi) = SUPPLY_V_RANGE;
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(format!("expected a voltage in [{lo}, {hi}] V (the bench's range), got {v}"))
    }
}

/// `--supply-v` value.
pub fn parse_supply_v(s: &str) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("expected a voltage in [{}, {}] V", SUPPLY_V_RANGE.0, SUPPLY_V_RANGE.1))?;
    check_supply_v(v)
}

/// `--speed-window-s` value: 0 (off) up to 5 s.
pub fn parse_speed_window(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && (0.0..=5.0).contains(&v) => Ok(v),
        _ => Err("expected a window in seconds, 0 (off) to 5".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_window_is_checked() {
        assert_eq!(parse_speed_window("0.1"), Ok(0.1));
        assert_eq!(parse_speed_window("0"), Ok(0.0));
        assert!(parse_speed_window("-0.1").is_err());
        assert!(parse_speed_window("NaN").is_err());
        assert!(parse_speed_window("6").is_err());
    }

    #[test]
    fn model_flags_become_options() {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            model: ModelArgs,
            #[command(flatten)]
            sensors: SensorArgs,
        }
        let cli = <Cli as clap::Parser>::try_parse_from(["x", "--params", "programmed", "--supply-v", "18"])
            .unwrap();
        let o = cli.model.load().unwrap();
        assert_eq!(o.rates, RateSet::Programmed);
        assert_eq!(o.supply_v, 18.0);
        assert_eq!(cli.sensors.model().unwrap(), SensorModel::bench());
        assert!(<Cli as clap::Parser>::try_parse_from(["x", "--supply-v", "40"]).is_err());
        let d = <Cli as clap::Parser>::try_parse_from(["x"]).unwrap();
        assert_eq!(
            format!("{:?}", d.model),
            format!("{:?}", ModelArgs::default()),
            "Default = clap defaults"
        );
        assert_eq!(d.sensors.speed_window_s, SensorArgs::default().speed_window_s);
        let stated = <Cli as clap::Parser>::try_parse_from(["x", "--sensor-noise", "default"]).unwrap();
        assert_eq!(stated.sensors.model().unwrap().stated, Some(NoiseModel::default()));
        let bad =
            <Cli as clap::Parser>::try_parse_from(["x", "--sensor-noise", "/nonexistent/n.toml"]).unwrap();
        let e = bad.sensors.model().unwrap_err().to_string();
        assert!(e.contains("--sensor-noise") && e.contains("/nonexistent/n.toml"), "{e}");
        let missing = ModelArgs { data_dir: Some("/nonexistent/dir".into()), ..cli.model };
        assert!(missing.load().unwrap_err().to_string().contains("/nonexistent/dir"));
    }
}
