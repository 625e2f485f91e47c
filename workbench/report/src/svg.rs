//! The workbench's one plotter: hand-written SVG charts for the compare report (time
//! traces, error budget, history) and the identification reports (x-y points with
//! error bars and fitted curves). No plotting or font library, `<text>` for labels, so
//! the HTML report stays one self-contained file that any browser renders.
//!
//! Long runs are drawn as a per-pixel-column min/max envelope: 70,000 samples become
//! ~2 points per pixel and a one-sample spike still shows.

use std::fmt::Write;

/// Chart size in px and the plot area's margins.
const W: f64 = 900.0;
const ML: f64 = 70.0;
const MR: f64 = 15.0;
const MT: f64 = 24.0;
const MB: f64 = 34.0;

/// One line of a line chart.
pub struct Series<'a> {
    pub values: &'a [f64],
    pub color: &'a str,
    pub label: &'a str,
}

/// Escape text for SVG/HTML.
pub fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            _ => o.push(c),
        }
    }
    o
}

/// A short number for an axis label.
fn tick_label(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        format!("{v:.1e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 1.0 {
        let s = format!("{v:.2}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// About `n` round tick values covering `[lo, hi]`.
fn ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0) {
        return vec![lo];
    }
    let raw = span / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() * step;
    let mut v = Vec::new();
    let mut t = first;
    while t <= hi + 1e-9 * step && v.len() < 50 {
        v.push(if t.abs() < 1e-12 * step { 0.0 } else { t });
        t += step;
    }
    v
}

/// Finite min and max of `vals`, padded by 5 %; a flat or empty range is widened.
fn padded_range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = vals
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    if hi - lo <= 1e-12 * (lo.abs() + hi.abs()).max(1e-12) {
        let pad = (lo.abs() * 0.01).max(1e-6);
        return (lo - pad, hi + pad);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// The y range of a line chart's series.
fn y_range(series: &[Series<'_>]) -> (f64, f64) {
    padded_range(series.iter().flat_map(|s| s.values.iter().copied()))
}

/// Min/max envelope of `y` over `cols` pixel columns, as a polyline point list.
fn envelope(
    t: &[f64],
    y: &[f64],
    x_of: &dyn Fn(f64) -> f64,
    y_of: &dyn Fn(f64) -> f64,
    cols: usize,
) -> String {
    let n = t.len().min(y.len());
    let mut pts = String::new();
    if n == 0 {
        return pts;
    }
    let per = n.div_ceil(cols.max(1)).max(1);
    let mut k = 0;
    while k < n {
        let end = (k + per).min(n);
        let (mut lo, mut hi, mut ilo, mut ihi) = (f64::INFINITY, f64::NEG_INFINITY, k, k);
        for (i, &v) in y.iter().enumerate().take(end).skip(k) {
            if v.is_finite() {
                if v < lo {
                    lo = v;
                    ilo = i;
                }
                if v > hi {
                    hi = v;
                    ihi = i;
                }
            }
        }
        if lo.is_finite() {
            // Keep the time order of the two extremes.
            let (a, b) = if ilo <= ihi { (ilo, ihi) } else { (ihi, ilo) };
            for i in [a, b] {
                let _ = write!(pts, "{:.1},{:.1} ", x_of(t[i]), y_of(y[i]));
                if a == b {
                    break;
                }
            }
        }
        k = end;
    }
    pts
}

/// A time chart of one or more series with shaded time spans (`[start, end]` s).
pub fn line_chart(
    title: &str,
    unit: &str,
    t: &[f64],
    series: &[Series<'_>],
    shade: &[(f64, f64)],
    height: f64,
) -> String {
    let h = height;
    let (t0, t1) = match (t.first(), t.last()) {
        (Some(a), Some(b)) if b > a => (*a, *b),
        (Some(a), _) => (*a, a + 1.0),
        _ => (0.0, 1.0),
    };
    let (lo, hi) = y_range(series);
    let pw = W - ML - MR;
    let ph = h - MT - MB;
    let x_of = |x: f64| ML + (x - t0) / (t1 - t0) * pw;
    let y_of = |y: f64| MT + (hi - y) / (hi - lo) * ph;
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W} {h}" width="{W}" height="{h}" role="img" aria-label="{}">"#,
        esc(title)
    );
    let _ = write!(s, r##"<rect x="{ML}" y="{MT}" width="{pw}" height="{ph}" fill="#fff" stroke="#999"/>"##);
    for (a, b) in shade {
        let (xa, xb) = (x_of(a.max(t0)), x_of(b.min(t1)));
        if xb > xa {
            let _ = write!(
                s,
                r##"<rect x="{xa:.1}" y="{MT}" width="{:.1}" height="{ph}" fill="#f6c343" fill-opacity="0.35"/>"##,
                xb - xa
            );
        }
    }
    for v in ticks(lo, hi, 5) {
        let y = y_of(v);
        let _ = write!(
            s,
            r##"<line x1="{ML}" x2="{:.1}" y1="{y:.1}" y2="{y:.1}" stroke="#e3e3e3"/><text x="{:.1}" y="{:.1}" text-anchor="end" font-size="11">{}</text>"##,
            ML + pw,
            ML - 4.0,
            y + 4.0,
            tick_label(v)
        );
    }
    for v in ticks(t0, t1, 10) {
        let x = x_of(v);
        let _ = write!(
            s,
            r##"<line x1="{x:.1}" x2="{x:.1}" y1="{MT}" y2="{:.1}" stroke="#eee"/><text x="{x:.1}" y="{:.1}" text-anchor="middle" font-size="11">{}</text>"##,
            MT + ph,
            MT + ph + 14.0,
            tick_label(v)
        );
    }
    if lo < 0.0 && hi > 0.0 {
        let y = y_of(0.0);
        let _ = write!(
            s,
            r##"<line x1="{ML}" x2="{:.1}" y1="{y:.1}" y2="{y:.1}" stroke="#888" stroke-dasharray="3,3"/>"##,
            ML + pw
        );
    }
    let cols = pw as usize;
    for se in series {
        let pts = envelope(t, se.values, &x_of, &y_of, cols);
        let _ = write!(
            s,
            r#"<polyline fill="none" stroke="{}" stroke-width="1.2" points="{}"/>"#,
            esc(se.color),
            pts.trim_end()
        );
    }
    let _ = write!(
        s,
        r#"<text x="{ML}" y="15" font-size="13" font-weight="bold">{}</text><text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="11">time [s]</text><text x="14" y="{:.1}" font-size="11" transform="rotate(-90 14 {:.1})" text-anchor="middle">[{}]</text>"#,
        esc(title),
        ML + pw / 2.0,
        h - 4.0,
        MT + ph / 2.0,
        MT + ph / 2.0,
        esc(unit)
    );
    let mut lx = W - MR - 8.0;
    for se in series.iter().rev() {
        let w = 12.0 + 7.0 * se.label.chars().count() as f64;
        lx -= w;
        let _ = write!(
            s,
            r#"<line x1="{lx:.1}" x2="{:.1}" y1="12" y2="12" stroke="{}" stroke-width="3"/><text x="{:.1}" y="16" font-size="11">{}</text>"#,
            lx + 10.0,
            esc(se.color),
            lx + 13.0,
            esc(se.label)
        );
        lx -= 10.0;
    }
    s.push_str("</svg>");
    s
}

/// One bar group of the error-budget chart.
pub struct Bar<'a> {
    pub label: &'a str,
    /// Share of the squared error, 0..1.
    pub error: f64,
    /// Share of the samples, 0..1.
    pub samples: f64,
}

/// Horizontal bars: error share (solid) against sample share (thin) per region.
pub fn budget_chart(title: &str, bars: &[Bar<'_>]) -> String {
    let label_w = 300.0;
    let row = 26.0;
    let h = MT + 12.0 + row * bars.len() as f64 + 20.0;
    let pw = W - label_w - MR - 60.0;
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W} {h}" width="{W}" height="{h}" role="img" aria-label="{}">"#,
        esc(title)
    );
    let _ = write!(
        s,
        r##"<text x="4" y="15" font-size="13" font-weight="bold">{}</text><rect x="{:.1}" y="6" width="12" height="8" fill="#c0392b"/><text x="{:.1}" y="14" font-size="11">share of squared error</text><rect x="{:.1}" y="9" width="12" height="3" fill="#555"/><text x="{:.1}" y="14" font-size="11">share of samples</text>"##,
        esc(title),
        W - 330.0,
        W - 314.0,
        W - 160.0,
        W - 144.0
    );
    for (i, b) in bars.iter().enumerate() {
        let y = MT + 12.0 + row * i as f64;
        let we = (b.error.clamp(0.0, 1.0)) * pw;
        let ws = (b.samples.clamp(0.0, 1.0)) * pw;
        let _ = write!(
            s,
            r##"<text x="{:.1}" y="{:.1}" text-anchor="end" font-size="11">{}</text><rect x="{label_w}" y="{:.1}" width="{pw:.1}" height="14" fill="#f2f2f2"/><rect x="{label_w}" y="{:.1}" width="{we:.1}" height="14" fill="#c0392b"/><rect x="{label_w}" y="{:.1}" width="{ws:.1}" height="4" fill="#555"/><text x="{:.1}" y="{:.1}" font-size="11">{:.0} % / {:.0} %</text>"##,
            label_w - 6.0,
            y + 11.0,
            esc(b.label),
            y,
            y,
            y + 16.0,
            label_w + pw + 6.0,
            y + 11.0,
            100.0 * b.error,
            100.0 * b.samples
        );
    }
    s.push_str("</svg>");
    s
}

/// Line colours for charts with many series (colour-blind-safe order first).
pub const PALETTE: [&str; 10] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
    "#17becf",
];

