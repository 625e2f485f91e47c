//! The scalar the model computes in ([`Real`]), and panic-free numeric helpers.
//!
//! The twin's physics is written once, generic over [`Real`]. Two instances:
//! - `f32`: the twin as it always was. Every operation is the plain IEEE operation in the
//!   order the source writes it, so the f32 bits (and the golden hashes) do not change.
//! - [`Fx`] (feature `fixed`): a signed 64-bit fixed-point number with 32 integer and 32
//!   fractional bits (`fixed::types::I32F32`), for microcontrollers without an FPU. Its
//!   operations saturate and count (see [`Fx`] and `docs/MODEL.md`, "The fixed-point
//!   twin").

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
    /// Not NaN and not infinite (always true for [`Fx`]).
    fn is_finite(self) -> bool;
    /// `a + b = s + e` exactly: Knuth's TwoSum for f32 (no FMA, the same bits
    /// everywhere); for [`Fx`], whose sums are exact, `(a + b, 0)`.
    fn two_sum(a: Self, b: Self) -> (Self, Self);
}

impl Real for f32 {
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

#[cfg(feature = "fixed")]
pub use fx::{saturations, Fx};

#[cfg(feature = "fixed")]
mod fx {
    use super::Real;
    use core::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};
    use core::sync::atomic::{AtomicU32, Ordering};
    use fixed::types::I32F32;

    /// Operations that saturated since the program started (all threads).
    static SATURATIONS: AtomicU32 = AtomicU32::new(0);

    /// How many [`Fx`] operations have saturated so far in this program: an addition,
    /// subtraction, product or quotient beyond ±2^31, a division by zero, or an f32/f64
    /// value out of range converted. The twin's valid inputs never do (the property
    /// test asserts it); a count above zero means a result was clipped, not wrapped.
    pub fn saturations() -> u32 {
        SATURATIONS.load(Ordering::Relaxed)
    }

    #[cold]
    #[inline(never)]
    fn saturated() {
        SATURATIONS.fetch_add(1, Ordering::Relaxed);
    }

    /// The fixed-point scalar: `fixed::types::I32F32`, range ±2^31 (±2.1e9), resolution
    /// 2^-32 (2.3e-10), the same format for every signal (why: `docs/MODEL.md`).
    ///
    /// Every operation saturates: a result beyond the range is clipped to the nearest
    /// end and counted ([`saturations`]); a wrapped result would flip a sign and send the
    /// twin somewhere physically impossible, a clipped one stays the closest value. A
    /// division by zero gives the end of the range in the numerator's sign (0 for 0 / 0),
    /// as IEEE gives an infinity; it is counted too. No operation can panic. Products
    /// round down (towards −∞) and quotients towards zero, as `fixed` does; sums are
    /// exact.
    #[derive(Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
    pub struct Fx(pub I32F32);

