//! The identified maps and parameters re-estimated within their stated uncertainty.
//!
//! The maps the twin runs on are identified data with a stated uncertainty
//! ([`simrod_io::map_uncertainty`]), in the smooth shapes of [`simrod_io::map_prior`].
//! Their error at that size is not linear in the run (a friction map and a load map
//! interact; the flanges' error from the true node changes applied one by one is 1.7x
//! what they do together, README "Measured on 2026-12-01"), so it cannot be profiled out
//! of a linear fit. Here it is estimated by re-simulation: a Gauss–Newton fit of the
//! prior's field coefficients and the parameter groups' log-factors, each with its
//! unit-normal prior, re-linearised at every accepted point by finite differences, a
//! step that raises the penalised energy taken back halfway towards the best point.
//!
//! What it gives is data the runs agree with *within the declared uncertainty*: an
//! estimate under an ASSUMED prior (the spectrum, the σ values), not an identification
//! of the maps, and it takes up whatever part of a missing effect looks like a map's
//! error (a rate scale, a connector resistance, a friction scale: README item 4).

use std::sync::Arc;

use model_core::Effects;
use simrod_io::datadir::{ModelData, ParamLine};
use simrod_io::map_prior::{apply, fields, Field};
use simrod_io::map_uncertainty::Uncertainty;

mod credit;
mod drift;
mod interval;
mod located;
mod settling;

pub use credit::{Credit, Separator};

use super::dynamics::sibling;
use super::engine::{Options, Twin};
use super::library::{current_value, with_values, ParamSpec};
use super::linalg::solve_spd;
use super::preparation::{prepare, run_each, said_worse, Prepared};
use settling::Settling;
use simrod_numerics::linalg::weighted_products;

/// Most fit samples the fit reads (every k-th of [`Prepared::idx`]); the prior's weight
/// is scaled by the thinning so that it stands against the whole run's information.
const ROWS: usize = 4000;
/// Most objective evaluations (each accepted one is followed by a new Jacobian). On the
/// 65 nothing-hidden perturbed cases of proofs 24–26 most fits settled (an accepted step
/// removing less than the material bar) by the fifth; the two whose credits came from an
/// unsettled estimate were still removing 294 and 484 bars at the sixth (README, "Built
/// and measured on 2026-12-01, morning"): ten, and a fit that has not settled by then
/// says so.
const MAX_EVALUATIONS: usize = 10;
/// Finite-difference step of a coefficient [σ]: small, as the friction's sign clamp and
/// the maps' interaction make wider secants wrong (0.5 σ left 1,007,537's load fields
/// at 3.8 σ RMS and a higher penalised energy, 46,761 against 46,146 at 0.05 σ).
const STEP: f64 = 0.05;
/// Where the prior becomes a wall [σ]: a coefficient or group further out costs the
/// material bar per σ² beyond. The prior's own weight (1 / thinning) makes a move of many
/// σ cost less than a material share of the noise, so without a wall the estimate took a
/// missing effect into the maps far outside their stated uncertainty (60 tuning cases
/// 505,531–505,590: a group at 22 σ, fields at 20 σ RMS; a doubled connector resistance, a
/// rate scale, taken as maps). A draw of the prior's ~300 unknowns with data passes 4 σ
/// somewhere in about 2 % of draws, by a little. ASSUMED (docs/MODEL.md).
pub const WALL: f64 = 4.0;
/// A channel's weighted error energy per fit sample above which the estimate leaves it
/// unexplained: 1.2x the noise's RMS, the proof's bar for a channel within the true
/// model's error (noise alone gives about 1).
pub const LEFT_OVER: f64 = 1.44;

/// What the estimate moved and what it left.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Estimate {
    /// Each field's name and the RMS of its coefficients [σ of the prior].
    pub fields: Vec<(String, f64)>,
    /// Each parameter group (its first key) and its factor on the identified value.
    pub params: Vec<(String, f64)>,
    /// The coefficient (`field[j]`) or group furthest from the identified data, and how
    /// far [σ of the prior]; the prior's wall is at [`WALL`].
    pub furthest: (String, f64),
    /// Per channel: name, weighted error energy per fit sample before and after (noise
    /// alone gives about 1).
    pub channels: Vec<(String, f64, f64)>,
    /// The penalised energy at each evaluation (data term plus the prior's).
    pub objective: Vec<f64>,
    /// Whether the fit settled: its last accepted step removed less than [`Estimate::bar`].
    /// An estimate that has not settled is still moving: what it leaves is provisional,
    /// and a cause is credited only where the refit with it settles.
    pub settled: bool,
    /// Every library cause on its own beside the estimate, highest credit first.
    pub credits: Vec<Credit>,
    /// The set beside the estimate: the ordinary verdict's causes first
    /// ([`Credit::verdict`]), then those that add beyond it (forward selection), each
    /// credited beyond the estimate refitted with the causes before it; values from the
    /// last refit of the set with the maps.
    pub set: Vec<Credit>,
    /// Per channel, the weighted error energy per fit sample with the set refitted beside
    /// the maps (empty without a set).
    pub after_set: Vec<f64>,
    /// The causes whose refit with the maps (beside [`Estimate::set`]) did not settle:
    /// not credited, reported.
    pub provisional: Vec<Credit>,
    /// Causes taken and then dropped: a later refit no longer needed them.
    pub dropped: Vec<String>,
    /// Members the refit needed less than the material bar, kept because the model
    /// without them leaves located structure (a channel's time span) they clear.
    pub located: Vec<String>,
    /// Causes taken and then replaced: the set refitted with a rival of the same round in
    /// their place fit better (lower penalised energy). Each: the cause, its rival.
    pub lost_to: Vec<(String, String)>,
    /// Causes taken and then refused: beside the estimated maps a parameter of theirs
    /// drifts over the run, with speed or with the load (the verdict's constancy test), so
    /// they stand for a time-varying or differently shaped effect the library lacks. Each:
    /// the cause, why.
    pub drifting: Vec<(String, String)>,
    /// The least credit that counts: the diagnosis' material share of the noise's energy
    /// on the rows read (`Options::min_reduction_of_noise`).
    pub bar: f64,
    /// Why the model this estimate describes (with its set where one stands) must not be
    /// adopted: it has not settled, or it makes a channel worse than the identified model
    /// on the run or on one run of a campaign (the verdict's test for a proposal). `None`:
    /// `--write-estimate` writes it.
    pub refused: Option<String>,
    /// The estimated model data.
    #[serde(skip)]
    pub data: Arc<ModelData>,
    /// The model with the set: the maps and parameters refitted beside
    /// [`Estimate::set`] and the effects with the set's values (`None` without a set).
    #[serde(skip)]
    pub with_set: Option<(Arc<ModelData>, Effects)>,
}

