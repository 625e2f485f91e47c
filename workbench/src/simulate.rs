//! `simrod simulate`: run the twin on a test profile, write every channel at every
//! step to a CSV, print a summary.
//!
//! Everything the user gives is checked before the run starts (exit code 2); what can
//! still fail afterwards is I/O (exit code 1), and then the previous output file, if
//! any, is left as it was.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Args;
use model_core::model::DT_US_RANGE;
use model_core::profile::MAX_SETS;
use model_core::{
    Builtin, Config, ConfigError, Effects, Model, Profile, ProfileError, Simulation, N_CHANNELS,
};

use crate::atomic::write_atomic;
use crate::datadir::ModelData;
use crate::error::CmdError;
use crate::profile_file::{load_profile, SCALE_RANGE};
use crate::sim_csv::{header, RowWriter};
use crate::summary::{StatsAccumulator, Summary};
use crate::twin::args::file_error;
pub use crate::twin::args::{
    check_supply_v, parse_supply_v, CouplingArg, ModelArgs, RatesArg, SpeedTargetArg, SUPPLY_V_RANGE,
};
use simrod_io::budget::BudgetArgs;

/// The scalings of a profile (`simulate`, `bench`, `check`).
#[derive(Debug, Clone, Copy, Default, Args)]
pub struct ScaleArgs {
    /// Throttle scale in [-1.5, 1.5]; negative runs the profile in reverse.
    /// Default: the profile file's `throttle_scale`, else 1.
    #[arg(long, value_name = "X", allow_negative_numbers = true, value_parser = parse_scale)]
    pub throttle_scale: Option<f32>,

    /// Load scale in [-1.5, 1.5]; negative swaps regenerating and motoring.
    /// Default: the profile file's `load_scale`, else 1.
    #[arg(long, value_name = "Y", allow_negative_numbers = true, value_parser = parse_scale)]
    pub load_scale: Option<f32>,
}

/// Arguments of `simrod simulate`.
#[derive(Debug, Clone, Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub source: ProfileSource,

    #[command(flatten)]
    pub scales: ScaleArgs,

    /// Step [µs], 10..=10000; 1000 is the bench's rate.
    #[arg(long, value_name = "US", default_value_t = 1000, value_parser = parse_dt_us, allow_negative_numbers = true)]
    pub dt_us: u32,

    #[command(flatten)]
    pub model: ModelArgs,

    /// Output CSV; replaced atomically, so a failed run keeps the previous file
    /// (a device or FIFO such as /dev/null or /dev/stdout is written directly).
    #[arg(long, short = 'o', value_name = "FILE.csv")]
    pub out: PathBuf,

    /// Do not print the summary.
    #[arg(long, short = 'q')]
    pub quiet: bool,

    #[command(flatten)]
    pub budget: BudgetArgs,
}

/// Bytes a `simulate` CSV row takes: 336 measured (TP07, every channel), rounded up.
pub const SIMULATE_ROW_BYTES: f64 = 360.0;

/// Refuse, before the first step, a run of `rows` rows whose file (`write_per_row`
/// bytes a row) or whose run held in memory (`hold_per_row`) exceeds the budget.
pub fn check_run_size(
    out: &Path,
    rows: f64,
    dt_us: u32,
    budget: &BudgetArgs,
    write_per_row: f64,
    hold_per_row: f64,
) -> Result<(), CmdError> {
    let b = budget.budget();
    let why = |per: f64| format!("{rows:.0} rows of {dt_us} µs, {per} bytes each");
    let over = |m: String| CmdError::Usage(format!("--out {}: {m}", out.display()));
    b.check(&format!("writing {}", out.display()), rows * write_per_row, &why(write_per_row))
        .map_err(over)?;
    b.check("holding the run", rows * hold_per_row, &why(hold_per_row)).map_err(over)
}

/// Exactly one of a built-in profile or a profile file.
#[derive(Debug, Clone, Args)]
#[group(required = true, multiple = false)]
pub struct ProfileSource {
    /// Built-in test profile (TP07, TP11, TP12, TP13, TP14; case-insensitive).
    #[arg(long, value_name = "NAME", value_parser = parse_builtin)]
    pub profile: Option<Builtin>,

    /// User test profile (TOML; format in workbench/examples/profile.toml).
    #[arg(long, value_name = "FILE.toml")]
    pub profile_file: Option<PathBuf>,
}

