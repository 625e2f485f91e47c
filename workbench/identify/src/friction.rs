//! `identify friction`: the axle friction map of each side (thesis 5.3.1, table 5.7).
//!
//! Data: plateaus with both load set points at 0. The flange only sees what is
//! downstream of it (docs/MODEL.md), so at steady state its torque is the friction at
//! the flange speed plus whatever the unpowered load motor still puts on the shaft: the
//! load torque map's load-0 row, which is not zero at high throttle (the load motors'
//! drag). That drag enters the fit as the base map's row scaled by a factor `d`
//! estimated with the friction (identifiable because at the speed limit the throttle
//! still changes the drag but not the speed); `d = 1` means the base row is right.
//!
//! Law (the thesis' "cubic near zero, linear outside", made continuous with a
//! continuous slope and odd, so reverse plateaus are the mirrored points the thesis had
//! to add by hand): with `u = w / w_t`,
//! `f(w) = f_t (3u − u³)/2 + k w_t (u³ − u)/2` for `|w| ≤ w_t`,
//! `f(w) = sign(w) (f_t + k (|w| − w_t))` outside. `f_t` is the torque at the threshold,
//! `k` the viscous slope. For a given `w_t` the law is linear in `f_t`, `k` (and `d`):
//! weighted least squares; `w_t` is optimised by a grid and golden-section search on
//! χ² (the thesis' "basic optimisation"). Uncertainties from the Jacobian at the
//! optimum, errors in the speed included, scaled by χ²/dof when above 1.
//!
//! The written map: the law on a grid dense in the cubic part, the base grid outside;
//! beyond the fastest plateau the base map's end step (the motor limits, which no
//! steady plateau reaches) is kept, offset to join the law.

use model_core::table::Table2;
use model_core::Params;

use super::maps::shaft_load_torque;
use super::plateau::Extraction;
use super::report::{campaign_section, num, pm, sp_str, xy_chart, Report, XyLine, XyPoints, PALETTE};
use super::{Context, Identification};
use simrod_io::datadir::Map1;
use simrod_io::error::CmdError;
use simrod_numerics::linalg::{self, Row};

/// Loads at or below this |set point| [%] count as zero.
const ZERO_LOAD: f64 = 0.5;
/// Nodes in the cubic part of the written map.
const CUBIC_NODES: usize = 10;

/// One steady point of one side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// [rpm] flange speed.
    pub w: f64,
    /// [N m] flange torque.
    pub c: f64,
    pub sd_w: f64,
    pub sd_c: f64,
    /// [N m] the base load map's load-0 torque on the shaft at this throttle and speed.
    pub drag: f64,
    /// Index of the plateau in the extraction.
    pub plateau: usize,
}

/// The law's parameters with their covariance.
#[derive(Debug, Clone, PartialEq)]
pub struct FrictionFit {
    /// [N m] torque at the threshold.
    pub f_t: f64,
    /// [N m/rpm] slope outside.
    pub k: f64,
    /// [rpm] threshold.
    pub w_t: f64,
    /// Scale of the base map's load-0 drag (1 when not observable).
    pub d: f64,
    /// Standard deviations of `f_t`, `k`, `w_t`, `d` (`d`: NaN when not fitted).
    pub sd: [f64; 4],
    pub chi2: f64,
    pub dof: usize,
    /// Table 5.7 statistics over the points: RMSE [N m] and r².
    pub rmse: f64,
    pub r2: f64,
    /// Whether the drag scale was fitted.
    pub drag_fitted: bool,
}

/// The law `f(w)`.
pub fn law(w: f64, f_t: f64, k: f64, w_t: f64) -> f64 {
    let (g1, g2) = basis(w, w_t);
    f_t * g1 + k * g2
}

