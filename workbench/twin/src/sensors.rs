//! How the bench records what the twin computes, applied to the twin's side of every
//! comparison. A speed channel is the angle travelled in a window centred on the sample,
//! divided by the window (pulse counting, `vbench::encoder`, without the quantisation).
//! Comparing an unfiltered simulated speed with a window-averaged measured one leaves a
//! structured residual at every speed transient (and biases whatever shapes them:
//! inertias, rates), so the twin's speeds get the same window before they are compared.

use model_core::Channel;

use simrod_vbench::noise::Encoders;

/// The bench's sensor model as the twin's side of a comparison sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorModel {
    /// [s] encoder counting window of the speed channels, centred on each sample;
    /// 0: the speeds are recorded as simulated (a `simrod simulate` file, or a bench
    /// run with `--noise none`).
    pub speed_window_s: f64,
    /// Pulses per revolution of the encoders of [`SPEED_CHANNELS`] (0: not counted).
    pub ppr: [u32; 4],
}

impl SensorModel {
    /// Speeds recorded exactly as simulated.
    pub const NONE: Self = Self { speed_window_s: 0.0, ppr: [0; 4] };

    /// The SimRod bench's encoders and counting window, as the virtual bench has them
    /// (`workbench/examples/noise.toml`).
    pub fn bench() -> Self {
        Self::counting(Encoders::default().window_s)
    }

    /// The bench's encoders counted over `window_s` (0: not counted).
    pub fn counting(window_s: f64) -> Self {
        if window_s <= 0.0 {
            return Self::NONE;
        }
        let e = Encoders::default();
        Self { speed_window_s: window_s, ppr: [e.sut_motor_ppr, e.kistler_ppr, e.kistler_ppr, e.siemens_ppr] }
    }

    /// RMS of the counting error on channel `ch` [rpm], if it is counted: one pulse in
    /// the window is `60 / (ppr · window)` rpm, and the count's error is the difference of
    /// the two boundary fractions (each uniform on one pulse, independent), so its RMS
    /// is that over √6. A residual of this size is the sensor's resolution, not a
    /// model error, however correlated it looks.
    pub fn counting_rms(&self, ch: Channel) -> Option<f64> {
        self.counting_step(ch).map(|q| q / 6f64.sqrt())
    }

    /// [rpm] One encoder count per window: the largest error the counting makes. At a
    /// steady speed the two boundary fractions hardly change, so over seconds the error
    /// can sit anywhere up to this, not around [`SensorModel::counting_rms`].
    pub fn counting_step(&self, ch: Channel) -> Option<f64> {
        let i = SPEED_CHANNELS.iter().position(|c| *c == ch)?;
        let ppr = *self.ppr.get(i)?;
        (ppr > 0 && self.speed_window_s > 0.0).then(|| 60.0 / (f64::from(ppr) * self.speed_window_s))
    }

    /// Record the simulated `channels` (`out[i]` is `channels[i]`, one value per step of
    /// `dt_s`) as the bench would: speed channels window-averaged, the rest unchanged.
    pub fn apply(&self, out: &mut [Vec<f32>], channels: &[Channel], dt_s: f64) {
        let half = half_width(self.speed_window_s, dt_s);
        if half == 0 {
            return;
        }
        for (v, c) in out.iter_mut().zip(channels) {
            if SPEED_CHANNELS.contains(c) {
                *v = window_average(v, dt_s, half);
            }
        }
    }
}

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
    use simrod_vbench::encoder::{windowed_rpm, Encoder};

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