impl Estimate {
    /// The model this estimate describes, on the model's effects `base`: refitted with
    /// the set where one stands, else the estimate alone with `base`.
    pub fn model(&self, base: Effects) -> (&Arc<ModelData>, Effects) {
        match &self.with_set {
            Some((data, fx)) => (data, *fx),
            None => (&self.data, base),
        }
    }

    /// The channels whose error the estimate leaves above [`LEFT_OVER`].
    pub fn left_over(&self) -> impl Iterator<Item = &str> {
        self.channels.iter().filter(|(_, _, a)| *a > LEFT_OVER).map(|(c, _, _)| c.as_str())
    }
}

/// One unknown: a field's coefficient or a parameter group's log-factor [σ], or a
/// library parameter of the set refitted beside them [its `delta`s from its start].
#[derive(Debug, Clone, Copy, PartialEq)]
enum Unknown {
    Coef { field: usize, j: usize },
    Group(usize),
    Effect(usize),
}

/// The fit's fixed parts: the runs, the prior, the samples read.
struct Problem<'a> {
    twin: &'a dyn Twin,
    p: &'a Prepared,
    o: &'a Options,
    fx: Effects,
    base: Arc<ModelData>,
    unc: Uncertainty,
    fields: Vec<Field>,
    unknowns: Vec<Unknown>,
    /// Fit samples read (positions in the prepared series) and their weights `[c][row]`.
    rows: Vec<usize>,
    w: Vec<Vec<f64>>,
    /// The library parameters refitted beside the maps (the set so far) and their
    /// starting values.
    free: Vec<(ParamSpec, f64)>,
    /// The prior's precision relative to the rows' (1 / thinning).
    prior: f64,
    /// The diagnosis' material bar on the rows read: a share of the noise's energy there.
    bar: f64,
}

/// The model's outputs `[channel][row]` at one point.
type Outputs = Vec<Vec<f64>>;

impl<'a> Problem<'a> {
    fn new(twin: &'a dyn Twin, p: &'a Prepared, o: &'a Options, fx: Effects) -> Result<Self, String> {
        let base = twin.data().ok_or("this twin runs on its own data only")?;
        let unc = Uncertainty::thesis();
        let fields = fields(&base, &unc);
        // A coefficient whose basis function is 0 everywhere (the sine of k = 0) moves nothing.
        let coefs = fields.iter().enumerate().flat_map(|(f, fl)| {
            (0..fl.coefs).filter(move |&j| fl.terms.iter().any(|t| t.weights[j] != 0.0)).map(move |j| (f, j))
        });
        let unknowns: Vec<Unknown> = coefs
            .map(|(field, j)| Unknown::Coef { field, j })
            .chain((0..unc.params.len()).map(Unknown::Group))
            .collect();
        let every = p.idx.len().div_ceil(ROWS).max(1);
        let rows: Vec<usize> = p.idx.iter().copied().step_by(every).collect();
        let w = (0..p.meas.len()).map(|c| rows.iter().map(|&t| p.weights.at(c, t)).collect()).collect();
        let bar = o.min_reduction_of_noise * (rows.len() * p.meas.len()) as f64;
        Ok(Self {
            twin,
            p,
            o,
            fx,
            base,
            unc,
            fields,
            unknowns,
            rows,
            w,
            free: Vec::new(),
            prior: 1.0 / every as f64,
            bar,
        })
    }

    /// The same runs, prior and rows with the library parameters `free` refitted beside
    /// the fields and groups (their unknowns follow the nuisance's).
    fn with_free(&self, free: Vec<(ParamSpec, f64)>) -> Self {
        let nuisance = self.unknowns.iter().filter(|u| !matches!(u, Unknown::Effect(_))).copied();
        let unknowns = nuisance.chain((0..free.len()).map(Unknown::Effect)).collect();
        Self {
            base: Arc::clone(&self.base),
            unc: self.unc.clone(),
            fields: self.fields.clone(),
            unknowns,
            rows: self.rows.clone(),
            w: self.w.clone(),
            free,
            ..*self
        }
    }

    /// Unknown `i`'s name: a field's coefficient `field[j]`, a group's first key or a
    /// library parameter.
    fn name(&self, i: usize) -> String {
        match self.unknowns[i] {
            Unknown::Coef { field, j } => format!("{}[{j}]", self.fields[field].name),
            Unknown::Group(g) => self.unc.params[g].keys.first().copied().unwrap_or("").to_string(),
            Unknown::Effect(k) => self.free[k].0.param.to_string(),
        }
    }

    /// The nuisance's units, each with its unknowns: a field (its coefficients) or a
    /// parameter group, named as [`Estimate::fields`] and [`Estimate::params`] name them.
    fn units(&self) -> Vec<(String, Vec<usize>)> {
        let mut units: Vec<(String, Vec<usize>)> = Vec::new();
        for (i, u) in self.unknowns.iter().enumerate() {
            let name = match *u {
                Unknown::Coef { field, .. } => self.fields[field].name.clone(),
                Unknown::Group(_) => self.name(i),
                Unknown::Effect(_) => continue,
            };
            match units.iter_mut().find(|(n, _)| *n == name) {
                Some((_, members)) => members.push(i),
                None => units.push((name, vec![i])),
            }
        }
        units
    }

