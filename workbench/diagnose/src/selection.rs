//! Stage 3: ranking by the linearised model. Each effect alone (a score test: the
//! weighted least-squares reduction of the residual its parameters achieve), then a
//! greedy orthogonal forward regression (the incremental reduction given the effects
//! already chosen), then the list of leaders worth a refit on the simulator.

use model_core::Channel;

use super::engine::{Candidate, ChannelChange, FittedParam, Options, MOVES_SHARE};
use super::linalg::{quad, solve_spd, sub_matrix};
use super::preparation::{channel_energies, region_errors, rmse, Prepared};
use super::refit::Fit;
use super::sensitivities::Sensitivities;

/// Bounded linear fit of the parameters `ix`: coefficients (in steps) and the weighted
/// error they remove.
pub(super) fn fit_lin(s: &Sensitivities, ix: &[usize]) -> (Vec<f64>, f64) {
    let th = bounded_solve(s, &s.g, &s.b, ix);
    let red = reduction(s, &s.g, &s.b, ix, &th);
    (th, red.max(0.0))
}

/// The coefficients (in steps) of the parameters `ix` that minimise the linearised
/// error with normal equations `(g, b)` (full `np` layout), clamped to their bounds.
fn bounded_solve(s: &Sensitivities, g: &[f64], b: &[f64], ix: &[usize]) -> Vec<f64> {
    let gs = sub_matrix(g, s.np(), ix);
    let bs: Vec<f64> = ix.iter().map(|&i| b[i]).collect();
    let mut th = solve_spd(&gs, &bs, 1e-9).unwrap_or_else(|| vec![0.0; ix.len()]);
    for (t, &i) in th.iter_mut().zip(ix) {
        let sp = &s.specs[i];
        let v = (s.starts[i] + *t * s.steps[i]).clamp(sp.lower, sp.upper);
        *t = (v - s.starts[i]) / s.steps[i];
    }
    th
}

/// The weighted error removed by coefficients `th` of `ix` under `(g, b)`.
fn reduction(s: &Sensitivities, g: &[f64], b: &[f64], ix: &[usize], th: &[f64]) -> f64 {
    let gs = sub_matrix(g, s.np(), ix);
    2.0 * th.iter().zip(ix).map(|(a, &i)| a * b[i]).sum::<f64>() - quad(&gs, th)
}

/// The error the parameters `ix` remove on data their fit did not see: each held-out
/// fold's reduction with the coefficients fitted on the other folds, summed. An effect
/// that only fits noise, or model error peculiar to one stretch or run, removes nothing
/// (or adds error) there. Without folds, the in-sample reduction.
pub(super) fn held_out(s: &Sensitivities, ix: &[usize]) -> f64 {
    if s.gf.len() < 2 || ix.is_empty() {
        return if ix.is_empty() { 0.0 } else { fit_lin(s, ix).1 };
    }
    s.gf.iter()
        .zip(&s.bf)
        .map(|(gf, bf)| {
            let g: Vec<f64> = s.g.iter().zip(gf).map(|(a, b)| a - b).collect();
            let b: Vec<f64> = s.b.iter().zip(bf).map(|(a, b)| a - b).collect();
            let th = bounded_solve(s, &g, &b, ix);
            reduction(s, gf, bf, ix, &th)
        })
        .sum()
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
                moves: moved_channels(s, channels, ix),
                leaves_structure: None,
                drift: None,
                map_alias: None,
                refused: None,
                held: Vec::new(),
                energy_after: None,
                departure: None,
            };
            (cand, th)
        })
        .unzip()
}

/// The channels that carry at least [`MOVES_SHARE`] of the parameters' weighted
/// sensitivity (`J'WJ`'s diagonal per channel), in channel order.
fn moved_channels(s: &Sensitivities, channels: &[Channel], ix: &[usize]) -> Vec<&'static str> {
    moved(s, ix).into_iter().filter_map(|c| channels.get(c).map(|ch| ch.name())).collect()
}

