//! What each library cause adds beyond the maps and parameters within their uncertainty.
//!
//! At the estimate, every cause's parameters are fitted jointly with the fields'
//! coefficients, the parameter groups and the causes already taken (linearised there,
//! the prior kept): its credit is the penalised energy the joint fit removes beyond
//! what the estimate's own next step removes. A cause whose signature the maps and parameters reproduce within their
//! uncertainty (an inverter rate scale beside the identified rates, a connector
//! resistance beside the identified one) gets no credit: its `shared` share says that the
//! two readings cannot be told apart on these runs, rather than that the cause is absent.
//! A credit above the diagnosis' material bar is confirmed on the simulator (the joint
//! step and the estimate's own step, each shortened until the energy stops falling):
//! where the linearisation misleads, the simulator says so.

use std::sync::Arc;

use model_core::Effects;

use super::{Outputs, Point, Problem};
use crate::library::{current_value, library, with_values, ParamSpec};
use crate::linalg::{chol_solve, cholesky, dot, solve_spd, sub_matrix};
use crate::preparation::run_each;
use crate::sensitivities::effect_groups;

/// A library cause beside the estimate.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Credit {
    /// The cause ([`ParamSpec::cause`]).
    pub cause: String,
    /// Its parameters fitted jointly with the estimate (at the fraction of the joint step
    /// the simulator took, where confirmed): name, value, unit.
    pub params: Vec<(String, f64, String)>,
    /// Penalised energy it removes beyond the estimate's own step, linearised.
    pub linear: f64,
    /// The same on the simulator; `None` where the linear credit is under the bar.
    pub confirmed: Option<f64>,
    /// The fraction of the joint step the simulator took (1 where not confirmed).
    pub fraction: f64,
    /// Largest share of one of its parameters' signature the maps and parameters
    /// reproduce within their uncertainty (1: they can take it entirely).
    pub shared: f64,
    /// Where the maps take most of it ([`SEPARATE_FROM`]): the map or parameter group
    /// whose re-identification would tell the two readings apart best.
    pub separator: Option<Separator>,
    /// A cause of one channel's measurement chain, not of the physics.
    pub sensor: bool,
    /// A member of the set: each parameter's 95 % interval `[lo, hi]` at the set's last
    /// settled refit, the maps estimated beside it (empty otherwise).
    pub ci95: Vec<[f64; 2]>,
    /// A member of the ordinary verdict's set (or the lead it counts but cannot name,
    /// [`crate::Unnamed::counts`]), freed beside the maps from the verdict's values: it
    /// has no credit of its own beyond the estimate (`linear` 0), and only a refit that
    /// no longer needs it drops it (not the interval rule).
    pub verdict: bool,
}

/// The map (field) or parameter group that, known exactly, leaves the most of a
/// cause's signature its own: where the maps' reading of it lives, so what a user
/// re-identifies (or excites apart) to tell the cause from the maps' uncertainty, as a
/// confounded pair names the run that separates it. Known exactly is the bound of
/// what re-identifying it can buy: a map the runs already pin better than its stated σ
/// separates nothing when its σ is merely cut (at a quarter of it a differential
/// friction's signature stayed 95 % shared, against 40 % with the SuT inverter power
/// map exact: 1,009,887).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Separator {
    /// The field or the group's first key (as the estimate names them).
    pub unit: String,
    /// [`Credit::shared`] with that unit known exactly: the other units alone.
    pub shared_then: f64,
}

/// The share of a cause's signature the maps take from which the report says what
/// would separate them ([`Separator`]): below it the cause is mostly its own.
const SEPARATE_FROM: f64 = 0.5;

impl Credit {
    /// The credit that counts: the simulator's where it was confirmed.
    pub fn value(&self) -> f64 {
        self.confirmed.unwrap_or(self.linear)
    }
}

/// Candidates confirmed on the simulator per selection round, best linear credit first:
/// the linearisation can misjudge (an axle friction scale beside its map: 2,625
/// linearised, −318 on the simulator, case 1,007,737).
const CONFIRMED_PER_ROUND: usize = 3;