    /// The model data at `x` (one value per unknown).
    fn data(&self, x: &[f64]) -> ModelData {
        let mut coefs: Vec<Vec<f64>> = self.fields.iter().map(|f| vec![0.0; f.coefs]).collect();
        let mut z = vec![0.0; self.unc.params.len()];
        for (u, v) in self.unknowns.iter().zip(x) {
            match *u {
                Unknown::Coef { field, j } => coefs[field][j] = *v,
                Unknown::Group(g) => z[g] = *v,
                Unknown::Effect(_) => {}
            }
        }
        apply(&self.base, &self.unc, &self.fields, &coefs, &z)
    }

    /// The free library parameters' values at `x`, within their bounds.
    fn values(&self, x: &[f64]) -> Vec<f64> {
        let at = self.unknowns.iter().zip(x).filter_map(|(u, v)| match *u {
            Unknown::Effect(k) => Some((k, *v)),
            _ => None,
        });
        at.map(|(k, v)| self.value(k, v)).collect()
    }

    /// Free library parameter `k`'s value at unknown `z` (its `delta`s from its start),
    /// within its bounds.
    fn value(&self, k: usize, z: f64) -> f64 {
        let (s, start) = &self.free[k];
        (start + s.delta * z).clamp(s.lower, s.upper)
    }

    /// The model's effects at `x`: the free library parameters at their values.
    fn effects(&self, x: &[f64]) -> Effects {
        let specs: Vec<&ParamSpec> = self.free.iter().map(|(s, _)| s).collect();
        with_values(&self.fx, &specs, &self.values(x))
    }

    /// The model's outputs on the rows at `x`.
    fn outputs(&self, x: &[f64]) -> Result<Outputs, String> {
        self.outputs_with(&Arc::new(self.data(x)), self.effects(x))
    }

    /// The member of the set the fit at `at` needs least, if it needs it less than the
    /// bar: for each cause among the free parameters, the penalised energy its return to
    /// the model's value costs with every other unknown following (`u' Σ⁻¹ u`, `Σ` its
    /// block of the inverse normal matrix `g` at `at`, `u` its shift in `delta`s).
    fn redundant(&self, at: &Point, g: &[f64]) -> Result<Option<String>, String> {
        let n = self.unknowns.len();
        let values = self.values(&at.x);
        let mut least: Option<(f64, &str)> = None;
        let mut causes: Vec<&str> = self.free.iter().map(|(s, _)| s.cause).collect();
        causes.dedup();
        for cause in causes {
            let k: Vec<usize> = (0..self.free.len()).filter(|&j| self.free[j].0.cause == cause).collect();
            let pos: Vec<usize> = k.iter().map(|&j| n - self.free.len() + j).collect();
            let cols = pos.iter().map(|&i| {
                let mut e = vec![0.0; n];
                e[i] = 1.0;
                solve_spd(g, &e, 1e-12).ok_or("the set's normal equations are singular")
            });
            let cols: Vec<Vec<f64>> = cols.collect::<Result<_, _>>()?;
            let sigma: Vec<f64> = pos.iter().flat_map(|&i| cols.iter().map(move |c| c[i])).collect();
            let u: Vec<f64> = k
                .iter()
                .map(|&j| (values[j] - current_value(&self.fx, &self.free[j].0)) / self.free[j].0.delta)
                .collect();
            // Σ is a block of an SPD inverse: should its solve fail numerically, the member stays.
            let Some(w) = solve_spd(&sigma, &u, 1e-12) else { continue };
            let cost: f64 = u.iter().zip(&w).map(|(a, b)| a * b).sum();
            if least.is_none_or(|(c, _)| cost < c) {
                least = Some((cost, cause));
            }
        }
        Ok(least.filter(|(c, _)| *c < self.bar).map(|(_, cause)| cause.to_string()))
    }

    /// Each unknown's prior precision: none on the library's parameters.
    fn precision(&self, i: usize) -> f64 {
        match self.unknowns[i] {
            Unknown::Effect(_) => 0.0,
            _ => self.prior,
        }
    }

    /// The prior's penalty of unknown `i` at `v`: its precision, and beyond [`WALL`] σ
    /// the wall's, the material bar per σ² beyond it.
    fn penalty(&self, i: usize, v: f64) -> f64 {
        let beyond = self.beyond_wall(i, v);
        self.precision(i) * v * v + self.bar * beyond * beyond
    }

    /// How far [σ] unknown `i` at `v` is beyond the wall (0 for the library's parameters).
    fn beyond_wall(&self, i: usize, v: f64) -> f64 {
        match self.precision(i) {
            0.0 => 0.0,
            _ => (v.abs() - WALL).max(0.0),
        }
    }

    /// The side of the wall unknown `i` at `z` is beyond (−1, 1), 0 inside it.
    fn side(&self, i: usize, z: f64) -> f64 {
        match self.beyond_wall(i, z) > 0.0 {
            true => z.signum(),
            false => 0.0,
        }
    }

    /// Half the penalty's second derivative with unknown `i` landing at `z` (the normal
    /// matrix' diagonal term): the wall's where `z` is beyond it.
    fn curvature(&self, i: usize, z: f64) -> f64 {
        self.precision(i) + self.side(i, z).abs() * self.bar
    }

    /// Half the penalty's first derivative at `v` on the quadratic piece where `z` lands
    /// (what the prior takes off the gradient); `pull(i, v, v)` is the derivative at `v`.
    fn pull(&self, i: usize, v: f64, z: f64) -> f64 {
        let side = self.side(i, z);
        self.precision(i) * v + side.abs() * self.bar * (v - side * WALL)
    }

    /// As [`Problem::outputs`] with effects `fx`.
    fn outputs_with(&self, d: &Arc<ModelData>, fx: Effects) -> Result<Outputs, String> {
        let y = self.twin.run_data(d, &fx, self.p.stride)?;
        Ok(y.iter().map(|s| self.rows.iter().map(|&t| f64::from(s[t])).collect()).collect())
    }

    /// A run's change from outputs `y0` on the rows (an empty run: none).
    fn change(&self, y: Vec<Vec<f32>>, y0: &Outputs) -> Outputs {
        if y.is_empty() {
            return vec![vec![0.0; self.rows.len()]; y0.len()];
        }
        let at = y.iter().zip(y0);
        at.map(|(s, b)| self.rows.iter().zip(b).map(|(&t, v)| f64::from(s[t]) - v).collect()).collect()
    }

