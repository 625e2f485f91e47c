//! The measurement chain of every measured channel: what the sensor, its amplifier and
//! the acquisition do to the physical signal before it is written to the bench's file.
//! Four effects, each with one parameter per channel of [`MEASURED`] (declared in
//! [`crate::effects`]): `sensor_gain` and `sensor_offset` (the sensor's calibration),
//! `sensor_lag` (a first-order amplifier or anti-alias filter) and `sensor_delay` (the
//! channel sampled late: an acquisition unit without a shared clock, by any time, not
//! only whole steps: a 2.3 ms skew realised as 2 ms was fitted better by a lag).
//!
//! Order, as on the bench: `gain x + offset` at the sensor, the lag on the amplifier's
//! output, then the delay of the acquisition. The derived channels (powers, sums) are
//! computed from the chain's output, as the thesis computes them from the recorded
//! channels (5.13).
//!
//! Start: the run starts at rest, so before the first step the lag sits at, and the
//! delay line is filled with, the channel's first value (not 0: a voltage starts at
//! 24 V). Coefficients are computed once at construction in f64 with basic operations
//! only (the exponential through [`crate::expm`]), so host and target agree bit for bit.

use crate::expm::expm;
use crate::num::Real;
use crate::outputs::MEASURED;

/// Number of measured channels: one chain each.
pub const N_MEASURED: usize = MEASURED.len();

/// Delay-line samples shared by all channels (512 B): a channel delayed by `d` steps
/// takes `d` of them, in [`MEASURED`] order. 128 ms at 1 ms in all, beyond the 1-100 ms
/// skews of unsynchronised acquisition units; a channel beyond what is left is cut to it.
pub const SENSOR_DELAY_CAPACITY: usize = 128;

/// First-order lag `tau dy/dt = x - y`, exact for an input linear between samples
/// (first-order hold): `y1 = a y0 + b x1 - c (x1 - x0)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Lag<R = f32> {
    a: R,
    b: R,
    c: R,
}

impl<R: Real> Lag<R> {
    /// The coefficients for time constant `tau` [s] at step `dt` [s]; `None` for 0 (off).
    /// Not inlined: one copy of the exponential for all channels (flash).
    #[inline(never)]
    fn new(tau: f32, dt: f64) -> Option<Self> {
        if tau <= 0.0 {
            return None;
        }
        let r = dt / f64::from(tau);
        let a = expm(&[[-r]])[0][0];
        let b = 1.0 - a;
        // (1 - e^-r) / r - e^-r, by its series where the difference cancels.
        let c = if r < 1e-3 { r * (0.5 - r * (1.0 / 3.0 - r / 8.0)) } else { b / r - a };
        Some(Self { a: R::from_f64(a), b: R::from_f64(b), c: R::from_f64(c) })
    }
}

/// One channel's delay: its slots of the shared line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Slots {
    start: u8,
    len: u8,
}

/// A delay of `seconds` at step `dt_s` as whole steps and the fraction of a step beyond
/// them, in [0, 1). A delay within 1e-4 of a step of a whole number is that number, so
/// a delay of whole steps stays an exact shift despite the f32 value's round-off (0.1 s
/// is 100.0000015 steps; f32 keeps 6e-8 of 128 steps, 8e-6).
pub fn delay_split(seconds: f32, dt_s: f64) -> (u64, f64) {
    const WHOLE: f64 = 1e-4;
    let steps = (f64::from(seconds) / dt_s).max(0.0);
    let whole = (steps + WHOLE) as u64;
    let frac = steps - whole as f64;
    (whole, if frac > WHOLE { frac } else { 0.0 })
}

/// The delay-line slots a delay of `seconds` takes at step `dt_s`: one per whole step,
/// and one more for a fraction (it interpolates towards the value a step older).
pub fn delay_slots(seconds: f32, dt_s: f64) -> u64 {
    let (whole, frac) = delay_split(seconds, dt_s);
    whole + u64::from(frac > 0.0)
}

/// The chain's coefficients, fixed at construction.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain<R: Real = f32> {
    gain: [R; N_MEASURED],
    offset: [R; N_MEASURED],
    /// In the wide format: a lag's weights are as small as the step over its time
    /// constant.
    lag: [Option<Lag<R::Wide>>; N_MEASURED],
    delay: [Slots; N_MEASURED],
    /// Each delay's fraction of a step beyond its whole steps ([`delay_split`]); 0 for a
    /// delay cut by the line's end.
    frac: [R; N_MEASURED],
    /// Some channel has a lag or a delay (else the step is a calibration only).
    dynamic: bool,
    /// Every gain 1 and every offset 0: with exact sums (`Real::EXACT_SUM`, fixed point)
    /// `v 1 + 0` is `v`, and the calibration is skipped.
    unity: bool,
}

/// What the chain remembers between steps.
#[derive(Debug, Clone)]
pub struct ChainState<R: Real = f32> {
    started: bool,
    /// Lag outputs (wide: they accumulate) and inputs of the last step.
    y: [R::Wide; N_MEASURED],
    x: [R; N_MEASURED],
    /// Write positions, relative to each channel's first slot.
    pos: [u8; N_MEASURED],
    line: [R; SENSOR_DELAY_CAPACITY],
}

