//! Measured runs in memory, whatever file they came from.
//!
//! Every reader (CSV, MAT) produces a [`Measurement`]; every analysis consumes one.
//! Channel names are the bench's export names (`model_core::Channel::name`) after any
//! renaming by a mapping file; units are as written in the file.

use std::path::PathBuf;

/// One channel of a measured run.
#[derive(Debug, Clone, PartialEq)]
pub struct Signal {
    /// Bench name, e.g. `C_Kistler_L`.
    pub name: String,
    /// Unit as written in the source, e.g. `N m`.
    pub unit: String,
    /// One value per time sample.
    pub values: Vec<f64>,
}

/// A measured run on a uniform time grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// Where it came from (for messages).
    pub source: PathBuf,
    /// [s] sample times, strictly increasing and uniform (readers resample if needed).
    pub time_s: Vec<f64>,
    /// The channels.
    pub signals: Vec<Signal>,
}

/// Names of the set-point channels a bench file carries (inputs of the twin).
pub const SETPOINT_THROTTLE: &str = "SuT Throttle";
/// Load L set point, percent, + regenerating.
pub const SETPOINT_LOAD_L: &str = "Dm Left";
/// Load R set point, percent, + regenerating.
pub const SETPOINT_LOAD_R: &str = "Dm Right";

impl Measurement {
    /// The signal called `name`, if present.
    pub fn signal(&self, name: &str) -> Option<&Signal> {
        self.signals.iter().find(|s| s.name == name)
    }
}
