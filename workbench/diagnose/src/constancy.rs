//! Whether a refitted parameter is a constant: every library effect is, but a plant that
//! warms up (gearbox oil, a connector's resistance) or an offset that drifts is fitted
//! by the nearest constant, which is then a fair average of something else. The refit's
//! Jacobian gives, at no simulation, the estimate each fifth of each run would give
//! alone (one Gauss–Newton step from the joint optimum on that fifth's normal
//! equations). A constant effect's fifths scatter around the optimum; a time-varying one
//! walks away from it in one direction, run after run.

use super::library::ParamSpec;
use super::linalg::solve_spd;
use super::preparation::{Prepared, TIME_FOLDS};
use super::refit::Fit;
use super::sensitivities::normal_equations_by;

/// Stretches each run is cut into: a single run's held-out folds, and the same fifths
/// in every run of a campaign, so that a warm-up that restarts with each run adds up
/// instead of cancelling.
const STRETCHES: usize = TIME_FOLDS;

/// Largest σ of a stretch's own estimate, as a share of the parameter's departure from
/// where it started, for the stretch to count: a stretch at rest does not estimate a
/// friction.
const RESOLVE: f64 = 0.25;

/// Least trend over the stretches, in standard errors (the stretch estimates' σ from
/// the sandwich, whose noise model takes coloured noise into account).
const MIN_Z: f64 = 5.0;

/// Least change between the first and last stretch, as a share of the parameter's
/// departure from where it started: a drift that matters against what is claimed.
const MIN_SHARE: f64 = 0.5;

/// A parameter whose estimate changes steadily over the course of a run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Drift {
    /// Parameter name.
    pub param: &'static str,
    /// Its estimate from the first and from the last stretch of the run(s) alone.
    pub first: f64,
    pub last: f64,
}

/// The first parameter of `fit` (residual `resid[channel][fit sample]`, σ from noise
/// alone `std`, the sandwich's) that drifts: its stretch estimates are monotone within their noise, their linear trend is at least [`MIN_Z`] standard errors
/// and their first-to-last change is at least [`MIN_SHARE`] of the departure from
/// `starts` — also with the first or the last stretch left out, so that one odd stretch
/// (a start-up at low speed) is not taken for a drift.
pub(super) fn drift(
    p: &Prepared,
    resid: &[Vec<f64>],
    fit: &Fit,
    specs: &[&ParamSpec],
    starts: &[f64],
    std: &[f64],
) -> Option<Drift> {
    let stretch = stretches(p);
    let (g, b) = normal_equations_by(&p.weights, &fit.jac, |c, t| resid[c][t], STRETCHES, |_, t| stretch[t]);
    let n = fit.jac.len();
    let total: Vec<f64> = (0..n * n).map(|x| g.iter().map(|gs| gs[x]).sum()).collect();
    (0..n).find_map(|i| {
        let naive = inverse_diagonal(&total, n, i)?.sqrt();
        // The sandwich's inflation over the white-noise σ, applied to every stretch.
        let inflate = (std.get(i)? / naive).max(1.0);
        let departure = (fit.values[i] - starts.get(i)?).abs();
        let points: Vec<(f64, f64, f64)> = (0..STRETCHES)
            .filter_map(|s| {
                let d = solve_spd(&g[s], &b[s], 1e-12)?;
                let sd = inflate * inverse_diagonal(&g[s], n, i)?.sqrt();
                (sd <= RESOLVE * departure).then_some((s as f64, fit.values[i] + d[i], sd))
            })
            .collect();
        let (first, last) = (points.first()?.1, points.last()?.1);
        walks(&points, departure).then(|| Drift { param: specs[i].param, first, last })
    })
}

/// Whether at least four `(x, estimate, σ)` points walk one way ([`trend`]), also with
/// the first or the last left out.
fn walks(pts: &[(f64, f64, f64)], departure: f64) -> bool {
    let n = pts.len();
    n >= 4 && trend(pts, departure) && trend(&pts[1..], departure) && trend(&pts[..n - 1], departure)
}

/// Whether `(x, estimate, σ)` points walk one way: a weighted linear trend of at least
/// [`MIN_Z`] standard errors, every step along it or within two σ of flat, and a
/// first-to-last change of at least [`MIN_SHARE`] of `departure`.
fn trend(pts: &[(f64, f64, f64)], departure: f64) -> bool {
    let w: Vec<f64> = pts.iter().map(|p| 1.0 / (p.2 * p.2)).collect();
    let sw: f64 = w.iter().sum();
    let xm = pts.iter().zip(&w).map(|(p, w)| w * p.0).sum::<f64>() / sw;
    let ym = pts.iter().zip(&w).map(|(p, w)| w * p.1).sum::<f64>() / sw;
    let sxx: f64 = pts.iter().zip(&w).map(|(p, w)| w * (p.0 - xm).powi(2)).sum();
    let sxy: f64 = pts.iter().zip(&w).map(|(p, w)| w * (p.0 - xm) * (p.1 - ym)).sum();
    if sxx.is_nan() || sxx <= 0.0 {
        return false;
    }
    let slope = sxy / sxx;
    let z = slope * sxx.sqrt();
    let steady = pts.windows(2).all(|s| {
        let step = s[1].1 - s[0].1;
        step * slope.signum() >= -2.0 * s[0].2.hypot(s[1].2)
    });
    let (first, last) = (pts[0].1, pts[pts.len() - 1].1);
    z.abs() >= MIN_Z && steady && (last - first) * slope.signum() >= MIN_SHARE * departure
}