    impl core::fmt::Debug for Fx {
        fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
            core::fmt::Display::fmt(&self.0, f)
        }
    }

    impl Fx {
        /// The value of raw bits (a value times 2^32), for tables generated by `build.rs`.
        pub const fn from_bits(bits: i64) -> Self {
            Fx(I32F32::from_bits(bits))
        }

        /// The raw bits (the value times 2^32).
        pub const fn to_bits(self) -> i64 {
            self.0.to_bits()
        }

        #[inline(always)]
        fn clip(positive: bool) -> Self {
            saturated();
            Fx(if positive { I32F32::MAX } else { I32F32::MIN })
        }
    }

    impl Add for Fx {
        type Output = Fx;
        #[inline(always)]
        fn add(self, r: Fx) -> Fx {
            match self.0.checked_add(r.0) {
                Some(v) => Fx(v),
                None => Fx::clip(r.0 > I32F32::ZERO),
            }
        }
    }

    impl Sub for Fx {
        type Output = Fx;
        #[inline(always)]
        fn sub(self, r: Fx) -> Fx {
            match self.0.checked_sub(r.0) {
                Some(v) => Fx(v),
                None => Fx::clip(r.0 < I32F32::ZERO),
            }
        }
    }

    /// `I32F32::checked_mul` on the bits, from four 32 x 32 -> 64-bit products: the
    /// same result (`floor(a b / 2^32)`, `None` beyond i64), without the 128-bit
    /// multiplication `fixed` widens to, which a 32-bit core expands into many more
    /// instructions. Tested against `checked_mul`.
    #[inline(always)]
    pub(crate) fn mul_bits(a: i64, b: i64) -> Option<i64> {
        let (ah, al) = (a >> 32, i64::from(a as u32));
        let (bh, bl) = (b >> 32, i64::from(b as u32));
        // a b = ah bh 2^64 + (ah bl + al bh) 2^32 + al bl: every product fits its type
        // (|ah|, |bh| <= 2^31; al, bl < 2^32), and the floor of a b / 2^32 is exact.
        let ll = (al as u64) * (bl as u64);
        let mid = i128::from(ah * bl) + i128::from(al * bh) + i128::from(ll >> 32);
        let q = (i128::from(ah * bh) << 32) + mid;
        i64::try_from(q).ok()
    }

    /// `I32F32::checked_div` on the bits for a non-zero divisor: the quotient
    /// `(a 2^32) / b` truncated towards zero, `None` beyond i64. `fixed` computes it as
    /// a 128-bit division, which a 32-bit core (no 128-bit division routine) expands
    /// into a 128-step bit loop; here two 64-bit divisions and, for |b| >= 1, a
    /// normalised quotient estimate with at most two corrections (Knuth, TAOCP 4.3.1,
    /// algorithm D). Tested against `checked_div`.
    #[inline]
    pub(crate) fn div_bits(a: i64, b: i64) -> Option<i64> {
        use core::num::NonZeroU64;
        let n = a.unsigned_abs();
        // Divisions by `NonZeroU64`: no division-by-zero panic path in the step.
        let d = NonZeroU64::new(b.unsigned_abs())?;
        // |a| 2^32 / d = q1 2^32 + (r1 2^32) / d, with r1 < d.
        let (q1, r1) = (n / d, n % d);
        if q1 >> 32 != 0 {
            return None;
        }
        let q2 = if d.get() >> 32 == 0 {
            (r1 << 32) / d
        } else {
            // d >= 2^32: normalise so d's top bit is set (r1 < d keeps r1 << s in range).
            let s = d.leading_zeros();
            let (dn, rn) = (d.get() << s, r1 << s);
            let dh = NonZeroU64::new(dn >> 32)?;
            let mut q = (rn / dh).min(u64::from(u32::MAX));
            let num = u128::from(rn) << 32;
            let mut prod = u128::from(q) * u128::from(dn);
            while prod > num {
                q -= 1;
                prod -= u128::from(dn);
            }
            q
        };
        let m = (q1 << 32) | q2;
        if (a < 0) != (b < 0) {
            if m > 1 << 63 {
                None
            } else {
                Some(0i64.wrapping_sub_unsigned(m))
            }
        } else {
            i64::try_from(m).ok()
        }
    }

    impl Mul for Fx {
        type Output = Fx;
        #[inline(always)]
        fn mul(self, r: Fx) -> Fx {
            match mul_bits(self.to_bits(), r.to_bits()) {
                Some(v) => Fx::from_bits(v),
                None => Fx::clip((self.0 < I32F32::ZERO) == (r.0 < I32F32::ZERO)),
            }
        }
    }

    impl Div for Fx {
        type Output = Fx;
        #[inline(always)]
        fn div(self, r: Fx) -> Fx {
            if r.0 == I32F32::ZERO {
                if self.0 == I32F32::ZERO {
                    saturated();
                    return Fx(I32F32::ZERO);
                }
                return Fx::clip(self.0 > I32F32::ZERO);
            }
            match div_bits(self.to_bits(), r.to_bits()) {
                Some(v) => Fx::from_bits(v),
                None => Fx::clip((self.0 < I32F32::ZERO) == (r.0 < I32F32::ZERO)),
            }
        }
    }

    impl Neg for Fx {
        type Output = Fx;
        #[inline(always)]
        fn neg(self) -> Fx {
            match self.0.checked_neg() {
                Some(v) => Fx(v),
                None => Fx::clip(true),
            }
        }
    }

    impl AddAssign for Fx {
        #[inline(always)]
        fn add_assign(&mut self, r: Fx) {
            *self = *self + r;
        }
    }

    impl SubAssign for Fx {
        #[inline(always)]
        fn sub_assign(&mut self, r: Fx) {
            *self = *self - r;
        }
    }

    impl Real for Fx {
        const ZERO: Self = Fx(I32F32::ZERO);
        const ONE: Self = Fx(I32F32::ONE);
        const EXACT_SUM: bool = true;
        #[inline(always)]
        fn lit(v: f32) -> Self {
            match I32F32::checked_from_num(v) {
                Some(x) => Fx(x),
                None if v.is_nan() => Fx::ZERO,
                None => Fx::clip(v > 0.0),
            }
        }
        #[inline]
        fn from_f64(v: f64) -> Self {
            match I32F32::checked_from_num(v) {
                Some(x) => Fx(x),
                None if v.is_nan() => Fx::ZERO,
                None => Fx::clip(v > 0.0),
            }
        }
        #[inline]
        fn to_f32(self) -> f32 {
            self.0.to_num::<f32>()
        }
        #[inline(always)]
        fn is_finite(self) -> bool {
            true
        }
        #[inline(always)]
        fn two_sum(a: Self, b: Self) -> (Self, Self) {
            (a + b, Fx::ZERO)
        }
    }
}

