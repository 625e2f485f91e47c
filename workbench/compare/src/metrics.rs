//! Whole-run error figures of one channel. The residual is `sim − meas` everywhere in
//! this crate, so a positive bias means the twin reads high.
//!
//! Samples where either side is not finite are left out of every figure.

use serde::Serialize;

/// The channels' operating spans (`workbench/data/channel_spans.toml`, each with its
/// origin), compiled in.
/// Share of a channel's operating span below which its measured range no longer
/// normalises the error: a channel that moves less than this in a run is near-constant.
pub const SPAN_FLOOR_FRACTION: f64 = 0.1;
/// Absolute floor of the normaliser [channel unit], for an all-zero channel without a
/// documented span.
pub const NORMALISER_FLOOR_ABS: f64 = 1e-9;

pub use simrod_twin::spans::operating_span;

/// What the NRMSE of a channel is relative to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Normaliser {
    /// The measured range (max − min) of the run.
    Range,
    /// A tenth of the channel's documented operating span: the run barely moves it.
    Span,
}

impl Normaliser {
    /// How the report names it.
    pub fn describe(self) -> &'static str {
        match self {
            Normaliser::Range => "range",
            Normaliser::Span => "span/10",
        }
    }
}

/// The scale of channel `name` given its measured range: the range, unless it is under
/// a tenth of the channel's operating span.
pub fn normaliser(name: &str, range: f64) -> (f64, Normaliser) {
    let floor = operating_span(name).map_or(NORMALISER_FLOOR_ABS, |s| SPAN_FLOOR_FRACTION * s);
    if range.is_finite() && range >= floor {
        (range, Normaliser::Range)
    } else {
        (floor, Normaliser::Span)
    }
}

/// Error figures of one channel.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Metrics {
    /// Samples that entered the figures.
    pub n: usize,
    /// Root mean square of the residual.
    pub rmse: f64,
    /// RMSE / normaliser.
    pub nrmse: f64,
    /// The measured range, or a tenth of the channel's operating span when that is
    /// larger ([`normaliser`]).
    pub normaliser: f64,
    /// Which of the two `normaliser` is.
    pub normalised_by: Normaliser,
    /// 100 (1 − ‖e‖ / ‖y − mean y‖); `None` for a constant or near-constant measurement.
    pub fit_percent: Option<f64>,
    /// Coefficient of determination 1 − Σe² / Σ(y − mean y)²; `None` for a constant
    /// measurement.
    pub r2: Option<f64>,
    /// Mean of sim − meas.
    pub bias: f64,
    /// Largest |sim − meas|.
    pub max_abs_error: f64,
    /// [s] where it occurs.
    pub max_error_time_s: f64,
}

/// The residual `sim − meas`, NaN where either side is not finite.
pub fn residual(meas: &[f64], sim: &[f64]) -> Vec<f64> {
    meas.iter().zip(sim).map(|(m, s)| if m.is_finite() && s.is_finite() { s - m } else { f64::NAN }).collect()
}

/// The residual of one paired channel with the samples inside gaps masked (NaN), and
/// its figures: what every comparison of a twin run with a measurement reports.
pub fn paired(p: &simrod_twin::Paired, time_s: &[f64], gaps: &[bool]) -> (Vec<f64>, Metrics) {
    let mut e = residual(&p.meas, &p.sim);
    for (r, gap) in e.iter_mut().zip(gaps) {
        if *gap {
            *r = f64::NAN;
        }
    }
    let m = metrics(&p.name, time_s, &p.meas, &e);
    (e, m)
}

