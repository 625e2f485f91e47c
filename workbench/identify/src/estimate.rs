//! What the transient identifications (`inertia`, `inverter-rates`, `stiffness`) hand
//! back: parameter estimates with a standard uncertainty — or the reason the data
//! cannot determine them — a report, and plots; and how they become an
//! [`Identification`]: the base data directory with the determined values set in its
//! `parameters.toml` (comment: uncertainty and method), the report, the charts, and
//! `identified.toml`, a fragment in the model's own format (`key = value  # [unit]
//! origin`) holding only what this identification found.
//!
//! An undetermined parameter is never written as a number: its key appears only in a
//! comment of the fragment, and the data directory keeps the base model's value.

use std::fmt::Write as _;

use super::report::{Plot as ReportFile, Report};
use super::{Context, Identification};

/// One identified (or undetermined) parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Key in `parameters.toml`.
    pub key: String,
    /// `None`: the data cannot determine it (see `note`).
    pub value: Option<f64>,
    /// Standard uncertainty (one standard deviation), in `unit`.
    pub sigma: f64,
    pub unit: &'static str,
    /// The base model's value, for comparison.
    pub base: Option<f64>,
    /// How it was found, or why it could not be.
    pub note: String,
}

impl Estimate {
    /// A determined value.
    pub fn value(key: &str, value: f64, sigma: f64, unit: &'static str, note: impl Into<String>) -> Self {
        Self { key: key.to_owned(), value: Some(value), sigma, unit, base: None, note: note.into() }
    }

    /// An undetermined value, with the reason.
    pub fn undetermined(key: &str, unit: &'static str, why: impl Into<String>) -> Self {
        Self { key: key.to_owned(), value: None, sigma: f64::NAN, unit, base: None, note: why.into() }
    }

    /// With the base model's value attached.
    pub fn with_base(mut self, base: f64) -> Self {
        self.base = Some(base);
        self
    }

    /// `value ± sigma unit`, or `undetermined`.
    pub fn display(&self) -> String {
        match self.value {
            Some(v) => format!("{} ± {} {}", sig(v), sig(self.sigma), self.unit),
            None => "undetermined".to_owned(),
        }
    }
}

/// A chart to write next to the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Plot {
    /// File name without extension.
    pub name: String,
    pub svg: String,
}

/// The result of one identification.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Outcome {
    /// Subcommand name (`inertia`, `inverter-rates`, `stiffness`).
    pub what: String,
    pub estimates: Vec<Estimate>,
    /// Report body (Markdown), after the estimates table.
    pub lines: Vec<String>,
    pub plots: Vec<Plot>,
    /// Runs and regions left out, and why.
    pub notes: Vec<String>,
}

/// A number with 5 significant digits, without trailing zeros.
pub fn sig(v: f64) -> String {
    if !v.is_finite() {
        return "-".to_owned();
    }
    if v == 0.0 {
        return "0".to_owned();
    }
    let mag = v.abs().log10().floor() as i32;
    let decimals = (4 - mag).clamp(0, 9) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    }
}

impl Outcome {
    /// The estimate for `key`, if any.
    pub fn get(&self, key: &str) -> Option<&Estimate> {
        self.estimates.iter().find(|e| e.key == key)
    }

