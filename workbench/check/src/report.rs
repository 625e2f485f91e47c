//! A check's result for people and for scripts: the terminal table, JSON, and a
//! self-contained HTML page with every limit's margin over time (the workbench's page
//! frame and its one SVG plotter).

use std::fmt::Write as _;

use serde_json::{json, Value};
use simrod_report::html::page_start;
use simrod_report::svg::{esc, line_chart, Series};
use simrod_report::table::columns;
use simrod_report::{num, pct};

use crate::delay::DelayMargin;
use crate::limits::{Limit, Rule};
use crate::monitor::{AT_LIMIT, BINS};
use crate::run::Knob;
use crate::setpoint::SetPoint;
use crate::{samples_needed, CheckReport, LimitReport, Verdict};

/// `-6.0 %` of the limit's size.
fn margin_pct(l: &LimitReport, m: f64) -> String {
    format!("{:.1} %", 100.0 * m / l.limit.size())
}

/// The verdict, with the time beyond a bound that allows some.
pub fn verdict_text(l: &LimitReport) -> String {
    let n = &l.nominal;
    match l.limit.rule {
        Rule::Bound { for_s, .. } if for_s > 0.0 && n.longest_beyond_s > 0.0 => {
            format!("{} (beyond {:.2} s at most; {for_s} s allowed)", l.verdict.word(), n.longest_beyond_s)
        }
        _ => l.verdict.word().into(),
    }
}

/// `P [lo, hi]` with the counts.
fn probability(l: &LimitReport) -> String {
    l.mc.as_ref().map_or("-".into(), |m| {
        format!(
            "{} ({}/{}) [{}, {}]",
            num(m.p),
            m.violations,
            m.samples,
            num(m.interval.0),
            num(m.interval.1)
        )
    })
}

/// The worst sample's peak, margin and time.
fn worst_case(l: &LimitReport) -> String {
    l.mc.as_ref().map_or("-".into(), |m| {
        format!(
            "{} {} (margin {}) at {:.3} s, sample {}",
            num(m.worst.peak),
            l.limit.unit,
            num(m.worst.margin),
            m.worst.t_s,
            m.worst_sample
        )
    })
}

/// What keeps a limit inside, in words.
pub fn set_point_text(l: &LimitReport, requested: (f32, f32)) -> String {
    l.set_points.map_or("-".into(), |sp| set_points_text(sp, requested))
}

/// A set point per knob, in words.
pub fn set_points_text(sp: [SetPoint; 2], requested: (f32, f32)) -> String {
    let parts: Vec<String> = Knob::BOTH
        .iter()
        .zip(sp)
        .filter_map(|(k, s)| {
            let other = match k {
                Knob::Throttle => format!("load x{}", requested.1),
                Knob::Load => format!("throttle x{}", requested.0),
            };
            match s {
                SetPoint::Scale { scale, .. } => Some(format!("{} scale ≤ {:.3} ({other})", k.name(), scale)),
                SetPoint::AtRequested => {
                    Some(format!("{} scale as requested (more samples, not a lower scale)", k.name()))
                }
                SetPoint::Unreachable => Some(format!("no {} scale (crossed even at 0)", k.name())),
                SetPoint::Off => None,
            }
        })
        .collect();
    if parts.is_empty() {
        "-".into()
    } else {
        parts.join("; or ")
    }
}

