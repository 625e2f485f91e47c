//! Stage 2: how every measured channel responds to every library parameter — one
//! simulation per parameter (finite differences, in parallel) — and the weighted normal
//! equations of the linear fits, whole and per channel.

use model_core::{Channel, Effects};

use super::engine::{Options, Twin};
use super::library::{current_value, library, with_values, ParamSpec};
use super::preparation::{channel_energies, flagged_windows, run_each, Prepared, RunResult, Weights};

/// The library's parameters and the linearised model around the current one.
#[derive(Default)]
pub(super) struct Sensitivities {
    /// Every library parameter, in library order.
    pub specs: Vec<ParamSpec>,
    /// Each parameter's value in the current model.
    pub starts: Vec<f64>,
    /// The finite-difference step (negative at the upper bound); the fits' unit.
    pub steps: Vec<f64>,
    /// `sens[parameter][channel][fit sample]`: the output change for one step.
    pub sens: Vec<Vec<Vec<f64>>>,
    /// `J'WJ` over all channels (`np x np`, row-major).
    pub g: Vec<f64>,
    /// `J'W r` over all channels.
    pub b: Vec<f64>,
    /// `J'WJ` per channel.
    pub gc: Vec<Vec<f64>>,
    /// `J'W r` per channel.
    pub bc: Vec<Vec<f64>>,
    /// Parameter indices of each candidate cause, in library order.
    pub groups: Vec<(&'static str, Vec<usize>)>,
    /// `J'WJ` and `J'W r` of each held-out fold ([`Prepared::folds`]), all channels.
    pub gf: Vec<Vec<f64>>,
    pub bf: Vec<Vec<f64>>,
}

impl Sensitivities {
    /// Number of parameters.
    pub fn np(&self) -> usize {
        self.specs.len()
    }
}

/// A channel's own measurement chain is a candidate only where the channel's error is
/// this much above its noise (weighted energy per fit sample; noise alone gives 1 to
/// about 1 %): a sensor cause moves its channel alone, so it cannot explain error
/// elsewhere, and the 56 chain parameters of quiet channels would double the work. A
/// channel below it whose residual has located structure is a candidate too
/// ([`located_structure`]).
pub const SENSOR_EXCESS: f64 = 1.02;

/// Whether `s` is worth a sensitivity run on this data: every physical parameter, and
/// the chain parameters of channels with error above [`SENSOR_EXCESS`] or with located
/// structure (`located`, [`located_structure`]). Not the throttle
/// voltage's gain: the pedal's volts per percent feed the controller as well as the
/// recording, so a gain on the recorded voltage alone describes a wrong calibration
/// without being its cause (tuning cases with the plant's calibration 0.5 % off claimed
/// it); the throttle's delay, lag and offset are the acquisition's.
fn worth_fitting(
    s: &ParamSpec,
    p: &Prepared,
    channels: &[Channel],
    energies: &[f64],
    located: &[bool],
) -> bool {
    if s.cause == s.effect {
        return true;
    }
    if s.effect == "sensor_gain" && Channel::from_key(s.param) == Some(Channel::Throttle) {
        return false;
    }
    let n = p.idx.len().max(1) as f64;
    let fitted = Channel::from_key(s.param).and_then(|c| channels.iter().position(|k| *k == c));
    fitted.is_some_and(|i| {
        energies.get(i).is_some_and(|e| e / n > SENSOR_EXCESS) || located.get(i).copied().unwrap_or(false)
    })
}

/// Per channel, whether the current residual has a time window the structure test flags
/// ([`Prepared::base_windows`], [`flagged_windows`]; a mains line is no sensor's): a
/// sensor's lag or delay errs only at the transients, which a whole-run energy can leave
/// below [`SENSOR_EXCESS`] while the diagnosis locates the error on that channel.
fn located_structure(p: &Prepared) -> Vec<bool> {
    let mut located = vec![false; p.base_windows.len()];
    for (c, _) in flagged_windows(&p.base_windows).into_iter().filter(|(_, w)| w.line_hz.is_none()) {
        located[c] = true;
    }
    located
}

/// Simulate one step of every library parameter worth fitting and set up the normal
/// equations.
pub(super) fn sensitivities(twin: &dyn Twin, p: &Prepared, o: &Options) -> Result<Sensitivities, String> {
    let energies = channel_energies(p, &p.base_sim);
    let located = located_structure(p);
    let specs: Vec<ParamSpec> = library(&o.params)
        .into_iter()
        .filter(|s| worth_fitting(s, p, twin.channels(), &energies, &located))
        .collect();
    let starts: Vec<f64> = specs.iter().map(|s| current_value(&o.base, s)).collect();
    let steps: Vec<f64> = specs.iter().zip(&starts).map(|(s, &v)| s.step_from(v)).collect();
    let jobs: Vec<Effects> = specs
        .iter()
        .zip(starts.iter().zip(&steps))
        .map(|(s, (v, h))| with_values(&o.base, &[s], &[v + h]))
        .collect();
    let mut sens: Vec<Vec<Vec<f64>>> = Vec::with_capacity(specs.len());
    // A parameter the twin never reads on these runs responds with the base run.
    let pairs: Vec<(&Effects, &ParamSpec)> = jobs.iter().zip(&specs).collect();
    let runs: Vec<RunResult> = run_each(&pairs, o, |(fx, s)| match p.unread.param(s) {
        true => Ok(p.base_sim.clone()),
        false => twin.run_every(fx, p.stride),
    });
    for r in runs {
        let y = r?;
        check_shape(p, &y)?;
        sens.push(
            y.iter()
                .zip(&p.base)
                .map(|(a, b)| p.idx.iter().map(|&t| f64::from(a[t]) - b[t]).collect())
                .collect(),
        );
    }
    // The two sums read the same Jacobian and are each a serial pass: side by side.
    let ((gc, bc), (gf, bf)) =
        rayon::join(|| channel_normal_equations(p, &sens), || fold_normal_equations(p, &sens));
    let np = specs.len();
    let mut g = vec![0.0; np * np];
    let mut b = vec![0.0; np];
    for (gcc, bcc) in gc.iter().zip(&bc) {
        g.iter_mut().zip(gcc).for_each(|(a, x)| *a += x);
        b.iter_mut().zip(bcc).for_each(|(a, x)| *a += x);
    }
    let groups = effect_groups(&specs);
    Ok(Sensitivities { specs, starts, steps, sens, g, b, gc, bc, groups, gf, bf })
}

/// A simulation must have the measurement's channels and samples.
pub(super) fn check_shape(p: &Prepared, y: &[Vec<f32>]) -> Result<(), String> {
    let n = p.meas.first().map_or(0, Vec::len);
    if y.len() != p.meas.len() || y.iter().any(|c| c.len() != n) {
        return Err("the twin returned channels of the wrong shape".into());
    }
    Ok(())
}

/// Per channel `c`: `J_c' w_c J_c` (symmetric, full) and `J_c' w_c r_c`.
fn channel_normal_equations(p: &Prepared, sens: &[Vec<Vec<f64>>]) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    normal_equations_by(&p.weights, sens, |c, k| base_residual(p, c, k), p.weights.channels(), |c, _| c)
}

