//! How the bench records what the twin computes, applied to the twin's side of every
//! comparison. A speed channel is the angle travelled in a window centred on the sample,
//! divided by the window (pulse counting, `vbench::encoder`, without the quantisation).
//! Comparing an unfiltered simulated speed with a window-averaged measured one leaves a
//! structured residual at every speed transient (and biases whatever shapes them:
//! inertias, rates), so the twin's speeds get the same window before they are compared.

use model_core::Channel;

use simrod_vbench::noise::{Encoders, NoiseModel};

/// The bench's sensor model as the twin's side of a comparison sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorModel {
    /// [s] encoder counting window of the speed channels, centred on each sample;
    /// 0: the speeds are recorded as simulated (a `simrod simulate` file, or a bench
    /// run with `--noise none`).
    pub speed_window_s: f64,
    /// Pulses per revolution of the encoders of [`SPEED_CHANNELS`] (0: not counted).
    pub ppr: [u32; 4],
    /// The noise the user states the sensors have (`--sensor-noise`, the bench's noise
    /// file); `None`: only what the residual itself shows is known of it.
    pub stated: Option<NoiseModel>,
}

impl SensorModel {
    /// Speeds recorded exactly as simulated.
    pub const NONE: Self = Self { speed_window_s: 0.0, ppr: [0; 4], stated: None };

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
        Self {
            speed_window_s: window_s,
            ppr: [e.sut_motor_ppr, e.kistler_ppr, e.kistler_ppr, e.siemens_ppr],
            stated: None,
        }
    }

    /// Per channel of `channels` (`None`: one derived from others; `series` gives each
    /// recorded channel's `n` samples), the noise
    /// σ stated for each sample [the channel's unit]: `sigma + g · at_limit` with `g` the
    /// bench's limit factor from the recorded flange torques and SuT motor speed (0 where
    /// one is not recorded). `None` for a counted speed (its counting error is
    /// correlated over the window, not white), a channel without a sensor model, or
    /// when no noise is stated.
    pub fn stated_sigma<'a>(
        &self,
        channels: &[Option<Channel>],
        series: impl Fn(Channel) -> Option<&'a [f64]>,
        n: usize,
    ) -> Vec<Option<Vec<f64>>> {
        let Some(nm) = self.stated else { return vec![None; channels.len()] };
        let at = |c: Channel, k: usize| series(c).and_then(|v| v.get(k).copied()).filter(|v| v.is_finite());
        let g: Vec<f64> = (0..n)
            .map(|k| {
                let v = |c| at(c, k).unwrap_or(0.0);
                nm.limits.factor(v(Channel::CKistlerL), v(Channel::CKistlerR), v(Channel::SuTMotorEnc))
            })
            .collect();
        channels
            .iter()
            .map(|c| c.and_then(|c| nm.gauss(c)).map(|p| g.iter().map(|g| p.sigma_at(*g)).collect()))
            .collect()
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

    /// A recorder of `channels` as the bench would record them, one value per step of
    /// `dt_s`, keeping the samples `keep` names: speed channels window-averaged, the rest
    /// as simulated.
    pub fn recorder(&self, channels: &[Channel], dt_s: f64, steps: usize, keep: Keep) -> Recorder {
        let half = half_width(self.speed_window_s, dt_s);
        let kept = keep.count(steps);
        let tracks = channels
            .iter()
            .map(|c| {
                if half > 0 && SPEED_CHANNELS.contains(c) {
                    let mut angle = Vec::with_capacity(steps + 1);
                    angle.push(0.0);
                    Track::Counted { channel: *c, angle, prev: 0.0 }
                } else {
                    Track::Plain { channel: *c, kept: Vec::with_capacity(kept) }
                }
            })
            .collect();
        Recorder { tracks, half, dt: dt_s, keep, step: 0, next: keep.first }
    }
}

/// Which samples of a run to keep: sample `first`, then every `stride`-th. The fits read
/// a long run at a stride; only the kept samples are stored (and window-averaged).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Keep {
    pub first: usize,
    pub stride: usize,
}

impl Keep {
    /// Every sample.
    pub const ALL: Self = Self { first: 0, stride: 1 };

