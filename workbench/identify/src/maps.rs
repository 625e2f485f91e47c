//! `identify speed-map`, `load-maps`, `power-maps`: the model's 1-D and 2-D maps from
//! steady plateaus (thesis 5.2.1, 5.2.2, 5.5).
//!
//! The thesis matched plateau means into tables by hand. Here the maps keep the base
//! model's grids (so they drop into `model-core/data`) and the grid values are fitted by
//! weighted least squares on the model's own interpolation basis (linear in 1-D,
//! bilinear in 2-D, edges clamped as the model clamps): a plateau between grid points
//! informs its neighbours in proportion to their interpolation weights, and many
//! plateaus near a node average. A node is *observed* when the data determine it to
//! better than 2 % of the map's range; every other node keeps the base value and is
//! marked in the report (never silently extrapolated). Uncertainties are one standard
//! deviation, scaled up by χ²/dof when the plateaus scatter more than their noise.
//!
//! Frames (docs/MODEL.md): the speed map is *mapped* throttle (after the Curtis input
//! map, from the base data) → motor speed magnitude; plateaus at the speed limit only
//! say the map is at or above the limit and are left out (censored). The load torque
//! map is the flange torque minus the friction (base data: identify friction first) at
//! the plateau's speed, referred to the map's sign convention through the model's own
//! regen fade and back-EMF envelope; a regenerating load at standstill shows nothing.

use model_core::table::locate;
use model_core::{throttle, Params};

use super::plateau::Extraction;
use super::report::{campaign_section, num, pm, sp_str, xy_chart, Report, XyLine, XyPoints, PALETTE};
use super::{Context, Identification, MapFit};
use simrod_io::datadir::{Map1, Map2, ModelData};
use simrod_io::error::CmdError;
use simrod_numerics::linalg::{self, Row};

/// Nodes determined to better than this share of the map's range count as observed.
pub const OBSERVED_REL: f64 = 0.02;

/// One plateau value placed on a map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obs {
    /// Column coordinate (throttle set point, or mapped throttle for the speed map).
    pub x: f64,
    /// Row coordinate (load set point; 0 for 1-D maps).
    pub y: f64,
    pub v: f64,
    pub sd: f64,
    /// Index of the plateau in its extraction.
    pub plateau: usize,
}

/// Fitted grid values.
#[derive(Debug, Clone, PartialEq)]
pub struct GridFit {
    pub values: Vec<f64>,
    /// Standard deviation per node (NaN where not observed).
    pub sd: Vec<f64>,
    pub observed: Vec<bool>,
    /// `v − fit` per observation.
    pub resid: Vec<f64>,
    pub chi2: f64,
    pub dof: usize,
}

impl GridFit {
    /// Observed nodes.
    pub fn n_observed(&self) -> usize {
        self.observed.iter().filter(|o| **o).count()
    }

    /// RMS of the residuals of the observations used.
    pub fn rms_resid(&self) -> f64 {
        let used: Vec<f64> = self.resid.iter().copied().filter(|r| r.is_finite()).collect();
        if used.is_empty() {
            return f64::NAN;
        }
        (used.iter().map(|r| r * r).sum::<f64>() / used.len() as f64).sqrt()
    }

    /// Observations left out because they lean on an unobserved node.
    pub fn n_dropped(&self) -> usize {
        self.resid.iter().filter(|r| !r.is_finite()).count()
    }
}

/// The model's linear interpolation weights on a grid (edges clamp).
pub fn weights_1d(xs: &[f32], q: f64) -> Vec<(usize, f64)> {
    let (i, t) = locate(xs, q as f32);
    let t = f64::from(t);
    vec![(i, 1.0 - t), (i + 1, t)].into_iter().filter(|(_, w)| *w != 0.0).collect()
}

