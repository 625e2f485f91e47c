//! `simrod bench`: the command around the virtual bench ([`crate::vbench`]): the
//! arguments of `simrod simulate` plus the plant, its data, the measurement chain and
//! the random cases, and the files it writes.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use clap::{Args, ValueEnum};
use model_core::Maps;

use crate::atomic::write_atomic;
use crate::datadir::ModelData;
use crate::error::CmdError;
use crate::measure::write::{save, Format};
use crate::measure::Measurement;
use crate::simulate::{check_delay, check_run_size, RunSpec, SimulateArgs};
use crate::twin::args::file_error;
use crate::vbench::bench::{BenchRun, PlantKind};
use crate::vbench::bench_effects::{load_bench_effects, BenchEffects};
use crate::vbench::chain::{ChainOptions, Recorded};
use crate::vbench::noise::NoiseModel;
use crate::vbench::perturb::{perturb, summary, Uncertainty};
use crate::vbench::scenario::{moved_channels, Scenario, Truth, TruthChange};

/// `--noise`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NoiseArg {
    /// The documented defaults.
    Default,
    /// Exact model values.
    None,
    /// A noise TOML file.
    File(PathBuf),
}

fn parse_noise(s: &str) -> Result<NoiseArg, String> {
    Ok(match s {
        "default" => NoiseArg::Default,
        "none" => NoiseArg::None,
        "" => return Err("expected default, none or a noise TOML file".into()),
        f => NoiseArg::File(PathBuf::from(f)),
    })
}

/// `--plant`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PlantArg {
    /// The independent physics plant (continuous f64 physics, its own code for every
    /// effect, and physics the twin lacks).
    Physics,
    /// The twin itself (its own bits; library and acquisition effects only).
    Twin,
}

impl From<PlantArg> for PlantKind {
    fn from(p: PlantArg) -> Self {
        match p {
            PlantArg::Physics => PlantKind::Physics,
            PlantArg::Twin => PlantKind::Twin,
        }
    }
}

/// `--scenario`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ScenarioArg {
    /// A realistic random case drawn from `--seed`.
    Random,
}

/// Arguments of `simrod bench`: those of `simrod simulate` (profile, scales, `--params`,
/// `--effects`, `--dt-us`, `--out`, ...) plus the plant and the measurement chain.
#[derive(Debug, Clone, Args)]
#[command(mut_arg("out", |a| a
    .value_name("FILE.csv|FILE.mat")
    .help("Output file, CSV or MAT by its extension; replaced atomically")))]
#[command(mut_arg("effects", |a| a
    .help("Effect file (TOML): the twin's effects, bench-only physics (physics plant) and the \
           acquisition's effects; all listed in workbench/examples/bench_effects.toml")))]
#[command(mut_group("ProfileSource", |g| g.required(false)))]
pub struct BenchArgs {
    #[command(flatten)]
    pub run: SimulateArgs,

    /// The plant that makes the measurement.
    #[arg(long, value_enum, default_value_t = PlantArg::Physics)]
    pub plant: PlantArg,

    /// Perturb the bench's maps and identified parameters (smoothly, within the
    /// uncertainty the thesis reports) with this seed: a bench that is not the
    /// identified data. The twin that compares keeps the identified data.
    #[arg(long, value_name = "SEED", allow_negative_numbers = true, value_parser = crate::simulate::parse_seed)]
    pub perturb_maps: Option<u64>,

    /// Draw a realistic random case from `--seed` (profile, scales, 0–3 effects, map
    /// perturbation) instead of `--profile`/`--effects`/`--perturb-maps`; the truth is
    /// written to `--truth`.
    #[arg(long, value_enum)]
    pub scenario: Option<ScenarioArg>,

    /// Where a scenario's truth goes (default: the output's name with `.truth.toml`).
    #[arg(long, value_name = "FILE.toml", requires = "scenario")]
    pub truth: Option<PathBuf>,

    /// Write the bench's model data (its maps and parameters, perturbed with
    /// `--perturb-maps` or a scenario's perturbation) to this directory, in the format
    /// `--data-dir` reads: the twin on it, with the hidden effects, is the true model of
    /// the bench where the twin's physics describes it (for judging only).
    #[arg(long, value_name = "DIR")]
    pub write_data: Option<PathBuf>,

    /// Measurement noise: `default`, `none` (exact model values) or a TOML file
    /// (format: workbench/examples/noise.toml).
    #[arg(long, value_name = "default|none|FILE.toml", default_value = "default", value_parser = parse_noise)]
    pub noise: NoiseArg,

    /// Seed of the noise (and of `--scenario`); the same seed gives the same file.
    #[arg(long, value_name = "N", default_value_t = 1, allow_negative_numbers = true, value_parser = crate::simulate::parse_seed)]
    pub seed: u64,

    /// The Siemens encoder loses pulses at high speed (thesis fig. 5.35/5.36).
    #[arg(long)]
    pub miscount: bool,

