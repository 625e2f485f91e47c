//! What every identification writes besides its data files: `report.md` (values, fit
//! statistics, per-plateau tables, what was rejected and why) and SVG charts, drawn by
//! hand like `crate::report::svg` so no plotting library is needed.

use std::fmt::Write as _;
use std::io;
use std::path::{Path, PathBuf};

pub use crate::report::num;
use crate::report::svg::esc;

use super::plateau::Extraction;
use super::run::Run;
use crate::atomic::write_atomic;

/// A chart written next to the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Plot {
    /// File name, e.g. `friction_L.svg`.
    pub file: String,
    pub svg: String,
}

/// A Markdown report under construction.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Report {
    pub md: String,
    pub plots: Vec<Plot>,
}

impl Report {
    /// A report titled `title`.
    pub fn new(title: &str) -> Self {
        Self { md: format!("# {title}\n\n"), plots: Vec::new() }
    }

    /// A section heading.
    pub fn h2(&mut self, s: &str) {
        let _ = write!(self.md, "## {s}\n\n");
    }

    /// A paragraph.
    pub fn para(&mut self, s: &str) {
        let _ = write!(self.md, "{s}\n\n");
    }

    /// A bullet list.
    pub fn bullets<S: AsRef<str>>(&mut self, items: &[S]) {
        for i in items {
            let _ = writeln!(self.md, "- {}", i.as_ref());
        }
        self.md.push('\n');
    }

    /// A table.
    pub fn table<S: AsRef<str>>(&mut self, head: &[&str], rows: &[Vec<S>]) {
        let _ = writeln!(self.md, "| {} |", head.join(" | "));
        let _ = writeln!(self.md, "|{}", "---|".repeat(head.len()));
        for r in rows {
            let cells: Vec<String> = r.iter().map(|c| c.as_ref().replace('|', "/")).collect();
            let _ = writeln!(self.md, "| {} |", cells.join(" | "));
        }
        self.md.push('\n');
    }

    /// A chart, linked from the text.
    pub fn plot(&mut self, file: &str, caption: &str, svg: String) {
        let _ = write!(self.md, "![{caption}]({file})\n\n");
        self.plots.push(Plot { file: file.to_string(), svg });
    }

    /// Write `report.md` and the charts into `dir`; returns the paths.
    pub fn write(&self, dir: &Path) -> io::Result<Vec<PathBuf>> {
        let mut out = Vec::new();
        let p = dir.join("report.md");
        write_atomic(&p, |w| w.write_all(self.md.as_bytes()))?;
        out.push(p);
        for pl in &self.plots {
            let p = dir.join(&pl.file);
            write_atomic(&p, |w| w.write_all(pl.svg.as_bytes()))?;
            out.push(p);
        }
        Ok(out)
    }
}

/// `v ± sd` with short numbers.
pub fn pm(v: f64, sd: f64) -> String {
    format!("{} ± {}", num(v), num(sd))
}

/// Set points as `thr/L/R %`.
pub fn sp_str(sp: &[f64; 3]) -> String {
    format!("{}/{}/{}", num(sp[0]), num(sp[1]), num(sp[2]))
}

/// The runs used and those that gave nothing, and every rejected candidate.
pub fn campaign_section(rep: &mut Report, runs: &[Run], ex: &Extraction) {
    rep.h2("Campaign");
    let used: Vec<usize> = {
        let mut v: Vec<usize> = ex.plateaus.iter().map(|p| p.run).collect();
        v.dedup();
        v
    };
    rep.para(&format!(
        "{} run(s), {} with plateaus; {} plateau(s) kept, {} candidate(s) rejected. \
         A plateau is a stretch of constant set points after the response settled \
         (window means within 4 σ of the final level); mean ± rms per channel, rms being \
         the thesis' quality figure.",
        runs.len(),
        used.len(),
        ex.plateaus.len(),
        ex.rejected.len()
    ));
    let name = |i: usize| runs.get(i).map_or("?", |r| r.name.as_str()).to_string();
    if !ex.runs_without.is_empty() {
        rep.para("Runs rejected as a whole:");
        let items: Vec<String> =
            ex.runs_without.iter().map(|(i, why)| format!("`{}`: {why}", name(*i))).collect();
        rep.bullets(&items);
    }
    if !ex.rejected.is_empty() {
        rep.para("Rejected candidates (set points throttle/load L/load R %):");
        let rows: Vec<Vec<String>> = ex
            .rejected
            .iter()
            .map(|r| {
                vec![name(r.run), format!("{:.2}–{:.2}", r.t0, r.t1), sp_str(&r.sp), r.reason.to_string()]
            })
            .collect();
        rep.table(&["run", "t [s]", "set points", "reason"], &rows);
    }
    let warnings: Vec<String> = ex
        .plateaus
        .iter()
        .flat_map(|p| {
            p.warnings.iter().map(move |w| format!("`{}` {:.1}–{:.1} s: {w}", name(p.run), p.t0, p.t1))
        })
        .collect();
    if !warnings.is_empty() {
        rep.para("Warnings on kept plateaus:");
        rep.bullets(&warnings);
    }
}

