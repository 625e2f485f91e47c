//! `simrod compare --report DIR`: one self-contained `DIR/index.html` (inline CSS and
//! SVG, no script, nothing fetched), one section per channel: measured vs simulated,
//! the residual with the worst windows shaded, and the error budget. With [`Extras`]:
//! a before/after overlay for the channels a change of effects moved, and the error
//! per iteration from the compare history.

use std::fmt::Write as _;
use std::io;
use std::path::{Path, PathBuf};

use super::svg::{budget_chart, esc, history_chart, line_chart, Bar, Series};
use super::{change_pct, num, pct};
use simrod_compare::budget::RegionKind;
use simrod_compare::residual::Verdict;
use simrod_compare::{ChannelResult, CompareResult};
use simrod_io::atomic::write_atomic;

const CSS: &str = "body{font-family:sans-serif;margin:1.5em;color:#222;max-width:960px}\
table{border-collapse:collapse;font-size:13px}td,th{padding:2px 8px;border-bottom:1px solid #ddd}\
td.n{text-align:right;font-variant-numeric:tabular-nums}tr.worst{background:#fde2e1;font-weight:bold}\
h2{margin-top:2em;border-top:2px solid #444;padding-top:.5em}.note{color:#555;font-size:13px}\
.flag{color:#c0392b;font-weight:bold}svg{display:block;margin:.5em 0}a{color:#1f5fa8}";

fn channel_id(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect()
}

fn channel_section(o: &mut String, c: &ChannelResult, t: &[f64], worst: bool) {
    let m = &c.metrics;
    let _ = write!(
        o,
        "<h2 id=\"{}\">{}{}{}</h2>",
        channel_id(&c.name),
        esc(&c.name),
        if c.derived { " (derived)" } else { "" },
        if worst { " <span class=\"flag\">worst channel</span>" } else { "" }
    );
    let _ = write!(
        o,
        "<p>RMSE {} {u}, NRMSE {} %, fit {}, r² {}, bias {} {u}, max |e| {} {u} at {:.3} s. Residual: {}.</p>",
        num(m.rmse),
        num(100.0 * m.nrmse),
        m.fit_percent.map_or("-".into(), |v| format!("{v:.1} %")),
        m.r2.map_or("-".into(), |v| format!("{v:.4}")),
        num(m.bias),
        num(m.max_abs_error),
        m.max_error_time_s,
        c.whiteness.verdict.describe(),
        u = esc(&c.unit)
    );
    let negligible = c.whiteness.verdict == Verdict::Negligible;
    let shade: Vec<(f64, f64)> =
        if negligible { Vec::new() } else { c.worst_spans.iter().map(|s| (s.start_s, s.end_s)).collect() };
    o.push_str(&line_chart(
        &format!("{}: measured vs simulated", c.name),
        &c.unit,
        t,
        &[
            Series { values: &c.meas, color: "#1f77b4", label: "measured" },
            Series { values: &c.sim, color: "#ff7f0e", label: "simulated" },
        ],
        &shade,
        260.0,
    ));
    o.push_str(&line_chart(
        &format!("{}: residual sim − meas (worst windows shaded)", c.name),
        &c.unit,
        t,
        &[Series { values: &c.residual(), color: "#c0392b", label: "residual" }],
        &shade,
        200.0,
    ));
    if negligible {
        o.push_str("<p class=\"note\">The residual is at rounding level: no budget.</p>");
        return;
    }
    let spans: Vec<String> = c
        .worst_spans
        .iter()
        .map(|s| format!("{:.2}–{:.2} s (RMS {} {})", s.start_s, s.end_s, num(s.rms), esc(&c.unit)))
        .collect();
    let _ = write!(o, "<p>Worst windows: {}.</p>", spans.join(", "));
    let mut comb: Vec<_> = c.budget.iter().filter(|b| b.kind == RegionKind::Combined).collect();
    comb.sort_by(|a, b| b.error_share.total_cmp(&a.error_share));
    comb.truncate(8);
    let bars: Vec<Bar<'_>> = comb
        .iter()
        .map(|b| Bar { label: &b.region, error: b.error_share, samples: b.sample_share })
        .collect();
    o.push_str(&budget_chart(&format!("{}: error budget by operating region", c.name), &bars));
    let singles: Vec<Bar<'_>> = c
        .budget
        .iter()
        .filter(|b| b.kind == RegionKind::Single)
        .map(|b| Bar { label: &b.region, error: b.error_share, samples: b.sample_share })
        .collect();
    o.push_str(&budget_chart(&format!("{}: error budget by single condition", c.name), &singles));
    let xc: Vec<String> = c
        .cross
        .iter()
        .map(|x| {
            format!(
                "<tr><td>{}</td><td class=n>{:+.3}</td><td class=n>{:+.3}{}</td><td>{}</td></tr>",
                esc(&x.input),
                x.peak,
                x.lag_s,
                if x.at_edge { " (edge)" } else { "" },
                if x.significant { "yes" } else { "no" }
            )
        })
        .collect();
    let _ = write!(
        o,
        "<p>Whiteness: lag-1 ρ {:+.3}, {} of {} lags outside ±{}.</p>\
         <table><tr><th>input</th><th>peak ρ</th><th>lag [s]</th><th>significant</th></tr>{}</table>",
        c.whiteness.lag1,
        pct(c.whiteness.fraction_outside),
        c.whiteness.lags,
        num(c.whiteness.band),
        xc.join("")
    );
}

