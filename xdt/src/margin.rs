//! The XiL loop's delay margin: the largest loop delay at which the closed loop stays
//! stable and inside the torque flange's rating.
//!
//! **Instability criterion** (on the flange torques `C_Kistler_L/R`, the quantity that
//! breaks a flange): the torque's oscillating part, the torque minus its centred moving
//! mean over [`Criterion::detrend_s`] (a cycle's ramps cancel exactly, an oscillation
//! above `1 / detrend_s` passes), has an envelope per window of [`Criterion::window_s`]
//! (the largest |oscillating part| of either side). The loop is **unstable** when that
//! envelope grows in [`Criterion::rising_windows`] consecutive windows or more, by a
//! factor of at least [`Criterion::growth`] over the run (from no less than 5 % of the
//! floor), to at least [`Criterion::floor_nm`]: a growing oscillation; or when the
//! envelope stays at or above the floor, each window within 10 % of the one before, for
//! [`Criterion::sustained_windows`] windows: an
//! oscillation that grew within a window or two into a limit cycle (the load motors'
//! 80 N m saturate it). A one-off transient (a cycle's corner) rises in one window and
//! decays after it, so it counts as neither. The loop is
//! **outside its limits** when a flange torque reaches [`Criterion::rating_nm`]
//! (Kistler 4550A200: 200 N m) or a channel is not finite. A run stops at the first
//! verdict.
//!
//! **Search.** The delay is swept by bisection between 0 and [`DELAY_CAPACITY`] twin
//! steps, assuming one crossing (stable below, not above; the example
//! `xil_delay_margin` prints a sweep that shows it). The margin found is the largest
//! delay judged stable *on that cycle*: close to the crossing an oscillation grows too
//! slowly to reach the criterion within the cycle, so the margin is an upper estimate
//! by up to the step of delay at which growth becomes visible in the cycle's length.

use model_core::{Channel, Config, Maps};

use crate::cycle::Route;
use crate::vehicle::Vehicle;
use crate::xdt::XdtTuning;
use crate::xil::{Timing, XilError, XilLoop, DELAY_CAPACITY};

/// Samples of the centred moving mean (odd, covers up to 0.5 s at 1 ms).
const RING: usize = 501;
/// Window envelopes kept for the report.
pub const HISTORY: usize = 16;

/// The instability criterion's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Criterion {
    /// [s] length of the moving mean taken off the torque.
    pub detrend_s: f32,
    /// [s] envelope window.
    pub window_s: f32,
    /// Consecutive rising windows that make a growing oscillation.
    pub rising_windows: u32,
    /// [-] growth of the envelope over those windows.
    pub growth: f32,
    /// [N m] envelope the oscillation must reach.
    pub floor_nm: f32,
    /// Windows at or above the floor in a row, none falling by more than 10 %, that make
    /// a sustained oscillation.
    pub sustained_windows: u32,
    /// [N m] flange rating.
    pub rating_nm: f32,
}

impl Default for Criterion {
    /// 0.1 s mean (passes oscillations above 10 Hz whole, at 5 Hz about half), 0.5 s
    /// windows, 3 rises by 4x in all to 10 N m (5 % of the rating), or 10 N m held for
    /// 4 windows (2 s); rating 200 N m.
    fn default() -> Self {
        Self {
            detrend_s: 0.1,
            window_s: 0.5,
            rising_windows: 3,
            growth: 4.0,
            floor_nm: 10.0,
            sustained_windows: 4,
            rating_nm: 200.0,
        }
    }
}

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    /// The whole cycle, neither growing nor over the rating.
    Stable,
    /// A growing oscillation: at time [s], by this factor over the rising run.
    Growing { at_s: f64, growth: f32 },
    /// An oscillation held at or above the floor: at time [s], its envelope [N m].
    Sustained { at_s: f64, envelope_nm: f32 },
    /// A flange torque reached the rating: at time [s], the torque [N m].
    OverRating { at_s: f64, torque_nm: f32 },
    /// A channel left the finite numbers at time [s].
    NonFinite { at_s: f64 },
}

