//! `simrod check`: will a test stay inside the bench's limits? The flags become a typed
//! [`CheckConfig`] once (the profile and model flags are `simulate`'s, loaded by the same
//! code); the check itself is `simrod_check::check`.
//!
//! Exit codes for a test-approval workflow: 0 the test is safe at the requested
//! confidence (every limit inside, or shown safe by the Monte Carlo), 1 a limit is
//! crossed, likely crossed or not yet shown safe (the table says which), 2 bad input.

use std::io::Write;
use std::path::PathBuf;

use clap::Args;
use simrod_check::limits::Limits;
use simrod_check::run::{ProfileRun, TestRun};
use simrod_check::uncertainty::{self, Choice, Uncertainty};
use simrod_check::{check, report, CheckError, CheckOptions, CheckReport};

use crate::atomic::write_atomic;
use crate::cmd_xil::{parse_cycle, LoopArgs, XilSpec};
use crate::error::CmdError;
use crate::simulate::{check_dt_us, parse_dt_us, parse_seed, run_spec, ProfileSource, ScaleArgs};
use crate::twin::args::{file_error, ModelArgs};
use crate::xil_run::{delay_check, XilRun};
use simrod_xdt::Cycle;

/// What `simrod check --help` explains after the options.
const HOW: &str = "\
How the check is made:
  Limits       every [[limit]] of the limits file (default workbench/data/limits.toml: SuT speed,
               torque, peak and continuous power; load currents and powers; torque flanges and
               couplings; supply current, power and voltage window), each with its origin, on
               every step: the peak, the margin, when and in which set.
  Flange mode  the torque flange rings near 2 kHz; its peaks between samples are bounded from
               the samples, which needs at least 4 a period: --dt-us 126 or less (default 100)
               when the flange or coupling limits are checked.
  Uncertainty  --uncertainty FILE, --from-identify DIR or --from-diagnose FILE.json: N models
               drawn (--samples, --seed; the same seed gives the same numbers on any number of
               threads). Per limit the probability of a violation with its Clopper-Pearson
               interval at --confidence P, and the worst case seen. Safe: the interval's upper
               end is at most 1 - P; likely crossed: the estimate is above 1 - P.
  Set points   (profiles) for every limit that does not pass, the largest throttle scale (load kept) and
               load scale (throttle kept) at which the nominal model stays inside the limit
               tightened by the Monte Carlo's spread (bisection, 1/256 of the scale).
  XiL loop     --cycle NAME runs the closed loop (twin + vehicle twin through the RT platform's
               --loop-delay-ms and --loop-dt-ms) as the test; the Monte Carlo draws the twin's
               parameters. Its delay margin (bisection at the bench's 1 ms step, as
               `simrod xil --margin`) must be at least --delay-safety K times the loop delay.
               A closed loop has no set-point scales: the set-point search does not apply.
  Exit code    0 approved, 1 not approved (a limit crossed, likely crossed or undecided),
               2 bad input.";

/// Arguments of `simrod check`.
#[derive(Debug, Clone, Args)]
#[command(after_long_help = HOW)]
pub struct CheckArgs {
    #[command(flatten)]
    pub source: ProfileSource,

    #[command(flatten)]
    pub scales: ScaleArgs,

    /// Check a closed XiL loop on this drive cycle instead of a profile (ece15,
    /// delivery, hill; see `simrod xil`); one of --profile, --profile-file, --cycle.
    #[arg(long, value_name = "NAME", value_parser = parse_cycle, group = "ProfileSource",
          conflicts_with_all = ["throttle_scale", "load_scale"])]
    pub cycle: Option<Cycle>,

    #[command(flatten)]
    pub looping: LoopArgs,

    /// K: refuse a closed loop whose delay margin is below K x its loop delay. 3 by
    /// default: the margin is found on one cycle and is an upper estimate near the
    /// crossing (simrod_xdt::margin), and the RT platform's delay jitters; 3x leaves
    /// room for both (assumed, a common safety factor on dead time).
    #[arg(long, value_name = "K", default_value_t = 3.0, value_parser = parse_factor, requires = "cycle")]
    pub delay_safety: f64,

    /// Step [µs], 10..=10000. 100 resolves the 2 kHz torque-flange mode the flange and
    /// coupling limits need (126 µs at most).
    #[arg(long, value_name = "US", default_value_t = 100, value_parser = parse_dt_us, allow_negative_numbers = true)]
    pub dt_us: u32,

    #[command(flatten)]
    pub model: ModelArgs,

    /// Limits file (TOML; default: the built-in workbench/data/limits.toml, whose header
    /// says how to add limits).
    #[arg(long, value_name = "FILE.toml")]
    pub limits: Option<PathBuf>,

    #[command(flatten)]
    pub uncertainty: UncertaintyArgs,

    /// Monte Carlo samples (with an uncertainty).
    #[arg(long, value_name = "N", default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub samples: u64,

    /// Seed of the Monte Carlo's draws.
    #[arg(long, value_name = "S", default_value_t = 1, allow_negative_numbers = true, value_parser = parse_seed)]
    pub seed: u64,

    /// Confidence P: a limit is safe when its violation probability is at most 1 - P,
    /// shown at confidence P.
    #[arg(long, value_name = "P", default_value_t = 0.95, value_parser = parse_confidence)]
    pub confidence: f64,

    /// Worker threads (default: the machine's cores, at most 8).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=256))]
    pub threads: Option<u32>,

    /// Do not search the set points that keep failing limits inside.
    #[arg(long)]
    pub no_set_points: bool,

    /// Write the result as JSON (replaced atomically).
    #[arg(long, value_name = "FILE.json")]
    pub json: Option<PathBuf>,

    /// Write a self-contained HTML page with every limit's margin over time.
    #[arg(long, value_name = "FILE.html")]
    pub html: Option<PathBuf>,

    /// Print only the verdict line.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

