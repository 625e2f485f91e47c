//! `simrod demo`: the improve-the-model loop in one command, with nothing to set up.
//!
//! 1. The virtual bench measures TP07 on the physics plant (a bench the twin did not
//!    write) with a physical effect the model lacks (hidden until the end), with the
//!    default sensor noise and a fixed seed.
//! 2. `compare` says where the model fails (and starts the history).
//! 3. `diagnose` names the missing effect and its parameters.
//! 4. The proposed effect file is written.
//! 5. `compare` again with it: the error falls; the HTML report shows before/after.
//! 6. The hidden effect is revealed next to what was found, and the files are listed.
//!
//! Every step calls the same library function as its command, with the arguments the
//! command would get from its defaults, so the demo shows exactly what a user would get
//! by hand.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use model_core::{Builtin, Maps, Params, Profile, SpeedTarget};

use crate::atomic::write_atomic;
use crate::cmd_compare::{self, CompareArgs, Compared};
use crate::cmd_diagnose::{self, DiagnoseArgs};
use crate::compare::residual::Verdict;
use crate::effects_file::{summarize_effects, write_effects};
use crate::error::CmdError;
use crate::history;
use crate::measure::write::save;
use crate::report::{change_pct, html, num, pct};
use crate::twin::ModelOptions;
use crate::vbench::bench::{BenchRun, PlantKind};
use crate::vbench::bench_effects::BenchEffects;
use crate::vbench::chain::ChainOptions;
use crate::vbench::noise::NoiseModel;

/// The effect the demo's bench has and its model lacks: friction in the differential,
/// which the torque flanges do not see (only the SuT's power does).
pub const HIDDEN: (&str, &str, f32, &str) = ("differential_friction", "coulomb_nm", 4.0, "N m");

/// Arguments of `simrod demo`.
#[derive(Debug, Clone, Args)]
pub struct DemoArgs {
    /// Directory for the demo's files (created if missing; its previous demo history is
    /// replaced).
    #[arg(long, value_name = "DIR", default_value = "simrod-demo")]
    pub dir: PathBuf,

    /// Seed of the measured run's sensor noise.
    #[arg(long, value_name = "N", default_value_t = 1, allow_negative_numbers = true, value_parser = crate::simulate::parse_seed)]
    pub seed: u64,

    /// Worker threads for the diagnosis (default: the machine's cores, at most 8).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=256), allow_negative_numbers = true)]
    pub threads: Option<u32>,
}

fn say(text: &str) -> Result<(), CmdError> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| CmdError::Runtime(format!("stdout: {e}")))
}

fn secs(t: Instant) -> String {
    format!("[{:.2} s]", t.elapsed().as_secs_f64())
}

/// Step 1: the measured run (physics plant), written to `path`.
fn make_measurement(path: &Path, seed: u64) -> Result<(usize, f64), CmdError> {
    let mut hidden = BenchEffects::none();
    hidden
        .library
        .set(HIDDEN.0, HIDDEN.1, HIDDEN.2)
        .map_err(|e| CmdError::Runtime(format!("demo effect: {e:?}")))?;
    let profile =
        Profile::builtin(Builtin::TP07, 1.0, 1.0).map_err(|e| CmdError::Runtime(format!("TP07: {e:?}")))?;
    let opts = ModelOptions::default();
    let run = BenchRun {
        plant: PlantKind::Physics,
        params: Params::thesis(opts.rates, opts.coupling),
        maps: Maps::builtin(),
        speed_target: SpeedTarget::Map,
        profile: &profile,
        supply_v: opts.supply_v,
        dt_us: 1000,
        effects: &hidden,
        chain: ChainOptions { noise: Some(NoiseModel::default()), seed, miscount: false },
        pulses: false,
    };
    let m = run.measure(path).map_err(CmdError::Runtime)?;
    save(path, &m).map_err(|e| CmdError::Runtime(format!("{}: cannot write: {e}", path.display())))?;
    Ok((m.time_s.len(), m.time_s.last().copied().unwrap_or(0.0)))
}