/// The model's bilinear weights on a 2-D grid, row-major node index.
pub fn weights_2d(xs: &[f32], ys: &[f32], qx: f64, qy: f64) -> Vec<(usize, f64)> {
    let nx = xs.len();
    let mut out = Vec::with_capacity(4);
    for (iy, wy) in weights_1d(ys, qy) {
        for (ix, wx) in weights_1d(xs, qx) {
            out.push((iy * nx + ix, wx * wy));
        }
    }
    out
}

/// Least squares on an interpolation basis; unobserved nodes keep `base`.
///
/// Which nodes the data determine is decided with a weak prior (30x the map's range):
/// a node is observed when its posterior deviation is under [`OBSERVED_REL`] of the
/// range. An observation that also leans on an unobserved node (a chain of plateaus
/// between grid points that leaves one combination free) is dropped rather than fitted
/// against the base value, and the observed set recomputed until it is stable; the
/// final fit uses only observations lying entirely on observed nodes.
pub fn fit_grid(base: &[f64], obs: &[Obs], basis: &dyn Fn(&Obs) -> Vec<(usize, f64)>) -> GridFit {
    let n = base.len();
    let span = {
        let vals = base.iter().chain(obs.iter().map(|o| &o.v));
        let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
        (hi - lo).max(lo.abs().max(hi.abs()) * 0.1).max(1.0)
    };
    let tol = OBSERVED_REL * span;
    // A weak prior: 30x the map's range, yet within what f64 Cholesky resolves against
    // the data weights (sd floored at 1e-4 of the range, e.g. for noise-free runs).
    let sigma_p = 30.0 * span;
    let rows: Vec<Row> =
        obs.iter().map(|o| Row { coef: basis(o), y: o.v, sd: o.sd.max(1e-4 * span) }).collect();
    let prior: Vec<(f64, f64)> = base.iter().map(|b| (*b, sigma_p)).collect();
    let mut used = vec![true; rows.len()];
    let mut observed = vec![false; n];
    for _ in 0..=rows.len() {
        let active: Vec<Row> = rows.iter().zip(&used).filter(|(_, u)| **u).map(|(r, _)| r.clone()).collect();
        observed = match linalg::wls(&active, n, Some(&prior)) {
            Some(f) => (0..n).map(|i| f.sd(i) < tol).collect(),
            None => vec![false; n],
        };
        let next: Vec<bool> = rows
            .iter()
            .map(|r| r.coef.iter().all(|(i, _)| observed.get(*i).copied().unwrap_or(false)))
            .collect();
        if next == used {
            break;
        }
        used = next;
    }
    let idx: Vec<Option<usize>> = {
        let mut k = 0;
        observed
            .iter()
            .map(|o| {
                o.then(|| {
                    k += 1;
                    k - 1
                })
            })
            .collect()
    };
    let m = observed.iter().filter(|o| **o).count();
    let rows2: Vec<Row> = rows
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(r, _)| Row {
            coef: r
                .coef
                .iter()
                .filter_map(|(i, c)| idx.get(*i).copied().flatten().map(|j| (j, *c)))
                .collect(),
            y: r.y,
            sd: r.sd,
        })
        .collect();
    let prior2: Vec<(f64, f64)> = (0..n).filter(|i| observed[*i]).map(|i| (base[i], sigma_p)).collect();
    let mut values = base.to_vec();
    let mut sd = vec![f64::NAN; n];
    let fit2 = if m > 0 { linalg::wls(&rows2, m, Some(&prior2)) } else { None };
    let dof = rows2.len().saturating_sub(m);
    let mut chi2 = 0.0;
    if let Some(f) = &fit2 {
        let scale = if dof > 0 { (f.chi2 / dof as f64).max(1.0).sqrt() } else { 1.0 };
        for (i, j) in idx.iter().enumerate() {
            if let Some(j) = j {
                values[i] = f.x[*j];
                sd[i] = f.sd(*j) * scale;
            }
        }
        chi2 = f.chi2;
    }
    // Residuals of every observation against the written map (NaN: not used).
    let resid = rows
        .iter()
        .zip(&used)
        .map(|(r, u)| {
            if *u {
                r.y - r.coef.iter().map(|(i, c)| c * values.get(*i).copied().unwrap_or(0.0)).sum::<f64>()
            } else {
                f64::NAN
            }
        })
        .collect();
    GridFit { values, sd, observed, resid, chi2, dof }
}