/// The terminal report.
pub fn render(r: &CheckReport) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "simrod check: {}", r.title);
    let _ = writeln!(
        o,
        "  {:.3} s at {} µs; limits: {}; torque-flange mode {:.0} Hz (resolved: {} samples a period)",
        r.duration_s,
        r.dt_us,
        r.limits_source,
        r.flange_hz,
        num(1e6 / (r.flange_hz * f64::from(r.dt_us)))
    );
    match &r.mc {
        Some(m) => {
            let _ = writeln!(
                o,
                "  Monte Carlo: {} samples, seed {}, {} thread(s), from {}: {}",
                m.samples,
                m.seed,
                r.threads,
                m.source,
                m.items.join("; ")
            );
            for n in &m.notes {
                let _ = writeln!(o, "  note: {n}");
            }
            let _ = writeln!(
                o,
                "  safe = violation probability ≤ {} shown at {} confidence (Clopper–Pearson interval's upper end); likely crossed = estimate above it",
                pct(1.0 - r.confidence),
                pct(r.confidence)
            );
        }
        None => {
            let _ = writeln!(o, "  nominal model only (give --uncertainty, --from-identify or --from-diagnose for a Monte Carlo)");
        }
    }
    o.push('\n');
    o.push_str(&table(r));
    if let Some(d) = &r.delay {
        let _ = writeln!(o, "\n{}", d.text());
    }
    let failing: Vec<&LimitReport> = r.failing().collect();
    if let (Some(why), false) = (&r.no_set_points, failing.is_empty()) {
        let _ = writeln!(o, "\nSet points: not searched, {why}.");
    } else if !failing.is_empty() {
        let _ = writeln!(
            o,
            "\nSet points that keep them inside (nominal model; the Monte Carlo's spread allowed for):"
        );
        if let (Some(all), true) = (r.set_point_all, failing.len() > 1) {
            let _ =
                writeln!(o, "  all of them: {}", set_points_text(all, (r.scales.throttle, r.scales.load)));
        }
        for l in &failing {
            let _ =
                writeln!(o, "  {}: {}", l.limit.id, set_point_text(l, (r.scales.throttle, r.scales.load)));
            if l.verdict == Verdict::Undecided {
                let _ = writeln!(
                    o,
                    "    undecided: no violation seen is not yet proof at this confidence; {} samples without a violation would be",
                    samples_needed(r.confidence)
                );
            }
        }
    }
    o.push('\n');
    let _ = writeln!(o, "{}", verdict_line(r));
    let t = &r.timing;
    let _ = writeln!(
        o,
        "check took {:.2} s (nominal {:.2} s, Monte Carlo {:.2} s, set points {:.2} s)",
        t.nominal_s + t.monte_carlo_s + t.set_points_s,
        t.nominal_s,
        t.monte_carlo_s,
        t.set_points_s
    );
    o
}

/// The table of every limit: rule, peak, margin, when, where, verdict (and the Monte
/// Carlo's columns when there is one).
pub fn table(r: &CheckReport) -> String {
    let mut rows = vec![vec![
        "limit".to_string(),
        "rule".into(),
        "peak".into(),
        "margin".into(),
        "margin %".into(),
        "at [s]".into(),
        "where".into(),
        "verdict".into(),
    ]];
    if r.mc.is_some() {
        rows[0].push(format!("P(violation) [{} interval]", pct(r.confidence)));
        rows[0].push("worst case seen".into());
    }
    for l in &r.limits {
        let n = &l.nominal;
        let mut row = vec![
            l.limit.id.clone(),
            l.limit.describe(),
            format!("{} {}", num(n.peak), l.limit.unit),
            num(n.margin),
            margin_pct(l, n.margin),
            format!("{:.3}", n.t_s),
            l.phase.clone(),
            verdict_text(l),
        ];
        if r.mc.is_some() {
            row.push(probability(l));
            row.push(worst_case(l));
        }
        rows.push(row);
    }
    columns(&rows, &[0, 1, 2, 6, 7, 8, 9])
}

/// `APPROVED: ...` or `NOT APPROVED: ...`, one line.
pub fn verdict_line(r: &CheckReport) -> String {
    let failing: Vec<String> = r
        .failing()
        .map(|l| {
            format!(
                "{} {} ({} {} at {:.3} s, {})",
                l.limit.id,
                l.verdict.word().to_lowercase(),
                num(l.nominal.peak),
                l.limit.unit,
                l.nominal.t_s,
                l.phase
            )
        })
        .collect();
    let delay = r.delay.as_ref().filter(|d| !d.passes()).map(|d| d.text());
    let failing: Vec<String> = failing.into_iter().chain(delay).collect();
    if failing.is_empty() {
        let delay = r.delay.as_ref().map_or(String::new(), |d| format!("; {}", d.text()));
        format!("APPROVED: all {} limits inside{delay}", r.limits.len())
    } else {
        format!("NOT APPROVED: {}", failing.join("; "))
    }
}

fn rule_json(l: &Limit) -> Value {
    match l.rule {
        Rule::Bound { min, max, for_s } => json!({"min": min, "max": max, "for_s": for_s}),
        Rule::Thermal { rated, tau_s, initial } => {
            json!({"thermal": {"rated": rated, "tau_s": tau_s, "initial": initial}})
        }
    }
}

