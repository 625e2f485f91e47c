//! What every reader hands over (columns as read), and the one pipeline that turns it
//! into a [`Measurement`]: mapping, unit checks and conversions, time checks, resampling.
//! Keeping it in one place makes CSV and MAT files of the same data load identically.

use std::path::PathBuf;

use super::mapping::Mapping;
use super::resample;
use super::units::{bench_unit, factor_to};
use super::{LoadOptions, Loaded, Measurement, Signal};
use crate::error::FileError;

/// One column as the file gives it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RawColumn {
    /// Name as written (CSV header without the unit; MAT: bench name if the variable
    /// stands for one, else the variable name).
    pub name: String,
    /// Other names mapping keys may use for it (MAT: the variable name).
    pub alias: Option<String>,
    /// Unit as written, `None` when the file gives none.
    pub unit: Option<String>,
    pub values: Vec<f64>,
}

/// Where sample `i` is in the file, for messages.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Rows {
    /// CSV: the 1-based line of each sample, and the line of the header.
    Lines { lines: Vec<usize>, header: usize },
    /// MAT: samples are vector elements (reported 1-based, as MATLAB indexes).
    Samples,
}

/// A file's contents before any interpretation.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RawTable {
    pub source: PathBuf,
    pub time: RawColumn,
    pub columns: Vec<RawColumn>,
    pub rows: Rows,
}

impl RawTable {
    /// An error at sample `i` (0-based), in channel `ch`.
    pub fn at_sample(&self, i: usize, ch: &str, msg: &str) -> FileError {
        match &self.rows {
            Rows::Lines { lines, .. } => FileError {
                file: self.source.clone(),
                line: lines.get(i).copied(),
                col: None,
                message: format!("channel \"{ch}\": {msg}"),
            },
            Rows::Samples => {
                FileError::whole(&self.source, format!("channel \"{ch}\", sample {}: {msg}", i + 1))
            }
        }
    }

    /// An error about the channel list (CSV: located at the header).
    pub fn at_header(&self, msg: String) -> FileError {
        match &self.rows {
            Rows::Lines { header, .. } => {
                FileError { file: self.source.clone(), line: Some(*header), col: None, message: msg }
            }
            Rows::Samples => FileError::whole(&self.source, msg),
        }
    }
}

/// Mapping, units, time checks, resampling: the shared second half of every reader.
pub(crate) fn finish(mut raw: RawTable, opts: &LoadOptions) -> Result<Loaded, FileError> {
    let mut notes = Vec::new();
    if let Some(m) = &opts.mapping {
        apply_mapping(&mut raw, m, &mut notes)?;
    }
    check_names(&raw, opts)?;
    let time_unit = raw.time.unit.clone().unwrap_or_default();
    let tf = factor_to("s", &time_unit).ok_or_else(|| {
        raw.at_header(format!(
            "time column \"{}\": unit `{time_unit}` is not a time unit (accepted: s, ms, us)",
            raw.time.name
        ))
    })?;
    scale(&mut raw.time.values, tf);
    let mut signals = Vec::with_capacity(raw.columns.len());
    for c in std::mem::take(&mut raw.columns) {
        signals.push(to_signal(&raw, c)?);
    }
    check_finite(&raw, &raw.time.name, &raw.time.values)?;
    for s in &signals {
        check_finite(&raw, &s.name, &s.values)?;
    }
    let time = std::mem::take(&mut raw.time.values);
    if time.is_empty() {
        return Err(FileError::whole(&raw.source, "no samples (empty file)"));
    }
    let grid = resample::check_time(&raw, &time, signals.len(), opts)?;
    let mut m = Measurement { source: raw.source.clone(), time_s: time, signals };
    let mut gaps = Vec::new();
    let mut resampled_dt = None;
    if let Some(g) = grid {
        notes.push(format!(
            "{}: irregular sampling; resampled by linear interpolation onto a uniform {} s grid (the median interval)",
            raw.source.display(),
            g.dt
        ));
        if !g.gaps.is_empty() {
            notes.push(format!(
                "{}: {} gap(s) interpolated across and marked in channel \"{}\"",
                raw.source.display(),
                g.gaps.len(),
                super::GAP_CHANNEL
            ));
        }
        resampled_dt = Some(g.dt);
        gaps = g.gaps.clone();
        m = resample::onto_grid(&m, &g);
    }
    Ok(Loaded { measurement: m, notes, resampled_dt, gaps })
}

