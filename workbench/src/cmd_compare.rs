//! `simrod compare MEAS`: run the twin on a measured run's inputs and show where model
//! and measurement disagree (terminal table, `--json`, `--report DIR`).
//!
//! Arguments and files are checked before the comparison runs (exit code 2, as for
//! every bad input); only writing the report can fail afterwards (exit code 1).
//!
//! Every comparison is appended to the measurement's history
//! (`<stem>.simrod-history.jsonl`, [`crate::history`]; `--no-history` skips it); a
//! history that cannot be written is a warning, not a failed comparison. The report
//! draws the previous iteration's simulation ("before") under this one where the error
//! moved, when the effects changed since then (or against `--baseline-effects`).

use std::io::Write;
use std::path::{Path, PathBuf};

use clap::Args;
use model_core::Builtin;

use crate::compare::{compare_prepared, CompareError, CompareOptions, CompareResult, InputSource};
use crate::effects_file::load_effects;
use crate::error::CmdError;
use crate::history::{self, Entry};
use crate::iterate;
use crate::measure::{self, LoadOptions, Loaded, Mapping};
use crate::report::{html, json, table};
use crate::simulate::{parse_builtin, parse_scale};
use crate::twin::args::{ModelArgs, SensorArgs};
use crate::twin::{check_budget, plausible, MeasuredTwin};
use simrod_io::budget::BudgetArgs;

/// What `simrod compare --help` explains after the options.
const HOW: &str = "\
How the comparison is made:
  Inputs    the file's set points (SuT Throttle, Dm Left, Dm Right [%]) drive the twin; row k is
            the end of a step and its set points are the ones held over that step (as `simrod
            bench` writes). The twin starts at rest one step before the first row. --profile
            drives it from a built-in profile instead (profile time = row time - one step).
  Step      the file's sample interval when it is a whole number of µs in 10..=10000 µs and
            uniform; otherwise the file is resampled (linear) to 1 ms and the twin runs at 1 ms.
  Sensors   the twin's speeds are recorded as the bench records them: averaged over the encoder
            counting window (--speed-window-s, 0.1 s; 0 for files whose speeds are not counted).
            `simrod diagnose` runs the same twin on the same file with the same flags.
  Residual  sim - meas. NRMSE = RMSE / the measured range (max - min), or a tenth of the channel's
            operating span (workbench/data/channel_spans.toml) when the run moves it less
            (column norm.: range or span/10). fit = 100 (1 - |e| / |y - mean y|) and
            r2 = 1 - sum e^2 / sum (y - mean y)^2, only where the range normalises.
            Headlines (worst channel, region, span) name only residuals with structure.
  Regions   from measured/commanded signals: accelerating / decelerating / steady (slope of the
            0.1 s-smoothed |SuTMotorEnc| beyond +-50 rpm/s); forward / reverse (throttle sign,
            else speed sign); loads motoring / regenerating / unloaded (mean load set point
            beyond +-0.5 %, + regenerating); at a limit (speed within 3 % of 2100/500 rpm,
            commanded load current, P_SuT_inv or |C_Kistler| within 5 % of the maps' extremes).
            The error budget is each region's share of a channel's squared error.
  Residual  whiteness: autocorrelation over 200 lags against a 95 % band that follows the noise
  tests     level; cross-correlation with the set points and their changes over +-1 s
            (+ lag: the residual follows the input, as after a controller delay).";

/// Arguments of `simrod compare`.
#[derive(Debug, Clone, Args)]
#[command(after_long_help = HOW)]
pub struct CompareArgs {
    /// Measured run: .csv (also .txt, .tsv) or .mat, as `simrod bench` writes them.
    #[arg(value_name = "MEAS")]
    pub meas: PathBuf,

    #[command(flatten)]
    pub model: ModelArgs,

    #[command(flatten)]
    pub sensors: SensorArgs,

    /// Mapping file (TOML) renaming/scaling the file's channels to bench names.
    #[arg(long, value_name = "FILE")]
    pub mapping: Option<PathBuf>,

    /// Interpolate across gaps in the time axis instead of refusing the file.
    #[arg(long)]
    pub allow_gaps: bool,

    /// Drive the twin from a built-in profile instead of the file's set-point channels
    /// (for files without `SuT Throttle`, `Dm Left`, `Dm Right`).
    #[arg(long, value_name = "NAME", value_parser = parse_builtin)]
    pub profile: Option<Builtin>,

    /// Throttle scale of `--profile`, in [-1.5, 1.5].
    #[arg(long, value_name = "X", requires = "profile", allow_negative_numbers = true, value_parser = parse_scale)]
    pub throttle_scale: Option<f32>,

    /// Load scale of `--profile`, in [-1.5, 1.5].
    #[arg(long, value_name = "Y", requires = "profile", allow_negative_numbers = true, value_parser = parse_scale)]
    pub load_scale: Option<f32>,

    /// Width of the worst-span windows [s].
    #[arg(long, value_name = "S", default_value_t = 2.0, value_parser = parse_window, allow_negative_numbers = true)]
    pub window_s: f64,

    /// Print the comparison as JSON on stdout instead of the table.
    #[arg(long)]
    pub json: bool,

    /// Also write DIR/index.html (self-contained; DIR is created if missing).
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,

    /// Do not append this comparison to the measurement's history
    /// (`<stem>.simrod-history.jsonl` next to MEAS; see `simrod history`).
    #[arg(long)]
    pub no_history: bool,

    /// Draw the report's before/after overlay against the twin with these effects
    /// (default: the previous history record's effects, when they differ from --effects).
    #[arg(long, value_name = "FILE.toml")]
    pub baseline_effects: Option<PathBuf>,

    /// Leave out (and count, per channel) samples beyond 100 times their channel's
    /// operating span instead of refusing the file: corrupt samples in an otherwise
    /// good run. Set points are never masked.
    #[arg(long)]
    pub mask_implausible: bool,

    #[command(flatten)]
    pub budget: BudgetArgs,
}

/// Peak memory of a comparison per sample of the twin's grid [bytes]: 620 measured on
/// a 300 MB bench CSV (2.13 M samples, 15 channels; `cargo bench -p workbench --bench
/// memory`), rounded up.
pub const COMPARE_BYTES_PER_SAMPLE: f64 = 700.0;

impl CompareArgs {
    /// `simrod compare MEAS` with every flag at its default (for callers in code, such as
    /// the demo; a test checks these are clap's defaults).
    pub fn for_file(meas: &Path) -> Self {
        Self {
            meas: meas.to_path_buf(),
            model: ModelArgs::default(),
            sensors: SensorArgs::default(),
            mapping: None,
            allow_gaps: false,
            profile: None,
            throttle_scale: None,
            load_scale: None,
            window_s: 2.0,
            json: false,
            report: None,
            no_history: false,
            baseline_effects: None,
            mask_implausible: false,
            budget: BudgetArgs::default(),
        }
    }
}

/// `--window-s` value: finite and > 0.
pub fn parse_window(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err("expected a window length in seconds, > 0".into()),
    }
}