/// What the library adds beyond the estimate.
#[derive(Default)]
pub(super) struct Credits {
    /// Every cause on its own beside the estimate, highest first.
    pub each: Vec<Credit>,
    /// The forward selection: each cause credited beyond the estimate refitted with the
    /// causes before it; values from the last refit.
    pub set: Vec<Credit>,
    /// Per channel, the weighted error energy per fit sample with the set refitted beside
    /// the maps (empty without a set).
    pub after_set: Vec<f64>,
    /// The causes whose refit with the maps did not settle, not credited.
    pub provisional: Vec<Credit>,
    /// Causes taken and then dropped: a later refit no longer needed them.
    pub dropped: Vec<String>,
    /// Members the refit needed less than the bar, kept for the located structure the
    /// model without them leaves on their channels.
    pub located: Vec<String>,
    /// Causes taken and then replaced by a rival of their round whose refit fit better:
    /// the cause, the rival.
    pub lost_to: Vec<(String, String)>,
    /// Causes taken and refused for a drift beside the estimated maps: the cause, why.
    pub drifting: Vec<(String, String)>,
    /// The model at the last settled refit of the set: its data and effects.
    pub with_set: Option<(simrod_io::datadir::ModelData, model_core::Effects)>,
}

/// The causes a round takes (one; the verdict's set at the start), and the set with them.
pub(super) struct Pick {
    pub credits: Vec<Credit>,
    /// The set's library parameters, these causes' among them, at their values.
    pub free: Vec<(ParamSpec, f64)>,
}

/// The ordinary verdict's set as the selection's first stage: every library cause whose
/// parameters `proposed` (the verdict's effects) sets apart from the model's (`pb.fx`),
/// all its parameters freed from the verdict's values; `None` where it proposes none.
/// `verdict`: the verdict proposes them, or read them as it reads those it proposes
/// ([`Credit::verdict`], [`crate::Unnamed::counts`]); otherwise the selection's rules
/// judge them as any other.
pub(super) fn first_stage(pb: &Problem, proposed: &Effects, verdict: bool) -> Option<Pick> {
    let specs = library(&pb.o.params);
    let differs = |e: &usize| current_value(proposed, &specs[*e]) != current_value(&pb.fx, &specs[*e]);
    let (mut credits, mut free) = (Vec::new(), Vec::new());
    for (cause, idx) in effect_groups(&specs).into_iter().filter(|(_, idx)| idx.iter().any(differs)) {
        let at: Vec<(ParamSpec, f64)> =
            idx.iter().map(|&e| (specs[e].clone(), current_value(proposed, &specs[e]))).collect();
        credits.push(Credit {
            cause: cause.to_string(),
            params: at.iter().map(|(s, v)| param_line(s, *v)).collect(),
            linear: 0.0,
            confirmed: None,
            fraction: 1.0,
            shared: 0.0,
            separator: None,
            sensor: idx.iter().all(|&e| specs[e].is_chain()),
            ci95: Vec::new(),
            verdict,
        });
        free.extend(at);
    }
    (!credits.is_empty()).then_some(Pick { credits, free })
}