fn builtin_names() -> String {
    Builtin::ALL.map(Builtin::name).join(", ")
}

/// `--profile` value: a built-in profile name.
pub fn parse_builtin(s: &str) -> Result<Builtin, String> {
    Builtin::from_name(s).ok_or_else(|| format!("unknown profile; known: {}", builtin_names()))
}

/// Checks a scale factor (`--throttle-scale`, `--load-scale`).
pub fn check_scale(v: f32) -> Result<f32, String> {
    let (lo, hi) = (SCALE_RANGE.0 as f32, SCALE_RANGE.1 as f32);
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(format!("expected a number in [{lo}, {hi}], got {v}"))
    }
}

/// `--throttle-scale` / `--load-scale` value.
pub fn parse_scale(s: &str) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("expected a number in [{}, {}]", SCALE_RANGE.0, SCALE_RANGE.1))?;
    check_scale(v)
}

/// Checks a step size against the model's range.
pub fn check_dt_us(v: u32) -> Result<u32, String> {
    if (DT_US_RANGE.0..=DT_US_RANGE.1).contains(&v) {
        Ok(v)
    } else {
        Err(format!("expected a step in [{}, {}] µs, got {v}", DT_US_RANGE.0, DT_US_RANGE.1))
    }
}

/// `--dt-us` value.
pub fn parse_dt_us(s: &str) -> Result<u32, String> {
    let v: u32 = s
        .trim()
        .parse()
        .map_err(|_| format!("expected a whole number of µs in [{}, {}]", DT_US_RANGE.0, DT_US_RANGE.1))?;
    check_dt_us(v)
}

/// A random seed: a whole number in [0, 2^64).
pub fn parse_seed(s: &str) -> Result<u64, String> {
    s.trim().parse::<u64>().map_err(|_| format!("expected a whole number in [0, {}]", u64::MAX))
}

/// A validated run: what to simulate and how to describe it.
#[derive(Debug, Clone)]
pub struct RunSpec {
    /// One line naming the profile and options, for the summary.
    pub title: String,
    pub config: Config,
    pub profile: Profile,
    pub supply_v: f32,
    /// Maps from `--data-dir` (`None`: the built-in maps).
    pub data: Option<Arc<ModelData>>,
}

impl RunSpec {
    /// The simulation this spec describes.
    pub fn simulation(&self) -> Result<Simulation<'_>, CmdError> {
        let model = match &self.data {
            None => Model::new(&self.config),
            Some(d) => {
                let maps = d.maps().map_err(|e| CmdError::Usage(format!("--data-dir: {e}")))?;
                Model::with_maps(&self.config, maps)
            }
        };
        let model = model.map_err(|e| CmdError::Usage(config_error(e)))?;
        Ok(Simulation::from_model(model, self.profile.clone(), self.supply_v))
    }
}

fn config_error(e: ConfigError) -> String {
    match e {
        ConfigError::StepSize(dt) => format!("--dt-us {dt}: {}", check_dt_us(dt).err().unwrap_or_default()),
        ConfigError::Parameter(p) => format!("model parameter `{p}` must be finite and > 0"),
        ConfigError::Effect(id) => format!("effect `{id}`: {}", crate::effects_file::constraint(id)),
    }
}

fn profile_error(e: ProfileError, what: &str) -> String {
    match e {
        ProfileError::SetCount(n) => format!("{what}: {n} sets, expected 1 to {MAX_SETS}"),
        ProfileError::Duration(i) => format!("{what}: set {}: invalid duration", i + 1),
        ProfileError::SetPoint(i) => format!("{what}: set {}: set point outside [-100, 100] %", i + 1),
        ProfileError::Scale => format!("{what}: scale outside [-1.5, 1.5]"),
    }
}

impl SimulateArgs {
    /// The input files the arguments name (profile file, effect file, data directory).
    pub fn inputs(&self) -> simrod_io::guard::Inputs {
        self.model.inputs().file("--profile-file", self.source.profile_file.as_deref())
    }

    /// Validate the arguments and load the input files. Everything wrong here is a
    /// usage error; nothing is written.
    pub fn spec(&self) -> Result<RunSpec, CmdError> {
        run_spec(&self.source, self.scales, self.dt_us, &self.model)
    }
}

