//! Stage 4: confirmation on the real (nonlinear) simulator. Levenberg–Marquardt from the
//! linear estimate; for one-parameter effects a coarse grid before and a fine profile
//! scan after, since a rugged objective (backlash events, a clipping limit) hides narrow
//! basins from a local search. The error a refit removes is measured, not predicted.

use model_core::chain::{delay_slots, SENSOR_DELAY_CAPACITY};
use model_core::Effects;

/// The effect whose parameters share the model's delay line ([`Problem::upper`]).
const SENSOR_DELAY: &str = "sensor_delay";

use super::engine::{Candidate, Options, Twin};
use super::library::{with_values, ParamSpec};
use super::linalg::solve_spd;
use super::preparation::{energy, region_errors, rmse, run_all, Prepared};
use super::sensitivities::{check_shape, Sensitivities};
use super::uncertainty::Spread;

/// Most Levenberg–Marquardt iterations (each: one Jacobian, up to 2 × [`DAMPING_PAIRS`] steps).
const MAX_ITERATIONS: usize = 8;
/// Damping increases tried per iteration before giving up, two at a time
/// ([`damped_step`]): six tries.
const DAMPING_PAIRS: usize = 3;

/// A refit on the simulator.
pub(super) struct Fit {
    /// Fitted parameter values.
    pub values: Vec<f64>,
    /// Simulated channels at `values`.
    pub sim: Vec<Vec<f32>>,
    /// `jac[parameter][channel][fit sample]`: output change per unit of the parameter.
    pub jac: Vec<Vec<Vec<f64>>>,
    /// Weighted squared error at `values`.
    pub energy: f64,
    /// One-parameter fits: (value, energy) of a fine scan around the optimum (of the
    /// first parameter, with the others at their values then).
    pub profile: Vec<(f64, f64)>,
    /// The effects already in the model refitted beside the candidate's own parameters
    /// ([`with_held`]); `None` for a refit of the candidate alone.
    pub held: Option<Beside>,
}

/// What a refit beside the held effects refitted, and what it is credited from.
pub(super) struct Beside {
    /// Indices into [`Sensitivities::specs`]; their values follow the own ones in
    /// [`Fit::values`].
    pub ix: Vec<usize>,
    /// The energy the held values' own refit leaves ([`Held`]): what refitting them
    /// removes anyway is not the candidate's.
    pub from: f64,
}

impl Fit {
    /// The held parameters refitted beside the own ones (none for a refit alone).
    pub(super) fn held_ix(&self) -> &[usize] {
        self.held.as_ref().map_or(&[], |b| &b.ix)
    }

    /// The error the refit removes as credited to its candidate: from the current
    /// model's `e0`, or beside the held effects from their own refit.
    pub(super) fn credit(&self, e0: f64) -> f64 {
        self.held.as_ref().map_or(e0, |b| b.from) - self.energy
    }

    /// A refit at `values` whose simulation is `sim` and error `energy`, with no
    /// Jacobian nor profile (for tests of what is judged on a refit).
    #[cfg(test)]
    pub(super) fn fixed(values: Vec<f64>, sim: Vec<Vec<f32>>, energy: f64) -> Fit {
        Fit { values, sim, jac: Vec::new(), energy, profile: Vec::new(), held: None }
    }
}

/// The bounded parameters of one refit, and how to simulate them.
struct Problem<'a> {
    twin: &'a dyn Twin,
    p: &'a Prepared,
    o: &'a Options,
    specs: &'a [&'a ParamSpec],
}