/// The torque a load motor puts on the shaft for map value `t_map` [N m] at axle speed
/// `w_rpm` and throttle set point `thr_sp` [%], + braking forward motion: the model's
/// law (regenerating torque brakes either way and fades out below the fade speed;
/// motoring drives in the run direction up to the back-EMF limit). A port of model.rs.
pub fn shaft_load_torque(t_map: f64, w_rpm: f64, thr_sp: f64, p: &Params) -> f64 {
    if t_map >= 0.0 {
        let fade = f64::from(p.regen_fade_rpm);
        if fade > 0.0 {
            t_map * (w_rpm / fade).clamp(-1.0, 1.0)
        } else {
            0.0
        }
    } else {
        t_map * drive_dir(thr_sp) * envelope(w_rpm, thr_sp, p)
    }
}

fn drive_dir(thr_sp: f64) -> f64 {
    if thr_sp < 0.0 {
        -1.0
    } else {
        1.0
    }
}

/// The motoring torque envelope: 1 up to the load's base speed, 0 at its no-load speed.
fn envelope(w_rpm: f64, thr_sp: f64, p: &Params) -> f64 {
    let along = w_rpm * drive_dir(thr_sp) * f64::from(p.load_gear_ratio);
    let (nl, b) = (f64::from(p.load_no_load_rpm), f64::from(p.load_base_rpm));
    ((nl - along) / (nl - b)).clamp(0.0, 1.0)
}

fn map1_values(m: &Map1) -> Vec<f64> {
    m.y.iter().map(|v| f64::from(*v)).collect()
}

fn map2_values(m: &Map2) -> Vec<f64> {
    m.z.iter().map(|v| f64::from(*v)).collect()
}

fn identified_comments(base: &[String], what: &str, fit: &GridFit, n_obs: usize) -> Vec<String> {
    let mut c = vec![
        format!(
            "# Identified by `simrod identify {what}` from {n_obs} plateau values: {} of {} grid values observed;",
            fit.n_observed(),
            fit.values.len()
        ),
        "# the others keep the base model's values (marked in report.md).".to_string(),
    ];
    c.extend(base.iter().filter(|l| !l.contains("Synthesized") && !l.contains("Replace with")).cloned());
    c
}

fn run_name(ctx: &Context<'_>, ex: &Extraction, plateau: usize) -> String {
    ex.plateaus.get(plateau).and_then(|p| ctx.runs.get(p.run)).map_or("?".into(), |r| r.name.clone())
}

fn maps_err(e: simrod_io::datadir::DataError) -> CmdError {
    CmdError::Usage(format!("--data-dir: {e}"))
}