/// A channel's error must move by this share of its RMSE to count as changed (noise-only
/// channels move by far less when an effect is added).
pub const CHANGED_REL: f64 = 0.05;

/// The same run simulated with other effects (the previous iteration's, or
/// `--baseline-effects`): the "before" of the overlay.
#[derive(Debug, Clone, Default)]
pub struct Baseline {
    /// Where the baseline's effects came from, for the heading.
    pub origin: String,
    /// The baseline's effects, one line.
    pub before: String,
    /// The current comparison's effects, one line.
    pub after: String,
    /// Per channel, in the comparison's order.
    pub channels: Vec<BaselineChannel>,
}

/// One channel simulated with the baseline's effects.
#[derive(Debug, Clone, Default)]
pub struct BaselineChannel {
    pub name: String,
    pub sim: Vec<f64>,
    /// `sim − meas`, NaN where left out.
    pub residual: Vec<f64>,
    pub rmse: f64,
    pub nrmse: f64,
}

/// The compare history, for the error-per-iteration section.
#[derive(Debug, Clone, Default)]
pub struct HistoryView {
    /// The file it was read from.
    pub path: String,
    /// Channel names, the columns.
    pub channels: Vec<String>,
    /// One row per iteration, oldest first.
    pub rows: Vec<HistoryRow>,
}

/// One iteration.
#[derive(Debug, Clone, Default)]
pub struct HistoryRow {
    pub timestamp: String,
    pub effects: String,
    /// NRMSE (0..1) per column.
    pub nrmse: Vec<Option<f64>>,
}

/// What a report shows beyond the comparison itself.
#[derive(Debug, Clone, Default)]
pub struct Extras {
    pub baseline: Option<Baseline>,
    pub history: Option<HistoryView>,
}

/// Whether a channel's error moved between baseline and now (see [`CHANGED_REL`]).
pub fn changed(before_rmse: f64, after_rmse: f64) -> bool {
    before_rmse.is_finite()
        && after_rmse.is_finite()
        && (after_rmse - before_rmse).abs() > CHANGED_REL * before_rmse.max(after_rmse)
}