/// `(∂f/∂f_t, ∂f/∂k)`.
fn basis(w: f64, w_t: f64) -> (f64, f64) {
    if w.abs() > w_t {
        (w.signum(), w.signum() * (w.abs() - w_t))
    } else {
        let u = w / w_t;
        (0.5 * (3.0 * u - u * u * u), 0.5 * w_t * (u * u * u - u))
    }
}

/// `∂f/∂w_t`.
fn d_wt(w: f64, f_t: f64, k: f64, w_t: f64) -> f64 {
    if w.abs() > w_t {
        -w.signum() * k
    } else {
        let u = w / w_t;
        -1.5 * f_t * u * (1.0 - u * u) / w_t - k * u * u * u
    }
}

/// `∂f/∂w`.
fn slope(w: f64, f_t: f64, k: f64, w_t: f64) -> f64 {
    if w.abs() > w_t {
        k
    } else {
        let u = w / w_t;
        (1.5 * f_t * (1.0 - u * u) + 0.5 * k * w_t * (3.0 * u * u - 1.0)) / w_t
    }
}

/// Linear fit for a fixed threshold: `(f_t, k, d, chi2)`.
fn fit_at(pts: &[Point], w_t: f64, drag: bool, guess: (f64, f64)) -> Option<(linalg::Fit, Vec<Row>)> {
    let np = if drag { 3 } else { 2 };
    let mut g = guess;
    let mut last = None;
    for _ in 0..2 {
        let rows: Vec<Row> = pts
            .iter()
            .map(|p| {
                let (a, b) = basis(p.w, w_t);
                let mut coef = vec![(0, a), (1, b)];
                if drag {
                    coef.push((2, p.drag));
                }
                let s = slope(p.w, g.0, g.1, w_t) * p.sd_w;
                Row { coef, y: p.c, sd: (p.sd_c * p.sd_c + s * s).sqrt().max(1e-9) }
            })
            .collect();
        let f = linalg::wls(&rows, np, None)?;
        g = (f.x[0], f.x[1]);
        last = Some((f, rows));
    }
    last
}

