//! How the bench turns shaft motion into its speed channels, for the twin's side of a
//! comparison: a speed channel is the angle travelled in a window centred on the sample,
//! divided by the window (pulse counting, `vbench::encoder`, without the quantisation).
//! Comparing an unfiltered simulated speed with a window-averaged measured one biases
//! whatever shapes speed transients (inertias, rates), so the twin's speeds get the same
//! window before they are compared.

use model_core::Channel;

/// The channels the bench measures by counting encoder pulses.
pub const SPEED_CHANNELS: [Channel; 4] =
    [Channel::SuTMotorEnc, Channel::TKistlerL, Channel::TKistlerR, Channel::SiemensEnc];

/// Window-averaged speed: sample `k` (end of step `k`) averages over `2 * half` steps
/// centred on it, shortened at the ends of the run; the angle is integrated with the
/// trapezoidal rule from rest at t = 0. `half = 0` returns the input.
pub fn window_average(rpm: &[f32], dt: f64, half: usize) -> Vec<f32> {
    if half == 0 {
        return rpm.to_vec();
    }
    let n = rpm.len();
    let mut angle = Vec::with_capacity(n + 1);
    angle.push(0.0f64);
    let mut prev = 0.0f64;
    for &v in rpm {
        let v = f64::from(v);
        let last = angle.last().copied().unwrap_or(0.0);
        angle.push(last + 0.5 * (prev + v) * dt);
        prev = v;
    }
    (0..n)
        .map(|k| {
            let c = k + 1;
            let lo = c.saturating_sub(half);
            let hi = (c + half).min(n);
            ((angle[hi] - angle[lo]) / ((hi - lo) as f64 * dt)) as f32
        })
        .collect()
}

/// Window half-width in samples for a window of `window_s` at step `dt`.
pub fn half_width(window_s: f64, dt: f64) -> usize {
    if window_s > 0.0 && dt > 0.0 {
        ((0.5 * window_s / dt).round() as usize).max(1)
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vbench::encoder::{windowed_rpm, Encoder};

    #[test]
    fn matches_a_fine_encoder() {
        // A fine-pitch encoder (no quantisation to speak of) on a speed ramp and plateau
        // gives what the window average computes.
        let dt = 1e-3;
        let rpm: Vec<f32> = (0..3000).map(|k| if k < 1000 { k as f32 * 0.2 } else { 200.0 }).collect();
        let mut e = Encoder::new(1_000_000, 0.5);
        let mut counts = vec![0];
        let mut prev = 0.0;
        for &v in &rpm {
            counts.push(e.advance(prev, f64::from(v), dt, &mut |_| false));
            prev = f64::from(v);
        }
        let enc = windowed_rpm(&counts, 1_000_000, dt, 50);
        let avg = window_average(&rpm, dt, 50);
        for (k, (a, b)) in enc.iter().zip(&avg).enumerate() {
            assert!((a - f64::from(*b)).abs() < 1e-3, "k={k}: encoder {a} vs average {b}");
        }
        // A ramp's centred average is the ramp itself away from its corners.
        assert!((avg[500] - 100.0).abs() < 0.11, "{}", avg[500]);
    }
}
