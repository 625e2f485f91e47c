//! SuT speed controller: PID on motor speed, torque output within the motor's torque
//! and power limits, with conditional-integration anti-windup (the integrator freezes
//! while the output is saturated in the direction the error pushes).

use crate::params::Params;

/// Controller state.
#[derive(Debug, Clone, Copy, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pid {
    integ: f32,
    d_filt: f32,
    prev_meas: f32,
}

impl Pid {
    /// Motor torque [N m] for a command and a measured speed [rad/s], motor frame.
    pub fn update(&mut self, p: &Params, cmd: f32, meas: f32, dt: f32) -> f32 {
        let e = cmd - meas;
        // Derivative on measurement through a first-order filter (no kick on steps).
        let raw_d = (meas - self.prev_meas) / dt;
        self.prev_meas = meas;
        let a = dt / (p.pid_d_filter_s + dt);
        self.d_filt += a * (raw_d - self.d_filt);
        let lim = torque_limit(p, meas);
        let unsat = p.pid_kp * e + self.integ - p.pid_kd * self.d_filt;
        let pushing_out = (unsat > lim && e > 0.0) || (unsat < -lim && e < 0.0);
        if !pushing_out {
            self.integ = crate::num::clamp(self.integ + p.pid_ki * e * dt, -lim, lim);
        }
        crate::num::clamp(unsat, -lim, lim)
    }
}

/// Torque limit at a motor speed [rad/s]: the torque limit, and the power limit above
/// base speed.
#[inline]
pub fn torque_limit(p: &Params, speed: f32) -> f32 {
    let w = if speed < 0.0 { -speed } else { speed };
    let by_power = if w > 0.0 { p.motor_power_max_w / w } else { p.motor_torque_max_nm };
    if by_power < p.motor_torque_max_nm {
        by_power
    } else {
        p.motor_torque_max_nm
    }
}