fn set_point_json(s: SetPoint) -> Value {
    match s {
        SetPoint::Scale { scale, fraction } => json!({"scale": scale, "fraction_of_requested": fraction}),
        SetPoint::AtRequested => json!("at_requested"),
        SetPoint::Unreachable => json!("unreachable"),
        SetPoint::Off => json!("off"),
    }
}

/// `{"test", "limits_file", "dt_us", "duration_s", "scales", "flange_mode_hz",
/// "confidence", "monte_carlo": {...} | null, "limits": [{"id", "name", "quantity",
/// "unit", "rule", "origin", "assumed", "nominal": {...}, "monte_carlo": {...} | null,
/// "verdict", "set_points": {"throttle", "load"} | null}], "set_point_all",
/// "set_points_not_applicable", "delay_margin": {...} | null, "approved", "exit_code",
/// "threads", "timing_s"}`. Non-finite numbers are `null`.
pub fn to_json(r: &CheckReport) -> Value {
    let limits: Vec<Value> = r
        .limits
        .iter()
        .map(|l| {
            let n = &l.nominal;
            json!({
                "id": l.limit.id,
                "name": l.limit.name,
                "quantity": l.limit.quantity.name(),
                "unit": l.limit.unit,
                "rule": rule_json(&l.limit),
                "origin": l.limit.origin,
                "assumed": l.limit.assumed,
                "nominal": {
                    "peak": n.peak,
                    "margin": n.margin,
                    "margin_pct": 100.0 * n.margin / l.limit.size(),
                    "t_s": n.t_s,
                    "phase": l.phase,
                    "crossed": n.crossed,
                    "first_beyond_s": n.first_beyond_s,
                    "longest_beyond_s": n.longest_beyond_s,
                },
                "monte_carlo": l.mc.as_ref().map(|m| json!({
                    "violations": m.violations,
                    "samples": m.samples,
                    "p": m.p,
                    "interval": [m.interval.0, m.interval.1],
                    "worst": {
                        "sample": m.worst_sample,
                        "peak": m.worst.peak,
                        "margin": m.worst.margin,
                        "t_s": m.worst.t_s,
                        "phase": m.worst_phase,
                        "crossed": m.worst.crossed,
                    },
                    "spread": l.spread,
                })),
                "verdict": l.verdict.key(),
                "set_points": l.set_points.map(|s| json!({"throttle": set_point_json(s[0]), "load": set_point_json(s[1])})),
            })
        })
        .collect();
    json!({
        "test": r.title,
        "limits_file": r.limits_source,
        "dt_us": r.dt_us,
        "duration_s": r.duration_s,
        "scales": {"throttle": r.scales.throttle, "load": r.scales.load},
        "flange_mode_hz": r.flange_hz,
        "confidence": r.confidence,
        "monte_carlo": r.mc.as_ref().map(|m| json!({
            "source": m.source, "samples": m.samples, "seed": m.seed, "distributions": m.items, "notes": m.notes,
        })),
        "limits": limits,
        "set_point_all": r.set_point_all.map(|s| json!({"throttle": set_point_json(s[0]), "load": set_point_json(s[1])})),
        "set_points_not_applicable": r.no_set_points,
        "delay_margin": r.delay.as_ref().map(DelayMargin::to_json),
        "approved": r.approved,
        "exit_code": if r.approved { 0 } else { 1 },
        "threads": r.threads,
        "timing_s": {"nominal": r.timing.nominal_s, "monte_carlo": r.timing.monte_carlo_s, "set_points": r.timing.set_points_s},
    })
}

/// The chart title of a limit's margin (what the page's test looks for).
pub fn chart_title(l: &Limit) -> String {
    format!("{}: margin to {} (beyond it shaded)", l.name, l.describe())
}