/// `simrod identify speed-map`.
pub fn speed_map(ctx: &Context<'_>) -> Result<Identification, CmdError> {
    let ex = ctx.extract(&["SuTMotorEnc"]);
    let p = ctx.params();
    let maps = ctx.base.maps().map_err(maps_err)?;
    let mut obs: [Vec<Obs>; 2] = [Vec::new(), Vec::new()];
    let mut censored: [Vec<Obs>; 2] = [Vec::new(), Vec::new()];
    for (j, pl) in ex.plateaus.iter().enumerate() {
        let thr = pl.sp[0] as f32;
        let d = throttle::dir_index(thr);
        let mapped = f64::from(maps.throttle_input.eval(throttle::voltage(&p, thr)));
        let o = Obs { x: mapped, y: 0.0, v: pl.mean(0).abs(), sd: pl.sem(0).max(1e-6), plateau: j };
        let limit = f64::from(p.speed_limit_rpm[d]);
        if o.v >= limit - (3.0 * o.sd).max(0.002 * limit) {
            censored[d].push(o);
        } else {
            obs[d].push(o);
        }
    }
    if obs.iter().all(Vec::is_empty) {
        return Err(CmdError::Usage(format!(
            "speed-map: no plateau below the speed limits; {}",
            super::resistance::why_none(ctx, &ex)
        )));
    }
    let mut data = ctx.base.clone();
    let mut rep = Report::new("simrod identify speed-map");
    rep.para(
        "Mapped throttle (set point → V = |sp|/20 → Curtis input map of the base data) → steady SuT motor speed \
         magnitude (thesis 5.2.1, fig. 5.6/5.7), forward and reverse. Plateaus at the speed limit are censored \
         (they only bound the map from below). `(v)` marks grid values kept from the base model.",
    );
    let mut changed = Vec::new();
    let mut fits = Vec::new();
    for d in 0..2 {
        let (name, file, base) = if d == 0 {
            ("forward", "speed_map_fwd.csv", &ctx.base.speed_fwd)
        } else {
            ("reverse", "speed_map_rev.csv", &ctx.base.speed_rev)
        };
        let xs = base.x.clone();
        let fit = fit_grid(&map1_values(base), &obs[d], &|o: &Obs| weights_1d(&xs, o.x));
        rep.h2(&format!("Speed map, {name} (limit {} rpm)", num(f64::from(p.speed_limit_rpm[d]))));
        let rows: Vec<Vec<String>> = base
            .x
            .iter()
            .enumerate()
            .map(|(i, x)| {
                let v = if fit.observed[i] {
                    pm(fit.values[i], fit.sd[i])
                } else {
                    format!("({})", num(fit.values[i]))
                };
                vec![num(f64::from(*x)), num(f64::from(base.y[i])), v]
            })
            .collect();
        rep.table(&["mapped throttle [%]", "base [rpm]", "identified [rpm]"], &rows);
        rep.para(&format!(
            "{} plateau(s) used, {} at the limit; {} of {} grid values observed; residual rms {} rpm, χ²/dof {}.",
            obs[d].len(),
            censored[d].len(),
            fit.n_observed(),
            fit.values.len(),
            num(fit.rms_resid()),
            num(fit.chi2 / fit.dof.max(1) as f64)
        ));
        let prow: Vec<Vec<String>> = obs[d]
            .iter()
            .zip(&fit.resid)
            .map(|(o, r)| {
                (o, if r.is_finite() { num(*r) } else { "not used (unobserved neighbour)".to_string() })
            })
            .chain(censored[d].iter().map(|o| (o, "at limit".to_string())))
            .map(|(o, r)| {
                let pl = &ex.plateaus[o.plateau];
                vec![
                    run_name(ctx, &ex, o.plateau),
                    format!("{:.1}–{:.1}", pl.t0, pl.t1),
                    num(pl.sp[0]),
                    num(o.x),
                    pm(o.v, pl.stats[0].rms),
                    r,
                ]
            })
            .collect();
        rep.table(
            &["run", "t [s]", "throttle sp [%]", "mapped [%]", "speed [rpm] (± rms)", "residual [rpm]"],
            &prow,
        );
        let (px, py, pe): (Vec<f64>, Vec<f64>, Vec<f64>) =
            unzip3(obs[d].iter().chain(&censored[d]).map(|o| (o.x, o.v, 2.0 * o.sd)));
        let bx: Vec<f64> = base.x.iter().map(|v| f64::from(*v)).collect();
        rep.plot(
            &format!("speed_map_{}.svg", ["fwd", "rev"][d]),
            &format!("speed map {name}"),
            xy_chart(
                &format!("Speed map {name}: steady speed vs mapped throttle (± 2 s.e.)"),
                "mapped throttle [%]",
                "motor speed [rpm]",
                &[XyPoints { x: &px, y: &py, err: Some(&pe), color: PALETTE[0], label: "plateaus" }],
                &[
                    XyLine { x: &bx, y: &fit.values, color: PALETTE[1], label: "identified", dashed: false },
                    XyLine { x: &bx, y: &map1_values(base), color: "#888", label: "base", dashed: true },
                ],
            ),
        );
        let target = if d == 0 { &mut data.speed_fwd } else { &mut data.speed_rev };
        target.y = fit.values.iter().map(|v| *v as f32).collect();
        target.comments = identified_comments(&base.comments, "speed-map", &fit, obs[d].len());
        if fit.n_observed() > 0 {
            changed.push(file.to_string());
        }
        fits.push(MapFit { file: file.to_string(), observed: fit.observed.clone(), sd: fit.sd.clone() });
    }
    campaign_section(&mut rep, ctx.runs, &ex);
    Ok(Identification { data, changed, report: rep, fits, values: Vec::new() })
}

