//! `simrod diagnose MEAS`: which physical effect does the model lack in this measured
//! run? The statistics are in [`crate::diagnose::engine`]; this module turns a
//! measurement file into the engine's inputs and its answer into a report, JSON or an
//! effect file.
//!
//! The twin runs on the file's recorded set points through [`crate::compare::align`]
//! (the same alignment as `simrod compare`: model step = sample interval, or a 1 ms
//! resampling), so a diagnosis and a comparison of the same file see the same model.
//!
//! Gaps: the engine fits every sample, so an interpolated stretch would be fitted as if
//! it had been measured. Files with gaps are refused (the reader's own check; there is
//! no `--allow-gaps` here), as is a file whose `gap` column flags samples or whose
//! fitted channels hold non-finite values: cut the run at the gap instead.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use model_core::{Channel, Effects};
use serde_json::{json, Map, Value};

use crate::compare::regions;
use crate::diagnose::engine::{FittedParam, Stated};
use crate::diagnose::twin::{fitted_channels, BuiltinProbe, Campaign, RecordedTwin};
use crate::diagnose::within_uncertainty::Credit;
use crate::diagnose::{self, Diagnosis, Options, VerdictKind};
use crate::effects_file::{format_effects, summarize_effects, write_effects};
use crate::error::CmdError;
use crate::measure::{self, LoadOptions, Mapping, GAP_CHANNEL};
use crate::report::table::columns;
use crate::report::{change_pct, num, pct};
use crate::simulate::check_delay;
use crate::twin::args::{ModelArgs, SensorArgs};
use crate::twin::{check_budget, Aligned, InputSource, MeasuredTwin, ModelOptions};
use simrod_io::budget::BudgetArgs;

/// Fewest fitted channels a diagnosis runs on: with fewer, most effects look alike.
pub const MIN_CHANNELS: usize = 4;

/// Candidates listed in the terminal ranking (the JSON has all of them).
const SHOWN: usize = 8;

