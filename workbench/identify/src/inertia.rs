//! `simrod identify inertia`: the load inertias L, R and the SuT inertia (axle frame,
//! the model's `load_inertia_l/r` and `sut_inertia`) from acceleration and deceleration
//! transients (thesis 5.3.2, eq. 5.2/5.3: inertial torque = total − friction − load).
//!
//! **Load inertias, from the flange torque.** The Kistler flange measures the torque
//! between the SuT half inertia and the flange; everything downstream of it is the
//! flange, the coupling and the load: `C_Kistler = (J_load + J_flange) dω/dt +
//! friction(ω) + T_load`. With the load set points at zero, `T_load` is the base model's
//! load-torque map at zero load (a small regenerating drag at full throttle, faded out
//! near standstill as the model does), and `friction` is the friction map (the base
//! model's, or an identified one through `--data-dir`). Over each ramp the speed is
//! fitted by a line (dω/dt, and a smooth speed at which to evaluate the friction), and
//! `J = mean(C − friction − T_load) / (dω/dt) − J_flange` (datasheet flange inertia).
//!
//! **SuT inertia, from the electrical power.** The SuT side's inertia shows only in the
//! motor torque, which the bench does not measure — but in the SuT inverter's power:
//! the model draws the power map's steady value plus the *unmapped* mechanical power
//! (what the motor delivers beyond the mapped friction and loads: accelerating inertias)
//! through the drive efficiency η (`model-core/src/model.rs`). So over a transient from
//! one steady speed to another, `∫ conv(V_DC I_DC − P_map) dt = ΔE_kin` with
//! `conv(p) = η p` (drawing) or `p / η` (returning), `P_map` the SuT power map at the set
//! points through its rate limiter, and `E_kin = Σ_sides ½ (J_SuT/2 + J_flange + J_load)
//! ω²`. With the load inertias known this gives `J_SuT`. It rests on η (an assumed
//! parameter) and on the power map: accelerations and decelerations weigh η oppositely
//! (η vs 1/η), so the report shows both groups' means as a check.
//!
//! **Weak excitation.** The thesis found the inertial torque often drowned in friction
//! ("the total torque coincides exactly with just the friction contribution"). Here a
//! transient counts only if its torque excess over friction exceeds 3 times its
//! uncertainty: noise (block means) plus the friction map's mismatch, measured on the
//! steady plateaus of the same runs (RMS of `C − friction − T_load` there). A quantity
//! without such a transient, or known only to worse than 30 %, is reported
//! **undetermined**, with the numbers, instead of a value. Estimates are combined by an inverse-variance mean after rejecting outliers
//! (robust z > 4); the uncertainty is the propagated one (noise and the fitted dω/dt per
//! transient; the friction mismatch and, for the SuT, the load inertias counted as
//! common to all transients), scaled up by the Birge ratio when the estimates scatter
//! more than that allows.

use std::cmp::Ordering::{Equal, Less};

use model_core::drivetrain::RAD_S_PER_RPM;
use model_core::{Maps, Params};

use super::estimate::{sig, Estimate, Outcome, Plot};
use super::report::{xy_chart, XyPoints};
use super::transients::{
    find, find_transients, line_fit, require, sample_dt, steady_intervals, throttle_pct, Transient,
    MIN_INTERVAL_S,
};
use simrod_io::error::FileError;
use simrod_io::measure::{Measurement, SETPOINT_LOAD_L, SETPOINT_LOAD_R};
use simrod_numerics::stats::{mad_sigma, mean, median, moving_mean, std_dev};

/// Significance a transient's excess must reach (in its standard uncertainties).
pub const MIN_SIGNIFICANCE: f64 = 3.0;
/// Largest relative uncertainty of a value still reported as determined.
pub const MAX_REL_SD: f64 = 0.3;
/// Load set points within this of zero count as "loads off" [%].
const LOAD_OFF_PCT: f64 = 0.5;
/// Block length for the noise of a mean [s] (longer than the 24 Hz coupling period).
const BLOCK_S: f64 = 0.05;
/// Half-width of the smoothing that decides the sign of the inverter power [s].
const SMOOTH_S: f64 = 0.1;