#[cfg(all(test, feature = "fixed"))]
mod tests {
    use super::*;

    /// Saturation clips to the nearest end and is counted; in-range results are exact
    /// (sums) or rounded as documented (products down, quotients towards zero).
    #[test]
    fn fixed_point_saturates_counts_and_never_panics() {
        let big = Fx::lit(2.0e9);
        let before = saturations();
        assert_eq!(big + big, Fx(fixed::types::I32F32::MAX));
        assert_eq!(-big - big, Fx(fixed::types::I32F32::MIN));
        assert_eq!(big * -big, Fx(fixed::types::I32F32::MIN));
        assert_eq!(Fx::ONE / Fx::ZERO, Fx(fixed::types::I32F32::MAX));
        assert_eq!(-Fx::ONE / Fx::ZERO, Fx(fixed::types::I32F32::MIN));
        assert_eq!(Fx::ZERO / Fx::ZERO, Fx::ZERO);
        assert_eq!(Fx::lit(f32::INFINITY), Fx(fixed::types::I32F32::MAX));
        assert_eq!(Fx::lit(f32::NAN), Fx::ZERO);
        assert!(saturations() >= before + 7);
        assert_eq!(Fx::lit(1.5) + Fx::lit(0.25), Fx::lit(1.75));
        assert_eq!(Fx::lit(3.0) * Fx::lit(-0.5), Fx::lit(-1.5));
        assert_eq!(Fx::from_bits(1) * Fx::lit(-0.5), Fx::from_bits(-1), "products round down");
        assert_eq!(Fx::from_bits(-1) / Fx::lit(2.0), Fx::ZERO, "quotients round towards zero");
        assert_eq!(Fx::two_sum(Fx::lit(2.5), Fx::from_bits(1)), (Fx::from_bits((5 << 31) + 1), Fx::ZERO));
        assert_eq!(Fx::lit(0.1).to_f32(), 0.1);
    }

    /// The hand-made product and quotient give `fixed`'s own results, bit for bit and
    /// overflow for overflow: on edge values and 2 million random pairs of every scale.
    #[test]
    fn mul_and_div_equal_fixed_bit_for_bit() {
        use super::fx::{div_bits, mul_bits};
        use fixed::types::I32F32;
        let f = |v: i64| I32F32::from_bits(v);
        let edge = [
            0i64,
            1,
            -1,
            2,
            -2,
            i64::MAX,
            i64::MIN,
            i64::MIN + 1,
            1 << 32,
            -(1 << 32),
            (1 << 32) + 1,
            (1 << 32) - 1,
            1 << 31,
            -(1 << 31),
            1 << 62,
            -(1 << 62),
            u32::MAX as i64,
            -(u32::MAX as i64),
            0x7fff_ffff_0000_0000,
            0x1234_5678_9abc_def0,
        ];
        let check = |a: i64, b: i64| {
            assert_eq!(mul_bits(a, b), f(a).checked_mul(f(b)).map(I32F32::to_bits), "{a} * {b}");
            if b != 0 {
                assert_eq!(div_bits(a, b), f(a).checked_div(f(b)).map(I32F32::to_bits), "{a} / {b}");
            }
        };
        for a in edge {
            for b in edge {
                check(a, b);
            }
        }
        // xorshift64*: values of every magnitude (a random shift of a random word).
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            s ^= s >> 12;
            s ^= s << 25;
            s ^= s >> 27;
            let v = s.wrapping_mul(0x2545_f491_4f6c_dd1d);
            (v as i64) >> (v % 64)
        };
        for _ in 0..2_000_000 {
            let (a, b) = (next(), next());
            check(a, b);
        }
    }
}