fn scale(v: &mut [f64], f: f64) {
    if f != 1.0 {
        v.iter_mut().for_each(|x| *x *= f);
    }
}

fn apply_mapping(raw: &mut RawTable, m: &Mapping, notes: &mut Vec<String>) -> Result<(), FileError> {
    let matches = |c: &RawColumn, key: &str| c.name == key || c.alias.as_deref() == Some(key);
    for key in m.keys() {
        let found = matches(&raw.time, key) || raw.columns.iter().any(|c| matches(c, key));
        if !found {
            notes.push(format!("{}: mapping key \"{key}\" matches no column", raw.source.display()));
        }
    }
    let lookup = |c: &RawColumn, table_key: &dyn Fn(&str) -> bool| -> Option<String> {
        [Some(c.name.as_str()), c.alias.as_deref()]
            .into_iter()
            .flatten()
            .find(|k| table_key(k))
            .map(str::to_owned)
    };
    if let Some(k) = lookup(&raw.time, &|k| m.unit.contains_key(k)) {
        raw.time.unit = m.unit.get(&k).cloned();
    }
    for c in &mut raw.columns {
        if let Some(k) = lookup(c, &|k| m.unit.contains_key(k)) {
            c.unit = m.unit.get(&k).cloned();
        }
        if let Some(k) = lookup(c, &|k| m.scale.contains_key(k)) {
            scale(&mut c.values, m.scale.get(&k).copied().unwrap_or(1.0));
        }
        if let Some(k) = lookup(c, &|k| m.rename.contains_key(k)) {
            if let Some(to) = m.rename.get(&k) {
                c.alias = Some(std::mem::replace(&mut c.name, to.clone()));
            }
        }
    }
    Ok(())
}

/// No two channels with one name; every required channel present.
fn check_names(raw: &RawTable, opts: &LoadOptions) -> Result<(), FileError> {
    for (i, c) in raw.columns.iter().enumerate() {
        let dup = raw.columns[..i].iter().any(|d| d.name == c.name) || c.name == raw.time.name;
        if dup {
            return Err(raw.at_header(format!("channel \"{}\" appears twice (after renaming)", c.name)));
        }
    }
    let missing: Vec<&str> = opts
        .required
        .iter()
        .map(String::as_str)
        .filter(|r| !raw.columns.iter().any(|c| c.name == *r))
        .collect();
    if !missing.is_empty() {
        return Err(raw.at_header(missing_message(&missing)));
    }
    Ok(())
}

/// "missing required channel(s) ..." with the names quoted.
pub(crate) fn missing_message(missing: &[&str]) -> String {
    let list: Vec<String> = missing.iter().map(|m| format!("\"{m}\"")).collect();
    format!(
        "missing required channel(s) {} (rename them with a mapping file if the bench calls them differently)",
        list.join(", ")
    )
}

fn to_signal(raw: &RawTable, c: RawColumn) -> Result<Signal, FileError> {
    let Some(bench) = bench_unit(&c.name) else {
        return Ok(Signal { name: c.name, unit: c.unit.unwrap_or_default(), values: c.values });
    };
    let Some(unit) = c.unit.as_deref() else {
        return Err(raw.at_header(format!(
            "channel \"{}\" has no unit; expected {bench} (write it in the header, or in a mapping file's [unit] table)",
            c.name
        )));
    };
    let f = factor_to(bench, unit).ok_or_else(|| {
        raw.at_header(format!(
            "channel \"{}\": unit `{unit}` cannot be {bench} (see the accepted units in the measure::units docs)",
            c.name
        ))
    })?;
    let mut values = c.values;
    scale(&mut values, f);
    Ok(Signal { name: c.name, unit: bench.to_owned(), values })
}

fn check_finite(raw: &RawTable, name: &str, v: &[f64]) -> Result<(), FileError> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(raw.at_sample(i, name, &format!("value {} is not finite", v[i]))),
        None => Ok(()),
    }
}
