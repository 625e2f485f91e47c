//! Curtis 1232E/SE speed-mode rate logic (thesis 5.6, fig. A.3 / 5.50).
//!
//! The speed command moves towards the target at a rate chosen by the case (full,
//! partial or low acceleration; neutral or partial deceleration). A rate parameter of
//! `t` seconds means `Typical Max Speed / t` rpm/s. Between the LS and HS thresholds
//! (percent of Typical Max Speed, on the actual motor speed) the LS and HS ramp rates
//! blend linearly; partial acceleration blends linearly (in rpm/s) between the Low
//! Accel Rate at the low-throttle threshold and the Accel Rate at full throttle.

use crate::num::{clamp, Real};
use crate::params::{DirectionRates, Params};
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

#[inline]
fn rpm_per_s<R: Real>(p: &Params<R>, seconds: R) -> R {
    if seconds > R::ZERO {
        p.typical_max_speed_rpm / seconds
    } else {
        R::ZERO
    }
}

#[inline]
fn hs_ls_blend<R: Real>(p: &Params<R>, r: &DirectionRates<R>, speed_rpm: R, hs_s: R, ls_s: R) -> R {
    let s =
        if speed_rpm < R::ZERO { -speed_rpm } else { speed_rpm } / p.typical_max_speed_rpm * R::lit(100.0);
    let w = if r.hs_pct > r.ls_pct {
        clamp((s - r.ls_pct) / (r.hs_pct - r.ls_pct), R::ZERO, R::ONE)
    } else if s >= r.ls_pct {
        R::ONE
    } else {
        R::ZERO
    };
    let lo = rpm_per_s(p, ls_s);
    lo + w * (rpm_per_s(p, hs_s) - lo)
}

/// Ramp rate [rpm/s] and case for the current throttle, target, command and speed.
pub fn ramp_rate<R: Real>(
    p: &Params<R>,
    scale: &RateScale<R>,
    mapped_pct: R,
    target_rpm: R,
    cmd_rpm: R,
    speed_rpm: R,
) -> (R, RateCase) {
    if target_rpm == cmd_rpm {
        return (R::ZERO, RateCase::Hold);
    }
    let moving = if cmd_rpm != R::ZERO { cmd_rpm } else { target_rpm };
    let d = dir_index(moving);
    let Some(r) = p.rates.dir.get(d) else {
        return (R::ZERO, RateCase::Hold);
    };
    let sc = scale.get(d).copied().unwrap_or([R::ONE, R::ONE]);
    let same_side = (target_rpm >= R::ZERO) == (cmd_rpm >= R::ZERO) || cmd_rpm == R::ZERO;
    let mag = |v: R| if v < R::ZERO { -v } else { v };
    let accelerating = same_side && mag(target_rpm) > mag(cmd_rpm);
    if accelerating {
        let acc = hs_ls_blend(p, r, speed_rpm, r.accel_hs_s, r.accel_ls_s);
        let (rate, case) = if mapped_pct >= p.full_throttle_pct {
            (acc, RateCase::FullAccel)
        } else if mapped_pct <= p.low_throttle_pct {
            (rpm_per_s(p, r.low_accel_s), RateCase::LowAccel)
        } else {
            let f = (mapped_pct - p.low_throttle_pct) / (p.full_throttle_pct - p.low_throttle_pct);
            let low = rpm_per_s(p, r.low_accel_s);
            (low + f * (acc - low), RateCase::PartialAccel)
        };
        (rate * sc[0], case)
    } else if mapped_pct <= R::ZERO {
        let rate = hs_ls_blend(p, r, speed_rpm, r.neutral_decel_hs_s, r.neutral_decel_ls_s);
        (rate * sc[1], RateCase::NeutralDecel)
    } else {
        (rpm_per_s(p, r.partial_decel_s) * sc[1], RateCase::PartialDecel)
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
        let (r, c) = ramp_rate(&p, &ONE, 100.0, 2100.0, 500.0, 500.0);
        assert_eq!(c, RateCase::FullAccel);
        assert!((r - 3300.0 / 3.9845).abs() < 1e-3);
        let (r, c) = ramp_rate(&p, &ONE, 5.0, 300.0, 0.0, 0.0);
        assert_eq!(c, RateCase::LowAccel);
        assert!((r - 3300.0 / 32.0).abs() < 1e-3);
        let (_, c) = ramp_rate(&p, &ONE, 50.0, 1400.0, 200.0, 200.0);
        assert_eq!(c, RateCase::PartialAccel);
        // Neutral deceleration below LS (40 % of 3300 = 1320 rpm): LS rate.
        let (r, c) = ramp_rate(&p, &ONE, 0.0, 0.0, 1000.0, 1000.0);
        assert_eq!(c, RateCase::NeutralDecel);
        assert!((r - 3300.0 / 3.1399).abs() < 1e-3);
        // Halfway between LS (1320) and HS (2310): halfway between the rates.
        let (r, _) = ramp_rate(&p, &ONE, 0.0, 0.0, 1815.0, 1815.0);
        let want = 0.5 * (3300.0 / 3.1399 + 3300.0 / 2.2693);
        assert!((r - want).abs() < 0.1, "{r} vs {want}");
        let (r, c) = ramp_rate(&p, &ONE, 30.0, 500.0, 1500.0, 1500.0);
        assert_eq!(c, RateCase::PartialDecel);
        assert!((r - 3300.0 / 9.9752).abs() < 1e-3);
        // Reverse uses the reverse rates.
        let (r, c) = ramp_rate(&p, &ONE, 100.0, -500.0, -100.0, -100.0);
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
