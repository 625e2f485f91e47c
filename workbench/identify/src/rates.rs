//! `simrod identify inverter-rates`: the Curtis rate parameters and the LS threshold
//! from throttle steps (thesis 5.6, tables 5.16/5.17), per direction.
//!
//! Each throttle step is classified as the controller classifies it (thesis 5.6, fig.
//! 5.50): |speed| grows → acceleration, blended between Low Accel Rate (mapped throttle
//! ≤ 10 %) and Accel Rate (≥ 90 %) in proportion to the mapped throttle; |speed| falls
//! with mapped throttle 0 → Neutral Decel; with throttle left → Partial Decel. The
//! measured SuT speed ramps at the commanded rate once the speed loop has caught up, so
//! the rate is the speed's slope: fitted over 0.2 s windows of each ramp, giving rate
//! against speed. Accel and Neutral Decel rates blend linearly between their LS and HS
//! values between LS and HS % of Typical Max Speed; the model for one direction is
//!
//! ```text
//! accel:         r = (1 − f) r_low + f (r_ls + g_a h(s))     f = (mapped − 10) / 80, clamped
//! neutral decel: r = r_nls + g_n h(s)                         h(s) = clamp(s − LS, 0, HS − LS)
//! partial decel: r = r_pd
//! ```
//!
//! linear in the rates for a given LS, which is found by a grid search (a change of
//! slope). A rate parameter `t` [s] is `Typical Max Speed / r`. The thesis found HS
//! "not reached"; when the speed never reaches HS, only the blend's gradient is seen,
//! so the HS rate is the blend extrapolated to the base model's HS (said so in the
//! note) and HS itself is undetermined. LS is reported only when the change of slope
//! is significant (F test) with data on both sides. Uncertainties: the larger of the
//! least-squares standard error and a bootstrap over transients (resampled within each
//! direction and case; for LS at least 0.5 %, the grid's and the speed window's scale).
//! Ramps too short to show a settled slope (reverse decelerations from 500 rpm last
//! ~0.3 s) are listed as left out, not fitted.

use std::fmt::Write as _;

use model_core::{Maps, Params};

use super::estimate::{sig, Estimate, Outcome, Plot};
use super::report::{xy_chart, XyLine, XyPoints};
use super::transients::{
    find_transients, line_fit, mapped_pct, require, sample_dt, steady_intervals, throttle_pct, MIN_INTERVAL_S,
};
use simrod_io::error::FileError;
use simrod_io::measure::Measurement;
use simrod_numerics::stats::{spread68, Rng};

/// Window over which one rate sample is fitted [s].
const WINDOW_S: f64 = 0.2;
/// F statistic a change of slope must exceed to count as an LS threshold.
const F_KNEE: f64 = 15.0;

/// What the rate identification needs from the base model.
#[derive(Debug, Clone, Copy)]
pub struct RatesOptions<'a> {
    /// Base parameters: Typical Max Speed, the throttle-case thresholds, HS (kept when
    /// not reached) and the values shown for comparison.
    pub params: Params,
    /// The throttle input map (set point → mapped throttle).
    pub maps: Maps<'a>,
    /// Bootstrap replicates (0: least-squares errors only).
    pub bootstrap: usize,
}

/// The controller case of a transient.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Case {
    /// Full, partial or low acceleration; `f` says which blend.
    Accel,
    NeutralDecel,
    PartialDecel,
}

impl Case {
    fn name(self, f: f64) -> &'static str {
        match self {
            Case::Accel if f >= 1.0 => "full accel",
            Case::Accel if f <= 0.0 => "low accel",
            Case::Accel => "partial accel",
            Case::NeutralDecel => "neutral decel",
            Case::PartialDecel => "partial decel",
        }
    }
}

/// One fitted rate sample.
#[derive(Debug, Clone, Copy)]
struct Sample {
    /// |speed| in % of Typical Max Speed.
    s: f64,
    /// |slope| [rpm/s].
    r: f64,
    case: Case,
    /// Accel blend weight of the Accel Rate (1 full, 0 low).
    f: f64,
    /// Transient id (for the bootstrap).
    tr: usize,
}

/// A transient as the report lists it.
#[derive(Debug, Clone)]
struct TransientRow {
    run: usize,
    t: f64,
    before: f64,
    after: f64,
    s0: f64,
    s1: f64,
    dir: usize,
    case: Case,
    f: f64,
    mean_rate: f64,
}