impl<R: Real> Default for ChainState<R> {
    fn default() -> Self {
        Self {
            started: false,
            y: [R::Wide::ZERO; N_MEASURED],
            x: [R::ZERO; N_MEASURED],
            pos: [0; N_MEASURED],
            line: [R::ZERO; SENSOR_DELAY_CAPACITY],
        }
    }
}

impl<R: Real> Chain<R> {
    /// From the effects' per-channel values (validated) at step `dt` [s].
    pub fn new(
        gain: [f32; N_MEASURED],
        offset: [f32; N_MEASURED],
        lag_s: [f32; N_MEASURED],
        delay_s: [f32; N_MEASURED],
        dt: f64,
    ) -> Self {
        let mut delay = [Slots::default(); N_MEASURED];
        let mut frac = [R::ZERO; N_MEASURED];
        let mut used = 0usize;
        for ((slot, f), d) in delay.iter_mut().zip(frac.iter_mut()).zip(delay_s) {
            let (whole, fraction) = delay_split(d, dt);
            let wanted = whole as usize + usize::from(fraction > 0.0);
            let len = wanted.min(SENSOR_DELAY_CAPACITY - used);
            if len == wanted {
                *f = R::from_f64(fraction);
            }
            *slot = Slots { start: used as u8, len: len as u8 };
            used += len;
        }
        let lag = lag_s.map(|t| Lag::new(t, dt));
        let dynamic = lag.iter().any(Option::is_some) || delay.iter().any(|s| s.len > 0);
        let unity = gain.iter().all(|g| *g == 1.0) && offset.iter().all(|k| *k == 0.0);
        Self { gain: gain.map(R::lit), offset: offset.map(R::lit), lag, delay, frac, dynamic, unity }
    }

    /// Each channel's delay-line slots, as realised (a fractional delay takes one more
    /// than its whole steps).
    pub fn delay_steps(&self) -> [usize; N_MEASURED] {
        self.delay.map(|s| usize::from(s.len))
    }

    /// The recorded values of one step from the physical ones, in [`MEASURED`] order.
    #[inline]
    pub fn apply(&self, s: &mut ChainState<R>, raw: &[R; N_MEASURED]) -> [R; N_MEASURED] {
        let mut out = *raw;
        if !(R::EXACT_SUM && self.unity) {
            for ((o, v), (g, k)) in out.iter_mut().zip(raw).zip(self.gain.iter().zip(&self.offset)) {
                *o = *v * *g + *k;
            }
        }
        if self.dynamic {
            self.lag_and_delay(s, &mut out);
        }
        out
    }

    /// The amplifiers' lags, then the acquisition's delays, in place.
    fn lag_and_delay(&self, s: &mut ChainState<R>, out: &mut [R; N_MEASURED]) {
        let first = !s.started;
        s.started = true;
        let lags = self.lag.iter().zip(s.y.iter_mut().zip(s.x.iter_mut()));
        for (v, (lag, (y, x))) in out.iter_mut().zip(lags) {
            if let Some(lag) = lag {
                if first {
                    (*y, *x) = (v.wide(), *v);
                }
                *y = lag.a * *y + lag.b * v.wide() - lag.c * (*v - *x).wide();
                *x = *v;
                *v = R::narrow(*y);
            }
        }
        let delays = self.delay.iter().zip(&self.frac);
        for (v, ((slots, frac), pos)) in out.iter_mut().zip(delays.zip(s.pos.iter_mut())) {
            *v = delayed(&mut s.line, *slots, *frac, pos, *v, first);
        }
    }
}

