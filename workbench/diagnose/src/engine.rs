//! Which physical effect is missing? A diagnosis runs as a sequence of stages, each in
//! its own module:
//!
//! 1. [`preparation`](super::preparation): the current model's residual and each
//!    channel's noise level, estimated from the residual minus its 0.25 s moving average
//!    (model errors are slow, measurement noise — even coloured by an encoder's counting
//!    window — is fast), so every channel enters the fit weighted by `1/σ²`; in a
//!    campaign, each run's samples by that run's own σ.
//! 2. [`sensitivities`](super::sensitivities): every measured channel's response to every
//!    library parameter (one simulation per parameter, in parallel).
//! 3. [`selection`](super::selection): score test and greedy orthogonal forward
//!    regression on the linearised model.
//!    A parameter whose objective has narrow valleys (a gear's free play) is scanned on
//!    its declared grid instead ([`scan`](super::scan)).
//!    A channel's delay and its lag, alike to first order, are told apart by refitting
//!    both ([`dynamics`](super::dynamics)).
//! 4. [`refit`](super::refit): Levenberg–Marquardt refit of the leaders on the real
//!    simulator; the error it removes, measured, not predicted.
//!    A sensor gain or offset the verdict may name that one shape of a map mimics is marked
//!    ([`alias`](super::alias)): the run cannot tell the sensor from a wrong map.
//! 5. [`uncertainty`](super::uncertainty): a sandwich (HAC) covariance with a positive
//!    semi-definite (Bartlett-tapered) noise correlation, widened to the spread of the
//!    estimates with one held-out fold left out (fold jackknife).
//! 6. [`confounding`](super::confounding): candidates whose predicted residual shapes
//!    nearly coincide, and the profile that best separates them.
//! 7. [`verdict`](super::verdict): missing, nothing missing, partial or unexplained.
//!
//! This module holds the public types and the orchestration.

use std::sync::Arc;

use model_core::{Channel, Effects, Params, SetPoints};
use simrod_io::datadir::ModelData;

use super::alias::{map_aliases, Shapes};
use super::confounding::{confounded_groups, Leaders};
pub use super::constancy::{Along, Drift};
use super::dynamics::{choose_dynamics, rank_alike, with_siblings};
use super::empirical::{correct, Empirical, Inputs as EmpiricalInputs};
use super::library::ParamSpec;
use super::preparation::{prepare, Prepared};
use super::refit::{confirm, refit, refit_alone, with_held, Fit, Held};
use super::scan::scan_valleys;
use super::selection::{close_runners_up, greedy, next_leaders, refit_list, score_effects};
use super::sensitivities::{sensitivities, Sensitivities};
use super::twin::Resumable;
use super::uncertainty::{joint_distance, parameter_std, Spread};
use super::verdict::{
    base_structure, conclude, stated, structure_in, table_beats_library, Evidence, Verdict,
    PREFER_TABLE_MARGIN,
};

/// Something that simulates the measured channels for given effects.
pub trait Twin: Sync {
    /// Channels returned by [`Twin::run`], in order.
    fn channels(&self) -> &[Channel];
    /// Samples per channel.
    fn samples(&self) -> usize;
    /// Sample interval [s].
    fn dt_s(&self) -> f64;
    /// Simulated `[channel][sample]`.
    fn run(&self, fx: &Effects) -> Result<Vec<Vec<f32>>, String>;

    /// Per channel, the largest error its sensor makes by design (a tachometer: one
    /// count per window), [unit]; 0 for none. Structure within it is not a model error.
    fn resolution(&self) -> Vec<f64> {
        vec![0.0; self.channels().len()]
    }

    /// Per channel, the noise σ its sensor is stated to have on each sample (`None`: not
    /// stated; then only the residual tells the noise).
    fn stated_sigma(&self) -> Vec<Option<Vec<f64>>> {
        vec![None; self.channels().len()]
    }

    /// Samples of each recorded run, in order (one run: all of them). Held-out
    /// validation leaves one run out at a time when there are several.
    fn segments(&self) -> Vec<usize> {
        vec![self.samples()]
    }

    /// Keep the physical values of a run with `fx`, so that effects differing from `fx`
    /// only in the measurement chain are replayed, not simulated (a twin that cannot
    /// does nothing). The results are the same either way.
    fn hold_physics(&self, fx: &Effects) -> Result<(), String> {
        let _ = fx;
        Ok(())
    }

    /// Every `stride`-th sample of [`Twin::run`] (from the first): what the fits read.
    /// A long run's full output is then held only while it is reduced.
    fn run_every(&self, fx: &Effects, stride: usize) -> Result<Vec<Vec<f32>>, String> {
        Ok(self.run(fx)?.into_iter().map(|c| every(c, stride)).collect())
    }

    /// The model data the twin runs on (its `--data-dir`, or the built-in data), for an
    /// empirical correction of its maps; `None`: this twin's maps cannot be changed.
    fn data(&self) -> Option<Arc<ModelData>> {
        None
    }

    /// The recorded set points, one per sample (the maps' inputs); empty when unknown.
    fn set_points(&self) -> Vec<SetPoints> {
        Vec::new()
    }

    /// As [`Twin::run_every`] on other model data (an empirically corrected copy).
    fn run_data(&self, data: &Arc<ModelData>, fx: &Effects, stride: usize) -> Result<Vec<Vec<f32>>, String> {
        let _ = (data, fx, stride);
        Err("this twin runs on its own data only".into())
    }

    /// The run of `fx` on `data` at `stride` with its state kept along each run, for
    /// [`Twin::run_data_from`]; `None` for a twin that keeps none.
    fn checkpointed(&self, data: &Arc<ModelData>, fx: &Effects, stride: usize) -> Option<Resumable> {
        let _ = (data, fx, stride);
        None
    }

    /// As [`Twin::run_data`] on `data` with `base`'s effects and stride, where `data`
    /// differs from `base`'s data only in values run `i` ([`Twin::segments`] order)
    /// first reads at its step `first[i]` (`None`: never): each run is `base`'s up to
    /// its last checkpoint before that step and simulated from there, the same bits as
    /// simulated whole (a value not yet read cannot have changed anything).
    fn run_data_from(
        &self,
        data: &Arc<ModelData>,
        fx: &Effects,
        base: &Resumable,
        first: &[Option<usize>],
    ) -> Result<Vec<Vec<f32>>, String> {
        let _ = (data, fx, base, first);
        Err("this twin keeps no checkpoints".into())
    }
}

/// Every `stride`-th value of `v`, from the first (`v` itself for a stride of 1).
pub(crate) fn every<T: Copy>(v: Vec<T>, stride: usize) -> Vec<T> {
    if stride <= 1 {
        return v;
    }
    v.into_iter().step_by(stride).collect()
}