/// The HTML page: summary table, then per limit its origin and margin over time.
pub fn html(r: &CheckReport) -> String {
    let mut o = page_start(&format!("simrod check: {}", r.title));
    let _ = write!(
        o,
        "<h1>Will this test stay inside the bench's limits?</h1><p>{}<br>{:.3} s at {} µs; limits from {}; torque-flange mode {:.0} Hz.</p>",
        esc(&r.title),
        r.duration_s,
        r.dt_us,
        esc(&r.limits_source),
        r.flange_hz
    );
    if let Some(m) = &r.mc {
        let _ = write!(
            o,
            "<p class=\"note\">Monte Carlo: {} samples, seed {}, from {}: {}. Safe = violation probability ≤ {} shown at {} confidence.</p>",
            m.samples,
            m.seed,
            esc(&m.source),
            esc(&m.items.join("; ")),
            pct(1.0 - r.confidence),
            pct(r.confidence)
        );
    }
    let _ = write!(o, "<p><b>{}</b></p>", esc(&verdict_line(r)));
    if let Some(all) = r.set_point_all {
        let _ = write!(
            o,
            "<p>Keeps every failing limit inside: {}.</p>",
            esc(&set_points_text(all, (r.scales.throttle, r.scales.load)))
        );
    }
    o.push_str("<table><tr><th>limit</th><th>rule</th><th>peak</th><th>margin</th><th>at [s]</th><th>where</th><th>verdict</th><th>P(violation)</th><th>keeps it inside</th></tr>");
    for l in &r.limits {
        let _ = write!(
            o,
            "<tr{}><td><a href=\"#{}\">{}</a></td><td>{}</td><td class=n>{} {}</td><td class=n>{} ({})</td><td class=n>{:.3}</td><td>{}</td><td>{}</td><td class=n>{}</td><td>{}</td></tr>",
            if l.verdict.passes() { "" } else { " class=\"worst\"" },
            esc(&l.limit.id),
            esc(&l.limit.name),
            esc(&l.limit.describe()),
            num(l.nominal.peak),
            esc(&l.limit.unit),
            num(l.nominal.margin),
            margin_pct(l, l.nominal.margin),
            l.nominal.t_s,
            esc(&l.phase),
            esc(&verdict_text(l)),
            esc(&probability(l)),
            esc(&set_point_text(l, (r.scales.throttle, r.scales.load)))
        );
    }
    o.push_str("</table>");
    let t: Vec<f64> = (0..BINS).map(|b| (b + 1) as f64 / BINS as f64 * r.duration_s).collect();
    for l in &r.limits {
        section(&mut o, l, &t);
    }
    o.push_str("</body></html>\n");
    o
}

/// One limit: origin, result, and its margin over time with the crossed spans shaded.
fn section(o: &mut String, l: &LimitReport, t: &[f64]) {
    let _ = write!(
        o,
        "<h2 id=\"{}\">{}</h2><p>{} on {}: {}. Origin: {}.{}</p><p>Nominal: peak {} {} at {:.3} s ({}), margin {} {} ({}); {}.</p>",
        esc(&l.limit.id),
        esc(&l.limit.name),
        esc(&l.limit.id),
        esc(l.limit.quantity.name()),
        esc(&l.limit.describe()),
        esc(&l.limit.origin),
        l.limit.assumed.as_ref().map_or(String::new(), |a| format!(" <i>Assumed</i>: {}.", esc(a))),
        num(l.nominal.peak),
        esc(&l.limit.unit),
        l.nominal.t_s,
        esc(&l.phase),
        num(l.nominal.margin),
        esc(&l.limit.unit),
        margin_pct(l, l.nominal.margin),
        esc(&verdict_text(l))
    );
    let nominal: Vec<f64> = l.nominal.trace.iter().map(|v| f64::from(*v)).collect();
    let envelope: Vec<f64> =
        l.mc.as_ref().map_or(Vec::new(), |m| m.envelope.iter().map(|v| f64::from(*v)).collect());
    let mut series = vec![Series { values: &nominal, color: "#1f77b4", label: "nominal" }];
    if !envelope.is_empty() {
        series.push(Series { values: &envelope, color: "#c0392b", label: "worst sample" });
    }
    let shade = crossed_spans(t, &nominal, -AT_LIMIT * l.limit.size());
    o.push_str(&line_chart(&chart_title(&l.limit), &l.limit.unit, t, &series, &shade, 220.0));
}

/// Time spans where the margin is below `floor` (beyond the limit).
fn crossed_spans(t: &[f64], m: &[f64], floor: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut start: Option<f64> = None;
    let mut prev = 0.0;
    for (ti, mi) in t.iter().zip(m) {
        match (start, *mi < floor) {
            (None, true) => start = Some(prev),
            (Some(s), false) => {
                out.push((s, *ti));
                start = None;
            }
            _ => {}
        }
        prev = *ti;
    }
    if let Some(s) = start {
        out.push((s, prev));
    }
    out
}