/// Where the model fails, in three lines.
fn failure_summary(c: &Compared) -> String {
    let r = &c.result;
    let Some(w) = r.worst_channel() else {
        return "   the model matches the measurement: no channel has structure left\n".into();
    };
    let mut o = format!(
        "   worst channel  {}: NRMSE {} %, RMSE {} {}; residual {}\n",
        w.name,
        num(100.0 * w.metrics.nrmse),
        num(w.metrics.rmse),
        w.unit,
        w.whiteness.verdict.describe()
    );
    if let Some(t) = w.top_regions.first() {
        o.push_str(&format!(
            "   worst region   {} of its squared error in {} ({} of the samples)\n",
            pct(t.error_share),
            t.region,
            pct(t.sample_share)
        ));
    }
    if let Some(s) = w.worst_spans.first() {
        o.push_str(&format!(
            "   worst span     {:.1}–{:.1} s, residual RMS {} {}\n",
            s.start_s,
            s.end_s,
            num(s.rms),
            w.unit
        ));
    }
    let coloured: Vec<&str> = r
        .channels
        .iter()
        .filter(|c| c.whiteness.verdict == Verdict::Coloured)
        .map(|c| c.name.as_str())
        .collect();
    o.push_str(&format!(
        "   structure left in {} of {} channels: {}\n",
        coloured.len(),
        r.channels.len(),
        coloured.join(", ")
    ));
    o
}

/// Per channel NRMSE before → after: the main channels, and any other whose error moved.
fn error_change(before: &Compared, after: &Compared) -> String {
    let mut rows = vec![vec![
        "channel".to_string(),
        "NRMSE before".into(),
        "".into(),
        "after".into(),
        "change".into(),
        "residual after".into(),
    ]];
    for c in &after.result.channels {
        let Some(b) = before.result.channel(&c.name) else { continue };
        let main = history::MAIN_CHANNELS.contains(&c.name.as_str());
        if !main && !html::changed(b.metrics.rmse, c.metrics.rmse) {
            continue;
        }
        let (x, y) = (b.metrics.nrmse, c.metrics.nrmse);
        rows.push(vec![
            c.name.clone(),
            format!("{} %", num(100.0 * x)),
            "→".into(),
            format!("{} %", num(100.0 * y)),
            change_pct(x, y),
            c.whiteness.verdict.describe().into(),
        ]);
    }
    let widths: Vec<usize> =
        (0..6).map(|k| rows.iter().map(|r| r[k].chars().count()).max().unwrap_or(0)).collect();
    let mut o = String::new();
    for r in &rows {
        let line = format!(
            "   {:<w0$}  {:>w1$} {} {:>w3$}  {:>w4$}  {}",
            r[0],
            r[1],
            r[2],
            r[3],
            r[4],
            r[5],
            w0 = widths[0],
            w1 = widths[1],
            w3 = widths[3],
            w4 = widths[4]
        );
        o.push_str(line.trim_end());
        o.push('\n');
    }
    o
}