    /// `C'WC` of columns `cols` with the prior's curvature at `x` on the diagonal (`n x n`).
    fn gram(&self, cols: &[Outputs], x: &[f64]) -> Result<Vec<f64>, String> {
        let n = cols.len();
        let mut g = self.products(cols, cols)?;
        for i in 0..n {
            // The lower triangle is what the solves read; the product's rounding may
            // differ by a bit between the two.
            for j in 0..i {
                g[j * n + i] = g[i * n + j];
            }
            g[i * n + i] += match self.curvature(i, x[i]) {
                // Conditioning only: a library parameter carries no prior.
                0.0 => 1e-9 * g[i * n + i].max(1e-12),
                p => p,
            };
        }
        Ok(g)
    }

    /// `A'WB` of columns `a` and `b` on the rows read, row-major `a.len() x b.len()`
    /// ([`weighted_products`]: the estimate's Jacobian has a few hundred columns).
    fn products(&self, a: &[Outputs], b: &[Outputs]) -> Result<Vec<f64>, String> {
        fn slices(v: &[Outputs]) -> Vec<&[Vec<f64>]> {
            v.iter().map(Vec::as_slice).collect()
        }
        weighted_products(&slices(a), &slices(b), &self.w)
            .ok_or_else(|| "a column is not shaped as the rows read".into())
    }

    fn residual(&self, y: &Outputs) -> Outputs {
        let meas = self.p.meas.iter().zip(y);
        meas.map(|(m, s)| self.rows.iter().zip(s).map(|(&t, v)| m[t] - v).collect()).collect()
    }

    /// `Σ w a b` over channels and rows.
    fn dot(&self, a: &Outputs, b: &Outputs) -> f64 {
        let per = a.iter().zip(b).zip(&self.w);
        per.map(|((x, y), w)| x.iter().zip(y).zip(w).map(|((u, v), q)| q * u * v).sum::<f64>()).sum()
    }

    /// The penalised energy: the weighted residual's plus the prior's.
    fn objective(&self, r: &Outputs, x: &[f64]) -> f64 {
        self.dot(r, r) + x.iter().enumerate().map(|(i, v)| self.penalty(i, *v)).sum::<f64>()
    }

    /// Per channel, the weighted energy per row.
    fn energies(&self, r: &Outputs) -> Vec<f64> {
        let n = self.rows.len().max(1) as f64;
        r.iter()
            .zip(&self.w)
            .map(|(rc, wc)| rc.iter().zip(wc).map(|(v, q)| q * v * v).sum::<f64>() / n)
            .collect()
    }

    /// The outputs' change per unit of every unknown at `x` (finite differences of
    /// [`STEP`] σ, or one `delta` of a library parameter or its
    /// [`ParamSpec::slope_step`], central for those as the refit's, in parallel); an
    /// unknown that changes only what these runs never read responds 0.
    fn jacobian(&self, x: &[f64], y0: &Outputs) -> Result<Vec<Outputs>, String> {
        let d0 = self.data(x);
        let (h, central) = self.differences(x);
        let n = self.unknowns.len();
        let jobs: Vec<(usize, f64)> =
            (0..n).map(|i| (i, h[i])).chain((0..n).filter(|&i| central[i]).map(|i| (i, -h[i]))).collect();
        let runs = run_each(&jobs, self.o, |&(i, by)| {
            let mut xi = x.to_vec();
            xi[i] += by;
            let d = self.data(&xi);
            let unread = match self.unknowns[i] {
                Unknown::Effect(k) => self.p.unread.param(&self.free[k].0),
                _ => self.p.unread.only_unread_differ(&d0, &d),
            };
            match unread {
                true => Ok(Vec::new()),
                false => self.twin.run_data(&Arc::new(d), &self.effects(&xi), self.p.stride),
            }
        });
        let mut runs = runs.into_iter();
        let mut cols: Vec<Outputs> = Vec::with_capacity(n);
        for _ in 0..n {
            cols.push(self.change(runs.next().unwrap_or_else(|| Ok(Vec::new()))?, y0));
        }
        for i in (0..n).filter(|&i| central[i]) {
            let below = self.change(runs.next().unwrap_or_else(|| Ok(Vec::new()))?, y0);
            for (c, b) in cols[i].iter_mut().zip(below) {
                c.iter_mut().zip(b).for_each(|(v, w)| *v -= w);
            }
        }
        let span = |i: usize| if central[i] { 2.0 * h[i] } else { h[i] };
        let per_unit = |c: Outputs, h: f64| -> Outputs {
            c.into_iter().map(|v| v.into_iter().map(|d| d / h).collect()).collect()
        };
        Ok(cols.into_iter().enumerate().map(|(i, c)| per_unit(c, span(i))).collect())
    }

    /// Each unknown's finite-difference step at `x` and whether it is taken both ways:
    /// a library parameter the model is linear in between whole steps (a sensor delay)
    /// kinks at every whole step, where a one-sided difference sees only its side.
    fn differences(&self, x: &[f64]) -> (Vec<f64>, Vec<bool>) {
        let dt = self.twin.dt_s();
        let at = |u: &Unknown, z: f64| match *u {
            Unknown::Effect(k) => {
                let s = &self.free[k].0;
                let below = |h: f64| self.value(k, z) - h >= s.lower;
                s.slope_step(dt).map_or((1.0, false), |h| (h / s.delta, below(h)))
            }
            _ => (STEP, false),
        };
        self.unknowns.iter().zip(x).map(|(u, z)| at(u, *z)).unzip()
    }

    /// The right-hand side of a step from `x` with columns `cols` and residual `r`:
    /// `C'W r` less the prior's pull at `x` (the normal matrix is [`Problem::gram`]).
    fn gradient(&self, cols: &[Outputs], r: &Outputs, x: &[f64]) -> Result<Vec<f64>, String> {
        let b = self.data_gradient(cols, r)?.into_iter().zip(x).enumerate();
        Ok(b.map(|(i, (b, v))| b - self.pull(i, *v, *v)).collect())
    }