fn baseline_section(o: &mut String, r: &CompareResult, b: &Baseline) {
    let _ = write!(
        o,
        "<h2 id=\"before-after\">Before / after</h2><p>Before: {} ({}).<br>After: {}.</p>",
        esc(&b.before),
        esc(&b.origin),
        esc(&b.after)
    );
    o.push_str("<table><tr><th>channel</th><th>unit</th><th>RMSE before</th><th>RMSE after</th><th>NRMSE % before</th><th>NRMSE % after</th><th>change</th></tr>");
    let mut moved = Vec::new();
    for c in &r.channels {
        let Some(bc) = b.channels.iter().find(|x| x.name == c.name) else { continue };
        let ch = changed(bc.rmse, c.metrics.rmse);
        if ch {
            moved.push((c, bc));
        }
        let _ = write!(
            o,
            "<tr{}><td>{}</td><td>{}</td><td class=n>{}</td><td class=n>{}</td><td class=n>{}</td><td class=n>{}</td><td class=n>{}</td></tr>",
            if ch { " class=\"worst\"" } else { "" },
            esc(&c.name),
            esc(&c.unit),
            num(bc.rmse),
            num(c.metrics.rmse),
            num(100.0 * bc.nrmse),
            num(100.0 * c.metrics.nrmse),
            change_pct(bc.rmse, c.metrics.rmse)
        );
    }
    o.push_str("</table>");
    if moved.is_empty() {
        let _ = write!(
            o,
            "<p class=\"note\">No channel's error moved by more than {:.0} %.</p>",
            100.0 * CHANGED_REL
        );
        return;
    }
    let _ = write!(
        o,
        "<p class=\"note\">Highlighted: error moved by more than {:.0} %; overlays below.</p>",
        100.0 * CHANGED_REL
    );
    for (c, bc) in moved {
        o.push_str(&line_chart(
            &format!("{}: measured, before, after", c.name),
            &c.unit,
            &r.time_s,
            &[
                Series { values: &c.meas, color: "#1f77b4", label: "measured" },
                Series { values: &bc.sim, color: "#9e9e9e", label: "before" },
                Series { values: &c.sim, color: "#ff7f0e", label: "after" },
            ],
            &[],
            260.0,
        ));
        o.push_str(&line_chart(
            &format!("{}: residual before and after", c.name),
            &c.unit,
            &r.time_s,
            &[
                Series { values: &bc.residual, color: "#9e9e9e", label: "before" },
                Series { values: &c.residual(), color: "#c0392b", label: "after" },
            ],
            &[],
            200.0,
        ));
    }
}

fn history_section(o: &mut String, h: &HistoryView) {
    let _ = write!(
        o,
        "<h2 id=\"history\">History</h2><p class=\"note\">{}: NRMSE % per iteration.</p>",
        esc(&h.path)
    );
    o.push_str("<table><tr><th>#</th><th>time (UTC)</th>");
    for c in &h.channels {
        let _ = write!(o, "<th>{}</th>", esc(c));
    }
    o.push_str("<th>effects</th></tr>");
    for (i, row) in h.rows.iter().enumerate() {
        let _ = write!(o, "<tr><td class=n>{}</td><td>{}</td>", i + 1, esc(&row.timestamp));
        for v in &row.nrmse {
            let _ = write!(o, "<td class=n>{}</td>", v.map_or("-".into(), |v| num(100.0 * v)));
        }
        let _ = write!(o, "<td>{}</td></tr>", esc(&row.effects));
    }
    o.push_str("</table>");
    let series: Vec<(String, Vec<Option<f64>>)> = h
        .channels
        .iter()
        .enumerate()
        .map(|(k, c)| {
            (c.clone(), h.rows.iter().map(|r| r.nrmse.get(k).copied().flatten().map(|v| 100.0 * v)).collect())
        })
        .collect();
    o.push_str(&history_chart("NRMSE per iteration", "NRMSE [%]", &series));
}

/// The start of a self-contained report page (`simrod compare --report`, `simrod
/// check --html`): doctype, title and the shared style, up to the open `<body>`.
pub fn page_start(title: &str) -> String {
    format!(
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>{CSS}</style></head><body>",
        esc(title)
    )
}

/// The report page.
pub fn render(r: &CompareResult) -> String {
    render_with(r, &Extras::default())
}

