//! Panic-free numeric helpers for the step.

/// `v` limited to `[lo, hi]`. Unlike `f32::clamp`, no `lo <= hi` assertion (a panic
/// path the target's step must not link when the bounds are run-time values); the
/// same bits as `f32::clamp` whenever `lo <= hi`, and a NaN `v` passes through.
#[inline(always)]
pub(crate) fn clamp(v: f32, lo: f32, hi: f32) -> f32 {
    if v < lo {
        lo
    } else if v > hi {
        hi
    } else {
        v
    }
}
