//! Whether a refitted parameter is a constant: every library effect is, but a plant that
//! warms up (gearbox oil, a connector's resistance) or an offset that drifts is fitted
//! by the nearest constant, which is then a fair average of something else. The refit's
//! Jacobian gives, at no simulation, the estimate each fifth of each run would give
//! alone (one Gauss–Newton step from the joint optimum on that fifth's normal
//! equations). A constant effect's fifths scatter around the optimum; a time-varying one
//! walks away from it in one direction, run after run.
//!
//! The same holds over the operating point: a constant effect's value does not depend on
//! how fast the bench turns. A plant effect the library lacks, fitted by the library
//! effect of nearest form (a drag quadratic in speed by a viscous differential friction),
//! asks for a value that grows band by band from the slowest fifth of the speeds to the
//! fastest: the library effect only averages it.

use model_core::Channel;

use super::library::ParamSpec;
use super::linalg::solve_spd;
use super::preparation::{Prepared, TIME_FOLDS};
use super::refit::{in_scale, Fit};
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

/// A parameter whose estimate changes steadily over the course of a run, with speed or
/// with the load.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Drift {
    /// The cause the parameter belongs to ([`ParamSpec::cause`]): the refitted
    /// candidate's own, or an effect already in the model refitted beside it.
    pub cause: &'static str,
    /// Parameter name.
    pub param: &'static str,
    /// What it changes along.
    pub along: Along,
    /// Its estimate from the first and from the last stretch (or band) alone.
    pub first: f64,
    pub last: f64,
}

/// What a [`Drift`] is measured along.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Along {
    /// The course of the run(s): fifths of each run's fit samples.
    Time,
    /// The operating speed: fifths of the moving fit samples by measured |motor speed|.
    Speed,
    /// The load: fifths of the loaded fit samples by measured |axle torque| (both flanges).
    Torque,
}

impl Along {
    /// What a parameter that fails the test does: "drifts over the run", ….
    pub fn what(self) -> &'static str {
        match self {
            Self::Time => "drifts over the run",
            Self::Speed => "changes with speed",
            Self::Torque => "changes with the load torque",
        }
    }
}

/// Below this share of the largest |motor speed| (|axle torque|) the bench is at rest
/// (unloaded): no band.
const REST: f64 = 0.05;

/// The first parameter of `fit` (residual `resid[channel][fit sample]`, σ from noise
/// alone `std`, the sandwich's) that drifts over the run, or else that changes with
/// speed or with the load ([`Along`]).
pub(super) fn drift(
    p: &Prepared,
    resid: &[Vec<f64>],
    fit: &Fit,
    specs: &[&ParamSpec],
    starts: &[f64],
    std: &[f64],
) -> Option<Drift> {
    let r = Refitted { p, resid, fit, specs, starts, std };
    [Along::Time, Along::Speed, Along::Torque].into_iter().find_map(|along| r.drift_along(along))
}

/// What [`drift`] tests: a refit, its residual and its parameters' σ.
struct Refitted<'a> {
    p: &'a Prepared,
    resid: &'a [Vec<f64>],
    fit: &'a Fit,
    specs: &'a [&'a ParamSpec],
    starts: &'a [f64],
    std: &'a [f64],
}

