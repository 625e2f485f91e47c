//! The `controller_delay` effect: a pure delay between the throttle and the speed
//! controller, as a fixed-capacity delay line (no heap; [`DELAY_CAPACITY`] steps).

use crate::effects::DELAY_CAPACITY;
use crate::num::Real;

/// Delay length in steps, fixed at construction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Delay {
    len: usize,
}

/// The delay line's samples and write position.
#[derive(Debug, Clone)]
pub struct DelayState<R = f32> {
    buf: [R; DELAY_CAPACITY],
    pos: usize,
}

impl<R: Real> Default for DelayState<R> {
    fn default() -> Self {
        Self { buf: [R::ZERO; DELAY_CAPACITY], pos: 0 }
    }
}

impl Delay {
    /// A delay of `delay_s` at step `dt_s` [s], rounded to whole steps and capped at
    /// [`DELAY_CAPACITY`].
    pub fn new(delay_s: f32, dt_s: f64) -> Self {
        let steps = (f64::from(delay_s) / dt_s + 0.5) as usize;
        Self { len: steps.min(DELAY_CAPACITY) }
    }

    /// Length in steps (0: off).
    pub fn steps(&self) -> usize {
        self.len
    }

    /// Push `v`, return the value of `len` steps ago (0 before the line has filled).
    #[inline]
    pub fn apply<R: Real>(&self, s: &mut DelayState<R>, v: R) -> R {
        if self.len == 0 {
            return v;
        }
        let pos = s.pos;
        let out = s.buf.get(pos).copied().unwrap_or(v);
        if let Some(slot) = s.buf.get_mut(pos) {
            *slot = v;
        }
        s.pos = if pos + 1 >= self.len { 0 } else { pos + 1 };
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delays_by_whole_steps_and_caps() {
        let d = Delay::new(0.003, 1e-3);
        assert_eq!(d.steps(), 3);
        let mut s = DelayState::default();
        let out: [f32; 6] = core::array::from_fn(|k| d.apply(&mut s, k as f32 + 1.0));
        assert_eq!(out, [0.0, 0.0, 0.0, 1.0, 2.0, 3.0]);
        assert_eq!(Delay::new(10.0, 1e-3).steps(), DELAY_CAPACITY);
        let off = Delay::new(0.0, 1e-3);
        assert_eq!(off.apply(&mut s, 7.5), 7.5);
    }
}
