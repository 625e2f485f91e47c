//! Throttle steps and the speed transients after them, shared by `identify inertia` and
//! `identify inverter-rates` (thesis 5.3.2 and 5.6: "transient regions (throttle
//! steps) are identified and starting/final speed steady-state values are extracted").
//!
//! A run is cut into intervals of constant throttle set point (at least 1 s). An
//! interval that starts with a *step* (not an interpolated ramp) is a candidate
//! transient: the speed before the step (end of the previous interval), the speed at
//! the end of the interval, and the part in between where the speed ramps at the rate
//! the controller chose. That part starts 0.2 s after the step (half the 0.1 s counting
//! window of the bench's speed channels, and the speed loop catching up with the
//! command: its lag still shrinks, steepening the slope by a few %, at 0.1 s in the
//! twin, by < 0.5 % from 0.2 s on) and ends 0.08 s before the
//! speed comes within 10 % of the step (or 3 speed quanta) of its final value.
//! Small helpers (channel look-up with clear errors, linear fits) live here too; the
//! statistics are in [`simrod_numerics::stats`].

use model_core::{Maps, Params};

use simrod_io::error::FileError;
use simrod_io::measure::{Measurement, Signal, SETPOINT_THROTTLE};
use simrod_numerics::stats::{mean, median, median_filter};

/// Shortest constant-throttle interval considered [s].
pub const MIN_INTERVAL_S: f64 = 1.0;
/// Dead time after a step before the speed ramps at its rate [s].
pub const RAMP_LAG_S: f64 = 0.2;
/// Margin before the end of the ramp [s].
pub const RAMP_TAIL_S: f64 = 0.08;
/// Shortest usable ramp [s].
pub const MIN_RAMP_S: f64 = 0.1;

/// The signal named by any of `names` (first match; MAT files turn `:` into `_`).
pub fn find<'a>(m: &'a Measurement, names: &[&str]) -> Option<&'a Signal> {
    names.iter().find_map(|n| m.signal(n))
}

/// The values of a required channel, or an error naming file, channel and purpose.
pub fn require<'a>(m: &'a Measurement, names: &[&str], purpose: &str) -> Result<&'a [f64], FileError> {
    let s = find(m, names).ok_or_else(|| {
        let alts = if names.len() > 1 { format!(" (or {})", names[1..].join(", ")) } else { String::new() };
        FileError::whole(
            &m.source,
            format!(
                "missing channel `{}`{alts}, needed for {purpose}",
                names.first().copied().unwrap_or("?")
            ),
        )
    })?;
    if s.values.len() != m.time_s.len() {
        return Err(FileError::whole(
            &m.source,
            format!("channel `{}` has {} samples, time has {}", s.name, s.values.len(), m.time_s.len()),
        ));
    }
    if let Some(k) = s.values.iter().position(|v| !v.is_finite()) {
        return Err(FileError::whole(
            &m.source,
            format!("channel `{}`: sample {} (t = {} s) is not a finite number", s.name, k + 1, m.time_s[k]),
        ));
    }
    Ok(&s.values)
}

/// Sample interval of a run [s] (the readers put runs on a uniform grid).
pub fn sample_dt(m: &Measurement) -> Result<f64, FileError> {
    let t = &m.time_s;
    if t.len() < 2 {
        return Err(FileError::whole(&m.source, "fewer than 2 samples"));
    }
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(FileError::whole(&m.source, "time does not increase"));
    }
    Ok(dt)
}

/// The signed throttle set point [%] per sample, and the tolerance within which it
/// counts as constant. From the PLC's set-point channel if the run has it (exact), else
/// from the `Throttle` voltage (`|sp| = V / volts_per_pct`, median-filtered; the sign,
/// which the voltage does not carry, from the direction of the motor speed).
pub fn throttle_pct(m: &Measurement, p: &Params, motor_rpm: &[f64]) -> Result<(Vec<f64>, f64), FileError> {
    if m.signal(SETPOINT_THROTTLE).is_some() {
        let v = require(m, &[SETPOINT_THROTTLE], "the throttle steps")?;
        return Ok((v.to_vec(), 0.05));
    }
    let v = require(m, &["Throttle"], "the throttle steps (no `SuT Throttle` set-point channel either)")?;
    let k = f64::from(p.throttle_volts_per_pct);
    if k.is_nan() || k <= 0.0 {
        return Err(FileError::whole(&m.source, "throttle_volts_per_pct must be > 0"));
    }
    let med = median_filter(v, 10);
    let mut dir = 1.0;
    let out = med
        .iter()
        .zip(motor_rpm)
        .map(|(x, w)| {
            if w.abs() > 20.0 {
                dir = w.signum();
            }
            dir * x / k
        })
        .collect();
    Ok((out, 0.6))
}

