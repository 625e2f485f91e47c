//! What each library cause adds beyond the maps and parameters within their uncertainty.
//!
//! At the estimate, every cause's parameters are fitted jointly with the fields'
//! coefficients and the parameter groups (linearised there, the prior kept): its credit
//! is the penalised energy the joint fit removes beyond what the estimate's own next
//! step removes. A cause whose signature the maps and parameters reproduce within their
//! uncertainty (an inverter rate scale beside the identified rates, a connector
//! resistance beside the identified one) gets no credit: its `shared` share says that the
//! two readings cannot be told apart on these runs, rather than that the cause is absent.
//! A credit above the diagnosis' material bar is confirmed on the simulator (the joint
//! step and the estimate's own step, each shortened until the energy stops falling):
//! where the linearisation misleads, the simulator says so.

use std::sync::Arc;

use super::{Outputs, Point, Problem};
use crate::library::{current_value, library, with_values, ParamSpec};
use crate::linalg::solve_spd;
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
    /// Largest share of one of its parameters' signature the maps and parameters
    /// reproduce within their uncertainty (1: they can take it entirely).
    pub shared: f64,
    /// A cause of one channel's measurement chain, not of the physics.
    pub sensor: bool,
}

impl Credit {
    /// The credit that counts: the simulator's where it was confirmed.
    pub fn value(&self) -> f64 {
        self.confirmed.unwrap_or(self.linear)
    }
}

/// Most causes the greedy selection takes.
const MAX_SET: usize = 4;
/// Candidates confirmed on the simulator per selection round, best linear credit first:
/// the linearisation can misjudge (an axle friction scale beside its map: 2,625
/// linearised, −318 on the simulator, case 1,007,737).
const CONFIRMED_PER_ROUND: usize = 3;

/// What the library adds beyond the estimate.
pub(super) struct Credits {
    /// Every cause on its own beside the estimate, highest first.
    pub each: Vec<Credit>,
    /// The set chosen greedily: each cause credited beyond the estimate and the causes
    /// before it, refitted jointly with them.
    pub set: Vec<Credit>,
}