/// `simrod demo`.
pub fn execute(args: &DemoArgs) -> Result<(), CmdError> {
    let start = Instant::now();
    let dir = &args.dir;
    std::fs::create_dir_all(dir)
        .map_err(|e| CmdError::Runtime(format!("{}: cannot create: {e}", dir.display())))?;
    let meas = dir.join("measured.csv");
    let fx_path = dir.join("effects.toml");
    let report = dir.join("report");
    let plot = dir.join("history.svg");
    // A fresh loop each time: the demo's history starts with this run.
    let hist = history::path_for(&meas);
    match std::fs::remove_file(&hist) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            return Err(CmdError::Runtime(format!("{}: cannot replace: {e}", hist.display())))
        }
        _ => {}
    }

    say("simrod demo: find the physical effect the model lacks, add it, watch the error fall\n\n")?;

    let t = Instant::now();
    let (n, dur) = make_measurement(&meas, args.seed)?;
    say(&format!(
        "1. Measure   {}: TP07 on the virtual bench (physics plant), {n} samples over {dur:.0} s, default sensor noise (seed {}),\n             with one physical effect the model does not have (revealed at step 6)  {}\n\n",
        meas.display(),
        args.seed,
        secs(t)
    ))?;

    let t = Instant::now();
    let before = cmd_compare::run(&CompareArgs::for_file(&meas))?;
    say(&format!(
        "2. Compare   simrod compare {}: where does the model fail?  {}\n{}\n",
        meas.display(),
        secs(t),
        failure_summary(&before)
    ))?;

    let t = Instant::now();
    let d = cmd_diagnose::run(&DiagnoseArgs { threads: args.threads, ..DiagnoseArgs::for_file(&meas) })?;
    let g = &d.diagnosis;
    let mut text =
        format!("3. Diagnose  simrod diagnose {}: which effect is missing?  {}\n", meas.display(), secs(t));
    text.push_str(&format!("   VERDICT: {}\n", g.verdict));
    text.push_str("   top candidates (share of the error above noise removed, refitted on the simulator):\n");
    for c in g.ranking.iter().take(3) {
        text.push_str(&format!(
            "     {:<24} {:>5}  {}\n",
            c.effect,
            c.confirmed_reduction.map_or_else(|| pct(c.predicted_reduction), pct),
            cmd_diagnose::params_text(c)
        ));
    }
    say(&(text + "\n"))?;

    let t = Instant::now();
    let proposed = d.proposal().map_err(|why| CmdError::Runtime(format!("demo: {why}")))?;
    write_effects(&proposed, &fx_path).map_err(|e| CmdError::Runtime(e.to_string()))?;
    say(&format!(
        "4. Add       wrote {}: {}  {}\n\n",
        fx_path.display(),
        summarize_effects(&proposed),
        secs(t)
    ))?;

    let t = Instant::now();
    let mut again = CompareArgs::for_file(&meas);
    again.model.effects = Some(fx_path.clone());
    again.report = Some(report.clone());
    let after = cmd_compare::run(&again)?;
    say(&format!(
        "5. Compare   simrod compare {} --effects {}: the error falls  {}\n{}\n",
        meas.display(),
        fx_path.display(),
        secs(t),
        error_change(&before, &after)
    ))?;

    let t = Instant::now();
    let h = history::read(&hist).map_err(|e| CmdError::Runtime(format!("{}: {e}", hist.display())))?;
    let svg = crate::cmd_history::plot(&h, false);
    write_atomic(&plot, |w| w.write_all(svg.as_bytes()))
        .map_err(|e| CmdError::Runtime(format!("{}: cannot write: {e}", plot.display())))?;
    let found = g
        .ranking
        .first()
        .filter(|c| c.effect == HIDDEN.0)
        .and_then(|c| c.params.iter().find(|p| p.name == HIDDEN.1))
        .map_or_else(
            || "not found".to_string(),
            |p| format!("found {} = {} ± {} {}", p.name, num(p.value), num(1.96 * p.std), p.unit),
        );
    let mut text = format!(
        "6. Reveal    the bench's hidden effect: {} {} = {} {}; diagnose {}\n",
        HIDDEN.0, HIDDEN.1, HIDDEN.2, HIDDEN.3, found
    );
    text.push_str(&format!("   measured run   {}\n", meas.display()));
    text.push_str(&format!("   effect file    {}\n", fx_path.display()));
    if let Some(r) = &after.report {
        text.push_str(&format!("   HTML report    {} (before/after overlay, history)\n", r.display()));
    }
    text.push_str(&format!(
        "   history        {} ({} iterations; `simrod history {}`)\n",
        hist.display(),
        h.entries.len(),
        meas.display()
    ));
    text.push_str(&format!("   history plot   {}  {}\n", plot.display(), secs(t)));
    for w in before.warnings.iter().chain(&after.warnings) {
        text.push_str(&format!("   warning: {w}\n"));
    }
    text.push_str(&format!("\ndemo took {:.2} s\n", start.elapsed().as_secs_f64()));
    say(&text)
}