/// Fit the law to one side's points.
pub fn fit(pts: &[Point]) -> Option<FrictionFit> {
    let w_max = pts.iter().map(|p| p.w.abs()).fold(0.0, f64::max);
    if pts.iter().filter(|p| p.w.abs() > 1.0).count() < 4 || w_max < 5.0 {
        return None;
    }
    let drag = {
        let (lo, hi) =
            pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.drag), b.max(p.drag)));
        hi - lo > 1e-6
    };
    let guess = (pts.iter().map(|p| p.c.abs()).fold(0.0, f64::max) * 0.3, 0.05);
    let chi2 = |w_t: f64| fit_at(pts, w_t, drag, guess).map_or(f64::INFINITY, |(f, _)| f.chi2);
    // Grid (log-spaced) then golden section around the best grid point.
    let (lo, hi) = (0.5f64, 0.9 * w_max);
    let n = 60;
    let grid: Vec<f64> = (0..n).map(|j| lo * (hi / lo).powf(j as f64 / (n - 1) as f64)).collect();
    let scores: Vec<f64> = grid.iter().map(|w| chi2(*w)).collect();
    let best = (0..n).min_by(|a, b| scores[*a].total_cmp(&scores[*b]))?;
    let (mut a, mut b) = (grid[best.saturating_sub(1)], grid[(best + 1).min(n - 1)]);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (b - phi * (b - a), a + phi * (b - a));
    let (mut fc, mut fd) = (chi2(c), chi2(d));
    for _ in 0..40 {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - phi * (b - a);
            fc = chi2(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + phi * (b - a);
            fd = chi2(d);
        }
    }
    let mut w_t = if fc < fd { c } else { d };
    // No plateau inside the cubic part: any threshold below the slowest plateau fits
    // alike. Then only the linear part is measured; the threshold is set halfway to
    // the slowest plateau and reported as undetermined.
    let w_min = pts.iter().map(|p| p.w.abs()).filter(|w| *w > 1.0).fold(f64::INFINITY, f64::min);
    let determined = pts.iter().any(|p| p.w.abs() > 1.0 && p.w.abs() < 0.98 * w_t);
    if !determined {
        w_t = 0.5 * w_min;
    }
    let (lin, rows) = fit_at(pts, w_t, drag, guess)?;
    let (f_t, k) = (lin.x[0], lin.x[1]);
    let dd = if drag { lin.x[2] } else { 1.0 };
    let dof = pts.len().saturating_sub(if drag { 4 } else { 3 }).max(1);
    let scale = (lin.chi2 / dof as f64).max(1.0).sqrt();
    // Full covariance from the Jacobian in (f_t, k, w_t[, d]); with the threshold
    // undetermined, the linear fit's covariance in (f_t, k[, d]).
    let sd: [f64; 4] = if determined {
        let np = if drag { 4 } else { 3 };
        let jrows: Vec<Row> = pts
            .iter()
            .zip(&rows)
            .map(|(p, r)| {
                let (g1, g2) = basis(p.w, w_t);
                let mut coef = vec![(0, g1), (1, g2), (2, d_wt(p.w, f_t, k, w_t))];
                if drag {
                    coef.push((3, p.drag));
                }
                Row { coef, y: 0.0, sd: r.sd }
            })
            .collect();
        let jac = linalg::wls(&jrows, np, None)?;
        let sd = |i: usize| jac.sd(i) * scale;
        [sd(0), sd(1), sd(2), if drag { sd(3) } else { f64::NAN }]
    } else {
        let sd = |i: usize| lin.sd(i) * scale;
        [sd(0), sd(1), f64::NAN, if drag { sd(2) } else { f64::NAN }]
    };
    let resid: Vec<f64> = pts.iter().map(|p| p.c - law(p.w, f_t, k, w_t) - dd * p.drag).collect();
    let mean_c = pts.iter().map(|p| p.c).sum::<f64>() / pts.len() as f64;
    let ss_res: f64 = resid.iter().map(|r| r * r).sum();
    let ss_tot: f64 = pts.iter().map(|p| (p.c - mean_c).powi(2)).sum();
    Some(FrictionFit {
        f_t,
        k,
        w_t,
        d: dd,
        sd,
        chi2: lin.chi2,
        dof,
        rmse: (ss_res / pts.len() as f64).sqrt(),
        r2: if ss_tot > 0.0 { 1.0 - ss_res / ss_tot } else { f64::NAN },
        drag_fitted: drag,
    })
}

/// The points of side `i` (0 = L) from zero-load plateaus.
fn points(ex: &Extraction, side: usize, drag_map: &Table2<'_>, p: &Params) -> Vec<Point> {
    let (ci, wi) = (side, 2 + side);
    ex.plateaus
        .iter()
        .enumerate()
        .filter(|(_, pl)| pl.sp[1].abs() <= ZERO_LOAD && pl.sp[2].abs() <= ZERO_LOAD)
        .map(|(j, pl)| {
            let w = pl.mean(wi);
            let t_map = f64::from(drag_map.eval(pl.sp[0] as f32, pl.sp[1 + side] as f32));
            Point {
                w,
                c: pl.mean(ci),
                sd_w: pl.sem(wi),
                sd_c: pl.sem(ci),
                drag: shaft_load_torque(t_map, w, pl.sp[0], p),
                plateau: j,
            }
        })
        .collect()
}