/// Tuning of a diagnosis; the defaults are what `simrod diagnose` uses.
#[derive(Debug, Clone)]
pub struct Options {
    /// Effects already in the model (the user's current effect file).
    pub base: Effects,
    /// Model parameters (for neutral values of overrides).
    pub params: Params,
    /// Greedy selection steps.
    pub max_selected: usize,
    /// Candidates refitted on the simulator.
    pub refit: usize,
    /// Worker threads.
    pub threads: usize,
    /// Show a progress bar of the simulations on stderr (drawn only on a terminal).
    pub progress: bool,
    /// Most samples used in the regressions (the series is strided down to this).
    pub max_fit_samples: usize,
    /// Residual energy over the noise expectation up to which a residual is noise-like.
    pub noise_like_ratio: f64,
    /// Least energy an effect must remove, as a share of the noise energy, to count
    /// (chance fits of autocorrelated noise stay far below this).
    pub min_reduction_of_noise: f64,
    /// Share of the excess error an effect must remove to be named.
    pub explain_fraction: f64,
    /// Below this share the residual is called unexplained.
    pub unexplained_fraction: f64,
    /// Cosine above which two candidates' predicted residuals are called confounded.
    pub confounded_cosine: f64,
    /// Operating regions, `(name, mask over the samples)`, for the per-region error each
    /// candidate removes (e.g. from `compare::regions`); empty for none.
    pub regions: Vec<(String, Vec<bool>)>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            base: Effects::NONE,
            params: Params::default(),
            max_selected: 3,
            refit: 3,
            threads: std::thread::available_parallelism().map_or(2, |n| n.get()).min(8),
            progress: false,
            max_fit_samples: 12_000,
            noise_like_ratio: 1.2,
            min_reduction_of_noise: 0.01,
            explain_fraction: 0.6,
            unexplained_fraction: 0.3,
            confounded_cosine: 0.9,
            regions: Vec::new(),
        }
    }
}

/// A fitted parameter.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FittedParam {
    /// Parameter name.
    pub name: &'static str,
    /// Fitted value.
    pub value: f64,
    /// Value before the fit (neutral or current).
    pub start: f64,
    /// Standard deviation as reported (`uncertainty`: the larger of the sandwich's and the
    /// fold jackknife's, widened by the Birge ratio of what the fit leaves, with the
    /// bounded errors added); `f64::INFINITY` when the run does not determine the
    /// parameter; `NaN` when not refitted.
    pub std: f64,
    /// Of `std`, the part the identified data's stated uncertainty contributes
    /// ([`super::systematic`], added in quadrature); 0 when none, NaN when not refitted.
    pub std_data: f64,
    /// 95 % interval of the truth (value ± 1.96 std, less the centre of a step bias of
    /// known sign: [`ParamSpec::ci95`], clipped to bounds; NaN when not refitted).
    pub ci95: (f64, f64),
    /// Unit.
    pub unit: &'static str,
}

impl FittedParam {
    /// Parameter `sp` refitted to `value` from `start`, with the σ reported (and its
    /// data part) and the 95 % interval clipped to the bounds.
    pub(super) fn refitted(sp: &ParamSpec, value: f64, (std, std_data): (f64, f64), start: f64) -> Self {
        FittedParam { name: sp.param, value, start, std, std_data, ci95: sp.ci95(value, std), unit: sp.unit }
    }
}

/// Parameters `specs` (with `values`, σ `std`, its data part `data` and `starts` alike)
/// as [`Stated`] entries, one per cause, in order of first appearance.
pub(super) fn by_cause(
    specs: &[&ParamSpec],
    values: &[f64],
    (std, data): (&[f64], &[f64]),
    starts: &[f64],
) -> Vec<Stated> {
    let mut out: Vec<Stated> = Vec::new();
    for (k, sp) in specs.iter().enumerate() {
        let (Some(&v), Some(&sd), Some(&s0)) = (values.get(k), std.get(k), starts.get(k)) else { continue };
        let fp = FittedParam::refitted(sp, v, (sd, data.get(k).copied().unwrap_or(0.0)), s0);
        match out.iter_mut().find(|st| st.effect == sp.cause) {
            Some(st) => st.params.push(fp),
            None => out.push(Stated { effect: sp.cause, params: vec![fp] }),
        }
    }
    out
}

/// An effect the verdict names, as it states it: the values `--write-effects` writes
/// (the set's joint refit when a set is named, else the effect's own refit) with the
/// uncertainty stated beside them. A set member's own refit, in the ranking, is another
/// value: it was fitted without the other members.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Stated {
    /// Effect (or one channel's sensor cause) as the ranking names it.
    pub effect: &'static str,
    /// Its parameters as proposed.
    pub params: Vec<FittedParam>,
}

/// Error of one channel before and after adding the effect.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ChannelChange {
    /// Channel name.
    pub channel: &'static str,
    /// RMSE with the current model.
    pub rmse_before: f64,
    /// RMSE predicted by the linear fit.
    pub rmse_predicted: f64,
    /// RMSE after the refit, on the simulator (if refitted).
    pub rmse_confirmed: Option<f64>,
}

/// Error in one operating region before and after adding an effect, as weighted mean
/// squared error over the region's samples and channels (1.0 = the noise level).
#[derive(Debug, Clone, serde::Serialize)]
pub struct RegionChange {
    /// Region name.
    pub region: String,
    /// Share of the samples in the region.
    pub samples: f64,
    /// With the current model.
    pub before: f64,
    /// Predicted by the linear fit.
    pub predicted: f64,
    /// After the refit, on the simulator (if refitted).
    pub confirmed: Option<f64>,
}

/// One candidate effect.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Candidate {
    /// Effect id.
    pub effect: &'static str,
    /// Fitted parameters.
    pub params: Vec<FittedParam>,
    /// Share of the excess (above-noise) weighted error removed, linear prediction.
    pub predicted_reduction: f64,
    /// The same, measured on the simulator after the refit.
    pub confirmed_reduction: Option<f64>,
    /// Weighted squared error after the refit: what tells two candidates apart that both
    /// remove all of the excess (a delay and a lag on a slow channel).
    pub energy_after: Option<f64>,
    /// Some parameter differs from its start by more than 2 (finite) standard deviations.
    pub significant: bool,
    /// Per-channel errors.
    pub channels: Vec<ChannelChange>,
    /// Per-region errors (when regions were given).
    pub regions: Vec<RegionChange>,
    /// The channels it moves (each at least [`MOVES_SHARE`] of its weighted
    /// sensitivity); one alone: a sensor cause, several: a physical one.
    pub moves: Vec<&'static str>,
    /// After its refit, whether structure is left in some channel's residual (`None`:
    /// not refitted).
    pub leaves_structure: Option<bool>,
    /// After its refit, a parameter whose value changes steadily over the run: not a
    /// constant effect but the average of a time-varying one.
    pub drift: Option<Drift>,
    /// For a sensor gain or offset: the map whose one shape removes about as much of the
    /// error ([`super::alias`]), when one does.
    pub map_alias: Option<MapAlias>,
    /// Why a significant candidate is not proposed (the verdict's own words; `None`: it
    /// counts, or it is not significant).
    pub refused: Option<String>,
    /// The effects already in the model, refitted beside it (their values change with
    /// it, and are written with it: [`super::refit::with_held`]).
    pub held: Vec<Stated>,
    /// How far its refit moved its own parameters from where they started, jointly:
    /// `z' R⁻¹ z` of their departures over their reported σ in their correlation
    /// ([`super::uncertainty::joint_distance`]), and how many were determined; `None`:
    /// not refitted, or not computable. Computed once with the refit: the verdict reads
    /// it whenever it asks whether the candidate counts.
    pub departure: Option<(f64, usize)>,
}