/// The run a profile's flags describe (`simulate`, `bench`, `check`): the flags checked
/// and the profile, effect and data files loaded once, here. Everything wrong is a usage
/// error; nothing is written.
pub fn run_spec(
    source: &ProfileSource,
    scales: ScaleArgs,
    dt_us: u32,
    model_args: &ModelArgs,
) -> Result<RunSpec, CmdError> {
    let throttle_scale = usage("--throttle-scale", scales.throttle_scale.map(check_scale).transpose())?;
    let load_scale = usage("--load-scale", scales.load_scale.map(check_scale).transpose())?;
    let dt_us = usage("--dt-us", check_dt_us(dt_us))?;
    let model = model_args.load()?;
    let supply_v = model.supply_v;
    let data = model.data.clone();
    let (profile, name, ts, ls) = match (&source.profile, &source.profile_file) {
        (Some(b), None) => {
            let (ts, ls) = (throttle_scale.unwrap_or(1.0), load_scale.unwrap_or(1.0));
            let sets = data.as_deref().and_then(|d| d.profile(b.name())).unwrap_or(b.sets());
            let p = Profile::new(sets, ts, ls).map_err(|e| CmdError::Usage(profile_error(e, b.name())))?;
            (p, b.name().to_string(), ts, ls)
        }
        (None, Some(path)) => {
            let f = load_profile(path).map_err(|e| file_error("--profile-file", e))?;
            let ts = throttle_scale.or(f.throttle_scale).unwrap_or(1.0);
            let ls = load_scale.or(f.load_scale).unwrap_or(1.0);
            let what = path.display().to_string();
            let p = f.profile(Some(ts), Some(ls)).map_err(|e| CmdError::Usage(profile_error(e, &what)))?;
            let name = f.name.clone().unwrap_or_else(|| {
                path.file_stem().map_or(what.clone(), |s| s.to_string_lossy().into_owned())
            });
            (p, name, ts, ls)
        }
        _ => {
            return Err(CmdError::Usage(
                "give exactly one of --profile NAME or --profile-file FILE.toml".into(),
            ))
        }
    };

    if let Some(path) = &model_args.effects {
        check_delay(&model.effects, dt_us)
            .map_err(|m| CmdError::Usage(format!("{}: {m}", path.display())))?;
    }
    let config = model.config(dt_us, model.effects);
    let title = format!(
        "{name}: throttle x{ts}, load x{ls} | dt {dt_us} µs | supply {supply_v} V | {}",
        model_args.describe()
    );
    let spec = RunSpec { title, config, profile, supply_v, data };
    spec.simulation()?; // the model's own checks, before any output is touched
    Ok(spec)
}

/// Prefixes a value check's message with the flag it is about.
fn usage<T>(flag: &str, r: Result<T, String>) -> Result<T, CmdError> {
    r.map_err(|m| CmdError::Usage(format!("{flag}: {m}")))
}

/// The delays are held in fixed lines; the model would cut a longer delay, so refuse it
/// instead (with the numbers: [`Effects::check_delays`]).
pub fn check_delay(fx: &Effects, dt_us: u32) -> Result<(), String> {
    fx.check_delays(dt_us).map_err(|e| e.to_string())
}

/// Run `sim` to the end of its profile, writing the CSV to `out` if given, and
/// summarise. The reusable core of every command that runs a profile.
pub fn run(sim: Simulation<'_>, title: String, mut out: Option<&mut dyn Write>) -> io::Result<Summary> {
    let start = Instant::now();
    let mut output_wall = Duration::ZERO;
    let mut acc = StatsAccumulator::new();
    let mut rows = RowWriter::new();
    if let Some(w) = out.as_mut() {
        w.write_all(header().as_bytes())?;
    }
    for (k, o) in sim.enumerate() {
        if let Some(c) = o.non_finite() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "the model diverged at step {} (t = {:.6} s): {} is {}; nothing was written",
                    k + 1,
                    o.t_s(),
                    c.name(),
                    o.get(c)
                ),
            ));
        }
        acc.observe(&o);
        if let Some(w) = out.as_mut() {
            let t = Instant::now();
            rows.write_row(*w, &o)?;
            output_wall += t.elapsed();
        }
    }
    Ok(acc.finish(title, start.elapsed(), output_wall))
}