fn unzip3(it: impl Iterator<Item = (f64, f64, f64)>) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (mut a, mut b, mut c) = (Vec::new(), Vec::new(), Vec::new());
    for (x, y, z) in it {
        a.push(x);
        b.push(y);
        c.push(z);
    }
    (a, b, c)
}

/// Fit one 2-D map and report it; the file `{key}.csv` goes into `changed` when the
/// campaign observed any of its cells.
#[allow(clippy::too_many_arguments)]
fn map2(
    rep: &mut Report,
    fits: &mut Vec<MapFit>,
    changed: &mut Vec<String>,
    ctx: &Context<'_>,
    ex: &Extraction,
    what: &str,
    key: &str,
    title: &str,
    unit: &str,
    base: &Map2,
    obs: &[Obs],
) -> Map2 {
    let (xs, ys) = (base.x.clone(), base.y.clone());
    let fit = fit_grid(&map2_values(base), obs, &|o: &Obs| weights_2d(&xs, &ys, o.x, o.y));
    rep.h2(title);
    rep.para(&format!(
        "{} plateau value(s), {} not used (they lean on a cell the campaign does not determine); \
         {} of {} cells observed; residual rms {} {unit}, χ²/dof {}. \
         Rows: load set point [%]; columns: throttle set point [%]; `(v)`: kept from the base model.",
        obs.len(),
        fit.n_dropped(),
        fit.n_observed(),
        fit.values.len(),
        num(fit.rms_resid()),
        num(fit.chi2 / fit.dof.max(1) as f64)
    ));
    let nx = base.x.len();
    let mut head: Vec<String> = vec!["load \\ throttle".into()];
    head.extend(base.x.iter().map(|x| num(f64::from(*x))));
    let head_ref: Vec<&str> = head.iter().map(String::as_str).collect();
    let rows: Vec<Vec<String>> = base
        .y
        .iter()
        .enumerate()
        .map(|(iy, y)| {
            let mut r = vec![num(f64::from(*y))];
            r.extend((0..nx).map(|ix| {
                let i = iy * nx + ix;
                if fit.observed[i] {
                    num(fit.values[i])
                } else {
                    format!("({})", num(fit.values[i]))
                }
            }));
            r
        })
        .collect();
    rep.table(&head_ref, &rows);
    // Chart: each observed load row against throttle.
    let mut pts = Vec::new();
    let mut lines = Vec::new();
    for (iy, y) in base.y.iter().enumerate() {
        if !(0..nx).any(|ix| fit.observed[iy * nx + ix]) {
            continue;
        }
        let on_row: Vec<&Obs> = obs
            .iter()
            .filter(|o| weights_1d(&base.y, o.y).iter().any(|(j, w)| *j == iy && *w > 0.5))
            .collect();
        let color = PALETTE[pts.len() % PALETTE.len()];
        pts.push((
            on_row.iter().map(|o| o.x).collect::<Vec<f64>>(),
            on_row.iter().map(|o| o.v).collect::<Vec<f64>>(),
            on_row.iter().map(|o| 2.0 * o.sd).collect::<Vec<f64>>(),
            color,
            format!("load {}", num(f64::from(*y))),
        ));
        lines.push((
            base.x.iter().map(|v| f64::from(*v)).collect::<Vec<f64>>(),
            (0..nx).map(|ix| fit.values[iy * nx + ix]).collect::<Vec<f64>>(),
            color,
        ));
    }
    let xp: Vec<XyPoints<'_>> =
        pts.iter().map(|(x, y, e, c, l)| XyPoints { x, y, err: Some(e), color: c, label: l }).collect();
    let xl: Vec<XyLine<'_>> =
        lines.iter().map(|(x, y, c)| XyLine { x, y, color: c, label: "", dashed: false }).collect();
    rep.plot(&format!("{key}.svg"), title, xy_chart(title, "throttle set point [%]", unit, &xp, &xl));
    let prow: Vec<Vec<String>> = obs
        .iter()
        .zip(&fit.resid)
        .map(|(o, r)| {
            let pl = &ex.plateaus[o.plateau];
            vec![
                run_name(ctx, ex, o.plateau),
                format!("{:.1}–{:.1}", pl.t0, pl.t1),
                sp_str(&pl.sp),
                pm(o.v, o.sd),
                if r.is_finite() { num(*r) } else { "not used (unobserved neighbour)".to_string() },
            ]
        })
        .collect();
    rep.table(&["run", "t [s]", "set points [%]", &format!("value [{unit}] (± s.e.)"), "residual"], &prow);
    fits.push(MapFit { file: format!("{key}.csv"), observed: fit.observed.clone(), sd: fit.sd.clone() });
    let mut out = base.clone();
    out.z = fit.values.iter().map(|v| *v as f32).collect();
    out.comments = identified_comments(&base.comments, what, &fit, obs.len());
    if fit.n_observed() > 0 {
        changed.push(format!("{key}.csv"));
    }
    out
}