/// What the inertia identification needs from the base model.
#[derive(Debug, Clone, Copy)]
pub struct InertiaOptions<'a> {
    /// Flange inertia, drive efficiency, power rate limit, gear ratio, regen fade.
    pub params: Params,
    /// Friction, load-torque and SuT-power maps, and the throttle input map.
    pub maps: Maps<'a>,
}

/// One transient's estimate of one inertia.
#[derive(Debug, Clone, Copy)]
struct PerTransient {
    run: usize,
    t: f64,
    /// [kg m²]
    j: f64,
    /// Noise part of its standard uncertainty [kg m²].
    sd_noise: f64,
    /// Friction-mismatch part, signed by the direction of the excitation [kg m²].
    sd_sys: f64,
    /// Excess and its uncertainty (torque [N m] or energy [J]), for the report.
    excess: f64,
    excess_sd: f64,
    /// dω/dt [rad/s²] (load) or Δ(Σω²) [rad²/s²] (SuT).
    excitation: f64,
    accel: bool,
    used: bool,
}

/// Everything read from one run.
struct RunData<'m> {
    m: &'m Measurement,
    dt: f64,
    torque: [&'m [f64]; 2],
    speed: [&'m [f64]; 2],
    throttle: Vec<f64>,
    loads: [Vec<f64>; 2],
    /// V_DC · I_DC, if both are measured.
    p_el: Option<Vec<f64>>,
    transients: Vec<Transient>,
    plateaus: Vec<(usize, usize)>,
}

fn read_run<'m>(m: &'m Measurement, p: &Params, notes: &mut Vec<String>) -> Result<RunData<'m>, FileError> {
    let name = m.source.display().to_string();
    let dt = sample_dt(m)?;
    let why = "the load inertias (flange torque and speed)";
    let torque = [require(m, &["C_Kistler_L"], why)?, require(m, &["C_Kistler_R"], why)?];
    let speed = [require(m, &["T_Kistler_L"], why)?, require(m, &["T_Kistler_R"], why)?];
    let motor = require(m, &["SuTMotorEnc"], "the transients (SuT motor speed)")?;
    let (throttle, tol) = throttle_pct(m, p, motor)?;
    let n = m.time_s.len();
    let load = |name_sp: &str| -> Result<Vec<f64>, FileError> {
        match find(m, &[name_sp]) {
            Some(_) => Ok(require(m, &[name_sp], "the load set points")?.to_vec()),
            None => Ok(vec![0.0; n]),
        }
    };
    if find(m, &[SETPOINT_LOAD_L]).is_none() || find(m, &[SETPOINT_LOAD_R]).is_none() {
        notes.push(format!("{name}: no load set-point channels (`Dm Left`, `Dm Right`): loads taken as off"));
    }
    let loads = [load(SETPOINT_LOAD_L)?, load(SETPOINT_LOAD_R)?];
    let p_el = match (find(m, &["V_DC"]), find(m, &["I_DC"])) {
        (Some(_), Some(_)) => {
            let v = require(m, &["V_DC"], "the SuT inertia (inverter power)")?;
            let i = require(m, &["I_DC"], "the SuT inertia (inverter power)")?;
            Some(v.iter().zip(i).map(|(v, i)| v * i).collect())
        }
        _ => {
            notes.push(format!("{name}: no `V_DC`/`I_DC`: the SuT inertia cannot use this run"));
            None
        }
    };
    let iv = steady_intervals(&throttle, tol, (MIN_INTERVAL_S / dt).round() as usize);
    let (transients, tnotes) = find_transients(&m.time_s, &iv, motor, dt);
    notes.extend(tnotes.into_iter().map(|x| format!("{name}: {x}")));
    // Plateaus: the last second of each constant-throttle interval, if the speed is steady.
    let sec = ((1.0 / dt).round() as usize).max(3);
    let mut plateaus = Vec::new();
    for i in &iv {
        if i.end - i.start < 2 * sec {
            continue;
        }
        let (a, b) = (i.end - sec, i.end);
        let steady = (0..2).all(|s| {
            line_fit(&m.time_s[a..b], &speed[s][a..b])
                .is_some_and(|l| (l.slope * 1.0).abs() < 2.0 + 0.01 * l.at(l.x_mean).abs())
        });
        if steady {
            plateaus.push((a, b));
        }
    }
    Ok(RunData { m, dt, torque, speed, throttle, loads, p_el, transients, plateaus })
}

