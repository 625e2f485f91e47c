//! Stage 3: ranking by the linearised model. Each effect alone (a score test: the
//! weighted least-squares reduction of the residual its parameters achieve), then a
//! greedy orthogonal forward regression (the incremental reduction given the effects
//! already chosen), then the list of leaders worth a refit on the simulator.

use model_core::Channel;

use super::engine::{Candidate, ChannelChange, FittedParam, Options};
use super::linalg::{quad, solve_spd, sub_matrix};
use super::preparation::{region_errors, rmse, Prepared};
use super::sensitivities::Sensitivities;

/// Bounded linear fit of the parameters `ix`: coefficients (in steps) and the weighted
/// error they remove.
pub(super) fn fit_lin(s: &Sensitivities, ix: &[usize]) -> (Vec<f64>, f64) {
    let gs = sub_matrix(&s.g, s.np(), ix);
    let bs: Vec<f64> = ix.iter().map(|&i| s.b[i]).collect();
    let mut th = solve_spd(&gs, &bs, 1e-9).unwrap_or_else(|| vec![0.0; ix.len()]);
    for (t, &i) in th.iter_mut().zip(ix) {
        let sp = &s.specs[i];
        let v = (s.starts[i] + *t * s.steps[i]).clamp(sp.lower, sp.upper);
        *t = (v - s.starts[i]) / s.steps[i];
    }
    let red = 2.0 * th.iter().zip(&bs).map(|(a, c)| a * c).sum::<f64>() - quad(&gs, &th);
    (th, red.max(0.0))
}

/// Every effect scored alone, in library order, with its linear coefficients (in steps).
pub(super) fn score_effects(
    p: &Prepared,
    s: &Sensitivities,
    channels: &[Channel],
) -> (Vec<Candidate>, Vec<Vec<f64>>) {
    s.groups
        .iter()
        .map(|(effect, ix)| {
            let (th, red) = fit_lin(s, ix);
            let cand = Candidate {
                effect,
                params: fitted_params(s, ix, &th),
                predicted_reduction: (red / p.excess).min(1.0),
                confirmed_reduction: None,
                significant: false,
                channels: channel_changes(p, s, channels, ix, &th),
                regions: region_errors(p, &p.regions, |c, k| {
                    ix.iter().zip(&th).map(|(&i, t)| s.sens[i][c][k] * t).sum::<f64>()
                }),
            };
            (cand, th)
        })
        .unzip()
}

/// The linear fit's values, not yet with an uncertainty (that needs the refit).
fn fitted_params(s: &Sensitivities, ix: &[usize], th: &[f64]) -> Vec<FittedParam> {
    ix.iter()
        .zip(th)
        .map(|(&i, t)| {
            let v = s.starts[i] + t * s.steps[i];
            FittedParam {
                name: s.specs[i].param,
                value: v,
                start: s.starts[i],
                std: f64::NAN,
                ci95: (v, v),
                unit: s.specs[i].unit,
            }
        })
        .collect()
}

/// Per channel: the error now and as the linear fit predicts it.
fn channel_changes(
    p: &Prepared,
    s: &Sensitivities,
    channels: &[Channel],
    ix: &[usize],
    th: &[f64],
) -> Vec<ChannelChange> {
    let m = p.idx.len() as f64;
    channels
        .iter()
        .enumerate()
        .map(|(c, ch)| {
            let gs = sub_matrix(&s.gc[c], s.np(), ix);
            let bs: Vec<f64> = ix.iter().map(|&i| s.bc[c][i]).collect();
            let red_c = 2.0 * th.iter().zip(&bs).map(|(a, x)| a * x).sum::<f64>() - quad(&gs, th);
            let before = rmse(&p.meas[c], &p.base[c], &p.idx);
            let after2 = (before * before - red_c / p.weights[c] / m).max(0.0);
            ChannelChange {
                channel: ch.name(),
                rmse_before: before,
                rmse_predicted: after2.sqrt(),
                rmse_confirmed: None,
            }
        })
        .collect()
}

/// Greedy forward selection: each step adds the effect with the largest incremental
/// reduction, until it removes less than 5 % of the excess. `(effect, share of excess)`.
pub(super) fn greedy(p: &Prepared, s: &Sensitivities, o: &Options) -> Vec<(&'static str, f64)> {
    let mut selected: Vec<(&'static str, f64)> = Vec::new();
    let mut chosen: Vec<usize> = Vec::new();
    let mut chosen_red = 0.0;
    for _ in 0..o.max_selected {
        let mut best: Option<(usize, f64)> = None;
        for (gi, (effect, ix)) in s.groups.iter().enumerate() {
            if selected.iter().any(|(e, _)| e == effect) {
                continue;
            }
            let mut joint = chosen.clone();
            joint.extend(ix);
            let inc = fit_lin(s, &joint).1 - chosen_red;
            if best.is_none_or(|(_, r)| inc > r) {
                best = Some((gi, inc));
            }
        }
        let Some((gi, inc)) = best else { break };
        if inc < 0.05 * p.excess {
            break;
        }
        chosen.extend(&s.groups[gi].1);
        chosen_red += inc;
        selected.push((s.groups[gi].0, inc / p.excess));
    }
    selected
}

/// The candidates to refit: the selected ones, then the best by predicted reduction up to
/// `o.refit` in all.
pub(super) fn refit_list(cands: &[Candidate], selected: &[(&'static str, f64)], o: &Options) -> Vec<usize> {
    let mut order: Vec<usize> = (0..cands.len()).collect();
    order.sort_by(|&a, &b| cands[b].predicted_reduction.total_cmp(&cands[a].predicted_reduction));
    let mut list: Vec<usize> =
        selected.iter().filter_map(|(e, _)| cands.iter().position(|c| c.effect == *e)).collect();
    for &i in &order {
        if list.len() >= o.refit.max(selected.len()) {
            break;
        }
        if !list.contains(&i) {
            list.push(i);
        }
    }
    list
}