    /// `C'W r`: the data's part of [`Problem::gradient`].
    fn data_gradient(&self, cols: &[Outputs], r: &Outputs) -> Result<Vec<f64>, String> {
        self.products(cols, std::slice::from_ref(r))
    }

    /// The Gauss–Newton step from `x`: minimises `|r − C dx|²_W` plus the prior's penalty
    /// at `x + dx`. The penalty is quadratic on each side of the wall, so the step is
    /// solved with the piece where it lands until that no longer changes (an active set;
    /// solving with the piece at `x` alone stepped across the wall and back, case 505,576).
    fn step(&self, cols: &[Outputs], r: &Outputs, x: &[f64]) -> Option<Vec<f64>> {
        let mut g = self.gram(cols, x).ok()?;
        let data = self.data_gradient(cols, r).ok()?;
        let (n, mut z) = (x.len(), x.to_vec());
        for _ in 0..ACTIVE_SET_SOLVES {
            let b: Vec<f64> = (0..n).map(|i| data[i] - self.pull(i, x[i], z[i])).collect();
            let next: Vec<f64> = x.iter().zip(solve_spd(&g, &b, 1e-12)?).map(|(a, d)| a + d).collect();
            let moved: Vec<usize> = (0..n).filter(|&i| self.side(i, next[i]) != self.side(i, z[i])).collect();
            for &i in &moved {
                g[i * n + i] += self.curvature(i, next[i]) - self.curvature(i, z[i]);
            }
            z = next;
            if moved.is_empty() {
                break;
            }
        }
        Some(z)
    }
}

/// Most solves of one step's active set (each a linear solve, no simulation).
const ACTIVE_SET_SOLVES: usize = 20;

/// Estimate the maps and parameters within their stated uncertainty on `meas`
/// (`[channel][sample]`, channels as `twin.channels()`), the model's effects
/// (`o.base`) held as they are, on `o.threads` workers; the set beyond it starts from the
/// ordinary verdict's (`proposed`: [`crate::Diagnosis::proposed`]).
pub fn estimate_within_uncertainty(
    twin: &dyn Twin,
    meas: &[Vec<f64>],
    o: &Options,
    (proposed, unnamed): (&Effects, Option<&crate::Unnamed>),
) -> Result<Estimate, String> {
    let run = || estimate(twin, &prepare(twin, meas, o)?, o, (o.base, proposed, unnamed));
    match rayon::ThreadPoolBuilder::new().num_threads(o.threads.max(1)).build() {
        Ok(pool) => pool.install(run),
        Err(_) => run(),
    }
}

/// Estimate the maps and parameters within their stated uncertainty on the prepared
/// runs, the model's effects `fx` held as they are; then, while a library cause adds
/// beyond the estimate, take the best and estimate again from the identified data with
/// the set so far freed beside the maps (forward selection, the whole set refitted at
/// each stage). From the identified data, not from the estimate: the estimate has taken
/// part of a missing effect into the maps, which holds the effect's refit in a local
/// minimum (a 120 ms controller delay beside perturbed maps, case 1,007,743: from the
/// estimate the refit stays at 37 ms, penalised energy 72,139; from the identified data it
/// reaches 124 ms, 40,756, and no rate scale is credited after it).
///
/// The selection's first stage is the ordinary verdict's set (`proposed`, beside the
/// model's effects `fx`), where it proposes one: the estimate takes into the maps, within
/// their uncertainty, part of an effect the verdict read on the identified maps, and
/// forward selection from the estimate alone then lost it (60 tuning cases 505,531–505,590:
/// found beside identified maps 11 of 19 against the verdict's 17). Its members are
/// dropped only where the refit no longer needs them ([`Problem::redundant`]): the
/// interval rule dropped a hidden axle friction scale the estimate alone credited 3,176
/// beyond itself (505,538).
///
/// Where the verdict names nothing, the candidate it could not name (`unnamed`, the
/// diagnosis' [`Diagnosis::unnamed`]) is that first stage instead. One that counts but
/// explains too little of the run to be named is taken as the verdict's: it was read on
/// the identified maps as the verdict's are. Rerun on 14 proof cases where it was taken
/// (11 holding it hidden): judged as any other cause, one hidden effect was lost and both
/// false claims it made (1,008,909, 1,009,440) stayed; not taken at all, five hidden
/// effects were lost and the two false claims went. One refused only for making a
/// channel worse is judged as any other: a wrong map can cancel part of a real effect's
/// error, so that the effect alone trades one run's error for another's; beside the maps
/// estimated within their uncertainty the trade either goes or the estimate is refused
/// ([`Estimate::refused`]). Proofs 31–33 missed a hidden connector resistance so twice
/// (1,009,001, 1,009,143: refused as making I_DPU 2.7 1.15x and 1.20x worse beside
/// perturbed maps) while the estimate moved the identified resistance to the truth.
///
/// [`Diagnosis::unnamed`]: crate::Diagnosis::unnamed
pub(super) fn estimate(
    twin: &dyn Twin,
    p: &Prepared,
    o: &Options,
    (fx, proposed, unnamed): (Effects, &Effects, Option<&crate::Unnamed>),
) -> Result<Estimate, String> {
    let pb = Problem::new(twin, p, o, fx)?;
    let fit = pb.fit(vec![0.0; pb.unknowns.len()])?;
    let (each, picks) = credit::round(&pb, &fit.best, &[], true)?;
    let mut credits = credit::Credits { each, ..Default::default() };
    let first = credit::first_stage(&pb, proposed, true)
        .or_else(|| credit::first_stage(&pb, &unnamed?.effects, unnamed?.counts));
    let (picks, fallback) = match first {
        Some(v) => (vec![v], picks),
        None => (picks, Vec::new()),
    };
    select(&pb, picks, fallback, &mut credits)?;
    let mut e = summarise(&pb, &fit, credits);
    e.refused = refused(&pb, &e)?;
    Ok(e)
}