impl Problem<'_> {
    /// Into the declared ranges, and every sensor delay into what the shared delay line
    /// leaves it ([`Problem::upper`]) beside the ones before it, so that together they fit.
    fn clamp(&self, v: &mut [f64]) {
        for (x, s) in v.iter_mut().zip(self.specs) {
            *x = x.clamp(s.lower, s.upper);
        }
        for i in (0..v.len()).filter(|&i| self.specs[i].effect == SENSOR_DELAY) {
            let mut before = v.to_vec();
            for (x, s) in before.iter_mut().zip(self.specs).skip(i + 1) {
                *x = s.neutral;
            }
            v[i] = v[i].min(self.upper(i, &before));
        }
    }

    /// The largest value parameter `i` may take at `theta`: its declared upper end, and
    /// for a sensor delay at most what the model's delay line holds beside every other
    /// channel's delay in the effects run — the line holds
    /// [`SENSOR_DELAY_CAPACITY`] steps for all channels together and the model cuts the
    /// rest, so beyond it a refit saw a flat objective (a 0.1 s skew of I_DPU 2.7 beside a
    /// 40 ms SuTMotorEnc delay fitted 0.1 s with σ undetermined, and a lag was named).
    fn upper(&self, i: usize, theta: &[f64]) -> f64 {
        let s = self.specs[i];
        if s.effect != SENSOR_DELAY {
            return s.upper;
        }
        let mut others = theta.to_vec();
        others[i] = s.neutral;
        let dt = self.twin.dt_s();
        let taken: u64 = self.effects(&others).sensor_delay_s.iter().map(|d| delay_slots(*d, dt)).sum();
        let room = (SENSOR_DELAY_CAPACITY as u64).saturating_sub(taken);
        s.upper.min(room as f64 * dt)
    }

    /// Whether parameter `i`'s slope at `theta` is a central difference of `h`: for one
    /// the model is linear in between whole steps (a sensor delay), whose objective
    /// kinks at every whole step, where a one-sided difference sees only its side: at a
    /// step edge the forward slope moves the samples after it, not the ones a shorter
    /// delay would fix; where there is room below.
    fn central(&self, i: usize, theta: &[f64], h: f64) -> bool {
        let s = self.specs[i];
        h > 0.0 && s.slope_step(self.twin.dt_s()).is_some() && theta[i] - h >= s.lower
    }

    fn effects(&self, theta: &[f64]) -> Effects {
        with_values(&self.o.base, self.specs, theta)
    }

    /// Simulate `theta`; `None` if the twin fails or returns the wrong shape.
    fn run(&self, theta: &[f64]) -> Option<Vec<Vec<f32>>> {
        let y = self.twin.run_every(&self.effects(theta), self.p.stride).ok()?;
        check_shape(self.p, &y).ok().map(|()| y)
    }

    /// Simulate each of `thetas` in parallel.
    fn run_many(&self, thetas: &[Vec<f64>]) -> Vec<Option<Vec<Vec<f32>>>> {
        let jobs: Vec<Effects> = thetas.iter().map(|t| self.effects(t)).collect();
        run_all(self.twin, self.p, &jobs, self.o)
            .into_iter()
            .map(|r| r.ok().filter(|y| check_shape(self.p, y).is_ok()))
            .collect()
    }

    /// Forward-difference step of parameter `i` at `theta`: half the sensitivity step
    /// (closer to linear), or the span over which the model is linear in it
    /// ([`ParamSpec::slope_step`]); backwards at the upper bound.
    fn step(&self, i: usize, theta: &[f64]) -> f64 {
        let s = self.specs[i];
        let h = s.slope_step(self.twin.dt_s()).unwrap_or(0.5 * s.delta);
        if theta[i] + h <= self.upper(i, theta) {
            h
        } else {
            -h
        }
    }
}

/// The current point of the search.
struct State {
    theta: Vec<f64>,
    sim: Vec<Vec<f32>>,
    energy: f64,
}

/// Levenberg–Marquardt on the simulator for the parameters `specs`, from `start`.
/// `None` if the simulator fails at the start or while taking the Jacobian.
pub(super) fn refit(
    twin: &dyn Twin,
    p: &Prepared,
    o: &Options,
    specs: &[&ParamSpec],
    start: &[f64],
) -> Option<Fit> {
    let pb = Problem { twin, p, o, specs };
    let mut theta = start.to_vec();
    pb.clamp(&mut theta);
    let sim = pb.run(&theta)?;
    let mut st = State { energy: energy(p, &sim), theta, sim };
    if let [s0] = specs {
        coarse_grid(&pb, s0, &mut st);
    }
    let mut lambda = 1e-3;
    let mut jac = Vec::new();
    for _ in 0..MAX_ITERATIONS {
        jac = jacobian(&pb, &st)?;
        let (g, b) = normal_equations(p, &jac, &st.sim);
        if !damped_step(&pb, &g, &b, &mut lambda, &mut st)? {
            break;
        }
    }
    let mut fit =
        Fit { values: st.theta, sim: st.sim, jac, energy: st.energy, profile: Vec::new(), held: None };
    if let [s0] = specs {
        profile_scan(&pb, s0, &mut fit);
    }
    Some(fit)
}

