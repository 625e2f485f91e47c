//! Throttle chain (thesis 3.1.1, 5.2.1): set point -> voltage -> mapped throttle ->
//! target speed.

use crate::data::Maps;
use crate::num::{clamp, Real};
use crate::params::{Params, SpeedTarget};

/// Throttle voltage at the controller [V] from the signed set point [%]: `|sp| / 20`,
/// within 0..5 V. The sign is the direction switch, not part of the voltage.
#[inline]
pub fn voltage<R: Real>(p: &Params<R>, setpoint_pct: R) -> R {
    let a = if setpoint_pct < R::ZERO { -setpoint_pct } else { setpoint_pct };
    clamp(R::narrow(a.wide() * p.throttle_volts_per_pct), R::ZERO, R::lit(5.0))
}

/// Direction index of a signed quantity: 0 forward (>= 0), 1 reverse.
#[inline]
pub fn dir_index<R: Real>(v: R) -> usize {
    usize::from(v < R::ZERO)
}

/// Signed target motor speed [rpm] for a mapped throttle [%] in the direction of
/// `setpoint_pct`. `hint` speeds up the map lookup (see `table::locate_hinted`).
#[inline]
pub fn target_speed_rpm<R: Real>(
    maps: &Maps<'_, R>,
    p: &Params<R>,
    mode: SpeedTarget,
    mapped_pct: R,
    setpoint_pct: R,
    hint: &mut usize,
) -> R {
    let d = dir_index(setpoint_pct);
    let limit = p.speed_limit_rpm.get(d).copied().unwrap_or(R::ZERO);
    let mag = match mode {
        SpeedTarget::Map => {
            let t = if d == 0 { &maps.speed_fwd } else { &maps.speed_rev };
            t.eval_hinted(mapped_pct, hint)
        }
        SpeedTarget::Parameter => {
            let max = p.max_speed_rpm.get(d).copied().unwrap_or(R::ZERO);
            R::narrow(mapped_pct.wide() * R::Wide::lit(0.01) * max.wide())
        }
    };
    let mag = clamp(mag, R::ZERO, limit);
    if d == 0 {
        mag
    } else {
        -mag
    }
}