/// The written map: the law on a grid dense in the cubic part and the base grid
/// outside; beyond `w_max` the base's end step is kept (offset to join the law).
/// Returns the map and notes on what was extrapolated or kept.
pub fn table(f: &FrictionFit, base: &Map1, w_max: f64, header_note: String) -> (Map1, Vec<String>) {
    let base_at = |x: f64| {
        f64::from(model_core::table::Table1::new(&base.x, &base.y).map_or(0.0, |t| t.eval(x as f32)))
    };
    let round = |v: f64| (v * 100.0).round() / 100.0;
    let mut pos: Vec<f64> = (1..=CUBIC_NODES).map(|j| round(f.w_t * j as f64 / CUBIC_NODES as f64)).collect();
    pos.extend(base.x.iter().map(|x| f64::from(*x)).filter(|x| *x > f.w_t * 1.02));
    pos.sort_by(f64::total_cmp);
    pos.dedup_by(|a, b| (*a - *b).abs() < 0.01);
    pos.retain(|x| *x > 0.0);
    // Where the base map steps up (motor limits): slope > 3x its slope at w_max.
    let base_slope = (base_at(w_max) - base_at(w_max - 5.0)) / 5.0;
    let step = base
        .x
        .windows(2)
        .zip(base.y.windows(2))
        .map(|(x, y)| (f64::from(x[0]), f64::from(x[1]), f64::from(y[0]), f64::from(y[1])))
        .find(|(x0, x1, y0, y1)| *x0 >= w_max && (y1 - y0) / (x1 - x0) > 3.0 * base_slope.max(1e-6))
        .map(|t| t.0);
    let mut notes = Vec::new();
    let value = |x: f64| match step {
        Some(xs) if x > xs => law(xs, f.f_t, f.k, f.w_t) + base_at(x) - base_at(xs),
        _ => law(x, f.f_t, f.k, f.w_t),
    };
    let extrapolated: Vec<String> =
        pos.iter().filter(|x| **x > w_max && step.is_none_or(|s| **x <= s)).map(|x| num(*x)).collect();
    if !extrapolated.is_empty() {
        notes.push(format!(
            "law extrapolated beyond the fastest plateau ({} rpm) at ±{} rpm",
            num(w_max),
            extrapolated.join(", ±")
        ));
    }
    if let Some(xs) = step {
        notes.push(format!(
            "beyond {} rpm the base map's end step (motor limits, 5.3.1) is kept, offset to join the law",
            num(xs)
        ));
    }
    let mut x = Vec::with_capacity(2 * pos.len() + 1);
    let mut y = Vec::with_capacity(2 * pos.len() + 1);
    for p in pos.iter().rev() {
        x.push(-*p as f32);
        y.push(-value(*p) as f32);
    }
    x.push(0.0);
    y.push(0.0);
    for p in &pos {
        x.push(*p as f32);
        y.push(value(*p) as f32);
    }
    let mut comments = vec![
        "# Identified by `simrod identify friction` (thesis 5.3.1): odd cubic near zero, linear outside."
            .to_string(),
        format!("# {header_note}"),
    ];
    comments.extend(
        base.comments.iter().filter(|c| !c.contains("Synthesized") && !c.contains("Replace with")).cloned(),
    );
    (Map1 { comments, header: base.header.clone(), x, y }, notes)
}