/// The judgement of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Verdict {
    pub outcome: Outcome,
    /// [N m] largest |flange torque| seen.
    pub peak_nm: f32,
    /// [-] largest growth of the envelope over a rising run.
    pub max_growth: f32,
    /// [N m] largest window envelope.
    pub max_envelope_nm: f32,
    /// [N m] the last window envelopes, oldest first (`n_history` of them valid).
    pub history: [f32; HISTORY],
    pub n_history: usize,
    /// [s] the time the first kept window starts.
    pub history_start_s: f64,
}

impl Verdict {
    /// Stable and inside the rating.
    pub fn is_stable(&self) -> bool {
        self.outcome == Outcome::Stable
    }

    /// The kept window envelopes, oldest first.
    pub fn envelopes(&self) -> &[f32] {
        self.history.get(..self.n_history).unwrap_or(&[])
    }
}

/// The streaming envelope of the flange torques' oscillating part (the criterion above,
/// fed one step at a time: [`judge`] uses it, and so can a caller that also writes the
/// run).
#[derive(Debug, Clone)]
pub struct Envelope {
    c: Criterion,
    half: usize,
    window: u32,
    ring: [[f32; RING]; 2],
    head: usize,
    filled: usize,
    sum: [f64; 2],
    in_window: u32,
    cur: f32,
    last: f32,
    rises: u32,
    run_start: f32,
    max_growth: f32,
    max_envelope: f32,
    above_floor: u32,
    history: [f32; HISTORY],
    n_history: usize,
    windows: u64,
}

/// What closing a window found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Found {
    /// A growing oscillation, by this factor over its rising run.
    Growing(f32),
    /// An oscillation held at this envelope [N m].
    Sustained(f32),
}

impl Envelope {
    /// For a twin step of `dt_s` [s].
    pub fn new(c: Criterion, dt_s: f64) -> Self {
        let half = ((f64::from(c.detrend_s) / dt_s * 0.5) as usize).clamp(1, RING / 2);
        let window = ((f64::from(c.window_s) / dt_s + 0.5) as u32).max(1);
        Self {
            c,
            half,
            window,
            ring: [[0.0; RING]; 2],
            head: 0,
            filled: 0,
            sum: [0.0; 2],
            in_window: 0,
            cur: 0.0,
            last: 0.0,
            rises: 0,
            run_start: 0.0,
            max_growth: 1.0,
            max_envelope: 0.0,
            above_floor: 0,
            history: [0.0; HISTORY],
            n_history: 0,
            windows: 0,
        }
    }

    /// [N m] the largest window envelope so far.
    pub fn max_envelope_nm(&self) -> f32 {
        self.max_envelope
    }

    /// Take one step's flange torques; `Some` when a window closes with a growing or
    /// sustained oscillation.
    pub fn push(&mut self, torque: [f32; 2]) -> Option<Found> {
        let len = 2 * self.half + 1;
        let mut dev = 0.0f32;
        for (side, t) in torque.iter().enumerate() {
            let (Some(ring), Some(sum)) = (self.ring.get_mut(side), self.sum.get_mut(side)) else { continue };
            let slot = self.head;
            if self.filled >= len {
                let old = ring.get((slot + RING - len) % RING).copied().unwrap_or(0.0);
                *sum -= f64::from(old);
            }
            if let Some(s) = ring.get_mut(slot) {
                *s = *t;
            }
            *sum += f64::from(*t);
            if self.filled + 1 >= len {
                let mid = ring.get((slot + RING - self.half) % RING).copied().unwrap_or(0.0);
                let d = (f64::from(mid) - *sum / len as f64).abs() as f32;
                dev = dev.max(d);
            }
        }
        self.head = (self.head + 1) % RING;
        self.filled = (self.filled + 1).min(RING);
        self.cur = self.cur.max(dev);
        self.in_window += 1;
        if self.in_window < self.window {
            return None;
        }
        self.close_window()
    }