    /// The `parameters.toml` fragment: determined values as `key = value  # [unit] ...`,
    /// undetermined ones as comments naming the reason.
    pub fn parameters_toml(&self, sources: &[String]) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "# simrod identify {}: from {} run(s): {}",
            self.what,
            sources.len(),
            sources.join(", ")
        );
        let _ = writeln!(
            s,
            "# Uncertainties are one standard deviation. Undetermined keys are left as comments,"
        );
        let _ = writeln!(s, "# so merging this fragment keeps the base model's value for them.");
        for e in &self.estimates {
            let note = e.note.replace(['\n', '\r'], " ");
            match e.value {
                Some(v) => {
                    let _ = writeln!(
                        s,
                        "{} = {}  # [{}] identified ± {} ({}): {}",
                        e.key,
                        toml_number(v),
                        e.unit,
                        sig(e.sigma),
                        self.what,
                        note
                    );
                }
                None => {
                    let _ = writeln!(s, "# {} = undetermined  # [{}] {}", e.key, e.unit, note);
                }
            }
        }
        s
    }

    /// The Markdown report.
    pub fn report_markdown(&self, sources: &[String]) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "Runs: {}\n", sources.join(", "));
        let _ = writeln!(s, "| parameter | identified (± 1 s.d.) | base model | note |");
        let _ = writeln!(s, "|---|---|---|---|");
        for e in &self.estimates {
            let base = e.base.map_or("-".to_owned(), |b| format!("{} {}", sig(b), e.unit));
            let _ =
                writeln!(s, "| `{}` | {} | {} | {} |", e.key, e.display(), base, e.note.replace('|', "/"));
        }
        s.push('\n');
        for l in &self.lines {
            let _ = writeln!(s, "{l}");
        }
        if !self.notes.is_empty() {
            let _ = writeln!(s, "\n## Left out\n");
            for n in &self.notes {
                let _ = writeln!(s, "- {n}");
            }
        }
        s.push('\n');
        s
    }

    /// The identification: the base data with the determined values set, the report
    /// with the charts, and the fragment `identified.toml`.
    pub fn finish(self, ctx: &Context<'_>) -> Identification {
        let sources: Vec<String> = ctx.runs.iter().map(|r| r.name.clone()).collect();
        let mut data = ctx.base.clone();
        let mut changed = Vec::new();
        let mut missing = Vec::new();
        for e in &self.estimates {
            let Some(v) = e.value else { continue };
            let comment = format!(
                "[{}] identified ± {} (1 s.d.) by simrod identify {} from {} run(s): {}",
                e.unit,
                sig(e.sigma),
                self.what,
                sources.len(),
                e.note.replace(['\n', '\r'], " ")
            );
            if data.set_param(&e.key, v as f32, &comment) {
                changed.push(e.key.clone());
            } else {
                missing.push(e.key.clone());
            }
        }
        let mut rep = Report::new(&format!("simrod identify {}", self.what));
        rep.md.push_str(&self.report_markdown(&sources));
        if !missing.is_empty() {
            rep.para(&format!(
                "Not in the base `parameters.toml`, so only in `identified.toml`: {}",
                missing.join(", ")
            ));
        }
        for p in &self.plots {
            rep.plot(&format!("{}.svg", p.name), &p.name, p.svg.clone());
        }
        rep.para("Only the values found here, in the model's format: `identified.toml`.");
        rep.plots.push(ReportFile { file: "identified.toml".into(), svg: self.parameters_toml(&sources) });
        let values = self
            .estimates
            .iter()
            .filter_map(|e| {
                let value = e.value?;
                Some(super::Value { name: e.key.clone(), value, sd: e.sigma, unit: e.unit.to_string() })
            })
            .collect();
        Identification { data, changed, report: rep, fits: Vec::new(), values }
    }
}

/// A number as `parameters.toml` holds it (always with a decimal point, 7 significant
/// digits: the model is f32).
fn toml_number(v: f64) -> String {
    let s = format!("{v:.7e}");
    let x: f64 = s.parse().unwrap_or(v);
    let t = format!("{x}");
    if t.contains(['.', 'e', 'E']) {
        t
    } else {
        format!("{t}.0")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fragment_writes_values_and_comments_out_undetermined() {
        let o = Outcome {
            what: "inertia".into(),
            estimates: vec![
                Estimate::value("load_inertia_l", 0.36341, 0.012, "kg m^2", "6 transients"),
                Estimate::undetermined("sut_inertia", "kg m^2", "power excess below noise"),
            ],
            ..Outcome::default()
        };
        let t = o.parameters_toml(&["a.csv".into()]);
        assert!(
            t.contains("\nload_inertia_l = 0.36341  # [kg m^2] identified ± 0.012 (inertia): 6 transients\n"),
            "{t}"
        );
        assert!(t.contains("\n# sut_inertia = undetermined  # [kg m^2] power excess below noise\n"), "{t}");
        // Every non-comment line is `key = number  # ...`, as build.rs reads it.
        for l in t.lines().filter(|l| !l.starts_with('#')) {
            let (k, rest) = l.split_once('=').unwrap();
            assert!(!k.trim().is_empty());
            let v = rest.split('#').next().unwrap().trim();
            assert!(v.parse::<f32>().unwrap().is_finite(), "{l}");
        }
        assert_eq!(toml_number(7000.0), "7000.0");
        assert_eq!(sig(3.98452), "3.9845");
        assert_eq!(sig(0.0012345678), "0.0012346");
    }
}
