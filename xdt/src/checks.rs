//! Checks of the parameter set against the DXP's published performance, from the force
//! balance of the vehicle (`vehicle.toml`) driven by the bench's SuT (model-core's
//! parameters: the motor's torque and power limits, the gear ratio, the Curtis's
//! programmed Max Speed). Independent of the XiL loop: plain statics.
//!
//! - **Top speed**: the highest speed at which the tractive force still covers the road
//!   load on the flat, no higher than the Curtis's Max Speed Fwd (5000 rpm, table 5.16:
//!   the vehicle's governor). The bench itself stops at 2100 rpm (table 5.3, a 24 V
//!   limit): that caps the cycles in XiL (see `xdt`), not the vehicle.
//! - **Gradeability**: the steepest grade on which the tractive force at low speed (the
//!   motor's torque limit) covers weight, rolling resistance and drag.
//!
//! f64 and basic operations only (no trigonometry): the grade condition is squared so
//! no square root is needed.

use model_core::controller::torque_limit;
use model_core::drivetrain::RAD_S_PER_RPM;
use model_core::Params;

use crate::vehicle::Vehicle;

/// What limits the top speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TopSpeedLimit {
    /// The Curtis's Max Speed (the governor).
    MaxSpeed,
    /// The motor's torque or power limit against the road load.
    Traction,
}

/// [N] tractive force at the wheels at speed `v` [m/s], from the motor's limits.
fn traction(veh: &Vehicle, p: &Params, v: f64) -> f64 {
    let r = f64::from(veh.wheel_radius_m);
    let n = f64::from(p.sut_gear_ratio);
    let w_motor = v / r * n;
    let t = f64::from(torque_limit(p, w_motor as f32));
    t * n * f64::from(veh.driveline_efficiency) / r
}

/// [N] road load on the flat at `v` [m/s] with mass `m` [kg].
fn road_flat(veh: &Vehicle, m: f64, v: f64) -> f64 {
    let g = f64::from(veh.gravity_m_s2);
    m * g * f64::from(veh.rolling_resistance) + 0.5 * f64::from(veh.air_density_kg_m3 * veh.cd_a_m2) * v * v
}

/// [m/s] the top speed at the vehicle's mass, and what sets it.
pub fn top_speed(veh: &Vehicle, p: &Params) -> (f64, TopSpeedLimit) {
    let m = f64::from(veh.mass_kg);
    let governor = f64::from(p.max_speed_rpm[0]) / f64::from(p.sut_gear_ratio)
        * f64::from(RAD_S_PER_RPM)
        * f64::from(veh.wheel_radius_m);
    let surplus = |v: f64| traction(veh, p, v) - road_flat(veh, m, v);
    if surplus(governor) >= 0.0 {
        return (governor, TopSpeedLimit::MaxSpeed);
    }
    // Traction falls and the load rises with speed: one crossing, by bisection.
    let (mut lo, mut hi) = (0.0f64, governor);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if surplus(mid) >= 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (lo, TopSpeedLimit::Traction)
}

/// [%] the steepest grade (rise / run) the vehicle climbs at mass `m` [kg], at the
/// speed `v` [m/s] (its tractive force there against weight, rolling resistance and
/// drag).
pub fn gradeability(veh: &Vehicle, p: &Params, m: f64, v: f64) -> f64 {
    let f = traction(veh, p, v) - 0.5 * f64::from(veh.air_density_kg_m3 * veh.cd_a_m2) * v * v;
    let w = m * f64::from(veh.gravity_m_s2);
    let c = f64::from(veh.rolling_resistance);
    // On grade g: w (g + c) / sqrt(1 + g^2) <= f, i.e. (w (g + c))^2 <= f^2 (1 + g^2).
    let climbs = |g: f64| w * (g + c) <= 0.0 || (w * (g + c)) * (w * (g + c)) <= f * f * (1.0 + g * g);
    if f <= 0.0 {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0f64, 10.0f64);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if climbs(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    100.0 * lo
}

/// [N m] motor torque (motor frame) that climbs `grade_pct` at mass `m` [kg] from
/// standstill: what the parameter set would need.
pub fn torque_for_grade(veh: &Vehicle, p: &Params, m: f64, grade_pct: f64) -> f64 {
    let g = grade_pct / 100.0;
    let w = m * f64::from(veh.gravity_m_s2);
    let c = f64::from(veh.rolling_resistance);
    // (g + c) / sqrt(1 + g^2) by Newton's square root (basic operations).
    let s = 1.0 + g * g;
    let mut root = s;
    for _ in 0..40 {
        root = 0.5 * (root + s / root);
    }
    let f = w * (g + c) / root;
    f * f64::from(veh.wheel_radius_m) / (f64::from(p.sut_gear_ratio) * f64::from(veh.driveline_efficiency))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hand check of the bisection: a traction limited well below the governor.
    #[test]
    fn traction_limited_top_speed_balances_the_forces() {
        let veh = Vehicle { cd_a_m2: 5.0, ..Vehicle::default() };
        let p = Params { motor_power_max_w: 1500.0, ..Params::default() };
        let (v, lim) = top_speed(&veh, &p);
        assert_eq!(lim, TopSpeedLimit::Traction);
        let m = f64::from(veh.mass_kg);
        assert!((traction(&veh, &p, v) - road_flat(&veh, m, v)).abs() < 1e-6, "{v}");
        // 1500 W x 0.95 = F v at the balance.
        assert!((traction(&veh, &p, v) * v - 1425.0).abs() < 1e-3);
    }

    #[test]
    fn gradeability_and_the_torque_it_needs_agree() {
        let veh = Vehicle::default();
        let p = Params::default();
        let m = f64::from(veh.mass_kg);
        let g = gradeability(&veh, &p, m, 0.0);
        let t = torque_for_grade(&veh, &p, m, g);
        assert!((t - f64::from(p.motor_torque_max_nm)).abs() < 1e-6, "{g} % needs {t} N m");
    }
}