/// Why the estimate (with its set where one stands) must not be adopted, by the
/// verdict's tests: an estimate alone that has not settled is still moving; one that
/// makes a channel worse on some run trades that run's error for another's (the three
/// dishonest cases of proof 28, 1,008,371, 1,008,375 and 1,008,388, went on from such an
/// estimate, with no credited set, and ended with powers 2x worse).
fn refused(pb: &Problem, e: &Estimate) -> Result<Option<String>, String> {
    if e.with_set.is_none() && !e.settled {
        return Ok(Some("the estimate has not settled".into()));
    }
    let (data, fx) = e.model(pb.fx);
    let sim = pb.twin.run_data(data, &fx, pb.p.stride)?;
    let worse = said_worse(pb.p, &sim, pb.o);
    Ok(worse.map(|w| format!("the estimated model is a trade, not an explanation: {w}")))
}

/// Forward selection with backward elimination from `picks` (the verdict's set, or the
/// first round's causes, best first): each cause taken, the set refitted with the maps
/// from the identified data — and with each of the round's other confirmed causes in its
/// place, the refit of lowest penalised energy kept ([`Credits::lost_to`]); a member the
/// refit no longer needs ([`Problem::redundant`]) or cannot tell from absent
/// ([`Problem::unsupported`], not the verdict's) or whose parameter drifts beside the
/// estimated maps ([`Problem::drifting`], not the verdict's) dropped and the rest
/// refitted; the next
/// round at the refit, the causes taken or dropped excluded, and the lag or delay of a
/// channel whose delay or lag was ([`sibling_taken`]); at most [`MAX_SET`] taken.
/// Where every member is dropped, the selection starts again from `fallback` (the first
/// round's causes at the estimate, when `picks` is the verdict's set), the dropped
/// excluded with the faults of their channels ([`gone_with`]): a dropped verdict's set
/// says nothing against the estimate's own causes (a
/// false regeneration efficiency dropped, and a hidden 4.6 N m differential friction
/// credited 3,498 beyond the estimate never tried, tuning case 505,667).
/// A set stands only where its refit settled: a refit that does not leaves the set as it
/// was before that cause, the cause and those with it reported as provisional (an
/// estimate that had not settled either, 2 of the 65 nothing-hidden kept cases, credits
/// nothing; one that settles once the cause is beside it credits the cause).
///
/// [`Credits::lost_to`]: credit::Credits::lost_to
fn select(
    pb: &Problem,
    mut picks: Vec<credit::Pick>,
    mut fallback: Vec<credit::Pick>,
    credits: &mut credit::Credits,
) -> Result<(), String> {
    let mut taken = Vec::<String>::new();
    // The channels of the measurement-chain causes dropped ([`gone_with`]).
    let mut chains = Vec::<&str>::new();
    let mut settled = Vec::new();
    // The last settled refit and its intervals: the set's model, energies and intervals
    // are taken there.
    let mut last: Option<(Problem, Point, Vec<[f64; 2]>)> = None;
    'taking: while taken.len() < MAX_SET {
        let mut options = std::mem::take(&mut picks).into_iter();
        let Some(next) = options.next() else { break };
        let mut rivals: Vec<credit::Pick> = options.collect();
        let newest: Vec<String> = next.credits.iter().map(|c| c.cause.clone()).collect();
        taken.extend(newest.iter().cloned());
        credits.set.extend(next.credits);
        let mut free = next.free;
        // The refit without a member just dropped, made by the located test.
        let mut ready: Option<(Problem, Fit)> = None;
        loop {
            let (stage, refit, won) = match ready.take() {
                Some((stage, refit)) => (stage, refit, None),
                None => refitted(pb, free, std::mem::take(&mut rivals))?,
            };
            if let Some(won) = won {
                let names: Vec<String> = won.iter().map(|c| c.cause.clone()).collect();
                credits.lost_to.extend(newest.iter().map(|c| (c.clone(), names.join(" + "))));
                credits.set.retain(|c| !newest.contains(&c.cause));
                taken.retain(|c| !newest.contains(c));
                taken.extend(names);
                credits.set.extend(won);
            }
            let values = stage.values(&refit.best.x);
            credit::set_values(&mut credits.set, &stage.free, &values);
            if !refit.settled {
                let all = std::mem::replace(&mut credits.set, settled);
                credits.provisional =
                    all.into_iter().filter(|c| credits.set.iter().all(|k| k.cause != c.cause)).collect();
                break 'taking;
            }
            let verdict: Vec<&str> =
                credits.set.iter().filter(|c| c.verdict).map(|c| c.cause.as_str()).collect();
            let found = stage.needless(&refit.best, &values, &verdict)?;
            credits.located.extend(found.located.filter(|c| !credits.located.contains(c)));
            let Some((cause, drifts)) = found.drop else {
                settled = credits.set.clone();
                let names: Vec<&str> = taken.iter().map(String::as_str).collect();
                picks = credit::round(&stage, &refit.best, &names, false)?.1;
                picks.retain(|p| !p.free.iter().any(|(s, _)| sibling_taken(s, &taken)));
                last = Some((stage, refit.best, found.intervals));
                break;
            };
            credits.set.retain(|c| c.cause != cause);
            let on = stage.free.iter().filter(|(s, _)| s.cause == cause && s.is_chain());
            chains.extend(on.map(|(s, _)| s.param));
            match drifts {
                Some(why) => credits.drifting.push((cause.clone(), why)),
                None => credits.dropped.push(cause.clone()),
            }
            free = stage.free_without(&values, &cause);
            ready = found.without;
            if free.is_empty() {
                let open = |p: &credit::Pick| !p.free.iter().any(|(s, _)| gone_with(s, &taken, &chains));
                picks = std::mem::take(&mut fallback).into_iter().filter(open).collect();
                continue 'taking;
            }
        }
    }
    if let Some((stage, at, intervals)) = last.filter(|_| !credits.set.is_empty()) {
        credits.after_set = stage.energies(&at.r);
        credits.with_set = Some((stage.data(&at.x), stage.effects(&at.x)));
        credit::set_intervals(&mut credits.set, &stage.free, &intervals);
    }
    Ok(())
}