/// Error per iteration of the improve-the-model loop: one line with markers per series
/// (`label`, value per iteration, `None` where not recorded), x = iteration 1..n, y on a
/// log axis because a good effect cuts an error by factors, not by fixed amounts.
pub fn history_chart(title: &str, y_label: &str, series: &[(String, Vec<Option<f64>>)]) -> String {
    let n = series.iter().map(|(_, v)| v.len()).max().unwrap_or(0).max(1);
    let legend_w = 170.0;
    let h = 300.0;
    let pw = W - ML - MR - legend_w;
    let ph = h - MT - MB;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in series.iter().flat_map(|(_, v)| v.iter().flatten()).filter(|v| v.is_finite() && **v > 0.0) {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    if !lo.is_finite() {
        (lo, hi) = (0.1, 1.0);
    }
    let (llo, mut lhi) = (lo.log10().floor(), hi.log10().ceil());
    if lhi <= llo {
        lhi = llo + 1.0;
    }
    let x_of = |i: usize| if n == 1 { ML + pw / 2.0 } else { ML + i as f64 / (n - 1) as f64 * pw };
    let y_of = |v: f64| MT + (lhi - v.log10()) / (lhi - llo) * ph;
    let mut s = String::new();
    let _ = write!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W} {h}" width="{W}" height="{h}" role="img" aria-label="{}"><rect x="{ML}" y="{MT}" width="{pw}" height="{ph}" fill="#fff" stroke="#999"/>"##,
        esc(title)
    );
    // Decades, and 2 and 5 within them when the range is short.
    let mults: &[f64] = if lhi - llo <= 2.0 { &[1.0, 2.0, 5.0] } else { &[1.0] };
    let mut e = llo;
    while e <= lhi {
        for m in mults {
            let v = m * 10f64.powf(e);
            if v.log10() > lhi + 1e-9 {
                continue;
            }
            let y = y_of(v);
            let _ = write!(
                s,
                r##"<line x1="{ML}" x2="{:.1}" y1="{y:.1}" y2="{y:.1}" stroke="{}"/><text x="{:.1}" y="{:.1}" text-anchor="end" font-size="11">{}</text>"##,
                ML + pw,
                if *m == 1.0 { "#d0d0d0" } else { "#eeeeee" },
                ML - 4.0,
                y + 4.0,
                tick_label(v)
            );
        }
        e += 1.0;
    }
    let every = n.div_ceil(20).max(1);
    for i in (0..n).step_by(every) {
        let x = x_of(i);
        let _ = write!(
            s,
            r##"<line x1="{x:.1}" x2="{x:.1}" y1="{MT}" y2="{:.1}" stroke="#eee"/><text x="{x:.1}" y="{:.1}" text-anchor="middle" font-size="11">{}</text>"##,
            MT + ph,
            MT + ph + 14.0,
            i + 1
        );
    }
    for (k, (label, v)) in series.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        let pts: Vec<(f64, f64)> = v
            .iter()
            .enumerate()
            .filter_map(|(i, y)| y.filter(|y| y.is_finite() && *y > 0.0).map(|y| (x_of(i), y_of(y))))
            .collect();
        let line: Vec<String> = pts.iter().map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
        let _ = write!(
            s,
            r#"<polyline fill="none" stroke="{color}" stroke-width="1.5" points="{}"/>"#,
            line.join(" ")
        );
        for (x, y) in &pts {
            let _ = write!(s, r#"<circle cx="{x:.1}" cy="{y:.1}" r="3" fill="{color}"/>"#);
        }
        let ly = MT + 8.0 + 16.0 * k as f64;
        let lx = ML + pw + 12.0;
        let _ = write!(
            s,
            r#"<line x1="{lx:.1}" x2="{:.1}" y1="{ly:.1}" y2="{ly:.1}" stroke="{color}" stroke-width="3"/><text x="{:.1}" y="{:.1}" font-size="11">{}</text>"#,
            lx + 14.0,
            lx + 18.0,
            ly + 4.0,
            esc(label)
        );
    }
    let _ = write!(
        s,
        r#"<text x="{ML}" y="15" font-size="13" font-weight="bold">{}</text><text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="11">iteration</text><text x="14" y="{:.1}" font-size="11" transform="rotate(-90 14 {:.1})" text-anchor="middle">{} (log)</text></svg>"#,
        esc(title),
        ML + pw / 2.0,
        h - 4.0,
        MT + ph / 2.0,
        MT + ph / 2.0,
        esc(y_label)
    );
    s
}