/// A map whose one shape does what a sensor cause does: the run cannot tell them apart.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MapAlias {
    /// The map's data file.
    pub file: &'static str,
    /// How the map changes.
    pub shape: MapShape,
    /// The shape's best value.
    pub value: f64,
    /// The error it removes, as a share of what the sensor cause's refit removes.
    pub share: f64,
}

/// One shape of a map ([`MapAlias`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MapShape {
    /// Every value times `1 + value` (what a sensor gain does).
    Scale,
    /// Every value plus `value` times the map's largest value (what a sensor offset does).
    Shift,
}

/// Share of a candidate's weighted sensitivity a channel must carry to count as moved.
pub const MOVES_SHARE: f64 = 0.05;

#[cfg(test)]
impl Candidate {
    /// A candidate named `effect` whose linear prediction removes `predicted` of the
    /// excess, nothing else known: the tests' starting point (`..Candidate::named(…)`).
    pub(super) fn named(effect: &'static str, predicted: f64) -> Candidate {
        Candidate {
            effect,
            params: Vec::new(),
            predicted_reduction: predicted,
            confirmed_reduction: None,
            energy_after: None,
            significant: false,
            channels: Vec::new(),
            regions: Vec::new(),
            moves: Vec::new(),
            leaves_structure: None,
            drift: None,
            map_alias: None,
            refused: None,
            held: Vec::new(),
            departure: None,
        }
    }
}

impl Candidate {
    /// A sensor cause: it moves one channel alone (the measurement chain's effects;
    /// a physical effect moves several channels consistently).
    pub fn is_sensor(&self) -> bool {
        self.moves.len() == 1
    }

    /// Confirmed reduction if refitted, else predicted.
    pub fn reduction(&self) -> f64 {
        self.confirmed_reduction.unwrap_or(self.predicted_reduction)
    }
}

/// Candidates that explain the residual about equally and in the same shape.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ConfoundedGroup {
    /// Effect ids, best first.
    pub effects: Vec<&'static str>,
    /// Cosine between their predicted residuals on this run.
    pub cosine: f64,
    /// The built-in profile (with scalings) that best separates them, and the cosine there.
    pub separating_profile: Option<(String, f64)>,
}

/// Where the residual is that nothing explains.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Location {
    /// Channel with the largest share of the excess error.
    pub channel: &'static str,
    /// Its share.
    pub share: f64,
    /// The worst window [s, s] of that channel's residual, in its run.
    pub window_s: (f64, f64),
    /// The run of a campaign the window is in (1 for the first; `None` for one run).
    pub run: Option<usize>,
    /// The operating region holding the largest share of the channel's excess: (name,
    /// share of the excess, share of the samples).
    pub region: Option<(String, f64, f64)>,
    /// The measured signal (or `d/dt` of one) the residual follows, and the correlation.
    pub follows: Option<(String, f64)>,
}

impl Location {
    /// "41.0–43.0 s", or "run 3, 41.0–43.0 s" in a campaign.
    pub fn when(&self) -> String {
        let (from, to) = self.window_s;
        match self.run {
            Some(r) => format!("run {r}, {from:.1}–{to:.1} s"),
            None => format!("{from:.1}–{to:.1} s"),
        }
    }
}

/// The verdict, machine-readable.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VerdictKind {
    /// The residual is noise-like.
    NothingMissing,
    /// One effect (or a confounded group headed by it) explains the residual.
    Missing,
    /// The best effect explains part; the rest is unexplained.
    Partial,
    /// Nothing in the library explains the residual.
    Unexplained,
}

/// The candidate a verdict that names nothing could not name ([`Diagnosis::unnamed`]).
#[derive(Debug, Clone)]
pub struct Unnamed {
    /// The base effects plus the candidate at its refitted values.
    pub effects: Effects,
    /// It counts (significant, refused by no test) but explains too little of the run to
    /// be named. Otherwise it is the best candidate, refused only for making a channel
    /// worse (`Evidence::refused_for_worse`): a trade a wrong map may cause, as an
    /// empirical table is tried beside it (`beside_refused`).
    pub counts: bool,
}

/// Everything a diagnosis found.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Diagnosis {
    /// The verdict.
    pub kind: VerdictKind,
    /// One sentence for people.
    pub verdict: String,
    /// Weighted residual energy over what noise alone would give.
    pub excess_ratio: f64,
    /// Estimated noise σ per channel.
    pub noise: Vec<(&'static str, f64)>,
    /// The effect the verdict names (missing, or partly explaining), if any.
    pub lead: Option<&'static str>,
    /// Every library effect, best first.
    pub ranking: Vec<Candidate>,
    /// Effects picked by the greedy selection, with their incremental reductions.
    pub selected: Vec<(&'static str, f64)>,
    /// The effects the verdict names, with the values it proposes ([`Stated`]).
    pub stated: Vec<Stated>,
    /// Effects already in the model that the proposal takes out: the named set's joint
    /// refit returned them to the thesis model ([`SetFit::returned`]).
    pub taken_out: Vec<&'static str>,
    /// Confounded groups among the leaders.
    pub confounded: Vec<ConfoundedGroup>,
    /// Where the unexplained residual is (for partial or unexplained verdicts).
    pub unexplained: Option<Location>,
    /// The base effects plus the effects the verdict names (the base where it names none).
    #[serde(skip)]
    pub proposed: Effects,
    /// Where the verdict names nothing: the candidate it could not name, which the
    /// estimate within the uncertainty starts from with the maps estimated beside it.
    #[serde(skip)]
    pub unnamed: Option<Unnamed>,
    /// When the library leaves error: an empirical correction of the maps, fitted on
    /// top of `proposed` (for `--write-data`), or why none is offered.
    pub empirical: Option<Empirical>,
}

/// Candidate test profiles to run in simulation, for finding the one that separates
/// confounded effects.
pub trait ProfileProbe: Sync {
    /// Number of candidate profiles.
    fn count(&self) -> usize;
    /// Name of profile `i` (with its scalings), as a user would ask for it.
    fn name(&self, i: usize) -> String;
    /// Simulated measured channels `[channel][sample]` of profile `i` with `fx`, a sample
    /// every 10 ms, at the model step `rate` names.
    fn run(&self, i: usize, fx: &Effects, rate: ProbeRate) -> Option<Vec<Vec<f32>>>;
}

/// The model step of a probe run. Every candidate profile is screened at a coarse step
/// (the twin's drivetrain is integrated exactly over a step, its lags are exact: on the
/// tuning runs' confounded pairs, the cosines at 5 ms matched those at 1 ms to 0.001 for
/// mechanical pairs and ranked the profiles alike, at a fifth of the cost); the one
/// named is run again at the bench's rate for the cosine the user is told.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProbeRate {
    /// Coarse: for ranking the candidates.
    Screen,
    /// The bench's 1 kHz: what a measurement of the named profile would show.
    Bench,
}

