//! Time-axis checks and the one resampling the readers do.
//!
//! - Time must be strictly increasing: a repeated or backward time is an error at its row.
//! - Sampling is *uniform* when every interval is within [`JITTER_TOL`] (1 %) of the
//!   median interval; the file's times are then kept exactly as read.
//! - Otherwise the run is resampled: linear interpolation of every channel onto
//!   `t0 + k * median` (k = 0, 1, ... up to the last sample). Interpolation, not a
//!   filter, so a value at an original time is the original value.
//! - An interval longer than `gap_samples` (default [`GAP_SAMPLES`] = 5) median
//!   intervals is a *gap*: lost data, not jitter. It is an error unless gaps are allowed
//!   (`--allow-gaps`); then the run is interpolated across it too, and every grid sample
//!   strictly inside a gap is marked 1 in the extra channel [`super::GAP_CHANNEL`]
//!   (0 elsewhere) so analyses can leave them out ([`Measurement::gap_mask`]).

use super::table::RawTable;
use super::{LoadOptions, Measurement, Signal, GAP_CHANNEL};
use crate::error::FileError;
use simrod_numerics::stats::median;

/// Relative deviation from the median interval still counted as uniform sampling.
pub const JITTER_TOL: f64 = 0.01;
/// Default: an interval longer than this many median intervals is a gap.
pub const GAP_SAMPLES: f64 = 5.0;

/// A uniform grid to resample onto, with the gaps it spans.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub t0: f64,
    pub dt: f64,
    pub n: usize,
    /// `(start, end)` times of the gaps (the samples either side are real).
    pub gaps: Vec<(f64, f64)>,
}

/// Check the time column; `Some(grid)` when the run must be resampled.
pub(crate) fn check_time(
    raw: &RawTable,
    t: &[f64],
    channels: usize,
    opts: &LoadOptions,
) -> Result<Option<Grid>, FileError> {
    let name = raw.time.name.as_str();
    for (i, w) in t.windows(2).enumerate() {
        if w[1] <= w[0] {
            let what = if w[1] == w[0] { "duplicated" } else { "goes back" };
            return Err(raw.at_sample(
                i + 1,
                name,
                &format!("time {} s {what} (previous sample {} s)", w[1], w[0]),
            ));
        }
    }
    if t.len() < 3 {
        return Ok(None);
    }
    let dts: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let Some(m) = median(&dts) else { return Ok(None) };
    if dts.iter().all(|d| (d - m).abs() <= JITTER_TOL * m) {
        return Ok(None);
    }
    let mut gaps = Vec::new();
    for (i, d) in dts.iter().enumerate() {
        if *d > opts.gap_samples * m {
            if !opts.allow_gaps {
                return Err(raw.at_sample(
                    i + 1,
                    name,
                    &format!(
                        "gap of {d} s before this sample ({:.1} median intervals of {m} s, from t = {} s to {} s); \
                         --allow-gaps interpolates across gaps and marks them for the analyses",
                        d / m,
                        t[i],
                        t[i + 1]
                    ),
                ));
            }
            gaps.push((t[i], t[i + 1]));
        }
    }
    let span = t[t.len() - 1] - t[0];
    let n = (span / m + 1e-6).floor() + 1.0;
    // Every column twice (as read and on the grid), 8 bytes a value.
    let bytes = n * (channels + 2) as f64 * 16.0;
    let why = format!("{n} samples at the median interval {m} s, {channels} channels");
    opts.budget.check("resampling it", bytes, &why).map_err(|e| FileError::whole(&raw.source, e))?;
    Ok(Some(Grid { t0: t[0], dt: m, n: n as usize, gaps }))
}

/// Linear interpolation from increasing sample times onto increasing grid times: the
/// interval and weight of every grid time, found once and applied to any number of
/// channels sampled at those times. Grid times outside the samples hold the edge value;
/// a grid time on a sample gives that sample exactly.
#[derive(Debug, Clone)]
pub struct Interp {
    /// Per grid time: the interval `[j, j + 1]` and the weight of `j + 1`.
    idx: Vec<(usize, f64)>,
}

impl Interp {
    /// The interpolation from `t` onto `grid` (`t` non-empty, both increasing).
    pub fn new(t: &[f64], grid: &[f64]) -> Self {
        let mut idx = Vec::with_capacity(grid.len());
        let mut j = 0usize;
        for &tk in grid {
            while j + 2 < t.len() && t[j + 1] <= tk {
                j += 1;
            }
            let a = t.get(j).copied().unwrap_or(tk);
            let b = t.get(j + 1).copied().unwrap_or(a);
            let w = if b > a { ((tk - a) / (b - a)).clamp(0.0, 1.0) } else { 0.0 };
            idx.push((j, w));
        }
        Self { idx }
    }

    /// `values` (one per sample time) at the grid times; NaN where there are none.
    pub fn apply(&self, values: &[f64]) -> Vec<f64> {
        self.idx
            .iter()
            .map(|&(j, w)| {
                let Some(&a) = values.get(j) else { return f64::NAN };
                let b = values.get(j + 1).copied().unwrap_or(a);
                if w == 0.0 {
                    a
                } else if w == 1.0 {
                    b
                } else if (b - a).is_finite() {
                    a + w * (b - a)
                } else {
                    // Finite values of opposite sign near f64::MAX: b − a overflows, the
                    // weighted sum does not (found by the fuzzer).
                    (1.0 - w) * a + w * b
                }
            })
            .collect()
    }
}

/// Linear interpolation of every channel onto `g`, plus the gap mask when there are gaps.
pub(crate) fn onto_grid(m: &Measurement, g: &Grid) -> Measurement {
    let grid: Vec<f64> = (0..g.n).map(|k| g.t0 + k as f64 * g.dt).collect();
    let interp = Interp::new(&m.time_s, &grid);
    let mut signals: Vec<Signal> = m
        .signals
        .iter()
        .map(|s| Signal { name: s.name.clone(), unit: s.unit.clone(), values: interp.apply(&s.values) })
        .collect();
    if !g.gaps.is_empty() {
        signals.push(Signal {
            name: GAP_CHANNEL.to_owned(),
            unit: "-".to_owned(),
            values: grid
                .iter()
                .map(|&tk| {
                    // A grid time within 0.1 % of an interval of a real sample is that sample.
                    let eps = 1e-3 * g.dt;
                    let inside = g.gaps.iter().any(|&(a, b)| tk > a + eps && tk < b - eps);
                    if inside {
                        1.0
                    } else {
                        0.0
                    }
                })
                .collect(),
        });
    }
    Measurement { source: m.source.clone(), time_s: grid, signals }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_keeps_original_points_and_marks_gaps() {
        let m = Measurement {
            source: "x".into(),
            time_s: vec![0.0, 1.0, 2.0, 8.0, 9.0],
            signals: vec![Signal {
                name: "a".into(),
                unit: "".into(),
                values: vec![0.0, 10.0, 20.0, 80.0, 90.0],
            }],
        };
        let g = Grid { t0: 0.0, dt: 1.0, n: 10, gaps: vec![(2.0, 8.0)] };
        let r = onto_grid(&m, &g);
        assert_eq!(r.time_s.len(), 10);
        assert_eq!(r.signals[0].values[5], 50.0);
        assert_eq!(r.signals[0].values[9], 90.0);
        assert_eq!(r.gap_mask(), [0, 0, 0, 1, 1, 1, 1, 1, 0, 0].map(|v| v == 1));
    }
}
