//! `simrod history MEAS`: the error per channel over the iterations of the
//! improve-the-model loop, from the history `simrod compare` keeps next to MEAS
//! (`<stem>.simrod-history.jsonl`, see [`crate::history`]).

use std::io::Write;
use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use crate::atomic::write_atomic;
use crate::error::CmdError;
use crate::history::{self, History};
use crate::report::svg::history_chart;
use crate::report::{change_pct, num};

/// Arguments of `simrod history`.
#[derive(Debug, Clone, Args)]
pub struct HistoryArgs {
    /// The measurement whose comparisons to show (or its `.simrod-history.jsonl` file).
    #[arg(value_name = "MEAS")]
    pub meas: PathBuf,

    /// Print the records as JSON on stdout instead of the table.
    #[arg(long)]
    pub json: bool,

    /// Also write a plot of NRMSE per iteration (SVG, replaced atomically).
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,

    /// Every recorded channel, not only the main ones.
    #[arg(long)]
    pub all: bool,
}

/// Read the history of `args.meas`; a missing history is a usage error (nothing to show).
pub fn load(args: &HistoryArgs) -> Result<History, CmdError> {
    let path = history::path_for(&args.meas);
    if !path.exists() {
        return Err(CmdError::Usage(format!(
            "{}: no history ({} does not exist); `simrod compare {}` starts one",
            args.meas.display(),
            path.display(),
            args.meas.display()
        )));
    }
    history::read(&path).map_err(|e| CmdError::Usage(format!("{}: cannot read: {e}", path.display())))
}

/// The table: one row per iteration, NRMSE % per channel, worst channel, effects.
pub fn render(h: &History, all: bool) -> String {
    let chans = history::shown_channels(&h.entries, all);
    let mut rows = vec![{
        let mut r = vec!["#".to_string(), "time (UTC)".into()];
        r.extend(chans.iter().cloned());
        r.extend(["worst".to_string(), "effects".into()]);
        r
    }];
    for (i, e) in h.entries.iter().enumerate() {
        let mut r =
            vec![(i + 1).to_string(), e.timestamp.replace('T', " ").trim_end_matches('Z').to_string()];
        r.extend(chans.iter().map(|c| e.nrmse(c).map_or("-".into(), |v| num(100.0 * v))));
        r.push(e.worst_channel.clone().unwrap_or_else(|| "-".into()));
        r.push(e.effects.summary.clone());
        rows.push(r);
    }
    if let (Some(first), Some(last)) = (h.entries.first(), h.entries.last()) {
        if h.entries.len() > 1 {
            let mut r = vec![format!("1→{}", h.entries.len()), "change".into()];
            r.extend(chans.iter().map(|c| match (first.nrmse(c), last.nrmse(c)) {
                (Some(a), Some(b)) => change_pct(a, b),
                _ => "-".into(),
            }));
            rows.push(r);
        }
    }
    let ncol = rows.iter().map(Vec::len).max().unwrap_or(0);
    let widths: Vec<usize> = (0..ncol)
        .map(|c| rows.iter().filter_map(|r| r.get(c)).map(|s| s.chars().count()).max().unwrap_or(0))
        .collect();
    let mut o = format!("simrod history: {} ({} iterations)\n", h.path.display(), h.entries.len());
    o.push_str("  NRMSE % per channel (RMSE / range of the measurement)\n");
    for n in history::notes(h) {
        o.push_str(&format!("  note: {n}\n"));
    }
    o.push('\n');
    for r in &rows {
        let mut line = String::new();
        for (c, (cell, w)) in r.iter().zip(&widths).enumerate() {
            if c > 0 {
                line.push_str("  ");
            }
            // Text columns (time, worst, effects) left, numbers right.
            if c == 1 || c + 2 >= ncol {
                line.push_str(&format!("{cell:<w$}"));
            } else {
                line.push_str(&format!("{cell:>w$}"));
            }
        }
        o.push_str(line.trim_end());
        o.push('\n');
    }
    o
}

/// The plot: NRMSE % per iteration for the shown channels.
pub fn plot(h: &History, all: bool) -> String {
    let series: Vec<(String, Vec<Option<f64>>)> = history::shown_channels(&h.entries, all)
        .into_iter()
        .map(|c| {
            let v = h.entries.iter().map(|e| e.nrmse(&c).map(|v| 100.0 * v)).collect();
            (c, v)
        })
        .collect();
    history_chart(&format!("NRMSE per iteration: {}", h.path.display()), "NRMSE [%]", &series)
}

/// `simrod history`.
pub fn execute(args: &HistoryArgs) -> Result<(), CmdError> {
    if let Some(p) = &args.plot {
        let inputs = simrod_io::guard::Inputs::new()
            .file("the measurement", Some(&args.meas))
            .file("the history", Some(&history::path_for(&args.meas)));
        inputs.check("--plot", p).map_err(CmdError::Usage)?;
    }
    let h = load(args)?;
    for w in &h.warnings {
        eprintln!("warning: {w}");
    }
    let text = if args.json {
        let v = json!({
            "history": h.path.display().to_string(),
            "channels": history::shown_channels(&h.entries, args.all),
            "notes": history::notes(&h),
            "warnings": h.warnings,
            "iterations": h.entries,
        });
        let mut s = serde_json::to_string_pretty(&v).map_err(|e| CmdError::Runtime(format!("JSON: {e}")))?;
        s.push('\n');
        s
    } else {
        render(&h, args.all)
    };
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| CmdError::Runtime(format!("stdout: {e}")))?;
    if let Some(p) = &args.plot {
        let svg = plot(&h, args.all);
        write_atomic(p, |w| w.write_all(svg.as_bytes()))
            .map_err(|e| CmdError::Runtime(format!("{}: cannot write: {e}", p.display())))?;
        eprintln!("plot: {}", p.display());
    }
    Ok(())
}
