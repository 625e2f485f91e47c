//! Panic-free numeric helpers (basic operations only: the same bits on every target).

/// `v` limited to `[lo, hi]`; unlike `f32::clamp` no `lo <= hi` assertion (a panic path
/// the target's step must not link); a NaN `v` passes through.
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

/// The abscissa where the piecewise-linear curve through `n` points `at(i) = (x_i, y_i)`,
/// `y` non-decreasing, first reaches `q`: the inverse of a monotone table. Below the
/// first point the first `x`, above the last the first `x` of the highest `y`; the flag
/// says the value was clipped there. Flat stretches are skipped (the lowest `x` wins).
/// Also the index of the segment's end (0 when clipped), for [`invert_monotone_hinted`].
#[inline]
pub(crate) fn invert_monotone(n: usize, at: impl Fn(usize) -> (f32, f32), q: f32) -> (f32, bool, usize) {
    let (x0, y0) = at(0);
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    if !(q > y0) {
        // At or below the first value (NaN too): the first abscissa.
        return (x0, q < y0 || q.is_nan(), 0);
    }
    let (mut xa, mut ya) = (x0, y0);
    let mut top = (x0, y0);
    for i in 1..n {
        let (xb, yb) = at(i);
        if yb > top.1 {
            top = (xb, yb);
        }
        if yb >= q && yb > ya {
            return (xa + (q - ya) / (yb - ya) * (xb - xa), false, i);
        }
        (xa, ya) = (xb, yb);
    }
    (top.0, true, 0)
}

/// [`invert_monotone`], trying the segment ending at `*hint` first and updating it: the
/// signals move slowly, so the last segment is almost always still the one. The same
/// result: with `y` non-decreasing, a segment with `y_a < q <= y_b` is the first to
/// reach `q`.
#[inline]
pub(crate) fn invert_monotone_hinted(
    n: usize,
    at: impl Fn(usize) -> (f32, f32),
    q: f32,
    hint: &mut usize,
) -> (f32, bool) {
    let h = *hint;
    if h >= 1 && h < n {
        let ((xa, ya), (xb, yb)) = (at(h - 1), at(h));
        if ya < q && q <= yb {
            return (xa + (q - ya) / (yb - ya) * (xb - xa), false);
        }
    }
    let (x, clipped, i) = invert_monotone(n, at, q);
    if i > 0 {
        *hint = i;
    }
    (x, clipped)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_of_a_monotone_table() {
        let pts = [(0.0f32, 0.0f32), (2.0, 200.0), (10.0, 420.0), (80.0, 2100.0), (100.0, 2100.0)];
        let at = |i: usize| pts[i];
        let inv = |q: f32| {
            let (x, clipped, _) = invert_monotone(5, at, q);
            (x, clipped)
        };
        assert_eq!(inv(0.0), (0.0, false));
        assert_eq!(inv(-1.0), (0.0, true));
        assert_eq!(inv(100.0), (1.0, false));
        assert_eq!(inv(310.0), (6.0, false));
        assert_eq!(inv(2100.0), (80.0, false));
        assert_eq!(inv(2200.0), (80.0, true));
        assert_eq!(inv(f32::NAN), (0.0, true));
    }

    /// With any hint, the hinted inverse gives exactly the plain one.
    #[test]
    fn hinted_inverse_is_the_inverse() {
        let pts =
            [(0.0f32, 0.0f32), (2.0, 200.0), (10.0, 420.0), (30.0, 420.0), (80.0, 2100.0), (100.0, 2100.0)];
        let at = |i: usize| pts[i];
        for q in [-5.0f32, 0.0, 1.0, 100.0, 200.0, 300.0, 420.0, 421.0, 2000.0, 2100.0, 2500.0, f32::NAN] {
            for start in 0..8 {
                let mut hint = start;
                let (a, b) = (invert_monotone_hinted(6, at, q, &mut hint), invert_monotone(6, at, q));
                assert_eq!((a.0.to_bits(), a.1), (b.0.to_bits(), b.1), "q {q} hint {start}");
                // Twice: the hint the first call left serves the second.
                let again = invert_monotone_hinted(6, at, q, &mut hint);
                assert_eq!((again.0.to_bits(), again.1), (b.0.to_bits(), b.1), "q {q} hint {start}");
            }
        }
    }
}
