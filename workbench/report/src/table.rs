//! The terminal view: aligned columns, and the worst channel, region and time span
//! spelled out in words so they stand out without colour.

use std::fmt::Write;

use super::{num, pct};
use model_core::{RateSet, SpeedTarget};
use simrod_compare::budget::RegionShare;
use simrod_compare::residual::Verdict;
use simrod_compare::structure;
use simrod_compare::{ChannelResult, CompareResult};

/// Columns padded to their widest cell: those listed in `left` (text) left-aligned,
/// the others (numbers) right-aligned.
pub fn columns(rows: &[Vec<String>], left: &[usize]) -> String {
    let ncol = rows.iter().map(Vec::len).max().unwrap_or(0);
    let widths: Vec<usize> = (0..ncol)
        .map(|c| rows.iter().filter_map(|r| r.get(c)).map(|s| s.chars().count()).max().unwrap_or(0))
        .collect();
    let mut out = String::new();
    for r in rows {
        let mut line = String::new();
        for (c, (cell, w)) in r.iter().zip(&widths).enumerate() {
            if c > 0 {
                line.push_str("  ");
            }
            if left.contains(&c) {
                let _ = write!(line, "{cell:<w$}");
            } else {
                let _ = write!(line, "{cell:>w$}");
            }
        }
        out.push_str(line.trim_end());
        out.push('\n');
    }
    out
}

fn name_of(c: &ChannelResult) -> String {
    if c.derived {
        format!("{}*", c.name)
    } else {
        c.name.clone()
    }
}

fn negligible(c: &ChannelResult) -> bool {
    c.whiteness.verdict == Verdict::Negligible
}

fn region_phrase(s: &RegionShare) -> String {
    format!("{} in {} ({} of samples)", pct(s.error_share), s.region, pct(s.sample_share))
}

/// The whole terminal report.
pub fn render(r: &CompareResult) -> String {
    let mut o = String::new();
    header(&mut o, r);
    metrics(&mut o, r);
    regions(&mut o, r);
    spans(&mut o, r);
    structure(&mut o, r);
    local_structure(&mut o, r);
    o
}

/// Windows with structure beyond noise, per channel (the test `diagnose` shares).
fn local_structure(o: &mut String, r: &CompareResult) {
    let flagged: usize = r.channels.iter().map(|c| c.structure.len()).sum();
    let _ = writeln!(
        o,
        "Structure left (block means of {} s in {} s windows, {} % false alarms over all {} windows, error >= {}x the noise there): {}",
        structure::BLOCK_S,
        structure::WINDOW_S,
        100.0 * structure::ALPHA,
        r.structure_tested,
        structure::MATERIAL,
        if flagged == 0 { "none".to_string() } else { format!("{flagged} window(s)") }
    );
    for c in r.channels.iter().filter(|c| !c.structure.is_empty()) {
        let dt = r.setup.dt_us as f64 * 1e-6;
        let mut w: Vec<&structure::Window> = c.structure.iter().collect();
        w.sort_by(|a, b| a.log_p.total_cmp(&b.log_p));
        let shown: Vec<String> = w
            .iter()
            .take(3)
            .map(|x| {
                let t0 = r.time_s.get(x.start).copied().unwrap_or(x.start as f64 * dt);
                let what = if x.line_hz.is_some() || x.fast {
                    x.what(&c.unit)
                } else {
                    format!("mean {} {}", num(x.mean), c.unit)
                };
                format!(
                    "{:.1}–{:.1} s (error {:.1}x the noise, {what}, p {})",
                    t0,
                    t0 + x.len as f64 * dt,
                    x.energy_ratio,
                    structure::p_text(x.p)
                )
            })
            .collect();
        let _ = writeln!(o, "  {:<14} {} window(s): {}", c.name, c.structure.len(), shown.join("; "));
    }
}

