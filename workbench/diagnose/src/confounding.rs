//! Stage 6: confounding. Candidates whose predicted residual changes nearly coincide on
//! this run cannot be told apart by it; they are reported as a group, with the built-in
//! profile (simulated, not guessed) on which their effects differ most.

use model_core::Effects;

use super::engine::{Candidate, ConfoundedGroup, Options, ProbeRate, ProfileProbe};
use super::library::{with_values, ParamSpec};
use super::refit::Fit;
use super::sensitivities::Sensitivities;

/// Everything the confounding test looks at.
pub(super) struct Leaders<'a> {
    /// Candidates in library order (as `lin` and the refits index them).
    pub cands: &'a [Candidate],
    /// Linear coefficients (in steps) of each candidate.
    pub lin: &'a [Vec<f64>],
    /// Refits, by candidate index.
    pub fits: &'a [(usize, Fit)],
    /// The ranking, best first.
    pub ranking: &'a [Candidate],
}

/// The significant candidates whose predicted change has a |cosine| of at least
/// `o.confounded_cosine` with the leader's and that explain at least 70 % as much, as one
/// group headed by the leader (empty if the leader is alone or not significant).
pub(super) fn confounded_groups(
    l: &Leaders,
    s: &Sensitivities,
    o: &Options,
    weights: &[f64],
    probe: Option<&dyn ProfileProbe>,
) -> Vec<ConfoundedGroup> {
    let Some(lead) = l.ranking.first().filter(|c| c.significant) else { return Vec::new() };
    let li = l.cands.iter().position(|c| c.effect == lead.effect).unwrap_or(0);
    let va = shape(s, l.lin, li);
    let mut members = vec![lead.effect];
    let mut worst_cos: f64 = 1.0;
    for (ci, c) in l.cands.iter().enumerate() {
        if ci == li || !c.significant || c.reduction() < 0.7 * lead.reduction() {
            continue;
        }
        let vb = shape(s, l.lin, ci);
        let cos = g_dot(s, &va, &vb) / (g_dot(s, &va, &va) * g_dot(s, &vb, &vb)).sqrt().max(1e-300);
        if cos.abs() >= o.confounded_cosine {
            members.push(c.effect);
            worst_cos = worst_cos.min(cos.abs());
        }
    }
    if members.len() < 2 {
        return Vec::new();
    }
    let separating = probe.and_then(|pr| separating_profile(pr, o, &s.specs, &members, l, weights));
    vec![ConfoundedGroup { effects: members, cosine: worst_cos, separating_profile: separating }]
}

/// Candidate `ci`'s linear coefficients as a vector over all parameters.
fn shape(s: &Sensitivities, lin: &[Vec<f64>], ci: usize) -> Vec<f64> {
    let mut v = vec![0.0; s.np()];
    for (t, &i) in lin[ci].iter().zip(&s.groups[ci].1) {
        v[i] = *t;
    }
    v
}

/// `a' G c`: the weighted inner product of the output changes `a` and `c` predict.
fn g_dot(s: &Sensitivities, a: &[f64], c: &[f64]) -> f64 {
    let np = s.np();
    let mut sum = 0.0;
    for (i, &ai) in a.iter().enumerate() {
        if ai == 0.0 {
            continue;
        }
        for (gij, cj) in s.g[i * np..(i + 1) * np].iter().zip(c) {
            sum += ai * gij * cj;
        }
    }
    sum
}

/// Among the built-in profiles the probe offers, the one where the first two members'
/// simulated effects are least alike (smallest |cosine| of their output changes), ranked
/// at the probe's coarse step and named with its cosine at the bench's rate.
fn separating_profile(
    probe: &dyn ProfileProbe,
    o: &Options,
    specs: &[ParamSpec],
    members: &[&'static str],
    l: &Leaders,
    w: &[f64],
) -> Option<(String, f64)> {
    use rayon::prelude::*;
    let (a, b) = (member_effects(o, specs, l, members[0]), member_effects(o, specs, l, members[1]));
    let cosine = |i: usize, rate: ProbeRate| {
        let runs: Vec<Option<Vec<Vec<f32>>>> =
            [&o.base, &a, &b].par_iter().map(|fx| probe.run(i, fx, rate)).collect();
        match runs.as_slice() {
            [Some(base), Some(sa), Some(sb)] => change_cosine(base, sa, sb, w),
            _ => None,
        }
    };
    // Each profile's three runs are independent of every other's: on the pool, and the
    // best chosen in profile order (ties go to the first, as a serial search would).
    let cosines: Vec<Option<f64>> =
        (0..probe.count()).into_par_iter().map(|i| cosine(i, ProbeRate::Screen)).collect();
    let mut best: Option<(usize, f64)> = None;
    for (i, cos) in cosines.into_iter().enumerate() {
        let Some(cos) = cos else { continue };
        if best.is_none_or(|(_, c)| cos < c) {
            best = Some((i, cos));
        }
    }
    best.map(|(i, screened)| (probe.name(i), cosine(i, ProbeRate::Bench).unwrap_or(screened)))
}

/// A member at its fitted values (its linear estimate if not refitted, a step if absent).
fn member_effects(o: &Options, specs: &[ParamSpec], l: &Leaders, effect: &str) -> Effects {
    let c = l.cands.iter().find(|c| c.effect == effect);
    let sp: Vec<&ParamSpec> = specs.iter().filter(|s| s.cause == effect).collect();
    let vals: Vec<f64> = match (c, l.fits.iter().find(|(ci, _)| l.cands[*ci].effect == effect)) {
        (_, Some((_, f))) => f.values.clone(),
        (Some(c), None) => c.params.iter().map(|p| p.value).collect(),
        _ => sp.iter().map(|s| s.neutral + s.delta).collect(),
    };
    with_values(&o.base, &sp, &vals)
}

/// |cosine| between the weighted output changes `sa - base` and `sb - base`; `None` when
/// either change stays within the noise (the profile separates nothing then).
fn change_cosine(base: &[Vec<f32>], sa: &[Vec<f32>], sb: &[Vec<f32>], w: &[f64]) -> Option<f64> {
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (c, wc) in w.iter().enumerate().take(base.len()) {
        let (Some(ya), Some(yb)) = (sa.get(c), sb.get(c)) else { return None };
        for ((b0, a), b) in base[c].iter().zip(ya).zip(yb) {
            let da = f64::from(a - b0);
            let db = f64::from(b - b0);
            ab += wc * da * db;
            aa += wc * da * da;
            bb += wc * db * db;
        }
    }
    let samples = base.first().map_or(0, Vec::len) as f64;
    if aa < 0.01 * samples || bb < 0.01 * samples {
        return None;
    }
    Some((ab / (aa * bb).sqrt().max(1e-300)).abs())
}