/// Candidate `ci` (an effect group of `s`) refitted alone, from its linear estimate.
pub(super) fn refit_alone(
    twin: &dyn Twin,
    p: &Prepared,
    o: &Options,
    s: &Sensitivities,
    cands: &[Candidate],
    ci: usize,
) -> Option<Fit> {
    let specs: Vec<&ParamSpec> = s.groups[ci].1.iter().map(|&i| &s.specs[i]).collect();
    let start: Vec<f64> = cands.get(ci)?.params.iter().map(|f| f.value).collect();
    refit(twin, p, o, &specs, &start)
}

/// The library parameters the model already holds away from their neutral values (the
/// effects earlier rounds added, or the user's), and their refit together from their
/// current values: what their values alone can still remove.
pub(super) struct Held {
    /// Indices into [`Sensitivities::specs`].
    pub ix: Vec<usize>,
    /// Their joint refit (`None`: nothing held, or the refit failed).
    pub fit: Option<Fit>,
}

impl Held {
    pub(super) fn refit(twin: &dyn Twin, p: &Prepared, s: &Sensitivities, o: &Options) -> Held {
        let ix: Vec<usize> = (0..s.specs.len()).filter(|&i| s.specs[i].off_neutral(s.starts[i])).collect();
        let specs: Vec<&ParamSpec> = ix.iter().map(|&i| &s.specs[i]).collect();
        let start: Vec<f64> = ix.iter().map(|&i| s.starts[i]).collect();
        let fit = if ix.is_empty() { None } else { refit(twin, p, o, &specs, &start) };
        Held { ix, fit }
    }
}

/// `fit` of candidate `ci` (refitted alone) or, when it credits the candidate with more,
/// its refit jointly with the effects already in the model (`held`), from their current
/// values: the refit of the whole set at each stage. A value an
/// earlier round fitted without the candidate is biased by its absence (a connector
/// resistance fitted before a differential friction was known takes part of the
/// friction's power draw), and the true candidate then looks harmful against it.
///
/// The joint refit is credited only with what it removes beyond the held values refitted
/// alone: what refitting them removes anyway is not the candidate's. The alone fit is
/// credited with what it removes from the current model. A candidate that is itself held
/// is refitted alone, as before (and so is a one-channel cause: `confirm_leaders`). The
/// profile of a one-parameter fit is kept, shifted to the joint minimum.
pub(super) fn with_held(
    twin: &dyn Twin,
    (p, o, s): (&Prepared, &Options, &Sensitivities),
    ci: usize,
    held: &Held,
    fit: Fit,
) -> Fit {
    let own = &s.groups[ci].1;
    let (Some(h), held) = (held.fit.as_ref(), &held.ix) else { return fit };
    if own.iter().any(|i| held.contains(i)) || fit.values.len() != own.len() {
        return fit;
    }
    let specs: Vec<&ParamSpec> = own.iter().chain(held).map(|&i| &s.specs[i]).collect();
    let start: Vec<f64> = fit.values.iter().copied().chain(held.iter().map(|&i| s.starts[i])).collect();
    match refit(twin, p, o, &specs, &start) {
        Some(j) if h.energy - j.energy > p.e0 - fit.energy => {
            let shift = j.energy - fit.energy;
            let profile = fit.profile.iter().map(|(v, e)| (*v, e + shift)).collect();
            Fit { profile, held: Some(Beside { ix: held.to_vec(), from: h.energy }), ..j }
        }
        _ => fit,
    }
}

/// Intervals of a one-parameter refit's coarse grid ([`coarse_grid`], one simulation
/// per point) and of its profile scan ([`profile_scan`]). Half of the 15 and 24 they
/// were: the refits are the largest share of a diagnosis beside wrong maps, and on
/// proof 19's 200 cases the halved grids gave the same verdict, rounds, claims and
/// findings in every case (three differ only in an interval's bounds or a refusal's
/// reason), 8 % less time on the perturbed benchmark rows.
const COARSE_STEPS: u32 = 8;
const PROFILE_STEPS: u32 = 12;

