//! `simrod identify <what> RUNS... --out DIR`: arguments, loading, writing. The
//! identifications themselves are in [`crate::identify`].
//!
//! Every input (runs, mapping, base data directory) is loaded and checked before any
//! output is written (exit code 2 for a bad input); the output directory then receives
//! a complete model data directory (base files with the identified ones replaced,
//! loadable with `--data-dir` and compilable as `model-core/data`), `report.md` and
//! SVG charts.

use std::path::PathBuf;

use clap::{Args, Subcommand};

use crate::datadir::ModelData;
use crate::error::CmdError;
use crate::identify::progress::Progress;
use crate::identify::run::Run;
use crate::identify::{identify, Context, What};
use crate::measure::Mapping;
use crate::simulate::{CouplingArg, RatesArg};

/// Arguments shared by every identification.
#[derive(Debug, Clone, Args)]
pub struct CommonArgs {
    /// Measured runs of the campaign (.csv, .txt, .tsv or .mat with the bench's channel
    /// names and the set points `SuT Throttle`, `Dm Left`, `Dm Right`).
    #[arg(value_name = "RUNS", required = true)]
    pub runs: Vec<PathBuf>,

    /// Output directory (created if missing): the data directory, report.md, charts.
    #[arg(long, short = 'o', value_name = "DIR")]
    pub out: PathBuf,

    /// Mapping file (TOML) renaming/scaling the runs' channels to bench names.
    #[arg(long, value_name = "FILE")]
    pub mapping: Option<PathBuf>,

    /// Base model data directory (default: the built-in data): its grids are kept, its
    /// values stay where the campaign says nothing, and its other maps are used (e.g.
    /// the friction identified before `load-maps`).
    #[arg(long, value_name = "DIR")]
    pub data_dir: Option<PathBuf>,

    /// Curtis rate set of the base parameters.
    #[arg(long, value_enum, default_value_t = RatesArg::Identified)]
    pub params: RatesArg,

    /// Coupling stiffness of the base parameters.
    #[arg(long, value_enum, default_value_t = CouplingArg::Identified)]
    pub coupling: CouplingArg,

    /// Print nothing but errors.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

/// `simrod identify` subcommands.
#[derive(Debug, Clone, Subcommand)]
pub enum IdentifyCmd {
    /// Mapped throttle -> SuT speed (1-D, forward and reverse) from steady plateaus
    /// (thesis 5.2.1): speed_map_fwd.csv, speed_map_rev.csv.
    SpeedMap(CommonArgs),
    /// (throttle, load set point) -> load axle torque and phase current (2-D, thesis
    /// 5.2.2): load_torque_L/R.csv, load_current_L/R.csv (current only from runs that
    /// log I_LML_phase / I_LMR_phase). Use the identified friction as --data-dir.
    LoadMaps(CommonArgs),
    /// (throttle, load set point) -> SuT inverter and load motor powers (2-D, thesis
    /// 5.5): sut_inverter_power.csv, load_power_L/R.csv.
    PowerMaps(CommonArgs),
    /// Axle friction per side from flange torque vs speed at zero load (thesis 5.3.1):
    /// odd cubic/linear law, threshold optimised, RMSE and r² as in table 5.7.
    Friction(CommonArgs),
    /// Connector resistance R = (V_DC_busbars - V_DC) / I_DC over plateaus (thesis 5.5).
    Resistance(CommonArgs),
    /// Inertias from throttle-step transients with the loads off (thesis 5.3.2): load L/R
    /// from flange torque minus friction, SuT from the inverter's unmapped power;
    /// undetermined when the excitation is weak.
    Inertia(CommonArgs),
    /// Curtis rate parameters and the LS threshold per direction from throttle-step
    /// transients (thesis 5.6, table 5.17): the ident.* keys.
    InverterRates(CommonArgs),
    /// Coupling stiffness from the pulse-timed twist between the R flange's Kistler and
    /// the Siemens encoder (thesis 5.4), miscounting revolutions rejected. Needs the pulse
    /// channels (`simrod bench --pulses` writes them).
    Stiffness(CommonArgs),
}

impl IdentifyCmd {
    fn split(&self) -> (What, &CommonArgs) {
        match self {
            IdentifyCmd::SpeedMap(a) => (What::SpeedMap, a),
            IdentifyCmd::LoadMaps(a) => (What::LoadMaps, a),
            IdentifyCmd::PowerMaps(a) => (What::PowerMaps, a),
            IdentifyCmd::Friction(a) => (What::Friction, a),
            IdentifyCmd::Resistance(a) => (What::Resistance, a),
            IdentifyCmd::Inertia(a) => (What::Inertia, a),
            IdentifyCmd::InverterRates(a) => (What::InverterRates, a),
            IdentifyCmd::Stiffness(a) => (What::Stiffness, a),
        }
    }
}

/// Arguments of `simrod identify`.
#[derive(Debug, Clone, Args)]
pub struct IdentifyArgs {
    #[command(subcommand)]
    pub what: IdentifyCmd,
}

/// Run `simrod identify`.
pub fn execute(args: &IdentifyArgs) -> Result<(), CmdError> {
    let (what, a) = args.what.split();
    let inputs = simrod_io::guard::Inputs::new()
        .files("a run", &a.runs)
        .file("--mapping", a.mapping.as_deref())
        .dir("--data-dir", a.data_dir.as_deref());
    inputs.check_dir("--out", &a.out).map_err(CmdError::Usage)?;
    let base = match &a.data_dir {
        Some(d) => ModelData::load(d)?,
        None => ModelData::builtin()?,
    };
    let mapping = a.mapping.as_deref().map(Mapping::load).transpose()?;
    let bar = if a.quiet { Progress::hidden() } else { Progress::new("loading", a.runs.len()) };
    let mut runs = Vec::with_capacity(a.runs.len());
    for p in &a.runs {
        runs.push(Run::load(p, mapping.as_ref())?);
        bar.tick(&p.display().to_string());
    }
    bar.finish();
    let mut ctx = Context::new(&runs, &base, &bar);
    ctx.rates = a.params.into();
    ctx.coupling = a.coupling.into();
    let result = identify(what, &ctx)?;
    let files = result
        .write(&a.out)
        .map_err(|e| CmdError::Runtime(format!("{}: cannot write: {e}", a.out.display())))?;
    if !a.quiet {
        let changed =
            if result.changed.is_empty() { "nothing".to_string() } else { result.changed.join(", ") };
        println!(
            "identify {}: {} run(s); identified {changed}; wrote {} file(s) to {} (see {})",
            what.name(),
            runs.len(),
            files.len(),
            a.out.display(),
            a.out.join("report.md").display()
        );
    }
    Ok(())
}