/// Mapped throttle [%] for a signed set point, through the controller's input map.
pub fn mapped_pct(p: &Params, maps: &Maps<'_>, sp: f64) -> f64 {
    let volts = model_core::throttle::voltage(p, sp as f32);
    f64::from(maps.throttle_input.eval(volts))
}

/// A stretch of constant throttle set point: samples `start..end`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interval {
    pub start: usize,
    pub end: usize,
    /// [%] signed set point.
    pub throttle: f64,
}

/// Maximal stretches where the set point stays within `tol` of its first value, at
/// least `min_len` samples long.
pub fn steady_intervals(u: &[f64], tol: f64, min_len: usize) -> Vec<Interval> {
    let mut out = Vec::new();
    let mut a = 0;
    while a < u.len() {
        let u0 = u[a];
        let mut b = a + 1;
        while b < u.len() && (u[b] - u0).abs() <= tol {
            b += 1;
        }
        if b - a >= min_len.max(1) {
            out.push(Interval { start: a, end: b, throttle: u0 });
        }
        a = b;
    }
    out
}

/// A speed transient after a throttle step.
#[derive(Debug, Clone, PartialEq)]
pub struct Transient {
    /// Index of its interval in the run's [`steady_intervals`].
    pub interval: usize,
    /// First sample of the new set point.
    pub step: usize,
    /// End of the constant-throttle interval (exclusive).
    pub end: usize,
    /// [%] set point before and after the step.
    pub before: f64,
    pub after: f64,
    /// [rpm] motor speed just before the step and at the end of the interval.
    pub s0: f64,
    pub s1: f64,
    /// The speed was steady before the step / at the end of the interval.
    pub settled_before: bool,
    pub settled_after: bool,
    /// Samples `ramp.0..ramp.1` where the speed moves at its controlled rate.
    pub ramp: (usize, usize),
    /// |speed| grows.
    pub accel: bool,
    /// 0 forward, 1 reverse.
    pub dir: usize,
}

/// Least-squares line `y = a + b x`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    pub intercept: f64,
    pub slope: f64,
    /// Standard error of the slope (white residuals).
    pub se_slope: f64,
    /// Residual standard deviation.
    pub resid_sd: f64,
    pub x_mean: f64,
}

impl Line {
    pub fn at(&self, x: f64) -> f64 {
        self.intercept + self.slope * x
    }
}

/// Fit a line; `None` with fewer than 3 points or no spread in `x`.
pub fn line_fit(x: &[f64], y: &[f64]) -> Option<Line> {
    let n = x.len().min(y.len());
    if n < 3 {
        return None;
    }
    let nf = n as f64;
    let mx = x[..n].iter().sum::<f64>() / nf;
    let my = y[..n].iter().sum::<f64>() / nf;
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (a, b) in x[..n].iter().zip(&y[..n]) {
        sxx += (a - mx) * (a - mx);
        sxy += (a - mx) * (b - my);
    }
    if sxx.is_nan() || sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let ss: f64 = x[..n].iter().zip(&y[..n]).map(|(a, b)| (b - intercept - slope * a).powi(2)).sum();
    let resid_sd = (ss / (nf - 2.0)).sqrt();
    Some(Line { intercept, slope, se_slope: resid_sd / sxx.sqrt(), resid_sd, x_mean: mx })
}

/// The resolution of a (possibly pulse-counted) speed channel: the median size of the
/// non-zero sample-to-sample changes. For a counted speed this is one pulse per window.
pub fn quantum(v: &[f64]) -> f64 {
    let d: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]).abs()).filter(|x| *x > 1e-9).collect();
    median(&d).unwrap_or(0.0)
}

/// Is `v[a..b]` steady: the fitted change over the window within `tol`?
fn steady(t: &[f64], v: &[f64], a: usize, b: usize, tol: f64) -> bool {
    match line_fit(&t[a..b], &v[a..b]) {
        Some(l) => (l.slope * (t[b - 1] - t[a])).abs() <= tol,
        None => b > a,
    }
}

