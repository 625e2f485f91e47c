//! Which physical effect is missing? Ranking, refit, uncertainty, confounding, verdict.
//!
//! 1. Residual of the current model, and each channel's noise level estimated from the
//!    residual minus its 0.25 s moving average (model errors are slow, measurement
//!    noise — even coloured by an encoder's counting window — is fast), so every channel
//!    enters the fit weighted by `1/σ²`.
//! 2. Sensitivity of every measured channel to every library parameter (one simulation
//!    per parameter, finite differences, run in parallel).
//! 3. Score test / orthogonal forward regression: the weighted least-squares reduction
//!    of the residual each effect's parameters achieve alone, then greedily the
//!    incremental reduction given the effects already chosen.
//! 4. Confirmation: a Levenberg–Marquardt refit of the best candidates on the real
//!    (nonlinear) simulator; the error it removes, measured, not predicted.
//! 5. Uncertainty: a sandwich (HAC) covariance `G⁻¹ S G⁻¹` of the refit, where `S` comes
//!    from a noise model fitted to the whole refit residual of each channel — its local
//!    level (bench noise grows at the operating limits) and its autocorrelation (encoder
//!    counting windows, coloured noise). Resampling the residual instead (a block
//!    bootstrap) collapses when an effect shows in only a few transients: at the optimum
//!    the residual there is orthogonal to the Jacobian. The noise model is not fooled.
//! 6. Confounding: candidates whose predicted residual shapes nearly coincide are reported
//!    as a group, with the profile (simulated, not guessed) that best separates them.
//! 7. Verdict: a significant candidate that removes most of the excess error *and leaves a
//!    noise-like residual* → that effect; noise-like residual → nothing missing; a
//!    candidate that explains part → partial, with the unexplained rest located;
//!    otherwise "unexplained", and where.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use model_core::{Channel, Effects, Params};

use super::library::{current_value, library, with_values, ParamSpec};
use super::linalg::{quad, solve_spd, sub_matrix};

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
    /// Bootstrap replicates.
    pub bootstrap: usize,
    /// Worker threads.
    pub threads: usize,
    /// PRNG seed for the bootstrap.
    pub seed: u64,
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
            bootstrap: 200,
            threads: std::thread::available_parallelism().map_or(2, |n| n.get()).min(8),
            seed: 0x5eed,
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
    /// Bootstrap standard deviation.
    pub std: f64,
    /// 95 % interval (value ± 1.96 std, clipped to bounds).
    pub ci95: (f64, f64),
    /// Unit.
    pub unit: &'static str,
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
    /// Some parameter differs from its start by more than 2 bootstrap std.
    pub significant: bool,
    /// Per-channel errors.
    pub channels: Vec<ChannelChange>,
    /// Per-region errors (when regions were given).
    pub regions: Vec<RegionChange>,
}

impl Candidate {
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
    /// The worst window [s, s] of that channel's residual.
    pub window_s: (f64, f64),
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
    /// Confounded groups among the leaders.
    pub confounded: Vec<ConfoundedGroup>,
    /// Where the unexplained residual is (for partial or unexplained verdicts).
    pub unexplained: Option<Location>,
    /// The base effects plus the effect to add (for `--write-effects`).
    #[serde(skip)]
    pub proposed: Effects,
}

/// Candidate test profiles to run in simulation, for finding the one that separates
/// confounded effects.
pub trait ProfileProbe: Sync {
    /// Number of candidate profiles.
    fn count(&self) -> usize;
    /// Name of profile `i` (with its scalings), as a user would ask for it.
    fn name(&self, i: usize) -> String;
    /// Simulated measured channels `[channel][sample]` of profile `i` with `fx`.
    fn run(&self, i: usize, fx: &Effects) -> Option<Vec<Vec<f32>>>;
}

struct Prepared {
    meas: Vec<Vec<f64>>,
    base: Vec<Vec<f64>>,
    weights: Vec<f64>,
    idx: Vec<usize>,
}

/// Noise σ of a residual: the part faster than a `2h+1`-sample moving average, corrected
/// for the average's own share so that white noise gives an unbiased estimate. Not
/// trimmed: bench noise grows at the operating limits, and trimming would cut exactly
/// that part.
fn noise_sigma(r: &[f64], h: usize) -> f64 {
    let n = r.len();
    let k = 2 * h + 1;
    if n < 2 * k {
        return 0.0;
    }
    let mut prefix = vec![0.0; n + 1];
    for (i, v) in r.iter().enumerate() {
        prefix[i + 1] = prefix[i] + v;
    }
    let hp = (h..n - h).map(|t| r[t] - (prefix[t + h + 1] - prefix[t - h]) / k as f64);
    let var = hp.map(|v| v * v).sum::<f64>() / (n - 2 * h) as f64;
    // x - mean(k) of white noise has variance σ²(1 - 1/k).
    (var * k as f64 / (k as f64 - 1.0)).sqrt()
}

