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
    /// A small whole number (exact in both).
    fn from_u8(n: u8) -> Self;
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

    /// `(u1 2^32 + u0) / v` and its remainder for `u1 < v` (the quotient fits 32 bits),
    /// from two 32-bit hardware divisions on 16-bit digits (Hacker's Delight 9-3,
    /// `divlu`). A 64-bit division routine on a 32-bit core is a bit loop instead.
    #[inline]
    pub(crate) fn divlu(u1: u32, u0: u32, v: core::num::NonZeroU32) -> (u32, u32) {
        const B: u32 = 1 << 16;
        let s = v.leading_zeros();
        let v = v.get() << s;
        // Normalised: the top bit of v is set, so its high digit is not 0.
        let (vn1, vn0) = (v >> 16, v & 0xffff);
        let Some(d1) = core::num::NonZeroU32::new(vn1) else { return (u32::MAX, 0) };
        let un32 = if s == 0 { u1 } else { (u1 << s) | (u0 >> (32 - s)) };
        let un10 = u0 << s;
        let (un1, un0) = (un10 >> 16, un10 & 0xffff);
        // One 16-bit quotient digit of (hi 2^16 + lo) / v, corrected at most twice.
        let digit = |hi: u32, lo: u32| {
            let (mut q, mut rhat) = (hi / d1, hi % d1);
            while q >= B || q * vn0 > (rhat << 16) + lo {
                q -= 1;
                rhat += vn1;
                if rhat >= B {
                    break;
                }
            }
            q
        };
        let q1 = digit(un32, un1);
        let un21 = (un32 << 16).wrapping_add(un1).wrapping_sub(q1.wrapping_mul(v));
        let q0 = digit(un21, un0);
        let r = (un21 << 16).wrapping_add(un0).wrapping_sub(q0.wrapping_mul(v)) >> s;
        ((q1 << 16) | q0, r)
    }

    /// One base-2^32 quotient digit of `(top 2^32 + next) / dn` for a normalised `dn`
    /// (top bit set) and `top < dn`, and the remainder (Knuth, TAOCP 4.3.1, algorithm D:
    /// the estimate from the divisor's high digit is at most 2 too large).
    #[inline]
    fn digit64(top: u64, next: u32, dn: u64) -> (u32, u64) {
        let dh = (dn >> 32) as u32;
        let (th, tl) = ((top >> 32) as u32, top as u32);
        let mut q = match core::num::NonZeroU32::new(dh) {
            Some(d) if th < dh => divlu(th, tl, d).0,
            _ => u32::MAX,
        };
        let num = (u128::from(top) << 32) | u128::from(next);
        let mut prod = u128::from(q) * u128::from(dn);
        while prod > num {
            q -= 1;
            prod -= u128::from(dn);
        }
        (q, (num - prod) as u64)
    }

    /// `I32F32::checked_div` on the bits for a non-zero divisor: the quotient
    /// `(a 2^32) / b` truncated towards zero, `None` beyond i64. `fixed` computes it as
    /// a 128-bit division, which a 32-bit core (no 128-bit division routine) expands
    /// into a 128-step bit loop, and a 64-bit one is a bit loop too; here the quotient's
    /// two base-2^32 digits come from the core's 32-bit divisions ([`divlu`], Knuth's
    /// algorithm D for divisors of two digits). Tested against `checked_div`.
    #[inline]
    pub(crate) fn div_bits(a: i64, b: i64) -> Option<i64> {
        let n = a.unsigned_abs();
        let d = b.unsigned_abs();
        let (nh, nl) = ((n >> 32) as u32, n as u32);
        // |a| 2^32 / d, the dividend's digits (nh, nl, 0).
        let m = if d >> 32 == 0 {
            let d32 = core::num::NonZeroU32::new(d as u32)?;
            if nh >= d32.get() {
                return None;
            }
            let (q1, r) = divlu(nh, nl, d32);
            let (q0, _) = divlu(r, 0, d32);
            (u64::from(q1) << 32) | u64::from(q0)
        } else {
            // Two-digit divisor, normalised; the dividend shifted alike is (n2, n1, n0, 0)
            // with (n2, n1) < dn because |a| < 2^63 <= d 2^32.
            let s = d.leading_zeros();
            let dn = d << s;
            let top = if s == 0 { 0 } else { n >> (64 - s) };
            let (q1, r) = digit64((top << 32) | ((n << s) >> 32), (n << s) as u32, dn);
            let (q0, _) = digit64(r, 0, dn);
            (u64::from(q1) << 32) | u64::from(q0)
        };
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
        fn from_u8(n: u8) -> Self {
            Fx::from_bits(i64::from(n) << 32)
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
        // The 64-by-32 step on its own, against u64 division.
        for _ in 0..1_000_000 {
            let v = (next() as u32).max(1);
            let (u1, u0) = ((next() as u32) % v, next() as u32);
            let n = (u64::from(u1) << 32) | u64::from(u0);
            let want = ((n / u64::from(v)) as u32, (n % u64::from(v)) as u32);
            assert_eq!(super::fx::divlu(u1, u0, core::num::NonZeroU32::new(v).unwrap()), want, "{n} / {v}");
        }
    }
}