/// Per held-out fold: `J'WJ` (full) and `J'W r` over all channels.
fn fold_normal_equations(p: &Prepared, sens: &[Vec<Vec<f64>>]) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let nf = p.folds.iter().max().map_or(1, |m| m + 1);
    normal_equations_by(
        &p.weights,
        sens,
        |c, k| base_residual(p, c, k),
        nf,
        |_, k| p.folds.get(k).copied().unwrap_or(0),
    )
}

/// The current model's residual on channel `c` at fit sample `k`.
fn base_residual(p: &Prepared, c: usize, k: usize) -> f64 {
    let t = p.idx[k];
    p.meas[c][t] - p.base[c][t]
}

/// `J'WJ` (symmetric, full) and `J'W r` summed into `n` parts, the term of channel `c`
/// at fit sample `k` going to part `part(c, k)`: `weights` are each channel's `1/σ²`,
/// `jac[i][c][k]` the Jacobian, `resid(c, k)` the residual. Shared by the linearised
/// fits (on the sensitivities) and the fold jackknife (on a refit's Jacobian).
pub(super) fn normal_equations_by(
    weights: &Weights,
    jac: &[Vec<Vec<f64>>],
    resid: impl Fn(usize, usize) -> f64,
    n: usize,
    part: impl Fn(usize, usize) -> usize,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let np = jac.len();
    let mut g = vec![vec![0.0; np * np]; n];
    let mut b = vec![vec![0.0; np]; n];
    for c in 0..weights.channels() {
        let samples = jac.first().map_or(0, |j| j[c].len());
        #[allow(clippy::needless_range_loop)] // k indexes every parameter's column alike
        for k in 0..samples {
            let q = part(c, k).min(n - 1);
            let (w, r) = (weights.at(c, k), resid(c, k));
            for i in 0..np {
                let si = jac[i][c][k];
                if si == 0.0 {
                    continue;
                }
                b[q][i] += w * si * r;
                for j in 0..=i {
                    g[q][i * np + j] += w * si * jac[j][c][k];
                }
            }
        }
    }
    for gq in &mut g {
        for i in 0..np {
            for j in 0..i {
                gq[j * np + i] = gq[i * np + j];
            }
        }
    }
    (g, b)
}