/// The report page with the before/after and history sections.
pub fn render_with(r: &CompareResult, x: &Extras) -> String {
    let s = &r.setup;
    let mut o = String::with_capacity(1 << 20);
    o.push_str(&page_start(&format!("simrod compare: {}", s.source)));
    let _ = write!(
        o,
        "<h1>Measurement vs twin</h1><p>{}<br>{} samples, {:.3} s, model step {} µs; inputs: {}; supply {} V; effects {}.</p>",
        esc(&s.source),
        s.samples,
        s.duration_s,
        s.dt_us,
        esc(&s.inputs),
        s.supply_v,
        if s.effects_on { "on" } else { "off" }
    );
    for n in &r.notes {
        let _ = write!(o, "<p class=\"note\">{}</p>", esc(n));
    }
    let _ = write!(
        o,
        "<p class=\"note\">Residual = sim − meas. NRMSE = RMSE / (max − min of the measurement, at least 1 % of its RMS). Fit = 100 (1 − ‖e‖/‖y − ȳ‖). r² = 1 − Σe²/Σ(y − ȳ)².</p>"
    );
    let worst = r.worst_channel().map(|c| c.name.clone());
    o.push_str("<table><tr><th>channel</th><th>unit</th><th>RMSE</th><th>NRMSE %</th><th>fit %</th><th>r²</th><th>bias</th><th>max |e|</th><th>at [s]</th><th>residual</th><th>largest error share</th></tr>");
    for c in &r.channels {
        let m = &c.metrics;
        let is_worst =
            worst.as_deref() == Some(c.name.as_str()) && c.whiteness.verdict != Verdict::Negligible;
        let top = match (c.whiteness.verdict, c.top_regions.first()) {
            (Verdict::Negligible, _) | (_, None) => "-".to_string(),
            (_, Some(t)) => {
                format!("{} in {} ({} of samples)", pct(t.error_share), esc(&t.region), pct(t.sample_share))
            }
        };
        let _ = write!(
            o,
            "<tr{}><td><a href=\"#{}\">{}</a></td><td>{}</td><td class=n>{}</td><td class=n>{}</td><td class=n>{}</td><td class=n>{}</td><td class=n>{}</td><td class=n>{}</td><td class=n>{:.3}</td><td>{}</td><td>{}</td></tr>",
            if is_worst { " class=\"worst\"" } else { "" },
            channel_id(&c.name),
            esc(&c.name),
            esc(&c.unit),
            num(m.rmse),
            num(100.0 * m.nrmse),
            m.fit_percent.map_or("-".into(), |v| format!("{v:.1}")),
            m.r2.map_or("-".into(), |v| format!("{v:.4}")),
            num(m.bias),
            num(m.max_abs_error),
            m.max_error_time_s,
            c.whiteness.verdict.describe(),
            top
        );
    }
    o.push_str("</table>");
    o.push_str(&line_chart(
        "Set points the twin ran on",
        "%",
        &r.time_s,
        &[
            Series { values: &r.inputs[0], color: "#2c3e50", label: "throttle" },
            Series { values: &r.inputs[1], color: "#27ae60", label: "load L" },
            Series { values: &r.inputs[2], color: "#8e44ad", label: "load R" },
        ],
        &[],
        220.0,
    ));
    if let Some(b) = &x.baseline {
        baseline_section(&mut o, r, b);
    }
    if let Some(h) = x.history.as_ref().filter(|h| !h.rows.is_empty()) {
        history_section(&mut o, h);
    }
    for c in &r.channels {
        channel_section(&mut o, c, &r.time_s, worst.as_deref() == Some(c.name.as_str()));
    }
    o.push_str("</body></html>\n");
    o
}

/// Write `dir/index.html` atomically, creating `dir` if needed; returns the file.
pub fn write_report(dir: &Path, r: &CompareResult) -> io::Result<PathBuf> {
    write_report_with(dir, r, &Extras::default())
}

/// [`write_report`] with the before/after and history sections.
pub fn write_report_with(dir: &Path, r: &CompareResult, x: &Extras) -> io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let path = dir.join("index.html");
    let page = render_with(r, x);
    write_atomic(&path, |w| w.write_all(page.as_bytes()))?;
    Ok(path)
}