/// What was compared and how.
fn header(o: &mut String, r: &CompareResult) {
    let s = &r.setup;
    let rates = match s.rates {
        RateSet::Programmed => "programmed",
        RateSet::Identified => "identified",
    };
    let target = match s.speed_target {
        SpeedTarget::Map => "map",
        SpeedTarget::Parameter => "parameter",
    };
    let _ = writeln!(o, "simrod compare: {}", s.source);
    let _ = writeln!(
        o,
        "  {} samples, {:.3} s, model step {} µs{}; inputs: {}",
        s.samples,
        s.duration_s,
        s.dt_us,
        if s.resampled { " (resampled)" } else { "" },
        s.inputs
    );
    let _ = writeln!(
        o,
        "  twin: {rates} rates, speed target {target}, supply {} V, effects {}",
        s.supply_v,
        if s.effects_on { "on" } else { "off" }
    );
    for n in &r.notes {
        let _ = writeln!(o, "  note: {n}");
    }
    let _ =
        writeln!(o, "  residual = sim − meas; NRMSE = RMSE / norm. (the measured range, or span/10: a tenth of the channel's operating span when the run moves it less); * = derived");
    o.push('\n');
}

/// Whole-run figures per channel and the worst channel.
fn metrics(o: &mut String, r: &CompareResult) {
    // Metrics.
    let worst = r.worst_channel().map(|c| c.name.clone());
    let mut rows = vec![vec![
        "channel".to_string(),
        "unit".into(),
        "RMSE".into(),
        "NRMSE %".into(),
        "norm.".into(),
        "fit %".into(),
        "r²".into(),
        "bias".into(),
        "max |e|".into(),
        "at [s]".into(),
        "residual".into(),
    ]];
    for c in &r.channels {
        let m = &c.metrics;
        let mut verdict = c.whiteness.verdict.describe().to_string();
        if worst.as_deref() == Some(c.name.as_str()) && !negligible(c) {
            verdict.push_str("   <- WORST");
        }
        rows.push(vec![
            name_of(c),
            c.unit.clone(),
            num(m.rmse),
            num(100.0 * m.nrmse),
            m.normalised_by.describe().into(),
            m.fit_percent.map_or("-".into(), |v| format!("{:.1}", v + 0.0)),
            m.r2.map_or("-".into(), |v| format!("{:.4}", v + 0.0)),
            num(m.bias),
            num(m.max_abs_error),
            format!("{:.3}", m.max_error_time_s),
            verdict,
        ]);
    }
    // The last column is text: left-align it by padding nothing (it is last).
    o.push_str(&columns(&rows, &[0, 1, 4, 10]));
    o.push('\n');
    let worst_c = r.worst_channel().filter(|c| !negligible(c));
    match worst_c {
        Some(c) => {
            let _ = writeln!(
                o,
                "WORST CHANNEL: {} — NRMSE {} %, RMSE {} {}, max |e| {} {} at {:.3} s",
                c.name,
                num(100.0 * c.metrics.nrmse),
                num(c.metrics.rmse),
                c.unit,
                num(c.metrics.max_abs_error),
                c.unit,
                c.metrics.max_error_time_s
            );
        }
        None if r.channels.iter().all(negligible) => {
            let _ = writeln!(o, "No channel has a residual above rounding: model and measurement agree.");
        }
        None => {
            let _ = writeln!(
                o,
                "No channel has structure left: every residual is noise-like (white) or within its sensor's counting resolution; nothing for the model to explain."
            );
        }
    }
    o.push('\n');
}

/// Operating regions and each channel's error budget.
fn regions(o: &mut String, r: &CompareResult) {
    let worst_c = r.worst_channel().filter(|c| !negligible(c));
    // Regions.
    let _ = writeln!(o, "Operating regions (share of samples):");
    if let Some(c) = r.channels.first() {
        let singles: Vec<String> = c
            .budget
            .iter()
            .filter(|b| b.kind == simrod_compare::budget::RegionKind::Single)
            .map(|b| format!("{} {}", b.region, pct(b.sample_share)))
            .collect();
        let _ = writeln!(o, "  {}", singles.join(", "));
    }
    let _ = writeln!(
        o,
        "Error budget (combined regions direction / motion / load, share of the channel's squared error):"
    );
    let mut rows = Vec::new();
    for c in r.channels.iter().filter(|c| !negligible(c)) {
        let tops: Vec<String> = c.top_regions.iter().map(region_phrase).collect();
        rows.push(vec![name_of(c), tops.join("; ")]);
    }
    if rows.is_empty() {
        let _ = writeln!(o, "  (no channel has an error to budget)");
    } else {
        for line in columns(&rows, &[0, 1]).lines() {
            let _ = writeln!(o, "  {line}");
        }
    }
    if let Some(c) = worst_c {
        if let Some(top) = c.top_regions.first() {
            let _ = writeln!(
                o,
                "WORST REGION: {} of the {} squared error is in {} ({} of the samples)",
                pct(top.error_share),
                c.name,
                top.region,
                pct(top.sample_share)
            );
        }
    }
    o.push('\n');
}

