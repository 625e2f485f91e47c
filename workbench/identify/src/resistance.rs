//! `identify resistance`: the busbar-to-inverter connector resistance (thesis 5.5, eq.
//! 5.5: `R = (V_DC_busbars − V_DC) / I_DC`).
//!
//! The thesis averaged per-plateau ratios, section by section, and got 0.0166 and
//! 0.0255 Ω. A ratio at a small current is mostly noise, and any probe offset between
//! the two voltage channels becomes `offset / I`, which explodes at low current and
//! differs between campaigns with different current ranges. Here the plateau means of
//! the drop (computed sample by sample, so the probes' noise averages out) are fitted
//! against the current by weighted least squares, `ΔV = R I + b`: the slope is the
//! resistance, the intercept absorbs a voltage-probe offset, and both come with their
//! standard uncertainty (errors in the current included, scaled up by the fit's
//! χ²/dof when the scatter exceeds the plateaus' own noise). The thesis method is
//! reported next to it, and the fit is repeated per section (loads 0 / loads on).

use super::plateau::Plateau;
use super::report::{campaign_section, num, pm, sp_str, xy_chart, Report, XyLine, XyPoints, PALETTE};
use super::run::DV_CONN;
use super::{Context, Identification};
use simrod_io::error::CmdError;
use simrod_numerics::linalg::{self, Row};

/// Plateaus under this |I_DC| [A] are left out of the thesis-style ratio average.
const RATIO_MIN_A: f64 = 5.0;

/// A fit of `ΔV = R I + b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResistanceFit {
    pub r: f64,
    pub r_sd: f64,
    pub b: f64,
    pub b_sd: f64,
    pub chi2_dof: f64,
    pub n: usize,
}

/// Fit over plateaus `(I, ΔV, sd_I, sd_ΔV)`; `None` with fewer than 3 plateaus or no
/// spread of current.
pub fn fit(points: &[(f64, f64, f64, f64)], r0: f64) -> Option<ResistanceFit> {
    let n = points.len();
    let (lo, hi) =
        points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    if n < 3 || (hi - lo).is_nan() || hi - lo <= 1.0 {
        return None;
    }
    let mut r = r0;
    let mut f = None;
    // Errors in the current enter through the slope: iterate the effective weights.
    for _ in 0..4 {
        let rows: Vec<Row> = points
            .iter()
            .map(|&(i, dv, si, sv)| Row {
                coef: vec![(0, i), (1, 1.0)],
                y: dv,
                sd: (sv * sv + r * r * si * si).sqrt().max(1e-12),
            })
            .collect();
        let fit = linalg::wls(&rows, 2, None)?;
        r = fit.x[0];
        f = Some(fit);
    }
    let f = f?;
    let dof = (n - 2).max(1) as f64;
    let scale = (f.chi2 / dof).max(1.0).sqrt();
    Some(ResistanceFit {
        r: f.x[0],
        r_sd: f.sd(0) * scale,
        b: f.x[1],
        b_sd: f.sd(1) * scale,
        chi2_dof: f.chi2 / dof,
        n,
    })
}