/// `simrod identify friction`.
pub fn identify(ctx: &Context<'_>) -> Result<Identification, CmdError> {
    let ex = ctx.extract(&["C_Kistler_L", "C_Kistler_R", "T_Kistler_L", "T_Kistler_R"]);
    let params = ctx.params();
    let maps = ctx.base.maps().map_err(|e| CmdError::Usage(format!("--data-dir: {e}")))?;
    let mut data = ctx.base.clone();
    let mut rep = Report::new("simrod identify friction");
    rep.para(
        "Axle friction per side from the flange torque at steady speed with both loads at 0 (thesis 5.3.1). \
         Law: odd, cubic for |w| ≤ w_t and linear outside with a continuous slope; \
         C = f(w) + d · (base load-0 drag). Uncertainties are one standard deviation.",
    );
    let zero =
        ex.plateaus.iter().filter(|p| p.sp[1].abs() <= ZERO_LOAD && p.sp[2].abs() <= ZERO_LOAD).count();
    let mut rows = Vec::new();
    let mut changed = Vec::new();
    let mut all_pts = Vec::new();
    let mut values = Vec::new();
    for side in 0..2 {
        let name = ["L", "R"][side];
        let pts = points(&ex, side, &maps.load_torque[side], &params);
        let f = fit(&pts).ok_or_else(|| {
            CmdError::Usage(format!(
                "friction {name}: {} zero-load plateau(s), need 4 or more at different speeds (TP11 with load scale 0); {}",
                pts.len(),
                super::resistance::why_none(ctx, &ex)
            ))
        })?;
        let w_max = pts.iter().map(|p| p.w.abs()).fold(0.0, f64::max);
        let base_map = &ctx.base.friction[side];
        let note = format!(
            "side {name}: f_t = {} N m, k = {} N m/rpm, w_t = {} from {} plateaus (RMSE {} N m, r2 {:.4})",
            pm(f.f_t, f.sd[0]),
            pm(f.k, f.sd[1]),
            if f.sd[2].is_finite() {
                format!("{} rpm", pm(f.w_t, f.sd[2]))
            } else {
                format!("{} rpm (undetermined)", num(f.w_t))
            },
            pts.len(),
            num(f.rmse),
            f.r2
        );
        let (map, notes) = table(&f, base_map, w_max, note);
        let base_rmse = {
            let t = model_core::table::Table1::new(&base_map.x, &base_map.y).ok();
            let ss: f64 = pts
                .iter()
                .map(|p| (p.c - p.drag - t.map_or(0.0, |t| f64::from(t.eval(p.w as f32)))).powi(2))
                .sum();
            (ss / pts.len().max(1) as f64).sqrt()
        };
        rows.push(vec![
            name.to_string(),
            pm(f.f_t, f.sd[0]),
            pm(f.k, f.sd[1]),
            if f.sd[2].is_finite() {
                pm(f.w_t, f.sd[2])
            } else {
                format!("{} (not determined: no plateau below {} rpm)", num(f.w_t), num(2.0 * f.w_t))
            },
            if f.drag_fitted { pm(f.d, f.sd[3]) } else { "not observed (kept 1)".into() },
            format!("{} N m", num(f.rmse)),
            format!("{:.4}", f.r2),
            num(f.chi2 / f.dof as f64),
            pts.len().to_string(),
            format!("{} N m", num(base_rmse)),
        ]);
        let a = (3.0 * f.f_t - f.k * f.w_t) / (2.0 * f.w_t);
        let c3 = (f.k * f.w_t - f.f_t) / (2.0 * f.w_t.powi(3));
        let mut items = vec![format!(
            "side {name}: for |w| ≤ {} rpm, f = {} w {} {} w³; outside, f = sign(w) ({} + {} (|w| − {})); Coulomb-like offset f_t − k w_t = {} N m",
            num(f.w_t),
            num(a),
            if c3 < 0.0 { "−" } else { "+" },
            num(c3.abs()),
            num(f.f_t),
            num(f.k),
            num(f.w_t),
            num(f.f_t - f.k * f.w_t)
        )];
        items.extend(notes);
        rep.bullets(&items);
        plot(&mut rep, name, &pts, &f, &map, base_map, w_max);
        let v = |n: &str, value: f64, sd: f64, unit: &str| super::Value {
            name: format!("friction_{name}.{n}"),
            value,
            sd,
            unit: unit.to_string(),
        };
        values.extend([
            v("f_t", f.f_t, f.sd[0], "N m"),
            v("k", f.k, f.sd[1], "N m/rpm"),
            v("w_t", f.w_t, f.sd[2], "rpm"),
            v("d", f.d, f.sd[3], "-"),
            v("rmse", f.rmse, f64::NAN, "N m"),
            v("r2", f.r2, f64::NAN, "-"),
        ]);
        data.friction[side] = map;
        changed.push(format!("axle_friction_{name}.csv"));
        all_pts.push((side, pts, f));
    }
    rep.h2("Fit (thesis table 5.7)");
    rep.table(
        &[
            "side",
            "f_t [N m]",
            "k [N m/rpm]",
            "w_t [rpm]",
            "drag scale d",
            "RMSE",
            "r²",
            "χ²/dof",
            "points",
            "base map RMSE",
        ],
        &rows,
    );
    rep.para(&format!(
        "{zero} zero-load plateau(s) of {} in all. Thesis table 5.7 for comparison: RMSE 1.7583 N m (r² 0.9882) L, \
         2.2156 N m (r² 0.9857) R. The load torque map is not changed here (identify it with `load-maps`, \
         with this output as --data-dir).",
        ex.plateaus.len()
    ));
    rep.h2("Plateaus");
    let mut prow = Vec::new();
    for (side, pts, f) in &all_pts {
        for p in pts {
            let pl = &ex.plateaus[p.plateau];
            prow.push(vec![
                ["L", "R"][*side].to_string(),
                ctx.runs.get(pl.run).map_or("?".into(), |r| r.name.clone()),
                format!("{:.1}–{:.1}", pl.t0, pl.t1),
                sp_str(&pl.sp),
                pm(p.w, pl.stats[2 + side].rms),
                pm(p.c, pl.stats[*side].rms),
                num(p.drag * f.d),
                num(p.c - law(p.w, f.f_t, f.k, f.w_t) - f.d * p.drag),
            ]);
        }
    }
    rep.table(
        &[
            "side",
            "run",
            "t [s]",
            "set points [%]",
            "speed [rpm] (± rms)",
            "torque [N m] (± rms)",
            "drag [N m]",
            "residual [N m]",
        ],
        &prow,
    );
    campaign_section(&mut rep, ctx.runs, &ex);
    Ok(Identification { data, changed, report: rep, fits: Vec::new(), values })
}