/// Diagnose `meas` (`[channel][sample]`, channels as `twin.channels()`).
pub fn diagnose(
    twin: &dyn Twin,
    meas: &[Vec<f64>],
    o: &Options,
    probe: Option<&dyn ProfileProbe>,
) -> Result<Diagnosis, String> {
    // One pool of `o.threads` workers for every batch of simulations of this diagnosis;
    // if none can be made, rayon's global pool does the same work.
    match rayon::ThreadPoolBuilder::new().num_threads(o.threads.max(1)).build() {
        Ok(pool) => pool.install(|| stages(twin, meas, o, probe)),
        Err(_) => stages(twin, meas, o, probe),
    }
}

/// The stages of [`diagnose`], in order.
fn stages(
    twin: &dyn Twin,
    meas: &[Vec<f64>],
    o: &Options,
    probe: Option<&dyn ProfileProbe>,
) -> Result<Diagnosis, String> {
    let mut p = prepare(twin, meas, o)?;
    p.data_items = super::systematic::responses(twin, &p, o);
    p.data_corrected = twin.data().is_some_and(|d| super::empirical::has_corrections(&d));
    let s = sensitivities(twin, &p, o)?;
    let (mut cands, lin) = score_effects(&p, &s, twin.channels());
    scan_valleys(twin, &p, &s, o, &mut cands);
    let mut selected = greedy(&p, &s, o);
    let ready = choose_dynamics(twin, &p, &s, o, &cands, &mut selected);
    let mut leaders = refit_list(&cands, &selected, o);
    let held = Held::refit(twin, &p, &s, o);
    with_siblings(&s, twin.channels(), &mut leaders);
    let (mut fits, set) = rayon::join(
        || confirm_leaders(twin, (&p, &s, o, &held), &leaders, ready, &mut cands),
        || joint_fit(twin, &p, &s, o, &selected),
    );
    let resolution = twin.resolution();
    let structure =
        |sim: &[Vec<f32>]| structure_in(&p, twin.channels(), &resolution, twin.dt_s() * p.stride as f64, sim);
    let mark = |fits: &[(usize, Fit)], cands: &mut [Candidate]| {
        for (ci, f) in fits {
            if let Some(c) = cands.get_mut(*ci) {
                c.leaves_structure = Some(structure(&f.sim).is_some());
            }
        }
    };
    mark(&fits, &mut cands);
    let mut shapes = Shapes::default();
    map_aliases(twin, &p, &s, o, &selected, (&mut cands, &mut shapes));
    let base_structure = base_structure(&p, twin.channels(), twin.dt_s() * p.stride as f64);
    // Refused leaders make room for the next ones: when no refitted candidate counts, the
    // next by predicted reduction get their refit (a true friction ranked fourth, behind
    // sensor causes a wrong map mimics, was otherwise never tried).
    let mut next = {
        let ranking = rank_alike(&p, twin.dt_s(), &cands, &fits);
        let ev = evidence(twin, (&p, &s, o), &cands, &fits, set.as_ref(), &ranking);
        match ranking.iter().find(|c| ev.counts(c)) {
            Some(lead) => close_runners_up(&cands, &fits, lead.reduction()),
            None => next_leaders(&cands, &fits, o),
        }
    };
    if !next.is_empty() {
        with_siblings(&s, twin.channels(), &mut next);
        let more = confirm_leaders(twin, (&p, &s, o, &held), &next, Vec::new(), &mut cands);
        mark(&more, &mut cands);
        fits.extend(more);
        map_aliases(twin, &p, &s, o, &selected, (&mut cands, &mut shapes));
    }
    let ranking = rank_alike(&p, twin.dt_s(), &cands, &fits);
    let group = Leaders { cands: &cands, lin: &lin, fits: &fits, ranking: &ranking };
    let confounded = confounded_groups(&group, &s, o, &p.weights.means(p.idx.len()), probe);
    let ev = Evidence {
        confounded: &confounded,
        base_structure,
        ..evidence(twin, (&p, &s, o), &cands, &fits, set.as_ref(), &ranking)
    };
    let refused: Vec<Option<String>> =
        ranking.iter().map(|c| c.significant.then(|| ev.refusal(c)).flatten()).collect();
    let (v, empirical) = tables(twin, &ev, conclude(&ev));
    selected.retain(|(e, _)| v.named.contains(e));
    let stated = stated(&ev, &v);
    let taken_out = ev.set.filter(|s| s.effects == v.named).map(|s| s.removed.clone()).unwrap_or_default();
    let unnamed = unnamed(&ev, &v);
    let sentence = match empirical.as_ref() {
        Some(e) if e.refused.is_none() => format!("{}; {}", v.sentence, e.offer()),
        _ => v.sentence,
    };
    Ok(Diagnosis {
        kind: v.kind,
        verdict: sentence,
        excess_ratio: p.excess_ratio,
        noise: p.noise.clone(),
        lead: v.lead,
        ranking: ranking.into_iter().zip(refused).map(|(c, refused)| Candidate { refused, ..c }).collect(),
        selected,
        stated,
        taken_out,
        confounded,
        unexplained: v.unexplained,
        proposed: v.proposed,
        unnamed,
        empirical,
    })
}

/// The evidence the verdict weighs: the refits `fits` of `cands`, ranked, and the
/// selected set, on the diagnosis' data, sensitivities and options (`base`), with nothing
/// confounded and no structure flagged yet (what whether a candidate counts does not read).
fn evidence<'a>(
    twin: &'a dyn Twin,
    (p, s, o): (&'a Prepared, &'a Sensitivities, &'a Options),
    cands: &'a [Candidate],
    fits: &'a [(usize, Fit)],
    set: Option<&'a SetFit>,
    ranking: &'a [Candidate],
) -> Evidence<'a> {
    Evidence {
        p,
        s,
        o,
        channels: twin.channels(),
        resolution: twin.resolution(),
        dt: twin.dt_s(),
        cands,
        fits,
        set,
        ranking,
        confounded: &[],
        base_structure: None,
    }
}