/// Whether the parameter `s` goes with the causes `taken` (and dropped): one of theirs,
/// or a measurement-chain fault of a channel in `chains` (those of the dropped chain
/// causes; a chain parameter's name is its channel). The estimate explained what a
/// dropped sensor cause fitted on its channel; another fault of that channel is the
/// same story told again: a C_Kistler_L delay after its dropped lag (tuning case
/// 505,621), a V_DC gain after a dropped V_DC offset where neither was hidden (proof 29's
/// kept cases 1,008,713 and 1,008,719, read for this rule: later proofs start above them).
fn gone_with(s: &ParamSpec, taken: &[String], chains: &[&str]) -> bool {
    taken.iter().any(|t| t == s.cause) || (s.is_chain() && chains.contains(&s.param))
}

/// Whether the cause `s` belongs to is the lag or delay of a channel whose delay or lag
/// ([`sibling`]) the set has `taken`: the two fit alike on that channel (the ordinary
/// verdict names neither where they do), so the second tells the first's story again and
/// the refit then drops one of the two by chance. Proof 35's 1,009,341 (read since, as a
/// tuning case) took a hidden C_Kistler_L lag first (credit 504, its delay its losing
/// rival), then the delay beside it, dropped the lag as redundant and claimed the delay,
/// 0.0188 s for the lag's 0.0207 s.
fn sibling_taken(s: &ParamSpec, taken: &[String]) -> bool {
    sibling(s.cause).is_some_and(|sib| taken.contains(&sib))
}

/// What [`Problem::needless`] finds at a settled refit.
struct Needless<'a> {
    /// A member to drop, with why where it drifts.
    drop: Option<(String, Option<String>)>,
    /// The set's 95 % intervals as reported ([`Problem::reported`]; empty where the refit
    /// no longer needs a member).
    intervals: Vec<[f64; 2]>,
    /// The member the refit needs least, kept for the located structure it clears.
    located: Option<String>,
    /// The set refitted without the member the refit no longer needs, where dropped.
    without: Option<(Problem<'a>, Fit)>,
}

impl<'a> Problem<'a> {
    /// A member of the set to drop, if any, with why where it drifts (`None`: the refit
    /// does not need it), and the 95 % intervals at the settled refit `at` (`values`: the
    /// free parameters there): one the refit needs least ([`Problem::redundant`]; then no
    /// intervals, a fold jackknife, and the refit without it) unless it clears located
    /// structure ([`Problem::without_located`]: then it is kept and named), else one the
    /// runs cannot tell from absent ([`Problem::unsupported`]) or whose value drifts
    /// ([`Problem::drifting`]), neither among the verdict's `kept`.
    fn needless(&self, at: &Point, values: &[f64], kept: &[&str]) -> Result<Needless<'a>, String> {
        let g = self.gram(&at.jacobian, &at.x)?;
        let mut located = None;
        if let Some(cause) = self.redundant(at, &g)? {
            let (pb, fit, clears) = self.without_located(at, values, &cause)?;
            if !clears {
                let (drop, without) = (Some((cause, None)), Some((pb, fit)));
                return Ok(Needless { drop, intervals: Vec::new(), located: None, without });
            }
            located = Some(cause);
        }
        let posterior = self.intervals(at, &g).ok_or("the set's normal equations are singular")?;
        let intervals = self.reported(at, &posterior);
        let drop = match self.unsupported(values, &intervals, kept) {
            Some(cause) => Some((cause, None)),
            None => self.drifting(at, kept)?.map(|(c, why)| (c, Some(why))),
        };
        Ok(Needless { drop, intervals, located, without: None })
    }

    /// The free library parameters without `cause`'s, each from its value in `values`.
    fn free_without(&self, values: &[f64], cause: &str) -> Vec<(ParamSpec, f64)> {
        let kept = self.free.iter().zip(values).filter(|((s, _), _)| s.cause != cause);
        kept.map(|((s, _), v)| (s.clone(), *v)).collect()
    }
}

/// The set with the library parameters `free` refitted with the maps from the identified
/// data, and each of the `rivals`' sets in its place: the refit of lowest penalised
/// energy (a settled one before one that did not settle), and the winning rival's causes
/// where one won.
fn refitted<'a>(
    pb: &Problem<'a>,
    free: Vec<(ParamSpec, f64)>,
    rivals: Vec<credit::Pick>,
) -> Result<(Problem<'a>, Fit, Option<Vec<Credit>>), String> {
    let stage = pb.with_free(free);
    let refit = stage.fit(vec![0.0; stage.unknowns.len()])?;
    let mut best = (stage, refit, None);
    for rival in rivals {
        let other = pb.with_free(rival.free);
        let fit = other.fit(vec![0.0; other.unknowns.len()])?;
        if fit.settled && (!best.1.settled || fit.best.energy < best.1.best.energy) {
            best = (other, fit, Some(rival.credits));
        }
    }
    Ok(best)
}

/// Most causes the forward selection takes.
const MAX_SET: usize = 4;

/// One evaluated point of the fit.
struct Point {
    x: Vec<f64>,
    y: Outputs,
    r: Outputs,
    /// The penalised energy there.
    energy: f64,
    /// The Jacobian there.
    jacobian: Vec<Outputs>,
}

/// The damped Gauss–Newton fit.
struct Fit {
    best: Point,
    /// Per channel energy per row with the identified data.
    before: Vec<f64>,
    /// The penalised energy at each evaluation.
    objective: Vec<f64>,
    settled: bool,
}