/// One round at the point `at` of `pb` (the causes `taken` refitted there): with
/// `each`, every open cause's credit on its own (confirmed where above the bar), and
/// those of the [`CONFIRMED_PER_ROUND`] best linear credits confirmed above the bar, best
/// first (the rest are the best's rivals, [`super::select`]).
pub(super) fn round(
    pb: &Problem,
    at: &Point,
    taken: &[&str],
    each: bool,
) -> Result<(Vec<Credit>, Vec<Pick>), String> {
    let specs = library(&pb.o.params);
    let fx = pb.effects(&at.x);
    let starts: Vec<f64> = specs.iter().map(|s| current_value(&fx, s)).collect();
    let steps: Vec<f64> = specs.iter().zip(&starts).map(|(s, &v)| s.step_from(v)).collect();
    let data = Arc::new(pb.data(&at.x));
    let jobs: Vec<usize> = (0..specs.len()).collect();
    let runs =
        run_each(&jobs, pb.o, |&i| match pb.p.unread.param(&specs[i]) || taken.contains(&specs[i].cause) {
            true => Ok(Vec::new()),
            false => {
                pb.twin.run_data(&data, &with_values(&fx, &[&specs[i]], &[starts[i] + steps[i]]), pb.p.stride)
            }
        });
    let effect_cols: Vec<Outputs> =
        runs.into_iter().map(|o| o.map(|out| pb.change(out, &at.y))).collect::<Result<_, _>>()?;
    let normal = Normal::new(pb, &at.jacobian, &effect_cols, &at.r, &at.x)?;
    let shared = (0..effect_cols.len()).map(|e| normal.shared(e)).collect();
    let cx = Context { pb, at, specs: &specs, starts, steps, normal, shared };
    let causes: Vec<(&'static str, Vec<usize>)> = effect_groups(&specs)
        .into_iter()
        .filter(|(c, idx)| !taken.contains(c) && idx.iter().any(|&e| cx.normal.gee(e, e) != 0.0))
        .collect();
    let own = cx.normal.solve(&[])?;
    let mut all: Vec<Credit> = match each {
        true => causes.iter().filter_map(|(c, idx)| cx.credit(c, idx, &own, true).ok()).collect(),
        false => Vec::new(),
    };
    cx.separate(&mut all, &causes);
    all.sort_by(|a, b| b.value().total_cmp(&a.value()));
    let picks = cx.confirmed(&causes, &own)?.into_iter().map(|(credit, idx)| cx.pick(credit, idx));
    Ok((all, picks.collect::<Result<_, _>>()?))
}

/// The set's credits' parameters at the refit's `values` of the library parameters `free`.
pub(super) fn set_values(set: &mut [Credit], free: &[(ParamSpec, f64)], values: &[f64]) {
    for c in set {
        let mine = free.iter().zip(values).filter(|((s, _), _)| s.cause == c.cause);
        c.params = mine.map(|((s, _), v)| param_line(s, *v)).collect();
    }
}

/// Each member of `set` gets its parameters' intervals (`intervals` in the order of `free`).
pub(super) fn set_intervals(set: &mut [Credit], free: &[(ParamSpec, f64)], intervals: &[[f64; 2]]) {
    for c in set {
        let mine = free.iter().zip(intervals).filter(|((s, _), _)| s.cause == c.cause);
        c.ci95 = mine.map(|(_, iv)| *iv).collect();
    }
}

/// A parameter as a credit reports it: name, value, unit.
fn param_line(s: &ParamSpec, v: f64) -> (String, f64, String) {
    (s.param.to_string(), v, s.unit.to_string())
}

/// The fixed parts of a round.
struct Context<'a, 'b> {
    pb: &'a Problem<'b>,
    /// The estimate (its penalised energy is what the own step starts from).
    at: &'a Point,
    specs: &'a [ParamSpec],
    /// Each library parameter's value at the estimate (the set's refitted).
    starts: Vec<f64>,
    steps: Vec<f64>,
    normal: Normal,
    /// Per effect column, [`Normal::shared`].
    shared: Vec<f64>,
}

impl Context<'_, '_> {
    /// The estimate moved by `step` times `a`: the unknowns, and the values of effect
    /// columns `idx` (whose part of the step follows the unknowns'), within their bounds.
    fn moved(&self, idx: &[usize], step: &Step, a: f64) -> (Vec<f64>, Vec<f64>) {
        let n = self.normal.n;
        let x = self.at.x.iter().zip(&step.dx[..n]).map(|(u, d)| u + a * d).collect();
        let sp = self.specs;
        let values = idx.iter().zip(&step.dx[n..]);
        let values =
            values.map(|(&e, d)| (self.starts[e] + a * self.steps[e] * d).clamp(sp[e].lower, sp[e].upper));
        (x, values.collect())
    }

    /// The penalised energy at `x` with the effect columns `idx` at `values`.
    fn energy(&self, x: &[f64], idx: &[usize], values: &[f64]) -> Result<f64, String> {
        let pb = self.pb;
        let sp: Vec<&ParamSpec> = idx.iter().map(|&e| &self.specs[e]).collect();
        let y = pb.outputs_with(&Arc::new(pb.data(x)), with_values(&pb.effects(x), &sp, values))?;
        Ok(pb.objective(&pb.residual(&y), x))
    }

    /// Cause `cause` (columns `idx`) beyond the estimate, whose own step is `own`:
    /// linearised, and confirmed on the simulator when `confirm` and above the bar.
    fn credit(&self, cause: &str, idx: &[usize], own: &Step, confirm: bool) -> Result<Credit, String> {
        let joint = self.normal.solve(idx)?;
        let linear = joint.reduction - own.reduction;
        let shared = idx.iter().map(|&e| self.shared[e]).fold(0.0, f64::max);
        let (confirmed, fraction) = match confirm && linear >= self.pb.bar {
            true => self.confirm(own, (idx, &joint)).map(|(c, a)| (Some(c), a))?,
            false => (None, 1.0),
        };
        let values = self.moved(idx, &joint, fraction).1;
        let sp = self.specs;
        let params = idx.iter().zip(&values).map(|(&e, v)| param_line(&sp[e], *v));
        let sensor = idx.iter().all(|&e| sp[e].is_chain());
        Ok(Credit {
            cause: cause.to_string(),
            params: params.collect(),
            linear,
            confirmed,
            fraction,
            shared,
            separator: None,
            sensor,
            ci95: Vec::new(),
            verdict: false,
        })
    }

    /// Each credit of `all` the maps take [`SEPARATE_FROM`] or more of gets its
    /// [`Separator`]: every field and parameter group in turn known exactly (out of the
    /// nuisance), one factorisation each.
    fn separate(&self, all: &mut [Credit], causes: &[(&'static str, Vec<usize>)]) {
        let idx_of = |c: &Credit| causes.iter().find(|(n, _)| *n == c.cause).map(|(_, idx)| idx.as_slice());
        let shared = all.iter().enumerate().filter(|(_, c)| c.shared >= SEPARATE_FROM);
        let wanted: Vec<(usize, &[usize])> = shared.filter_map(|(k, c)| Some((k, idx_of(c)?))).collect();
        let mut cols: Vec<usize> = wanted.iter().flat_map(|(_, idx)| idx.iter().copied()).collect();
        cols.sort_unstable();
        cols.dedup();
        if cols.is_empty() {
            return;
        }
        for (unit, members) in self.pb.units() {
            let Some(then) = self.normal.shared_without(&cols, &members) else { continue };
            for (k, idx) in &wanted {
                let share = idx.iter().filter_map(|e| cols.binary_search(e).ok()).map(|p| then[p]);
                let share = share.fold(0.0, f64::max);
                let c = &mut all[*k];
                if c.separator.as_ref().is_none_or(|s| share < s.shared_then) {
                    c.separator = Some(Separator { unit: unit.clone(), shared_then: share });
                }
            }
        }
    }

    /// The causes confirmed above the bar among the [`CONFIRMED_PER_ROUND`] best linear
    /// credits beyond the estimate, best confirmed first.
    fn confirmed<'c>(
        &self,
        causes: &'c [(&'static str, Vec<usize>)],
        own: &Step,
    ) -> Result<Vec<(Credit, &'c [usize])>, String> {
        let linear =
            causes.iter().filter_map(|(c, idx)| Some((self.credit(c, idx, own, false).ok()?.linear, c, idx)));
        let mut linear: Vec<_> = linear.filter(|(l, _, _)| *l >= self.pb.bar).collect();
        linear.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut above = Vec::new();
        for (_, c, idx) in linear.into_iter().take(CONFIRMED_PER_ROUND) {
            let k = self.credit(c, idx, own, true)?;
            if k.value() >= self.pb.bar {
                above.push((k, idx.as_slice()));
            }
        }
        above.sort_by(|a, b| b.0.value().total_cmp(&a.0.value()));
        Ok(above)
    }

    /// The set once `credit` (columns `idx`) is taken: the set's parameters at their
    /// values here, the cause's at the fraction of the joint step the simulator took.
    fn pick(&self, credit: Credit, idx: &[usize]) -> Result<Pick, String> {
        let joint = self.normal.solve(idx)?;
        let (x, values) = self.moved(idx, &joint, credit.fraction);
        let pb = self.pb;
        let held = pb.free.iter().map(|(s, _)| s.clone()).zip(pb.values(&x));
        let free = held.chain(idx.iter().map(|&e| self.specs[e].clone()).zip(values)).collect();
        Ok(Pick { credits: vec![credit], free })
    }

    /// The simulator's credit of the `joint` step (columns and step) beyond the own
    /// step, and the fraction of the joint step it takes: each simulated at the
    /// [`FRACTIONS`] until the energy stops falling; the own step counts only where it
    /// does not raise the energy.
    fn confirm(&self, own: &Step, (idx, joint): (&[usize], &Step)) -> Result<(f64, f64), String> {
        let shortest = |idx: &[usize], step: &Step| -> Result<(f64, f64), String> {
            let mut best = (f64::INFINITY, 1.0);
            for a in FRACTIONS {
                let (x, values) = self.moved(idx, step, a);
                let e = self.energy(&x, idx, &values)?;
                if e > best.0 {
                    break;
                }
                best = (e, a);
            }
            Ok(best)
        };
        let (with, a) = shortest(idx, joint)?;
        Ok((self.at.energy.min(shortest(&[], own)?.0) - with, a))
    }
}

