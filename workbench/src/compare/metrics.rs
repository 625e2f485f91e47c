//! Whole-run error figures of one channel. The residual is `sim − meas` everywhere in
//! this crate, so a positive bias means the twin reads high.
//!
//! Samples where either side is not finite are left out of every figure.

use serde::Serialize;

/// Relative floor of the NRMSE normaliser: 1 % of the measurement's RMS level, so a
/// flat channel (the busbar voltage of an ideal supply) does not divide by ~0.
pub const NORMALISER_FLOOR_REL: f64 = 0.01;
/// Absolute floor of the normaliser [channel unit], for an all-zero channel.
pub const NORMALISER_FLOOR_ABS: f64 = 1e-9;

/// Error figures of one channel.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Metrics {
    /// Samples that entered the figures.
    pub n: usize,
    /// Root mean square of the residual.
    pub rmse: f64,
    /// RMSE / normaliser.
    pub nrmse: f64,
    /// max(max − min of the measurement, 1 % of its RMS, 1e-9).
    pub normaliser: f64,
    /// 100 (1 − ‖e‖ / ‖y − mean y‖); `None` for a constant measurement.
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

/// Figures of one channel from the measurement and its residual.
pub fn metrics(time_s: &[f64], meas: &[f64], e: &[f64]) -> Metrics {
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
            fit_percent: None,
            r2: None,
            bias: f64::NAN,
            max_abs_error: f64::NAN,
            max_error_time_s: f64::NAN,
        };
    }
    let nf = n as f64;
    let mean_y = sum_y / nf;
    let (mut sst, mut sum_y2) = (0.0, 0.0);
    for (&y, &r) in meas.iter().zip(e) {
        if r.is_finite() {
            sst += (y - mean_y) * (y - mean_y);
            sum_y2 += y * y;
        }
    }
    let rmse = (sum_e2 / nf).sqrt();
    let normaliser = (hi - lo).max(NORMALISER_FLOOR_REL * (sum_y2 / nf).sqrt()).max(NORMALISER_FLOOR_ABS);
    let (fit_percent, r2) = if sst > 0.0 {
        (Some(100.0 * (1.0 - (sum_e2 / sst).sqrt())), Some(1.0 - sum_e2 / sst))
    } else {
        (None, None)
    };
    Metrics {
        n,
        rmse,
        nrmse: rmse / normaliser,
        normaliser,
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
        let m = metrics(&t, &y, &e);
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
    fn flat_channel_uses_the_floor_and_nan_samples_are_skipped() {
        let t = [0.0, 1.0, 2.0];
        let y = [24.0, 24.0, f64::NAN];
        let s = [24.1, 24.1, 24.0];
        let m = metrics(&t, &y, &residual(&y, &s));
        assert_eq!(m.n, 2);
        assert!((m.normaliser - 0.24).abs() < 1e-12);
        assert!(m.fit_percent.is_none() && m.r2.is_none());
        assert!((m.nrmse - 0.1 / 0.24).abs() < 1e-9);
    }
}
