//! 95 % intervals of the set's parameters at its settled refit, with the maps and
//! parameters estimated beside them: the maps' stated uncertainty is in the fit (their
//! prior), so it widens a parameter by as much as the maps can trade with it.
//!
//! The larger of two spreads, as the diagnosis' own intervals ([`crate::uncertainty`]):
//! the linearised posterior (the inverse of the penalised normal matrix, every other
//! unknown following) and the fold jackknife (each fold — a run of a campaign, a fifth of
//! a single run — left out in turn, the maps re-estimated on what is kept, one
//! Gauss–Newton step from the refit, no simulation). Both widened by what the fit leaves
//! above the noise (the Birge ratio) and by a parameter's quantisation and the twin's
//! step bias.

use super::{Point, Problem, Unknown};
use crate::library::current_value;
use crate::linalg::solve_spd;
use crate::uncertainty::{fold_jackknife_std, misfit_factor};

impl Problem<'_> {
    /// Each free library parameter's 95 % interval `[lo, hi]` at the refit `at` (`g` its
    /// penalised normal matrix, [`Problem::gram`]), in the order of [`Problem::free`],
    /// clamped to the parameter's range; `None` where the normal equations cannot be
    /// solved.
    pub(super) fn intervals(&self, at: &Point, g: &[f64]) -> Option<Vec<[f64; 2]>> {
        let n = self.unknowns.len();
        let own: Vec<usize> = (0..n).filter(|&i| matches!(self.unknowns[i], Unknown::Effect(_))).collect();
        let posterior = own.iter().map(|&i| {
            let mut e = vec![0.0; n];
            e[i] = 1.0;
            solve_spd(g, &e, 1e-12).map(|c| c[i].max(0.0).sqrt())
        });
        let posterior: Vec<f64> = posterior.collect::<Option<_>>()?;
        // The prior linearised at the refit: its curvature and its pull there.
        let precision: Vec<f64> = (0..n).map(|i| self.curvature(i, at.x[i])).collect();
        let pull: Vec<f64> = (0..n).map(|i| self.pull(i, at.x[i], at.x[i])).collect();
        let folds: Vec<usize> =
            self.rows.iter().map(|&t| self.p.folds.get(t).copied().unwrap_or(0)).collect();
        let weights = self.p.weights.on_rows(&self.rows);
        let jack = fold_jackknife_std(&weights, &at.r, &at.jacobian, &folds, Some((&precision, &pull)));
        let e_noise = (self.rows.len() * self.w.len()) as f64;
        let birge = misfit_factor(self.dot(&at.r, &at.r), e_noise);
        let values = self.values(&at.x);
        let dt = self.twin.dt_s();
        let each = own.iter().zip(&posterior).zip(self.free.iter().zip(&values));
        let intervals = each.map(|((&i, sd), ((s, _), v))| {
            let sd = jack.as_ref().map_or(*sd, |j| sd.max(j[i]));
            let (q, b) = (s.quantum(dt), s.step_bias.at(*v));
            let half = 1.96 * ((birge * sd * s.delta).powi(2) + q * q / 12.0 + b * b / 3.0).sqrt();
            [(v - half).max(s.lower), (v + half).min(s.upper)]
        });
        Some(intervals.collect())
    }

    /// The member of the set the runs tell least from absent, if they cannot tell it at
    /// all: every one of its parameters' 95 % `intervals` at the refit's `values` (in the
    /// order of [`Problem::free`]) holds the model's value. Least: the smallest largest
    /// distance of a parameter from the model's value in half-widths. The causes `kept`
    /// (the verdict's) are not weighed.
    pub(super) fn unsupported(
        &self,
        values: &[f64],
        intervals: &[[f64; 2]],
        kept: &[&str],
    ) -> Option<String> {
        let mut causes: Vec<&str> = self.free.iter().map(|(s, _)| s.cause).collect();
        causes.dedup();
        causes.retain(|c| !kept.contains(c));
        let mine = |cause: &str| -> Vec<(f64, f64, [f64; 2])> {
            let at = self.free.iter().zip(values.iter().zip(intervals));
            let at = at.filter(|((s, _), _)| s.cause == cause);
            at.map(|((s, _), (v, iv))| (current_value(&self.fx, s), *v, *iv)).collect()
        };
        let held = |cause: &&str| mine(cause).iter().all(|&(v0, _, [lo, hi])| lo <= v0 && v0 <= hi);
        let depth = |cause: &str| {
            let far = mine(cause).into_iter();
            far.map(|(v0, v, [lo, hi])| (v - v0).abs() / (0.5 * (hi - lo)).max(f64::MIN_POSITIVE))
                .fold(0.0, f64::max)
        };
        let least = causes.into_iter().filter(held).min_by(|a, b| depth(a).total_cmp(&depth(b)));
        least.map(str::to_string)
    }
}
