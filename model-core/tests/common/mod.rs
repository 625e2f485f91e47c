//! Helpers shared by the model-core integration tests.
#![allow(dead_code)]

use model_core::*;

/// One held set for `secs`, then (optionally) a second held set.
pub fn steps(sets: &[(f32, f32, f32)]) -> Vec<ProfileSet> {
    sets.iter()
        .map(|&(d, t, l)| ProfileSet {
            duration_s: d,
            throttle_pct: t,
            load_l_pct: l,
            load_r_pct: l,
            throttle_mode: SetMode::Hold,
            load_mode: SetMode::Hold,
        })
        .collect()
}

pub fn config(rates: RateSet, dt_us: u32) -> Config {
    Config { dt_us, params: Params::thesis(rates, CouplingStiffness::Identified), ..Config::default() }
}

/// Run a profile, returning all outputs.
pub fn run(cfg: &Config, sets: &[ProfileSet]) -> Vec<Outputs> {
    let p = Profile::new(sets, 1.0, 1.0).expect("valid profile");
    Simulation::new(cfg, p, 24.0).expect("valid config").collect()
}

pub fn series(out: &[Outputs], c: Channel) -> Vec<(f64, f32)> {
    out.iter().map(|o| (o.t_s(), o.get(c))).collect()
}

/// Mean of a channel over [t0, t1).
pub fn mean(out: &[Outputs], c: Channel, t0: f64, t1: f64) -> f32 {
    let v: Vec<f32> = out.iter().filter(|o| o.t_s() >= t0 && o.t_s() < t1).map(|o| o.get(c)).collect();
    v.iter().sum::<f32>() / v.len() as f32
}

/// Least-squares slope of `c` over the samples whose value lies between `lo` and `hi`
/// inside the time window [t0, t1).
pub fn slope_between(out: &[Outputs], c: Channel, lo: f32, hi: f32, t0: f64, t1: f64) -> f64 {
    let pts: Vec<(f64, f64)> = out
        .iter()
        .filter(|o| o.t_s() >= t0 && o.t_s() < t1)
        .map(|o| (o.t_s(), f64::from(o.get(c))))
        .filter(|(_, v)| *v >= f64::from(lo) && *v <= f64::from(hi))
        .collect();
    assert!(pts.len() > 50, "too few points between {lo} and {hi}: {}", pts.len());
    let n = pts.len() as f64;
    let mt = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let mv = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let cov: f64 = pts.iter().map(|p| (p.0 - mt) * (p.1 - mv)).sum();
    let var: f64 = pts.iter().map(|p| (p.0 - mt) * (p.0 - mt)).sum();
    cov / var
}
