//! Electrics (thesis 5.5, fig. 5.38, A.4, A.5): DPU source -> busbars -> connector
//! resistance -> SuT inverter; busbars -> each load motor. Powers come from the 2-D
//! maps through rate limiters; currents from `I = P / V`; supply current is the sum.

use crate::num::Real;

/// First-order rate limiter on a power [W].
#[derive(Debug, Clone, Copy)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RateLimiter<R = f32> {
    y: R,
}

impl<R: Real> Default for RateLimiter<R> {
    fn default() -> Self {
        Self { y: R::ZERO }
    }
}

impl<R: Real> RateLimiter<R> {
    /// Move towards `target` by at most `max_step`.
    #[inline]
    pub fn update(&mut self, target: R, max_step: R) -> R {
        self.y += crate::num::clamp(target - self.y, -max_step, max_step);
        self.y
    }
}

/// Solution of the connector: the inverter draws `p` [W] at its terminals through `r`
/// [ohm] from busbars at `v_b` [V]. Returns `(i_dc, v_dc, p_limited)`.
///
/// Solves `r i^2 - v_b i + p = 0` (the smaller root) by Newton's method from `p / v_b`,
/// which converges monotonically; basic operations only, so every target gets the same
/// bits. A draw beyond what the connector can pass (`v_b^2 / 4r`) is limited to 95 % of it.
#[inline]
pub fn connector<R: Real>(p: R, v_b: R, r: R) -> (R, R, R) {
    // Not `v_b <= 0.0`: NaN must take this branch too.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    if !(v_b > R::ZERO) {
        return (R::ZERO, R::ZERO, R::ZERO);
    }
    let mut p = p;
    if r > R::ZERO {
        let p_max = R::lit(0.95) * v_b * v_b / (R::lit(4.0) * r);
        if p > p_max {
            p = p_max;
        }
    }
    let mut i = p / v_b;
    if r > R::ZERO {
        for _ in 0..4 {
            let f = r * i * i - v_b * i + p;
            let df = R::lit(2.0) * r * i - v_b;
            if df == R::ZERO {
                break;
            }
            i -= f / df;
        }
    }
    (i, v_b - r * i, p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn connector_solves_the_power_equation() {
        for &(p, v) in &[(6000.0f32, 24.0f32), (-1600.0, 24.0), (300.0, 12.0), (0.0, 30.0)] {
            let (i, vdc, pl) = connector(p, v, 0.0196);
            assert_eq!(pl, p);
            assert!((vdc * i - p).abs() <= 1e-4 * p.abs().max(1.0), "p={p} v={v}: {}", vdc * i);
            assert!(vdc <= v || p < 0.0);
        }
    }

    #[test]
    fn connector_limits_impossible_draws() {
        let (i, vdc, pl) = connector(6000.0, 12.0, 0.0196);
        assert!(pl < 6000.0 && (vdc * i - pl).abs() < 1.0 && vdc > 0.0);
    }

    #[test]
    fn rate_limiter_limits() {
        let mut r = RateLimiter::default();
        assert_eq!(r.update(100.0, 8.0), 8.0);
        assert_eq!(r.update(10.0, 8.0), 10.0);
        assert_eq!(r.update(-100.0, 8.0), 2.0);
    }
}