/// Where the model's uncertainty comes from (at most one).
#[derive(Debug, Clone, Args)]
#[group(required = false, multiple = false)]
pub struct UncertaintyArgs {
    /// Uncertainty file (TOML): normal or uniform distributions of parameters.toml keys
    /// and effect parameters (example: workbench/examples/uncertainty.toml).
    #[arg(long, value_name = "FILE.toml")]
    pub uncertainty: Option<PathBuf>,

    /// The identified values and standard uncertainties of a `simrod identify` output
    /// directory (its uncertainty.toml).
    #[arg(long, value_name = "DIR")]
    pub from_identify: Option<PathBuf>,

    /// The intervals of a `simrod diagnose --json` output: the effects its verdict names,
    /// around the values it proposes (pass the effect file it wrote as --effects for the
    /// rest of the model).
    #[arg(long, value_name = "FILE.json")]
    pub from_diagnose: Option<PathBuf>,
}

/// `--confidence` value: in (0.5, 1).
pub fn parse_confidence(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.5 && v < 1.0 => Ok(v),
        _ => Err("expected a confidence in (0.5, 1), e.g. 0.95".into()),
    }
}

/// `--delay-safety` value: a finite factor >= 1.
pub fn parse_factor(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 1.0 => Ok(v),
        _ => Err("expected a factor >= 1, e.g. 3".into()),
    }
}

/// The test checked: a profile or a closed XiL loop.
#[derive(Debug, Clone)]
pub enum CheckTest {
    Profile(ProfileRun),
    Xil(XilRun),
}

impl CheckTest {
    /// As the check crate runs it.
    pub fn as_test(&self) -> &dyn TestRun {
        match self {
            CheckTest::Profile(p) => p,
            CheckTest::Xil(x) => x,
        }
    }
}

/// The flags, checked and their files loaded.
#[derive(Debug, Clone)]
pub struct CheckConfig {
    pub test: CheckTest,
    /// K of the delay margin (closed loops).
    pub delay_safety: f64,
    pub limits: Limits,
    pub uncertainty: Option<Uncertainty>,
    pub samples: u64,
    pub seed: u64,
    pub confidence: f64,
    pub threads: usize,
    pub set_points: bool,
    pub json: Option<PathBuf>,
    pub html: Option<PathBuf>,
    pub quiet: bool,
}

impl CheckArgs {
    /// The input files the flags name.
    pub fn inputs(&self) -> simrod_io::guard::Inputs {
        let u = &self.uncertainty;
        self.looping
            .inputs(&self.model)
            .file("--profile-file", self.source.profile_file.as_deref())
            .file("--limits", self.limits.as_deref())
            .file("--uncertainty", u.uncertainty.as_deref())
            .dir("--from-identify", u.from_identify.as_deref())
            .file("--from-diagnose", u.from_diagnose.as_deref())
    }

    /// Check the flags and load every file they name; nothing runs yet.
    pub fn config(&self) -> Result<CheckConfig, CmdError> {
        let inputs = self.inputs();
        for (flag, out) in [("--json", &self.json), ("--html", &self.html)] {
            if let Some(p) = out {
                inputs.check(flag, p).map_err(CmdError::Usage)?;
                check_out(flag, p)?;
            }
        }
        if let (Some(j), Some(h)) = (&self.json, &self.html) {
            if j == h {
                return Err(CmdError::Usage(format!("--json and --html are both {}", j.display())));
            }
        }
        let (test, data) = match self.cycle {
            Some(cycle) => {
                let dt_us = check_dt_us(self.dt_us).map_err(|m| CmdError::Usage(format!("--dt-us: {m}")))?;
                let spec = XilSpec::new(cycle, &self.looping, &self.model, dt_us)?;
                let data = spec.data.clone();
                (CheckTest::Xil(XilRun { spec }), data)
            }
            None => {
                let s = run_spec(&self.source, self.scales, self.dt_us, &self.model)?;
                let data = s.data.clone();
                (CheckTest::Profile(ProfileRun::new(s.title, &s.profile, s.supply_v, s.config, s.data)), data)
            }
        };
        let limits = match &self.limits {
            Some(p) => Limits::load(p).map_err(|e| file_error("--limits", e))?,
            None => Limits::builtin()?,
        };
        let choice = Choice { rates: self.model.params.into(), coupling: self.model.coupling.into() };
        let uncertainty = self.uncertainty(test.as_test().config(), data.as_deref(), choice)?;
        Ok(CheckConfig {
            test,
            delay_safety: self.delay_safety,
            limits,
            uncertainty,
            samples: self.samples,
            seed: self.seed,
            confidence: self.confidence,
            threads: self.threads.map_or_else(
                || std::thread::available_parallelism().map_or(2, |n| n.get()).min(8),
                |t| t as usize,
            ),
            set_points: !self.no_set_points,
            json: self.json.clone(),
            html: self.html.clone(),
            quiet: self.quiet,
        })
    }