/// The worst time spans.
fn spans(o: &mut String, r: &CompareResult) {
    let s = &r.setup;
    // Spans.
    let _ = writeln!(o, "Worst {} s spans (RMS of the residual):", s.window_s);
    let mut rows = Vec::new();
    let mut worst_span: Option<(f64, &ChannelResult, usize)> = None;
    for c in r.channels.iter().filter(|c| !negligible(c)) {
        let mut row = vec![name_of(c)];
        let rank = c.structured(); // a noise-like residual's worst span is chance
        for (i, sp) in c.worst_spans.iter().enumerate() {
            row.push(format!("{:.2}–{:.2} s: {} {}", sp.start_s, sp.end_s, num(sp.rms), c.unit));
            // Rank spans across channels by RMS relative to the channel's normaliser.
            let rel = sp.rms / c.metrics.normaliser;
            if rank && i == 0 && worst_span.is_none_or(|(w, _, _)| rel > w) {
                worst_span = Some((rel, c, i));
            }
        }
        rows.push(row);
    }
    if rows.is_empty() {
        let _ = writeln!(o, "  (none)");
    } else {
        for line in columns(&rows, &[0, 1, 2, 3]).lines() {
            let _ = writeln!(o, "  {line}");
        }
    }
    if let Some((rel, c, i)) = worst_span {
        if let Some(sp) = c.worst_spans.get(i) {
            let _ = writeln!(
                o,
                "WORST SPAN: {} {:.2}–{:.2} s, residual RMS {} {} ({} % of its range)",
                c.name,
                sp.start_s,
                sp.end_s,
                num(sp.rms),
                c.unit,
                num(100.0 * rel)
            );
        }
    }
    o.push('\n');
}

/// Whiteness and cross-correlation of the residuals.
fn structure(o: &mut String, r: &CompareResult) {
    // Residual structure.
    let _ = writeln!(
        o,
        "Residual structure: whiteness over {} lags (95 % band ±{}); strongest cross-correlation with a set point and with a set-point change (+lag: the residual follows; n.s. = not significant)",
        r.channels.first().map_or(0, |c| c.whiteness.lags),
        r.channels.first().map_or("-".into(), |c| num(c.whiteness.band))
    );
    let mut rows = vec![vec![
        "channel".to_string(),
        "lag-1 ρ".into(),
        "outside band".into(),
        "verdict".into(),
        "set point: ρ @ lag".into(),
        "set-point change: ρ @ lag".into(),
    ]];
    let peak = |c: &ChannelResult, change: bool| {
        c.cross
            .iter()
            .filter(|x| x.input.starts_with("d/dt ") == change)
            .max_by(|a, b| a.peak.abs().total_cmp(&b.peak.abs()))
            .map_or("-".to_string(), |x| {
                format!(
                    "{} {:+.3} @ {:+.3} s{}{}",
                    x.input,
                    x.peak,
                    x.lag_s,
                    if x.at_edge { " (edge)" } else { "" },
                    if x.significant { "" } else { " (n.s.)" }
                )
            })
    };
    for c in r.channels.iter().filter(|c| !negligible(c)) {
        rows.push(vec![
            name_of(c),
            format!("{:+.3}", c.whiteness.lag1),
            pct(c.whiteness.fraction_outside),
            c.whiteness.verdict.describe().to_string(),
            peak(c, false),
            peak(c, true),
        ]);
    }
    if rows.len() == 1 {
        let _ = writeln!(o, "  (every residual is negligible)");
    } else {
        for line in columns(&rows, &[0, 3, 4, 5]).lines() {
            let _ = writeln!(o, "  {line}");
        }
    }
    let _ = writeln!(
        o,
        "\ncompare took {:.3} s (twin {:.3} s, analysis {:.3} s)",
        r.timing.0 + r.timing.1,
        r.timing.0,
        r.timing.1
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_align() {
        let t = columns(&[vec!["a".into(), "1".into()], vec!["long name".into(), "12.5".into()]], &[0]);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines[0], "a             1");
        assert_eq!(lines[1], "long name  12.5");
    }
}