/// One parameter: a coarse grid over its bounds (logarithmic over a wide positive
/// range), so that a non-smooth or strongly nonlinear response cannot trap the local
/// search near the linear estimate. Moves `st` to the best point.
fn coarse_grid(pb: &Problem, s0: &ParamSpec, st: &mut State) {
    let (lo, hi) = (s0.lower, pb.upper(0, &st.theta));
    let n = f64::from(COARSE_STEPS);
    let grid: Vec<f64> = if lo > 0.0 && hi / lo > 20.0 {
        (0..=COARSE_STEPS).map(|i| lo * (hi / lo).powf(f64::from(i) / n)).collect()
    } else {
        (0..=COARSE_STEPS).map(|i| lo + (hi - lo) * f64::from(i) / n).collect()
    };
    let thetas: Vec<Vec<f64>> = grid.iter().map(|v| vec![*v]).collect();
    let runs = pb.run_many(&thetas);
    for (theta, y) in thetas.into_iter().zip(runs) {
        let Some(y) = y else { continue };
        let ey = energy(pb.p, &y);
        if ey < st.energy {
            *st = State { theta, sim: y, energy: ey };
        }
    }
}

/// `jac[parameter][channel][fit sample]` by forward differences at `st`, or central ones
/// for a parameter the model is linear in between whole steps ([`Problem::central`]).
fn jacobian(pb: &Problem, st: &State) -> Option<Vec<Vec<Vec<f64>>>> {
    let n = pb.specs.len();
    let h: Vec<f64> = (0..n).map(|i| pb.step(i, &st.theta)).collect();
    let shifted = |i: usize, by: f64| {
        let mut t = st.theta.clone();
        t[i] += by;
        t
    };
    // A parameter the twin never reads on these runs leaves the current point's run.
    let unread = |i: usize| pb.p.unread.param(pb.specs[i]);
    let read: Vec<usize> = (0..n).filter(|&i| !unread(i)).collect();
    let central: Vec<usize> = read.iter().copied().filter(|&i| pb.central(i, &st.theta, h[i])).collect();
    let thetas: Vec<Vec<f64>> =
        read.iter().map(|&i| shifted(i, h[i])).chain(central.iter().map(|&i| shifted(i, -h[i]))).collect();
    let mut sims = pb.run_many(&thetas).into_iter();
    let mut up: Vec<Option<Vec<Vec<f32>>>> = vec![Some(st.sim.clone()); n];
    for &i in &read {
        up[i] = sims.next().flatten();
    }
    let mut down: Vec<Option<Vec<Vec<f32>>>> = vec![None; n];
    for &i in &central {
        down[i] = Some(sims.next().flatten()?);
    }
    let mut jac = Vec::with_capacity(n);
    for (i, (y, d)) in up.into_iter().zip(down).enumerate() {
        let y = y?;
        let (base, span) = match &d {
            Some(d) => (d, 2.0 * h[i]),
            None => (&st.sim, h[i]),
        };
        jac.push(
            y.iter()
                .zip(base)
                .map(|(a, b)| pb.p.idx.iter().map(|&t| (f64::from(a[t]) - f64::from(b[t])) / span).collect())
                .collect(),
        );
    }
    Some(jac)
}

/// `J'WJ` (row-major) and `J'W r` of the residual of `sim`.
fn normal_equations(p: &Prepared, jac: &[Vec<Vec<f64>>], sim: &[Vec<f32>]) -> (Vec<f64>, Vec<f64>) {
    let n = jac.len();
    let mut g = vec![0.0; n * n];
    let mut b = vec![0.0; n];
    for c in 0..p.weights.channels() {
        for (k, &t) in p.idx.iter().enumerate() {
            let (w, r) = (p.weights.at(c, t), p.meas[c][t] - f64::from(sim[c][t]));
            for i in 0..n {
                let ji = jac[i][c][k];
                b[i] += w * ji * r;
                for j in 0..=i {
                    g[i * n + j] += w * ji * jac[j][c][k];
                }
            }
        }
    }
    for i in 0..n {
        for j in 0..i {
            g[j * n + i] = g[i * n + j];
        }
    }
    (g, b)
}