/// Fractions of a linearised step tried on the simulator, in order: a step the
/// linearisation overshoots is shortened until the energy stops falling (a 120 ms
/// controller delay beside perturbed maps, case 1,007,743: the whole joint step, to 70 ms
/// with the maps moved along, raised the energy by 1.5 M; half of it removes 24,871).
const FRACTIONS: [f64; 4] = [1.0, 0.5, 0.25, 0.125];

/// The normal equations at the estimate: the nuisance block with its prior, the effects'
/// columns beside it.
struct Normal {
    n: usize,
    /// Nuisance Gram with the prior on its diagonal (`n x n`), and `C'W r − prior x`.
    gnn: Vec<f64>,
    bn: Vec<f64>,
    /// `E'W C` per effect column (`[effect][n]`), `E'W E` (full), `E'W r`.
    gne: Vec<Vec<f64>>,
    gee: Vec<Vec<f64>>,
    be: Vec<f64>,
}

/// A solved step: the unknowns' change and the quadratic model's energy reduction.
struct Step {
    dx: Vec<f64>,
    reduction: f64,
}

impl Normal {
    /// The normal equations with the nuisance's Gram `gram` (prior included) of columns
    /// `cols`, the effects' columns `effects`, at residual `r` and nuisance `x`.
    fn new(
        pb: &Problem,
        cols: &[Outputs],
        effects: &[Outputs],
        r: &Outputs,
        x: &[f64],
    ) -> Result<Self, String> {
        let bn = pb.gradient(cols, r, x)?;
        // One row per effect, also when the other side has no columns (`chunks` of a
        // row-major product would then give no rows at all).
        let rows =
            |g: Vec<f64>, k: usize| (0..effects.len()).map(|e| g[e * k..(e + 1) * k].to_vec()).collect();
        let gne = rows(pb.products(effects, cols)?, cols.len());
        let gee = rows(pb.products(effects, effects)?, effects.len());
        let be = pb.products(effects, std::slice::from_ref(r))?;
        Ok(Self { n: cols.len(), gnn: pb.gram(cols, x)?, bn, gne, gee, be })
    }