/// Indices of the channels [`moved_channels`] names.
fn moved(s: &Sensitivities, ix: &[usize]) -> Vec<usize> {
    moved_of(&per_channel(s, ix))
}

/// Indices of the channels carrying at least [`MOVES_SHARE`] of a cause's weighted
/// sensitivity `per` channel: what it moves.
pub(super) fn moved_of(per: &[f64]) -> Vec<usize> {
    let total: f64 = per.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return Vec::new();
    }
    (0..per.len()).filter(|&c| per[c] >= MOVES_SHARE * total).collect()
}

/// The channel that carries the largest share of the parameters' weighted sensitivity.
pub(super) fn main_channel(s: &Sensitivities, ix: &[usize]) -> Option<usize> {
    let per = per_channel(s, ix);
    (0..per.len()).filter(|&c| per[c] > 0.0).max_by(|&a, &b| per[a].total_cmp(&per[b]))
}

/// The parameters' weighted sensitivity (`J'WJ`'s diagonal) per channel.
fn per_channel(s: &Sensitivities, ix: &[usize]) -> Vec<f64> {
    let np = s.np();
    s.gc.iter().map(|g| ix.iter().map(|&i| g.get(i * np + i).copied().unwrap_or(0.0)).sum()).collect()
}

/// The linear fit's values, not yet with an uncertainty (that needs the refit): σ and
/// the interval are NaN (null in the JSON), never a zero-width "95 % interval".
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
                std_data: f64::NAN,
                ci95: (f64::NAN, f64::NAN),
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
            let after2 = (before * before - red_c / p.weights.mean(c, p.idx.len()) / m).max(0.0);
            ChannelChange {
                channel: ch.name(),
                rmse_before: before,
                rmse_predicted: after2.sqrt(),
                rmse_confirmed: None,
            }
        })
        .collect()
}

/// Share of the excess an effect must remove, in the fit and on held-out data, to join
/// the set (in the fit: as the greedy line always required).
const JOIN_IN_SAMPLE: f64 = 0.05;
const JOIN_HELD_OUT: f64 = 0.025;

/// Model selection over sets of effects on the linearised model: forward steps (each
/// adds the effect with the largest incremental reduction, when it removes at least
/// [`JOIN_IN_SAMPLE`] of the excess and at least [`JOIN_HELD_OUT`] on held-out data),
/// then backward elimination (a member whose removal costs less than
/// [`JOIN_HELD_OUT`] on held-out data leaves). `(effect, incremental share of the
/// excess)`, in the order chosen: the set the verdict names.
pub(super) fn greedy(p: &Prepared, s: &Sensitivities, o: &Options) -> Vec<(&'static str, f64)> {
    let params = |gs: &[usize]| group_params(s, gs);
    // A one-channel member that the set leaves above the noise on its channel is taken
    // out and the selection run again without it (see `absorbers`).
    let mut excluded: Vec<usize> = Vec::new();
    let chosen = loop {
        let mut chosen = forward(p, s, o, &excluded);
        backward(s, p, &mut chosen);
        let bad = absorbers(p, s, o, &chosen);
        if bad.is_empty() {
            break chosen;
        }
        excluded.extend(bad);
    };
    let mut out = Vec::with_capacity(chosen.len());
    let mut before = 0.0;
    for k in 0..chosen.len() {
        let red = fit_lin(s, &params(&chosen[..=k])).1;
        out.push((s.groups[chosen[k]].0, (red - before) / p.excess));
        before = red;
    }
    out
}

