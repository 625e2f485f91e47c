//! The comparison as JSON (`simrod compare --json`), for scripts and CI gates.
//! Non-finite numbers become `null`. Schema: see [`to_json`].

use serde_json::{json, Map, Value};

use model_core::{RateSet, SpeedTarget};
use simrod_compare::CompareResult;
use simrod_compare::{budget, structure};

fn obj<I: IntoIterator<Item = (String, Value)>>(it: I) -> Value {
    Value::Object(it.into_iter().collect::<Map<String, Value>>())
}

/// `{"setup", "notes", "channels": {name: metrics}, "worst_channel", "regions":
/// {"rules", "limits", "samples": {region: share}, "budget": {channel: [share]},
/// "top": {channel: [share]}}, "worst_spans": {channel: [span]}, "whiteness":
/// {channel: {...}}, "cross_correlation": {channel: [peak]}, "timing_s"}`.
pub fn to_json(r: &CompareResult) -> Value {
    let s = &r.setup;
    let channels = obj(r.channels.iter().map(|c| {
        let m = &c.metrics;
        (
            c.name.clone(),
            json!({
                "unit": c.unit,
                "derived": c.derived,
                "samples": m.n,
                "rmse": m.rmse,
                "nrmse": m.nrmse,
                "normaliser": m.normaliser,
                "normalised_by": m.normalised_by,
                "fit_percent": m.fit_percent,
                "r2": m.r2,
                "bias": m.bias,
                "max_abs_error": m.max_abs_error,
                "max_error_time_s": m.max_error_time_s,
            }),
        )
    }));
    let zeros = vec![0.0; r.time_s.len()];
    let samples = obj(budget::budget(&r.regions.classes, &zeros)
        .into_iter()
        .map(|b| (b.region, json!(b.sample_share))));
    let budget = obj(r.channels.iter().map(|c| (c.name.clone(), json!(c.budget))));
    let top = obj(r.channels.iter().map(|c| (c.name.clone(), json!(c.top_regions))));
    json!({
        "source": s.source,
        "setup": {
            "dt_us": s.dt_us,
            "resampled": s.resampled,
            "step_note": s.step_note,
            "samples": s.samples,
            "duration_s": s.duration_s,
            "inputs": s.inputs,
            "params": match s.rates { RateSet::Programmed => "programmed", RateSet::Identified => "identified" },
            "speed_target": match s.speed_target { SpeedTarget::Map => "map", SpeedTarget::Parameter => "parameter" },
            "supply_v": s.supply_v,
            "speed_window_s": s.speed_window_s,
            "effects_on": s.effects_on,
            "window_s": s.window_s,
            "residual": "sim - meas",
            "nrmse_normaliser": "max - min of the measurement, or a tenth of the channel's operating span (workbench/data/channel_spans.toml) when that is larger",
        },
        "notes": r.notes,
        "channels": channels,
        "worst_channel": r.worst_channel().map(|c| c.name.clone()),
        "regions": {
            "rules": r.regions.rules,
            "limits": r.regions.limits,
            "samples": samples,
            "budget": budget,
            "top": top,
        },
        "worst_spans": obj(r.channels.iter().map(|c| (c.name.clone(), json!(c.worst_spans)))),
        "whiteness": obj(r.channels.iter().map(|c| (c.name.clone(), json!(c.whiteness)))),
        "cross_correlation": obj(r.channels.iter().map(|c| (c.name.clone(), json!(c.cross)))),
        "structure": {
            "block_s": structure::BLOCK_S,
            "window_s": structure::WINDOW_S,
            "alpha": structure::ALPHA,
            "material_energy_ratio": structure::MATERIAL,
            "windows_tested": r.structure_tested,
            "flagged": obj(r.channels.iter().filter(|c| !c.structure.is_empty()).map(|c| {
                let w: Vec<serde_json::Value> = c.structure.iter().map(|x| {
                    let t0 = r.time_s.get(x.start).copied().unwrap_or(f64::NAN);
                    let t1 = r.time_s.get(x.start + x.len - 1).copied().unwrap_or(f64::NAN);
                    json!({"start_s": t0, "end_s": t1, "mean": x.mean, "energy_ratio": x.energy_ratio, "p": x.p, "chi2": x.chi2, "dof": x.dof, "line_hz": x.line_hz, "fast": x.fast})
                }).collect();
                (c.name.clone(), json!(w))
            })),
        },
        "timing_s": { "twin": r.timing.0, "analysis": r.timing.1 },
    })
}