/// The base model's load torque at set points and load speed (regenerating fade and
/// motoring back-EMF envelope as in `model-core/src/model.rs`).
fn load_torque(p: &Params, maps: &Maps<'_>, side: usize, thr: f64, load: f64, w_rad_s: f64) -> f64 {
    let t_map = f64::from(maps.load_torque[side].eval(thr as f32, load as f32));
    let fade = f64::from(p.regen_fade_rpm * RAD_S_PER_RPM);
    if t_map >= 0.0 {
        t_map * if fade > 0.0 { (w_rad_s / fade).clamp(-1.0, 1.0) } else { 0.0 }
    } else {
        let dir = if thr < 0.0 { -1.0 } else { 1.0 };
        let along = w_rad_s * dir * f64::from(p.load_gear_ratio) * 30.0 / std::f64::consts::PI;
        let span = f64::from(p.load_no_load_rpm - p.load_base_rpm);
        t_map * dir * ((f64::from(p.load_no_load_rpm) - along) / span).clamp(0.0, 1.0)
    }
}

fn friction(maps: &Maps<'_>, side: usize, rpm: f64) -> f64 {
    f64::from(maps.friction[side].eval(rpm as f32))
}

fn loads_off(r: &RunData<'_>, a: usize, b: usize) -> bool {
    r.loads.iter().all(|l| l[a..b].iter().all(|v| v.abs() <= LOAD_OFF_PCT))
}

/// Standard error of the mean of `e` from block means (blocks of `BLOCK_S`).
fn mean_se(e: &[f64], dt: f64) -> f64 {
    let blk = ((BLOCK_S / dt).round() as usize).max(1);
    let means: Vec<f64> = e.chunks(blk).filter(|c| c.len() * 2 >= blk).map(mean).collect();
    if means.len() >= 3 {
        std_dev(&means) / (means.len() as f64).sqrt()
    } else {
        std_dev(e) / (e.len() as f64 / blk as f64).max(1.0).sqrt()
    }
}