/// The candidate verdict `v` could not name ([`Diagnosis::unnamed`]): its counting lead
/// kept apart ([`Verdict::unnamed`]), or its best refused only for making a channel worse.
/// A verdict withdrawn for a table ([`table_beats_library`]) keeps no lead apart.
pub(super) fn unnamed(ev: &Evidence, v: &Verdict) -> Option<Unnamed> {
    if !v.named.is_empty() {
        return None;
    }
    if let Some(effects) = v.unnamed {
        return Some(Unnamed { effects, counts: true });
    }
    let (c, _) = ev.refused_for_worse(0.0)?;
    Some(Unnamed { effects: ev.proposed(Some(c)), counts: false })
}

/// Stage 8: when the library leaves error, an empirical correction of the maps, fitted
/// first on the current model alone. An unexplained residual is offered the table (or a
/// candidate refused only for making a channel worse, with a table on top of it:
/// [`beside_refused`]). A partial proposal is withdrawn when the table explains clearly
/// more on held-out data ([`table_beats_library`]), unless the two together remove
/// clearly more than the table alone; otherwise it gets no table: what it leaves is
/// diagnosed again next round with it in place, where a second library effect gets its
/// chance before a table absorbs it.
fn tables(twin: &dyn Twin, ev: &Evidence, v: Verdict) -> (Verdict, Option<Empirical>) {
    let on = |fx: Effects, against_current: bool| {
        correct(&EmpiricalInputs { twin, p: ev.p, o: ev.o, fx, channels: twin.channels(), against_current })
    };
    let fit = |fx: Effects| on(fx, false);
    let (p, o) = (ev.p, ev.o);
    // Each fit costs a simulation per map node: only where it can change the answer. A
    // table cannot beat a proposal that leaves less than the margin, and a residual
    // within a few percent of the noise energy has too little for a table to remove.
    // (A whole below `noise_like_ratio` can still hold a table's worth: a regenerating
    // map 8 % strong, once mostly corrected, left 17 % over the noise in 32 windows.)
    let left_after = (p.e0 - v.removed * p.excess) / p.e_noise;
    let can_beat = v.removed + PREFER_TABLE_MARGIN <= 1.0;
    match v.kind {
        VerdictKind::Unexplained if p.excess_ratio > 1.0 + TABLE_LEAST_EXCESS => {
            let alone = fit(o.base);
            match beside_refused(ev, &v, alone.as_ref(), &|fx| on(fx, true)) {
                Some((with, t)) => (with, Some(t)),
                None => (v, alone),
            }
        }
        VerdictKind::Partial => {
            // The table's worse figure, held-out (linear) or confirmed (simulator).
            let beats = |e: &Empirical| e.refused.is_none() && e.removes() >= v.removed + PREFER_TABLE_MARGIN;
            let Some(e) = can_beat.then(|| fit(o.base)).flatten().filter(beats) else { return (v, None) };
            // The proposal may still stand beside the table: it does when the two together
            // remove clearly more than the table alone (a physical effect the maps cannot
            // mimic, next to a wrong map).
            let beside = if left_after > o.noise_like_ratio { fit(v.proposed) } else { None };
            match beside.filter(|t| {
                t.refused.is_none()
                    && v.removed + (1.0 - v.removed) * t.removes() >= e.removes() + KEEP_BESIDE_TABLE
            }) {
                Some(t) => (v, Some(t)),
                None => (table_beats_library(ev, &v, e.removes()), Some(e)),
            }
        }
        _ => (v, None),
    }
}

/// The best candidate refused only for making a channel worse
/// ([`Evidence::refused_for_worse`]), proposed with a map correction fitted on top of it,
/// when the two make no channel worse than the current model (the table's guard, judged
/// against the current model only: the candidate's value was fitted with the wrong map
/// and is refitted next round with the table in place) and remove [`KEEP_BESIDE_TABLE`]
/// more of the excess than the table `alone` does.
fn beside_refused(
    ev: &Evidence,
    v: &Verdict,
    alone: Option<&Empirical>,
    fit: &dyn Fn(Effects) -> Option<Empirical>,
) -> Option<(Verdict, Empirical)> {
    let (c, why) = ev.refused_for_worse(ev.o.explain_fraction)?;
    let t = fit(ev.proposed(Some(c))).filter(|t| t.refused.is_none())?;
    let together = c.reduction() + (1.0 - c.reduction()) * t.removes();
    let table_alone = alone.filter(|e| e.refused.is_none()).map_or(0.0, Empirical::removes);
    (together >= table_alone + KEEP_BESIDE_TABLE)
        .then(|| (ev.with_table(c, &why, together, v.unexplained.clone()), t))
}

/// Least excess over the noise energy (a share of it) an unexplained residual must have
/// for a table to be fitted to it.
const TABLE_LEAST_EXCESS: f64 = 0.05;

/// How much more of the excess error the library's proposal and a table fitted on top
/// of it must remove together than the table alone, for the proposal to stand.
const KEEP_BESIDE_TABLE: f64 = 0.05;

/// A set of two or more effects refitted jointly on the simulator.
pub(super) struct SetFit {
    /// The effects, in the order the selection chose them.
    pub effects: Vec<&'static str>,
    /// Their parameters, effect by effect.
    pub specs: Vec<ParamSpec>,
    pub fit: Fit,
    /// σ of each parameter for the test whether it moved ([`Spread::std`]).
    pub std: Vec<f64>,
    /// σ of each parameter as reported ([`Spread::reported`]).
    pub reported: Vec<f64>,
    /// Of `reported`, the identified data's part ([`Spread::data`]).
    pub data: Vec<f64>,
    /// Each parameter's value before the fit (neutral or current).
    pub starts: Vec<f64>,
    /// A member's parameter that drifts over the run ([`Candidate::drift`]).
    pub drift: Option<Drift>,
    /// Effects the model held that the joint refit returned to the thesis model
    /// ([`SetFit::returned`]): taken out, and the members refitted without them.
    pub removed: Vec<&'static str>,
    /// The effects the members' values are applied to: the model's, less `removed`.
    pub base: Effects,
}