    /// Also export the R shaft's pulse channels (thesis table 5.9): `inc:Kistler`,
    /// `inc:SiemensEnc` (cumulative edge counts) and `tedge:Kistler`, `tedge:SiemensEnc`
    /// (time of the last edge) — what `simrod identify stiffness` needs.
    #[arg(long)]
    pub pulses: bool,
}

impl BenchArgs {
    /// The chain the arguments ask for (loads the noise file).
    pub fn chain(&self) -> Result<ChainOptions, CmdError> {
        let noise = match &self.noise {
            NoiseArg::Default => Some(NoiseModel::default()),
            NoiseArg::None => None,
            NoiseArg::File(p) => Some(NoiseModel::load(p)?),
        };
        Ok(ChainOptions { noise, seed: self.seed, miscount: self.miscount })
    }
}

/// A bench run: the file's content, and a scenario's truth.
#[derive(Debug)]
pub struct Benched {
    pub measurement: Measurement,
    /// `(path, TOML)` of the truth file, with `--scenario`.
    pub truth: Option<(PathBuf, String)>,
    /// The bench's model data (`--write-data`): the run's, perturbed when asked; `None`:
    /// the built-in data (loaded only when written).
    pub data: Option<Arc<ModelData>>,
}

/// The effect file (any of the three vocabularies) and the run it goes into; the
/// twin's own checks applied when the twin is the plant.
fn spec_and_effects(args: &BenchArgs, run: &SimulateArgs) -> Result<(RunSpec, BenchEffects), CmdError> {
    let mut plain = run.clone();
    let fx = match plain.model.effects.take() {
        Some(path) => load_bench_effects(&path).map_err(|e| file_error("--effects", e))?,
        None => BenchEffects::none(),
    };
    let mut spec = plain.spec()?;
    spec.config.effects = fx.library;
    if args.plant == PlantArg::Twin {
        if let Some(path) = &run.model.effects {
            check_delay(&fx.library, spec.config.dt_us)
                .map_err(|m| CmdError::Usage(format!("{}: {m}", path.display())))?;
        }
        spec.simulation()?;
    }
    Ok((spec, fx))
}

/// The bench's data: the run's, perturbed with `seed` when asked; what the
/// perturbation changed (empty without one), for a scenario's truth.
fn bench_data(
    spec: &mut RunSpec,
    run: &SimulateArgs,
    seed: Option<u64>,
) -> Result<Vec<TruthChange>, CmdError> {
    let Some(seed) = seed else { return Ok(Vec::new()) };
    let base = match &spec.data {
        Some(d) => d.as_ref().clone(),
        None => ModelData::builtin().map_err(|e| CmdError::Runtime(format!("built-in data: {e}")))?,
    };
    let p = perturb(&base, seed, &Uncertainty::thesis());
    let changes = summary(&base, &p)
        .items
        .into_iter()
        .filter(|i| i.rms > 0.0)
        .map(|i| TruthChange { name: i.name, unit: i.unit.to_owned(), rms: i.rms, max_abs: i.max_abs })
        .collect();
    spec.config.params = p.params(run.model.params.into(), run.model.coupling.into());
    spec.data = Some(Arc::new(p));
    Ok(changes)
}

/// The simulate arguments of a scenario: its profile and scales, no effect file.
fn scenario_args(args: &BenchArgs, s: &Scenario) -> Result<SimulateArgs, CmdError> {
    let r = &args.run;
    if r.source.profile.is_some() || r.source.profile_file.is_some() || r.model.effects.is_some() {
        return Err(CmdError::Usage(
            "--scenario random draws the profile and the effects: give no --profile, --profile-file or --effects"
                .into(),
        ));
    }
    if args.perturb_maps.is_some() {
        return Err(CmdError::Usage(
            "--scenario random draws the map perturbation: give no --perturb-maps".into(),
        ));
    }
    let mut run = r.clone();
    run.source.profile = Some(s.profile);
    run.scales.throttle_scale = Some(s.throttle_scale);
    run.scales.load_scale = Some(s.load_scale);
    Ok(run)
}

/// The truth of scenario `s` run as `run`, whose exact channels are `all`: what each
/// effect moves (against an exact run without it) and what the perturbation changed.
fn scenario_truth(
    s: &Scenario,
    run: &BenchRun<'_>,
    all: &Recorded,
    perturbation: Vec<TruthChange>,
) -> Result<String, CmdError> {
    let mut with = all.clone();
    run.effects.daq.apply_before_noise(&mut with);
    let mut moves = Vec::with_capacity(s.picks.len());
    for i in 0..s.picks.len() {
        let without_fx = s.effects_without(i);
        let mut without = BenchRun { effects: &without_fx, ..*run }.exact().map_err(CmdError::Runtime)?;
        without_fx.daq.apply_before_noise(&mut without);
        moves.push(moved_channels(&with, &without));
    }
    Truth::new(s, moves, perturbation).to_toml().map_err(CmdError::Runtime)
}