    fn close_window(&mut self) -> Option<Found> {
        let e = self.cur;
        (self.in_window, self.cur) = (0, 0.0);
        self.windows += 1;
        if self.n_history < HISTORY {
            self.n_history += 1;
        } else {
            self.history.copy_within(1.., 0);
        }
        if let Some(h) = self.history.get_mut(self.n_history - 1) {
            *h = e;
        }
        self.max_envelope = self.max_envelope.max(e);
        // A run starts from no less than 5 % of the floor: growth out of round-off noise
        // is no growth.
        let base = 0.05 * self.c.floor_nm;
        if e > self.last && self.windows > 1 {
            self.rises += 1;
        } else {
            (self.rises, self.run_start) = (0, if e > base { e } else { base });
        }
        // Held: at or above the floor and not decaying (each window within 10 % of the
        // last): a decaying ring-down, however large, is not a limit cycle.
        self.above_floor = match (e >= self.c.floor_nm, e >= 0.9 * self.last) {
            (true, true) => self.above_floor + 1,
            (true, false) => 1,
            (false, _) => 0,
        };
        self.last = e;
        let growth = e / self.run_start;
        if self.rises >= self.c.rising_windows {
            self.max_growth = self.max_growth.max(growth);
            if growth >= self.c.growth && e >= self.c.floor_nm {
                return Some(Found::Growing(growth));
            }
        }
        if self.above_floor >= self.c.sustained_windows {
            return Some(Found::Sustained(e));
        }
        None
    }
}

/// Run `lp` to the end of its cycle or to the first sign of instability.
pub fn judge(mut lp: XilLoop<'_>, c: Criterion) -> Verdict {
    let dt_s = f64::from(lp.model().dt_us()) * 1e-6;
    let mut env = Envelope::new(c, dt_s);
    let mut peak = 0.0f32;
    let mut outcome = Outcome::Stable;
    while let Some(o) = lp.step() {
        let t = [o.bench.get(Channel::CKistlerL), o.bench.get(Channel::CKistlerR)];
        let at_s = o.bench.t_s();
        if o.bench.non_finite().is_some() {
            outcome = Outcome::NonFinite { at_s };
            break;
        }
        let m = t[0].abs().max(t[1].abs());
        peak = peak.max(m);
        if m >= c.rating_nm {
            outcome = Outcome::OverRating { at_s, torque_nm: m };
            break;
        }
        match env.push(t) {
            Some(Found::Growing(growth)) => {
                outcome = Outcome::Growing { at_s, growth };
                break;
            }
            Some(Found::Sustained(envelope_nm)) => {
                outcome = Outcome::Sustained { at_s, envelope_nm };
                break;
            }
            None => {}
        }
    }
    let n = env.n_history;
    let first_kept = env.windows.saturating_sub(n as u64);
    Verdict {
        outcome,
        peak_nm: peak,
        max_growth: env.max_growth,
        max_envelope_nm: env.max_envelope,
        history: env.history,
        n_history: n,
        history_start_s: first_kept as f64 * f64::from(c.window_s),
    }
}

/// What [`delay_margin`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Margin {
    /// Largest stable delay [twin steps]; `None` when the loop is unstable without delay.
    pub stable_steps: Option<u32>,
    /// The smallest unstable delay found [twin steps] and its verdict; `None` when even
    /// [`DELAY_CAPACITY`] steps are stable (the margin is at least that).
    pub unstable: Option<(u32, Verdict)>,
    /// The verdict at the margin.
    pub at_margin: Option<Verdict>,
    /// Runs made.
    pub runs: u32,
}

