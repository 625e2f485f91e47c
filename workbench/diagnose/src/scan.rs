//! Stage 3b: a parameter whose fit objective has narrow valleys away from its neutral
//! value ([`model_core::effects::Fit::scan`]: a gearbox's free play, whose clunks must
//! line up in time) is scanned on its declared grid instead of being trusted to its
//! linearisation, which sees nothing at zero play. The best point of the grid becomes
//! the candidate's value (the refit's start) and its predicted reduction.

use super::engine::{Candidate, Options, Twin};
use super::library::{with_values, ParamSpec};
use super::preparation::{energy, rmse, run_all, Prepared};
use super::sensitivities::Sensitivities;

/// Scan every one-parameter cause that declares a grid and is not yet in the model (in
/// the model, it sits in its valley and its linearisation holds), and write the best grid
/// point into its candidate when it beats both the current model and the linear fit.
pub(super) fn scan_valleys(
    twin: &dyn Twin,
    p: &Prepared,
    s: &Sensitivities,
    o: &Options,
    cands: &mut [Candidate],
) {
    for (ci, (_, ix)) in s.groups.iter().enumerate() {
        let [i] = ix.as_slice() else { continue };
        let sp = &s.specs[*i];
        let Some((step, to)) = sp.scan() else { continue };
        if s.starts[*i] != sp.neutral || step <= 0.0 {
            continue;
        }
        let top = to.min(sp.upper);
        let grid: Vec<f64> =
            (1..).map(|k| sp.lower + k as f64 * step).take_while(|v| *v <= top + 1e-9).collect();
        let (Some((v, e, sim)), Some(c)) = (best_on_grid(twin, p, o, sp, &grid), cands.get_mut(ci)) else {
            continue;
        };
        let reduction = ((p.e0 - e) / p.excess).min(1.0);
        if e >= p.e0 || reduction <= c.predicted_reduction {
            continue;
        }
        c.predicted_reduction = reduction;
        if let Some(fp) = c.params.first_mut() {
            fp.value = v;
        }
        for (k, ch) in c.channels.iter_mut().enumerate() {
            let y: Vec<f64> = sim[k].iter().map(|x| f64::from(*x)).collect();
            ch.rmse_predicted = rmse(&p.meas[k], &y, &p.idx);
        }
    }
}

/// The best grid point `(value, energy, simulation)` of the scan of `sp` over `grid`
/// ([`coarse_to_fine`]).
fn best_on_grid(
    twin: &dyn Twin,
    p: &Prepared,
    o: &Options,
    sp: &ParamSpec,
    grid: &[f64],
) -> Option<(f64, f64, Vec<Vec<f32>>)> {
    let best = coarse_to_fine(grid.len(), |ks| {
        let jobs: Vec<_> = ks.iter().map(|&k| with_values(&o.base, &[sp], &[grid[k]])).collect();
        ks.iter()
            .zip(run_all(twin, p, &jobs, o))
            .filter_map(|(&k, r)| r.ok().map(|sim| (k, energy(p, &sim), sim)))
            .collect()
    });
    best.map(|(k, e, sim)| (grid[k], e, sim))
}

/// The point of lowest energy on a grid of `n` points, evaluating every other point and
/// then the two neighbours of the best of those (`eval(indices)` gives `(index, energy,
/// payload)` for those it could evaluate). A valley is wider than two grid steps (on the
/// tuning runs a free play's was about 1° wide at the 0.25° grid, and the best point of
/// the whole grid was always the best of this search), so half the simulations find it.
/// A grid of fewer than four points is evaluated whole. Ties go to the lower index, as in
/// a scan of the whole grid in order.
fn coarse_to_fine<T>(n: usize, eval: impl Fn(&[usize]) -> Vec<(usize, f64, T)>) -> Option<(usize, f64, T)> {
    let coarse: Vec<usize> = if n < 4 { (0..n).collect() } else { (1..n).step_by(2).collect() };
    let mut found = eval(&coarse);
    let at = found.iter().min_by(|a, b| a.1.total_cmp(&b.1)).map(|b| b.0);
    if let (Some(k), true) = (at, n >= 4) {
        let near: Vec<usize> = [k.wrapping_sub(1), k + 1].into_iter().filter(|j| *j < n).collect();
        found.extend(eval(&near));
    }
    found.sort_by_key(|x| x.0);
    found.into_iter().min_by(|a, b| a.1.total_cmp(&b.1))
}

#[cfg(test)]
mod tests {
    use super::coarse_to_fine;
    use std::cell::RefCell;

    /// A valley three points wide anywhere on a 40-point grid (over a slope, as a free
    /// play's objective sits on the rest of the model's error) is found at the whole
    /// grid's best point with 22 evaluations instead of 40.
    #[test]
    fn the_coarse_search_finds_a_valley_three_points_wide_with_half_the_evaluations() {
        for centre in 0..40usize {
            let energy = |k: usize| {
                let d = k.abs_diff(centre) as f64;
                let valley = if d <= 1.0 { -10.0 + 4.0 * d } else { 0.0 };
                valley + 0.1 * k as f64
            };
            let whole = (0..40).min_by(|a, b| energy(*a).total_cmp(&energy(*b))).unwrap();
            let calls = RefCell::new(0);
            let found = coarse_to_fine(40, |ks| {
                *calls.borrow_mut() += ks.len();
                ks.iter().map(|&k| (k, energy(k), ())).collect()
            });
            assert_eq!(found.map(|f| f.0), Some(whole), "valley at {centre}");
            assert!(*calls.borrow() <= 22, "{} evaluations", calls.borrow());
        }
    }

    /// A short grid is evaluated whole, and a grid where nothing could be evaluated has
    /// no best point.
    #[test]
    fn a_short_grid_is_scanned_whole_and_an_empty_result_is_none() {
        let seen = RefCell::new(Vec::new());
        let found = coarse_to_fine(3, |ks| {
            seen.borrow_mut().extend_from_slice(ks);
            ks.iter().map(|&k| (k, [3.0, 1.0, 2.0][k], ())).collect()
        });
        assert_eq!(*seen.borrow(), vec![0, 1, 2]);
        assert_eq!(found.map(|f| f.0), Some(1));
        assert!(coarse_to_fine::<()>(40, |_| Vec::new()).is_none());
    }
}