    /// Kept samples of a run of `steps`.
    pub fn count(&self, steps: usize) -> usize {
        if self.first >= steps {
            0
        } else {
            (steps - self.first).div_ceil(self.stride.max(1))
        }
    }
}

/// One channel being recorded.
enum Track {
    /// Stored as simulated, at the kept samples.
    Plain { channel: Channel, kept: Vec<f32> },
    /// Counted by an encoder: the angle (trapezoidal, from rest at t = 0) at every step,
    /// averaged over the window at the kept samples when the run ends.
    Counted { channel: Channel, angle: Vec<f64>, prev: f64 },
}

/// Where a [`Recorder`] stood ([`Recorder::mark`]): its step, its next kept sample, and
/// per track the length recorded and (encoders) the last speed.
#[derive(Debug, Clone)]
pub struct Mark {
    step: usize,
    next: usize,
    tracks: Vec<(usize, f64)>,
}

/// Records a run step by step ([`SensorModel::recorder`]).
pub struct Recorder {
    tracks: Vec<Track>,
    half: usize,
    dt: f64,
    keep: Keep,
    step: usize,
    next: usize,
}

impl Recorder {
    /// Record the next step, whose channel values `value` gives.
    #[inline]
    pub fn record(&mut self, value: impl Fn(Channel) -> f32) {
        let keep = self.step == self.next;
        for t in &mut self.tracks {
            match t {
                Track::Plain { channel, kept } => {
                    if keep {
                        kept.push(value(*channel));
                    }
                }
                Track::Counted { channel, angle, prev } => {
                    let v = f64::from(value(*channel));
                    let last = angle.last().copied().unwrap_or(0.0);
                    angle.push(last + 0.5 * (*prev + v) * self.dt);
                    *prev = v;
                }
            }
        }
        if keep {
            self.next += self.keep.stride.max(1);
        }
        self.step += 1;
    }

    /// Where the recording stands: what [`Recorder::resumed`] needs to take it up again
    /// from here.
    pub fn mark(&self) -> Mark {
        let tracks = self
            .tracks
            .iter()
            .map(|t| match t {
                Track::Plain { kept, .. } => (kept.len(), 0.0),
                Track::Counted { angle, prev, .. } => (angle.len(), *prev),
            })
            .collect();
        Mark { step: self.step, next: self.next, tracks }
    }

    /// A recorder holding what this one had recorded at `at` (a [`Recorder::mark`] of
    /// this recording, which has gone on since): records the same from there.
    pub fn resumed(&self, at: &Mark) -> Recorder {
        let tracks = self
            .tracks
            .iter()
            .zip(&at.tracks)
            .map(|(t, &(len, was))| match t {
                Track::Plain { channel, kept } => {
                    let mut k = Vec::with_capacity(kept.capacity());
                    k.extend_from_slice(&kept[..len.min(kept.len())]);
                    Track::Plain { channel: *channel, kept: k }
                }
                Track::Counted { channel, angle, .. } => {
                    let mut a = Vec::with_capacity(angle.capacity());
                    a.extend_from_slice(&angle[..len.min(angle.len())]);
                    Track::Counted { channel: *channel, angle: a, prev: was }
                }
            })
            .collect();
        Recorder { tracks, half: self.half, dt: self.dt, keep: self.keep, step: at.step, next: at.next }
    }

    /// The kept samples of every channel so far, as [`Recorder::finish`] gives them.
    pub fn output(&self) -> Vec<Vec<f32>> {
        let n = self.step;
        self.tracks
            .iter()
            .map(|t| match t {
                Track::Plain { kept, .. } => kept.clone(),
                Track::Counted { angle, .. } => (self.keep.first..n)
                    .step_by(self.keep.stride.max(1))
                    .map(|k| window_at(angle, k, self.half, self.dt))
                    .collect(),
            })
            .collect()
    }

    /// The kept samples of every channel, in the order of the recorder's channels.
    pub fn finish(self) -> Vec<Vec<f32>> {
        self.output()
    }
}

/// Window-averaged speed: sample `k` (end of step `k`) averages over `2 * half` steps
/// centred on it, shortened at the ends of the run; `angle[j]` is the angle after `j`
/// steps (`angle[0] = 0`).
fn window_at(angle: &[f64], k: usize, half: usize, dt: f64) -> f32 {
    let n = angle.len() - 1;
    let c = k + 1;
    let lo = c.saturating_sub(half);
    let hi = (c + half).min(n);
    ((angle[hi] - angle[lo]) / ((hi - lo) as f64 * dt)) as f32
}