/// Residuals `C − friction − T_load` on the steady plateaus with the loads off, per side.
fn plateau_residuals(runs: &[RunData<'_>], opts: &InertiaOptions<'_>) -> [Vec<f64>; 2] {
    let mut out = [Vec::new(), Vec::new()];
    for r in runs {
        for &(a, b) in &r.plateaus {
            if !loads_off(r, a, b) {
                continue;
            }
            for (s, o) in out.iter_mut().enumerate() {
                let w = mean(&r.speed[s][a..b]);
                if w.abs() < 2.0 {
                    continue; // at standstill friction is whatever holds the shaft
                }
                let thr = r.throttle[b - 1];
                let tl = load_torque(&opts.params, &opts.maps, s, thr, 0.0, w * RAD_S_PER_RPM as f64);
                o.push(mean(&r.torque[s][a..b]) - friction(&opts.maps, s, w) - tl);
            }
        }
    }
    out
}

/// A value known only to worse than `MAX_REL_SD` is reported undetermined (with the
/// numbers in the note): the thesis' "just an idea of the real amount".
fn precise_enough(e: Estimate) -> Estimate {
    match e.value {
        Some(v) if !matches!(e.sigma.partial_cmp(&(MAX_REL_SD * v.abs())), Some(Less | Equal)) => {
            let why = format!(
                "too uncertain: {} ± {} {} ({:.0} % > {:.0} %); {}",
                sig(v),
                sig(e.sigma),
                e.unit,
                100.0 * e.sigma / v.abs(),
                100.0 * MAX_REL_SD,
                e.note
            );
            Estimate::undetermined(&e.key, e.unit, why)
        }
        _ => e,
    }
}

/// Combine per-transient estimates: outlier rejection, inverse-variance mean, honest σ.
/// Returns `(value, sigma, used count, outliers)`.
fn combine(list: &mut [PerTransient]) -> Option<(f64, f64, usize, usize)> {
    let idx: Vec<usize> = (0..list.len()).filter(|&k| list[k].used).collect();
    if idx.is_empty() {
        return None;
    }
    let js: Vec<f64> = idx.iter().map(|&k| list[k].j).collect();
    let m = median(&js).unwrap_or(f64::NAN);
    let s = mad_sigma(&js).unwrap_or(f64::NAN);
    let mut outliers = 0;
    for &k in &idx {
        let e = &list[k];
        let sd = (e.sd_noise.powi(2) + e.sd_sys.powi(2) + s * s).sqrt();
        if idx.len() >= 3 && (e.j - m).abs() > 4.0 * sd {
            list[k].used = false;
            outliers += 1;
        }
    }
    let kept: Vec<&PerTransient> = list.iter().filter(|e| e.used).collect();
    let w: Vec<f64> = kept.iter().map(|e| 1.0 / (e.sd_noise.powi(2) + e.sd_sys.powi(2)).max(1e-30)).collect();
    let sw: f64 = w.iter().sum();
    let value = kept.iter().zip(&w).map(|(e, w)| e.j * w).sum::<f64>() / sw;
    let stat = (kept.iter().zip(&w).map(|(e, w)| (w * e.sd_noise).powi(2)).sum::<f64>()).sqrt() / sw;
    // Consistency (Birge ratio): if the estimates scatter more than their uncertainties
    // allow, those were too small by that factor.
    let chi2 = kept.iter().zip(&w).map(|(e, w)| (e.j - value).powi(2) * w).sum::<f64>();
    let birge = if kept.len() >= 2 { (chi2 / (kept.len() - 1) as f64).sqrt().max(1.0) } else { 1.0 };

    let sys = (kept.iter().zip(&w).map(|(e, w)| w * e.sd_sys).sum::<f64>() / sw).abs();
    Some((value, stat.hypot(sys) * birge, kept.len(), outliers))
}

/// Identify the inertias from `runs` (throttle steps with the loads off: TP11–TP14-like).
pub fn identify_inertia(runs: &[&Measurement], opts: &InertiaOptions<'_>) -> Result<Outcome, FileError> {
    let p = &opts.params;
    let mut notes = Vec::new();
    let data: Vec<RunData<'_>> = runs.iter().map(|m| read_run(m, p, &mut notes)).collect::<Result<_, _>>()?;
    let resid = plateau_residuals(&data, opts);
    let j_f = f64::from(p.flange_inertia);
    let mut out = Outcome { what: "inertia".into(), ..Outcome::default() };
    let mut sigma_f = [0.0f64; 2];
    for s in 0..2 {
        sigma_f[s] = if resid[s].len() >= 2 {
            (resid[s].iter().map(|r| r * r).sum::<f64>() / resid[s].len() as f64).sqrt()
        } else {
            f64::NAN // decided per transient below
        };
    }

    // Load inertias, per transient and side.
    let mut per: [Vec<PerTransient>; 2] = [Vec::new(), Vec::new()];
    for (ri, r) in data.iter().enumerate() {
        let name = r.m.source.display().to_string();
        if r.transients.is_empty() {
            notes.push(format!("{name}: no throttle step followed by a speed ramp; the run adds nothing"));
        }
        for tr in &r.transients {
            let (a, b) = tr.ramp;
            let t_at = r.m.time_s[tr.step];
            if !loads_off(r, tr.step, tr.end) {
                notes.push(format!("{name}: t = {t_at:.2} s: loads not off; not used for the inertias"));
                continue;
            }
            for s in 0..2 {
                let t = &r.m.time_s[a..b];
                let w_rad: Vec<f64> = r.speed[s][a..b].iter().map(|v| v * RAD_S_PER_RPM as f64).collect();
                let Some(line) = line_fit(t, &w_rad) else { continue };
                let wdot = line.slope;
                let excess: Vec<f64> = (a..b)
                    .map(|k| {
                        let w = line.at(r.m.time_s[k]);
                        let rpm = w / RAD_S_PER_RPM as f64;
                        r.torque[s][k]
                            - friction(&opts.maps, s, rpm)
                            - load_torque(p, &opts.maps, s, r.throttle[k], r.loads[s][k], w)
                    })
                    .collect();
                let e = mean(&excess);
                let se = mean_se(&excess, r.dt);
                let sf = if sigma_f[s].is_finite() {
                    sigma_f[s]
                } else {
                    // No plateaus to judge the friction map by: 10 % of the friction.
                    0.1 * friction(&opts.maps, s, line.at(line.x_mean) / RAD_S_PER_RPM as f64).abs()
                };
                let sd = (se * se + sf * sf).sqrt();
                let significant = e.abs() >= MIN_SIGNIFICANCE * sd && e * wdot > 0.0 && wdot != 0.0;
                // The fitted dω/dt is uncertain too (its least-squares error; how well
                // that describes counted speeds, the consistency check in `combine` says).
                let wdot_rel = line.se_slope / wdot.abs();
                let j = e / wdot;
                per[s].push(PerTransient {
                    run: ri,
                    t: t_at,
                    j: j - j_f,
                    sd_noise: (se / wdot.abs()).hypot(j * wdot_rel),
                    sd_sys: sf / wdot,
                    excess: e,
                    excess_sd: sd,
                    excitation: wdot,
                    accel: tr.accel,
                    used: significant,
                });
            }
        }
    }
    let keys = ["load_inertia_l", "load_inertia_r"];
    let bases = [f64::from(p.load_inertia[0]), f64::from(p.load_inertia[1])];
    let mut j_load: [(f64, f64, bool); 2] = [(bases[0], 0.0, false), (bases[1], 0.0, false)];
    for s in 0..2 {
        let list = &mut per[s];
        let n_all = list.len();
        let n_sig = list.iter().filter(|e| e.used).count();
        let est = match combine(list) {
            Some((v, sd, n, outl)) => {
                j_load[s] = (v, sd, true);
                Estimate::value(
                    keys[s],
                    v,
                    sd,
                    "kg m^2",
                    format!(
                        "{n} of {n_all} transients ({outl} outliers rejected, {} below {MIN_SIGNIFICANCE}σ); friction-map mismatch on plateaus {} N m RMS",
                        n_all - n_sig,
                        sig(sigma_f[s])
                    ),
                )
            }
            None => {
                let biggest =
                    list.iter().map(|e| e.excess.abs() / e.excess_sd.max(1e-12)).fold(0.0, f64::max);
                Estimate::undetermined(
                    keys[s],
                    "kg m^2",
                    if n_all == 0 {
                        "no acceleration/deceleration transients with the loads off".to_owned()
                    } else {
                        format!(
                            "weak excitation: in all {n_all} transients the torque excess over friction is below {MIN_SIGNIFICANCE}× its uncertainty (best {biggest:.1}×; friction-map mismatch {} N m RMS)",
                            sig(sigma_f[s])
                        )
                    },
                )
            }
        };
        out.estimates.push(precise_enough(est).with_base(bases[s]));
    }

    // SuT inertia from the inverter power: a first pass with the base value for the
    // (small) SuT share of the plateaus' kinetic-energy drift, then with the estimate.
    let eta = f64::from(p.sut_drive_efficiency);
    let base_sut = f64::from(p.sut_inertia);
    let (mut sut, mut shares) = sut_transients(&data, opts, &j_load, base_sut);
    if let Some((v, ..)) = combine(&mut sut.clone()) {
        (sut, shares) = sut_transients(&data, opts, &j_load, v);
    }
    let n_all = sut.len();
    let n_sig = sut.iter().filter(|e| e.used).count();
    let load_note = if j_load.iter().all(|j| j.2) {
        "load inertias as identified here".to_owned()
    } else {
        "load inertias partly from the base model (not identified here)".to_owned()
    };
    let group = |acc: bool| {
        let g: Vec<f64> = sut.iter().filter(|e| e.used && e.accel == acc).map(|e| e.j).collect();
        if g.is_empty() {
            "-".to_owned()
        } else {
            format!("{} (n = {})", sig(mean(&g)), g.len())
        }
    };
    let (acc_mean, dec_mean) = (group(true), group(false));
    let est = match combine(&mut sut) {
        Some((v, sd, n, outl)) => Estimate::value(
            "sut_inertia",
            v,
            {
                // J_SuT = 4 (W − ½ Σ J_load Δω²) / ΣΔω²: a load inertia's error moves every
                // transient alike, so it adds after the combination, not within it.
                let used: Vec<&[f64; 2]> = sut.iter().zip(&shares).filter(|(e, _)| e.used).map(|(_, s)| s).collect();
                let w = |i: usize| used.iter().map(|s| s[i]).sum::<f64>() / used.len().max(1) as f64;
                let common = (2.0 * w(0) * j_load[0].1).hypot(2.0 * w(1) * j_load[1].1);
                sd.hypot(common)
            },
            "kg m^2",
            format!(
                "{n} of {n_all} transients ({outl} outliers, {} below {MIN_SIGNIFICANCE}σ) from the inverter power, given η = {} and the power map; {load_note}; accelerations {acc_mean}, decelerations {dec_mean}",
                n_all - n_sig,
                sig(eta)
            ),
        ),
        None => Estimate::undetermined(
            "sut_inertia",
            "kg m^2",
            if n_all == 0 {
                "no transient between two steady speeds with the loads off and V_DC, I_DC measured".to_owned()
            } else {
                format!("weak excitation: in all {n_all} transients the unmapped energy is below {MIN_SIGNIFICANCE}× its uncertainty")
            },
        ),
    };
    out.estimates.push(precise_enough(est).with_base(base_sut));

    // Report.
    out.lines.push("\n## Per transient\n".into());
    out.lines.push("| quantity | run | t [s] | excitation | excess ± sd | estimate [kg m²] | used |".into());
    out.lines.push("|---|---|---|---|---|---|---|".into());
    let rows = [
        ("load L", &per[0], "rad/s²", "N m"),
        ("load R", &per[1], "rad/s²", "N m"),
        ("SuT", &sut, "Δω² rad²/s²", "J"),
    ];
    for (q, list, xu, eu) in rows {
        for e in list.iter() {
            out.lines.push(format!(
                "| {q} | {} | {:.2} | {} {xu} | {} ± {} {eu} | {} ± {} | {} |",
                runs.get(e.run).map_or(String::new(), |m| m.source.display().to_string()),
                e.t,
                sig(e.excitation),
                sig(e.excess),
                sig(e.excess_sd),
                sig(e.j),
                sig(e.sd_noise.hypot(e.sd_sys)),
                if e.used { "yes" } else { "no" }
            ));
        }
    }
    out.plots.extend(plot(&per, &sut));
    out.notes = notes;
    Ok(out)
}

/// Per transient between two steady speeds (loads off): the SuT inertia from the
/// unmapped inverter energy, and each side's share of Δ(Σω²). `j_sut` is only used for
/// the kinetic-energy drift on the plateaus (see `mismatch`).
fn sut_transients(
    data: &[RunData<'_>],
    opts: &InertiaOptions<'_>,
    j_load: &[(f64, f64, bool); 2],
    j_sut: f64,
) -> (Vec<PerTransient>, Vec<[f64; 2]>) {
    let eta = f64::from(opts.params.sut_drive_efficiency);
    let j_f = f64::from(opts.params.flange_inertia);
    let mut sut = Vec::new();
    let mut shares = Vec::new();
    for (ri, r) in data.iter().enumerate() {
        let Some(p_el) = &r.p_el else { continue };
        let p_map = mapped_power(r, opts);
        let resid: Vec<f64> = p_el.iter().zip(&p_map).map(|(a, b)| a - b).collect();
        // η applies by the sign of the power. The sign comes from the smoothed power, the
        // factor multiplies the raw one: choosing it by each noisy sample's own sign
        // would bias the integral where the power is near zero.
        let sign = moving_mean(&resid, ((SMOOTH_S / r.dt).round() as usize).max(1));
        let mech: Vec<f64> =
            resid.iter().zip(&sign).map(|(x, s)| x * if *s > 0.0 { eta } else { 1.0 / eta }).collect();
        let sec = |x: f64| ((x / r.dt).round() as usize).max(1);
        let rad = RAD_S_PER_RPM as f64;
        // Kinetic energy from the mean speeds over samples `a..b`.
        let energy = |a: usize, b: usize| -> f64 {
            (0..2)
                .map(|s| {
                    let w = mean(&r.speed[s][a..b]) * rad;
                    0.5 * (0.5 * j_sut + j_f + j_load[s].0) * w * w
                })
                .sum()
        };
        // The power map's mismatch on a steady stretch `a..b` [W, mechanical]: what the
        // unmapped power does not spend on the kinetic energy (the open differential's
        // L/R split still settles slowly after a transient, moving energy).
        let w = sec(0.2);
        let mismatch = |a: usize, b: usize| -> Option<(f64, f64)> {
            if b < a + 3 * w {
                return None;
            }
            let (c0, c1) = (a + w / 2, b - w / 2);
            let span = (c1 - c0) as f64 * r.dt;
            let work: f64 = mech[c0..c1].iter().sum::<f64>() * r.dt;
            let m = (work - (energy(b - w, b) - energy(a, a + w))) / span;
            let sd = std_dev(&mech[a..b]) / ((b - a) as f64).sqrt();
            Some((m, sd))
        };
        for tr in &r.transients {
            if !(tr.settled_before && tr.settled_after && loads_off(r, tr.step, tr.end)) {
                continue;
            }
            let pre = tr.step.saturating_sub(sec(0.6));
            let w_end = tr.end.saturating_sub(sec(0.5));
            let start = tr.step.saturating_sub(sec(0.2));
            // Up to the end of the interval: the L/R split settles for seconds.
            let stop = tr.end;
            let base_from = (tr.ramp.1 + sec(1.0)).max(tr.end.saturating_sub(sec(3.0))).min(w_end);
            let (Some((b0, sd0)), Some((b1, sd1))) = (mismatch(pre, tr.step), mismatch(base_from, tr.end))
            else {
                continue;
            };
            let work: f64 =
                (start..stop).map(|k| mech[k] - if k < tr.step { b0 } else { b1 }).sum::<f64>() * r.dt;
            let dur = (stop - start) as f64 * r.dt;
            let mut dsq = 0.0;
            let mut k_load = 0.0;
            let mut share = [0.0f64; 2];
            for (s, sh) in share.iter_mut().enumerate() {
                let w0 = mean(&r.speed[s][tr.step.saturating_sub(sec(0.3))..tr.step]) * rad;
                let w1 = mean(&r.speed[s][w_end..tr.end]) * rad;
                let d = w1 * w1 - w0 * w0;
                dsq += d;
                k_load += 0.5 * (j_load[s].0 + j_f) * d;
                *sh = d;
            }
            if !(dsq.is_finite() && dsq != 0.0) {
                continue;
            }
            let w_sut = work - k_load;
            let noise = std_dev(&mech[base_from..tr.end]);
            let sd_noise = noise * r.dt * ((stop - start) as f64).sqrt();
            let sd_base = (0.5 * (b1 - b0).abs() + sd1.hypot(sd0)) * dur;
            let sd = sd_noise.hypot(sd_base);
            let used = w_sut.abs() >= MIN_SIGNIFICANCE * sd && w_sut * dsq > 0.0;
            shares.push([share[0] / dsq, share[1] / dsq]);
            sut.push(PerTransient {
                run: ri,
                t: r.m.time_s[tr.step],
                j: 4.0 * w_sut / dsq,
                sd_noise: 4.0 * sd_noise / dsq.abs(),
                // Counted as common to all transients, whatever their direction.
                sd_sys: 4.0 * sd_base / dsq.abs(),
                excess: w_sut,
                excess_sd: sd,
                excitation: dsq,
                accel: tr.accel,
                used,
            });
        }
    }
    (sut, shares)
}

/// The SuT power map at the run's set points, through the model's rate limiter.
fn mapped_power(r: &RunData<'_>, opts: &InertiaOptions<'_>) -> Vec<f64> {
    let step = f64::from(opts.params.sut_power_rate_w_per_s) * r.dt;
    let mut y = f64::NAN;
    (0..r.throttle.len())
        .map(|k| {
            let lm = 0.5 * (r.loads[0][k] + r.loads[1][k]);
            let target = f64::from(opts.maps.sut_power.eval(r.throttle[k] as f32, lm as f32));
            y = if y.is_finite() { y + (target - y).clamp(-step, step) } else { target };
            y
        })
        .collect()
}

fn plot(per: &[Vec<PerTransient>; 2], sut: &[PerTransient]) -> [Plot; 2] {
    // Weak transients can give wild values; those beyond 5× the largest used one stay off
    // the chart (they are in the table).
    let pick = |l: &[PerTransient], used: bool| -> (Vec<f64>, Vec<f64>) {
        let lim = 5.0 * l.iter().filter(|e| e.used).map(|e| e.j.abs()).fold(0.1, f64::max);
        l.iter().filter(|e| e.used == used && e.j.abs() <= lim).map(|e| (e.excitation.abs(), e.j)).unzip()
    };
    let (l1, l0) = (pick(&per[0], true), pick(&per[0], false));
    let (r1, r0) = (pick(&per[1], true), pick(&per[1], false));
    let load = xy_chart(
        "Load inertias per transient (grey: below the significance threshold)",
        "|dω/dt| [rad/s²]",
        "J [kg m²]",
        &[
            XyPoints { x: &l1.0, y: &l1.1, err: None, color: "#c0392b", label: "load L" },
            XyPoints { x: &r1.0, y: &r1.1, err: None, color: "#2471a3", label: "load R" },
            XyPoints { x: &l0.0, y: &l0.1, err: None, color: "#bbbbbb", label: "L, weak" },
            XyPoints { x: &r0.0, y: &r0.1, err: None, color: "#888888", label: "R, weak" },
        ],
        &[],
    );
    let (s1, s0) = (pick(sut, true), pick(sut, false));
    let sut = xy_chart(
        "SuT inertia per transient, from the inverter power (grey: below the significance threshold)",
        "|Δ(ω_L² + ω_R²)| [rad²/s²]",
        "J_SuT [kg m²]",
        &[
            XyPoints { x: &s1.0, y: &s1.1, err: None, color: "#27ae60", label: "SuT" },
            XyPoints { x: &s0.0, y: &s0.1, err: None, color: "#bbbbbb", label: "weak" },
        ],
        &[],
    );
    [Plot { name: "inertia_load".into(), svg: load }, Plot { name: "inertia_sut".into(), svg: sut }]
}
