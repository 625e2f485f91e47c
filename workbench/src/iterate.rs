//! The improve-the-model loop around `simrod compare`: what a comparison records in the
//! history, and what its report needs to show the step from the previous iteration
//! (the baseline run "before" and the error per iteration).

use std::path::Path;

use model_core::{CouplingStiffness, Effects, RateSet, SpeedTarget};

use crate::compare::{metrics, CompareError, CompareOptions, CompareResult};
use crate::history::{self, Entry, History, OptionsRec};
use crate::report::html::{Baseline, BaselineChannel, HistoryRow, HistoryView};
use crate::twin::MeasuredTwin;

/// The options record of a comparison.
pub fn options_rec(
    opts: &CompareOptions,
    r: &CompareResult,
    mapping: Option<&Path>,
    allow_gaps: bool,
) -> OptionsRec {
    OptionsRec {
        params: match opts.model.rates {
            RateSet::Programmed => "programmed",
            RateSet::Identified => "identified",
        }
        .into(),
        speed_target: match opts.model.speed_target {
            SpeedTarget::Map => "map",
            SpeedTarget::Parameter => "parameter",
        }
        .into(),
        coupling: match opts.model.coupling {
            CouplingStiffness::Identified => "identified",
            CouplingStiffness::Datasheet => "datasheet",
        }
        .into(),
        supply_v: opts.model.supply_v,
        inputs: r.setup.inputs.clone(),
        window_s: opts.window_s,
        mapping: mapping.map(|p| p.display().to_string()),
        allow_gaps,
        data_dir: None,
        speed_window_s: Some(opts.model.sensors.speed_window_s),
    }
}

/// The effects to draw as "before": the latest history record's, when they differ from
/// the effects compared now (`None` otherwise, or when the record cannot be read back).
pub fn previous_effects(h: &History, now: &Effects) -> Option<(Effects, String)> {
    let (i, e) = h.entries.iter().enumerate().next_back()?;
    let fx = e.effects()?;
    (fx != *now).then(|| (fx, format!("iteration {} of the history, {}", i + 1, e.timestamp)))
}

/// The run simulated with `effects` instead of the compared ones, paired with the same
/// measured samples (gaps left out as in the comparison).
pub fn baseline(
    twin: &MeasuredTwin,
    opts: &CompareOptions,
    effects: Effects,
    origin: String,
) -> Result<Baseline, CompareError> {
    let al = twin.align(effects)?;
    let channels = al
        .channels
        .iter()
        .map(|p| {
            let (e, m) = metrics::paired(p, &al.grid.time_s, &al.grid.gaps);
            BaselineChannel {
                name: p.name.clone(),
                sim: p.sim.clone(),
                residual: e,
                rmse: m.rmse,
                nrmse: m.nrmse,
            }
        })
        .collect();
    Ok(Baseline {
        origin,
        before: crate::effects_file::summarize_effects(&effects),
        after: crate::effects_file::summarize_effects(&opts.model.effects),
        channels,
    })
}

/// The history as the report shows it (main channels).
pub fn history_view(path: &Path, entries: &[Entry]) -> HistoryView {
    let channels = history::shown_channels(entries, false);
    HistoryView {
        path: path.display().to_string(),
        rows: entries
            .iter()
            .map(|e| HistoryRow {
                timestamp: e.timestamp.clone(),
                effects: e.effects.summary.clone(),
                nrmse: channels.iter().map(|c| e.nrmse(c)).collect(),
            })
            .collect(),
        channels,
    }
}