/// The channels the bench measures by counting encoder pulses.
pub const SPEED_CHANNELS: [Channel; 4] =
    [Channel::SuTMotorEnc, Channel::TKistlerL, Channel::TKistlerR, Channel::SiemensEnc];

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

    /// The stated σ follows the bench's limit factor sample by sample (the flange
    /// torque half way into its ramp: the torque's and the DC current's `at_limit` half
    /// added); a counted speed and a derived channel have none, nor anything unstated.
    #[test]
    fn stated_noise_follows_the_operating_limits() {
        let torque = [0.0, 95.0, 200.0];
        let series = |c: Channel| (c == Channel::CKistlerR).then_some(&torque[..]);
        let chans = [Some(Channel::CKistlerL), Some(Channel::IDc), Some(Channel::SiemensEnc), None];
        let stated = SensorModel { stated: Some(NoiseModel::default()), ..SensorModel::bench() };
        let sd = stated.stated_sigma(&chans, series, 3);
        assert_eq!(sd[0].as_deref(), Some(&[0.3, 0.3 + 0.5 * 2.5, 0.3 + 2.5][..]));
        assert_eq!(sd[1].as_deref(), Some(&[0.1, 0.1 + 0.5 * 0.5, 0.1 + 0.5][..]));
        assert!(sd[2].is_none() && sd[3].is_none());
        assert!(SensorModel::bench().stated_sigma(&chans, series, 3).iter().all(Option::is_none));
    }

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
        let avg = recorded(&rpm, dt, Keep::ALL);
        for (k, (a, b)) in enc.iter().zip(&avg).enumerate() {
            assert!((a - f64::from(*b)).abs() < 1e-3, "k={k}: encoder {a} vs average {b}");
        }
        // A ramp's centred average is the ramp itself away from its corners.
        assert!((avg[500] - 100.0).abs() < 0.11, "{}", avg[500]);
    }

    /// A speed and a plain channel through the bench's sensors (0.1 s window), keeping
    /// the samples `keep` names.
    fn recorded_pair(rpm: &[f32], dt: f64, keep: Keep) -> Vec<Vec<f32>> {
        let chans = [Channel::SuTMotorEnc, Channel::IDc];
        let mut r = SensorModel::counting(0.1).recorder(&chans, dt, rpm.len(), keep);
        for (k, v) in rpm.iter().enumerate() {
            r.record(|c| if c == Channel::IDc { k as f32 } else { *v });
        }
        r.finish()
    }

    fn recorded(rpm: &[f32], dt: f64, keep: Keep) -> Vec<f32> {
        recorded_pair(rpm, dt, keep).swap_remove(0)
    }

    /// Keeping every `stride`-th sample from `first` gives exactly those samples of the
    /// full record, windowed speeds included (the windows still see every step).
    #[test]
    fn a_strided_record_is_the_full_record_strided() {
        let rpm: Vec<f32> = (0..1003).map(|k| (k as f32 * 0.013).sin() * 300.0 + (k % 7) as f32).collect();
        let full = recorded_pair(&rpm, 1e-3, Keep::ALL);
        for keep in
            [Keep { first: 0, stride: 5 }, Keep { first: 3, stride: 25 }, Keep { first: 1002, stride: 4 }]
        {
            let part = recorded_pair(&rpm, 1e-3, keep);
            for (f, p) in full.iter().zip(&part) {
                let want: Vec<u32> =
                    f.iter().skip(keep.first).step_by(keep.stride).map(|v| v.to_bits()).collect();
                let got: Vec<u32> = p.iter().map(|v| v.to_bits()).collect();
                assert_eq!(got, want, "{keep:?}");
                assert_eq!(p.len(), keep.count(rpm.len()));
            }
        }
        assert_eq!(recorded_pair(&rpm, 1e-3, Keep { first: 1003, stride: 2 })[0].len(), 0);
        // The plain channel is stored as given; the speed is averaged (a different value).
        assert_eq!(full[1][10], 10.0);
        assert_ne!(full[0][10].to_bits(), rpm[10].to_bits());
    }
}