/// Parameters of one direction's fit: `[r_low, r_ls, g_a, r_nls, g_n, r_pd]`.
const NP: usize = 6;

#[derive(Debug, Clone)]
struct Fit {
    /// `None`: no knee (g columns dropped).
    ls: Option<f64>,
    theta: [f64; NP],
    /// Least-squares standard errors (NaN where unsupported).
    se: [f64; NP],
    /// Which parameters the data support.
    support: [bool; NP],
    sse: f64,
    n: usize,
}

fn row(s: &Sample, ls: Option<f64>, hs: f64) -> [f64; NP] {
    let h = ls.map_or(0.0, |ls| (s.s - ls).clamp(0.0, (hs - ls).max(0.0)));
    match s.case {
        Case::Accel => [1.0 - s.f, s.f, s.f * h, 0.0, 0.0, 0.0],
        Case::NeutralDecel => [0.0, 0.0, 0.0, 1.0, h, 0.0],
        Case::PartialDecel => [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
    }
}

/// Solve the least squares on the supported columns; unsupported ones are 0.
fn solve(samples: &[Sample], ls: Option<f64>, hs: f64) -> Option<Fit> {
    let rows: Vec<[f64; NP]> = samples.iter().map(|s| row(s, ls, hs)).collect();
    let mut support = [false; NP];
    for (j, sup) in support.iter_mut().enumerate() {
        *sup = rows.iter().filter(|r| r[j].abs() > 1e-9).count() >= 2;
    }
    let idx: Vec<usize> = (0..NP).filter(|j| support[*j]).collect();
    let m = idx.len();
    if m == 0 || samples.len() <= m {
        return None;
    }
    let a: Vec<f64> = rows.iter().flat_map(|r| idx.iter().map(move |&i| r[i])).collect();
    let y: Vec<f64> = samples.iter().map(|s| s.r).collect();
    // Rank-revealing: a knee that leaves two columns collinear makes the fit undetermined.
    let sol = simrod_numerics::linalg::lstsq(&a, samples.len(), m, &y).filter(|f| f.full_rank())?;
    let (x, inv) = (sol.x, sol.cov);
    let mut theta = [0.0; NP];
    for (a, &i) in idx.iter().enumerate() {
        theta[i] = x[a];
    }
    let sse: f64 = rows.iter().zip(samples).map(|(r, s)| (s.r - dot(r, &theta)).powi(2)).sum();
    let s2 = sse / (samples.len() - m) as f64;
    let mut se = [f64::NAN; NP];
    for (a, &i) in idx.iter().enumerate() {
        se[i] = (inv[a * m + a] * s2).max(0.0).sqrt();
    }
    Some(Fit { ls, theta, se, support, sse, n: samples.len() })
}

fn dot(a: &[f64; NP], b: &[f64; NP]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The best LS on a grid (coarse 1 %, then 0.05 %) between the lowest speed seen and HS.
fn knee_fit(samples: &[Sample], hs: f64) -> Option<Fit> {
    let lo = samples.iter().map(|s| s.s).fold(f64::INFINITY, f64::min).max(0.5);
    let hi = samples.iter().map(|s| s.s).fold(0.0, f64::max).min(hs - 0.5);
    if hi.is_nan() || lo.is_nan() || hi <= lo + 1.0 {
        return None;
    }
    let best_on = |grid: &mut dyn Iterator<Item = f64>| -> Option<Fit> {
        let mut best: Option<Fit> = None;
        for ls in grid {
            if let Some(f) = solve(samples, Some(ls), hs) {
                if (f.support[2] || f.support[4]) && best.as_ref().is_none_or(|b| f.sse < b.sse) {
                    best = Some(f);
                }
            }
        }
        best
    };
    let coarse = best_on(&mut (0..).map(|k| lo + f64::from(k)).take_while(|x| *x <= hi))?;
    let c = coarse.ls.unwrap_or(lo);
    best_on(&mut (-20..=20).map(|k| c + 0.05 * f64::from(k)).filter(|x| *x >= lo && *x <= hi))
}

/// One direction's complete fit: a knee if significant, else one rate per case.
fn fit_direction(samples: &[Sample], hs: f64) -> Option<(Fit, Option<f64>)> {
    let flat = solve(samples, None, hs)?;
    let Some(knee) = knee_fit(samples, hs) else {
        return Some((flat, None));
    };
    let ls = knee.ls.unwrap_or(0.0);
    let extra = [2usize, 4].iter().filter(|j| knee.support[**j]).count() as f64;
    let dof = knee.n as f64 - knee.support.iter().filter(|s| **s).count() as f64;
    let f_stat = if knee.sse > 0.0 && dof > 0.0 {
        ((flat.sse - knee.sse) / extra.max(1.0)) / (knee.sse / dof)
    } else {
        f64::INFINITY
    };
    // Data on both sides of the knee, in a case that has a knee.
    let below = samples.iter().filter(|s| s.case != Case::PartialDecel && s.s < ls - 1.0).count();
    let above = samples.iter().filter(|s| s.case != Case::PartialDecel && s.s > ls + 1.0).count();
    if f_stat > F_KNEE && below >= 3 && above >= 3 {
        Some((knee, Some(f_stat)))
    } else {
        Some((flat, Some(f_stat)))
    }
}

/// Rate samples, transient rows and notes.
type Collected = (Vec<Sample>, Vec<TransientRow>, Vec<String>);

/// Rate samples and transient rows of all runs.
fn collect(runs: &[&Measurement], opts: &RatesOptions<'_>) -> Result<Collected, FileError> {
    let p = &opts.params;
    let typical = f64::from(p.typical_max_speed_rpm);
    if typical.is_nan() || typical <= 0.0 {
        return Err(FileError::whole("parameters.toml", "typical_max_speed_rpm must be > 0"));
    }
    let (full, low) = (f64::from(p.full_throttle_pct), f64::from(p.low_throttle_pct));
    let mut samples = Vec::new();
    let mut rows = Vec::new();
    let mut notes = Vec::new();
    for (ri, m) in runs.iter().enumerate() {
        let name = m.source.display().to_string();
        let dt = sample_dt(m)?;
        let speed = require(m, &["SuTMotorEnc"], "the inverter rates (SuT motor speed)")?;
        let (u, tol) = throttle_pct(m, p, speed)?;
        let iv = steady_intervals(&u, tol, (MIN_INTERVAL_S / dt).round() as usize);
        let (trs, tnotes) = find_transients(&m.time_s, &iv, speed, dt);
        notes.extend(tnotes.into_iter().map(|n| format!("{name}: {n}")));
        if trs.is_empty() {
            notes.push(format!("{name}: no throttle step followed by a speed ramp; the run adds nothing"));
        }
        let win = ((WINDOW_S / dt).round() as usize).max(3);
        for tr in trs {
            let t_at = m.time_s.get(tr.step).copied().unwrap_or(0.0);
            let sign_ok = tr.after == 0.0 || (tr.after < 0.0) == (tr.dir == 1);
            if !sign_ok {
                notes.push(format!(
                    "{name}: t = {t_at:.2} s: throttle direction differs from the speed's; skipped"
                ));
                continue;
            }
            let mapped = mapped_pct(p, &opts.maps, tr.after);
            let (case, f) = if tr.accel {
                (Case::Accel, ((mapped - low) / (full - low)).clamp(0.0, 1.0))
            } else if mapped <= 0.0 {
                (Case::NeutralDecel, 0.0)
            } else {
                (Case::PartialDecel, 0.0)
            };
            let id = rows.len();
            let (a, b) = tr.ramp;
            let mut k = a;
            let mut got = 0;
            while k + win <= b || (got == 0 && k < b) {
                let e = (k + win).min(b);
                if let Some(l) = line_fit(&m.time_s[k..e], &speed[k..e]) {
                    let s_mean = speed[k..e].iter().sum::<f64>() / (e - k) as f64;
                    samples.push(Sample {
                        s: s_mean.abs() / typical * 100.0,
                        r: l.slope.abs(),
                        case,
                        f,
                        tr: id,
                    });
                    got += 1;
                }
                k = e;
            }
            let whole = line_fit(&m.time_s[a..b], &speed[a..b]).map_or(f64::NAN, |l| l.slope.abs());
            rows.push(TransientRow {
                run: ri,
                t: t_at,
                before: tr.before,
                after: tr.after,
                s0: tr.s0,
                s1: tr.s1,
                dir: tr.dir,
                case,
                f,
                mean_rate: whole,
            });
        }
    }
    Ok((samples, rows, notes))
}

const DIRS: [&str; 2] = ["fwd", "rev"];

/// Identify the rates from `runs` (throttle steps with the loads at zero, like TP11–TP14).
pub fn identify_rates(runs: &[&Measurement], opts: &RatesOptions<'_>) -> Result<Outcome, FileError> {
    let p = &opts.params;
    let typical = f64::from(p.typical_max_speed_rpm);
    let (samples, rows, notes) = collect(runs, opts)?;
    let mut out = Outcome { what: "inverter-rates".into(), notes, ..Outcome::default() };
    let secs = |r: f64| typical / r;
    for (d, dn) in DIRS.into_iter().enumerate() {
        let base = p.rates.dir[d];
        let hs = f64::from(base.hs_pct);
        let mine: Vec<Sample> =
            samples.iter().copied().filter(|s| rows.get(s.tr).is_some_and(|r| r.dir == d)).collect();
        let key = |name: &str, unit: &str| format!("ident.{name}_{dn}_{unit}");
        let max_s = mine.iter().map(|s| s.s).fold(0.0, f64::max);
        let fit = fit_direction(&mine, hs);
        let Some((fit, f_stat)) = fit else {
            for (name, unit, b) in [
                ("accel_hs", "s", base.accel_hs_s),
                ("accel_ls", "s", base.accel_ls_s),
                ("low_accel", "s", base.low_accel_s),
                ("neutral_decel_hs", "s", base.neutral_decel_hs_s),
                ("neutral_decel_ls", "s", base.neutral_decel_ls_s),
                ("partial_decel", "s", base.partial_decel_s),
                ("ls", "pct", base.ls_pct),
                ("hs", "pct", base.hs_pct),
            ] {
                let u = if unit == "s" { "s" } else { "%" };
                out.estimates.push(
                    Estimate::undetermined(&key(name, unit), u, format!("no usable {dn} transients"))
                        .with_base(f64::from(b)),
                );
            }
            continue;
        };
        // Bootstrap over transients, stratified by case.
        let boot = bootstrap(&mine, &fit, hs, opts.bootstrap, 0x5eed + d as u64);
        let ls_sd = spread68(&boot.iter().filter_map(|t| t.1).collect::<Vec<_>>());
        let n_tr =
            |pred: &dyn Fn(&TransientRow) -> bool| rows.iter().filter(|r| r.dir == d && pred(r)).count();
        let n_full = n_tr(&|r| r.case == Case::Accel && r.f >= 1.0);
        let n_part = n_tr(&|r| r.case == Case::Accel && r.f > 0.0 && r.f < 1.0);
        let n_low = n_tr(&|r| r.case == Case::Accel && r.f <= 0.0);
        let n_neu = n_tr(&|r| r.case == Case::NeutralDecel);
        let n_pd = n_tr(&|r| r.case == Case::PartialDecel);
        let knee_ls = fit.ls;
        // A rate [rpm/s] from the parameters: at LS (`j_g = None`) or, with a knee, the
        // blend extrapolated to HS.
        let rate_of = |th: &[f64; NP], ls: Option<f64>, j_r: usize, j_g: Option<usize>| match (ls, j_g) {
            (Some(l), Some(g)) => th[j_r] + th[g] * (hs - l),
            _ => th[j_r],
        };
        // In seconds, with the larger of the propagated least-squares error and the
        // bootstrap's central 68 % half-range.
        let rate_est = |k: &str, j_r: usize, j_g: Option<usize>, ok: bool, b: f32, how: String, why: &str| {
            let r = rate_of(&fit.theta, knee_ls, j_r, j_g);
            let ols = match (knee_ls, j_g) {
                (Some(l), Some(g)) => (fit.se[j_r].powi(2) + ((hs - l) * fit.se[g]).powi(2)).sqrt(),
                _ => fit.se[j_r],
            };
            let boot_s: Vec<f64> = boot
                .iter()
                .map(|t| rate_of(&t.0, t.1.or(knee_ls), j_r, j_g))
                .filter(|r| *r > 0.0)
                .map(secs)
                .collect();
            let sd = (typical * ols / (r * r)).max(spread68(&boot_s));
            if ok && r > 0.0 && sd.is_finite() {
                Estimate::value(k, secs(r), sd, "s", how).with_base(f64::from(b))
            } else {
                Estimate::undetermined(k, "s", why).with_base(f64::from(b))
            }
        };
        let reached =
            if max_s >= hs { "reached".to_owned() } else { format!("not reached: max {:.1} %", max_s) };
        let hs_note = |what: &str| {
            match knee_ls {
            Some(ls) => format!(
                "{what} blend above LS {ls:.1} % extrapolated to HS {hs:.0} % (base value, {reached}); {} points",
                mine.len()
            ),
            None => format!("no change of slope up to {max_s:.1} % of Typical Max Speed: HS = LS rate"),
        }
        };
        let no_hs_data = knee_ls.is_none() && max_s < f64::from(base.ls_pct) + 5.0;
        let hs_undetermined = format!(
            "speed never above {max_s:.1} % of Typical Max Speed, below LS+5 % ({:.0} %): the HS rate never applies",
            base.ls_pct + 5.0
        );
        // Accel.
        out.estimates.push(rate_est(
            &key("accel_hs", "s"),
            1,
            Some(2),
            fit.support[1] && !no_hs_data && (knee_ls.is_none() || fit.support[2]),
            base.accel_hs_s,
            hs_note("accel"),
            if no_hs_data { &hs_undetermined } else { "no full/partial acceleration above LS" },
        ));
        out.estimates.push(rate_est(
            &key("accel_ls", "s"),
            1,
            None,
            fit.support[1],
            base.accel_ls_s,
            format!("{n_full} full + {n_part} partial acceleration transients"),
            "no usable full or partial acceleration transients (see Left out)",
        ));
        out.estimates.push(rate_est(
            &key("low_accel", "s"),
            0,
            None,
            fit.support[0],
            base.low_accel_s,
            format!("{n_low} low + {n_part} partial acceleration transients (blend weights from the mapped throttle)"),
            "no usable low or partial acceleration transients (see Left out)",
        ));
        out.estimates.push(rate_est(
            &key("neutral_decel_hs", "s"),
            3,
            Some(4),
            fit.support[3] && !no_hs_data && (knee_ls.is_none() || fit.support[4]),
            base.neutral_decel_hs_s,
            hs_note("neutral decel"),
            if no_hs_data { &hs_undetermined } else { "no neutral deceleration above LS" },
        ));
        out.estimates.push(rate_est(
            &key("neutral_decel_ls", "s"),
            3,
            None,
            fit.support[3],
            base.neutral_decel_ls_s,
            format!("{n_neu} neutral deceleration transients"),
            "no usable neutral deceleration transients (see Left out)",
        ));
        out.estimates.push(rate_est(
            &key("partial_decel", "s"),
            5,
            None,
            fit.support[5],
            base.partial_decel_s,
            format!("{n_pd} partial deceleration transients"),
            "no usable partial deceleration transients (see Left out)",
        ));
        let f_txt = f_stat.map_or("-".to_owned(), |f| format!("{f:.1}"));
        out.estimates.push(match knee_ls {
            Some(ls) => Estimate::value(
                &key("ls", "pct"),
                ls,
                ls_sd.max(0.5),
                "%",
                format!("change of slope (F = {f_txt} > {F_KNEE}) at {:.0} rpm", ls * typical / 100.0),
            ),
            None => Estimate::undetermined(
                &key("ls", "pct"),
                "%",
                format!("no significant change of slope within the speeds seen (up to {max_s:.1} %; F = {f_txt})"),
            ),
        }
        .with_base(f64::from(base.ls_pct)));
        out.estimates.push(
            Estimate::undetermined(
                &key("hs", "pct"),
                "%",
                if max_s < hs {
                    format!("not reached: speed up to {max_s:.1} % < HS {hs:.0} % (thesis: 'not reached')")
                } else {
                    format!("speeds above HS {hs:.0} % seen, but a second change of slope is not fitted")
                },
            )
            .with_base(f64::from(base.hs_pct)),
        );
        // Report: fit statistics, partial-acceleration check, plot.
        let resid_sd =
            (fit.sse / (fit.n as f64 - fit.support.iter().filter(|s| **s).count() as f64).max(1.0)).sqrt();
        out.lines.push(format!(
            "\n## {dn}: {} rate samples from {} transients; residual s.d. {} rpm/s; {} bootstrap replicates",
            mine.len(),
            rows.iter().filter(|r| r.dir == d).count(),
            sig(resid_sd),
            boot.len()
        ));
        out.plots.push(rate_plot(dn, &mine, &fit, hs, typical));
    }
    // Transient table.
    out.lines.push("\n## Transients\n".into());
    out.lines.push("| run | t [s] | throttle [%] | case | speed [rpm] | mean rate [rpm/s] | = [s] |".into());
    out.lines.push("|---|---|---|---|---|---|---|".into());
    for r in &rows {
        let mut l = String::new();
        let _ = write!(
            l,
            "| {} | {:.2} | {} → {} | {} {} | {:.0} → {:.0} | {} | {} |",
            runs.get(r.run).map_or(String::new(), |m| m.source.display().to_string()),
            r.t,
            sig(r.before),
            sig(r.after),
            DIRS[r.dir],
            r.case.name(r.f),
            r.s0,
            r.s1,
            sig(r.mean_rate),
            sig(typical / r.mean_rate)
        );
        out.lines.push(l);
    }
    Ok(out)
}

/// Bootstrap replicates `(theta, ls)`: transients resampled within each case.
fn bootstrap(
    samples: &[Sample],
    fit: &Fit,
    hs: f64,
    reps: usize,
    seed: u64,
) -> Vec<([f64; NP], Option<f64>)> {
    let mut groups: Vec<(Case, bool, Vec<usize>)> = Vec::new();
    let mut ids: Vec<usize> = samples.iter().map(|s| s.tr).collect();
    ids.sort_unstable();
    ids.dedup();
    for id in ids {
        let Some(s) = samples.iter().find(|s| s.tr == id) else { continue };
        let key = (s.case, s.f >= 1.0);
        match groups.iter_mut().find(|g| (g.0, g.1) == key) {
            Some(g) => g.2.push(id),
            None => groups.push((key.0, key.1, vec![id])),
        }
    }
    let mut rng = Rng::new(seed, 0);
    let mut out = Vec::with_capacity(reps);
    for _ in 0..reps {
        let mut pick: Vec<Sample> = Vec::with_capacity(samples.len());
        for g in &groups {
            for _ in 0..g.2.len() {
                let id = g.2[rng.index(g.2.len())];
                pick.extend(samples.iter().filter(|s| s.tr == id));
            }
        }
        let f = match fit.ls {
            Some(_) => knee_fit(&pick, hs),
            None => solve(&pick, None, hs),
        };
        if let Some(f) = f {
            out.push((f.theta, f.ls));
        }
    }
    out
}

fn rate_plot(dn: &str, samples: &[Sample], fit: &Fit, hs: f64, typical: f64) -> Plot {
    let sel = |pred: &dyn Fn(&Sample) -> bool| -> (Vec<f64>, Vec<f64>) {
        samples.iter().filter(|s| pred(s)).map(|s| (s.s * typical / 100.0, s.r)).unzip()
    };
    let full = sel(&|s| s.case == Case::Accel && s.f >= 1.0);
    let part = sel(&|s| s.case == Case::Accel && s.f < 1.0);
    let neu = sel(&|s| s.case == Case::NeutralDecel);
    let pd = sel(&|s| s.case == Case::PartialDecel);
    let smax = samples.iter().map(|s| s.s).fold(1.0, f64::max);
    let curve = |case: Case| -> Vec<(f64, f64)> {
        (0..=60)
            .map(|k| {
                let s = smax * f64::from(k) / 60.0;
                let r = dot(&row(&Sample { s, r: 0.0, case, f: 1.0, tr: 0 }, fit.ls, hs), &fit.theta);
                (s * typical / 100.0, r)
            })
            .collect()
    };
    let (ca, cn) = (curve(Case::Accel), curve(Case::NeutralDecel));
    let (cax, cay): (Vec<f64>, Vec<f64>) = ca.into_iter().unzip();
    let (cnx, cny): (Vec<f64>, Vec<f64>) = cn.into_iter().unzip();
    let pts = |v: &'_ (Vec<f64>, Vec<f64>),
               color: &'static str,
               label: &'static str|
     -> (Vec<f64>, Vec<f64>, &'static str, &'static str) {
        (v.0.clone(), v.1.clone(), color, label)
    };
    let groups = [
        pts(&full, "#c0392b", "full accel"),
        pts(&part, "#e67e22", "partial/low accel"),
        pts(&neu, "#2471a3", "neutral decel"),
        pts(&pd, "#27ae60", "partial decel"),
    ];
    let points: Vec<XyPoints<'_>> =
        groups.iter().map(|g| XyPoints { x: &g.0, y: &g.1, err: None, color: g.2, label: g.3 }).collect();
    let svg = xy_chart(
        &format!("Curtis ramp rates, {dn}: |d speed/dt| against |speed|"),
        "SuT motor speed [rpm]",
        "ramp rate [rpm/s]",
        &points,
        &[
            XyLine { x: &cax, y: &cay, color: "#7b241c", label: "fit: accel (full throttle)", dashed: false },
            XyLine { x: &cnx, y: &cny, color: "#1b4f72", label: "fit: neutral decel", dashed: false },
        ],
    );
    Plot { name: format!("rates_{dn}"), svg }
}