/// Try steps of increasing damping until one lowers the error; move `st` there.
/// `Some(true)` if it moved by more than a relative 1e-6 of the error (worth another
/// iteration), `None` if the damped system cannot be solved.
///
/// The system is solved in each parameter's own scale (its sensitivity step), so the
/// solver's ridge, relative to the largest diagonal, does not swamp a parameter whose
/// unit makes its information small (a stiffness in N m/rad beside a resistance in Ω).
///
/// Two dampings are simulated side by side (most tries fail: a refit starts from its
/// grid's or its linear fit's best point, and ends on six failures), then judged in turn
/// as one by one: the same steps, the same result.
fn damped_step(pb: &Problem, g: &[f64], b: &[f64], lambda: &mut f64, st: &mut State) -> Option<bool> {
    let scale: Vec<f64> = pb.specs.iter().map(|s| s.delta).collect();
    let (g, b) = in_scale(g, b, &scale);
    let candidate = |lambda: f64| -> Option<Vec<f64>> {
        let n = b.len();
        let mut gl = g.clone();
        for i in 0..n {
            gl[i * n + i] *= 1.0 + lambda;
        }
        let step = solve_spd(&gl, &b, 1e-12)?;
        let mut cand: Vec<f64> =
            st.theta.iter().zip(step.iter().zip(&scale)).map(|(a, (d, h))| a + d * h).collect();
        pb.clamp(&mut cand);
        Some(cand)
    };
    for _ in 0..DAMPING_PAIRS {
        let first = candidate(*lambda)?;
        let second = candidate(*lambda * 10.0);
        let (s1, s2) = rayon::join(|| pb.run(&first), || second.as_ref().and_then(|c| pb.run(c)));
        for (cand, sim) in [(Some(first), s1), (second, s2)] {
            let cand = cand?;
            let Some(sim) = sim else { return Some(false) };
            let e2 = energy(pb.p, &sim);
            if std::env::var_os("SIMROD_DIAG_DEBUG").is_some() {
                eprintln!(
                    "  LM {}: theta {:?} e {:.3} -> cand {cand:?} e2 {e2:.3} lambda {:e}",
                    pb.specs[0].effect, st.theta, st.energy, *lambda
                );
            }
            if e2 < st.energy {
                let rel = (st.energy - e2) / st.energy.max(1e-300);
                *st = State { theta: cand, sim, energy: e2 };
                *lambda = (*lambda * 0.3).max(1e-9);
                return Some(rel > 1e-6);
            }
            *lambda *= 10.0;
        }
    }
    Some(false)
}

/// The normal equations `g` (row-major), `b` for parameters measured in units of
/// `scale` (`θ = scale · u`): `D g D` and `D b` with `D = diag(scale)`.
pub(super) fn in_scale(g: &[f64], b: &[f64], scale: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = scale.len();
    let gs = (0..n * n).map(|k| g[k] * scale[k / n] * scale[k % n]).collect();
    let bs = b.iter().zip(scale).map(|(x, h)| x * h).collect();
    (gs, bs)
}

/// Fine scan around a one-parameter optimum (±25 % of its distance from the neutral
/// value, at least ± one sensitivity step): moves to any better point and keeps the scan
/// for a profile interval. Measured from the neutral value, not from 0: a gain of 1.02
/// scanned ±25 % of 1.02 had a grid of 0.02, as wide as the effect, and an interval no
/// narrower than the grid.
fn profile_scan(pb: &Problem, s0: &ParamSpec, fit: &mut Fit) {
    let v0 = fit.values[0];
    let half = (0.25 * (v0 - s0.neutral).abs()).max(s0.delta);
    let (lo, hi) = ((v0 - half).max(s0.lower), (v0 + half).min(pb.upper(0, &fit.values)));
    let n = f64::from(PROFILE_STEPS);
    let grid: Vec<Vec<f64>> = (0..=PROFILE_STEPS).map(|i| vec![lo + (hi - lo) * f64::from(i) / n]).collect();
    let mut prof = vec![(v0, fit.energy)];
    for (v, y) in grid.iter().zip(pb.run_many(&grid)) {
        let Some(y) = y else { continue };
        let e = energy(pb.p, &y);
        prof.push((v[0], e));
        if e < fit.energy {
            fit.energy = e;
            fit.values = v.clone();
            fit.sim = y;
        }
    }
    prof.sort_by(|a, b| a.0.total_cmp(&b.0));
    fit.profile = prof;
}

/// Whether a fitted value `v` of `s` moved from its `start` by more than 2 σ (never with
/// an undetermined σ): what makes a refit significant.
pub(super) fn moved(v: f64, start: f64, sd: f64, s: &ParamSpec) -> bool {
    sd.is_finite() && (v - start).abs() > 2.0 * sd && (v - start).abs() > 1e-6 * s.delta
}