/// Forward steps over the effect groups not `excluded`.
fn forward(p: &Prepared, s: &Sensitivities, o: &Options, excluded: &[usize]) -> Vec<usize> {
    let params = |gs: &[usize]| group_params(s, gs);
    let mut chosen: Vec<usize> = Vec::new();
    for _ in 0..o.max_selected {
        let base = fit_lin(s, &params(&chosen)).1;
        let mut best: Option<(usize, f64)> = None;
        for gi in (0..s.groups.len()).filter(|g| !chosen.contains(g) && !excluded.contains(g)) {
            let mut with = chosen.clone();
            with.push(gi);
            let inc = fit_lin(s, &params(&with)).1 - base;
            if best.is_none_or(|(_, r)| inc > r) {
                best = Some((gi, inc));
            }
        }
        let Some((gi, inc)) = best else { break };
        let mut with = chosen.clone();
        with.push(gi);
        let validated = held_out(s, &params(&with)) - held_out(s, &params(&chosen));
        if inc < JOIN_IN_SAMPLE * p.excess || validated < JOIN_HELD_OUT * p.excess {
            break;
        }
        chosen = with;
    }
    chosen
}

/// Whether a cause that moves one channel alone, taking its weighted error from
/// `before` to `after` over `samples` fit samples, only absorbs part of what is wrong
/// there: it leaves the channel above `o.noise_like_ratio` of the noise. A sensor's gain
/// or offset (`gauge`: [`is_gauge`]), once fitted, leaves its channel noise-like when it
/// is the fault; one that takes a share of a channel's error is the cheapest description
/// of *any* error there (a wrong map, a missing physical effect) and would be claimed
/// falsely. A cause with a shape of its own — a physical effect the run shows on one
/// channel only (a ramp rate acts on ramps), a sensor's delay or lag (it acts on the
/// transients, which no static map reproduces) — absorbs only when it also removes
/// less than `o.explain_fraction` of the channel's excess: beside a wrong map its
/// channel stays above the noise however right it is.
pub(super) fn absorbs(before: f64, after: f64, samples: usize, gauge: bool, o: &Options) -> bool {
    let m = samples.max(1) as f64;
    let excess = (before - m).max(1e-12);
    after / m > o.noise_like_ratio && (gauge || (before - after) / excess < o.explain_fraction)
}

/// Whether the candidate cause `cause` is a sensor's gain or offset (a static fault of
/// the measurement chain, [`absorbs`]).
pub(super) fn is_gauge(s: &Sensitivities, cause: &str) -> bool {
    s.specs.iter().any(|sp| sp.cause == cause && matches!(sp.effect, "sensor_gain" | "sensor_offset"))
}

/// Members of a set of two or more that move one channel alone (a sensor cause, in the
/// sense of [`Candidate::is_sensor`]) and that [`absorbs`] in the set's linear fit,
/// counting only what the member adds to the rest of the set there: they would bias
/// the rest of the set.
fn absorbers(p: &Prepared, s: &Sensitivities, o: &Options, chosen: &[usize]) -> Vec<usize> {
    if chosen.len() < 2 {
        return Vec::new();
    }
    let before = channel_energies(p, &p.base_sim);
    // Weighted error of channel `c` after the linear fit of the groups `gs`.
    let left = |c: usize, gs: &[usize]| -> f64 {
        let ix = group_params(s, gs);
        let (th, _) = fit_lin(s, &ix);
        let gs = sub_matrix(&s.gc[c], s.np(), &ix);
        let bs: Vec<f64> = ix.iter().map(|&i| s.bc[c][i]).collect();
        before[c] - (2.0 * th.iter().zip(&bs).map(|(a, x)| a * x).sum::<f64>() - quad(&gs, &th))
    };
    chosen
        .iter()
        .copied()
        .filter(|&g| {
            let Some(c) = one_channel(s, &s.groups[g].1) else { return false };
            let rest: Vec<usize> = chosen.iter().copied().filter(|&x| x != g).collect();
            absorbs(left(c, &rest), left(c, chosen), p.idx.len(), is_gauge(s, s.groups[g].0), o)
        })
        .collect()
}

/// The channel the parameters `ix` move, when they move one alone.
fn one_channel(s: &Sensitivities, ix: &[usize]) -> Option<usize> {
    match moved(s, ix).as_slice() {
        [c] => Some(*c),
        _ => None,
    }
}

