//! Pulse encoders as the data acquisition sees them: the shaft angle is integrated from
//! the model's speed (trapezoid rule over each sample interval), every pulse edge it
//! crosses is counted (signed: quadrature decoding knows the direction), and the speed
//! of a sample is the counted pulses in a window centred on it divided by the window.
//! The speeds are therefore whole multiples of `60 / (ppr * window)` rpm.
//!
//! Centred, not trailing: a trailing window would delay every speed by half a window,
//! which a comparison with the twin would mistake for a controller delay.

/// One encoder on one shaft.
#[derive(Debug, Clone)]
pub struct Encoder {
    ppr: f64,
    /// Shaft position in pulses (continuous); its floor is the last edge passed.
    pos: f64,
    /// Edges counted so far (signed).
    counted: i64,
}

impl Encoder {
    /// `phase` in [0, 1): where between two edges the shaft starts.
    pub fn new(ppr: u32, phase: f64) -> Self {
        Self { ppr: f64::from(ppr), pos: phase, counted: 0 }
    }

    /// Advance over one interval `dt` [s] in which the speed went from `rpm0` to `rpm1`;
    /// `lost(rpm)` says whether one edge at that speed is lost. Returns the count.
    pub fn advance(&mut self, rpm0: f64, rpm1: f64, dt: f64, lost: &mut dyn FnMut(f64) -> bool) -> i64 {
        self.advance_edges(rpm0, rpm1, dt, lost, &mut |_, _| {})
    }

    /// [`Encoder::advance`], also reporting every counted edge as `edge(fraction, count)`:
    /// where in the interval it fell (0..=1; the angle is taken as linear in time within
    /// one sample, as the trapezoid rule makes it at the ends) and the count after it.
    /// Edges and losses are drawn in the same order as `advance`, so both give the same
    /// counts from the same random stream.
    pub fn advance_edges(
        &mut self,
        rpm0: f64,
        rpm1: f64,
        dt: f64,
        lost: &mut dyn FnMut(f64) -> bool,
        edge: &mut dyn FnMut(f64, i64),
    ) -> i64 {
        let next = self.pos + 0.5 * (rpm0 + rpm1) / 60.0 * dt * self.ppr;
        let base = self.pos.floor() as i64;
        let edges = next.floor() as i64 - base;
        let span = next - self.pos;
        for e in 0..edges.unsigned_abs() {
            // The level crossed: base + 1, base + 2, ... forward; base, base - 1, ... back.
            let level = if edges > 0 { base + 1 + e as i64 } else { base - e as i64 };
            if !lost(rpm1) {
                self.counted += edges.signum();
                let frac = if span != 0.0 { ((level as f64 - self.pos) / span).clamp(0.0, 1.0) } else { 1.0 };
                edge(frac, self.counted);
            }
        }
        self.pos = next;
        self.counted
    }
}

/// Counts of a whole run: `counts[0]` at t = 0 (at rest), `counts[k + 1]` after sample `k`.
/// Returns one speed [rpm] per sample from a window of `2 * half` intervals centred on
/// it, shortened to what exists at the ends of the run.
pub fn windowed_rpm(counts: &[i64], ppr: u32, dt: f64, half: usize) -> Vec<f64> {
    let n = counts.len().saturating_sub(1);
    (0..n)
        .map(|k| {
            let c = k + 1;
            let lo = c.saturating_sub(half);
            let hi = (c + half).min(n);
            let pulses = (counts[hi] - counts[lo]) as f64;
            pulses / f64::from(ppr) / ((hi - lo) as f64 * dt) * 60.0
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_speed_counts_exactly() {
        // 60 rpm = 1 rev/s; 60 ppr -> 60 edges per second, 0.06 per ms.
        let mut e = Encoder::new(60, 0.5);
        let mut counts = vec![0];
        for _ in 0..1000 {
            counts.push(e.advance(60.0, 60.0, 1e-3, &mut |_| false));
        }
        assert_eq!(*counts.last().unwrap(), 60);
        let w = windowed_rpm(&counts, 60, 1e-3, 50);
        // 0.1 s window: 6 pulses (or 5/7 depending on the phase) of 10 rpm each.
        assert!(w[100..900].iter().all(|v| [50.0, 60.0, 70.0].contains(&(v.round()))), "{:?}", &w[100..110]);
        let mean = w[100..900].iter().sum::<f64>() / 800.0;
        assert!((mean - 60.0).abs() < 1.0, "{mean}");
    }

    #[test]
    fn reverse_counts_down_and_losses_drop_edges() {
        let mut e = Encoder::new(128, 0.5);
        for _ in 0..1000 {
            e.advance(-60.0, -60.0, 1e-3, &mut |_| false);
        }
        assert_eq!(e.counted, -128);
        let mut e = Encoder::new(128, 0.5);
        let mut k = 0;
        for _ in 0..1000 {
            e.advance(60.0, 60.0, 1e-3, &mut |_| {
                k += 1;
                k % 4 == 0
            });
        }
        assert_eq!(e.counted, 96);
    }
}