/// Run the bench `args` describe; nothing is written.
pub fn bench(args: &BenchArgs) -> Result<Benched, CmdError> {
    if Format::of(&args.run.out).is_none() {
        return Err(CmdError::Usage(format!(
            "--out {}: the file name must end in .csv or .mat",
            args.run.out.display()
        )));
    }
    let scenario = args.scenario.map(|_| Scenario::draw(args.seed));
    let run_args = match &scenario {
        Some(s) => scenario_args(args, s)?,
        None => args.run.clone(),
    };
    if scenario.is_none() && run_args.source.profile.is_none() && run_args.source.profile_file.is_none() {
        return Err(CmdError::Usage(
            "give one of --profile NAME, --profile-file FILE.toml or --scenario random".into(),
        ));
    }
    let (mut spec, fx) = match &scenario {
        Some(s) => {
            let (spec, _) = spec_and_effects(args, &run_args)?;
            (spec, s.effects())
        }
        None => spec_and_effects(args, &run_args)?,
    };
    let rows = spec.profile.duration_us() as f64 / f64::from(spec.config.dt_us);
    check_run_size(
        &args.run.out,
        rows,
        spec.config.dt_us,
        &args.run.budget,
        BENCH_ROW_BYTES,
        BENCH_HOLD_BYTES,
    )?;
    let perturb_seed = scenario.as_ref().map_or(args.perturb_maps, |s| s.perturb_maps);
    let perturbation = bench_data(&mut spec, &run_args, perturb_seed)?;
    let data = spec.data.clone();
    let maps = match &spec.data {
        Some(d) => d.maps().map_err(|e| CmdError::Usage(format!("--data-dir: {e}")))?,
        None => Maps::builtin(),
    };
    let run = BenchRun {
        plant: args.plant.into(),
        params: spec.config.params,
        maps,
        speed_target: spec.config.speed_target,
        profile: &spec.profile,
        supply_v: spec.supply_v,
        dt_us: spec.config.dt_us,
        effects: &fx,
        chain: args.chain()?,
        pulses: args.pulses,
    };
    let exact = run.exact().map_err(CmdError::Runtime)?;
    let truth = match &scenario {
        Some(s) => Some((truth_path(args), scenario_truth(s, &run, &exact, perturbation)?)),
        None => None,
    };
    let measurement = run.record(exact, &args.run.out);
    Ok(Benched { measurement, truth, data })
}

/// Bytes a bench row takes in the file: 141 measured (CSV, 17 channels), rounded up.
const BENCH_ROW_BYTES: f64 = 160.0;
/// Memory a bench row holds while the run is made: 256 measured (physics plant, 2.13 M
/// rows), rounded up.
const BENCH_HOLD_BYTES: f64 = 300.0;

/// `--truth`, or the output's name with `.truth.toml`.
fn truth_path(args: &BenchArgs) -> PathBuf {
    args.truth.clone().unwrap_or_else(|| args.run.out.with_extension("truth.toml"))
}

/// `simrod bench`.
pub fn execute(args: &BenchArgs) -> Result<(), CmdError> {
    let start = Instant::now();
    let out: &Path = &args.run.out;
    let inputs = args.run.inputs().file(
        "--noise",
        match &args.noise {
            NoiseArg::File(p) => Some(p.as_path()),
            _ => None,
        },
    );
    inputs.check("--out", out).map_err(CmdError::Usage)?;
    if args.scenario.is_some() {
        let truth = truth_path(args);
        inputs.check("--truth", &truth).map_err(CmdError::Usage)?;
        if truth == out {
            return Err(CmdError::Usage(format!("--truth {}: the same file as --out", truth.display())));
        }
    }
    if let Some(dir) = &args.write_data {
        inputs.check_dir("--write-data", dir).map_err(CmdError::Usage)?;
    }
    let Benched { measurement: m, truth, data } = bench(args)?;
    save(out, &m).map_err(|e| CmdError::Runtime(format!("{}: cannot write: {e}", out.display())))?;
    if let Some(dir) = &args.write_data {
        let builtin = || ModelData::builtin().map(Arc::new).map_err(|e| format!("built-in data: {e}"));
        let written = data.map_or_else(builtin, Ok).and_then(|d| d.write(dir).map_err(|e| e.to_string()));
        written.map_err(|e| CmdError::Runtime(format!("--write-data {}: {e}", dir.display())))?;
    }
    if let Some((path, text)) = &truth {
        write_atomic(path, |w| w.write_all(text.as_bytes()))
            .map_err(|e| CmdError::Runtime(format!("{}: cannot write: {e}", path.display())))?;
    }
    if !args.run.quiet {
        println!(
            "wrote {}: {} samples of {} channels, {:.3} s of bench time, in {:.2} s",
            out.display(),
            m.time_s.len(),
            m.signals.len(),
            m.time_s.last().copied().unwrap_or(0.0),
            start.elapsed().as_secs_f64()
        );
        if let Some((path, _)) = &truth {
            println!("wrote {}: the scenario's truth (what is hidden; for judging only)", path.display());
        }
        if let Some(dir) = &args.write_data {
            println!("wrote {}: the bench's model data (for judging only)", dir.display());
        }
    }
    Ok(())
}

#[cfg(test)]
#[path = "cmd_bench_tests.rs"]
mod tests;