/// The parameter indices of the effect groups `gs`.
pub(super) fn group_params(s: &Sensitivities, gs: &[usize]) -> Vec<usize> {
    gs.iter().flat_map(|&g| s.groups[g].1.iter().copied()).collect()
}

/// Backward elimination: while some member of `chosen` costs less than
/// [`JOIN_HELD_OUT`] of the excess on held-out data when left out, drop the cheapest.
fn backward(s: &Sensitivities, p: &Prepared, chosen: &mut Vec<usize>) {
    let params = |gs: &[usize]| group_params(s, gs);
    while chosen.len() > 1 {
        let all = held_out(s, &params(chosen));
        let cheapest = (0..chosen.len())
            .map(|m| {
                let rest: Vec<usize> =
                    chosen.iter().enumerate().filter(|(i, _)| *i != m).map(|(_, g)| *g).collect();
                (m, all - held_out(s, &params(&rest)))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match cheapest {
            Some((m, cost)) if cost < JOIN_HELD_OUT * p.excess => {
                chosen.remove(m);
            }
            _ => break,
        }
    }
}

/// The next `o.refit` candidates by predicted reduction that have no refit in `done`
/// and predict to remove something: the leaders' successors when none of them counts.
pub(super) fn next_leaders(cands: &[Candidate], done: &[(usize, Fit)], o: &Options) -> Vec<usize> {
    let mut order: Vec<usize> = (0..cands.len())
        .filter(|i| cands[*i].predicted_reduction > 0.0 && !done.iter().any(|(d, _)| d == i))
        .collect();
    order.sort_by(|&a, &b| cands[b].predicted_reduction.total_cmp(&cands[a].predicted_reduction));
    order.truncate(o.refit);
    order
}

/// The candidates without a refit whose linear prediction comes within
/// [`RUNNER_UP`] of what the counting lead removes on the simulator: a linearisation at
/// the neutral value sees a fraction of a strongly nonlinear effect (a 0.09 s controller
/// delay predicted at 46.5 % beside a SuTMotorEnc lag confirmed at 48.7 %, tuning case
/// 500,877), so the lead is named only against their refits.
pub(super) fn close_runners_up(cands: &[Candidate], done: &[(usize, Fit)], lead: f64) -> Vec<usize> {
    (0..cands.len())
        .filter(|i| !done.iter().any(|(d, _)| d == i))
        .filter(|&i| cands[i].predicted_reduction > 0.0 && cands[i].predicted_reduction >= RUNNER_UP * lead)
        .collect()
}

/// Share of the lead's confirmed reduction a candidate's linear prediction must reach
/// to be refitted beside it ([`close_runners_up`]). ASSUMED: 0.8.
const RUNNER_UP: f64 = 0.8;

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

#[cfg(test)]
mod tests {
    use super::*;

    /// Beside a lead confirmed at 48.7 % (tuning 500,877's SuTMotorEnc lag), a candidate
    /// predicted at 46.5 % (the controller delay) is refitted and one at 30 % is not (it
    /// is beside a lead at 36 %); one already refitted is not, however close, nor one that
    /// predicts to remove nothing when the lead removes nothing either.
    #[test]
    fn only_unrefitted_candidates_close_to_the_lead_are_refitted() {
        let cands = [
            Candidate::named("sensor_lag", 0.50),
            Candidate::named("controller_delay", 0.465),
            Candidate::named("supply_resistance", 0.30),
            Candidate::named("sensor_delay", 0.49),
        ];
        let done =
            [(0, Fit::fixed(vec![0.03], Vec::new(), 1.0)), (3, Fit::fixed(vec![0.03], Vec::new(), 1.0))];
        assert_eq!(close_runners_up(&cands, &done, 0.487), vec![1]);
        assert_eq!(close_runners_up(&cands, &done, 0.36), vec![1, 2]);
        let nothing = [Candidate::named("sensor_lag", 0.0), Candidate::named("controller_delay", 0.0)];
        assert!(close_runners_up(&nothing, &[], 0.0).is_empty());
    }
}