/// Every library cause's credit at the estimate `at` (the nuisance Jacobian `cols`
/// there), and the set the credits select; `bar` is the least that counts.
pub(super) fn credits(pb: &Problem, at: &Point, cols: &[Outputs], bar: f64) -> Result<Credits, String> {
    let specs = library(&pb.o.params);
    let starts: Vec<f64> = specs.iter().map(|s| current_value(&pb.fx, s)).collect();
    let steps: Vec<f64> = specs.iter().zip(&starts).map(|(s, &v)| s.step_from(v)).collect();
    let data = Arc::new(pb.data(&at.x));
    let jobs: Vec<usize> = (0..specs.len()).collect();
    let runs = run_each(&jobs, pb.o, |&i| match pb.p.unread.param(&specs[i]) {
        true => Ok(Vec::new()),
        false => {
            pb.twin.run_data(&data, &with_values(&pb.fx, &[&specs[i]], &[starts[i] + steps[i]]), pb.p.stride)
        }
    });
    let effect_cols: Vec<Outputs> =
        runs.into_iter().map(|o| o.map(|out| pb.change(out, &at.y))).collect::<Result<_, _>>()?;
    let normal = Normal::new(pb, cols, &effect_cols, &at.r, &at.x);
    let shared = (0..effect_cols.len()).map(|e| normal.shared(e)).collect();
    let cx = Context { pb, at, specs: &specs, starts, steps, normal, shared, bar };
    let causes: Vec<(&'static str, Vec<usize>)> = effect_groups(&specs)
        .into_iter()
        .filter(|(_, idx)| idx.iter().any(|&e| cx.normal.gee(e, e) != 0.0))
        .collect();
    let alone = cx.normal.solve(&[])?;
    let mut each: Vec<Credit> =
        causes.iter().filter_map(|(c, idx)| cx.credit(c, idx, (&[], &alone), true).ok()).collect();
    each.sort_by(|a, b| b.value().total_cmp(&a.value()));
    let set = cx.select(&causes)?;
    Ok(Credits { each, set })
}

/// The fixed parts of the credits.
struct Context<'a, 'b> {
    pb: &'a Problem<'b>,
    /// The estimate (its penalised energy is what the own step starts from).
    at: &'a Point,
    specs: &'a [ParamSpec],
    starts: Vec<f64>,
    steps: Vec<f64>,
    normal: Normal,
    /// Per effect column, [`Normal::shared`].
    shared: Vec<f64>,
    bar: f64,
}

impl Context<'_, '_> {
    /// The values of effect columns `idx` after `step` (whose effect part follows the
    /// nuisance's), within their bounds.
    fn values(&self, idx: &[usize], step: &Step) -> Vec<f64> {
        let (sp, st) = (self.specs, &self.steps);
        let d = &step.dx[self.normal.n..];
        idx.iter()
            .zip(d)
            .map(|(&e, d)| (self.starts[e] + st[e] * d).clamp(sp[e].lower, sp[e].upper))
            .collect()
    }

    /// Cause `cause` (columns `idx`) beyond the estimate and the causes `selected`, whose
    /// own step is `base`: linearised, and confirmed on the simulator when `confirm` and
    /// above the bar.
    fn credit(
        &self,
        cause: &str,
        idx: &[usize],
        (selected, base): (&[usize], &Step),
        confirm: bool,
    ) -> Result<Credit, String> {
        let both: Vec<usize> = selected.iter().chain(idx).copied().collect();
        let joint = self.normal.solve(&both)?;
        let linear = joint.reduction - base.reduction;
        let shared = idx.iter().map(|&e| self.shared[e]).fold(0.0, f64::max);
        let mut values = self.values(&both, &joint);
        let confirmed = match confirm && linear >= self.bar {
            true => {
                let own = (&base.dx[..self.normal.n], selected, &self.values(selected, base)[..]);
                let (c, a) = self.confirm(own, (&joint.dx[..self.normal.n], &both, &values))?;
                values
                    .iter_mut()
                    .zip(&both)
                    .for_each(|(v, &e)| *v = self.starts[e] + a * (*v - self.starts[e]));
                Some(c)
            }
            false => None,
        };
        let sp = self.specs;
        let mine = both.iter().zip(&values).skip(selected.len());
        let params = mine.map(|(&e, v)| (sp[e].param.to_string(), *v, sp[e].unit.to_string()));
        let sensor = idx.iter().all(|&e| sp[e].is_chain());
        Ok(Credit { cause: cause.to_string(), params: params.collect(), linear, confirmed, shared, sensor })
    }

    /// Forward selection: each round, the causes' linear credits beyond the estimate and
    /// the set so far, the best [`CONFIRMED_PER_ROUND`] confirmed on the simulator, the
    /// best confirmed one above the bar taken; at most [`MAX_SET`].
    fn select(&self, causes: &[(&'static str, Vec<usize>)]) -> Result<Vec<Credit>, String> {
        let (mut set, mut selected): (Vec<Credit>, Vec<usize>) = (Vec::new(), Vec::new());
        while set.len() < MAX_SET {
            let base = self.normal.solve(&selected)?;
            let open = causes.iter().filter(|(c, _)| set.iter().all(|s| s.cause != *c));
            let mut linear: Vec<(f64, &(&'static str, Vec<usize>))> = open
                .filter_map(|cause| {
                    Some((self.credit(cause.0, &cause.1, (&selected, &base), false).ok()?.linear, cause))
                })
                .filter(|(l, _)| *l >= self.bar)
                .collect();
            linear.sort_by(|a, b| b.0.total_cmp(&a.0));
            let tried = linear.iter().take(CONFIRMED_PER_ROUND);
            let confirmed =
                tried.map(|(_, (c, idx))| self.credit(c, idx, (&selected, &base), true).map(|k| (k, idx)));
            let mut best: Option<(Credit, &Vec<usize>)> = None;
            for k in confirmed {
                let k = k?;
                if k.0.value() >= self.bar && best.as_ref().is_none_or(|b| k.0.value() > b.0.value()) {
                    best = Some(k);
                }
            }
            let Some((credit, idx)) = best else { break };
            selected.extend(idx);
            set.push(credit);
        }
        Ok(set)
    }

    /// The simulator's credit and the fraction of the joint step it takes: the `own`
    /// step (nuisance change, effect columns, their values) and the `joint` one from the
    /// estimate, each simulated at the [`FRACTIONS`] until the energy stops falling; the
    /// own step counts only where it does not raise the energy.
    fn confirm(
        &self,
        own: (&[f64], &[usize], &[f64]),
        joint: (&[f64], &[usize], &[f64]),
    ) -> Result<(f64, f64), String> {
        let pb = self.pb;
        let energy = |a: f64, (dx, idx, values): (&[f64], &[usize], &[f64])| -> Result<f64, String> {
            let xs: Vec<f64> = self.at.x.iter().zip(dx).map(|(u, d)| u + a * d).collect();
            let sp: Vec<&ParamSpec> = idx.iter().map(|&e| &self.specs[e]).collect();
            let v: Vec<f64> =
                idx.iter().zip(values).map(|(&e, v)| self.starts[e] + a * (v - self.starts[e])).collect();
            let y = pb.outputs_with(&Arc::new(pb.data(&xs)), with_values(&pb.fx, &sp, &v))?;
            Ok(pb.objective(&pb.residual(&y), &xs))
        };
        let shortest = |step| -> Result<(f64, f64), String> {
            let mut best = (f64::INFINITY, 1.0);
            for a in FRACTIONS {
                let e = energy(a, step)?;
                if e > best.0 {
                    break;
                }
                best = (e, a);
            }
            Ok(best)
        };
        let (with, a) = shortest(joint)?;
        Ok((self.at.energy.min(shortest(own)?.0) - with, a))
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
    fn new(pb: &Problem, cols: &[Outputs], effects: &[Outputs], r: &Outputs, x: &[f64]) -> Self {
        use rayon::prelude::*;
        let (gnn, bn) = pb.normal(cols, r, x);
        let gne = effects.par_iter().map(|e| cols.iter().map(|c| pb.dot(e, c)).collect()).collect();
        let gee = effects.par_iter().map(|e| effects.iter().map(|f| pb.dot(e, f)).collect()).collect();
        let be = effects.par_iter().map(|e| pb.dot(e, r)).collect();
        Self { n: cols.len(), gnn, bn, gne, gee, be }
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
        let s = gee - self.gne[e].iter().zip(&z).map(|(a, b)| a * b).sum::<f64>();
        if gee > 0.0 {
            (1.0 - s / gee).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }
}
