//! What an FMU runs, as its `resources/` hold it: the settings file (step, start values
//! of the choices and of the supply voltage), an optional effect file and an optional
//! model data directory. The packaging writes these files and then reads them back
//! with [`Spec::load`], the code the FMU runs at instantiation, so the model
//! description is generated from exactly what the binary will load.
//!
//! The effect file and the data directory are read by the workspace's own readers
//! (`simrod_io::effects_file`, `simrod_io::datadir`): an FMU accepts what `simrod
//! simulate --effects/--data-dir` accepts, with the same messages.

use std::fmt::Write as _;
use std::path::Path;

use model_core::model::DT_US_RANGE;
use model_core::{data as d, Config, Effects, Maps, Model, Params};
use serde::Deserialize;
use simrod_io::datadir::ModelData;
use simrod_io::effects_file::load_effects;
use simrod_io::toml_util::{toml_error, toml_f32};

use crate::vars::{Choice, Choices};

/// The settings file in `resources/`.
pub const SETTINGS_FILE: &str = "simrod-fmu.toml";
/// The effect file in `resources/` (optional).
pub const EFFECTS_FILE: &str = "effects.toml";
/// The model data directory in `resources/` (optional; without it the maps compiled
/// into the binary run).
pub const DATA_DIR: &str = "data";

/// The settings file, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SettingsFile {
    dt_us: u32,
    rate_set: String,
    speed_target: String,
    coupling: String,
    supply_voltage: Option<f64>,
}

/// The settings: the twin's step and the start values of the choices and the supply.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// [µs] the twin's fixed step.
    pub dt_us: u32,
    /// Start values of the choices.
    pub choices: Choices,
    /// [V] start value of the supply voltage; `None`: the data's nominal voltage.
    pub supply_v: Option<f64>,
}

impl Default for Settings {
    /// `simrod simulate`'s defaults.
    fn default() -> Self {
        Self { dt_us: 1000, choices: Choices::default(), supply_v: None }
    }
}

impl Settings {
    /// The settings file's text.
    pub fn to_toml(&self) -> String {
        let mut s = String::from(
            "# The SimRod twin's FMU settings, written by `cargo xtask fmu`: the fixed step and\n\
             # the start values the model description declares (changing them here breaks the\n\
             # instantiation token: repackage instead).\n",
        );
        let _ = writeln!(s, "dt_us = {}", self.dt_us);
        for c in Choice::ALL {
            let name = c.item_name(self.choices.get(c)).unwrap_or_default();
            let _ = writeln!(s, "{} = \"{name}\"", c.name());
        }
        if let Some(v) = self.supply_v {
            let _ = writeln!(s, "supply_voltage = {}", toml_f32(v as f32));
        }
        s
    }

    /// Parse the settings file's text; errors are `file:line:col: message`.
    pub fn parse(text: &str, origin: &Path) -> Result<Self, String> {
        let f: SettingsFile = toml::from_str(text).map_err(|e| toml_error(origin, text, &e).to_string())?;
        let place = |m: String| format!("{}: {m}", origin.display());
        if !(DT_US_RANGE.0..=DT_US_RANGE.1).contains(&f.dt_us) {
            return Err(place(format!(
                "dt_us = {}: expected a step in [{}, {}] µs",
                f.dt_us, DT_US_RANGE.0, DT_US_RANGE.1
            )));
        }
        let mut choices = Choices::default();
        choices.set_by_name(Choice::RateSet, &f.rate_set).map_err(place)?;
        choices.set_by_name(Choice::SpeedTarget, &f.speed_target).map_err(place)?;
        choices.set_by_name(Choice::Coupling, &f.coupling).map_err(place)?;
        Ok(Self { dt_us: f.dt_us, choices, supply_v: f.supply_voltage })
    }
}

/// Everything an FMU instance runs, loaded from `resources/`.
#[derive(Debug, Clone, PartialEq)]
pub struct Spec {
    pub settings: Settings,
    /// The effect file's effects (start values of the effect parameters).
    pub effects: Effects,
    /// The data directory; `None`: the maps and parameters compiled into the binary.
    pub data: Option<ModelData>,
}

