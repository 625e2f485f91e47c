//! Throttle chain (thesis 3.1.1, 5.2.1): set point -> voltage -> mapped throttle ->
//! target speed.

use crate::data::Maps;
use crate::params::{Params, SpeedTarget};

/// Throttle voltage at the controller [V] from the signed set point [%]: `|sp| / 20`,
/// within 0..5 V. The sign is the direction switch, not part of the voltage.
#[inline]
pub fn voltage(p: &Params, setpoint_pct: f32) -> f32 {
    let a = if setpoint_pct < 0.0 { -setpoint_pct } else { setpoint_pct };
    (a * p.throttle_volts_per_pct).clamp(0.0, 5.0)
}

/// Direction index of a signed quantity: 0 forward (>= 0), 1 reverse.
#[inline]
pub fn dir_index(v: f32) -> usize {
    usize::from(v < 0.0)
}

/// Signed target motor speed [rpm] for a mapped throttle [%] in the direction of
/// `setpoint_pct`. `hint` speeds up the map lookup (see `table::locate_hinted`).
#[inline]
pub fn target_speed_rpm(
    maps: &Maps<'_>,
    p: &Params,
    mode: SpeedTarget,
    mapped_pct: f32,
    setpoint_pct: f32,
    hint: &mut usize,
) -> f32 {
    let d = dir_index(setpoint_pct);
    let limit = p.speed_limit_rpm.get(d).copied().unwrap_or(0.0);
    let mag = match mode {
        SpeedTarget::Map => {
            let t = if d == 0 { &maps.speed_fwd } else { &maps.speed_rev };
            t.eval_hinted(mapped_pct, hint)
        }
        SpeedTarget::Parameter => mapped_pct * 0.01 * p.max_speed_rpm.get(d).copied().unwrap_or(0.0),
    };
    let mag = crate::num::clamp(mag, 0.0, limit);
    if d == 0 {
        mag
    } else {
        -mag
    }
}