/// `simrod simulate`.
pub fn execute(args: &SimulateArgs) -> Result<(), CmdError> {
    args.inputs().check("--out", &args.out).map_err(CmdError::Usage)?;
    let spec = args.spec()?;
    check_out_path(&args.out)?;
    let sim = spec.simulation()?;
    check_run_size(&args.out, sim.total_steps() as f64, args.dt_us, &args.budget, SIMULATE_ROW_BYTES, 0.0)?;

    let start = Instant::now();
    let mut summary = None;
    write_atomic(&args.out, |w| {
        summary = Some(run(sim, spec.title.clone(), Some(w))?);
        Ok(())
    })
    .map_err(|e| match e.kind() {
        io::ErrorKind::InvalidData => CmdError::Runtime(e.to_string()),
        _ => CmdError::Runtime(format!("cannot write {}: {e}", args.out.display())),
    })?;
    let Some(mut summary) = summary else {
        return Err(CmdError::Runtime("the run produced no summary".into()));
    };
    // Include the flush, fsync and rename: that is what the user waited for.
    let total = start.elapsed();
    summary.output_wall += total.saturating_sub(summary.wall);
    summary.wall = total;

    if !args.quiet {
        let bytes = std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0);
        let text = format!(
            "{summary}wrote {} ({} rows x {} channels, {:.1} MB)\n",
            args.out.display(),
            summary.steps,
            N_CHANNELS,
            bytes as f64 / 1e6
        );
        print_stdout(&text)?;
    }
    Ok(())
}

/// Writes to stdout; a closed pipe (`| head`) is not an error, the run is done.
fn print_stdout(text: &str) -> Result<(), CmdError> {
    let mut out = io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != io::ErrorKind::BrokenPipe => {
            Err(CmdError::Runtime(format!("cannot write to stdout: {e}")))
        }
        _ => Ok(()),
    }
}

/// The output's directory must exist (we do not create directories on a typo) and the
/// output must not be a directory.
pub fn check_out_path(out: &Path) -> Result<(), CmdError> {
    let usage = |m: String| Err(CmdError::Usage(format!("--out {}: {m}", out.display())));
    if out.file_name().is_none() {
        return usage("expected a file name".into());
    }
    if out.is_dir() {
        return usage("is a directory; expected a file name".into());
    }
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return usage(format!("directory {} does not exist", dir.display()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_parsers_check_ranges() {
        assert_eq!(parse_scale("-1.5"), Ok(-1.5));
        assert_eq!(parse_scale("0.79"), Ok(0.79));
        assert!(parse_scale("1.51").unwrap_err().contains("[-1.5, 1.5]"));
        assert!(parse_scale("NaN").unwrap_err().contains("[-1.5, 1.5]"));
        assert!(parse_scale("inf").is_err());
        assert!(parse_scale("x").is_err());
        assert_eq!(parse_dt_us("100"), Ok(100));
        assert!(parse_dt_us("9").unwrap_err().contains("[10, 10000]"));
        assert!(parse_dt_us("10001").is_err());
        assert!(parse_dt_us("-5").is_err());
        assert_eq!(parse_supply_v("12"), Ok(12.0));
        assert!(parse_supply_v("30.5").unwrap_err().contains("[12, 30] V"));
        assert!(parse_builtin("tp07").is_ok());
        assert!(parse_builtin("TP99").unwrap_err().contains("TP07, TP11, TP12, TP13, TP14"));
    }

    #[test]
    fn long_delays_are_refused_not_capped() {
        let mut fx = Effects::NONE;
        fx.controller_delay_s = 0.25;
        assert!(check_delay(&fx, 1000).is_ok());
        assert!(check_delay(&fx, 100).unwrap_err().contains("at most 256 steps"));
    }

    #[test]
    fn run_without_output_summarises_the_whole_profile() {
        let profile = Profile::builtin(Builtin::TP12, 1.0, 0.0).unwrap();
        let dur = profile.duration_us();
        let sim = Simulation::new(&Config::default(), profile, 24.0).unwrap();
        let s = run(sim, "t".into(), None).unwrap();
        assert_eq!(s.steps, dur / 1000);
        assert_eq!(s.duration_us, dur);
        assert_eq!(s.output_wall, Duration::ZERO);
        let speed = s.get(model_core::Channel::SuTMotorEnc).unwrap();
        assert!(speed.max > 2000.0, "{speed:?}");
    }
}
