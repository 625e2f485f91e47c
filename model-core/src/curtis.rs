//! Curtis 1232E/SE speed-mode rate logic (thesis 5.6, fig. A.3 / 5.50).
//!
//! The speed command moves towards the target at a rate chosen by the case (full,
//! partial or low acceleration; neutral or partial deceleration). A rate parameter of
//! `t` seconds means `Typical Max Speed / t` rpm/s. Between the LS and HS thresholds
//! (percent of Typical Max Speed, on the actual motor speed) the LS and HS ramp rates
//! blend linearly; partial acceleration blends linearly (in rpm/s) between the Low
//! Accel Rate at the low-throttle threshold and the Accel Rate at full throttle.

use crate::num::{clamp, Real};
use crate::params::Params;
use crate::throttle::dir_index;

/// Which branch of the switching logic is active; reported as an output channel so a
/// comparison can split errors by controller state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum RateCase {
    /// Command equals the target.
    Hold = 0,
    FullAccel = 1,
    PartialAccel = 2,
    LowAccel = 3,
    NeutralDecel = 4,
    PartialDecel = 5,
}

/// Multipliers on the ramp rates, `[accel, decel]` per direction `[fwd, rev]`
/// (the `inverter_rate_scale` effect; 1 = as parameterised).
pub type RateScale<R = f32> = [[R; 2]; 2];

/// A rate parameter of `seconds` s in rpm/s (0 for a parameter not above 0).
fn rpm_per_s(p: &Params, seconds: f32) -> f32 {
    if seconds > 0.0 {
        p.typical_max_speed_rpm / seconds
    } else {
        0.0
    }
}

/// One direction's rates [rpm/s] `[HS, LS]` where they blend, its HS/LS thresholds [%],
/// and the effect's `[accel, decel]` multipliers.
#[derive(Debug, Clone, Copy)]
struct DirRamp<R: Real> {
    ls_pct: R,
    /// `hs − ls` as a divisor, where HS is above LS (else the rates switch at LS).
    blend: Option<R::Divisor>,
    accel: [R; 2],
    low_accel: R,
    neutral_decel: [R; 2],
    partial_decel: R,
    scale: [R; 2],
}

/// The rate logic's coefficients, computed once at construction (every quotient of
/// parameters; for f32 the same operations the step used to repeat, so the same bits).
#[derive(Debug, Clone, Copy)]
pub struct Ramp<R: Real = f32> {
    dir: [DirRamp<R>; 2],
    /// Typical Max Speed [rpm], as a divisor: the thresholds are percent of it.
    per_typical: R::Divisor,
    hundred: R,
    full_pct: R,
    low_pct: R,
    /// Full minus low throttle threshold [%], as a divisor.
    per_partial: R::Divisor,
}

impl<R: Real> Ramp<R> {
    /// The coefficients for parameters `p` and the rate multipliers `scale`.
    pub fn new(p: &Params, scale: &RateScale) -> Self {
        let dir = |d: usize| {
            let r = p.rates.dir[d];
            let both = |hs: f32, ls: f32| [R::lit(rpm_per_s(p, hs)), R::lit(rpm_per_s(p, ls))];
            DirRamp {
                ls_pct: R::lit(r.ls_pct),
                blend: (r.hs_pct > r.ls_pct).then(|| R::divisor(R::lit(r.hs_pct - r.ls_pct))),
                accel: both(r.accel_hs_s, r.accel_ls_s),
                low_accel: R::lit(rpm_per_s(p, r.low_accel_s)),
                neutral_decel: both(r.neutral_decel_hs_s, r.neutral_decel_ls_s),
                partial_decel: R::lit(rpm_per_s(p, r.partial_decel_s)),
                scale: scale[d].map(R::lit),
            }
        };
        Self {
            dir: [dir(0), dir(1)],
            per_typical: R::divisor(R::lit(p.typical_max_speed_rpm)),
            hundred: R::lit(100.0),
            full_pct: R::lit(p.full_throttle_pct),
            low_pct: R::lit(p.low_throttle_pct),
            per_partial: R::divisor(R::lit(p.full_throttle_pct - p.low_throttle_pct)),
        }
    }

    /// The HS/LS blend of `[hs, ls]` rates at a motor speed [rpm].
    #[inline]
    fn blend(&self, r: &DirRamp<R>, speed_rpm: R, [hs, lo]: [R; 2]) -> R {
        let s =
            if speed_rpm < R::ZERO { -speed_rpm } else { speed_rpm }.div_by(self.per_typical) * self.hundred;
        let w = match r.blend {
            Some(span) => clamp((s - r.ls_pct).div_by(span), R::ZERO, R::ONE),
            None if s >= r.ls_pct => R::ONE,
            None => R::ZERO,
        };
        lo + w * (hs - lo)
    }