/// Parameter indices grouped by cause ([`ParamSpec::cause`]), in order of first
/// appearance.
pub(super) fn effect_groups(specs: &[ParamSpec]) -> Vec<(&'static str, Vec<usize>)> {
    let mut v: Vec<(&'static str, Vec<usize>)> = Vec::new();
    for (i, s) in specs.iter().enumerate() {
        match v.iter_mut().find(|(e, _)| *e == s.cause) {
            Some((_, ix)) => ix.push(i),
            None => v.push((s.cause, vec![i])),
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use simrod_compare::structure::Window;

    /// A time window the structure test flags (or a mains line, `line`).
    fn flagged(line: bool) -> Window {
        Window {
            start: 2000,
            len: 2000,
            chi2: 200.0,
            dof: 20,
            p: 1e-30,
            log_p: -69.0,
            mean: 0.3,
            energy_ratio: 3.0,
            material: true,
            line_hz: line.then_some(50.0),
            fast: false,
        }
    }

    /// A lag on C_Kistler_L errs at the transients: its channel's whole-run error is at the
    /// noise, but the structure test flags a window there, so the channel's chain gets its
    /// candidates; a channel at the noise with only a mains line flagged (I_DC) does not.
    #[test]
    fn a_channel_with_located_structure_gets_its_chain_candidates() {
        let n = 100;
        let quiet = vec![0.0; n];
        let mut p = Prepared::single_run(
            vec![quiet.clone(), quiet],
            vec![("C_Kistler_L", 1.0), ("I_DC", 1.0)],
            vec![vec![0.0; n], vec![0.0; n]],
        );
        p.base_windows = vec![vec![flagged(false)], vec![flagged(true)]];
        let channels = [Channel::CKistlerL, Channel::IDc];
        let energies = vec![n as f64; 2];
        let lag = |c: Channel| {
            library(&Default::default())
                .into_iter()
                .find(|s| s.effect == "sensor_lag" && Channel::from_key(s.param) == Some(c))
                .expect("a lag spec for the channel")
        };
        let located = located_structure(&p);
        assert!(worth_fitting(&lag(Channel::CKistlerL), &p, &channels, &energies, &located));
        assert!(!worth_fitting(&lag(Channel::IDc), &p, &channels, &energies, &located));
        p.base_windows = vec![Vec::new(), Vec::new()];
        let located = located_structure(&p);
        assert!(!worth_fitting(&lag(Channel::CKistlerL), &p, &channels, &energies, &located));
    }
}