/// `simrod identify load-maps`.
pub fn load_maps(ctx: &Context<'_>) -> Result<Identification, CmdError> {
    let ex = ctx.extract(&["C_Kistler_L", "C_Kistler_R", "T_Kistler_L", "T_Kistler_R"]);
    let p = ctx.params();
    let maps = ctx.base.maps().map_err(maps_err)?;
    let fade = f64::from(p.regen_fade_rpm);
    let mut data: ModelData = ctx.base.clone();
    let mut rep = Report::new("simrod identify load-maps");
    rep.para(
        "Load motor axle torque per side (thesis 5.2.2, fig. 5.12–5.15) = flange torque − friction of the base data \
         at the plateau's flange speed, referred to the map through the model's regen fade and motoring envelope; \
         phase current maps from `I_LML_phase` / `I_LMR_phase` where the runs log them (the bench's current probes \
         measure the DC side, which the model derives from the load power maps).",
    );
    let mut changed = Vec::new();
    let mut fits = Vec::new();
    let mut skipped = 0;
    for side in 0..2 {
        let name = ["L", "R"][side];
        let mut obs = Vec::new();
        for (j, pl) in ex.plateaus.iter().enumerate() {
            let (thr, load) = (pl.sp[0], pl.sp[1 + side]);
            let (w, c) = (pl.mean(2 + side), pl.mean(side));
            let fric = &maps.friction[side];
            let f = f64::from(fric.eval(w as f32));
            let fs = f64::from(fric.eval((w + 0.5) as f32) - fric.eval((w - 0.5) as f32));
            let sd = (pl.sem(side).powi(2) + (fs * pl.sem(2 + side)).powi(2)).sqrt().max(1e-6);
            let dir = drive_dir(thr);
            let on_shaft = c - f;
            let v = if w.abs() >= 1.5 * fade {
                let y = dir * on_shaft;
                if y < 0.0 {
                    let env = envelope(w, thr, &p);
                    if env < 0.2 {
                        skipped += 1;
                        continue;
                    }
                    y / env
                } else {
                    y
                }
            } else if load < -0.5 {
                dir * on_shaft
            } else {
                skipped += 1; // regenerating or idle load at standstill: fades to nothing
                continue;
            };
            obs.push(Obs { x: thr, y: load, v, sd, plateau: j });
        }
        let m = map2(
            &mut rep,
            &mut fits,
            &mut changed,
            ctx,
            &ex,
            "load-maps",
            &format!("load_torque_{name}"),
            &format!("Load motor {name} axle torque"),
            "N m",
            &ctx.base.load_torque[side],
            &obs,
        );
        data.load_torque[side] = m;
    }
    if skipped > 0 {
        rep.para(&format!(
            "{skipped} plateau side(s) left out: a regenerating or idle load on a shaft at rest (|speed| < {} rpm) puts no torque on it, \
             or a motoring load beyond its back-EMF envelope.",
            num(1.5 * fade)
        ));
    }
    campaign_section(&mut rep, ctx.runs, &ex);
    // Phase currents, from the runs that log them.
    let ph = ctx.extract(&["I_LML_phase", "I_LMR_phase"]);
    if ph.plateaus.is_empty() {
        rep.h2("Phase current maps");
        rep.para(
            "Not identified: no run logs `I_LML_phase` / `I_LMR_phase` (map the drives' logged phase current with --mapping). \
             load_current_L/R.csv keep the base model's values.",
        );
    } else {
        for side in 0..2 {
            let name = ["L", "R"][side];
            let obs: Vec<Obs> = ph
                .plateaus
                .iter()
                .enumerate()
                .map(|(j, pl)| Obs {
                    x: pl.sp[0],
                    y: pl.sp[1 + side],
                    v: pl.mean(side),
                    sd: pl.sem(side).max(1e-6),
                    plateau: j,
                })
                .collect();
            let m = map2(
                &mut rep,
                &mut fits,
                &mut changed,
                ctx,
                &ph,
                "load-maps",
                &format!("load_current_{name}"),
                &format!("Load motor {name} phase current"),
                "A",
                &ctx.base.load_current[side],
                &obs,
            );
            data.load_current[side] = m;
        }
    }
    Ok(Identification { data, changed, report: rep, fits, values: Vec::new() })
}