impl Spec {
    /// Load `resources/` (the directory the importer's resource path names).
    pub fn load(resources: &Path) -> Result<Self, String> {
        let path = resources.join(SETTINGS_FILE);
        let text =
            std::fs::read_to_string(&path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
        let settings = Settings::parse(&text, &path)?;
        let fx_path = resources.join(EFFECTS_FILE);
        let effects =
            if fx_path.exists() { load_effects(&fx_path).map_err(|e| e.to_string())? } else { Effects::NONE };
        let data_dir = resources.join(DATA_DIR);
        let data = if data_dir.exists() {
            Some(ModelData::load(&data_dir).map_err(|e| e.to_string())?)
        } else {
            None
        };
        let spec = Self { settings, effects, data };
        spec.check_supply(spec.supply_start())
            .map_err(|m| format!("{}: supply_voltage: {m}", path.display()))?;
        effects.check_delays(settings.dt_us).map_err(|m| format!("{}: {m}", fx_path.display()))?;
        Ok(spec)
    }

    /// The scalar parameters with the given choices (from the data directory if any).
    pub fn params(&self, c: &Choices) -> Params {
        match &self.data {
            Some(data) => data.params(c.rates, c.coupling),
            None => Params::thesis(c.rates, c.coupling),
        }
    }

    /// The model's tables.
    pub fn maps(&self) -> Result<Maps<'_>, String> {
        match &self.data {
            Some(data) => data.maps().map_err(|e| e.to_string()),
            None => Ok(Maps::builtin()),
        }
    }

    /// A model at rest with the given choices and effects.
    pub fn model(&self, c: &Choices, effects: Effects) -> Result<Model<'_>, String> {
        effects.check_delays(self.settings.dt_us).map_err(|e| e.to_string())?;
        let cfg = Config {
            dt_us: self.settings.dt_us,
            params: self.params(c),
            speed_target: c.speed_target,
            effects,
        };
        Model::with_maps(&cfg, self.maps()?).map_err(|e| match e {
            model_core::ConfigError::StepSize(dt) => format!("step {dt} µs out of range"),
            model_core::ConfigError::Parameter(p) => format!("model parameter `{p}` must be finite and > 0"),
            model_core::ConfigError::Effect(id) => match effects.check() {
                Err(bad) => bad.to_string(),
                Ok(()) => format!("effect `{id}`: the model refuses these values"),
            },
        })
    }

    /// A parameter of the data (`parameters.toml` key), from the data directory or the
    /// compiled-in data; `None` if it has no such key.
    fn data_param(&self, key: &str, builtin: f32) -> f64 {
        f64::from(self.data.as_ref().and_then(|d| d.param(key)).unwrap_or(builtin))
    }

    /// [V] the bench's supply set-point range (`supply_voltage_min_v`, `_max_v`).
    pub fn supply_range(&self) -> (f64, f64) {
        (
            self.data_param("supply_voltage_min_v", d::SUPPLY_VOLTAGE_MIN_V),
            self.data_param("supply_voltage_max_v", d::SUPPLY_VOLTAGE_MAX_V),
        )
    }

    /// [V] the supply voltage's start value: the settings', else the data's nominal.
    pub fn supply_start(&self) -> f64 {
        self.settings.supply_v.unwrap_or_else(|| self.data_param("supply_voltage_v", d::SUPPLY_VOLTAGE_V))
    }

    /// Whether `v` is a supply voltage the bench can set.
    pub fn check_supply(&self, v: f64) -> Result<(), String> {
        let (lo, hi) = self.supply_range();
        if v.is_finite() && (lo..=hi).contains(&v) {
            Ok(())
        } else {
            Err(format!("{v} V is outside the bench's range [{lo}, {hi}] V"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::{CouplingStiffness, RateSet, SpeedTarget};

    #[test]
    fn settings_round_trip_and_errors_are_located() {
        let s = Settings {
            dt_us: 100,
            choices: Choices {
                rates: RateSet::Programmed,
                speed_target: SpeedTarget::Parameter,
                coupling: CouplingStiffness::Datasheet,
            },
            supply_v: Some(18.5),
        };
        let p = Path::new("simrod-fmu.toml");
        assert_eq!(Settings::parse(&s.to_toml(), p).unwrap(), s);
        assert_eq!(Settings::parse(&Settings::default().to_toml(), p).unwrap(), Settings::default());
        let bad = s.to_toml().replace("\"datasheet\"", "\"flender\"");
        let e = Settings::parse(&bad, p).unwrap_err();
        assert!(e.contains("coupling = \"flender\": expected one of identified, datasheet"), "{e}");
        let e = Settings::parse(&format!("{}wobble = 1\n", s.to_toml()), p).unwrap_err();
        assert!(e.starts_with("simrod-fmu.toml:9:1: ") && e.contains("wobble"), "{e}");
        let e = Settings::parse(&s.to_toml().replace("dt_us = 100", "dt_us = 5"), p).unwrap_err();
        assert!(e.contains("dt_us = 5: expected a step in [10, 10000] µs"), "{e}");
    }
}