    fn gee(&self, e: usize, f: usize) -> f64 {
        self.gee[e][f]
    }

    /// The step of the nuisance with the effect columns `idx` beside it.
    fn solve(&self, idx: &[usize]) -> Result<Step, String> {
        let (n, m) = (self.n, self.n + idx.len());
        let mut g = vec![0.0; m * m];
        for i in 0..n {
            g[i * m..i * m + n].copy_from_slice(&self.gnn[i * n..(i + 1) * n]);
        }
        for (a, &e) in idx.iter().enumerate() {
            for i in 0..n {
                g[i * m + n + a] = self.gne[e][i];
                g[(n + a) * m + i] = self.gne[e][i];
            }
            for (b, &f) in idx.iter().enumerate() {
                g[(n + a) * m + n + b] = self.gee[e][f];
            }
            // Conditioning only: the effects carry no prior.
            g[(n + a) * m + n + a] += 1e-9 * self.gee[e][e].max(1e-12);
        }
        let b: Vec<f64> = self.bn.iter().copied().chain(idx.iter().map(|&e| self.be[e])).collect();
        let dx = solve_spd(&g, &b, 1e-12).ok_or("the joint normal equations are singular")?;
        let reduction = b.iter().zip(&dx).map(|(u, v)| u * v).sum();
        Ok(Step { dx, reduction })
    }

    /// Share of effect column `e`'s weighted energy the nuisance (with its prior)
    /// reproduces: `1 − S/G_ee`, `S` its Schur complement.
    fn shared(&self, e: usize) -> f64 {
        let gee = self.gee[e][e];
        let Some(z) = solve_spd(&self.gnn, &self.gne[e], 1e-12) else { return 0.0 };
        let s = gee - dot(&self.gne[e], &z);
        share_of(gee, s)
    }

    /// [`Normal::shared`] of each effect column of `cols` by the nuisance without its
    /// columns `known` (sorted; known exactly): one factorisation for them all; `None`
    /// where that Gram is not positive definite.
    fn shared_without(&self, cols: &[usize], known: &[usize]) -> Option<Vec<f64>> {
        let keep: Vec<usize> = (0..self.n).filter(|i| known.binary_search(i).is_err()).collect();
        if keep.is_empty() {
            return Some(vec![0.0; cols.len()]);
        }
        let l = cholesky(&sub_matrix(&self.gnn, self.n, &keep), keep.len())?;
        let shared = |e: usize| {
            let b: Vec<f64> = keep.iter().map(|&i| self.gne[e][i]).collect();
            let z = chol_solve(&l, keep.len(), &b);
            share_of(self.gee[e][e], self.gee[e][e] - dot(&b, &z))
        };
        Some(cols.iter().map(|&e| shared(e)).collect())
    }
}