    /// Ramp rate [rpm/s] and case for the current throttle, target, command and speed.
    pub fn rate(&self, mapped_pct: R, target_rpm: R, cmd_rpm: R, speed_rpm: R) -> (R, RateCase) {
        if target_rpm == cmd_rpm {
            return (R::ZERO, RateCase::Hold);
        }
        let moving = if cmd_rpm != R::ZERO { cmd_rpm } else { target_rpm };
        let Some(r) = self.dir.get(dir_index(moving)) else {
            return (R::ZERO, RateCase::Hold);
        };
        let same_side = (target_rpm >= R::ZERO) == (cmd_rpm >= R::ZERO) || cmd_rpm == R::ZERO;
        let mag = |v: R| if v < R::ZERO { -v } else { v };
        let accelerating = same_side && mag(target_rpm) > mag(cmd_rpm);
        if accelerating {
            let acc = self.blend(r, speed_rpm, r.accel);
            let (rate, case) = if mapped_pct >= self.full_pct {
                (acc, RateCase::FullAccel)
            } else if mapped_pct <= self.low_pct {
                (r.low_accel, RateCase::LowAccel)
            } else {
                let f = (mapped_pct - self.low_pct).div_by(self.per_partial);
                (r.low_accel + f * (acc - r.low_accel), RateCase::PartialAccel)
            };
            (rate * r.scale[0], case)
        } else if mapped_pct <= R::ZERO {
            (self.blend(r, speed_rpm, r.neutral_decel) * r.scale[1], RateCase::NeutralDecel)
        } else {
            (r.partial_decel * r.scale[1], RateCase::PartialDecel)
        }
    }
}

/// Move `cmd` towards `target` by at most `rate * dt`.
#[inline]
pub fn advance<R: Real>(cmd_rpm: R, target_rpm: R, rate_rpm_s: R, dt_s: R) -> R {
    let max = rate_rpm_s * dt_s;
    cmd_rpm + clamp(target_rpm - cmd_rpm, -max, max)
}

/// [`advance`] on a compensated command `hi + lo`: a ramp adds a small increment every
/// step, whose low bits plain f32 would drop with a bias (a drift of ~1 rpm over a slow
/// ramp at 100 µs). Reaching the target sets it exactly.
#[inline]
pub fn advance_compensated<R: Real>(hi: R, lo: R, target_rpm: R, rate_rpm_s: R, dt_s: R) -> (R, R) {
    let max = rate_rpm_s * dt_s;
    let gap = target_rpm - hi;
    if gap <= max && gap >= -max {
        return (target_rpm, R::ZERO);
    }
    let step = clamp(gap, -max, max) + lo;
    R::two_sum(hi, step)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{CouplingStiffness, RateSet};

    const ONE: RateScale = [[1.0, 1.0], [1.0, 1.0]];

    #[test]
    fn cases_and_rates_identified() {
        let p = Params::thesis(RateSet::Identified, CouplingStiffness::Identified);
        let (r, c) = Ramp::new(&p, &ONE).rate(100.0, 2100.0, 500.0, 500.0);
        assert_eq!(c, RateCase::FullAccel);
        assert!((r - 3300.0 / 3.9845).abs() < 1e-3);
        let (r, c) = Ramp::new(&p, &ONE).rate(5.0, 300.0, 0.0, 0.0);
        assert_eq!(c, RateCase::LowAccel);
        assert!((r - 3300.0 / 32.0).abs() < 1e-3);
        let (_, c) = Ramp::new(&p, &ONE).rate(50.0, 1400.0, 200.0, 200.0);
        assert_eq!(c, RateCase::PartialAccel);
        // Neutral deceleration below LS (40 % of 3300 = 1320 rpm): LS rate.
        let (r, c) = Ramp::new(&p, &ONE).rate(0.0, 0.0, 1000.0, 1000.0);
        assert_eq!(c, RateCase::NeutralDecel);
        assert!((r - 3300.0 / 3.1399).abs() < 1e-3);
        // Halfway between LS (1320) and HS (2310): halfway between the rates.
        let (r, _) = Ramp::new(&p, &ONE).rate(0.0, 0.0, 1815.0, 1815.0);
        let want = 0.5 * (3300.0 / 3.1399 + 3300.0 / 2.2693);
        assert!((r - want).abs() < 0.1, "{r} vs {want}");
        let (r, c) = Ramp::new(&p, &ONE).rate(30.0, 500.0, 1500.0, 1500.0);
        assert_eq!(c, RateCase::PartialDecel);
        assert!((r - 3300.0 / 9.9752).abs() < 1e-3);
        // Reverse uses the reverse rates.
        let (r, c) = Ramp::new(&p, &ONE).rate(100.0, -500.0, -100.0, -100.0);
        assert_eq!(c, RateCase::FullAccel);
        assert!((r - 3300.0 / 3.5125).abs() < 1e-3);
    }

    #[test]
    fn compensated_ramp_has_no_drift() {
        // 100 µs steps of a 330.8 rpm/s ramp from 2100 rpm, 2 s: exact end 1438.4 rpm.
        let (rate, dt) = (3300.0f32 / 9.9752, 1e-4f32);
        let (mut hi, mut lo, mut plain) = (2100.0f32, 0.0f32, 2100.0f32);
        for _ in 0..20_000 {
            (hi, lo) = advance_compensated(hi, lo, 0.0, rate, dt);
            plain = advance(plain, 0.0, rate, dt);
        }
        let exact = 2100.0 - 20_000.0 * f64::from(rate * dt);
        assert!((f64::from(hi) - exact).abs() < 1e-3, "compensated {hi} vs {exact}");
        assert!((f64::from(plain) - exact).abs() > 10.0 * (f64::from(hi) - exact).abs(), "plain {plain}");
    }

    #[test]
    fn advance_never_overshoots() {
        assert_eq!(advance(0.0, 5.0, 1000.0, 0.001), 1.0);
        assert_eq!(advance(4.5, 5.0, 1000.0, 0.001), 5.0);
        assert_eq!(advance(0.0, -5.0, 1000.0, 0.001), -1.0);
    }
}
