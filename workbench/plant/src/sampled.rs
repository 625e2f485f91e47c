//! Filters on a sampled series, in f64: the measurement chain's lag and delay as the
//! bench's acquisition applies them to a continuous signal. Used by the plant for the
//! twin's `sensor_lag`/`sensor_delay` (its own code, not the twin's streaming f32
//! filters) and by the virtual bench's acquisition faults (`amplifier_lag`, `daq_skew`).

/// First-order lag `tau dy/dt = x − y` over a series sampled every `dt`, in place. `y`
/// starts at rest at the first sample's value; between samples `x` is linear (first-order
/// hold), for which the update is exact:
/// `y1 = a y0 + (1 − a) x1 − c (x1 − x0)`, `a = e^(−dt/tau)`,
/// `c = tau (1 − a) / dt − a`.
pub fn first_order_lag(x: &mut [f64], dt: f64, tau: f64) {
    if !(dt.is_finite() && dt > 0.0 && tau > 0.0) {
        return;
    }
    let Some(&x0) = x.first() else { return };
    let r = dt / tau;
    let a = (-r).exp();
    let b = -(-r).exp_m1(); // 1 − a, accurate for small r
    let c = if r < 1e-3 {
        // (1 − e^−r)/r − e^−r, without the cancellation
        r * (0.5 - r * (1.0 / 3.0 - r / 8.0))
    } else if r.is_finite() {
        b / r - a
    } else {
        0.0
    };
    let (mut y, mut xp) = (x0, x0);
    for v in x.iter_mut().skip(1) {
        let xi = *v;
        y = a * y + b * xi - c * (xi - xp);
        xp = xi;
        *v = y;
    }
}

/// The series delayed by `d` samples (`d >= 0`): `y[k] = x(k − d)` with `x` linear
/// between samples and equal to `x[0]` before the first sample (the run at rest). A `d`
/// within 1e-9 of a whole number is taken as that number, so a skew of whole samples is
/// an exact shift despite `skew / dt` round-off.
pub fn fractional_delay(x: &[f64], d: f64) -> Vec<f64> {
    let Some(&first) = x.first() else { return Vec::new() };
    if d.is_nan() || d < 0.0 {
        return x.to_vec();
    }
    let d = if (d - d.round()).abs() <= 1e-9 * d.max(1.0) { d.round() } else { d };
    (0..x.len())
        .map(|k| {
            let p = k as f64 - d;
            if p.is_nan() || p <= 0.0 {
                return first;
            }
            let i = p.floor();
            let f = p - i;
            let i = i as usize;
            let a = x.get(i).copied().unwrap_or(first);
            if f == 0.0 {
                a
            } else {
                let b = x.get(i + 1).copied().unwrap_or(a);
                (1.0 - f) * a + f * b
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact response of the lag to a unit step ramped over the first sample interval.
    #[test]
    fn lag_step_response() {
        let (dt, tau) = (1e-4, 0.04);
        let mut x: Vec<f64> = (0..2001).map(|k| if k == 0 { 0.0 } else { 1.0 }).collect();
        first_order_lag(&mut x, dt, tau);
        assert_eq!(x[0], 0.0);
        for (k, y) in x.iter().enumerate().skip(1) {
            let t = k as f64 * dt;
            let exact = 1.0 - tau / dt * ((dt / tau).exp() - 1.0) * (-t / tau).exp();
            assert!((y - exact).abs() < 1e-12, "k {k}: {y} vs {exact}");
        }
        // 1 − 1/e one time constant after the step.
        let k = (tau / dt).round() as usize;
        assert!((x[k] - (1.0 - (-1.0f64).exp())).abs() < 1e-3, "{}", x[k]);
        assert!(x.iter().all(|y| (0.0..=1.0).contains(y)));
    }

    #[test]
    fn fractional_delay_interpolates() {
        let x = [1.0, 3.0, 7.0, 15.0];
        assert_eq!(fractional_delay(&x, 0.0), x.to_vec());
        assert_eq!(fractional_delay(&x, 0.25), vec![1.0, 2.5, 6.0, 13.0]);
        assert_eq!(fractional_delay(&x, 1.5), vec![1.0, 1.0, 2.0, 5.0]);
        assert_eq!(fractional_delay(&x, 2.0 + 1e-12), vec![1.0, 1.0, 1.0, 3.0]);
        assert!(fractional_delay(&[], 1.0).is_empty());
        assert_eq!(fractional_delay(&x, f64::INFINITY), vec![1.0; 4]);
    }
}