/// `simrod identify power-maps`.
pub fn power_maps(ctx: &Context<'_>) -> Result<Identification, CmdError> {
    let ex = ctx.extract(&["P_SuT_inv", "P_LML", "P_LMR"]);
    if ex.plateaus.is_empty() {
        return Err(CmdError::Usage(format!(
            "power-maps: no plateau; {}",
            super::resistance::why_none(ctx, &ex)
        )));
    }
    let mut data = ctx.base.clone();
    let mut rep = Report::new("simrod identify power-maps");
    rep.para(
        "Electrical powers (thesis 5.5, table 5.13), plateau means of the per-sample products: \
         SuT inverter `V_DC · I_DC` over (throttle, mean load set point); load motors \
         `XLMtot · V_DC_busbars` over (throttle, own load set point).",
    );
    let mk = |f: &dyn Fn(&[f64; 3]) -> f64, ch: usize| -> Vec<Obs> {
        ex.plateaus
            .iter()
            .enumerate()
            .map(|(j, pl)| Obs {
                x: pl.sp[0],
                y: f(&pl.sp),
                v: pl.mean(ch),
                sd: pl.sem(ch).max(1e-6),
                plateau: j,
            })
            .collect()
    };
    let mut changed = Vec::new();
    let mut fits = Vec::new();
    let sut = mk(&|sp| 0.5 * (sp[1] + sp[2]), 0);
    let m = map2(
        &mut rep,
        &mut fits,
        &mut changed,
        ctx,
        &ex,
        "power-maps",
        "sut_inverter_power",
        "SuT inverter power",
        "W",
        &ctx.base.sut_power,
        &sut,
    );
    data.sut_power = m;
    for side in 0..2 {
        let name = ["L", "R"][side];
        let obs = mk(&|sp| sp[1 + side], 1 + side);
        let m = map2(
            &mut rep,
            &mut fits,
            &mut changed,
            ctx,
            &ex,
            "power-maps",
            &format!("load_power_{name}"),
            &format!("Load motor {name} power"),
            "W",
            &ctx.base.load_power[side],
            &obs,
        );
        data.load_power[side] = m;
    }
    campaign_section(&mut rep, ctx.runs, &ex);
    Ok(Identification { data, changed, report: rep, fits, values: Vec::new() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identify_grid_fit_recovers_observed_nodes_and_keeps_the_rest() {
        // 1-D: truth y = 3x on nodes 0..4; observations only between 0 and 2.
        let xs = [0.0f32, 1.0, 2.0, 3.0, 4.0];
        let base = [0.0, 0.0, 0.0, 50.0, 50.0];
        let obs: Vec<Obs> = [0.0, 0.3, 0.5, 1.0, 1.25, 1.7, 2.0]
            .iter()
            .enumerate()
            .map(|(j, x)| Obs { x: *x, y: 0.0, v: 3.0 * x, sd: 0.01, plateau: j })
            .collect();
        let f = fit_grid(&base, &obs, &|o: &Obs| weights_1d(&xs, o.x));
        assert_eq!(f.observed, vec![true, true, true, false, false]);
        for i in 0..3 {
            assert!((f.values[i] - 3.0 * i as f64).abs() < 1e-6, "{f:?}");
        }
        assert_eq!(&f.values[3..], &[50.0, 50.0]);
        assert!(f.chi2 < 1e-6 && f.dof == 4);
        // One observation between two otherwise free nodes determines only their mix.
        let obs = [Obs { x: 3.5, y: 0.0, v: 7.0, sd: 0.01, plateau: 0 }];
        let f = fit_grid(&base, &obs, &|o: &Obs| weights_1d(&xs, o.x));
        assert_eq!(f.observed, vec![false; 5]);
        assert_eq!(f.values, base.to_vec());
    }

    #[test]
    fn identify_bilinear_weights_match_the_model() {
        let xs = [0.0f32, 10.0, 30.0];
        let ys = [-1.0f32, 1.0];
        let z = [1.0f32, 2.0, 5.0, -3.0, 4.0, 0.5];
        let t = model_core::table::Table2::new(&xs, &ys, &z).unwrap();
        for (qx, qy) in [(5.0, 0.0), (25.0, 0.7), (40.0, -2.0), (0.0, 1.0)] {
            let v: f64 = weights_2d(&xs, &ys, qx, qy).iter().map(|(i, w)| w * f64::from(z[*i])).sum();
            assert!((v - f64::from(t.eval(qx as f32, qy as f32))).abs() < 1e-5, "{qx} {qy}");
        }
    }

    #[test]
    fn identify_shaft_torque_follows_the_model_law() {
        let p = Params::default();
        assert_eq!(shaft_load_torque(10.0, 100.0, 50.0, &p), 10.0);
        assert_eq!(shaft_load_torque(10.0, -100.0, -50.0, &p), -10.0);
        assert!((shaft_load_torque(10.0, 2.5, 50.0, &p) - 5.0).abs() < 1e-9);
        assert_eq!(shaft_load_torque(-10.0, 100.0, 50.0, &p), -10.0);
        assert_eq!(shaft_load_torque(-10.0, -40.0, -50.0, &p), 10.0);
        // Above the load's base speed (2000 rpm at the load = 200 rpm axle) it fades.
        assert!((shaft_load_torque(-10.0, 275.0, 50.0, &p) + 5.0).abs() < 1e-9);
    }
}