fn run_all(twin: &dyn Twin, jobs: &[Effects], threads: usize) -> Vec<Result<Vec<Vec<f32>>, String>> {
    let next = AtomicUsize::new(0);
    let out: Mutex<Vec<Option<Result<Vec<Vec<f32>>, String>>>> = Mutex::new(vec![None; jobs.len()]);
    std::thread::scope(|s| {
        for _ in 0..threads.max(1).min(jobs.len().max(1)) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(fx) = jobs.get(i) else { break };
                let r = twin.run(fx);
                if let Ok(mut o) = out.lock() {
                    o[i] = Some(r);
                }
            });
        }
    });
    out.into_inner()
        .unwrap_or_default()
        .into_iter()
        .map(|r| r.unwrap_or_else(|| Err("worker lost".into())))
        .collect()
}

/// Weighted squared error of `sim` against the measurement on the fit samples.
fn energy(p: &Prepared, sim: &[Vec<f32>]) -> f64 {
    let mut e = 0.0;
    for ((m, s), w) in p.meas.iter().zip(sim).zip(&p.weights) {
        for &t in &p.idx {
            let r = m[t] - f64::from(s[t]);
            e += w * r * r;
        }
    }
    e
}

/// Per region: weighted mean squared error of the current model (`before`) and of the
/// model changed by `delta(channel, fit sample)` (`predicted`).
fn region_errors(
    p: &Prepared,
    regions: &[(String, Vec<bool>)],
    delta: impl Fn(usize, usize) -> f64,
) -> Vec<RegionChange> {
    let m = p.idx.len().max(1) as f64;
    regions
        .iter()
        .map(|(name, mask)| {
            let (mut before, mut after, mut count) = (0.0, 0.0, 0usize);
            for (k, &t) in p.idx.iter().enumerate() {
                if !mask.get(t).copied().unwrap_or(false) {
                    continue;
                }
                count += 1;
                for (c, w) in p.weights.iter().enumerate() {
                    let r = p.meas[c][t] - p.base[c][t];
                    before += w * r * r;
                    after += w * (r - delta(c, k)).powi(2);
                }
            }
            let per = (count * p.weights.len()).max(1) as f64;
            RegionChange {
                region: name.clone(),
                samples: count as f64 / m,
                before: before / per,
                predicted: after / per,
                confirmed: None,
            }
        })
        .collect()
}

/// Weighted squared error per channel.
fn channel_energies(p: &Prepared, sim: &[Vec<f32>]) -> Vec<f64> {
    p.meas
        .iter()
        .zip(sim)
        .zip(&p.weights)
        .map(|((m, s), w)| p.idx.iter().map(|&t| w * (m[t] - f64::from(s[t])).powi(2)).sum())
        .collect()
}

fn rmse(m: &[f64], s: &[f64], idx: &[usize]) -> f64 {
    (idx.iter().map(|&t| (m[t] - s[t]).powi(2)).sum::<f64>() / idx.len().max(1) as f64).sqrt()
}

struct Fit {
    values: Vec<f64>,
    sim: Vec<Vec<f32>>,
    jac: Vec<Vec<Vec<f64>>>,
    energy: f64,
    /// One-parameter fits: (value, energy) of a fine scan around the optimum.
    profile: Vec<(f64, f64)>,
}

/// Fine scan around a one-parameter optimum (±25 %, or ±4 steps for small values): moves
/// to any better point (rugged objectives, e.g. backlash events, hide narrow basins from
/// a local search) and keeps the scan for a profile interval.
fn profile_scan(twin: &dyn Twin, p: &Prepared, o: &Options, s0: &ParamSpec, fit: &mut Fit) {
    let v0 = fit.values[0];
    let half = (0.25 * v0.abs()).max(4.0 * s0.delta * 0.25);
    let (lo, hi) = ((v0 - half).max(s0.lower), (v0 + half).min(s0.upper));
    let grid: Vec<f64> = (0..=24).map(|i| lo + (hi - lo) * f64::from(i) / 24.0).collect();
    let jobs: Vec<Effects> = grid.iter().map(|v| with_values(&o.base, &[s0], &[*v])).collect();
    let mut prof = vec![(v0, fit.energy)];
    for (v, r) in grid.iter().zip(run_all(twin, &jobs, o.threads)) {
        let Ok(y) = r else { continue };
        let e = energy(p, &y);
        prof.push((*v, e));
        if e < fit.energy {
            fit.energy = e;
            fit.values = vec![*v];
            fit.sim = y;
        }
    }
    prof.sort_by(|a, b| a.0.total_cmp(&b.0));
    fit.profile = prof;
}