/// Points with optional error bars.
pub struct XyPoints<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
    /// Half-length of the error bar per point (e.g. 2 standard errors).
    pub err: Option<&'a [f64]>,
    pub color: &'a str,
    pub label: &'a str,
}

/// A polyline.
pub struct XyLine<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub color: &'a str,
    pub label: &'a str,
    pub dashed: bool,
}

fn range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = vals
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { lo.abs().max(1.0) * 0.05 };
    (lo - pad, hi + pad)
}

/// An axis label: short, no trailing zeros.
fn tick_label(v: f64) -> String {
    let s = num(v);
    if s.contains('.') && !s.contains('e') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// Round tick values covering `[lo, hi]`.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let raw = (hi - lo) / 6.0;
    if !(raw.is_finite() && raw > 0.0) {
        return vec![lo];
    }
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let mut v = Vec::new();
    let mut t = (lo / step).ceil() * step;
    while t <= hi && v.len() < 20 {
        v.push(if t.abs() < 1e-9 * step { 0.0 } else { t });
        t += step;
    }
    v
}

/// An x-y chart of measured points (with error bars) and curves.
pub fn xy_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[XyPoints<'_>],
    lines: &[XyLine<'_>],
) -> String {
    const W: f64 = 820.0;
    const H: f64 = 440.0;
    const ML: f64 = 70.0;
    const MR: f64 = 20.0;
    const MT: f64 = 44.0;
    const MB: f64 = 42.0;
    let xs =
        points.iter().flat_map(|p| p.x.iter().copied()).chain(lines.iter().flat_map(|l| l.x.iter().copied()));
    let (x0, x1) = range(xs);
    let ys = points
        .iter()
        .flat_map(|p| {
            p.y.iter().enumerate().map(|(i, y)| y + p.err.and_then(|e| e.get(i)).copied().unwrap_or(0.0))
        })
        .chain(points.iter().flat_map(|p| {
            p.y.iter().enumerate().map(|(i, y)| y - p.err.and_then(|e| e.get(i)).copied().unwrap_or(0.0))
        }))
        .chain(lines.iter().flat_map(|l| l.y.iter().copied()));
    let (y0, y1) = range(ys);
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
    for v in ticks(y0, y1) {
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
    for v in ticks(x0, x1) {
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
            if let Some(e) = p.err.and_then(|e| e.get(i)).filter(|e| e.is_finite() && **e > 0.0) {
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

/// Colours for series, cycling.
pub const COLORS: [&str; 8] =
    ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2"];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identify_report_builds_markdown_and_wellformed_svg() {
        let mut r = Report::new("t");
        r.h2("Fit");
        r.table(&["a", "b"], &[vec!["1".to_string(), "x|y".to_string()]]);
        let svg = xy_chart(
            "a<b",
            "x",
            "y",
            &[XyPoints {
                x: &[1.0, 2.0],
                y: &[3.0, f64::NAN],
                err: Some(&[0.5, 0.5]),
                color: "#000",
                label: "p",
            }],
            &[XyLine { x: &[0.0, 3.0], y: &[0.0, 4.0], color: "#f00", label: "fit", dashed: true }],
        );
        assert!(
            svg.starts_with("<svg")
                && svg.ends_with("</svg>")
                && svg.contains("a&lt;b")
                && !svg.contains("NaN")
        );
        r.plot("a.svg", "chart", svg);
        assert!(r.md.contains("| 1 | x/y |") && r.md.contains("![chart](a.svg)"));
        let d = tempfile::tempdir().unwrap();
        let files = r.write(d.path()).unwrap();
        assert_eq!(files.len(), 2);
        assert_eq!(pm(1.23456, 0.01), "1.235 ± 0.0100");
        assert_eq!(ticks(0.0, 10.0).len(), 6);
        assert_eq!(
            (tick_label(-100.0), tick_label(2.5), tick_label(0.0)),
            ("-100".into(), "2.5".into(), "0".into())
        );
    }
}
