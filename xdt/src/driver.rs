//! The driver: turns the cycle's target speed into the throttle set point. Feed-forward
//! through the inverse of the bench's throttle chain (set point -> voltage -> mapped
//! throttle -> target motor speed, model-core's maps), so the Curtis's speed mode is
//! asked for the target directly; a PI on the speed error corrects what the ramps and
//! the load leave; conditional integration is the anti-windup.
//!
//! Configuration apart from state, as in model-core: [`DriverConfig`] is fixed at
//! construction, [`DriverState`] is what a step changes.

use model_core::drivetrain::RPM_PER_RAD_S;
use model_core::table::Table1;
use model_core::{Maps, Params};

use crate::num::{clamp, invert_monotone_hinted};

/// Throttle set points the driver gives: forward only, within the profile range.
pub const THROTTLE_RANGE: (f32, f32) = (0.0, 100.0);

/// km/h per m/s.
const KMH_PER_MPS: f32 = 3.6;

/// The driver's gains and the throttle chain it inverts.
#[derive(Debug, Clone, Copy)]
pub struct DriverConfig<'a> {
    /// [%/(km/h)] proportional gain.
    pub kp: f32,
    /// [%/(km/h s)] integral gain.
    pub ki: f32,
    /// [s] the driver's sample time.
    pub dt: f32,
    /// [m/s] at or below this target the driver stops: throttle 0, integrator cleared.
    pub stop_mps: f32,
    /// [rpm motor per m/s] `N / r` in rpm.
    rpm_per_mps: f32,
    /// [%/V] inverse of the throttle's volts per percent.
    pct_per_volt: f32,
    throttle_input: Table1<'a>,
    speed_fwd: Table1<'a>,
}

impl<'a> DriverConfig<'a> {
    /// For the bench's maps and parameters and a wheel of radius `r` [m].
    pub fn new(maps: &Maps<'a>, p: &Params, r: f32, gains: (f32, f32), dt: f32, stop_mps: f32) -> Self {
        Self {
            kp: gains.0,
            ki: gains.1,
            dt,
            stop_mps,
            rpm_per_mps: p.sut_gear_ratio / r * RPM_PER_RAD_S,
            pct_per_volt: 1.0 / p.throttle_volts_per_pct,
            throttle_input: maps.throttle_input,
            speed_fwd: maps.speed_fwd,
        }
    }

    /// [%] the set point whose steady motor speed is `v` [m/s]: the throttle chain
    /// inverted on its maps (the lowest set point that asks for the speed).
    #[inline]
    pub fn feed_forward(&self, v: f32) -> f32 {
        self.feed_forward_hinted(v, &mut [0; 2])
    }

    /// [`DriverConfig::feed_forward`] with search hints (speed map, throttle input map).
    #[inline]
    fn feed_forward_hinted(&self, v: f32, hints: &mut [usize; 2]) -> f32 {
        if v <= self.stop_mps {
            return 0.0;
        }
        let rpm = v * self.rpm_per_mps;
        let (sx, sy) = (self.speed_fwd.x(), self.speed_fwd.y());
        let pt = |x: &[f32], y: &[f32], i: usize| {
            (x.get(i).copied().unwrap_or(0.0), y.get(i).copied().unwrap_or(0.0))
        };
        let [h_speed, h_volts] = hints;
        let (mapped, _) = invert_monotone_hinted(sx.len().min(sy.len()), |i| pt(sx, sy, i), rpm, h_speed);
        let (tx, ty) = (self.throttle_input.x(), self.throttle_input.y());
        let (volts, _) = invert_monotone_hinted(tx.len().min(ty.len()), |i| pt(tx, ty, i), mapped, h_volts);
        clamp(volts * self.pct_per_volt, THROTTLE_RANGE.0, THROTTLE_RANGE.1)
    }
}

/// What the driver keeps between samples.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriverState {
    /// [%] the integral term.
    integ: f32,
    /// Search hints of the feed-forward's inversions.
    hints: [usize; 2],
}

impl DriverState {
    /// [%] throttle set point for a target `target` [m/s] now, `ahead` [m/s] a preview
    /// time later (the feed-forward's), at the measured speed `v` [m/s].
    #[inline]
    pub fn update(&mut self, c: &DriverConfig<'_>, target: f32, ahead: f32, v: f32) -> f32 {
        if target <= c.stop_mps && ahead <= c.stop_mps {
            self.integ = 0.0;
            return 0.0;
        }
        let e = (target - v) * KMH_PER_MPS;
        let (lo, hi) = THROTTLE_RANGE;
        let unsat = c.feed_forward_hinted(ahead, &mut self.hints) + c.kp * e + self.integ;
        let pushing_out = (unsat > hi && e > 0.0) || (unsat < lo && e < 0.0);
        if !pushing_out {
            self.integ = clamp(self.integ + c.ki * e * c.dt, -hi, hi);
        }
        clamp(unsat, lo, hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> DriverConfig<'static> {
        DriverConfig::new(&Maps::builtin(), &Params::default(), 0.25, (3.0, 1.0), 1e-3, 0.5 / 3.6)
    }

    /// The feed-forward, put through the twin's own throttle chain, asks for the speed.
    #[test]
    fn feed_forward_inverts_the_throttle_chain() {
        let c = cfg();
        let maps = Maps::builtin();
        let p = Params::default();
        for kmh in [1.0f32, 3.0, 5.0, 10.0, 15.0, 17.0] {
            let sp = c.feed_forward(kmh / 3.6);
            let mapped = maps.throttle_input.eval(model_core::throttle::voltage(&p, sp));
            let rpm = maps.speed_fwd.eval(mapped);
            let want = kmh / 3.6 / 0.25 * p.sut_gear_ratio * RPM_PER_RAD_S;
            assert!((rpm - want).abs() < 1e-3 * want, "{kmh} km/h: sp {sp} % -> {rpm} rpm, want {want}");
        }
        // Beyond the bench's 2100 rpm: the lowest set point that asks for the top.
        assert!((c.feed_forward(40.0 / 3.6) - 78.0).abs() < 1e-3);
        assert_eq!(c.feed_forward(0.0), 0.0);
    }

    #[test]
    fn integrator_winds_up_no_further_than_the_limits_allow() {
        let c = cfg();
        let mut s = DriverState::default();
        for _ in 0..100_000 {
            assert_eq!(s.update(&c, 40.0, 40.0, 0.0), 100.0);
        }
        // Saturated high with a positive error: the integrator stopped; a small negative
        // error brings the throttle off the stop at once.
        let out = s.update(&c, 10.0, 10.0, 10.5);
        assert!(out < 100.0 && out > 0.0, "{out}");
        assert_eq!(s.update(&c, 0.0, 0.0, 3.0), 0.0);
        assert_eq!(s.integ, 0.0);
    }
}