/// The transients of a run: one per interval that starts with a throttle step and in
/// which the motor speed `speed` [rpm] changes by more than the noise. Intervals that
/// cross zero speed (a reversal) are skipped. Notes say what was skipped and why.
pub fn find_transients(
    t: &[f64],
    intervals: &[Interval],
    speed: &[f64],
    dt: f64,
) -> (Vec<Transient>, Vec<String>) {
    let mut out = Vec::new();
    let mut notes = Vec::new();
    let q = quantum(speed).max(1e-6);
    let secs = |s: f64| ((s / dt).round() as usize).max(1);
    for (i, w) in intervals.windows(2).enumerate() {
        let (prev, cur) = (w[0], w[1]);
        let at = t.get(cur.start).copied().unwrap_or(0.0);
        if cur.start > prev.end + secs(0.005) {
            continue; // reached by an interpolated ramp, not a step
        }
        let tail = secs(0.3).min(prev.end - prev.start);
        let s0 = mean(&speed[prev.end - tail..prev.end]);
        let end_win = secs(0.5).min(cur.end - cur.start);
        let s1 = mean(&speed[cur.end - end_win..cur.end]);
        let delta = s1 - s0;
        if delta.abs() < (5.0 * q).max(30.0) {
            continue; // no speed change worth a transient
        }
        if s0 * s1 < 0.0 && s0.abs() > 3.0 * q && s1.abs() > 3.0 * q {
            notes.push(format!("t = {at:.2} s: speed reverses ({s0:.0} -> {s1:.0} rpm); skipped"));
            continue;
        }
        let tol = |s: f64| (2.0 * q).max(0.02 * s.abs());
        let pre_win = secs(0.5).min(prev.end - prev.start);
        let settled_before = steady(t, speed, prev.end - pre_win, prev.end, tol(s0));
        let settled_after = steady(t, speed, cur.end - end_win, cur.end, tol(s1));
        let a = cur.start + secs(RAMP_LAG_S);
        let near = (0.1 * delta.abs()).max(3.0 * q);
        let reach = (a..cur.end).find(|&k| (speed[k] - s1).abs() < near).unwrap_or(cur.end);
        let b = reach.saturating_sub(secs(RAMP_TAIL_S));
        if b <= a || (b - a) < secs(MIN_RAMP_S) {
            notes.push(format!(
                "t = {at:.2} s: speed change {delta:.0} rpm too quick or too short to show a ramp; skipped"
            ));
            continue;
        }
        let accel = s1.abs() > s0.abs();
        let moving = if s1.abs() > s0.abs() { s1 } else { s0 };
        out.push(Transient {
            interval: i + 1,
            step: cur.start,
            end: cur.end,
            before: prev.throttle,
            after: cur.throttle,
            s0,
            s1,
            settled_before,
            settled_after,
            ramp: (a, b),
            accel,
            dir: usize::from(moving < 0.0),
        });
    }
    (out, notes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals_and_a_ramp_transient() {
        // 1 kHz: throttle 0 for 2 s, then 50 % for 6 s; speed ramps 0 -> 1000 rpm at
        // 500 rpm/s from 2.05 s, quantised to 10 rpm.
        let dt = 1e-3;
        let n = 8000;
        let t: Vec<f64> = (1..=n).map(|k| k as f64 * dt).collect();
        let u: Vec<f64> = t.iter().map(|t| if *t <= 2.0 { 0.0 } else { 50.0 }).collect();
        let s: Vec<f64> =
            t.iter().map(|t| ((500.0 * (t - 2.05)).clamp(0.0, 1000.0) / 10.0).round() * 10.0).collect();
        let iv = steady_intervals(&u, 0.05, 1000);
        assert_eq!(iv.len(), 2);
        assert_eq!((iv[1].start, iv[1].throttle), (2000, 50.0));
        let (tr, notes) = find_transients(&t, &iv, &s, dt);
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(tr.len(), 1);
        let x = &tr[0];
        assert!(x.accel && x.dir == 0 && x.settled_before && x.settled_after);
        assert!((x.s1 - 1000.0).abs() < 1e-9 && x.s0.abs() < 1e-9);
        // The ramp stays inside the constant-rate part.
        assert!(t[x.ramp.0] >= 2.2 - 1e-9 && t[x.ramp.1] <= 3.85, "{:?}", x.ramp);
        let l = line_fit(&t[x.ramp.0..x.ramp.1], &s[x.ramp.0..x.ramp.1]).unwrap();
        assert!((l.slope - 500.0).abs() < 5.0, "{}", l.slope);
    }

    #[test]
    fn no_transient_without_a_speed_change() {
        let t: Vec<f64> = (1..=5000).map(|k| k as f64 * 1e-3).collect();
        let u: Vec<f64> = t.iter().map(|t| if *t < 2.0 { 0.0 } else { 20.0 }).collect();
        let s = vec![0.0; t.len()];
        let iv = steady_intervals(&u, 0.05, 1000);
        assert_eq!(iv.len(), 2);
        assert!(find_transients(&t, &iv, &s, 1e-3).0.is_empty());
    }

    #[test]
    fn speed_quantum() {
        assert_eq!(quantum(&[0.0, 0.0, 10.0, 10.0, 20.0]), 10.0);
        assert_eq!(quantum(&[5.0, 5.0]), 0.0);
    }
}