/// Figures of channel `name` from the measurement and its residual.
pub fn metrics(name: &str, time_s: &[f64], meas: &[f64], e: &[f64]) -> Metrics {
    let (mut n, mut sum_y, mut sum_e, mut sum_e2) = (0usize, 0.0, 0.0, 0.0);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut max_abs, mut max_t) = (0.0f64, time_s.first().copied().unwrap_or(0.0));
    for ((&y, &r), &t) in meas.iter().zip(e).zip(time_s) {
        if !r.is_finite() {
            continue;
        }
        n += 1;
        sum_y += y;
        sum_e += r;
        sum_e2 += r * r;
        lo = lo.min(y);
        hi = hi.max(y);
        if r.abs() > max_abs {
            max_abs = r.abs();
            max_t = t;
        }
    }
    if n == 0 {
        return Metrics {
            n,
            rmse: f64::NAN,
            nrmse: f64::NAN,
            normaliser: f64::NAN,
            normalised_by: Normaliser::Range,
            fit_percent: None,
            r2: None,
            bias: f64::NAN,
            max_abs_error: f64::NAN,
            max_error_time_s: f64::NAN,
        };
    }
    let nf = n as f64;
    let mean_y = sum_y / nf;
    let mut sst = 0.0;
    for (&y, &r) in meas.iter().zip(e) {
        if r.is_finite() {
            sst += (y - mean_y) * (y - mean_y);
        }
    }
    let rmse = (sum_e2 / nf).sqrt();
    let (normaliser, normalised_by) = self::normaliser(name, hi - lo);
    // Fit and r² compare the error with the channel's own variation; a near-constant
    // channel's variation is its noise, so they are not defined there.
    let (fit_percent, r2) = if sst > 0.0 && normalised_by == Normaliser::Range {
        (Some(100.0 * (1.0 - (sum_e2 / sst).sqrt())), Some(1.0 - sum_e2 / sst))
    } else {
        (None, None)
    };
    Metrics {
        n,
        rmse,
        nrmse: rmse / normaliser,
        normaliser,
        normalised_by,
        fit_percent,
        r2,
        bias: sum_e / nf,
        max_abs_error: max_abs,
        max_error_time_s: max_t,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        let t = [0.0, 1.0, 2.0, 3.0];
        let y = [0.0, 1.0, 2.0, 3.0];
        let s = [0.5, 1.5, 2.5, 1.0];
        let e = residual(&y, &s);
        let m = metrics("unknown", &t, &y, &e);
        assert_eq!(m.n, 4);
        let sse: f64 = 0.25 * 3.0 + 4.0;
        assert!((m.rmse - (sse / 4.0).sqrt()).abs() < 1e-12);
        assert!((m.normaliser - 3.0).abs() < 1e-12);
        assert!((m.nrmse - m.rmse / 3.0).abs() < 1e-12);
        assert!((m.bias - (1.5 - 2.0) / 4.0).abs() < 1e-12);
        assert_eq!(m.max_abs_error, 2.0);
        assert_eq!(m.max_error_time_s, 3.0);
        let sst = 5.0; // 2.25 + 0.25 + 0.25 + 2.25
        assert!((m.r2.unwrap() - (1.0 - sse / sst)).abs() < 1e-12);
        assert!((m.fit_percent.unwrap() - 100.0 * (1.0 - (sse / sst).sqrt())).abs() < 1e-9);
    }

    #[test]
    fn flat_channel_is_normalised_by_its_span_and_nan_samples_are_skipped() {
        let t = [0.0, 1.0, 2.0];
        let y = [24.0, 24.01, f64::NAN];
        let s = [24.1, 24.1, 24.0];
        let m = metrics("V_DC_busbars", &t, &y, &residual(&y, &s));
        assert_eq!(m.n, 2);
        // 12-30 V window: a tenth of 18 V, not the 0.01 V the run moved.
        assert!((m.normaliser - 1.8).abs() < 1e-12, "{}", m.normaliser);
        assert_eq!(m.normalised_by, Normaliser::Span);
        assert!(m.fit_percent.is_none() && m.r2.is_none(), "{m:?}");
        let rmse = ((0.1f64.powi(2) + 0.09f64.powi(2)) / 2.0).sqrt();
        assert!((m.nrmse - rmse / 1.8).abs() < 1e-9);
    }

    #[test]
    fn every_measured_and_derived_channel_has_a_span() {
        for c in model_core::MEASURED.iter().chain(&[
            model_core::Channel::PDpu,
            model_core::Channel::PSutInv,
            model_core::Channel::PLml,
            model_core::Channel::PLmr,
        ]) {
            let s = operating_span(c.name());
            assert!(s.is_some_and(|v| v > 0.0), "{} has no operating span", c.name());
        }
        // A channel that moves over its span is normalised by its range.
        assert_eq!(normaliser("SuTMotorEnc", 2100.0), (2100.0, Normaliser::Range));
    }
}