/// A finished comparison and what it left on disk.
#[derive(Debug, Clone)]
pub struct Compared {
    pub result: CompareResult,
    /// The history file, when this comparison was appended to it.
    pub history: Option<PathBuf>,
    /// The report, when asked for.
    pub report: Option<PathBuf>,
    /// Things that went wrong on the side (history unreadable or not writable).
    pub warnings: Vec<String>,
}

/// Compare, record in the history, write the report; prints nothing.
pub fn run(args: &CompareArgs) -> Result<Compared, CmdError> {
    let inputs = args
        .model
        .inputs()
        .file("the measurement", Some(&args.meas))
        .file("--mapping", args.mapping.as_deref())
        .file("--baseline-effects", args.baseline_effects.as_deref());
    if let Some(dir) = &args.report {
        inputs.check("--report", dir).map_err(CmdError::Usage)?;
    }
    if !args.no_history {
        inputs.check("the history", &history::path_for(&args.meas)).map_err(CmdError::Usage)?;
    }
    let mut model = args.model.load()?;
    model.sensors = args.sensors.model()?;
    let effects = model.effects;
    let baseline_fx = args.baseline_effects.as_deref().map(load_effects).transpose()?;
    let load_opts = LoadOptions {
        mapping: args.mapping.as_deref().map(Mapping::load).transpose()?,
        allow_gaps: args.allow_gaps,
        budget: args.budget.budget(),
        ..LoadOptions::default()
    };
    let mut loaded = measure::load_with(&args.meas, &load_opts)?;
    if args.mask_implausible {
        let masked = plausible::mask(&mut loaded.measurement);
        loaded.notes.extend(masked);
    }
    let doing = format!("comparing {}", args.meas.display());
    check_budget(&loaded.measurement.time_s, &args.budget.budget(), &doing, COMPARE_BYTES_PER_SAMPLE)
        .map_err(|e| CmdError::Usage(format!("{}: {e}", args.meas.display())))?;
    let inputs = match args.profile {
        Some(which) => InputSource::Profile {
            which,
            throttle_scale: args.throttle_scale.unwrap_or(1.0),
            load_scale: args.load_scale.unwrap_or(1.0),
        },
        None => InputSource::Recorded,
    };
    let opts = CompareOptions { model, inputs, window_s: args.window_s, ..CompareOptions::default() };
    let usage = |e: CompareError| CmdError::Usage(format!("{}: {e}", args.meas.display()));
    let twin = MeasuredTwin::new(&loaded.measurement, &opts.model, &opts.inputs).map_err(usage)?;
    // The file's values are on the twin's grid now: drop the measurement, so a long run
    // is held once.
    let Loaded { measurement, notes: mut load_notes, .. } = loaded;
    let source = measurement.source.clone();
    drop(measurement);

    // The history: read before appending (the previous record is the report's baseline).
    let hist_path = history::path_for(&args.meas);
    let mut warnings = Vec::new();
    let mut past = history::read(&hist_path).unwrap_or_else(|e| {
        warnings.push(format!("{}: cannot read the history: {e}", hist_path.display()));
        history::History::default()
    });
    warnings.append(&mut past.warnings);
    let before = match (baseline_fx, &args.baseline_effects) {
        (Some(fx), Some(p)) => Some((fx, format!("--baseline-effects {}", p.display()))),
        _ => iterate::previous_effects(&past, &effects),
    };
    let baseline = match (&args.report, before) {
        (Some(_), Some((fx, origin))) => Some(
            iterate::baseline(&twin, &opts, fx, origin)
                .map_err(|e| CmdError::Runtime(format!("baseline run: {e}")))?,
        ),
        _ => None,
    };

    let mut result = compare_prepared(twin, &source, &opts).map_err(usage)?;
    load_notes.extend(args.model.effects.as_ref().map(|p| format!("twin effects from {}", p.display())));
    load_notes.append(&mut result.notes);
    result.notes = load_notes;

    let mut rec = iterate::options_rec(&opts, &result, args.mapping.as_deref(), args.allow_gaps);
    rec.data_dir = args.model.data_dir.as_ref().map(|p| p.display().to_string());
    let entry = Entry::new(&result, &args.meas, &effects, args.model.effects.as_deref(), rec);
    if !args.no_history {
        // The report shows this iteration; the file gets it only once everything worked.
        past.entries.push(entry.clone());
    }
    let report = match &args.report {
        Some(dir) => Some(write_report(dir, &result, baseline, &past, &hist_path)?),
        None => None,
    };
    let mut recorded = None;
    if !args.no_history {
        match history::append(&hist_path, &entry) {
            Ok(()) => recorded = Some(hist_path.clone()),
            Err(e) => warnings.push(format!("{}: history not recorded: {e}", hist_path.display())),
        }
    }
    Ok(Compared { result, history: recorded, report, warnings })
}