/// The selected set (when it has two or more effects) refitted jointly, from the joint
/// linear estimate: each member's parameters with the others present, not alone.
fn joint_fit(
    twin: &dyn Twin,
    p: &Prepared,
    s: &Sensitivities,
    o: &Options,
    selected: &[(&'static str, f64)],
) -> Option<SetFit> {
    if selected.len() < 2 {
        return None;
    }
    let groups: Vec<usize> =
        selected.iter().filter_map(|(e, _)| s.groups.iter().position(|(g, _)| g == e)).collect();
    let ix = super::selection::group_params(s, &groups);
    let (th, _) = super::selection::fit_lin(s, &ix);
    let start: Vec<f64> = ix.iter().zip(&th).map(|(&i, t)| s.starts[i] + t * s.steps[i]).collect();
    let sp: Vec<&ParamSpec> = ix.iter().map(|&i| &s.specs[i]).collect();
    let fit = refit(twin, p, o, &sp, &start)?;
    let starts: Vec<f64> = ix.iter().map(|&i| s.starts[i]).collect();
    let effects = groups.iter().map(|&g| s.groups[g].0).collect();
    let set = SetFit::of(twin, p, (effects, Vec::new(), o.base), &sp, fit, starts);
    Some(take_out_returned(twin, p, o, set))
}

/// `set` without the members already in the model that its joint refit returns to the
/// thesis model ([`SetFit::returned`]), the others refitted on the model without them.
/// An effect an earlier round wrote for what a later one explains otherwise (a coupling
/// damping and an inertia scale standing in for a coupling stiffness found later) is
/// otherwise restated at a value its own interval says is no effect at all. `set` as it
/// is when no member returns, when none would be left, or when the refit fails.
fn take_out_returned(twin: &dyn Twin, p: &Prepared, o: &Options, set: SetFit) -> SetFit {
    let gone = set.returned();
    if gone.is_empty() || gone.len() == set.effects.len() {
        return set;
    }
    let mut base = o.base;
    for sp in set.specs.iter().filter(|sp| gone.contains(&sp.cause)) {
        // Every spec comes from the declarations, so `reset` cannot refuse it.
        let _ = base.reset(sp.effect, sp.param);
    }
    let keep: Vec<usize> = (0..set.specs.len()).filter(|&k| !gone.contains(&set.specs[k].cause)).collect();
    let sp: Vec<&ParamSpec> = keep.iter().map(|&k| &set.specs[k]).collect();
    let start: Vec<f64> = keep.iter().map(|&k| set.fit.values[k]).collect();
    let Some(fit) = refit(twin, p, &Options { base, ..o.clone() }, &sp, &start) else { return set };
    let starts: Vec<f64> = keep.iter().map(|&k| set.starts[k]).collect();
    let effects = set.effects.iter().copied().filter(|e| !gone.contains(e)).collect();
    SetFit::of(twin, p, (effects, gone, base), &sp, fit, starts)
}

impl SetFit {
    /// The set `effects` (the model's effects `removed` taken out, leaving `base`) from
    /// the joint refit `fit` of `sp` started at `starts`, with its parameters' spread.
    fn of(
        twin: &dyn Twin,
        p: &Prepared,
        (effects, removed, base): (Vec<&'static str>, Vec<&'static str>, Effects),
        sp: &[&ParamSpec],
        fit: Fit,
        starts: Vec<f64>,
    ) -> SetFit {
        let Spread { std, reported, data, drift } = parameter_std(p, &fit, sp, &starts, twin.dt_s());
        let specs = sp.iter().map(|&s| s.clone()).collect();
        SetFit { effects, specs, fit, std, reported, data, starts, drift, removed, base }
    }

    /// Whether the joint fit supports member `effect`: some parameter of it moved from
    /// its start by more than 2 σ, as a single effect must to be significant. A member
    /// the others leave at its start (within its uncertainty) has no evidence of its own.
    pub fn supports(&self, effect: &str) -> bool {
        self.specs
            .iter()
            .zip(self.fit.values.iter().zip(self.std.iter().zip(&self.starts)))
            .any(|(sp, (v, (sd, s0)))| sp.cause == effect && super::refit::moved(*v, *s0, *sd, sp))
    }

    /// Each parameter of `effect`: its spec, its start and its reported 95 % interval
    /// (the statistical and the data parts).
    fn intervals<'a>(
        &'a self,
        effect: &'a str,
    ) -> impl Iterator<Item = (&'a ParamSpec, f64, (f64, f64))> + 'a {
        let params =
            self.specs.iter().zip(self.fit.values.iter().zip(self.reported.iter().zip(&self.starts)));
        params
            .filter(move |(sp, _)| sp.cause == effect)
            .map(|(sp, (&v, (&sd, &s0)))| (sp, s0, FittedParam::refitted(sp, v, (sd, 0.0), s0).ci95))
    }

    /// Whether member `c` (its refit alone) has no support of its own that the set could
    /// lean on, and the set does not hold it clear of the thesis value by more than the
    /// data's uncertainty either ([`Self::clear_of_neutral`]). A member that drifts when
    /// fitted alone may be averaging a partner's effect, which the joint refit takes from
    /// it (an axle friction scale beside a connector resistance, each drifting with the
    /// load alone); so may a new member that its refit alone does not move significantly
    /// (a differential friction that only its partner's misfit holds off zero, for a
    /// bearing drag the library lacks: tuning cases 505,123 and 505,134).
    pub fn unsupported(&self, c: &Candidate) -> bool {
        let alone = c.drift.is_none() && (c.significant || self.held(c.effect));
        !alone && !self.clear_of_neutral(c.effect)
    }

    /// Whether member `effect` was already in the model: some parameter of it started off
    /// its neutral value.
    fn held(&self, effect: &str) -> bool {
        super::library::holds(&self.specs, &self.starts, effect)
    }

    /// Whether some parameter of `effect` has its reported 95 % interval clear of the
    /// thesis model's value: the joint refit holds it away from neutral by more than the
    /// maps' uncertainty could.
    pub fn clear_of_neutral(&self, effect: &str) -> bool {
        self.intervals(effect).any(|(sp, _, (lo, hi))| sp.neutral < lo || sp.neutral > hi)
    }

    /// Whether member `effect` is a measurement-chain fault with a partner of the same
    /// kind on another channel that the joint refit holds alike ([`ParamSpec::alike`]):
    /// one cause on both channels, which the set must not name as two sensors.
    pub fn alike_partner(&self, effect: &str) -> bool {
        let members = || self.specs.iter().zip(self.fit.values.iter().zip(&self.reported));
        members()
            .filter(|(sp, _)| sp.cause == effect)
            .any(|(sp, (&v, &sd))| members().any(|(sq, (&w, &sw))| sp.alike((v, sd), sq, (w, sw))))
    }

    /// The members already in the model (some parameter started off its neutral value)
    /// that the joint refit returns to the thesis model: every parameter's reported 95 %
    /// interval holds its neutral value, and some parameter's excludes the value the
    /// model had. A member whose intervals still hold the model's values is not moved
    /// back by the data (a delay the run cannot determine) and stays.
    pub fn returned(&self) -> Vec<&'static str> {
        let mut out: Vec<&'static str> = Vec::new();
        for &e in &self.effects {
            let (mut holds, mut excludes) = (true, false);
            for (sp, s0, (lo, hi)) in self.intervals(e) {
                holds &= lo <= sp.neutral && sp.neutral <= hi;
                excludes |= s0 < lo || s0 > hi;
            }
            if self.held(e) && holds && excludes {
                out.push(e);
            }
        }
        out
    }
}

/// Refit the candidates `list` on the simulator, with their uncertainty, and write the
/// results into `cands`; the refits by candidate index (a failed refit is left out).
/// The refits `ready` (by candidate index) are used as they are, and confirmed too when
/// not in `list`. Each is refitted beside the effects already in the model (`held`) when
/// that credits it with more ([`with_held`]).
fn confirm_leaders(
    twin: &dyn Twin,
    (p, s, o, held): (&Prepared, &Sensitivities, &Options, &Held),
    list: &[usize],
    mut ready: Vec<(usize, Fit)>,
    cands: &mut [Candidate],
) -> Vec<(usize, Fit)> {
    use rayon::prelude::*;
    let specs = |ci: usize| -> Vec<&ParamSpec> { s.groups[ci].1.iter().map(|&i| &s.specs[i]).collect() };
    // Each leader with its refit when one is ready, then the ready refits of the others.
    let mut jobs: Vec<(usize, Option<Fit>)> = Vec::with_capacity(list.len() + ready.len());
    for &ci in list {
        let fit = ready.iter().position(|(r, _)| *r == ci).map(|k| ready.remove(k).1);
        jobs.push((ci, fit));
    }
    jobs.extend(ready.into_iter().map(|(ci, f)| (ci, Some(f))));
    // The refits are independent: on the pool side by side (each one's own batches of
    // simulations share the pool), in list order.
    let done: Vec<(usize, Fit, Spread, Vec<Stated>)> = jobs
        .into_par_iter()
        .filter_map(|(ci, fit)| {
            let fit = match fit {
                Some(f) => f,
                None => refit_alone(twin, p, o, s, cands, ci)?,
            };
            // A one-channel cause is judged on its channel against the current model
            // ([`Evidence::absorbs`]): refitted alone, so the held values' refit cannot
            // clear that channel in its name.
            let fit = if cands[ci].is_sensor() { fit } else { with_held(twin, (p, o, s), ci, held, fit) };
            let sp: Vec<&ParamSpec> =
                specs(ci).into_iter().chain(fit.held_ix().iter().map(|&i| &s.specs[i])).collect();
            // The drift is measured from where the model stood, not from the linear guess.
            let current: Vec<f64> = cands[ci]
                .params
                .iter()
                .map(|f| f.start)
                .chain(fit.held_ix().iter().map(|&i| s.starts[i]))
                .collect();
            let spread = parameter_std(p, &fit, &sp, &current, twin.dt_s());
            // The held parameters follow the own ones in every list.
            let own = s.groups[ci].1.len();
            let beside = by_cause(
                after(&sp, own),
                after(&fit.values, own),
                (after(&spread.reported, own), after(&spread.data, own)),
                after(&current, own),
            );
            Some((ci, fit, spread, beside))
        })
        .collect();
    let mut fits = Vec::with_capacity(done.len());
    for (ci, fit, spread, beside) in done {
        confirm(&mut cands[ci], &fit, &spread, &specs(ci), p);
        cands[ci].drift = spread.drift;
        cands[ci].held = beside;
        let scale: Vec<f64> = s.groups[ci].1.iter().chain(fit.held_ix()).map(|&i| s.specs[i].delta).collect();
        cands[ci].departure = departure(p, &fit, &scale, &cands[ci].params);
        fits.push((ci, fit));
    }
    fits
}

/// [`Candidate::departure`] of the refit `fit` that gave `params` (their values, starts
/// and reported σ); `scale`: the sensitivity step of each of its parameters, the
/// candidate's and those held beside.
fn departure(p: &Prepared, fit: &Fit, scale: &[f64], params: &[FittedParam]) -> Option<(f64, usize)> {
    let z: Vec<Option<f64>> = params
        .iter()
        .map(|fp| Some((fp.value - fp.start) / fp.std).filter(|z| z.is_finite() && fp.std.is_finite()))
        .collect();
    let d2 = joint_distance(&p.weights, fit, scale, &z)?;
    Some((d2, z.iter().flatten().count()))
}

/// `v` after its first `k` elements (empty when it has no more).
fn after<T>(v: &[T], k: usize) -> &[T] {
    v.get(k..).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A set of `specs` (members `effects`) fitted at `values` from `starts`, with σ
    /// `(std, reported)`: the test whether each moved and the stated one; nothing
    /// simulated, nothing taken out.
    fn set_at(
        (effects, specs): (Vec<&'static str>, Vec<ParamSpec>),
        values: Vec<f64>,
        (std, reported): (Vec<f64>, Vec<f64>),
        starts: Vec<f64>,
    ) -> SetFit {
        let data = vec![0.0; starts.len()];
        let fit = Fit::fixed(values, Vec::new(), 0.0);
        SetFit {
            effects,
            specs,
            fit,
            std,
            reported,
            data,
            starts,
            drift: None,
            removed: Vec::new(),
            base: Effects::NONE,
        }
    }

    /// The library's parameters of `effect`, in declaration order.
    fn effect_specs(effect: &str) -> Vec<ParamSpec> {
        super::super::library::library(&Params::default())
            .into_iter()
            .filter(|s| s.effect == effect)
            .collect()
    }

    /// A member the joint fit moves by 3 σ is supported; one it leaves within 1 σ of its
    /// start is not, nor one whose σ is undetermined.
    #[test]
    fn a_set_supports_only_members_it_moves() {
        let lib = super::super::library::library(&Params::default());
        let spec = |e: &str| lib.iter().find(|s| s.effect == e).cloned().expect("a library effect");
        let (a, b, c) = (spec("supply_resistance"), spec("regen_efficiency"), spec("controller_delay"));
        let set = set_at(
            (vec![a.cause, b.cause, c.cause], vec![a, b, c]),
            vec![0.013, 0.05, 0.08],
            (vec![0.001, 0.05, f64::INFINITY], vec![0.001, 0.05, f64::INFINITY]),
            vec![0.010, 0.0, 0.0],
        );
        assert!(set.supports("supply_resistance"));
        assert!(!set.supports("regen_efficiency"));
        assert!(!set.supports("controller_delay"));
    }

    /// A member is returned to the thesis model only when it was in the model, every
    /// interval of the refit holds its neutral value and one excludes the model's value:
    /// not a new member, not one the refit leaves undetermined or still holding the
    /// model's value, not one moved elsewhere.
    #[test]
    fn only_held_members_refitted_back_to_neutral_are_returned() {
        // Per member, (start, value, reported σ) of each parameter, in library order.
        type Member = (&'static str, &'static [(f64, f64, f64)]);
        let members: [Member; 6] = [
            // Inertia held at 1.43/0.67/0.76, refitted to 1.05/0.96/0.97 ± 0.09: returned.
            ("inertia_scale", &[(1.43, 1.05, 0.09), (0.67, 0.96, 0.09), (0.76, 0.97, 0.09)]),
            // Damping held at 25, refitted to 3.9 ± 1.3 (thesis 3.65): returned.
            ("coupling_damping", &[(25.0, 3.9, 1.3)]),
            // A delay the run cannot determine (σ undetermined): stays.
            ("controller_delay", &[(0.03, 0.02, f64::INFINITY)]),
            // New (it starts neutral): not returned, whatever its interval.
            ("supply_resistance", &[(0.0, 0.001, 0.01)]),
            // Its interval holds both the thesis value and the model's: stays.
            ("axle_friction_scale", &[(1.1, 1.05, 0.05), (1.0, 1.0, 0.05)]),
            // Moved, but away from neutral: stays.
            ("differential_friction", &[(3.0, 6.0, 0.5), (0.0, 0.0, 0.01)]),
        ];
        let (mut sp, mut starts, mut values, mut sd) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (e, ps) in members {
            let own = effect_specs(e);
            assert_eq!(own.len(), ps.len(), "{e}'s parameters");
            for (s, &(s0, v, d)) in own.into_iter().zip(ps) {
                sp.push(s);
                starts.push(s0);
                values.push(v);
                sd.push(d);
            }
        }
        let effects = members.iter().map(|(e, _)| *e).collect();
        let set = set_at((effects, sp), values, (sd.clone(), sd), starts);
        assert_eq!(set.returned(), vec!["inertia_scale", "coupling_damping"]);
    }

    /// A member is clear of the thesis model when the reported interval (statistical and
    /// data parts) of one of its parameters excludes the neutral value: tuning case
    /// 500,800's axle friction scale (left 1.4547 ± 0.0238, beside a connector
    /// resistance) is; 500,821's (0.887 ± 0.292, 0.864 ± 0.349 beside perturbed friction
    /// maps) is not, nor is one that only its statistical σ would hold clear.
    #[test]
    fn a_member_is_clear_of_neutral_only_by_its_reported_interval() {
        let axle = effect_specs("axle_friction_scale");
        assert_eq!(axle.len(), 2, "left and right");
        let set = |values: Vec<f64>, std: Vec<f64>, reported: Vec<f64>| {
            set_at((vec![axle[0].cause], axle.clone()), values, (std, reported), vec![1.0, 1.0])
        };
        let sd = |a: f64, b: f64| vec![a / 1.96, b / 1.96];
        let clear = set(vec![1.4547, 1.0559], sd(0.0238, 0.0031), sd(0.0238, 0.0031));
        assert!(clear.clear_of_neutral("axle_friction_scale"));
        let wide = set(vec![0.887, 0.864], sd(0.292, 0.349), sd(0.292, 0.349));
        assert!(!wide.clear_of_neutral("axle_friction_scale"));
        let data_wide = set(vec![0.887, 0.864], sd(0.01, 0.01), sd(0.292, 0.349));
        assert!(data_wide.supports("axle_friction_scale"), "statistically it moved");
        assert!(!data_wide.clear_of_neutral("axle_friction_scale"));
        assert!(!clear.clear_of_neutral("connector_resistance"), "not a member");
    }

    /// A new member its refit alone leaves insignificant is named only when the set holds
    /// it clear of the thesis value: tuning case 505,134's differential friction
    /// (2.19 ± 17.2 N m, 0.081 ± 0.59 N m s/rad beside a controller delay, not
    /// significant alone) is not; the same member significant alone, or held clear, is;
    /// a member already in the model is judged on its drift alone.
    #[test]
    fn a_new_member_without_support_alone_must_be_clear_of_neutral() {
        let diff = effect_specs("differential_friction");
        assert_eq!(diff.len(), 2, "Coulomb and viscous");
        let set = |values: Vec<f64>, half: [f64; 2], starts: Vec<f64>| {
            let sd = vec![half[0] / 1.96, half[1] / 1.96];
            set_at((vec![diff[0].cause], diff.clone()), values, (vec![0.01, 0.001], sd), starts)
        };
        let member =
            |significant: bool| Candidate { significant, ..Candidate::named("differential_friction", 0.06) };
        let wide = set(vec![2.19, 0.081], [17.2, 0.59], vec![0.0, 0.0]);
        assert!(wide.supports("differential_friction"), "the set alone moves it");
        assert!(wide.unsupported(&member(false)));
        assert!(!wide.unsupported(&member(true)));
        let clear = set(vec![2.19, 0.221], [17.2, 0.14], vec![0.0, 0.0]);
        assert!(!clear.unsupported(&member(false)));
        let in_model = set(vec![2.19, 0.081], [17.2, 0.59], vec![1.5, 0.05]);
        assert!(!in_model.unsupported(&member(false)));
        let drifting = Candidate {
            drift: Some(Drift {
                cause: "differential_friction",
                param: "viscous_nm_s_per_rad",
                along: Along::Speed,
                first: 0.0,
                last: 0.2,
            }),
            ..member(true)
        };
        assert!(wide.unsupported(&drifting) && in_model.unsupported(&drifting));
        assert!(!clear.unsupported(&drifting));
    }

    /// A set naming both flange torques' gains held alike by the joint refit (proof case
    /// 1,005,925: 1.0809 and 1.0805, ± 0.035) has each member's partner alike; gains of
    /// 1.0805 and 1.05 do not, nor do the two sides of one physical effect.
    #[test]
    fn a_set_holds_sensor_faults_alike_on_two_channels() {
        let lib = super::super::library::library(&Params::default());
        let pick = |causes: [&str; 2]| -> Vec<ParamSpec> {
            causes
                .iter()
                .map(|c| lib.iter().find(|s| s.cause == *c).expect("in the library").clone())
                .collect()
        };
        let gains = pick(["sensor_gain.c_kistler_l", "sensor_gain.c_kistler_r"]);
        let set = |specs: Vec<ParamSpec>, values: Vec<f64>| {
            let effects = specs.iter().map(|s| s.cause).collect();
            set_at((effects, specs), values, (vec![0.0176; 2], vec![0.0176; 2]), vec![1.0, 1.0])
        };
        let alike = set(gains.clone(), vec![1.0805, 1.0809]);
        assert!(
            alike.alike_partner("sensor_gain.c_kistler_l") && alike.alike_partner("sensor_gain.c_kistler_r")
        );
        let apart = set(gains, vec![1.0805, 1.05]);
        assert!(
            !apart.alike_partner("sensor_gain.c_kistler_l")
                && !apart.alike_partner("sensor_gain.c_kistler_r")
        );
        let physical = set(effect_specs("axle_friction_scale"), vec![1.0805, 1.0809]);
        assert!(!physical.alike_partner("axle_friction_scale"), "one effect's two sides, not sensors");
    }
}