/// `1 − s/gee` within [0, 1]: the share of a column's energy `gee` whose Schur
/// complement is `s` that the nuisance takes (0 for a column that moves nothing).
fn share_of(gee: f64, s: f64) -> f64 {
    if gee > 0.0 {
        (1.0 - s / gee).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use simrod_numerics::linalg::lstsq;

    /// 200 samples of `f(t)`.
    fn col(f: impl Fn(f64) -> f64) -> Vec<f64> {
        (0..200).map(|t| f(f64::from(t))).collect()
    }

    /// The normal equations of nuisance columns `c` (a prior too weak to matter) and
    /// effect columns `e`, unit weights.
    fn normal(c: &[Vec<f64>], e: &[Vec<f64>]) -> Normal {
        let n = c.len();
        let mut gnn: Vec<f64> = c.iter().flat_map(|a| c.iter().map(|b| dot(a, b))).collect();
        for i in 0..n {
            gnn[i * n + i] += 1e-9;
        }
        let gne = e.iter().map(|x| c.iter().map(|a| dot(x, a)).collect()).collect();
        let gee = e.iter().map(|x| e.iter().map(|y| dot(x, y)).collect()).collect();
        Normal { n, gnn, bn: vec![0.0; n], gne, gee, be: vec![0.0; e.len()] }
    }

    /// The share of `y`'s energy the columns `c` reproduce, by SVD least squares (not
    /// the Schur complement under test).
    fn projected(c: &[&Vec<f64>], y: &[f64]) -> f64 {
        let m = y.len();
        let a: Vec<f64> = (0..m).flat_map(|t| c.iter().map(move |x| x[t])).collect();
        let fit = lstsq(&a, m, c.len(), y).unwrap();
        let r: Vec<f64> =
            (0..m).map(|t| y[t] - c.iter().zip(&fit.x).map(|(x, b)| x[t] * b).sum::<f64>()).collect();
        1.0 - dot(&r, &r) / dot(y, y)
    }

    /// Two units: A (one column) and B (two). An effect mostly A's shape is taken by the
    /// nuisance, and left its own once A is known exactly, not once B is; one spread over
    /// B's two columns the other way round. Every share equals the SVD projection's.
    #[test]
    fn the_share_the_maps_take_falls_with_the_unit_that_reads_the_effect_known() {
        let c = [col(|t| (0.05 * t).sin()), col(|t| t / 200.0), col(|t| (0.13 * t).cos())];
        let e = [
            col(|t| (0.05 * t).sin() + 0.1 * (0.7 * t).sin()),
            col(|t| 0.5 * t / 200.0 + 0.5 * (0.13 * t).cos() + 0.1 * (0.9 * t).cos()),
        ];
        let nm = normal(&c, &e);
        let (a, b) = (vec![0], vec![1, 2]);
        for (k, ek) in e.iter().enumerate() {
            let all = projected(&[&c[0], &c[1], &c[2]], ek);
            assert!((nm.shared(k) - all).abs() < 1e-6, "effect {k}: {} vs {all}", nm.shared(k));
            assert!(all > 0.9, "effect {k} is mostly the nuisance's: {all}");
            let without_a = nm.shared_without(&[k], &a).unwrap()[0];
            let without_b = nm.shared_without(&[k], &b).unwrap()[0];
            assert!((without_a - projected(&[&c[1], &c[2]], ek)).abs() < 1e-6, "{without_a}");
            assert!((without_b - projected(&[&c[0]], ek)).abs() < 1e-6, "{without_b}");
            assert_eq!(nm.shared_without(&[k], &[0, 1, 2]).unwrap(), vec![0.0]);
        }
        let w = |k: usize, u: &[usize]| nm.shared_without(&[k], u).unwrap()[0];
        assert!(w(0, &a) < 0.5 && w(0, &b) > 0.9, "A reads effect 0: {} / {}", w(0, &a), w(0, &b));
        assert!(w(1, &b) < 0.5 && w(1, &a) > 0.9, "B reads effect 1: {} / {}", w(1, &b), w(1, &a));
    }
}