/// `(A⁻¹)ᵢᵢ` of the `n × n` matrix `a`, if positive and finite.
fn inverse_diagonal(a: &[f64], n: usize, i: usize) -> Option<f64> {
    let mut e = vec![0.0; n];
    e[i] = 1.0;
    let v = solve_spd(a, &e, 1e-12)?[i];
    (v > 0.0 && v.is_finite()).then_some(v)
}

/// Per fit sample, the fifth of its run it lies in.
fn stretches(p: &Prepared) -> Vec<usize> {
    let n = p.idx.len();
    // A single run's folds are its own fifths, not runs.
    let run = |t: usize| if p.runs > 1 { p.folds.get(t).copied().unwrap_or(0) } else { 0 };
    let mut out = vec![0; n];
    let mut start = 0;
    while start < n {
        let r = run(start);
        let end = (start..n).find(|&t| run(t) != r).unwrap_or(n);
        let len = end - start;
        for (k, o) in out[start..end].iter_mut().enumerate() {
            *o = k * STRETCHES / len;
        }
        start = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A friction scale that falls steadily (a warm-up) walks; the same with the change
    /// all in the first stretch (a start-up), or scattered both ways, does not; nor does
    /// a steady walk too small against the departure claimed.
    #[test]
    fn a_steady_walk_is_a_drift_and_one_odd_stretch_is_not() {
        let pts = |v: &[f64]| -> Vec<(f64, f64, f64)> {
            v.iter().enumerate().map(|(k, &y)| (k as f64, y, 0.005)).collect()
        };
        assert!(walks(&pts(&[1.00, 0.96, 0.89, 0.82, 0.79]), 0.14));
        assert!(!walks(&pts(&[1.75, 1.265, 1.252, 1.255]), 0.26), "start-up");
        assert!(!walks(&pts(&[1.62, 1.45, 1.50, 1.41, 1.55]), 0.6), "scatter");
        assert!(!walks(&pts(&[1.10, 1.09, 1.08, 1.07, 1.06]), 0.2), "small against the departure");
        assert!(!walks(&pts(&[1.00, 0.96, 0.89]), 0.14), "three stretches");
    }

    /// A single run's fit samples fall in fifths of it; a campaign's in fifths of each
    /// run, the same fifth in every run.
    #[test]
    fn stretches_are_fifths_of_each_run() {
        let mut p = prepared(vec![vec![0.0; 10]], 1);
        assert_eq!(stretches(&p), [0, 0, 1, 1, 2, 2, 3, 3, 4, 4]);
        p.runs = 2;
        p.folds = vec![0, 0, 0, 0, 0, 0, 1, 1, 1, 1];
        assert_eq!(stretches(&p), [0, 0, 1, 2, 3, 4, 0, 1, 2, 3]);
    }

    /// One channel `y = θ(t) x(t)` with a steady or a constant `θ`, fitted by one constant:
    /// the stretch estimates from the refit's Jacobian find the drift, and only it.
    #[test]
    fn a_drifting_parameter_is_found_from_the_jacobian() {
        let n = 1000;
        let x: Vec<f64> = (0..n).map(|t| 1.0 + (t as f64 * 0.37).sin().abs()).collect();
        let case = |theta: &dyn Fn(usize) -> f64| {
            let noise = super::super::preparation::tests::gaussian(7, n);
            let meas: Vec<f64> = (0..n).map(|t| theta(t) * x[t] + 0.01 * noise[t]).collect();
            let fitted =
                meas.iter().zip(&x).map(|(m, x)| m * x).sum::<f64>() / x.iter().map(|v| v * v).sum::<f64>();
            let p = prepared(vec![meas], 1);
            let fit = Fit {
                values: vec![fitted],
                sim: vec![x.iter().map(|v| (fitted * v) as f32).collect()],
                jac: vec![vec![x.clone()]],
                energy: 0.0,
                profile: Vec::new(),
            };
            let spec = ParamSpec {
                effect: "axle_friction_scale",
                param: "left",
                cause: "axle_friction_scale",
                neutral: 1.0,
                delta: 0.01,
                lower: 0.0,
                upper: 10.0,
                unit: "-",
                step_bias: model_core::effects::Step::Abs(0.0),
            };
            let sd = 0.01 / x.iter().map(|v| v * v).sum::<f64>().sqrt();
            let resid = vec![(0..n).map(|t| p.meas[0][t] - f64::from(fit.sim[0][t])).collect()];
            drift(&p, &resid, &fit, &[&spec], &[1.0], &[sd])
        };
        let d = case(&|t| 1.0 - 0.2 * t as f64 / n as f64).expect("a warm-up drifts");
        assert!(d.first > d.last && d.first - d.last > 0.1, "{d:?}");
        assert!(case(&|_| 0.9).is_none(), "a constant does not drift");
    }

    fn prepared(meas: Vec<Vec<f64>>, runs: usize) -> Prepared {
        let n = meas[0].len();
        Prepared {
            weights: crate::preparation::Weights::uniform(vec![1e4; meas.len()]),
            noise: vec![("C_Kistler_L", 0.01); meas.len()],
            idx: (0..n).collect(),
            stride: 1,
            folds: (0..n).map(|k| k * 5 / n).collect(),
            runs,
            meas,
            ..Prepared::default()
        }
    }
}