fn plot(rep: &mut Report, name: &str, pts: &[Point], f: &FrictionFit, map: &Map1, base: &Map1, w_max: f64) {
    let x: Vec<f64> = pts.iter().map(|p| p.w).collect();
    let y: Vec<f64> = pts.iter().map(|p| p.c - f.d * p.drag).collect();
    let e: Vec<f64> = pts.iter().map(|p| 2.0 * p.sd_c).collect();
    let lim = 1.1 * w_max;
    let keep = |m: &Map1| -> (Vec<f64>, Vec<f64>) {
        m.x.iter()
            .zip(&m.y)
            .filter(|(x, _)| f64::from(x.abs()) <= lim)
            .map(|(x, y)| (f64::from(*x), f64::from(*y)))
            .unzip()
    };
    let (mx, my) = keep(map);
    let (bx, by) = keep(base);
    rep.plot(
        &format!("friction_{name}.svg"),
        &format!("friction {name}"),
        xy_chart(
            &format!("Axle friction {name}: flange torque − drag vs flange speed (± 2 s.e.)"),
            "axle speed [rpm]",
            "torque [N m]",
            &[XyPoints { x: &x, y: &y, err: Some(&e), color: PALETTE[0], label: "plateaus" }],
            &[
                XyLine { x: &mx, y: &my, color: PALETTE[1], label: "identified map", dashed: false },
                XyLine { x: &bx, y: &by, color: "#888", label: "base map", dashed: true },
            ],
        ),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pts(f_t: f64, k: f64, w_t: f64, d: f64) -> Vec<Point> {
        let ws = [
            -45.0, -30.0, -20.0, -12.0, -8.0, -3.0, 0.0, 6.0, 18.0, 25.0, 40.0, 90.0, 150.0, 190.0, 190.0,
            190.0,
        ];
        ws.iter()
            .enumerate()
            .map(|(j, w)| {
                let drag = if j >= 13 { 0.6667 * (j - 12) as f64 } else { 0.0 };
                Point { w: *w, c: law(*w, f_t, k, w_t) + d * drag, sd_w: 0.05, sd_c: 0.02, drag, plateau: j }
            })
            .collect()
    }

    #[test]
    fn identify_friction_law_is_odd_and_smooth() {
        for w in [-50.0, -20.0, -3.0, 0.5, 19.999, 20.0, 20.001, 70.0] {
            assert!((law(w, 8.0, 0.09, 20.0) + law(-w, 8.0, 0.09, 20.0)).abs() < 1e-12);
        }
        // The base map's L curve: 8 N m at 20 rpm, 0.09 N m/rpm, 1.1069 at 2 rpm.
        assert!((law(2.0, 8.0, 0.09, 20.0) - 1.1069).abs() < 1e-4);
        assert!((law(20.0 - 1e-9, 8.0, 0.09, 20.0) - law(20.0 + 1e-9, 8.0, 0.09, 20.0)).abs() < 1e-6);
        assert!((slope(20.0 - 1e-9, 8.0, 0.09, 20.0) - 0.09).abs() < 1e-6);
        let h = 1e-6;
        let num_d = (law(7.0, 8.0, 0.09, 20.0 + h) - law(7.0, 8.0, 0.09, 20.0 - h)) / (2.0 * h);
        assert!((num_d - d_wt(7.0, 8.0, 0.09, 20.0)).abs() < 1e-6);
    }

    #[test]
    fn identify_friction_fit_recovers_the_threshold_and_drag() {
        let f = fit(&pts(9.6, 0.108, 30.0, 0.9)).unwrap();
        assert!((f.w_t - 30.0).abs() < 0.01, "{f:?}");
        assert!(
            (f.f_t - 9.6).abs() < 1e-3 && (f.k - 0.108).abs() < 1e-5 && (f.d - 0.9).abs() < 1e-3,
            "{f:?}"
        );
        assert!(f.drag_fitted && f.r2 > 0.9999 && f.rmse < 1e-3);
        assert!(fit(&pts(9.6, 0.108, 30.0, 0.9)[..3]).is_none());
        // Nothing below the threshold: the linear part is still measured, the
        // threshold is reported undetermined.
        let fast: Vec<Point> = pts(9.6, 0.108, 30.0, 0.9).into_iter().filter(|p| p.w.abs() >= 40.0).collect();
        let f = fit(&fast).unwrap();
        assert!(f.sd[2].is_nan() && (f.w_t - 20.0).abs() < 1e-9, "{f:?}");
        assert!(
            (f.k - 0.108).abs() < 1e-6 && (f.f_t - f.k * f.w_t - (9.6 - 0.108 * 30.0)).abs() < 1e-4,
            "{f:?}"
        );
    }

    #[test]
    fn identify_friction_table_keeps_the_end_step() {
        let base = simrod_io::datadir::ModelData::builtin().unwrap().friction[0].clone();
        let f = fit(&pts(9.6, 0.108, 30.0, 1.0)).unwrap();
        let (m, notes) = table(&f, &base, 190.0, "test".into());
        let t = model_core::table::Table1::new(&m.x, &m.y).unwrap();
        assert!((f64::from(t.eval(100.0)) - law(100.0, 9.6, 0.108, 30.0)).abs() < 1e-3);
        assert!((f64::from(t.eval(-15.0)) + law(15.0, 9.6, 0.108, 30.0)).abs() < 0.05);
        // Step from 200 to 205 rpm as in the base (+10.45 N m).
        let step = t.eval(205.0) - t.eval(200.0);
        assert!((step - 10.45).abs() < 1e-3, "{step}");
        assert!(notes.iter().any(|n| n.contains("end step")), "{notes:?}");
        assert_eq!(m.x.len(), m.y.len());
        assert!(m.x.windows(2).all(|w| w[1] > w[0]));
    }
}