impl Problem<'_> {
    /// Evaluations from `x` until the fit settles ([`Settling`]), at most
    /// [`MAX_EVALUATIONS`]; a step that raises the penalised energy is taken back halfway
    /// towards the best point.
    fn fit(&self, mut x: Vec<f64>) -> Result<Fit, String> {
        let mut best: Option<Point> = None;
        let (mut objective, mut before, mut settled) = (Vec::new(), None, false);
        let mut settling = Settling::default();
        for _ in 0..MAX_EVALUATIONS {
            let y = self.outputs(&x)?;
            let r = self.residual(&y);
            let energy = self.objective(&r, &x);
            if !energy.is_finite() {
                return Err("the estimate of the maps within their uncertainty is not finite".into());
            }
            objective.push(energy);
            before.get_or_insert_with(|| self.energies(&r));
            let gain = match best.as_ref() {
                Some(b) if energy > b.energy => {
                    x = b.x.iter().zip(&x).map(|(a, c)| a + 0.5 * (c - a)).collect();
                    settled = settling.raised();
                    if settled {
                        break;
                    }
                    continue;
                }
                Some(b) => b.energy - energy,
                None => f64::INFINITY,
            };
            let jacobian = self.jacobian(&x, &y)?;
            let next = self.step(&jacobian, &r, &x).ok_or("the estimate's normal equations are singular")?;
            best = Some(Point { x: std::mem::replace(&mut x, next), y, r, energy, jacobian });
            if settling.accepted(gain, self.bar) {
                settled = true;
                break;
            }
        }
        let best = best.ok_or("no evaluation")?;
        Ok(Fit { best, before: before.unwrap_or_default(), objective, settled })
    }
}

/// The estimate's report at its best point.
fn summarise(pb: &Problem, fit: &Fit, credits: credit::Credits) -> Estimate {
    let mut sums = vec![(0.0, 0usize); pb.fields.len()];
    let mut params = Vec::new();
    for (u, v) in pb.unknowns.iter().zip(&fit.best.x) {
        match *u {
            Unknown::Coef { field, .. } => {
                sums[field].0 += v * v;
                sums[field].1 += 1;
            }
            Unknown::Group(g) => {
                let s = &pb.unc.params[g];
                params.push((s.keys.first().copied().unwrap_or("").to_string(), (s.sigma_ln * v).exp()));
            }
            Unknown::Effect(_) => {}
        }
    }
    let fields = pb.fields.iter().zip(sums).map(|(f, (s, n))| (f.name.clone(), (s / n.max(1) as f64).sqrt()));
    let names = pb.twin.channels().iter().map(|c| c.name().to_string());
    let after = pb.energies(&fit.best.r);
    let far = (0..pb.unknowns.len()).map(|i| (i, fit.best.x[i].abs())).max_by(|a, b| a.1.total_cmp(&b.1));
    let furthest = far.map_or((String::new(), 0.0), |(i, v)| (pb.name(i), v));
    Estimate {
        fields: fields.collect(),
        params,
        furthest,
        channels: names.zip(fit.before.iter().copied()).zip(after).map(|((n, b), a)| (n, b, a)).collect(),
        objective: fit.objective.clone(),
        settled: fit.settled,
        credits: credits.each,
        set: credits.set,
        after_set: credits.after_set,
        provisional: credits.provisional,
        dropped: credits.dropped,
        located: credits.located,
        lost_to: credits.lost_to,
        drifting: credits.drifting,
        bar: pb.bar,
        refused: None,
        data: Arc::new(labelled(&pb.base, pb.data(&fit.best.x))),
        with_set: credits.with_set.map(|(d, fx)| (Arc::new(labelled(&pb.base, d)), fx)),
    }
}

/// How an estimated table's comments say what it is.
pub const LABEL: &str =
    "# ESTIMATED within the stated uncertainty (simrod diagnose --maps-within-uncertainty): \
     the identified table moved by the runs under an ASSUMED prior, not an identification";

/// `data` with every table that differs from `base` labelled ([`LABEL`]; a parameter's
/// comment gets `ESTIMATED`).
fn labelled(base: &ModelData, mut data: ModelData) -> ModelData {
    let old = base.map_values();
    let (ones, twos) = data.maps_mut();
    for (k, m) in ones.into_iter().enumerate() {
        if m.y != old[k] {
            m.comments.push(LABEL.into());
        }
    }
    for (k, m) in twos.into_iter().enumerate() {
        if m.z != old[5 + k] {
            m.comments.push(LABEL.into());
        }
    }
    for (line, b) in data.params.iter_mut().zip(&base.params) {
        if let (ParamLine::Entry { value, comment, .. }, ParamLine::Entry { value: v0, .. }) = (line, b) {
            if value != v0 && !comment.contains("ESTIMATED") {
                comment.push_str(" ESTIMATED");
            }
        }
    }
    data
}

#[cfg(test)]
mod tests {
    use super::{gone_with, sibling_taken};
    use crate::engine::Options;
    use crate::library::{library, ParamSpec};

    fn spec(cause: &str) -> ParamSpec {
        let all = library(&Options::default().params);
        all.into_iter().find(|s| s.cause == cause).unwrap_or_else(|| panic!("no {cause}"))
    }

    #[test]
    fn a_dropped_sensor_cause_takes_its_channels_other_faults_with_it() {
        let taken = vec!["sensor_offset.v_dc".to_string(), "regen_efficiency".to_string()];
        let chains = ["v_dc"];
        let gone = |cause: &str| gone_with(&spec(cause), &taken, &chains);
        assert!(gone("sensor_offset.v_dc"));
        assert!(gone("sensor_gain.v_dc"));
        assert!(gone("regen_efficiency"));
        // Another channel's fault and a physical cause stay open.
        assert!(!gone("sensor_gain.v_dc_busbars"));
        assert!(!gone("sensor_gain.i_dc"));
        assert!(!gone("differential_friction"));
    }

    #[test]
    fn a_channels_lag_beside_its_taken_delay_is_its_story_told_again() {
        let taken = vec!["sensor_lag.c_kistler_l".to_string(), "controller_delay".to_string()];
        let again = |cause: &str| sibling_taken(&spec(cause), &taken);
        assert!(again("sensor_delay.c_kistler_l"));
        // The taken cause itself, another channel's delay, another fault of the channel
        // and a physical delay are not its sibling.
        assert!(!again("sensor_lag.c_kistler_l"));
        assert!(!again("sensor_delay.c_kistler_r"));
        assert!(!again("sensor_gain.c_kistler_l"));
        assert!(!again("controller_delay"));
    }
}
