//! Free play in the SuT gearbox (the `gear_backlash` effect).
//!
//! The gear mesh is far stiffer than anything the step can resolve, so it is modelled by
//! its two modes rather than as a stiff spring: in *contact* the motor share of the SuT
//! inertia moves with the differential (the thesis model); when the torque through the
//! mesh reverses it *separates*, the motor turns freely under its own torque while the
//! gap (axle-frame angle) opens and closes, and on closing the two re-engage with an
//! inelastic impact that conserves angular momentum. The motor encoder sees the motor,
//! the flanges see the shafts: the free flight shows as a brief speed mismatch and a
//! torque dip at every torque reversal.

use crate::drivetrain::{NS, W_A};
use crate::num::Real;

/// Torque [N m, axle frame] by which the mesh torque must reverse before the gears part;
/// avoids chattering around zero load.
const SEPARATION_NM: f32 = 0.05;

/// Backlash constants, fixed at construction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backlash<R = f32> {
    half_gap: R,
    j_m: R,
    j_side_free: R,
    /// Any gap at all (the gears then start apart).
    starts_free: bool,
}

/// Backlash state: the gears in contact or apart, the gap, the flank last engaged and
/// the free motor's speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BacklashState<R = f32> {
    free: bool,
    gap: R,
    side: R,
    w_m: R,
}

impl<R: Real> Backlash<R> {
    /// `gap_rad`: total free play [rad, axle frame]; `j_m`: motor-side inertia [kg m²,
    /// axle frame]; `j_side_free`: each side's SuT inertia without the motor share.
    pub fn new(gap_rad: R, j_m: R, j_side_free: R) -> Self {
        Self { half_gap: R::lit(0.5) * gap_rad, j_m, j_side_free, starts_free: gap_rad > R::ZERO }
    }

    /// The state at rest: the gears start in the middle of the gap (nothing engaged
    /// yet), apart if there is a gap at all.
    pub fn initial(&self) -> BacklashState<R> {
        BacklashState { free: self.starts_free, gap: R::ZERO, side: R::ONE, w_m: R::ZERO }
    }

    /// Whether backlash is modelled at all.
    #[inline]
    pub fn enabled(&self) -> bool {
        self.half_gap > R::ZERO
    }

    /// After the shafts stepped: move the free motor and the gap, re-engage on closing
    /// (impulse shared equally by the sides, as the open differential splits torque), or
    /// part when the mesh torque reverses.
    pub fn after_step(
        &self,
        s: &mut BacklashState<R>,
        motor_torque_axle: R,
        w_case_before: R,
        x: &mut [[R; NS]; 2],
        dt: R,
    ) {
        let (half, one, two) = (R::lit(0.5), R::ONE, R::lit(2.0));
        let w_case = half * (x[0][W_A] + x[1][W_A]);
        if s.free {
            let w_m0 = s.w_m;
            let w_m1 = w_m0 + motor_torque_axle / self.j_m * dt;
            let gap1 = s.gap + (w_m1 - w_case) * dt;
            if gap1 >= self.half_gap || gap1 <= -self.half_gap {
                // Contact within the step, at the fraction where the gap closes: the motor
                // flew freely until then, the impact is inelastic, and the motor torque of
                // the rest of the step drives the engaged train. Locating the impact inside
                // the step keeps the response continuous in the backlash (identifiable).
                s.side = if gap1 > R::ZERO { one } else { -one };
                let target = s.side * self.half_gap;
                let span = gap1 - s.gap;
                let f = if span != R::ZERO {
                    crate::num::clamp((target - s.gap) / span, R::ZERO, one)
                } else {
                    one
                };
                s.gap = target;
                let w_m_hit = w_m0 + motor_torque_axle / self.j_m * (f * dt);
                let impulse = (w_m_hit - w_case) / (one / self.j_m + one / (two * self.j_side_free));
                let rest = motor_torque_axle * ((one - f) * dt) / (self.j_m + two * self.j_side_free);
                for side in x.iter_mut() {
                    side[W_A] += impulse / (two * self.j_side_free) + rest;
                }
                s.free = false;
            } else {
                s.w_m = w_m1;
                s.gap = gap1;
            }
        } else {
            // Torque through the mesh: what the motor gives minus what accelerating its own
            // inertia takes. Parting when it pulls against the engaged flank.
            let accel = (w_case - w_case_before) / dt;
            let mesh = motor_torque_axle - self.j_m * accel;
            if s.side * mesh < -R::lit(SEPARATION_NM) {
                s.free = true;
                s.w_m = w_case;
            }
        }
    }
}

impl<R: Real> BacklashState<R> {
    /// Whether the gears are apart this step.
    #[inline]
    pub fn is_free(&self) -> bool {
        self.free
    }

    /// Motor speed [rad/s, axle frame] given the differential case speed.
    #[inline]
    pub fn motor_speed(&self, w_case: R) -> R {
        if self.free {
            self.w_m
        } else {
            w_case
        }
    }

    /// Motor torque reaching the differential case [N m, axle frame].
    #[inline]
    pub fn case_torque<T: Real>(&self, motor_torque_axle: T) -> T {
        if self.free {
            T::ZERO
        } else {
            motor_torque_axle
        }
    }
}