impl Refitted<'_> {
    /// The first parameter whose estimates, part by part along `along`, change one way
    /// beyond their noise and by a share of its departure from where it started: over
    /// time they walk ([`walks`]), over speed or load bands they rise ([`rises`]). Over
    /// time each stretch's estimate is joint (one Gauss–Newton step on its normal
    /// equations); over bands it is the parameter's alone with the others held at the
    /// optimum, because within one band of speeds a Coulomb and a viscous friction
    /// cannot be told apart.
    fn drift_along(&self, along: Along) -> Option<Drift> {
        let Self { p, resid, fit, specs, starts, std } = *self;
        // The parts each fit sample falls in, and those that count (a band's part 0 is the
        // bench at rest).
        let (part, counted) = match along {
            Along::Time => (stretches(p), 0..STRETCHES),
            Along::Speed => (bands(p, &[Channel::SuTMotorEnc])?, 1..STRETCHES + 1),
            Along::Torque => (bands(p, &[Channel::CKistlerL, Channel::CKistlerR])?, 1..STRETCHES + 1),
        };
        let parts = counted.end;
        // In each parameter's own scale (its sensitivity step), as the refit and its σ
        // are solved: the solvers' ridge is relative to the largest diagonal.
        let scale: Vec<f64> = specs.iter().map(|s| s.delta).collect();
        let (g, b): (Vec<Vec<f64>>, Vec<Vec<f64>>) = {
            let (g, b) = normal_equations_by(&p.weights, &fit.jac, |c, t| resid[c][t], parts, |_, t| part[t]);
            g.iter().zip(&b).map(|(g, b)| in_scale(g, b, &scale)).unzip()
        };
        let n = fit.jac.len();
        let total: Vec<f64> = (0..n * n).map(|x| g.iter().map(|gs| gs[x]).sum()).collect();
        (0..n).find_map(|i| {
            let h = scale[i];
            let naive = h * inverse_diagonal(&total, n, i)?.sqrt();
            // The sandwich's inflation over the white-noise σ, applied to every part.
            let inflate = (std.get(i)? / naive).max(1.0);
            let departure = claimed_departure(specs, &fit.values, starts, i)?;
            let points: Vec<(f64, f64, f64)> = counted
                .clone()
                .filter_map(|s| {
                    let (d, var) = match along {
                        Along::Time => (solve_spd(&g[s], &b[s], 1e-12)?[i], inverse_diagonal(&g[s], n, i)?),
                        Along::Speed | Along::Torque => {
                            let gii = g[s][i * n + i];
                            (gii > 0.0).then(|| (b[s][i] / gii, 1.0 / gii))?
                        }
                    };
                    let (d, sd) = (h * d, h * inflate * var.sqrt());
                    (sd <= RESOLVE * departure).then_some((s as f64, fit.values[i] + d, sd))
                })
                .collect();
            let (first, last) = (points.first()?.1, points.last()?.1);
            let drifts = match along {
                Along::Time => walks(&points, departure),
                Along::Speed | Along::Torque => rises(&points, departure),
            };
            drifts.then(|| Drift { cause: specs[i].cause, param: specs[i].param, along, first, last })
        })
    }
}

/// What parameter `i` of a refit (`values` started at `starts`) is held against: the
/// largest departure from its start of its cause's parameters in its unit. A cause
/// with several like parameters (an axle friction scale per side) claims the largest
/// of them; a side the fit leaves near its thesis value (a right scale of 1.006 beside
/// a left one of 1.25) claims no change of its own, and its small bias band by band
/// from an effect still missing — a regenerative loss, fitted next round — would
/// otherwise refuse the whole effect (tuning case 501,188: the true left scale, removing
/// 99 %, refused as its right "changes with speed", 1.03 to 0.999). `None` when a
/// start is missing.
fn claimed_departure(specs: &[&ParamSpec], values: &[f64], starts: &[f64], i: usize) -> Option<f64> {
    let own = specs.get(i)?;
    let like = specs.iter().enumerate().filter(|(_, sp)| sp.cause == own.cause && sp.unit == own.unit);
    like.map(|(j, _)| Some((values.get(j)? - starts.get(j)?).abs())).try_fold(0.0_f64, |m, d| Some(m.max(d?)))
}

/// Whether at least four `(x, estimate, σ)` points walk one way ([`trend`]), also with
/// the first or the last left out.
fn walks(pts: &[(f64, f64, f64)], departure: f64) -> bool {
    let n = pts.len();
    n >= 4 && trend(pts, departure) && trend(&pts[1..], departure) && trend(&pts[..n - 1], departure)
}

/// Whether `(x, estimate, σ)` points walk one way: a steady line ([`line`]) of at least
/// [`MIN_Z`] standard errors and a first-to-last change of at least [`MIN_SHARE`] of
/// `departure`.
fn trend(pts: &[(f64, f64, f64)], departure: f64) -> bool {
    let Some(l) = line(pts) else { return false };
    let (first, last) = (pts[0].1, pts[pts.len() - 1].1);
    l.z.abs() >= MIN_Z && l.steady && (last - first) * l.slope.signum() >= MIN_SHARE * departure
}