/// `simrod identify resistance`.
pub fn identify(ctx: &Context<'_>) -> Result<Identification, CmdError> {
    let ex = ctx.extract(&[DV_CONN, "I_DC"]);
    let pts: Vec<(f64, f64, f64, f64)> =
        ex.plateaus.iter().map(|p| (p.mean(1), p.mean(0), p.sem(1), p.sem(0))).collect();
    let r0 = f64::from(ctx.params().connector_resistance);
    let all = fit(&pts, r0).ok_or_else(|| {
        CmdError::Usage(format!(
            "resistance: {} usable plateau(s) (need 3 or more at different I_DC); {}",
            pts.len(),
            why_none(ctx, &ex)
        ))
    })?;
    let section = |loaded: bool| -> Option<ResistanceFit> {
        let p: Vec<_> =
            ex.plateaus.iter().zip(&pts).filter(|(pl, _)| is_loaded(pl) == loaded).map(|(_, x)| *x).collect();
        fit(&p, r0)
    };
    let ratios: Vec<f64> = pts.iter().filter(|p| p.0.abs() >= RATIO_MIN_A).map(|p| p.1 / p.0).collect();

    let mut data = ctx.base.clone();
    let comment = format!(
        "[ohm] identified by simrod identify resistance: {} from {} plateaus of {} runs (fit dV = R I + b; base {})",
        pm(all.r, all.r_sd),
        all.n,
        ctx.runs.len(),
        num(r0)
    );
    data.set_param("connector_resistance", all.r as f32, &comment);

    let mut rep = Report::new("simrod identify resistance");
    rep.para(
        "Connector resistance busbars → SuT inverter, `R = (V_DC_busbars − V_DC) / I_DC` (thesis eq. 5.5), \
         fitted over the steady plateaus as `ΔV = R·I_DC + b`. Uncertainties are one standard deviation.",
    );
    rep.h2("Result");
    let line = |name: &str, f: &Option<ResistanceFit>| match f {
        Some(f) => vec![
            name.to_string(),
            format!("{} Ω", pm(f.r, f.r_sd)),
            format!("{} V", pm(f.b, f.b_sd)),
            num(f.chi2_dof),
            f.n.to_string(),
        ],
        None => vec![name.to_string(), "-".into(), "-".into(), "-".into(), "too few plateaus".into()],
    };
    rep.table(
        &["plateaus", "R", "offset b", "χ²/dof", "n"],
        &[
            line("all (written)", &Some(all)),
            line("loads 0 (thesis section 2)", &section(false)),
            line("loads on (section 3)", &section(true)),
        ],
    );
    let (rm, rs) = mean_sd(&ratios);
    rep.para(&format!(
        "Thesis method (mean of the per-plateau ratios with |I_DC| ≥ {RATIO_MIN_A} A): {} Ω (sd {} over {} plateaus). \
         Base model: {} Ω. Written: `connector_resistance = {}` in parameters.toml.",
        num(rm),
        num(rs),
        ratios.len(),
        num(r0),
        simrod_io::datadir::fmt_f32(all.r as f32)
    ));
    let (x, y, e): (Vec<f64>, Vec<f64>, Vec<f64>) =
        pts.iter().fold((vec![], vec![], vec![]), |(mut x, mut y, mut e), p| {
            x.push(p.0);
            y.push(p.1);
            e.push(2.0 * p.3);
            (x, y, e)
        });
    let (lo, hi) = x.iter().fold((0.0f64, 0.0f64), |(a, b), v| (a.min(*v), b.max(*v)));
    let fx = [lo, hi];
    let fy = [all.b + all.r * lo, all.b + all.r * hi];
    let by = [r0 * lo, r0 * hi];
    rep.plot(
        "resistance.svg",
        "connector voltage drop vs current",
        xy_chart(
            "Connector drop vs I_DC (plateau means ± 2 s.e.)",
            "I_DC [A]",
            "V_DC_busbars − V_DC [V]",
            &[XyPoints { x: &x, y: &y, err: Some(&e), color: PALETTE[0], label: "plateaus" }],
            &[
                XyLine { x: &fx, y: &fy, color: PALETTE[1], label: "fit", dashed: false },
                XyLine { x: &fx, y: &by, color: "#888", label: "base R", dashed: true },
            ],
        ),
    );
    rep.h2("Plateaus");
    let rows: Vec<Vec<String>> = ex
        .plateaus
        .iter()
        .zip(&pts)
        .map(|(p, q)| {
            let name = ctx.runs.get(p.run).map_or("?", |r| r.name.as_str());
            let ratio = if q.0.abs() >= RATIO_MIN_A { num(q.1 / q.0) } else { "-".into() };
            vec![
                name.to_string(),
                format!("{:.1}–{:.1}", p.t0, p.t1),
                sp_str(&p.sp),
                pm(q.0, p.stats[1].rms),
                pm(q.1, p.stats[0].rms),
                ratio,
                num(q.1 - all.b - all.r * q.0),
            ]
        })
        .collect();
    rep.table(
        &["run", "t [s]", "set points [%]", "I_DC [A] (± rms)", "ΔV [V] (± rms)", "ΔV/I [Ω]", "residual [V]"],
        &rows,
    );
    campaign_section(&mut rep, ctx.runs, &ex);
    Ok(Identification {
        data,
        changed: vec!["parameters.toml: connector_resistance".into()],
        report: rep,
        fits: Vec::new(),
        values: vec![
            super::Value {
                name: "connector_resistance".into(),
                value: all.r,
                sd: all.r_sd,
                unit: "ohm".into(),
            },
            super::Value { name: "voltage_offset".into(), value: all.b, sd: all.b_sd, unit: "V".into() },
        ],
    })
}

fn is_loaded(p: &Plateau) -> bool {
    p.sp[1].abs() > 0.5 || p.sp[2].abs() > 0.5
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let sd = if v.len() > 1 {
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    } else {
        f64::NAN
    };
    (m, sd)
}

/// Why a campaign gave too few plateaus, for error messages.
pub fn why_none(ctx: &Context<'_>, ex: &super::plateau::Extraction) -> String {
    let mut parts: Vec<String> = ex
        .runs_without
        .iter()
        .take(5)
        .map(|(i, w)| format!("{}: {w}", ctx.runs.get(*i).map_or("?", |r| r.name.as_str())))
        .collect();
    if ex.runs_without.len() > 5 {
        parts.push(format!("... and {} more", ex.runs_without.len() - 5));
    }
    if parts.is_empty() {
        format!("{} plateau(s) found", ex.plateaus.len())
    } else {
        parts.join("; ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identify_resistance_fit_absorbs_a_probe_offset() {
        // dV = 0.025 I + 0.05 (a 50 mV probe offset), exact.
        let pts: Vec<_> =
            [2.0, 40.0, 90.0, 150.0, 210.0].iter().map(|i| (*i, 0.025 * i + 0.05, 0.01, 0.001)).collect();
        let f = fit(&pts, 0.02).unwrap();
        assert!((f.r - 0.025).abs() < 1e-9 && (f.b - 0.05).abs() < 1e-7, "{f:?}");
        // The thesis ratio would read 0.025 + 0.05 / I: 0.0501 at 2 A.
        assert!(fit(&pts[..2], 0.02).is_none());
        let same: Vec<_> = (0..5).map(|_| (10.0, 0.2, 0.01, 0.001)).collect();
        assert!(fit(&same, 0.02).is_none());
    }
}