/// The delay margin of the loop of a twin with `cfg` on `maps` and the xDT of `vehicle`
/// with `tuning` on `route`, sampled every `period` twin steps, at supply `supply_v`:
/// the largest loop delay (in twin steps, `cfg.dt_us` each) that is stable and inside
/// the flange rating under `criterion`, by bisection over 0..=[`DELAY_CAPACITY`]. For a
/// test-approval workflow: compare it with the RT platform's real delay times a safety
/// factor. Errors are the loop's configuration errors.
#[allow(clippy::too_many_arguments)]
pub fn delay_margin(
    cfg: &Config,
    maps: Maps<'_>,
    vehicle: &Vehicle,
    tuning: &XdtTuning,
    route: Route<'_>,
    period: u32,
    supply_v: f32,
    criterion: Criterion,
) -> Result<Margin, XilError> {
    let mut runs = 0;
    let mut run = |delay: u32| -> Result<Verdict, XilError> {
        let timing = Timing::new(period, delay).map_err(XilError::Timing)?;
        runs += 1;
        Ok(judge(XilLoop::new(cfg, maps, vehicle, tuning, route, timing, supply_v)?, criterion))
    };
    let at_zero = run(0)?;
    if !at_zero.is_stable() {
        return Ok(Margin { stable_steps: None, unstable: Some((0, at_zero)), at_margin: None, runs });
    }
    let cap = DELAY_CAPACITY as u32;
    let at_cap = run(cap)?;
    if at_cap.is_stable() {
        return Ok(Margin { stable_steps: Some(cap), unstable: None, at_margin: Some(at_cap), runs });
    }
    let (mut lo, mut hi) = ((0u32, at_zero), (cap, at_cap));
    while hi.0 - lo.0 > 1 {
        let mid = lo.0 + (hi.0 - lo.0) / 2;
        let v = run(mid)?;
        if v.is_stable() {
            lo = (mid, v);
        } else {
            hi = (mid, v);
        }
    }
    Ok(Margin { stable_steps: Some(lo.0), unstable: Some(hi), at_margin: Some(lo.1), runs })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn feed(env: &mut Envelope, amp: impl Fn(f64) -> f64, steps: usize) -> Option<(usize, Found)> {
        for k in 0..steps {
            let t = k as f64 * 1e-3;
            let c = (amp(t) * (2.0 * core::f64::consts::PI * 10.0 * t).sin() + 30.0 * t) as f32;
            if let Some(g) = env.push([c, 0.5 * c]) {
                return Some((k, g));
            }
        }
        None
    }

    #[test]
    fn a_growing_oscillation_is_found_and_a_decaying_one_is_not() {
        let c = Criterion::default();
        // 10 Hz on a ramp, growing 2x per second from 1 N m: 10 N m after 3.3 s.
        let mut env = Envelope::new(c, 1e-3);
        let (k, found) = feed(&mut env, |t| (t * core::f64::consts::LN_2).exp(), 20_000).expect("growing");
        assert!(
            matches!(found, Found::Growing(g) if g >= 4.0) && k > 3_000 && k < 6_000,
            "step {k}: {found:?}"
        );
        // A limit cycle at once (no rise to see): sustained, after 4 windows.
        let mut env = Envelope::new(c, 1e-3);
        let (k, found) = feed(&mut env, |_| 20.0, 20_000).expect("sustained");
        assert!(matches!(found, Found::Sustained(e) if e > 19.0) && k < 2_500, "step {k}: {found:?}");
        // The same oscillation decaying from 50 N m, and a ramp alone: never.
        let mut env = Envelope::new(c, 1e-3);
        assert_eq!(feed(&mut env, |t| 50.0 * (-t).exp(), 20_000), None);
        let mut env = Envelope::new(c, 1e-3);
        assert_eq!(feed(&mut env, |_| 0.0, 20_000), None);
        assert!(env.history.iter().all(|e| *e < 1e-3), "{:?}", env.history);
        // A step transient (one window up, then down) is not growth either.
        let mut env = Envelope::new(c, 1e-3);
        let step = |t: f64| if t > 2.0 { 60.0 * (-(t - 2.0) * 3.0).exp() } else { 0.0 };
        assert_eq!(feed(&mut env, step, 20_000), None);
    }
}