/// Whether band estimates `(band, estimate, σ)` change with speed (load): at least four
/// bands on a steady line ([`line`]) of at least [`MIN_Z`] standard errors, also with the
/// slowest or the fastest band left out, whose change over the bands is at least
/// [`MIN_SHARE`] of `departure`. The change is the line's, not the end bands' own: an
/// effect of the wrong form misfits every band a little, the slowest band is the least
/// certain, and the end bands of a curve bend away from its chord.
fn rises(pts: &[(f64, f64, f64)], departure: f64) -> bool {
    let n = pts.len();
    let Some(l) = line(pts) else { return false };
    let along = |p: &[(f64, f64, f64)]| line(p).is_some_and(|m| m.z.abs() >= MIN_Z && m.z * l.z > 0.0);
    let change = l.slope.abs() * (pts[n - 1].0 - pts[0].0);
    n >= 4
        && l.z.abs() >= MIN_Z
        && l.steady
        && change >= MIN_SHARE * departure
        && along(&pts[1..])
        && along(&pts[..n - 1])
}

/// A weighted straight line through `(x, estimate, σ)` points.
struct Line {
    slope: f64,
    /// The slope in its standard errors.
    z: f64,
    /// Every step goes along the slope or lies within two σ of flat.
    steady: bool,
}

