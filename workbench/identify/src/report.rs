//! What every identification writes besides its data files: `report.md` (values, fit
//! statistics, per-plateau tables, what was rejected and why) and SVG charts, drawn by
//! `simrod_report::svg` (plotters' SVG backend, no font library).

use std::fmt::Write as _;
use std::io;
use std::path::{Path, PathBuf};

pub use simrod_report::num;
pub use simrod_report::svg::{xy_chart, XyLine, XyPoints, PALETTE};

use super::plateau::Extraction;
use super::run::Run;
use simrod_io::atomic::write_atomic;

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identify_report_builds_markdown_and_wellformed_svg() {
        let mut r = Report::new("t");
        r.h2("Fit");
        r.table(&["a", "b"], &[vec!["1".to_string(), "x|y".to_string()]]);
        let svg = xy_chart("c", "x", "y", &[], &[]);
        r.plot("a.svg", "chart", svg);
        assert!(r.md.contains("| 1 | x/y |") && r.md.contains("![chart](a.svg)"));
        let d = tempfile::tempdir().unwrap();
        let files = r.write(d.path()).unwrap();
        assert_eq!(files.len(), 2);
        assert_eq!(pm(1.23456, 0.01), "1.235 ± 0.0100");
    }
}
