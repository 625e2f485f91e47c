//! SuT speed controller: PID on motor speed, torque output within the motor's torque
//! and power limits, with conditional-integration anti-windup (the integrator freezes
//! while the output is saturated in the direction the error pushes).
//!
//! Configuration apart from state (as quartiq/idsp does): [`PidConfig`] holds the gains,
//! limits and the derivative filter's factor, computed once at construction;
//! [`PidState`] is what the step changes.

use crate::num::{clamp, Real};
use crate::params::Params;

/// Controller coefficients, fixed at construction. The proportional gain acts on a
/// signal; the others are in the wide format (`Real::Wide`: the integral and the
/// derivative's filter accumulate over steps, and the step itself is small).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidConfig<R: Real = f32> {
    kp: R,
    ki: R::Wide,
    kd: R::Wide,
    /// Weight of the derivative's first-order filter, `dt / (tau + dt)`.
    d_weight: R::Wide,
    /// [s] step, and as a divisor.
    dt: R::Wide,
    per_dt: <R::Wide as Real>::Divisor,
    torque_max_nm: R,
    power_max_w: R,
    /// [N m] twice the torque limit, wide (see [`limit`]).
    twice_torque: R::Wide,
}

impl<R: Real> PidConfig<R> {
    /// Coefficients for parameters `p` at step `dt` [s]. The filter weight is computed
    /// here once, with the operations the step used to repeat, so the bits are the same.
    pub fn new(p: &Params, dt: R::Wide) -> Self {
        let w = <R::Wide as Real>::lit;
        Self {
            kp: R::lit(p.pid_kp),
            ki: w(p.pid_ki),
            kd: w(p.pid_kd),
            d_weight: dt / (w(p.pid_d_filter_s) + dt),
            dt,
            per_dt: R::Wide::divisor(dt),
            torque_max_nm: R::lit(p.motor_torque_max_nm),
            power_max_w: R::lit(p.motor_power_max_w),
            twice_torque: w(2.0 * p.motor_torque_max_nm),
        }
    }

    /// Torque limit at a motor speed [rad/s] (see [`torque_limit`]).
    #[inline]
    fn limit(&self, speed: R) -> R {
        limit(self.torque_max_nm, self.power_max_w, speed, self.twice_torque)
    }
}

/// Controller state: the integral and the derivative's filter in the wide format, the
/// last measured speed a signal.
#[derive(Debug, Clone, Copy)]
pub struct PidState<R: Real = f32> {
    integ: R::Wide,
    d_filt: R::Wide,
    prev_meas: R,
}

impl<R: Real> Default for PidState<R> {
    fn default() -> Self {
        Self { integ: R::Wide::ZERO, d_filt: R::Wide::ZERO, prev_meas: R::ZERO }
    }
}

impl<R: Real> PidState<R> {
    /// Motor torque [N m] for a command and a measured speed [rad/s], motor frame.
    pub fn update(&mut self, c: &PidConfig<R>, cmd: R, meas: R) -> R {
        let e = cmd - meas;
        // Derivative on measurement through a first-order filter (no kick on steps).
        let raw_d = (meas - self.prev_meas).wide().div_by(c.per_dt);
        self.prev_meas = meas;
        self.d_filt += c.d_weight * (raw_d - self.d_filt);
        let lim = c.limit(meas).wide();
        let unsat = (c.kp * e).wide() + self.integ - c.kd * self.d_filt;
        let pushing_out = (unsat > lim && e > R::ZERO) || (unsat < -lim && e < R::ZERO);
        if !pushing_out {
            self.integ = clamp(self.integ + R::wide_mul(c.ki, e) * c.dt, -lim, lim);
        }
        R::narrow(clamp(unsat, -lim, lim))
    }
}

/// Torque limit at a motor speed [rad/s]: the torque limit, and the power limit above
/// base speed.
#[inline]
pub fn torque_limit<R: Real>(p: &Params<R>, speed: R) -> R {
    let t = p.motor_torque_max_nm;
    limit(t, p.motor_power_max_w, speed, (t + t).wide())
}

#[inline]
fn limit<R: Real>(torque_max: R, power_max: R, speed: R, twice_torque: R::Wide) -> R {
    let w = if speed < R::ZERO { -speed } else { speed };
    // Where w 2 T <= P the power limit P / w is at least twice the torque limit T, so T
    // holds: the same result as dividing, without a quotient beyond a fixed-point
    // signal's range at standstill (P / w is at most 2 T where it is taken).
    let by_power =
        if w > R::ZERO && w.wide() * twice_torque > power_max.wide() { power_max / w } else { torque_max };
    if by_power < torque_max {
        by_power
    } else {
        torque_max
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hoisted filter weight gives the step the same bits as computing it each step.
    #[test]
    fn hoisted_filter_weight_is_bit_identical() {
        let p = Params { pid_kd: 0.05, pid_d_filter_s: 0.003, ..Params::default() };
        for dt in [1e-3f32, 1e-4, 3.7e-5] {
            let c = PidConfig::<f32>::new(&p, dt);
            let mut s = PidState::default();
            let (mut integ, mut d_filt, mut prev) = (0.0f32, 0.0f32, 0.0f32);
            for k in 0..2000 {
                let meas = (k as f32 * 0.01).sin() * 50.0;
                let cmd = if k % 500 < 250 { 100.0 } else { -20.0 };
                // The step as it was: the weight recomputed from the parameters.
                let e = cmd - meas;
                let raw_d = (meas - prev) / dt;
                prev = meas;
                let a = dt / (p.pid_d_filter_s + dt);
                d_filt += a * (raw_d - d_filt);
                let lim = torque_limit(&p, meas);
                let unsat = p.pid_kp * e + integ - p.pid_kd * d_filt;
                if !((unsat > lim && e > 0.0) || (unsat < -lim && e < 0.0)) {
                    integ = crate::num::clamp(integ + p.pid_ki * e * dt, -lim, lim);
                }
                let want = crate::num::clamp(unsat, -lim, lim);
                assert_eq!(s.update(&c, cmd, meas).to_bits(), want.to_bits(), "dt {dt} step {k}");
            }
        }
    }
}