/// The report with its extras: the before/after overlay (the run with the previous
/// effects) and the history section.
fn write_report(
    dir: &Path,
    result: &CompareResult,
    baseline: Option<html::Baseline>,
    past: &history::History,
    hist_path: &Path,
) -> Result<PathBuf, CmdError> {
    let extras = html::Extras {
        baseline,
        history: (!past.entries.is_empty()).then(|| iterate::history_view(hist_path, &past.entries)),
    };
    html::write_report_with(dir, result, &extras)
        .map_err(|e| CmdError::Runtime(format!("{}: {e}", dir.display())))
}

/// Run `simrod compare`.
pub fn execute(args: &CompareArgs) -> Result<(), CmdError> {
    let c = run(args)?;
    for w in &c.warnings {
        eprintln!("warning: {w}");
    }
    let text = if args.json {
        let mut s = serde_json::to_string_pretty(&json::to_json(&c.result))
            .map_err(|e| CmdError::Runtime(format!("JSON: {e}")))?;
        s.push('\n');
        s
    } else {
        table::render(&c.result)
    };
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| CmdError::Runtime(format!("stdout: {e}")))?;
    // Keep stdout pure JSON under --json.
    if let Some(h) = &c.history {
        eprintln!("history: {}", h.display());
    }
    if let Some(path) = &c.report {
        eprintln!("report: {}", path.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: CompareArgs,
    }

    #[test]
    fn for_file_is_the_command_line_default() {
        let parsed = Cli::try_parse_from(["simrod", "m.csv"]).unwrap().args;
        assert_eq!(format!("{parsed:?}"), format!("{:?}", CompareArgs::for_file(Path::new("m.csv"))));
    }
}
