//! The scalars the model computes in ([`Real`]), and panic-free numeric helpers.
//!
//! The twin's physics is written once, generic over [`Real`], a signal scalar with a
//! wide companion ([`Real::Wide`]) for the signals that need more range or resolution:
//! the drivetrain's state and its exact-discretization coefficients, the integrator
//! states, and anything multiplied by the step. Two instances:
//! - `f32`, whose wide companion is f32 itself (the conversions are the identity): the
//!   twin as it always was. Every operation is the plain IEEE operation in the order the
//!   source writes it, so the f32 bits (and the golden hashes) do not change.
//! - [`Fx`] (feature `fixed`): 32-bit fixed point (`fixed::types::I17F15`) for the
//!   signals, with [`FxWide`] (64-bit, `I32F32`) as its wide companion, for
//!   microcontrollers without an FPU. Operations saturate and count (see [`Fx`] and
//!   `docs/MODEL.md`, "The fixed-point twin", for every signal's format).

use core::fmt::Debug;
use core::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};

/// The scalar of the twin's step: the four operations, comparisons, and the few
/// conversions the step needs. Implemented for `f32` and, with feature `fixed`, for [`Fx`].
pub trait Real:
    Copy
    + Debug
    + PartialEq
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
{
    /// The format of the signals that need more range or resolution than this one (the
    /// drivetrain's state and coefficients, integrators, products with the step): `Self`
    /// for f32, [`FxWide`] for [`Fx`].
    type Wide: Real;
    /// A divisor fixed at construction ([`Real::divisor`]): for f32 the value itself (the
    /// step divides, as the twin always did); for fixed point its reciprocal, wide, so
    /// that the step multiplies instead of dividing.
    type Divisor: Copy + Debug + PartialEq;
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// Sums are exact (fixed point): [`Real::two_sum`]'s error term is always 0, so the
    /// low parts of compensated sums stay 0 and products with them can be skipped.
    const EXACT_SUM: bool;
    /// A literal or an f32 value (set points, parameters) as this scalar: `v` itself
    /// for f32; rounded to the nearest representable value for [`Fx`] (NaN to 0).
    fn lit(v: f32) -> Self;
    /// A coefficient computed in f64 at construction: `v as f32` for f32 (the rounding
    /// the twin always used), rounded to the nearest for [`Fx`].
    fn from_f64(v: f64) -> Self;
    /// The value as f32 (exact for f32; rounded to nearest for [`Fx`]).
    fn to_f32(self) -> f32;
    /// A small whole number (exact in both).
    fn from_u8(n: u8) -> Self;
    /// Not NaN and not infinite (always true for [`Fx`]).
    fn is_finite(self) -> bool;
    /// `a + b = s + e` exactly: Knuth's TwoSum for f32 (no FMA, the same bits
    /// everywhere); for [`Fx`], whose sums are exact, `(a + b, 0)`.
    fn two_sum(a: Self, b: Self) -> (Self, Self);
    /// This value in the wide format (exact; the identity for f32).
    fn wide(self) -> Self::Wide;
    /// A wide value in this format: rounded to the nearest (ties up) and saturating for
    /// [`Fx`]; the identity for f32.
    fn narrow(w: Self::Wide) -> Self;
    /// `w n` in the wide format: exactly `w * n.wide()`, for [`Fx`] from two 32-bit
    /// products instead of four (a wide coefficient times a signal).
    fn wide_mul(w: Self::Wide, n: Self) -> Self::Wide;
    /// `d` as a [`Real::Divisor`], for [`Real::div_by`].
    fn divisor(d: Self) -> Self::Divisor;
    /// `self / d`: the quotient itself for f32; for fixed point the product with `d`'s
    /// reciprocal (within one unit of the quotient, rounded from the wide product).
    fn div_by(self, d: Self::Divisor) -> Self;
}