/// The weighted least-squares [`Line`] through `pts`, if its x values differ.
fn line(pts: &[(f64, f64, f64)]) -> Option<Line> {
    let w: Vec<f64> = pts.iter().map(|p| 1.0 / (p.2 * p.2)).collect();
    let sw: f64 = w.iter().sum();
    let xm = pts.iter().zip(&w).map(|(p, w)| w * p.0).sum::<f64>() / sw;
    let ym = pts.iter().zip(&w).map(|(p, w)| w * p.1).sum::<f64>() / sw;
    let sxx: f64 = pts.iter().zip(&w).map(|(p, w)| w * (p.0 - xm).powi(2)).sum();
    let sxy: f64 = pts.iter().zip(&w).map(|(p, w)| w * (p.0 - xm) * (p.1 - ym)).sum();
    if sxx.is_nan() || sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    let steady = pts.windows(2).all(|s| {
        let step = s[1].1 - s[0].1;
        step * slope.signum() >= -2.0 * s[0].2.hypot(s[1].2)
    });
    Some(Line { slope, z: slope * sxx.sqrt(), steady })
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
    let run = |t: usize| p.run_of(t);
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

/// Per fit sample, its band of the measured `of` channels' |sum|: 0 below [`REST`] of
/// the largest (at rest, unloaded), else 1 to [`STRETCHES`] by fifths of the rest,
/// smallest first. `None` when a channel is not among the fitted ones.
fn bands(p: &Prepared, of: &[Channel]) -> Option<Vec<usize>> {
    let cols: Vec<&Vec<f64>> = of
        .iter()
        .map(|ch| p.noise.iter().position(|(name, _)| *name == ch.name()).map(|c| &p.meas[c]))
        .collect::<Option<_>>()?;
    let level: Vec<f64> = p
        .idx
        .iter()
        .map(|&t| cols.iter().map(|m| m.get(t).copied().unwrap_or(0.0)).sum::<f64>().abs())
        .collect();
    let top = level.iter().copied().fold(0.0, f64::max);
    let mut active: Vec<f64> = level.iter().copied().filter(|&v| v > REST * top).collect();
    active.sort_by(f64::total_cmp);
    let band = |v: f64| {
        if v <= REST * top {
            0
        } else {
            1 + (active.partition_point(|&m| m < v) * STRETCHES / active.len()).min(STRETCHES - 1)
        }
    };
    Some(level.iter().map(|&v| band(v)).collect())
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
                held: None,
            };
            let spec = axle_scale("left");
            let sd = 0.01 / x.iter().map(|v| v * v).sum::<f64>().sqrt();
            let resid = vec![(0..n).map(|t| p.meas[0][t] - f64::from(fit.sim[0][t])).collect()];
            drift(&p, &resid, &fit, &[&spec], &[1.0], &[sd])
        };
        let d = case(&|t| 1.0 - 0.2 * t as f64 / n as f64).expect("a warm-up drifts");
        assert!(d.first > d.last && d.first - d.last > 0.1, "{d:?}");
        assert!(case(&|_| 0.9).is_none(), "a constant does not drift");
    }

    /// An axle friction scale per side, fitted on a channel each (`y = θ(t) x`): a left
    /// scale of 1.25 with a right one that walks from 1.03 to 0.98 (a missing effect's
    /// bias on a side at its thesis value) does not drift against the 0.25 the effect
    /// claims; the same walk does when the right side is what the effect claims (the left
    /// at 1.0), and a left that walks by as much as it claims does.
    #[test]
    fn a_side_near_its_start_is_held_against_what_its_effect_claims() {
        let n = 1000;
        let x: Vec<f64> = (0..n).map(|t| 1.0 + (t as f64 * 0.37).sin().abs()).collect();
        let walk = |t: usize| 1.03 - 0.05 * t as f64 / n as f64;
        let case = |left: &dyn Fn(usize) -> f64, right: &dyn Fn(usize) -> f64| {
            let thetas: [&dyn Fn(usize) -> f64; 2] = [left, right];
            let meas: Vec<Vec<f64>> = thetas
                .iter()
                .enumerate()
                .map(|(k, th)| {
                    let noise = super::super::preparation::tests::gaussian(7 + k as u64, n);
                    (0..n).map(|t| th(t) * x[t] + 0.01 * noise[t]).collect()
                })
                .collect();
            let fitted: Vec<f64> = meas
                .iter()
                .map(|m| {
                    m.iter().zip(&x).map(|(m, x)| m * x).sum::<f64>() / x.iter().map(|v| v * v).sum::<f64>()
                })
                .collect();
            let p = prepared(meas, 1);
            let quiet = vec![0.0; n];
            let fit = Fit {
                values: fitted.clone(),
                sim: fitted.iter().map(|c| x.iter().map(|v| (c * v) as f32).collect()).collect(),
                jac: vec![vec![x.clone(), quiet.clone()], vec![quiet, x.clone()]],
                energy: 0.0,
                profile: Vec::new(),
                held: None,
            };
            let (l, r) = (axle_scale("left"), axle_scale("right"));
            let sd = 0.01 / x.iter().map(|v| v * v).sum::<f64>().sqrt();
            let resid: Vec<Vec<f64>> =
                (0..2).map(|c| (0..n).map(|t| p.meas[c][t] - f64::from(fit.sim[c][t])).collect()).collect();
            drift(&p, &resid, &fit, &[&l, &r], &[1.0, 1.0], &[sd, sd])
        };
        assert!(case(&|_| 1.25, &walk).is_none(), "a side at its start, beside one that moved");
        let d = case(&|_| 1.0, &walk).expect("the walk of the side the effect claims");
        assert_eq!((d.param, d.along), ("right", Along::Time), "{d:?}");
        let d = case(&|t| 1.45 - 0.4 * t as f64 / n as f64, &|_| 1.0).expect("a claimed side that walks");
        assert_eq!(d.param, "left", "{d:?}");
    }

    /// Speed-band estimates that grow band by band (a quadratic drag fitted by a viscous
    /// one, as 1,002,555 gave them) change with speed; a constant's scatter does not, nor
    /// does one odd slowest band, nor a change small against the value claimed.
    #[test]
    fn a_value_that_grows_band_by_band_changes_with_speed() {
        let pts = |v: &[(f64, f64)]| -> Vec<(f64, f64, f64)> {
            v.iter().enumerate().map(|(k, &(y, sd))| (k as f64 + 1.0, y, sd)).collect()
        };
        let drag = [(0.0746, 0.0119), (0.1108, 0.0045), (0.1342, 0.0024), (0.1605, 0.0010), (0.1576, 0.0114)];
        assert!(rises(&pts(&drag), 0.1694));
        assert!(!walks(&pts(&drag), 0.1694), "the time test's end-band rule would not see it");
        let scatter = [(0.160, 0.004), (0.166, 0.004), (0.158, 0.004), (0.163, 0.004), (0.161, 0.004)];
        assert!(!rises(&pts(&scatter), 0.16), "scatter");
        let odd = [(0.05, 0.004), (0.160, 0.004), (0.161, 0.004), (0.160, 0.004), (0.161, 0.004)];
        assert!(!rises(&pts(&odd), 0.16), "one odd slowest band");
        let small = [(0.150, 0.001), (0.155, 0.001), (0.160, 0.001), (0.165, 0.001), (0.170, 0.001)];
        assert!(!rises(&pts(&small), 0.16), "small against the value claimed");
    }

    /// A drag `k w²` on one channel fitted by a viscous `c w`: the estimates by band of
    /// the measured motor speed rise with speed, and the drift names speed, not time; a
    /// drag that is viscous does not change with speed.
    #[test]
    fn a_drag_of_the_wrong_form_changes_with_speed() {
        let case = |drag: &dyn Fn(f64) -> f64| one_scale_fitted(&[(Channel::SuTMotorEnc, 200.0)], 0.0, drag);
        let d = case(&|w| w * w).expect("a quadratic drag changes with speed");
        assert_eq!(d.along, Along::Speed, "{d:?}");
        assert!(d.last > d.first + 0.5, "{d:?}");
        assert!(case(&|w| 0.8 * w).is_none(), "a viscous drag fits at every speed");
    }

    /// A current that is its torque plus a constant, fitted as a gain of the torque (a
    /// sensor gain standing in for a shifted map): the gain each band of the measured
    /// axle torque asks for falls with the load, and the drift names the load torque; a
    /// true gain does not change with it.
    #[test]
    fn a_gain_standing_in_for_a_shift_changes_with_the_load_torque() {
        let flanges = [(Channel::CKistlerL, 20.0), (Channel::CKistlerR, 20.0)];
        let case = |current: &dyn Fn(f64) -> f64| one_scale_fitted(&flanges, 1.0, current);
        let d = case(&|t| t + 0.3).expect("a shift fitted as a gain changes with the load");
        assert_eq!(d.along, Along::Torque, "{d:?}");
        assert!(d.first > d.last + 0.3, "{d:?}");
        assert!(case(&|t| 1.05 * t).is_none(), "a gain fits at every load");
    }

    /// I_DC measured as `truth(x)` (noise σ 0.01) and fitted as `c x`, with `x` recorded
    /// on the operating channels `op` (each `x` times its factor), the model's value
    /// before the fit `start`: the drift test's answer.
    fn one_scale_fitted(op: &[(Channel, f64)], start: f64, truth: &dyn Fn(f64) -> f64) -> Option<Drift> {
        let n = 1000;
        let x: Vec<f64> = (0..n).map(|t| 0.3 + (t as f64 * 0.37).sin().abs()).collect();
        let noise = super::super::preparation::tests::gaussian(11, n);
        let meas: Vec<f64> = (0..n).map(|t| truth(x[t]) + 0.01 * noise[t]).collect();
        let c = meas.iter().zip(&x).map(|(m, x)| m * x).sum::<f64>() / x.iter().map(|v| v * v).sum::<f64>();
        let mut series: Vec<Vec<f64>> = op.iter().map(|(_, k)| x.iter().map(|v| k * v).collect()).collect();
        series.push(meas);
        let mut p = prepared(series, 1);
        p.noise = op.iter().map(|(ch, _)| (ch.name(), 1.0)).chain([(Channel::IDc.name(), 0.01)]).collect();
        let quiet = vec![0.0; n];
        let mut sim: Vec<Vec<f32>> = op.iter().map(|_| vec![0.0; n]).collect();
        sim.push(x.iter().map(|v| (c * v) as f32).collect());
        let mut jac: Vec<Vec<f64>> = op.iter().map(|_| quiet.clone()).collect();
        jac.push(x.clone());
        let fit = Fit { values: vec![c], sim, jac: vec![jac], energy: 0.0, profile: Vec::new(), held: None };
        let spec = ParamSpec {
            effect: "differential_friction",
            param: "viscous_nm_s_per_rad",
            cause: "differential_friction",
            neutral: 0.0,
            delta: 0.01,
            lower: 0.0,
            upper: 10.0,
            unit: "N m s/rad",
            step_bias: model_core::effects::Step::Abs(0.0),
            step_bias_side: model_core::effects::Side::Either,
        };
        let sd = 0.01 / x.iter().map(|v| v * v).sum::<f64>().sqrt();
        let resid: Vec<Vec<f64>> = (0..=op.len())
            .map(|ch| (0..n).map(|t| p.meas[ch][t] - f64::from(fit.sim[ch][t])).collect())
            .collect();
        drift(&p, &resid, &fit, &[&spec], &[start], &[sd])
    }

    /// One side's axle friction scale, as the library declares it for the fits here.
    fn axle_scale(param: &'static str) -> ParamSpec {
        ParamSpec {
            effect: "axle_friction_scale",
            param,
            cause: "axle_friction_scale",
            neutral: 1.0,
            delta: 0.01,
            lower: 0.0,
            upper: 10.0,
            unit: "-",
            step_bias: model_core::effects::Step::Abs(0.0),
            step_bias_side: model_core::effects::Side::Either,
        }
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
