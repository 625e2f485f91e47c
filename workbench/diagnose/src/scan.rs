//! Stage 3b: a parameter whose fit objective has narrow valleys away from its neutral
//! value ([`model_core::effects::Fit::scan`]: a gearbox's free play, whose clunks must
//! line up in time) is scanned on its declared grid instead of being trusted to its
//! linearisation, which sees nothing at zero play. The best point of the grid becomes
//! the candidate's value (the refit's start) and its predicted reduction.

use super::engine::{Candidate, Options, Twin};
use super::library::with_values;
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
        let jobs: Vec<_> = grid.iter().map(|v| with_values(&o.base, &[sp], &[*v])).collect();
        let best = grid
            .iter()
            .zip(run_all(twin, p, &jobs, o))
            .filter_map(|(v, r)| r.ok().map(|sim| (*v, energy(p, &sim), sim)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let (Some((v, e, sim)), Some(c)) = (best, cands.get_mut(ci)) else { continue };
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