impl Real for f32 {
    type Wide = f32;
    type Divisor = f32;
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const EXACT_SUM: bool = false;
    #[inline(always)]
    fn lit(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }
    #[inline(always)]
    fn from_u8(n: u8) -> Self {
        f32::from(n)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    #[inline(always)]
    fn two_sum(a: Self, b: Self) -> (Self, Self) {
        let s = a + b;
        let bp = s - a;
        let ap = s - bp;
        (s, (a - ap) + (b - bp))
    }
    #[inline(always)]
    fn wide(self) -> f32 {
        self
    }
    #[inline(always)]
    fn narrow(w: f32) -> f32 {
        w
    }
    #[inline(always)]
    fn wide_mul(w: f32, n: f32) -> f32 {
        w * n
    }
    #[inline(always)]
    fn divisor(d: f32) -> f32 {
        d
    }
    #[inline(always)]
    fn div_by(self, d: f32) -> f32 {
        self / d
    }
}

/// `v` limited to `[lo, hi]`. Unlike `f32::clamp`, no `lo <= hi` assertion (a panic
/// path the target's step must not link when the bounds are run-time values); the
/// same bits as `f32::clamp` whenever `lo <= hi`, and a NaN `v` passes through.
#[inline(always)]
pub(crate) fn clamp<R: Real>(v: R, lo: R, hi: R) -> R {
    if v < lo {
        lo
    } else if v > hi {
        hi
    } else {
        v
    }
}

/// The saturating operations both fixed-point formats share: `$t`, a newtype over the
/// `fixed` type `$inner`, with `$mul`/`$div` its product and quotient on the bits
/// (`None` beyond the range). Every result beyond the range is clipped to the nearest
/// end and counted ([`saturations`]); a division by zero gives the end in the
/// numerator's sign (0 for 0 / 0); a NaN converts to 0.
#[cfg(feature = "fixed")]
macro_rules! saturating_fixed {
    ($t:ident, $inner:ty, $mul:path, $div:path) => {
        impl core::fmt::Debug for $t {
            fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                core::fmt::Display::fmt(&self.0, f)
            }
        }

        impl $t {
            /// The end of the range in the sign `positive`, counted as a saturation.
            #[inline(always)]
            pub(super) fn clip(positive: bool) -> Self {
                $crate::num::saturated();
                $t(if positive { <$inner>::MAX } else { <$inner>::MIN })
            }

            /// An f32 rounded to the nearest, saturating (NaN to 0).
            #[inline(always)]
            fn from_f32(v: f32) -> Self {
                match <$inner>::checked_from_num(v) {
                    Some(x) => $t(x),
                    None if v.is_nan() => $t(<$inner>::ZERO),
                    None => $t::clip(v > 0.0),
                }
            }

            /// An f64 rounded to the nearest, saturating (NaN to 0).
            #[inline]
            fn from_f64_saturating(v: f64) -> Self {
                match <$inner>::checked_from_num(v) {
                    Some(x) => $t(x),
                    None if v.is_nan() => $t(<$inner>::ZERO),
                    None => $t::clip(v > 0.0),
                }
            }
        }

        impl core::ops::Add for $t {
            type Output = $t;
            #[inline(always)]
            fn add(self, r: $t) -> $t {
                match self.0.checked_add(r.0) {
                    Some(v) => $t(v),
                    None => $t::clip(r.0 > <$inner>::ZERO),
                }
            }
        }

        impl core::ops::Sub for $t {
            type Output = $t;
            #[inline(always)]
            fn sub(self, r: $t) -> $t {
                match self.0.checked_sub(r.0) {
                    Some(v) => $t(v),
                    None => $t::clip(r.0 < <$inner>::ZERO),
                }
            }
        }

        impl core::ops::Mul for $t {
            type Output = $t;
            #[inline(always)]
            fn mul(self, r: $t) -> $t {
                match $mul(self.to_bits(), r.to_bits()) {
                    Some(v) => $t::from_bits(v),
                    None => $t::clip((self.0 < <$inner>::ZERO) == (r.0 < <$inner>::ZERO)),
                }
            }
        }

        impl core::ops::Div for $t {
            type Output = $t;
            #[inline(always)]
            fn div(self, r: $t) -> $t {
                if r.0 == <$inner>::ZERO {
                    if self.0 == <$inner>::ZERO {
                        $crate::num::saturated();
                        return $t(<$inner>::ZERO);
                    }
                    return $t::clip(self.0 > <$inner>::ZERO);
                }
                match $div(self.to_bits(), r.to_bits()) {
                    Some(v) => $t::from_bits(v),
                    None => $t::clip((self.0 < <$inner>::ZERO) == (r.0 < <$inner>::ZERO)),
                }
            }
        }

        impl core::ops::Neg for $t {
            type Output = $t;
            #[inline(always)]
            fn neg(self) -> $t {
                match self.0.checked_neg() {
                    Some(v) => $t(v),
                    None => $t::clip(true),
                }
            }
        }

        impl core::ops::AddAssign for $t {
            #[inline(always)]
            fn add_assign(&mut self, r: $t) {
                *self = *self + r;
            }
        }

        impl core::ops::SubAssign for $t {
            #[inline(always)]
            fn sub_assign(&mut self, r: $t) {
                *self = *self - r;
            }
        }
    };
}

#[cfg(feature = "fixed")]
mod fx;
#[cfg(feature = "fixed")]
mod fx_wide;
#[cfg(feature = "fixed")]
pub use fx::Fx;
#[cfg(feature = "fixed")]
pub use fx_wide::FxWide;

/// Fixed-point operations that saturated since the program started (all threads).
#[cfg(feature = "fixed")]
static SATURATIONS: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

/// How many [`Fx`] and [`FxWide`] operations have saturated so far in this program: an
/// addition, subtraction, product, quotient or narrowing beyond the format's range, a
/// division by zero, or an f32/f64 value out of range converted. The twin's valid inputs
/// never do (the property test asserts it); a count above zero means a result was
/// clipped, not wrapped.
#[cfg(feature = "fixed")]
pub fn saturations() -> u32 {
    SATURATIONS.load(core::sync::atomic::Ordering::Relaxed)
}

#[cfg(feature = "fixed")]
#[cold]
#[inline(never)]
fn saturated() {
    SATURATIONS.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
}