/// Push `v` into the channel's slots and return the value `len` steps old, or with a
/// fraction `f` of a step the value `len - 1 + f` steps old: linear between the two
/// samples around it, as a channel sampled between the model's steps sees a signal
/// that is smooth at the step's scale. On the first step the slots are filled with `v`
/// (the run starts at rest).
#[inline]
fn delayed<R: Real>(
    line: &mut [R; SENSOR_DELAY_CAPACITY],
    slots: Slots,
    f: R,
    pos: &mut u8,
    v: R,
    first: bool,
) -> R {
    if slots.len == 0 {
        return v;
    }
    let (start, len) = (usize::from(slots.start), usize::from(slots.len));
    let Some(mine) = line.get_mut(start..start + len) else { return v };
    if first {
        mine.fill(v);
    }
    let p = usize::from(*pos);
    let next = if p + 1 >= len { 0 } else { p + 1 };
    // With a fraction, the value one step younger than the oldest: the next slot, or
    // `v` for one slot (read before the write; a whole delay reads nothing more).
    let younger = (f != R::ZERO).then(|| if len == 1 { v } else { mine.get(next).copied().unwrap_or(v) });
    let Some(slot) = mine.get_mut(p) else { return v };
    let oldest = *slot;
    *slot = v;
    *pos = next as u8;
    match younger {
        Some(y) => y + f * (oldest - y),
        None => oldest,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const N: usize = N_MEASURED;

    fn chain(lag: f32, delay: f32, ch: usize) -> Chain<f32> {
        let mut lags = [0.0; N];
        let mut delays = [0.0; N];
        lags[ch] = lag;
        delays[ch] = delay;
        Chain::new([1.0; N], [0.0; N], lags, delays, 1e-3)
    }

    fn run(c: &Chain<f32>, ch: usize, xs: &[f32]) -> std::vec::Vec<f32> {
        let mut s = ChainState::default();
        xs.iter()
            .map(|&x| {
                let mut raw = [0.0; N];
                raw[ch] = x;
                c.apply(&mut s, &raw)[ch]
            })
            .collect()
    }

    #[test]
    fn neutral_chain_passes_every_value_through() {
        let c = Chain::<f32>::new([1.0; N], [0.0; N], [0.0; N], [0.0; N], 1e-3);
        let mut s = ChainState::default();
        let raw: [f32; N] = core::array::from_fn(|i| i as f32 * 1.5 - 3.0);
        assert_eq!(c.apply(&mut s, &raw), raw);
    }

    #[test]
    fn gain_and_offset_calibrate_each_channel() {
        let mut g = [1.0; N];
        let mut k = [0.0; N];
        (g[2], k[2]) = (1.05, 1.5);
        let c = Chain::<f32>::new(g, k, [0.0; N], [0.0; N], 1e-3);
        let out = c.apply(&mut ChainState::default(), &[10.0; N]);
        assert_eq!(out[2], 10.0 * 1.05 + 1.5);
        assert_eq!(out[3], 10.0);
    }

    #[test]
    fn delay_shifts_by_whole_steps_from_the_first_value() {
        let out = run(&chain(0.0, 0.003, 1), 1, &[5.0, 6.0, 7.0, 8.0, 9.0]);
        assert_eq!(out, [5.0, 5.0, 5.0, 5.0, 6.0]);
    }

    /// A ramp delayed by 2.3 steps is the ramp 2.3 steps later, exactly: linear
    /// interpolation is exact on a line. Before the ramp, the first value (at rest).
    #[test]
    fn a_fractional_delay_interpolates_between_the_steps_around_it() {
        let xs: std::vec::Vec<f32> = (0..10).map(|k| 4.0 + k as f32 * 0.5).collect();
        let out = run(&chain(0.0, 0.0023, 1), 1, &xs);
        for (k, y) in out.iter().enumerate() {
            let want = 4.0 + (k as f64 - 2.3).max(0.0) * 0.5;
            assert!((f64::from(*y) - want).abs() < 1e-5, "step {k}: {y} vs {want}");
        }
        // Under one step: between the value and the one before it.
        let out = run(&chain(0.0, 0.00025, 1), 1, &[0.0, 8.0, 8.0]);
        assert_eq!(out, [0.0, 6.0, 8.0]);
    }

    #[test]
    fn delays_are_split_into_whole_steps_and_a_fraction() {
        assert_eq!(delay_split(0.003, 1e-3), (3, 0.0), "f32 round-off is not a fraction");
        let (whole, frac) = delay_split(0.0023, 1e-3);
        assert_eq!(whole, 2);
        assert!((frac - 0.3).abs() < 1e-6, "{frac}");
        assert_eq!((delay_slots(0.0023, 1e-3), delay_slots(0.003, 1e-3), delay_slots(0.0, 1e-3)), (3, 3, 0));
    }

    #[test]
    fn delays_share_the_line_and_are_cut_beyond_it() {
        let mut d = [0.0; N];
        (d[0], d[1], d[2]) = (0.1, 0.02, 0.1);
        let c = Chain::<f32>::new([1.0; N], [0.0; N], [0.0; N], d, 1e-3);
        assert_eq!(c.delay_steps()[..3], [100, 20, SENSOR_DELAY_CAPACITY - 120]);
        // A fractional delay takes a slot more; one cut by the line's end loses its fraction.
        (d[1], d[2]) = (0.0205, 0.1);
        let c = Chain::<f32>::new([1.0; N], [0.0; N], [0.0; N], d, 1e-3);
        assert_eq!(c.delay_steps()[..3], [100, 21, SENSOR_DELAY_CAPACITY - 121]);
        assert_eq!((c.frac[2], c.frac[1] > 0.49 && c.frac[1] < 0.51), (0.0, true));
    }

    /// Against the lag's continuous solution for a ramp from rest at 0:
    /// y(t) = t - tau (1 - e^(-t/tau)), which the first-order hold reproduces exactly.
    #[test]
    fn lag_follows_the_exact_ramp_response() {
        let tau = 0.04;
        let xs: std::vec::Vec<f32> = (0..200).map(|k| k as f32 * 1e-3).collect();
        let out = run(&chain(tau as f32, 0.0, 4), 4, &xs);
        for (k, y) in out.iter().enumerate() {
            let t = k as f64 * 1e-3;
            let want = t - tau * (1.0 - (-t / tau).exp());
            assert!((f64::from(*y) - want).abs() < 2e-6, "k {k}: {y} vs {want}");
        }
    }
}