    /// The distributions the uncertainty flag names, resolved against the model.
    fn uncertainty(
        &self,
        config: &model_core::Config,
        data: Option<&simrod_io::datadir::ModelData>,
        choice: Choice,
    ) -> Result<Option<Uncertainty>, CmdError> {
        let u = &self.uncertainty;
        let (raw, source, notes) = if let Some(p) = &u.uncertainty {
            let raw = uncertainty::from_file(p).map_err(|e| file_error("--uncertainty", e))?;
            (raw, p.display().to_string(), Vec::new())
        } else if let Some(d) = &u.from_identify {
            let raw = uncertainty::from_identify(d).map_err(|e| file_error("--from-identify", e))?;
            (raw, format!("identification {}", d.display()), Vec::new())
        } else if let Some(p) = &u.from_diagnose {
            let (raw, notes) = uncertainty::from_diagnose(p).map_err(|e| file_error("--from-diagnose", e))?;
            (raw, format!("diagnosis {}", p.display()), notes)
        } else {
            return Ok(None);
        };
        if raw.is_empty() {
            return Err(CmdError::Usage(format!("{source}: no uncertain value to draw")));
        }
        let mut r = Uncertainty::resolve(raw, &source, config, data, choice).map_err(CmdError::Usage)?;
        r.notes = notes;
        Ok(Some(r))
    }
}

/// An output file must be a file name in a directory that exists (checked before the
/// check runs, so a typo costs no Monte Carlo).
fn check_out(flag: &str, p: &std::path::Path) -> Result<(), CmdError> {
    let dir = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    if p.file_name().is_none() || p.is_dir() {
        return Err(CmdError::Usage(format!("{flag} {}: expected a file name", p.display())));
    }
    if !dir.is_dir() {
        return Err(CmdError::Usage(format!(
            "{flag} {}: directory {} does not exist",
            p.display(),
            dir.display()
        )));
    }
    Ok(())
}

/// Run the check `c` describes (library use: no output written). A closed loop's delay
/// margin is found first.
pub fn run(c: &CheckConfig) -> Result<CheckReport, CmdError> {
    let delay = match &c.test {
        CheckTest::Xil(x) => Some(delay_check(&x.spec, c.delay_safety)?),
        CheckTest::Profile(_) => None,
    };
    let o = CheckOptions {
        limits: &c.limits,
        uncertainty: c.uncertainty.as_ref(),
        samples: c.samples,
        seed: c.seed,
        confidence: c.confidence,
        threads: c.threads,
        progress: !c.quiet,
        set_points: c.set_points,
        delay,
    };
    check(c.test.as_test(), &o).map_err(|e| match e {
        CheckError::Usage(m) => CmdError::Usage(m),
        CheckError::Runtime(m) => CmdError::Runtime(m),
    })
}

/// `simrod check`.
pub fn execute(args: &CheckArgs) -> Result<(), CmdError> {
    let c = args.config()?;
    let r = run(&c)?;
    let write = |path: &PathBuf, text: String| {
        write_atomic(path, |w| w.write_all(text.as_bytes()))
            .map_err(|e| CmdError::Runtime(format!("cannot write {}: {e}", path.display())))
    };
    if let Some(p) = &c.json {
        let text = serde_json::to_string_pretty(&report::to_json(&r))
            .map_err(|e| CmdError::Runtime(format!("JSON: {e}")))?;
        write(p, text + "\n")?;
    }
    if let Some(p) = &c.html {
        write(p, report::html(&r))?;
    }
    let text = if c.quiet { String::new() } else { report::render(&r) };
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| CmdError::Runtime(format!("stdout: {e}")))?;
    if r.approved {
        if c.quiet {
            println!("{}", report::verdict_line(&r));
        }
        Ok(())
    } else {
        // Exit code 1: the test is not approved (the table above says why).
        Err(CmdError::Runtime(report::verdict_line(&r)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn confidence_is_checked() {
        assert_eq!(parse_confidence("0.99"), Ok(0.99));
        assert!(parse_confidence("1").is_err());
        assert!(parse_confidence("0.3").is_err());
        assert!(parse_confidence("NaN").is_err());
    }
}