/// Levenberg–Marquardt on the simulator for the parameters `specs`, from `start`.
fn refit(twin: &dyn Twin, p: &Prepared, o: &Options, specs: &[&ParamSpec], start: &[f64]) -> Option<Fit> {
    let clamp = |v: &mut Vec<f64>| {
        for (x, s) in v.iter_mut().zip(specs) {
            *x = x.clamp(s.lower, s.upper);
        }
    };
    let mut theta = start.to_vec();
    clamp(&mut theta);
    let mut sim = twin.run(&with_values(&o.base, specs, &theta)).ok()?;
    let mut e = energy(p, &sim);
    // One parameter: a coarse grid over its bounds first, so that a non-smooth or
    // strongly nonlinear response (backlash events, a clipping limit) cannot trap the
    // local search near the linear estimate.
    if let [s0] = specs {
        let (lo, hi) = (s0.lower, s0.upper);
        let grid: Vec<f64> = if lo > 0.0 && hi / lo > 20.0 {
            (0..16).map(|i| lo * (hi / lo).powf(f64::from(i) / 15.0)).collect()
        } else {
            (0..16).map(|i| lo + (hi - lo) * f64::from(i) / 15.0).collect()
        };
        let jobs: Vec<Effects> = grid.iter().map(|v| with_values(&o.base, specs, &[*v])).collect();
        for (v, r) in grid.iter().zip(run_all(twin, &jobs, o.threads)) {
            if let Ok(y) = r {
                let ey = energy(p, &y);
                if ey < e {
                    e = ey;
                    sim = y;
                    theta = vec![*v];
                }
            }
        }
    }
    let mut lambda = 1e-3;
    let mut jac: Vec<Vec<Vec<f64>>> = Vec::new();
    for _iter in 0..8 {
        // Jacobian by forward differences (half the sensitivity step: closer to linear).
        let jobs: Vec<Effects> = specs
            .iter()
            .zip(&theta)
            .map(|(s, &v)| {
                let h = if v + 0.5 * s.delta <= s.upper { 0.5 * s.delta } else { -0.5 * s.delta };
                let mut t = theta.clone();
                t[specs.iter().position(|x| std::ptr::eq(*x, *s)).unwrap_or(0)] = v + h;
                with_values(&o.base, specs, &t)
            })
            .collect();
        let runs = run_all(twin, &jobs, o.threads);
        jac = Vec::with_capacity(specs.len());
        for ((s, &v), r) in specs.iter().zip(&theta).zip(runs) {
            let y = r.ok()?;
            let h = if v + 0.5 * s.delta <= s.upper { 0.5 * s.delta } else { -0.5 * s.delta };
            jac.push(
                y.iter()
                    .zip(&sim)
                    .map(|(a, b)| p.idx.iter().map(|&t| (f64::from(a[t]) - f64::from(b[t])) / h).collect())
                    .collect(),
            );
        }
        let n = specs.len();
        let mut g = vec![0.0; n * n];
        let mut b = vec![0.0; n];
        for (c, w) in p.weights.iter().enumerate() {
            for (k, &t) in p.idx.iter().enumerate() {
                let r = p.meas[c][t] - f64::from(sim[c][t]);
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
        let mut improved = false;
        for _ in 0..6 {
            let mut gl = g.clone();
            for i in 0..n {
                gl[i * n + i] *= 1.0 + lambda;
            }
            let step = solve_spd(&gl, &b, 1e-12)?;
            let mut cand: Vec<f64> = theta.iter().zip(&step).map(|(a, d)| a + d).collect();
            clamp(&mut cand);
            let Ok(s2) = twin.run(&with_values(&o.base, specs, &cand)) else { break };
            let e2 = energy(p, &s2);
            if std::env::var_os("SIMROD_DIAG_DEBUG").is_some() {
                eprintln!(
                    "  LM {}: theta {theta:?} e {e:.3} -> cand {cand:?} e2 {e2:.3} lambda {lambda:e}",
                    specs[0].effect
                );
            }
            if e2 < e {
                let rel = (e - e2) / e.max(1e-300);
                theta = cand;
                sim = s2;
                e = e2;
                lambda = (lambda * 0.3).max(1e-9);
                improved = rel > 1e-6;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let mut fit = Fit { values: theta, sim, jac, energy: e, profile: Vec::new() };
    if let [s0] = specs {
        profile_scan(twin, p, o, s0, &mut fit);
    }
    Some(fit)
}

/// Standard deviations of the refit parameters from the sandwich covariance
/// `G⁻¹ S G⁻¹`, `G = J'WJ`, `S = J'W Σ W J` with `Σ` each channel's noise: local standard
/// deviation `s(t)` (moving RMS of the residual over `level_win` samples) times the
/// autocorrelation `ρ(k)` of the standardised residual, up to the lag where it fades.
fn sandwich_std(p: &Prepared, fit: &Fit, level_win: usize, max_lag: usize) -> Vec<f64> {
    let n = fit.values.len();
    let m = p.idx.len();
    let mut g = vec![0.0; n * n];
    let mut sm = vec![0.0; n * n];
    for (c, w) in p.weights.iter().enumerate() {
        let r: Vec<f64> = p.idx.iter().map(|&t| p.meas[c][t] - f64::from(fit.sim[c][t])).collect();
        // Local noise level: moving RMS, so at-limit noise weighs where it occurs.
        let h = (level_win / 2).max(1);
        let mut prefix = vec![0.0; m + 1];
        for (k, v) in r.iter().enumerate() {
            prefix[k + 1] = prefix[k] + v * v;
        }
        let level: Vec<f64> = (0..m)
            .map(|k| {
                let (lo, hi) = (k.saturating_sub(h), (k + h + 1).min(m));
                // Floored at 0.1 % of the channel's noise: stretches with no residual at
                // all (a shaft at rest) must not turn into infinite standardised values.
                ((prefix[hi] - prefix[lo]) / (hi - lo) as f64).max(1e-6 / w).sqrt()
            })
            .collect();
        let z: Vec<f64> = r.iter().zip(&level).map(|(a, b)| a / b).collect();
        let z0: f64 = z.iter().map(|v| v * v).sum::<f64>().max(1e-300);
        // Autocorrelation until it fades below 0.05 (at most `max_lag`).
        let mut rho = vec![1.0];
        for lag in 1..max_lag.min(m / 4).max(1) {
            let a = (0..m - lag).map(|k| z[k] * z[k + lag]).sum::<f64>() / z0;
            if a < 0.05 {
                break;
            }
            rho.push(a);
        }
        // Jacobian columns scaled by the weight and the local level.
        let u: Vec<Vec<f64>> =
            (0..n).map(|i| (0..m).map(|k| w * fit.jac[i][c][k] * level[k]).collect()).collect();
        // S = U' R U with R the Toeplitz matrix of ρ: convolve each column once.
        let v: Vec<Vec<f64>> = u
            .iter()
            .map(|col| {
                (0..m)
                    .map(|k| {
                        let mut acc = col[k];
                        for (lag, rl) in rho.iter().enumerate().skip(1) {
                            let left = if k >= lag { col[k - lag] } else { 0.0 };
                            let right = col.get(k + lag).copied().unwrap_or(0.0);
                            acc += rl * (left + right);
                        }
                        acc
                    })
                    .collect()
            })
            .collect();
        for i in 0..n {
            for j in 0..n {
                sm[i * n + j] += u[i].iter().zip(&v[j]).map(|(a, b)| a * b).sum::<f64>();
                g[i * n + j] += (0..m).map(|k| w * fit.jac[i][c][k] * fit.jac[j][c][k]).sum::<f64>();
            }
        }
    }
    // Cov = G⁻¹ S G⁻¹.
    let mut ginv_s = vec![0.0; n * n];
    for j in 0..n {
        let col: Vec<f64> = (0..n).map(|i| sm[i * n + j]).collect();
        if let Some(x) = solve_spd(&g, &col, 1e-12) {
            for i in 0..n {
                ginv_s[i * n + j] = x[i];
            }
        }
    }
    // A parameter the run does not excite at all (reverse rates on a forward-only run)
    // is undetermined: infinite σ, not the ridge's spurious zero.
    let gmax = (0..n).map(|i| g[i * n + i]).fold(0.0f64, f64::max);
    (0..n)
        .map(|i| {
            if g[i * n + i] <= 1e-12 * gmax {
                return f64::INFINITY;
            }
            let row: Vec<f64> = (0..n).map(|j| ginv_s[i * n + j]).collect();
            let x = solve_spd(&g, &row, 1e-12).unwrap_or_else(|| vec![f64::NAN; n]);
            x[i].max(0.0).sqrt()
        })
        .collect()
}

/// Diagnose `meas` (`[channel][sample]`, channels as `twin.channels()`).
pub fn diagnose(
    twin: &dyn Twin,
    meas: &[Vec<f64>],
    o: &Options,
    probe: Option<&dyn ProfileProbe>,
) -> Result<Diagnosis, String> {
    let channels = twin.channels();
    if meas.len() != channels.len() {
        return Err(format!("{} measured channels for {} simulated", meas.len(), channels.len()));
    }
    let n = twin.samples();
    if meas.iter().any(|m| m.len() != n) || n < 10 {
        return Err("measured channels must have as many samples as the twin (at least 10)".into());
    }
    let base = twin.run(&o.base)?;
    let stride = n.div_ceil(o.max_fit_samples.max(1)).max(1);
    let idx: Vec<usize> = (0..n).step_by(stride).collect();
    let base64: Vec<Vec<f64>> = base.iter().map(|c| c.iter().map(|v| f64::from(*v)).collect()).collect();
    let mut noise = Vec::new();
    let mut weights = Vec::new();
    for ((m, s), c) in meas.iter().zip(&base64).zip(channels) {
        let r: Vec<f64> = m.iter().zip(s).map(|(a, b)| a - b).collect();
        let rms = (m.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        // 0.25 s: slower than a tachometer's counting window, faster than most model error.
        let h = ((0.125 / twin.dt_s()).round() as usize).max(5);
        let sigma = noise_sigma(&r, h).max(1e-4 * rms).max(1e-9);
        noise.push((c.name(), sigma));
        weights.push(1.0 / (sigma * sigma));
    }
    let p = Prepared { meas: meas.to_vec(), base: base64, weights, idx };
    let e0 = energy(&p, &base);
    let e_noise = (p.idx.len() * channels.len()) as f64;
    // The error above noise. Floored at 0.1 % of the noise energy so that a run with no
    // excess does not turn chance reductions into large fractions.
    let excess = (e0 - e_noise).max(1e-3 * e_noise).max(1e-300);
    let excess_ratio = e0 / e_noise;

    // Sensitivities.
    let specs = library(&o.params);
    let starts: Vec<f64> = specs.iter().map(|s| current_value(&o.base, s)).collect();
    let steps: Vec<f64> = specs
        .iter()
        .zip(&starts)
        .map(|(s, &v)| if v + s.delta <= s.upper { s.delta } else { -s.delta })
        .collect();
    let jobs: Vec<Effects> = specs
        .iter()
        .zip(starts.iter().zip(&steps))
        .map(|(s, (v, h))| with_values(&o.base, &[s], &[v + h]))
        .collect();
    let runs = run_all(twin, &jobs, o.threads);
    let np = specs.len();
    let m = p.idx.len();
    // sens[p][c][k], in units of the parameter step (well conditioned).
    let mut sens: Vec<Vec<Vec<f64>>> = Vec::with_capacity(np);
    for r in runs {
        let y = r?;
        sens.push(
            y.iter()
                .zip(&p.base)
                .map(|(a, b)| p.idx.iter().map(|&t| f64::from(a[t]) - b[t]).collect())
                .collect(),
        );
    }
    let mut g = vec![0.0; np * np];
    let mut b = vec![0.0; np];
    let mut gc = vec![vec![0.0; np * np]; channels.len()];
    let mut bc = vec![vec![0.0; np]; channels.len()];
    for (c, w) in p.weights.iter().enumerate() {
        for (k, &t) in p.idx.iter().enumerate() {
            let r = p.meas[c][t] - p.base[c][t];
            for i in 0..np {
                let si = sens[i][c][k];
                if si == 0.0 {
                    continue;
                }
                bc[c][i] += w * si * r;
                for j in 0..=i {
                    gc[c][i * np + j] += w * si * sens[j][c][k];
                }
            }
        }
    }
    for c in 0..channels.len() {
        for i in 0..np {
            for j in 0..i {
                gc[c][j * np + i] = gc[c][i * np + j];
            }
        }
        for i in 0..np * np {
            g[i] += gc[c][i];
        }
        for i in 0..np {
            b[i] += bc[c][i];
        }
    }
    let groups: Vec<(&'static str, Vec<usize>)> = {
        let mut v: Vec<(&'static str, Vec<usize>)> = Vec::new();
        for (i, s) in specs.iter().enumerate() {
            match v.iter_mut().find(|(e, _)| *e == s.effect) {
                Some((_, ix)) => ix.push(i),
                None => v.push((s.effect, vec![i])),
            }
        }
        v
    };
    // Linear fit of a set of parameters, bounded; returns (coefficients in steps, reduction).
    let fit_lin = |ix: &[usize]| -> (Vec<f64>, f64) {
        let gs = sub_matrix(&g, np, ix);
        let bs: Vec<f64> = ix.iter().map(|&i| b[i]).collect();
        let mut th = solve_spd(&gs, &bs, 1e-9).unwrap_or_else(|| vec![0.0; ix.len()]);
        for (t, &i) in th.iter_mut().zip(ix) {
            let s = &specs[i];
            let v = (starts[i] + *t * steps[i]).clamp(s.lower, s.upper);
            *t = (v - starts[i]) / steps[i];
        }
        let red = 2.0 * th.iter().zip(&bs).map(|(a, c)| a * c).sum::<f64>() - quad(&gs, &th);
        (th, red.max(0.0))
    };

    // Score each effect alone.
    let mut cands: Vec<Candidate> = Vec::new();
    let mut lin: Vec<Vec<f64>> = Vec::new();
    for (effect, ix) in &groups {
        let (th, red) = fit_lin(ix);
        let chans = channels
            .iter()
            .enumerate()
            .map(|(c, ch)| {
                let gs = sub_matrix(&gc[c], np, ix);
                let bs: Vec<f64> = ix.iter().map(|&i| bc[c][i]).collect();
                let red_c = 2.0 * th.iter().zip(&bs).map(|(a, x)| a * x).sum::<f64>() - quad(&gs, &th);
                let before = rmse(&p.meas[c], &p.base[c], &p.idx);
                let after2 = (before * before - red_c / p.weights[c] / m as f64).max(0.0);
                ChannelChange {
                    channel: ch.name(),
                    rmse_before: before,
                    rmse_predicted: after2.sqrt(),
                    rmse_confirmed: None,
                }
            })
            .collect();
        cands.push(Candidate {
            effect,
            params: ix
                .iter()
                .zip(&th)
                .map(|(&i, t)| {
                    let v = starts[i] + t * steps[i];
                    FittedParam {
                        name: specs[i].param,
                        value: v,
                        start: starts[i],
                        std: f64::NAN,
                        ci95: (v, v),
                        unit: specs[i].unit,
                    }
                })
                .collect(),
            predicted_reduction: (red / excess).min(1.0),
            confirmed_reduction: None,
            significant: false,
            channels: chans,
            regions: region_errors(&p, &o.regions, |c, k| {
                ix.iter().zip(&th).map(|(&i, t)| sens[i][c][k] * t).sum::<f64>()
            }),
        });
        lin.push(th);
    }

    // Greedy orthogonal forward regression.
    let mut selected: Vec<(&'static str, f64)> = Vec::new();
    let mut chosen: Vec<usize> = Vec::new();
    let mut chosen_red = 0.0;
    for _ in 0..o.max_selected {
        let mut best: Option<(usize, f64)> = None;
        for (gi, (_, ix)) in groups.iter().enumerate() {
            if selected.iter().any(|(e, _)| *e == groups[gi].0) {
                continue;
            }
            let mut joint = chosen.clone();
            joint.extend(ix);
            let inc = fit_lin(&joint).1 - chosen_red;
            if best.is_none_or(|(_, r)| inc > r) {
                best = Some((gi, inc));
            }
        }
        let Some((gi, inc)) = best else { break };
        if inc < 0.05 * excess {
            break;
        }
        chosen.extend(&groups[gi].1);
        chosen_red += inc;
        selected.push((groups[gi].0, inc / excess));
    }

    // Refit the leaders on the simulator.
    let mut order: Vec<usize> = (0..cands.len()).collect();
    order.sort_by(|&a, &b2| cands[b2].predicted_reduction.total_cmp(&cands[a].predicted_reduction));
    let mut refit_list: Vec<usize> =
        selected.iter().filter_map(|(e, _)| cands.iter().position(|c| c.effect == *e)).collect();
    for &i in &order {
        if refit_list.len() >= o.refit.max(selected.len()) {
            break;
        }
        if !refit_list.contains(&i) {
            refit_list.push(i);
        }
    }
    // Noise level window for the sandwich covariance: 1 s; correlations up to 2 s.
    let level_win = ((1.0 / (twin.dt_s() * stride as f64)).round() as usize).max(3);
    let mut fits: Vec<(usize, Fit)> = Vec::new();
    for &ci in &refit_list {
        let ix = &groups[ci].1;
        let sp: Vec<&ParamSpec> = ix.iter().map(|&i| &specs[i]).collect();
        let start: Vec<f64> = cands[ci].params.iter().map(|f| f.value).collect();
        let Some(fit) = refit(twin, &p, o, &sp, &start) else { continue };
        let mut std = sandwich_std(&p, &fit, level_win, 2 * level_win);
        // One parameter: the profile interval — values whose energy the data cannot tell
        // from the minimum (3.84 for 95 %, scaled by the sandwich's inflation over the
        // naive variance) — widens the interval where the objective is rugged.
        if let ([sd], [s0]) = (std.as_mut_slice(), sp.as_slice()) {
            let g: f64 = (0..p.weights.len())
                .map(|c| p.weights[c] * fit.jac[0][c].iter().map(|j| j * j).sum::<f64>())
                .sum();
            let kappa = (*sd * *sd * g).max(1.0);
            let inside: Vec<f64> = fit
                .profile
                .iter()
                .filter(|(_, e)| *e - fit.energy <= 3.84 * kappa)
                .map(|(v, _)| *v)
                .collect();
            if let (Some(a), Some(b)) = (inside.first(), inside.last()) {
                let step = fit.profile.windows(2).map(|w| w[1].0 - w[0].0).fold(0.0, f64::max);
                let half = 0.5 * (b - a) + step;
                *sd = sd.max(half / 1.96).min(s0.upper - s0.lower);
            }
        }
        // A parameter the model can only realise in steps (a delay in whole time steps)
        // is uncertain by at least its quantisation.
        for (sd, sp) in std.iter_mut().zip(&sp) {
            let q = sp.quantum(twin.dt_s());
            *sd = (*sd * *sd + q * q / 12.0).sqrt();
        }
        let cand = &mut cands[ci];
        cand.confirmed_reduction = Some(((e0 - fit.energy) / excess).clamp(0.0, 1.0));
        cand.significant = false;
        for ((fp, &v), (sd, s)) in cand.params.iter_mut().zip(&fit.values).zip(std.iter().zip(&sp)) {
            fp.value = v;
            fp.std = *sd;
            fp.ci95 = ((v - 1.96 * sd).max(s.lower), (v + 1.96 * sd).min(s.upper));
            if (v - fp.start).abs() > 2.0 * sd && (v - fp.start).abs() > 1e-6 * s.delta {
                cand.significant = true;
            }
        }
        for (c, ch) in cand.channels.iter_mut().enumerate() {
            let s: Vec<f64> = fit.sim[c].iter().map(|v| f64::from(*v)).collect();
            ch.rmse_confirmed = Some(rmse(&p.meas[c], &s, &p.idx));
        }
        let confirmed =
            region_errors(&p, &o.regions, |c, k| f64::from(fit.sim[c][p.idx[k]]) - p.base[c][p.idx[k]]);
        for (rc, conf) in cand.regions.iter_mut().zip(confirmed) {
            rc.confirmed = Some(conf.predicted);
        }
        fits.push((ci, fit));
    }

    // Rank: refitted and significant first by confirmed reduction, then the rest.
    let key = |c: &Candidate| (c.confirmed_reduction.is_some() && c.significant, c.reduction());
    let mut ranking = cands.clone();
    ranking.sort_by(|a, b2| {
        let (ka, kb) = (key(a), key(b2));
        kb.0.cmp(&ka.0).then(kb.1.total_cmp(&ka.1))
    });

    // Confounding among refitted leaders.
    let mut confounded = Vec::new();
    if let Some(lead) = ranking.first().filter(|c| c.significant) {
        let li = cands.iter().position(|c| c.effect == lead.effect).unwrap_or(0);
        let lead_red = lead.reduction();
        let shape = |ci: usize| -> Vec<f64> {
            let ix = &groups[ci].1;
            let mut v = vec![0.0; np];
            for (t, &i) in lin[ci].iter().zip(ix) {
                v[i] = *t;
            }
            v
        };
        let dot = |a: &[f64], c: &[f64]| -> f64 {
            let mut s = 0.0;
            for i in 0..np {
                if a[i] == 0.0 {
                    continue;
                }
                for j in 0..np {
                    s += a[i] * g[i * np + j] * c[j];
                }
            }
            s
        };
        let va = shape(li);
        let mut members = vec![lead.effect];
        let mut worst_cos: f64 = 1.0;
        for (ci, c) in cands.iter().enumerate() {
            if ci == li || !c.significant || c.reduction() < 0.7 * lead_red {
                continue;
            }
            let vb = shape(ci);
            let cos = dot(&va, &vb) / (dot(&va, &va) * dot(&vb, &vb)).sqrt().max(1e-300);
            if cos.abs() >= o.confounded_cosine {
                members.push(c.effect);
                worst_cos = worst_cos.min(cos.abs());
            }
        }
        if members.len() > 1 {
            let separating =
                probe.and_then(|pr| separating_profile(pr, o, &specs, &members, &fits, &cands, &p.weights));
            confounded.push(ConfoundedGroup {
                effects: members,
                cosine: worst_cos,
                separating_profile: separating,
            });
        }
    }

    // Verdict.
    let locate_rest = |sim: &[Vec<f32>]| -> Location {
        let mut shares: Vec<(usize, f64)> = p
            .meas
            .iter()
            .zip(sim)
            .zip(&p.weights)
            .enumerate()
            .map(|(c, ((mm, s), w))| {
                (c, p.idx.iter().map(|&t| w * (mm[t] - f64::from(s[t])).powi(2)).sum::<f64>() - m as f64)
            })
            .collect();
        let total: f64 = shares.iter().map(|(_, e)| e.max(0.0)).sum::<f64>().max(1e-300);
        shares.sort_by(|a, b2| b2.1.total_cmp(&a.1));
        let (c, e) = shares[0];
        // Worst 2 s window of that channel's residual.
        let win = ((2.0 / twin.dt_s()).round() as usize).clamp(1, n);
        let r2: Vec<f64> = p.meas[c].iter().zip(&sim[c]).map(|(a, s)| (a - f64::from(*s)).powi(2)).collect();
        let mut acc: f64 = r2[..win].iter().sum();
        let (mut best, mut at) = (acc, 0);
        for i in win..n {
            acc += r2[i] - r2[i - win];
            if acc > best {
                best = acc;
                at = i + 1 - win;
            }
        }
        let dt = twin.dt_s();
        Location {
            channel: channels[c].name(),
            share: e.max(0.0) / total,
            window_s: (at as f64 * dt, (at + win) as f64 * dt),
        }
    };
    // Energy each refitted candidate leaves, and whether it leaves noise.
    let after = |effect: &str| fits.iter().find(|(ci, _)| cands[*ci].effect == effect).map(|(_, f)| f);
    let counts = |c: &Candidate| {
        c.significant && after(c.effect).is_some_and(|f| e0 - f.energy >= o.min_reduction_of_noise * e_noise)
    };
    let lead_ok = ranking.iter().find(|c| counts(c));
    let mut proposed = o.base;
    if let Some(l) = lead_ok {
        if let Some((ci, f)) = fits.iter().find(|(ci, _)| cands[*ci].effect == l.effect) {
            let sp: Vec<&ParamSpec> = groups[*ci].1.iter().map(|&i| &specs[i]).collect();
            proposed = with_values(&o.base, &sp, &f.values);
        }
    }
    let describe = |l: &Candidate| -> String {
        let params: Vec<String> = l
            .params
            .iter()
            .map(|fp| format!("{} = {:.4} ± {:.4} {}", fp.name, fp.value, 1.96 * fp.std, fp.unit))
            .collect();
        format!("{} ({})", l.effect, params.join(", "))
    };
    let ratio_after = lead_ok.and_then(|l| after(l.effect)).map_or(excess_ratio, |f| f.energy / e_noise);
    // An effect is judged on the channels it acts on: the share of their excess error it
    // removes, and whether what it leaves there is noise. (A torque-sensor offset acts on
    // one channel of thirteen; its share of the whole run's excess says little.)
    let e0c = channel_energies(&p, &base);
    let per_sample = p.idx.len() as f64;
    let on_affected = |f: &Fit| -> (f64, f64) {
        let e1c = channel_energies(&p, &f.sim);
        let (mut removed, mut excess_a, mut left, mut k) = (0.0, 0.0, 0.0, 0.0);
        for (a, b) in e0c.iter().zip(&e1c) {
            if a - b > o.min_reduction_of_noise * per_sample {
                removed += a - b;
                excess_a += (a - per_sample).max(1e-3 * per_sample);
                left += b;
                k += 1.0;
            }
        }
        if k == 0.0 {
            (0.0, f64::INFINITY)
        } else {
            ((removed / excess_a).min(1.0), left / (k * per_sample))
        }
    };
    let (red_a, after_a) = lead_ok.and_then(|l| after(l.effect)).map_or((0.0, f64::INFINITY), on_affected);
    let place = |loc: &Location| {
        format!(
            "{} ({:.0} % of the excess), worst at {:.1}–{:.1} s",
            loc.channel,
            100.0 * loc.share,
            loc.window_s.0,
            loc.window_s.1
        )
    };
    let (kind, verdict, unexplained) = match lead_ok {
        Some(l) if red_a >= o.explain_fraction && after_a <= o.noise_like_ratio && ratio_after <= o.noise_like_ratio => {
            let group = confounded.first().map(|g| {
                let sep =
                    g.separating_profile.as_ref().map(|(pr, cos)| format!("; run {pr} to separate them (cosine {cos:.2})"));
                format!(
                    " — confounded with {} on this run (cosine {:.2}){}",
                    g.effects[1..].join(", "),
                    g.cosine,
                    sep.unwrap_or_default()
                )
            });
            (
                VerdictKind::Missing,
                format!(
                    "missing effect: {}, removes {:.0} % of the error above noise on the channels it acts on and leaves a noise-like residual{}",
                    describe(l),
                    100.0 * red_a,
                    group.unwrap_or_default()
                ),
                None,
            )
        }
        Some(l) if red_a >= o.explain_fraction && after_a <= o.noise_like_ratio => {
            let loc = locate_rest(&after(l.effect).map_or_else(|| base.clone(), |f| f.sim.clone()));
            (
                VerdictKind::Partial,
                format!(
                    "missing effect: {} explains the error on the channels it acts on ({:.0} % there); more remains elsewhere ({:.1}x the noise): {}",
                    describe(l),
                    100.0 * red_a,
                    ratio_after,
                    place(&loc)
                ),
                Some(loc),
            )
        }
        _ if excess_ratio <= o.noise_like_ratio => (
            VerdictKind::NothingMissing,
            format!(
                "no effect is missing: the residual is noise-like (weighted energy {excess_ratio:.2}x what the estimated noise gives)"
            ),
            None,
        ),
        Some(l) if l.reduction() >= o.unexplained_fraction => {
            let loc = locate_rest(&after(l.effect).map_or_else(|| base.clone(), |f| f.sim.clone()));
            (
                VerdictKind::Partial,
                format!(
                    "partly explained: {} removes {:.0} % of the error above noise, but what remains is {:.1}x the noise and no library effect explains it: {}",
                    describe(l),
                    100.0 * l.reduction(),
                    ratio_after,
                    place(&loc)
                ),
                Some(loc),
            )
        }
        _ => {
            let loc = locate_rest(&base);
            (
                VerdictKind::Unexplained,
                format!(
                    "unexplained: no effect in the library explains the residual (the best, {}, removes {:.0} %): {}",
                    ranking.first().map_or("none", |c| c.effect),
                    100.0 * ranking.first().map_or(0.0, |c| c.reduction()),
                    place(&loc)
                ),
                Some(loc),
            )
        }
    };
    let lead = match kind {
        VerdictKind::Missing | VerdictKind::Partial => lead_ok.map(|l| l.effect),
        _ => None,
    };
    Ok(Diagnosis {
        kind,
        verdict,
        excess_ratio,
        noise,
        lead,
        ranking,
        selected,
        confounded,
        unexplained,
        proposed,
    })
}

/// Among the built-in profiles the probe offers, the one where the members' simulated
/// effects are least alike (smallest |cosine| of their output changes).
fn separating_profile(
    probe: &dyn ProfileProbe,
    o: &Options,
    specs: &[ParamSpec],
    members: &[&'static str],
    fits: &[(usize, Fit)],
    cands: &[Candidate],
    w: &[f64],
) -> Option<(String, f64)> {
    // Each member at its fitted values (or a step if not refitted).
    let fx_of = |effect: &str| -> Effects {
        let c = cands.iter().find(|c| c.effect == effect);
        let sp: Vec<&ParamSpec> = specs.iter().filter(|s| s.effect == effect).collect();
        let vals: Vec<f64> = match (c, fits.iter().find(|(ci, _)| cands[*ci].effect == effect)) {
            (_, Some((_, f))) => f.values.clone(),
            (Some(c), None) => c.params.iter().map(|p| p.value).collect(),
            _ => sp.iter().map(|s| s.neutral + s.delta).collect(),
        };
        with_values(&o.base, &sp, &vals)
    };
    let (a, b) = (fx_of(members[0]), fx_of(members[1]));
    let mut best: Option<(String, f64)> = None;
    for i in 0..probe.count() {
        let (Some(base), Some(sa), Some(sb)) = (probe.run(i, &o.base), probe.run(i, &a), probe.run(i, &b))
        else {
            continue;
        };
        let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
        for (c, wc) in w.iter().enumerate().take(base.len()) {
            for t in 0..base[c].len() {
                let da = f64::from(sa[c][t] - base[c][t]);
                let db = f64::from(sb[c][t] - base[c][t]);
                ab += wc * da * db;
                aa += wc * da * da;
                bb += wc * db * db;
            }
        }
        // Both effects must show above the noise on the profile, or it separates nothing.
        let samples = base.first().map_or(0, Vec::len) as f64;
        if aa < 0.01 * samples || bb < 0.01 * samples {
            continue;
        }
        let cos = (ab / (aa * bb).sqrt().max(1e-300)).abs();
        if best.as_ref().is_none_or(|(_, c)| cos < *c) {
            best = Some((probe.name(i), cos));
        }
    }
    best
}