const HOW: &str = "\
How the diagnosis works:
  The twin runs on the file's recorded set points (as in `simrod compare`). Each channel's
  noise level is estimated from the fast part of its residual, so every channel is weighted
  by 1/noise^2. Every parameter of every effect in the library gets a sensitivity run; each
  effect is scored by how much of the error above noise its parameters remove (linear
  prediction), the leaders are refitted on the simulator (confirmed), and their parameters'
  95 % intervals come from a sandwich covariance of the fit whose long-run (autocorrelated)
  residual variance uses a Bartlett taper, so it is never negative, widened to how far the
  estimate moves when one run of a campaign (a fifth of a single run) is left out, which
  shows a bias the rest of the model causes in one region. Effects whose predicted
  residual shapes coincide are reported as confounded, with the built-in profile that best
  separates them.
  Effects are selected as a set: forward steps on the linearised model, each effect kept
  only if it also removes error on data its fit did not see (leave-one-run-out in a
  campaign, contiguous fifths of a single run), then backward elimination; a set of two or
  more is refitted jointly on the simulator and named together ('missing effects: A + B').
  Verdicts: missing (the effect or set explains the error and leaves noise), partial (it
  explains part, or structure is left per channel and 2 s window, located), unexplained,
  nothing_missing (noise-like in total and in every channel and window, and no channel
  with a mains line: 50/60 Hz pickup).
  The twin runs exactly as in `simrod compare` with the same flags (--data-dir, --effects,
  --speed-window-s, ...): the bench counts encoder pulses in a window centred on each sample
  (0.1 s on the SimRod bench; 0 when the speeds are not window-counted), and the twin's
  speeds are averaged over the same window before they are compared.
  When the library leaves error (partial, unexplained), an EMPIRICAL correction of the maps
  is fitted: the maps whose nodes the runs visit (set-point grids from the recorded set
  points, friction over axle speed), one simulation per node, smoothed, the smoothing and
  the maps chosen on held-out 2 s blocks, confirmed on the simulator. When it alone removes
  clearly more than the library's proposal (15 points of the excess, held-out and on the
  simulator), no library effect is claimed. --write-data DIR writes it as a data directory
  (the corrected maps labelled EMPIRICAL) for --data-dir: a fitted table, not a physical
  effect.
  --maps-within-uncertainty also estimates the maps and parameters within their stated
  uncertainty (the thesis's σ and smooth shapes, an ASSUMED prior: docs/MODEL.md, a wall
  beyond 4 σ) by re-simulation, and reports what each channel's error becomes: error the
  data's own uncertainty can explain, or not. It takes up what a missing effect shares with a map's
  error, so beside it each library cause is credited by what it removes beyond it
  (confirmed on the simulator). The set starts from the verdict's causes, refitted with
  the maps from the identified data (dropped only where the refit no longer needs them
  and the model without them leaves no located structure on their channels);
  then the best credited cause is taken — or another of its round's confirmed causes
  whose refit fits better — and the maps estimated again from the identified data with
  it, until no cause adds more (at most four); one whose value drifts beside the
  estimated maps (the verdict's constancy test) is refused and said. A significant
  candidate the maps take as well is reported as such: the runs cannot tell the two
  readings apart. A cause counts only where the refit with it settles (otherwise it is
  reported as provisional); each member of the set gets 95 % intervals with the maps
  estimated beside it (posterior and fold jackknife, the maps re-estimated per fold).
  It is no verdict yet; --write-estimate DIR writes the estimate, refitted with the
  credited set when one stands (changed tables labelled ESTIMATED), for --data-dir, and
  DIR/effects.toml, the current effects with the set's values, for --effects — unless
  it has not settled or it makes a channel worse than the identified model on some run
  (the verdict's test for a proposal): then it writes nothing and says why.
  Files with gaps are refused: cut the run at the gap.
  Several runs are a campaign: the twin runs on each with the same effects and every fit is
  joint, so two effects confounded on one run are told apart when another run separates
  them (a different profile, scale or supply voltage).";

/// Arguments of `simrod diagnose`.
#[derive(Debug, Clone, Args)]
#[command(after_long_help = HOW)]
pub struct DiagnoseArgs {
    /// Measured runs with set points: .csv (also .txt, .tsv) or .mat, as `simrod bench`
    /// writes them. Several runs (other profiles, scales, supply voltages) are a
    /// campaign: the effects are shared and fitted to all of them jointly.
    #[arg(value_name = "MEAS", required = true, num_args = 1..)]
    pub meas: Vec<PathBuf>,

    #[command(flatten)]
    pub model: ModelArgs,

    #[command(flatten)]
    pub sensors: SensorArgs,

    /// Print the diagnosis as JSON on stdout instead of the report.
    #[arg(long)]
    pub json: bool,

    /// Write the current effects plus the effect found to this effect file (atomically).
    /// Nothing is written when the verdict proposes nothing.
    #[arg(long, value_name = "OUT.toml")]
    pub write_effects: Option<PathBuf>,

    /// When no library effect explains the error and an empirical correction of the
    /// maps (or of the throttle chain's volts per percent) is offered: write the model
    /// data with the corrected tables (labelled EMPIRICAL in their comments) to this
    /// directory, for `--data-dir` (or to compile into the firmware as model-core/data).
    /// Never an input's directory.
    #[arg(long, value_name = "DIR")]
    pub write_data: Option<PathBuf>,

    /// Also estimate the maps and parameters within their stated uncertainty
    /// (docs/MODEL.md: the σ of every map and parameter and the smooth shapes of their
    /// error, an ASSUMED prior) by re-simulation, and report how much of each channel's
    /// error that leaves, the verdict's causes (where it proposes none, its best candidate
    /// refused only for making a channel worse) refitted with the maps, and which library
    /// causes add beyond them (each taken refitted with the maps). The diagnosis itself is
    /// unchanged. Slow: about 300 simulations per
    /// iterate, up to ten iterates until settled, again for each cause taken.
    #[arg(long)]
    pub maps_within_uncertainty: bool,

    /// Write the estimate of --maps-within-uncertainty as a model data directory (the
    /// changed tables labelled ESTIMATED; refitted with the credited set when one
    /// stands), for `--data-dir`, and `DIR/effects.toml`, the current effects with the
    /// set's values, for `--effects`. Never an input's directory.
    #[arg(long, value_name = "DIR", requires = "maps_within_uncertainty")]
    pub write_estimate: Option<PathBuf>,

    /// Mapping file (TOML) renaming/scaling the file's channels to bench names.
    #[arg(long, value_name = "FILE")]
    pub mapping: Option<PathBuf>,

    /// Worker threads for the simulations (default: the machine's cores, at most 8).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=256), allow_negative_numbers = true)]
    pub threads: Option<u32>,

    #[command(flatten)]
    pub budget: BudgetArgs,
}

/// Peak memory of a diagnosis per sample of the twin's grid [bytes]: 435 measured on a
/// 300 MB bench CSV (2.13 M samples, 15 channels; `cargo bench -p workbench --bench
/// memory`), rounded up. The fits hold a fixed number of samples; this is the run.
pub const DIAGNOSE_BYTES_PER_SAMPLE: f64 = 500.0;

impl DiagnoseArgs {
    /// `simrod diagnose MEAS` with every flag at its default (for callers in code, such
    /// as the demo; a test checks these are clap's defaults).
    pub fn for_file(meas: &Path) -> Self {
        Self {
            meas: vec![meas.to_path_buf()],
            model: ModelArgs::default(),
            sensors: SensorArgs::default(),
            json: false,
            write_effects: None,
            write_data: None,
            maps_within_uncertainty: false,
            write_estimate: None,
            mapping: None,
            threads: None,
            budget: BudgetArgs::default(),
        }
    }
}

/// How the diagnosis was set up, for the report.
#[derive(Debug, Clone)]
pub struct DiagSetup {
    pub source: String,
    pub samples: usize,
    pub duration_s: f64,
    pub dt_us: u32,
    pub step_note: String,
    /// Channels fitted, in the engine's order.
    pub channels: Vec<&'static str>,
    /// Fitted channels the file lacks.
    pub missing: Vec<&'static str>,
    /// The current effects (`--effects`).
    pub base: Effects,
    pub effects_path: Option<PathBuf>,
    pub speed_window_s: f64,
    /// `--sensor-noise` as given (`None`: the noise is estimated from the residual).
    pub sensor_noise: Option<PathBuf>,
    pub notes: Vec<String>,
}

/// A finished diagnosis.
#[derive(Debug, Clone)]
pub struct Diagnosed {
    pub setup: DiagSetup,
    pub diagnosis: Diagnosis,
    /// The maps and parameters estimated within their stated uncertainty
    /// (`--maps-within-uncertainty`).
    pub within: Option<diagnose::Estimate>,
    /// [s] wall time: loading and aligning, the engine (with the estimate).
    pub timing: (f64, f64),
}

impl Diagnosed {
    /// The effects to write, or why there are none: only a `missing` or `partial`
    /// verdict proposes (an effect fitted to a noise-like or unexplained residual would be
    /// a guess).
    pub fn proposal(&self) -> Result<Effects, String> {
        let d = &self.diagnosis;
        match d.kind {
            VerdictKind::Missing | VerdictKind::Partial if d.proposed != self.setup.base => Ok(d.proposed),
            VerdictKind::NothingMissing => Err("nothing is missing, so nothing is proposed".into()),
            VerdictKind::Unexplained => {
                Err("no library effect explains the residual, so nothing is proposed".into())
            }
            _ => Err("the diagnosis proposes no change to the current effects".into()),
        }
    }

    /// The effect the verdict adds (the leading candidate when something is proposed).
    pub fn leader(&self) -> Option<&diagnose::engine::Candidate> {
        self.diagnosis.ranking.first()
    }
}

/// One run of a campaign on the twin's grid.
struct RunOnGrid {
    src: String,
    twin: MeasuredTwin,
    al: Aligned,
    notes: Vec<String>,
    /// Per fittable channel, the noise σ stated for each sample (taken while the
    /// measured channels were still in `twin`).
    stated: Vec<(Channel, Option<Vec<f64>>)>,
}

/// Load one run, check it and put it on the twin's grid (the file's values move into
/// the pairs: a long run is held once).
fn load_run(
    path: &Path,
    args: &DiagnoseArgs,
    model: &ModelOptions,
    opts: &LoadOptions,
) -> Result<RunOnGrid, CmdError> {
    let src = path.display().to_string();
    let usage = |e: String| CmdError::Usage(format!("{src}: {e}"));
    let loaded = measure::load_with(path, opts)?;
    let doing = format!("diagnosing {src}");
    check_budget(&loaded.measurement.time_s, &args.budget.budget(), &doing, DIAGNOSE_BYTES_PER_SAMPLE)
        .map_err(|e| usage(e.to_string()))?;
    if loaded.measurement.gap_mask().iter().any(|g| *g) {
        return Err(usage(format!(
            "the run has samples flagged in its `{GAP_CHANNEL}` column; diagnose fits every sample, so cut the run at the gap"
        )));
    }
    let mut twin = MeasuredTwin::new(&loaded.measurement, model, &InputSource::Recorded)
        .map_err(|e| usage(e.to_string()))?;
    check_delay(&model.effects, twin.grid.dt_us).map_err(|m| {
        CmdError::Usage(format!("{}: {m}", args.model.effects.as_deref().unwrap_or(Path::new("")).display()))
    })?;
    drop(loaded.measurement);
    let channels = fitted_channels();
    let stated = channels.iter().copied().zip(twin.stated_sigma(&channels)).collect();
    let al = twin.align_taking(model.effects).map_err(|e| usage(e.to_string()))?;
    let mut notes = loaded.notes;
    notes.push(format!("{src}: {}", al.grid.step_note));
    notes.extend(al.grid.data_notes.iter().map(|n| format!("{src}: {n}")));
    Ok(RunOnGrid { src, twin, al, notes, stated })
}

/// Every run of the command line, loaded side by side on `threads` workers (a
/// campaign's files are independent); the first failing file's error, in command-line
/// order.
fn load_runs(
    args: &DiagnoseArgs,
    model: &ModelOptions,
    opts: &LoadOptions,
    threads: usize,
) -> Result<Vec<RunOnGrid>, CmdError> {
    use rayon::prelude::*;
    let load = || -> Vec<Result<RunOnGrid, CmdError>> {
        args.meas.par_iter().map(|path| load_run(path, args, model, opts)).collect()
    };
    let loaded = match rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build() {
        Ok(pool) => pool.install(load),
        Err(_) => load(),
    };
    loaded.into_iter().collect()
}

/// Load, align and diagnose one run or a campaign of runs; writes nothing.
pub fn run(args: &DiagnoseArgs) -> Result<Diagnosed, CmdError> {
    let t0 = Instant::now();
    let mut model = args.model.load()?;
    model.sensors = args.sensors.model()?;
    let base = model.effects;
    let inputs =
        args.model.inputs().files("a measurement", &args.meas).file("--mapping", args.mapping.as_deref());
    if let Some(out) = &args.write_effects {
        inputs.check("--write-effects", out).map_err(CmdError::Usage)?;
        check_out_path(out)?;
    }
    for (flag, dir) in [("--write-data", &args.write_data), ("--write-estimate", &args.write_estimate)] {
        let Some(dir) = dir else { continue };
        inputs.check_dir(flag, dir).map_err(CmdError::Usage)?;
    }
    let load_opts = LoadOptions {
        mapping: args.mapping.as_deref().map(Mapping::load).transpose()?,
        budget: args.budget.budget(),
        ..LoadOptions::default()
    };
    let threads = args.threads.map_or_else(|| Options::default().threads, |t| t as usize);
    let mut runs = load_runs(args, &model, &load_opts, threads)?;
    let src = runs.iter().map(|r| r.src.as_str()).collect::<Vec<_>>().join(" + ");
    let limits = regions::Limits::of_model(&model).map_err(|e| CmdError::Usage(format!("{src}: {e}")))?;
    let mut o = Options {
        base,
        params: model.params(),
        regions: region_masks(&runs, &limits),
        progress: true,
        ..Options::default()
    };
    o.threads = threads;
    let dt_us = runs[0].al.grid.dt_us;
    let samples = runs.iter().map(|r| r.al.grid.time_s.len()).sum();
    let duration_s = runs.iter().map(|r| r.al.grid.duration_s()).sum();
    let step_note = runs[0].al.grid.step_note.clone();
    let fitted = fitted_series(&mut runs, &src)?;
    let probe = BuiltinProbe::standard(model.clone(), fitted.channels.clone());
    let mut notes = Vec::new();
    let twins: Vec<RecordedTwin> = runs
        .into_iter()
        .map(|r| {
            notes.extend(r.notes);
            let mut stated = r.stated;
            let mine =
                fitted.channels.iter().map(|c| stated.iter_mut().find(|(s, _)| s == c)?.1.take()).collect();
            RecordedTwin::with_stated(r.twin, fitted.channels.clone(), mine)
        })
        .collect();
    let campaign = Campaign::new(twins).map_err(|e| CmdError::Usage(format!("{src}: {e}")))?;
    let t1 = Instant::now();
    let diagnosis = diagnose::diagnose(&campaign, &fitted.series, &o, Some(&probe))
        .map_err(|e| CmdError::Runtime(format!("{src}: diagnosis failed: {e}")))?;
    let within = match args.maps_within_uncertainty {
        true => Some(
            diagnose::estimate_within_uncertainty(
                &campaign,
                &fitted.series,
                &o,
                (&diagnosis.proposed, diagnosis.unnamed.as_ref()),
            )
            .map_err(|e| {
                CmdError::Runtime(format!("{src}: the estimate within the uncertainty failed: {e}"))
            })?,
        ),
        false => None,
    };
    let t2 = Instant::now();

    if args.meas.len() > 1 {
        notes.push(format!("campaign of {} runs, fitted jointly (the effects are shared)", args.meas.len()));
    }
    if !fitted.missing.is_empty() {
        notes.push(format!("not in every file (not fitted): {}", fitted.missing.join(", ")));
    }
    Ok(Diagnosed {
        setup: DiagSetup {
            source: src,
            samples,
            duration_s,
            dt_us,
            step_note,
            channels: fitted.channels.iter().map(|c| c.name()).collect(),
            missing: fitted.missing,
            base,
            effects_path: args.model.effects.clone(),
            speed_window_s: args.sensors.speed_window_s,
            sensor_noise: args.sensors.sensor_noise.clone(),
            notes,
        },
        diagnosis,
        within,
        timing: (t1.duration_since(t0).as_secs_f64(), t2.duration_since(t1).as_secs_f64()),
    })
}

/// The measured channels the diagnosis fits, `[channel][sample]` over the runs one after
/// another, and those not in every file.
struct Fitted {
    channels: Vec<Channel>,
    series: Vec<Vec<f64>>,
    missing: Vec<&'static str>,
}

/// The fitted channels every run has (moved out of the runs' pairs); every sample must
/// be finite.
fn fitted_series(runs: &mut [RunOnGrid], src: &str) -> Result<Fitted, CmdError> {
    let mut f = Fitted { channels: Vec::new(), series: Vec::new(), missing: Vec::new() };
    let has = |r: &RunOnGrid, c: Channel| r.al.channels.iter().any(|p| !p.derived && p.name == c.name());
    for c in fitted_channels() {
        if !runs.iter().all(|r| has(r, c)) {
            f.missing.push(c.name());
            continue;
        }
        let mut all = Vec::new();
        for r in runs.iter_mut() {
            let time = &r.al.grid.time_s;
            let Some(p) = r.al.channels.iter_mut().find(|p| !p.derived && p.name == c.name()) else {
                continue;
            };
            if let Some(k) = p.meas.iter().position(|v| !v.is_finite()) {
                return Err(CmdError::Usage(format!(
                    "{}: {} is not a finite number at t = {:.6} s; diagnose needs every sample",
                    r.src,
                    c.name(),
                    time.get(k).copied().unwrap_or(f64::NAN)
                )));
            }
            all.append(&mut p.meas);
        }
        f.channels.push(c);
        f.series.push(all);
    }
    if f.channels.len() < MIN_CHANNELS {
        return Err(CmdError::Usage(format!(
            "{src}: diagnose needs at least {MIN_CHANNELS} of the measured channels; missing: {}",
            f.missing.join(", ")
        )));
    }
    Ok(f)
}

/// Operating regions as `simrod compare` classifies them (from the measured and
/// commanded signals), for the error each candidate removes per region, over the runs one
/// after another: the combined regions holding at least 1 % of the samples, and "at a
/// limit".
fn region_masks(runs: &[RunOnGrid], limits: &regions::Limits) -> Vec<(String, Vec<bool>)> {
    let classes: Vec<regions::Classification> =
        runs.iter().map(|r| regions::classify(&r.al, &regions::RegionRules::default(), limits)).collect();
    let all = || classes.iter().flat_map(|c| c.classes.iter());
    let mut masks: Vec<(String, Vec<bool>)> = (0..regions::N_COMBINED)
        .map(|i| (regions::combined_name(i), all().map(|c| c.combined() == i).collect::<Vec<bool>>()))
        .filter(|(_, m)| m.iter().filter(|x| **x).count() * 100 >= m.len())
        .collect();
    masks.push(("at a limit".into(), all().map(|c| c.limits != 0).collect()));
    masks
}

/// The output's directory must exist and the output must not be a directory: checked
/// before the (long) diagnosis, so a typo costs nothing.
fn check_out_path(out: &Path) -> Result<(), CmdError> {
    let bad = |m: &str| Err(CmdError::Usage(format!("--write-effects {}: {m}", out.display())));
    if out.file_name().is_none() || out.is_dir() {
        return bad("expected a file name");
    }
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return bad(&format!("directory {} does not exist", dir.display()));
    }
    Ok(())
}

/// Parameters as `name = value ± half the 95 % interval, unit` (no unit for ratios).
pub fn params_text(c: &diagnose::engine::Candidate) -> String {
    c.params
        .iter()
        .map(|p| {
            let pm = if p.std.is_finite() { format!(" ± {}", num(1.96 * p.std)) } else { String::new() };
            let unit = if p.unit == "-" { String::new() } else { format!(" {}", p.unit) };
            format!("{} = {}{pm}{unit}", p.name, num(p.value))
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The terminal report: the verdict first, then the evidence.
pub fn render(d: &Diagnosed) -> String {
    let s = &d.setup;
    let g = &d.diagnosis;
    let mut o = String::new();
    o.push_str(&format!("simrod diagnose: {}\n", s.source));
    o.push_str(&format!(
        "  {} samples, {:.3} s, model step {} µs; {} channels fitted; speed window {} s; sensor noise {}\n",
        s.samples,
        s.duration_s,
        s.dt_us,
        s.channels.len(),
        s.speed_window_s,
        s.sensor_noise.as_ref().map_or("estimated".to_string(), |p| format!("stated ({})", p.display()))
    ));
    o.push_str(&format!(
        "  current effects{}: {}\n",
        s.effects_path.as_ref().map_or(String::new(), |p| format!(" ({})", p.display())),
        summarize_effects(&s.base)
    ));
    for n in &s.notes {
        o.push_str(&format!("  note: {n}\n"));
    }
    o.push_str(&format!(
        "  residual energy {:.2}x what the estimated noise alone gives (1 = nothing left to explain)\n\n",
        g.excess_ratio
    ));
    o.push_str(&format!("VERDICT ({}): {}\n\n", kind_name(&g.kind), g.verdict));

    o.push_str("Ranking (share of the error above noise each effect removes; confirmed = refitted on the simulator):\n");
    let mut rows = vec![vec![
        "effect".to_string(),
        "predicted".into(),
        "confirmed".into(),
        "significant".into(),
        "cause".into(),
        "parameters (± 95 %)".into(),
    ]];
    for c in g.ranking.iter().take(SHOWN) {
        rows.push(vec![
            c.effect.to_string(),
            pct(c.predicted_reduction),
            c.confirmed_reduction.map_or("-".into(), pct),
            if c.significant { "yes" } else { "no" }.into(),
            if c.is_sensor() { "sensor" } else { "physical" }.into(),
            params_text(c),
        ]);
    }
    o.push_str(&columns(&rows, &[0, 3, 4, 5]));
    if g.ranking.len() > SHOWN {
        o.push_str(&format!(
            "  ({} more effects remove less; all of them in --json)\n",
            g.ranking.len() - SHOWN
        ));
    }
    if !g.selected.is_empty() {
        let sel: Vec<String> = g.selected.iter().map(|(e, r)| format!("{e} {}", pct(*r))).collect();
        o.push_str(&format!("  greedy selection (incremental share): {}\n", sel.join(", then ")));
    }
    o.push('\n');

    if let Some(l) = d.leader() {
        o.push_str(&format!("Per channel with {} (RMSE; noise σ estimated from the residual):\n", l.effect));
        let mut rows = vec![vec![
            "channel".to_string(),
            "noise σ".into(),
            "before".into(),
            "predicted".into(),
            "confirmed".into(),
            "change".into(),
        ]];
        for ch in &l.channels {
            let sigma = g.noise.iter().find(|(n, _)| *n == ch.channel).map_or(f64::NAN, |(_, v)| *v);
            let after = ch.rmse_confirmed.unwrap_or(ch.rmse_predicted);
            let change = change_pct(ch.rmse_before, after);
            rows.push(vec![
                ch.channel.to_string(),
                num(sigma),
                num(ch.rmse_before),
                num(ch.rmse_predicted),
                ch.rmse_confirmed.map_or("-".into(), num),
                change,
            ]);
        }
        o.push_str(&columns(&rows, &[0]));
        o.push('\n');
        if !l.regions.is_empty() {
            o.push_str(&format!(
                "Per operating region with {} (weighted mean squared error, 1.0 = noise), worst first:\n",
                l.effect
            ));
            let mut regs: Vec<_> = l.regions.iter().filter(|r| r.samples > 0.0).collect();
            regs.sort_by(|a, b| (b.before * b.samples).total_cmp(&(a.before * a.samples)));
            let mut rows = vec![vec![
                "region".to_string(),
                "samples".into(),
                "before".into(),
                "predicted".into(),
                "confirmed".into(),
            ]];
            for r in regs.iter().take(6) {
                rows.push(vec![
                    r.region.clone(),
                    pct(r.samples),
                    num(r.before),
                    num(r.predicted),
                    r.confirmed.map_or("-".into(), num),
                ]);
            }
            o.push_str(&columns(&rows, &[0]));
            o.push('\n');
        }
    }

    for grp in &g.confounded {
        o.push_str(&format!(
            "CONFOUNDED on this run: {} (cosine {:.2}: their residual shapes nearly coincide)\n",
            grp.effects.join(", "),
            grp.cosine
        ));
        match &grp.separating_profile {
            Some((p, cos)) => o.push_str(&format!(
                "  to separate them, measure: simrod bench --profile {p} (cosine there {cos:.2})\n"
            )),
            None => o.push_str("  no built-in profile separates them\n"),
        }
    }
    if let Some(e) = &g.empirical {
        o.push_str(&render_empirical(e));
    }
    if let Some(e) = &d.within {
        let ranked: Vec<&str> = g.ranking.iter().filter(|c| c.significant).map(|c| c.effect).collect();
        o.push_str(&render_within(e, &ranked));
    }
    if let Some(loc) = &g.unexplained {
        o.push_str(&format!(
            "UNEXPLAINED: {} holds {} of the excess error, worst at {}\n",
            loc.channel,
            pct(loc.share),
            loc.when()
        ));
        if let Some((name, e, t)) = &loc.region {
            o.push_str(&format!(
                "  operating region: {} of its excess in {name} ({} of the time)\n",
                pct(*e),
                pct(*t)
            ));
        }
        if let Some((name, r)) = &loc.follows {
            o.push_str(&format!(
                "  it follows {name} (correlation {r:.2}): look at the block that reads it\n"
            ));
        }
    }
    o.push_str(&format!(
        "\ndiagnose took {:.2} s (load and align {:.2} s, engine {:.2} s)\n",
        d.timing.0 + d.timing.1,
        d.timing.0,
        d.timing.1
    ));
    o
}

/// The empirical correction: the maps, what it removes per channel, or why it is refused.
fn render_empirical(e: &diagnose::empirical::Empirical) -> String {
    let mut o = String::from("\nEMPIRICAL CORRECTION (a fitted table, not a physical effect)\n");
    for m in &e.maps {
        o.push_str(&format!(
            "  {:<24} {:>3} of {:>3} nodes changed, RMS {} max {} ({})\n",
            m.file,
            m.nodes.0,
            m.nodes.1,
            num(m.rms_change),
            num(m.max_change),
            m.quantity
        ));
    }
    o.push_str(&format!(
        "  removes {} of the remaining excess error on held-out data, {} on the whole run (roughness weight {:.2e})\n",
        pct(e.heldout_reduction),
        pct(e.confirmed_reduction),
        e.lambda
    ));
    for c in e
        .channels
        .iter()
        .filter(|c| c.rmse_confirmed.is_some_and(|a| (a - c.rmse_before).abs() > 0.02 * c.rmse_before))
    {
        let after = c.rmse_confirmed.unwrap_or(c.rmse_before);
        o.push_str(&format!(
            "    {:<14} RMSE {} -> {} ({})\n",
            c.channel,
            num(c.rmse_before),
            num(after),
            change_pct(c.rmse_before, after)
        ));
    }
    match &e.refused {
        Some(why) => o.push_str(&format!("  not offered: {why}\n")),
        None => o.push_str("  write it with --write-data DIR and run the twin with --data-dir DIR\n"),
    }
    o
}

/// The maps and parameters within their stated uncertainty: what each channel's error
/// becomes, what moved most.
fn render_within(e: &diagnose::Estimate, ranked: &[&str]) -> String {
    let mut o = String::from(
        "\nMAPS AND PARAMETERS WITHIN THEIR STATED UNCERTAINTY (an estimate under an ASSUMED prior, not an identification)\n",
    );
    match e.after_set.is_empty() {
        true => o.push_str("  channel         error energy / noise: identified -> estimated\n"),
        false => o.push_str(
            "  channel         error energy / noise: identified -> estimated -> with the set below\n",
        ),
    }
    for (k, (c, before, after)) in e.channels.iter().enumerate() {
        let with = e.after_set.get(k).map_or(String::new(), |v| format!(" -> {v:>6.2}"));
        o.push_str(&format!("    {c:<14} {before:>8.2} -> {after:>6.2}{with}\n"));
    }
    let mut fields: Vec<&(String, f64)> = e.fields.iter().filter(|(_, v)| *v > 0.0).collect();
    fields.sort_by(|a, b| b.1.total_cmp(&a.1));
    let moved: Vec<String> = fields.iter().take(4).map(|(n, v)| format!("{n} {v:.2} σ")).collect();
    let mut params: Vec<&(String, f64)> = e.params.iter().collect();
    params.sort_by(|a, b| b.1.ln().abs().total_cmp(&a.1.ln().abs()));
    let factors: Vec<String> = params.iter().take(3).map(|(n, f)| format!("{n} x{f:.3}")).collect();
    o.push_str(&format!("  moved most: {}; parameters: {}\n", moved.join(", "), factors.join(", ")));
    let (name, far) = &e.furthest;
    o.push_str(&format!(
        "  furthest from the identified data: {name} at {far:.1} σ (beyond {} σ the prior is a wall)\n",
        diagnose::within_uncertainty::WALL
    ));
    let left: Vec<&str> = e.left_over().collect();
    match left.is_empty() {
        true => {
            o.push_str("  every channel's error is within what the maps' stated uncertainty can explain\n")
        }
        false => o.push_str(&format!(
            "  error the maps' stated uncertainty cannot explain (above {} per fit sample): {}\n",
            diagnose::within_uncertainty::LEFT_OVER,
            left.join(", ")
        )),
    }
    o.push_str(&render_credits(e, ranked));
    match &e.refused {
        None => o.push_str(
            "  write it with --write-estimate DIR and run the twin with --data-dir DIR --effects DIR/effects.toml\n",
        ),
        Some(why) => o.push_str(&format!("  not for adoption (--write-estimate writes nothing): {why}\n")),
    }
    o
}

/// The library causes beside the estimate: those that add more than the bar beyond it,
/// and the diagnosis' significant candidates the maps and parameters take as well.
fn render_credits(e: &diagnose::Estimate, ranked: &[&str]) -> String {
    let mut o = String::new();
    if !e.settled {
        o.push_str(&format!(
            "  the estimate had not settled after {} evaluations (a step still removed {:.0} or more): what it leaves is provisional, and a cause counts only where the refit with it settles\n",
            e.objective.len(),
            e.bar
        ));
    }
    match e.set.is_empty() {
        true => o.push_str(&format!("  no library cause adds {:.0} or more beyond it\n", e.bar)),
        false => o.push_str(&format!(
            "  beyond it, in order (the ordinary verdict's set first, then the energy each removes beyond it and those before, bar {:.0}; confirmed on the simulator; values from the set's refit with the maps from the identified data, 95 % intervals with the maps estimated beside them):\n",
            e.bar
        )),
    }
    if !e.dropped.is_empty() {
        o.push_str(&format!(
            "  taken and dropped again (a later refit did not need them): {}\n",
            e.dropped.join(", ")
        ));
    }
    if !e.located.is_empty() {
        o.push_str(&format!(
            "  kept although the refit needed them less than the bar (without them the model leaves located structure on their channels): {}\n",
            e.located.join(", ")
        ));
    }
    for (cause, why) in &e.drifting {
        o.push_str(&format!(
            "  {cause} taken and refused: {why}, a time-varying or differently shaped effect the library lacks, not a constant one\n"
        ));
    }
    for (cause, rival) in &e.lost_to {
        o.push_str(&format!(
            "  {cause} taken and replaced: the set refitted with {rival} in its place fits better (lower penalised energy)\n"
        ));
    }
    for c in &e.set {
        let interval = |k: usize| c.ci95.get(k).map(|[lo, hi]| format!(" [{}, {}]", num(*lo), num(*hi)));
        let params = c
            .params
            .iter()
            .enumerate()
            .map(|(k, (n, v, u))| format!("{n} = {}{} {u}", num(*v), interval(k).unwrap_or_default()));
        let params: Vec<String> = params.collect();
        let kind = if c.sensor { "sensor" } else { "physical" };
        let credit = match c.verdict {
            true => "verdict's".to_string(),
            false => format!("{:.0}", c.value()),
        };
        o.push_str(&format!("    {:<28} {credit:>9}  {} [{kind}]\n", c.cause, params.join(", ")));
    }
    for c in &e.provisional {
        o.push_str(&format!(
            "  {} ({:.0}) not credited: the refit of the maps with it did not settle\n",
            c.cause,
            c.value()
        ));
    }
    for c in e.set.iter().filter(|c| c.verdict) {
        let Some(alone) = e.credits.iter().find(|k| k.cause == c.cause && k.value() < e.bar) else {
            continue;
        };
        o.push_str(&format!(
            "  {}: the verdict's, kept; the maps and parameters within their uncertainty take {} of its signature as well, and alone it adds {:.0} beyond the estimate: these runs cannot tell it from an error of the identified data{}\n",
            c.cause,
            pct(alone.shared),
            alone.value(),
            separated(alone)
        ));
    }
    for name in ranked {
        let in_set = e.set.iter().any(|c| c.cause == *name);
        let Some(c) = e.credits.iter().find(|c| c.cause == *name && c.value() < e.bar && !in_set) else {
            continue;
        };
        o.push_str(&format!(
            "  {name}: the maps and parameters within their uncertainty take it as well ({} of its signature): these runs cannot tell the two readings apart{}\n",
            pct(c.shared),
            separated(c)
        ));
    }
    o
}

/// What would tell a cause from the maps ([`Credit::separator`]), for its report line.
fn separated(c: &Credit) -> String {
    c.separator.as_ref().map_or_else(String::new, |s| {
        format!("; with {} known exactly the others would take {} of it", s.unit, pct(s.shared_then))
    })
}

fn kind_name(k: &VerdictKind) -> &'static str {
    match k {
        VerdictKind::Missing => "missing",
        VerdictKind::NothingMissing => "nothing_missing",
        VerdictKind::Partial => "partial",
        VerdictKind::Unexplained => "unexplained",
    }
}

/// `{"source", "kind", "verdict", "excess_ratio", "ranking": [{"effect", "params":
/// {name: value}, "uncertainty": {name: std}, "uncertainty_data": {name: the part of
/// std the identified data's stated uncertainty contributes}, "ci95": {name: [lo, hi]}, "units",
/// "error_reduction", "predicted_reduction", "confirmed_reduction", "significant",
/// "cause": "sensor"|"physical", "moves": [channel], "leaves_structure", "drift": null or
/// {"param", "along": "time"|"speed"|"torque", "first", "last"}, "map_alias": null or
/// {"file", "shape", "value", "share"}, "refused": null or why a significant candidate is
/// not proposed, "held": [as "stated"] (the effects already in the model refitted beside
/// it, whose new values are written with it), "channels": [...]}], "selected", "stated":
/// [{"effect", "params", "uncertainty", "uncertainty_data", "ci95", "units"}] (what the verdict names, with
/// the values it proposes: a set's joint refit, not its members' own in the ranking, then
/// the effects already in the model refitted beside the lead), "taken_out": [effect] (the
/// effects already in the model the proposal takes out: the named set's joint refit
/// returned them to the thesis model), "confounded",
/// "unexplained", "noise": {channel: σ},
/// "proposed_effects": TOML text or null, "empirical", "within_uncertainty": null or
/// {"fields": [[name, RMS σ]], "params": [[first key, factor]], "furthest": [coefficient
/// or group, σ], "channels": [[channel,
/// energy before, after]], "objective": [..], "settled", "credits": [{"cause", "params": [[name,
/// value, unit]], "linear", "confirmed", "fraction", "shared", "separator": null or {"unit" (the field or
/// group that, known exactly, leaves the most of the cause its own), "shared_then" ("shared"
/// by the other fields and groups)}, "sensor", "ci95": [[lo, hi]
/// per parameter] (set members only)}] (each cause on its own), "set": [as "credits"] (the
/// forward selection, each beyond the estimate refitted with those before), "after_set": [per channel], "provisional": [as "credits"] (taken, but the
/// refit with them did not settle: not credited), "dropped": [cause] (taken, then not
/// needed by a later refit), "bar"} (`--maps-within-uncertainty`), "setup",
/// "timing_s"}`. NaN becomes null.
pub fn to_json(d: &Diagnosed) -> Value {
    let g = &d.diagnosis;
    let s = &d.setup;
    let obj = |it: Vec<(String, Value)>| Value::Object(it.into_iter().collect::<Map<String, Value>>());
    // One parameter field of every parameter, by name.
    let field = |ps: &[FittedParam], f: &dyn Fn(&FittedParam) -> Value| {
        obj(ps.iter().map(|p| (p.name.to_string(), f(p))).collect())
    };
    let stated = |st: &Stated| {
        json!({
            "effect": st.effect,
            "params": field(&st.params, &|p| json!(p.value)),
            "uncertainty": field(&st.params, &|p| json!(p.std)),
            "uncertainty_data": field(&st.params, &|p| json!(p.std_data)),
            "ci95": field(&st.params, &|p| json!([p.ci95.0, p.ci95.1])),
            "units": field(&st.params, &|p| json!(p.unit)),
        })
    };
    let ranking: Vec<Value> = g
        .ranking
        .iter()
        .map(|c| {
            json!({
                "effect": c.effect,
                "params": field(&c.params, &|p| json!(p.value)),
                "uncertainty": field(&c.params, &|p| json!(p.std)),
                "uncertainty_data": field(&c.params, &|p| json!(p.std_data)),
                "ci95": field(&c.params, &|p| json!([p.ci95.0, p.ci95.1])),
                "start": field(&c.params, &|p| json!(p.start)),
                "units": field(&c.params, &|p| json!(p.unit)),
                "error_reduction": c.reduction(),
                "predicted_reduction": c.predicted_reduction,
                "confirmed_reduction": c.confirmed_reduction,
                "significant": c.significant,
                "cause": if c.is_sensor() { "sensor" } else { "physical" },
                "moves": c.moves,
                "leaves_structure": c.leaves_structure,
                "drift": c.drift,
                "map_alias": c.map_alias,
                "refused": c.refused,
                "held": c.held.iter().map(stated).collect::<Vec<_>>(),
                "channels": c.channels,
                "regions": c.regions,
            })
        })
        .collect();
    json!({
        "source": s.source,
        "kind": kind_name(&g.kind),
        "verdict": g.verdict,
        "excess_ratio": g.excess_ratio,
        "ranking": ranking,
        "selected": g.selected.iter().map(|(e, r)| json!({"effect": e, "incremental_reduction": r})).collect::<Vec<_>>(),
        "stated": g.stated.iter().map(stated).collect::<Vec<_>>(),
        "taken_out": g.taken_out,
        "confounded": g.confounded,
        "unexplained": g.unexplained,
        "noise": obj(g.noise.iter().map(|(n, v)| (n.to_string(), json!(v))).collect()),
        "proposed_effects": d.proposal().ok().and_then(|fx| format_effects(&fx).ok()),
        "empirical": g.empirical,
        "within_uncertainty": d.within,
        "setup": {
            "samples": s.samples,
            "duration_s": s.duration_s,
            "dt_us": s.dt_us,
            "step_note": s.step_note,
            "channels": s.channels,
            "missing_channels": s.missing,
            "current_effects": summarize_effects(&s.base),
            "effects_file": s.effects_path.as_ref().map(|p| p.display().to_string()),
            "speed_window_s": s.speed_window_s,
            "sensor_noise": s.sensor_noise.as_ref().map(|p| p.display().to_string()),
            "notes": s.notes,
        },
        "timing_s": {"load_align": d.timing.0, "engine": d.timing.1},
    })
}

/// Write the proposal to `out`; `Ok(Err(why))` when nothing is proposed.
pub fn write_proposal(d: &Diagnosed, out: &Path) -> Result<Result<(), String>, CmdError> {
    match d.proposal() {
        Ok(fx) => {
            write_effects(&fx, out).map_err(|e| CmdError::Runtime(e.to_string()))?;
            Ok(Ok(()))
        }
        Err(why) => Ok(Err(why)),
    }
}

/// Write the empirically corrected model data to `dir`; `Ok(Err(why))` when none is
/// offered.
pub fn write_correction(d: &Diagnosed, dir: &Path) -> Result<Result<(), String>, CmdError> {
    let e = d.diagnosis.empirical.as_ref();
    match e.and_then(|e| e.data.as_ref()) {
        Some(data) => {
            data.write(dir).map_err(|e| CmdError::Runtime(format!("--write-data {}: {e}", dir.display())))?;
            Ok(Ok(()))
        }
        None => Ok(Err(match e.and_then(|e| e.refused.clone()) {
            Some(why) => format!("no empirical correction is offered: {why}"),
            None => "no empirical correction is offered (only when the library leaves error)".into(),
        })),
    }
}

/// The effect file `--write-estimate DIR` writes beside the data.
pub const ESTIMATE_EFFECTS: &str = "effects.toml";

/// Write the estimate within the stated uncertainty to `dir`: the model data refitted
/// with the credited set when one stands (else the estimate alone), and beside it
/// [`ESTIMATE_EFFECTS`], the current effects with the set's values, so that the two
/// files together are the model the report's last column describes.
pub fn write_estimate(d: &Diagnosed, dir: &Path) -> Result<Result<(), String>, CmdError> {
    let Some(e) = &d.within else {
        return Ok(Err("no estimate was made (--maps-within-uncertainty)".into()));
    };
    if let Some(why) = &e.refused {
        return Ok(Err(why.clone()));
    }
    let (data, fx) = e.model(d.setup.base);
    let err = |e: String| CmdError::Runtime(format!("--write-estimate {}: {e}", dir.display()));
    data.write(dir).map_err(|e| err(e.to_string()))?;
    write_effects(&fx, &dir.join(ESTIMATE_EFFECTS)).map_err(|e| err(e.to_string()))?;
    Ok(Ok(()))
}

/// `simrod diagnose`.
pub fn execute(args: &DiagnoseArgs) -> Result<(), CmdError> {
    let d = run(args)?;
    // Write first, report after: the report says what happened to the file, and a failed
    // write still shows the diagnosis before the error.
    let written = args.write_effects.as_deref().map(|p| (p, write_proposal(&d, p)));
    let data_written = args.write_data.as_deref().map(|p| (p, write_correction(&d, p)));
    let estimate_written = args.write_estimate.as_deref().map(|p| (p, write_estimate(&d, p)));
    let mut text = if args.json {
        let mut v = to_json(&d);
        if let (Some((p, Ok(Ok(())))), Some(m)) = (&written, v.as_object_mut()) {
            m.insert("effects_written".into(), json!(p.display().to_string()));
        }
        if let (Some((p, Ok(Ok(())))), Some(m)) = (&data_written, v.as_object_mut()) {
            m.insert("data_written".into(), json!(p.display().to_string()));
        }
        if let (Some((p, Ok(Ok(())))), Some(m)) = (&estimate_written, v.as_object_mut()) {
            m.insert("estimate_written".into(), json!(p.display().to_string()));
        }
        let mut s = serde_json::to_string_pretty(&v).map_err(|e| CmdError::Runtime(format!("JSON: {e}")))?;
        s.push('\n');
        s
    } else {
        render(&d)
    };
    let mut result = Ok(());
    let data_msg = data_written.map(|(p, w)| {
        let ok =
            format!("wrote the empirically corrected model data to {} (use it with --data-dir)", p.display());
        (p, w, ok)
    });
    let estimate_msg = estimate_written.map(|(p, w)| {
        let fx = p.join(ESTIMATE_EFFECTS);
        let ok = format!(
            "wrote the estimated model data to {} and its effects to {} (use them with --data-dir {} --effects {})",
            p.display(),
            fx.display(),
            p.display(),
            fx.display()
        );
        (p, w, ok)
    });
    let fx_msg = written.map(|(p, w)| {
        let ok = format!("wrote {} ({})", p.display(), summarize_effects(&d.diagnosis.proposed));
        (p, w, ok)
    });
    for (p, w, ok) in fx_msg.into_iter().chain(data_msg).chain(estimate_msg) {
        let msg = match w {
            Ok(Ok(())) => ok,
            Ok(Err(why)) => format!("{} not written: {why}", p.display()),
            Err(e) => {
                result = Err(e);
                String::new()
            }
        };
        if !msg.is_empty() {
            if args.json {
                eprintln!("{msg}"); // keep stdout pure JSON
            } else {
                text.push_str(&msg);
                text.push('\n');
            }
        }
    }
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| CmdError::Runtime(format!("stdout: {e}")))?;
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn for_file_is_the_command_line_default() {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            args: DiagnoseArgs,
        }
        let parsed = <Cli as clap::Parser>::try_parse_from(["simrod", "m.csv"]).unwrap().args;
        assert_eq!(format!("{parsed:?}"), format!("{:?}", DiagnoseArgs::for_file(Path::new("m.csv"))));
    }
}
