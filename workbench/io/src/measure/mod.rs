//! Measured runs in memory, whatever file they came from.
//!
//! Every reader (CSV, MAT) produces a [`Measurement`]; every analysis consumes one.
//! Channel names are the bench's export names (`model_core::Channel::name`) after any
//! renaming by a mapping file. Known channels carry the bench unit (converted if the file
//! used another accepted unit, see [`units`]); others keep the unit as written.
//!
//! Formats: [`csv`] (what is accepted), [`mat`] (the variable convention), [`mapping`]
//! files, and the time checks and resampling in [`resample`]. Every problem is a
//! [`MeasureError`] naming the file, the line (CSV) or sample (MAT), and the channel.

use std::path::PathBuf;

pub mod csv;
pub mod mapping;
pub mod mat;
pub mod resample;
pub(crate) mod table;
pub mod units;
pub mod write;

#[cfg(test)]
mod tests;

use std::path::Path;

use crate::budget::Budget;
pub use mapping::Mapping;

/// Errors of the readers: a [`crate::error::FileError`], `file:line:col: message`.
/// CSV problems carry the 1-based line (and column) and name the channel; MAT problems
/// name the variable and the 1-based sample.
pub type MeasureError = crate::error::FileError;

/// Names (any case) that make a column the time axis.
pub const TIME_NAMES: &[&str] = &["time", "t", "zeit"];

/// A column is the time axis if its name is one of [`TIME_NAMES`] and its unit, when
/// given, is a time unit (so `T [°C]` stays a channel).
pub(crate) fn is_time(name: &str, unit: Option<&str>) -> bool {
    TIME_NAMES.iter().any(|t| t.eq_ignore_ascii_case(name))
        && unit.is_none_or(|u| units::factor_to("s", u).is_some())
}

/// Extra channel added when a run was interpolated across gaps (`--allow-gaps`): 1 for
/// samples inside a gap, 0 elsewhere. See [`Measurement::gap_mask`].
pub const GAP_CHANNEL: &str = "gap";

/// How to load a file. `Default` is strict: no mapping, gaps are errors.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadOptions {
    /// Renames, scales and units of a mapping file.
    pub mapping: Option<Mapping>,
    /// Interpolate across gaps (and mark them) instead of refusing the file.
    pub allow_gaps: bool,
    /// An interval longer than this many median intervals is a gap.
    pub gap_samples: f64,
    /// Channels the analysis needs (bench names, after renaming).
    pub required: Vec<String>,
    /// Most memory loading may take (the file, its values, a resampled grid).
    pub budget: Budget,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            mapping: None,
            allow_gaps: false,
            gap_samples: resample::GAP_SAMPLES,
            required: Vec::new(),
            budget: Budget::default(),
        }
    }
}

/// A loaded run and what loading did to it.
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    pub measurement: Measurement,
    /// Things the user should know (resampled, mapping keys that matched nothing).
    pub notes: Vec<String>,
    /// `Some(dt)` when the file was resampled onto a `dt` grid.
    pub resampled_dt: Option<f64>,
    /// `(start, end)` [s] of the gaps interpolated across.
    pub gaps: Vec<(f64, f64)>,
}

/// Load a `.csv` (also `.txt`, `.tsv`) or `.mat` file, with an optional mapping file.
pub fn load(path: &Path, mapping: Option<&Path>) -> Result<Measurement, MeasureError> {
    let opts = LoadOptions { mapping: mapping.map(Mapping::load).transpose()?, ..LoadOptions::default() };
    load_with(path, &opts).map(|l| l.measurement)
}

/// Load with explicit options; the format follows the extension.
pub fn load_with(path: &Path, opts: &LoadOptions) -> Result<Loaded, MeasureError> {
    format_of(path)?;
    let size = std::fs::metadata(path).map_err(|e| MeasureError::io(path, &e))?.len() as f64;
    // The bytes, then one f64 per value (a CSV value is 8 to 15 characters).
    opts.budget
        .check("reading it", READ_COST * size, "the file and its values")
        .map_err(|m| MeasureError::whole(path, m))?;
    let bytes = std::fs::read(path).map_err(|e| MeasureError::io(path, &e))?;
    parse_bytes(path, bytes, opts)
}

/// A file's contents, read as the reader its extension names (`path` is only named in
/// messages): the whole pipeline of [`load_with`] without the file system, for callers
/// that hold the bytes (the fuzz targets).
pub fn parse_bytes(path: &Path, bytes: Vec<u8>, opts: &LoadOptions) -> Result<Loaded, MeasureError> {
    let raw = match format_of(path)? {
        Format::Csv => csv::read_bytes(path, bytes)?,
        Format::Mat => mat::parse(path, &bytes)?,
    };
    table::finish(raw, opts)
}

/// Memory to read a file, per byte of the file (measured: 2.0 for a bench CSV).
const READ_COST: f64 = 2.5;

enum Format {
    Csv,
    Mat,
}

fn format_of(path: &Path) -> Result<Format, MeasureError> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    match ext.as_str() {
        "csv" | "txt" | "tsv" => Ok(Format::Csv),
        "mat" => Ok(Format::Mat),
        _ => Err(MeasureError::whole(path, "unknown measurement format; expected a .csv or .mat file")),
    }
}

/// One channel of a measured run.
#[derive(Debug, Clone, PartialEq)]
pub struct Signal {
    /// Bench name, e.g. `C_Kistler_L`.
    pub name: String,
    /// Unit, e.g. `N m`: the bench unit for known channels, else as written.
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

    /// Error unless every channel in `names` is present (listing all that are missing).
    pub fn require(&self, names: &[&str]) -> Result<(), MeasureError> {
        let missing: Vec<&str> = names.iter().copied().filter(|n| self.signal(n).is_none()).collect();
        if missing.is_empty() {
            Ok(())
        } else {
            Err(MeasureError::whole(&self.source, table::missing_message(&missing)))
        }
    }

    /// Per sample: true inside a gap that loading interpolated across (never true for
    /// a run without [`GAP_CHANNEL`]). Analyses skip these samples.
    pub fn gap_mask(&self) -> Vec<bool> {
        match self.signal(GAP_CHANNEL) {
            Some(g) => g.values.iter().map(|v| *v != 0.0).collect(),
            None => vec![false; self.time_s.len()],
        }
    }
}