/// Points with optional error bars, for [`xy_chart`].
pub struct XyPoints<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
    /// Half-length of the error bar per point (e.g. 2 standard errors).
    pub err: Option<&'a [f64]>,
    pub color: &'a str,
    pub label: &'a str,
}

/// A polyline, for [`xy_chart`].
pub struct XyLine<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub color: &'a str,
    pub label: &'a str,
    pub dashed: bool,
}

/// An x-y chart of measured points (with error bars) and curves (fits, model maps).
pub fn xy_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[XyPoints<'_>],
    lines: &[XyLine<'_>],
) -> String {
    const W: f64 = 820.0;
    const H: f64 = 440.0;
    const MR: f64 = 20.0;
    const MT: f64 = 44.0;
    const MB: f64 = 42.0;
    let err = |p: &XyPoints<'_>, i: usize| p.err.and_then(|e| e.get(i)).copied().unwrap_or(0.0);
    let xs =
        points.iter().flat_map(|p| p.x.iter().copied()).chain(lines.iter().flat_map(|l| l.x.iter().copied()));
    let (x0, x1) = padded_range(xs);
    let ys = points
        .iter()
        .flat_map(|p| p.y.iter().enumerate().flat_map(move |(i, y)| [y + err(p, i), y - err(p, i)]))
        .chain(lines.iter().flat_map(|l| l.y.iter().copied()));
    let (y0, y1) = padded_range(ys);
    let (pw, ph) = (W - ML - MR, H - MT - MB);
    let xp = |x: f64| ML + (x - x0) / (x1 - x0) * pw;
    let yp = |y: f64| MT + (y1 - y) / (y1 - y0) * ph;
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W} {H}" width="{W}" height="{H}" role="img" aria-label="{}">"#,
        esc(title)
    );
    let _ = write!(s, r##"<rect x="{ML}" y="{MT}" width="{pw}" height="{ph}" fill="#fff" stroke="#999"/>"##);
    for v in ticks(y0, y1, 6) {
        let y = yp(v);
        let _ = write!(
            s,
            r##"<line x1="{ML}" x2="{:.1}" y1="{y:.1}" y2="{y:.1}" stroke="#eee"/><text x="{:.1}" y="{:.1}" text-anchor="end" font-size="11">{}</text>"##,
            ML + pw,
            ML - 4.0,
            y + 4.0,
            tick_label(v)
        );
    }
    for v in ticks(x0, x1, 6) {
        let x = xp(v);
        let _ = write!(
            s,
            r##"<line x1="{x:.1}" x2="{x:.1}" y1="{MT}" y2="{:.1}" stroke="#eee"/><text x="{x:.1}" y="{:.1}" text-anchor="middle" font-size="11">{}</text>"##,
            MT + ph,
            MT + ph + 14.0,
            tick_label(v)
        );
    }
    for l in lines {
        let pts: Vec<String> =
            l.x.iter()
                .zip(l.y)
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .map(|(x, y)| format!("{:.1},{:.1}", xp(*x), yp(*y)))
                .collect();
        let dash = if l.dashed { r#" stroke-dasharray="5,4""# } else { "" };
        let _ = write!(
            s,
            r#"<polyline fill="none" stroke="{}" stroke-width="1.6"{dash} points="{}"/>"#,
            esc(l.color),
            pts.join(" ")
        );
    }
    for p in points {
        for (i, (x, y)) in p.x.iter().zip(p.y).enumerate() {
            if !(x.is_finite() && y.is_finite()) {
                continue;
            }
            let e = err(p, i);
            if e.is_finite() && e > 0.0 {
                let _ = write!(
                    s,
                    r#"<line x1="{0:.1}" x2="{0:.1}" y1="{1:.1}" y2="{2:.1}" stroke="{3}"/>"#,
                    xp(*x),
                    yp(y + e),
                    yp(y - e),
                    esc(p.color)
                );
            }
            let _ = write!(
                s,
                r#"<circle cx="{:.1}" cy="{:.1}" r="2.6" fill="{}"/>"#,
                xp(*x),
                yp(*y),
                esc(p.color)
            );
        }
    }
    let _ = write!(
        s,
        r#"<text x="{ML}" y="16" font-size="13" font-weight="bold">{}</text><text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="11">{}</text><text x="14" y="{:.1}" font-size="11" transform="rotate(-90 14 {:.1})" text-anchor="middle">{}</text>"#,
        esc(title),
        ML + pw / 2.0,
        H - 6.0,
        esc(x_label),
        MT + ph / 2.0,
        MT + ph / 2.0,
        esc(y_label)
    );
    let mut lx = ML;
    let legend = points
        .iter()
        .map(|p| (p.label, p.color, true))
        .chain(lines.iter().map(|l| (l.label, l.color, false)));
    for (label, color, dot) in legend.filter(|l| !l.0.is_empty()) {
        let mark = if dot {
            format!(r#"<circle cx="{:.1}" cy="31" r="3" fill="{}"/>"#, lx + 5.0, esc(color))
        } else {
            format!(
                r#"<line x1="{lx:.1}" x2="{:.1}" y1="31" y2="31" stroke="{}" stroke-width="2"/>"#,
                lx + 12.0,
                esc(color)
            )
        };
        let _ = write!(s, r#"{mark}<text x="{:.1}" y="35" font-size="11">{}</text>"#, lx + 16.0, esc(label));
        lx += 28.0 + 6.5 * label.chars().count() as f64;
    }
    s.push_str("</svg>");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        let t = ticks(0.0, 70.0, 10);
        assert_eq!(t.first(), Some(&0.0));
        assert_eq!(t.last(), Some(&70.0));
        assert!(t.windows(2).all(|w| (w[1] - w[0] - 10.0).abs() < 1e-9));
        let t = ticks(-1.3, 2.6, 5);
        assert!(t.iter().all(|v| (v * 2.0).fract().abs() < 1e-9));
        assert_eq!(ticks(5.0, 5.0, 5), vec![5.0]);
    }

    #[test]
    fn envelope_keeps_spikes_and_bounds_point_count() {
        let n = 70_000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let mut y = vec![0.0; n];
        y[31_234] = 100.0;
        let pts = envelope(&t, &y, &|x| x, &|v| v, 800);
        assert!(pts.split(' ').filter(|p| !p.is_empty()).count() <= 2 * 800 + 2);
        assert!(pts.contains(",100.0"));
    }

    #[test]
    fn charts_are_well_formed_with_odd_data() {
        let t = [0.0, 1.0, 2.0];
        let y = [f64::NAN, f64::NAN, f64::NAN];
        let c = line_chart(
            "a<b",
            "N m",
            &t,
            &[Series { values: &y, color: "#000", label: "x" }],
            &[(0.5, 1.5)],
            200.0,
        );
        assert!(c.starts_with("<svg") && c.ends_with("</svg>"));
        assert!(c.contains("a&lt;b") && !c.contains("NaN"));
        let b = budget_chart("t", &[Bar { label: "forward / steady", error: 0.7, samples: 0.2 }]);
        assert!(b.contains("70 % / 20 %"));
    }

    #[test]
    fn xy_chart_draws_points_error_bars_and_lines() {
        let svg = xy_chart(
            "a<b",
            "x",
            "y",
            &[XyPoints {
                x: &[1.0, 2.0, 3.0],
                y: &[3.0, f64::NAN, 2.0],
                err: Some(&[0.5, 0.5, f64::NAN]),
                color: "#000",
                label: "p",
            }],
            &[XyLine { x: &[0.0, 3.0], y: &[0.0, 4.0], color: "#f00", label: "fit", dashed: true }],
        );
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>") && svg.contains("a&lt;b"));
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        // Two finite points, one error bar, one dashed line, and the legend's dot.
        assert_eq!(svg.matches("<circle").count(), 3);
        assert_eq!(svg.matches(r##"stroke="#000"/>"##).count(), 1);
        assert!(svg.contains("stroke-dasharray") && svg.contains(">fit<"));
        // Nothing to draw: still well formed.
        let e = xy_chart("t", "x", "y", &[], &[]);
        assert!(e.ends_with("</svg>") && !e.contains("NaN"));
        assert_eq!(ticks(0.0, 10.0, 6).len(), 6);
        assert_eq!(
            (tick_label(-100.0), tick_label(2.5), tick_label(0.0)),
            ("-100".into(), "2.5".into(), "0".into())
        );
    }

    #[test]
    fn history_chart_draws_every_point_on_a_log_axis() {
        let series = vec![
            ("I_DC".to_string(), vec![Some(1.4), Some(0.3), Some(0.29)]),
            ("C_Kistler_L".to_string(), vec![Some(1.1), None, Some(f64::NAN)]),
        ];
        let c = history_chart("NRMSE per iteration", "NRMSE [%]", &series);
        assert!(c.starts_with("<svg") && c.ends_with("</svg>"));
        assert_eq!(c.matches("<circle").count(), 4);
        assert!(c.contains(">I_DC<") && c.contains(">0.1<") && c.contains(">1<") && c.contains(">2<"));
        assert!(!c.contains("NaN") && !c.contains("inf"));
        // One iteration, no values: still well formed.
        let c = history_chart("t", "y", &[("a".to_string(), vec![None])]);
        assert!(c.ends_with("</svg>") && !c.contains("NaN"));
    }
}