/// Write a refit into its candidate: values and their uncertainty (`spread`'s reported
/// σ), the reduction measured on the simulator, per-channel and per-region errors.
/// Significant: some parameter moved from its start by more than 2 of `spread`'s σ for
/// that test (never with an undetermined σ).
/// A refit beside the held effects is credited with what it removes beyond their own
/// refit ([`Fit::credit`]).
pub(super) fn confirm(cand: &mut Candidate, fit: &Fit, spread: &Spread, specs: &[&ParamSpec], p: &Prepared) {
    cand.confirmed_reduction = Some((fit.credit(p.e0) / p.excess).clamp(0.0, 1.0));
    cand.energy_after = Some(fit.energy);
    cand.significant = false;
    let sds = spread.std.iter().zip(spread.reported.iter().zip(&spread.data));
    for ((fp, &v), ((sd, (shown, data)), s)) in cand.params.iter_mut().zip(&fit.values).zip(sds.zip(specs)) {
        fp.value = v;
        fp.std = *shown;
        fp.std_data = *data;
        fp.ci95 = s.ci95(v, *shown);
        cand.significant |= moved(v, fp.start, *sd, s);
    }
    for (c, ch) in cand.channels.iter_mut().enumerate() {
        let s: Vec<f64> = fit.sim[c].iter().map(|v| f64::from(*v)).collect();
        ch.rmse_confirmed = Some(rmse(&p.meas[c], &s, &p.idx));
    }
    let confirmed =
        region_errors(p, &p.regions, |c, k| f64::from(fit.sim[c][p.idx[k]]) - p.base[c][p.idx[k]]);
    for (rc, conf) in cand.regions.iter_mut().zip(confirmed) {
        rc.confirmed = Some(conf.predicted);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::Channel;

    /// `y(t) = A exp(-k t)`, with `A` and `k` carried in the differential-friction slots
    /// of the effects (any two library parameters would do).
    struct Decay {
        channels: Vec<Channel>,
        n: usize,
    }

    const DT: f64 = 0.01;

    fn param(fx: &Effects, name: &str) -> f64 {
        fx.get("differential_friction", name).ok().flatten().map_or(0.0, f64::from)
    }

    impl Twin for Decay {
        fn channels(&self) -> &[Channel] {
            &self.channels
        }
        fn samples(&self) -> usize {
            self.n
        }
        fn dt_s(&self) -> f64 {
            DT
        }
        fn run(&self, fx: &Effects) -> Result<Vec<Vec<f32>>, String> {
            let (a, k) = (param(fx, "coulomb_nm"), param(fx, "viscous_nm_s_per_rad"));
            Ok(vec![(0..self.n).map(|i| (a * (-k * i as f64 * DT).exp()) as f32).collect()])
        }
    }

    fn spec(param: &'static str, upper: f64) -> ParamSpec {
        ParamSpec {
            effect: "differential_friction",
            param,
            cause: "differential_friction",
            neutral: 0.0,
            delta: 0.01,
            lower: 0.0,
            upper,
            unit: "-",
            step_bias: model_core::effects::Step::Abs(0.0),
            step_bias_side: model_core::effects::Side::Either,
        }
    }

    /// Exact data from `A = 5`, `k = 1.5` (both exact in `f32`, the effects' precision).
    fn setup(n: usize) -> (Decay, Prepared) {
        let twin = Decay { channels: vec![Channel::Throttle], n };
        let meas = vec![(0..n).map(|i| 5.0 * (-1.5 * i as f64 * DT).exp()).collect::<Vec<f64>>()];
        let base_sim = vec![vec![0.0f32; n]];
        let p = Prepared {
            meas,
            base: vec![vec![0.0; n]],
            base_sim,
            weights: crate::preparation::Weights::uniform([1.0]),
            noise: vec![("Throttle", 1.0)],
            idx: (0..n).collect(),
            stride: 1,
            folds: vec![0; n],
            runs: 1,
            e_noise: n as f64,
            excess: 1.0,
            ..Prepared::default()
        };
        (twin, p)
    }

    /// The model's delay line holds 128 steps for all channels together (1.28 s at this
    /// twin's 10 ms): beside 1.20 s already on SuTMotorEnc, I_DPU 2.7's delay may go to
    /// 0.08 s, not its declared 0.1 s; the Jacobian steps back from there; a second
    /// delay in the same refit gets what is left (nothing), so together they fit.
    #[test]
    fn a_sensor_delay_is_searched_only_as_far_as_the_delay_line_holds() {
        let (twin, p) = setup(10);
        let mut base = Effects::NONE;
        base.sensor_delay_s[1] = 1.2;
        let o = Options { base, ..Options::default() };
        let lib = crate::library::library(&o.params);
        let spec =
            |q: &str| lib.iter().find(|s| s.effect == "sensor_delay" && s.param == q).cloned().unwrap();
        let (dpu, vdc) = (spec("i_dpu_2_7"), spec("v_dc"));
        assert_eq!(dpu.upper, 0.1);
        let specs = [&dpu, &vdc];
        let pb = Problem { twin: &twin, p: &p, o: &o, specs: &specs };
        let mut theta = vec![0.1, 0.1];
        pb.clamp(&mut theta);
        assert!((theta[0] - 0.08).abs() < 1e-12 && theta[1] == 0.0, "{theta:?}");
        assert!(pb.effects(&theta).check_delays(10_000).is_ok());
        assert!(pb.step(0, &[0.075, 0.0]) < 0.0 && pb.step(0, &[0.05, 0.0]) > 0.0);
        // Without the other delay the declared range holds.
        let free = Options::default();
        let pb = Problem { twin: &twin, p: &p, o: &free, specs: &specs };
        let mut theta = vec![0.1, 0.1];
        pb.clamp(&mut theta);
        assert_eq!(theta, [0.1, 0.1]);
    }

    /// Levenberg–Marquardt on a known nonlinear function: both parameters of an
    /// exponential decay from 40 % and 33 % off, to 1e-6 relative (the effects hold `f32`,
    /// whose resolution is 1e-7 relative; the outputs' rounding moves the optimum less).
    #[test]
    fn lm_fits_an_exponential_decay() {
        let (twin, p) = setup(500);
        let o = Options { threads: 2, ..Options::default() };
        let (sa, sk) = (spec("coulomb_nm", 60.0), spec("viscous_nm_s_per_rad", 20.0));
        let fit = refit(&twin, &p, &o, &[&sa, &sk], &[3.0, 1.0]).expect("the twin runs");
        assert!((fit.values[0] / 5.0 - 1.0).abs() < 1e-6, "A = {}", fit.values[0]);
        assert!((fit.values[1] / 1.5 - 1.0).abs() < 1e-6, "k = {}", fit.values[1]);
        assert!(fit.energy < 1e-9, "energy {}", fit.energy);
        // The Jacobian is the derivative at the optimum (forward difference of 0.005).
        let t = 1.0;
        let k = (t / DT) as usize;
        let dk = -t * 5.0 * (-1.5 * t).exp();
        assert!((fit.jac[1][0][k] / dk - 1.0).abs() < 0.01, "dy/dk {} vs {dk}", fit.jac[1][0][k]);
    }

    /// The decay with its amplitude in units 1e4 times too small and its rate in units
    /// 1e3 times too large, as a stiffness in N m/rad sits beside a resistance in Ω: the
    /// two diagonals of `J'WJ` differ by about 1e14, so a ridge relative to the larger one
    /// swamps the smaller (LM barely moved it and its σ came out undetermined). Solved in
    /// each parameter's own scale, both are fitted and both σ are finite.
    #[test]
    fn parameters_of_very_different_scales_are_fitted_together() {
        struct Scaled(Decay);
        impl Twin for Scaled {
            fn channels(&self) -> &[Channel] {
                self.0.channels()
            }
            fn samples(&self) -> usize {
                self.0.samples()
            }
            fn dt_s(&self) -> f64 {
                DT
            }
            fn run(&self, fx: &Effects) -> Result<Vec<Vec<f32>>, String> {
                let (a, k) = (param(fx, "coulomb_nm") * 1e-4, param(fx, "viscous_nm_s_per_rad") * 1e3);
                Ok(vec![(0..self.0.n).map(|i| (a * (-k * i as f64 * DT).exp()) as f32).collect()])
            }
        }
        let (twin, p) = setup(500);
        let twin = Scaled(twin);
        let o = Options { threads: 2, ..Options::default() };
        let sa = ParamSpec { delta: 100.0, ..spec("coulomb_nm", 1e6) };
        let sk = ParamSpec { delta: 1e-5, ..spec("viscous_nm_s_per_rad", 0.02) };
        let fit = refit(&twin, &p, &o, &[&sa, &sk], &[3e4, 1e-3]).expect("the twin runs");
        assert!((fit.values[0] / 5e4 - 1.0).abs() < 1e-4, "A = {}", fit.values[0]);
        assert!((fit.values[1] / 1.5e-3 - 1.0).abs() < 1e-4, "k = {}", fit.values[1]);
        let sd = crate::uncertainty::parameter_std(&p, &fit, &[&sa, &sk], &[0.0, 0.0], DT).std;
        assert!(sd.iter().all(|s| s.is_finite() && *s > 0.0), "σ {sd:?}");
    }

    /// One parameter (the rate, amplitude known): coarse grid, LM and profile scan, from
    /// a start far off; the profile brackets the optimum.
    #[test]
    fn lm_fits_a_decay_rate_alone() {
        let (twin, p) = setup(500);
        let o = Options {
            base: with_values(&Effects::NONE, &[&spec("coulomb_nm", 60.0)], &[5.0]),
            ..Options::default()
        };
        let sk = spec("viscous_nm_s_per_rad", 20.0);
        let fit = refit(&twin, &p, &o, &[&sk], &[12.0]).expect("the twin runs");
        assert!((fit.values[0] / 1.5 - 1.0).abs() < 1e-6, "k = {}", fit.values[0]);
        let (lo, hi) = (fit.profile[0].0, fit.profile[fit.profile.len() - 1].0);
        assert!(lo < 1.5 && 1.5 < hi, "profile {lo}..{hi}");
        assert!(fit.profile.iter().all(|(_, e)| *e >= fit.energy));
    }

    /// The model holds the decay rate at 1.0 (truth 1.5) and lacks the amplitude (5):
    /// the amplitude refitted alone, against the biased rate, leaves error; refitted with
    /// the held rate, both come out right, and the refit says it moved the rate. The rate,
    /// itself held, is refitted alone.
    #[test]
    fn a_held_value_is_refitted_with_the_candidate() {
        let (twin, mut p) = setup(500);
        p.e0 = energy(&p, &p.base_sim);
        let (sa, sk) = (spec("coulomb_nm", 60.0), spec("viscous_nm_s_per_rad", 20.0));
        let o =
            Options { base: with_values(&Effects::NONE, &[&sk], &[1.0]), threads: 2, ..Options::default() };
        let s = Sensitivities {
            specs: vec![sa.clone(), sk.clone()],
            starts: vec![0.0, 1.0],
            groups: vec![("amplitude", vec![0]), ("rate", vec![1])],
            ..Sensitivities::default()
        };
        let held = Held::refit(&twin, &p, &s, &o);
        assert_eq!(held.ix, [1]);
        let alone = refit(&twin, &p, &o, &[&sa], &[3.0]).expect("the twin runs");
        assert!(alone.energy > 1.0, "alone, the amplitude cannot fit: {}", alone.energy);
        let joint = with_held(&twin, (&p, &o, &s), 0, &held, alone);
        assert_eq!(joint.held_ix(), [1]);
        assert!((joint.values[0] / 5.0 - 1.0).abs() < 1e-5, "A = {}", joint.values[0]);
        assert!((joint.values[1] / 1.5 - 1.0).abs() < 1e-5, "k = {}", joint.values[1]);
        let rate = refit(&twin, &p, &o, &[&sk], &[1.0]).expect("the twin runs");
        assert!(with_held(&twin, (&p, &o, &s), 1, &held, rate).held.is_none());
    }

    /// An undetermined σ never makes a candidate significant; a finite small one does.
    #[test]
    fn significance_needs_a_finite_sigma() {
        let (twin, p) = setup(100);
        let sa = spec("coulomb_nm", 60.0);
        let fit = Fit {
            values: vec![5.0],
            sim: twin.run(&Effects::NONE).unwrap(),
            jac: Vec::new(),
            energy: 0.0,
            profile: Vec::new(),
            held: None,
        };
        let fp = super::super::engine::FittedParam {
            name: "coulomb_nm",
            value: 0.0,
            start: 0.0,
            std: f64::NAN,
            std_data: f64::NAN,
            ci95: (0.0, 0.0),
            unit: "-",
        };
        let mut cand = Candidate { params: vec![fp], ..Candidate::named("differential_friction", 0.0) };
        for (sd, significant) in [(f64::INFINITY, false), (f64::NAN, false), (0.1, true), (3.0, false)] {
            let spread = Spread { std: vec![sd], reported: vec![sd], data: vec![0.0], drift: None };
            confirm(&mut cand, &fit, &spread, &[&sa], &p);
            assert_eq!(cand.significant, significant, "σ = {sd}");
        }
        // Significance is judged on the test's σ; the reported one (widened for what the
        // fit leaves) is what the parameter shows.
        let spread = Spread { std: vec![0.1], reported: vec![3.0], data: vec![0.0], drift: None };
        confirm(&mut cand, &fit, &spread, &[&sa], &p);
        assert!(cand.significant);
        assert_eq!(cand.params[0].std, 3.0);
    }
}
