//! Matrix exponential of a small dense matrix, in f64, with basic operations only.
//!
//! Used once at construction to discretize the linear drivetrain exactly (zero-order
//! hold). Only `+ - * /` appear, all correctly rounded under IEEE 754 on every target
//! (Rust never contracts them into FMA), so the host and the Cortex-M4F (soft f64)
//! compute the same bits. Scaling and squaring with a 14-term Taylor series: after
//! scaling the norm is below 0.5, so the truncation error is below 0.5^15/15! ~ 2e-17.

/// Largest absolute row sum.
fn norm_inf<const N: usize>(m: &[[f64; N]; N]) -> f64 {
    let mut best = 0.0;
    for row in m {
        let mut s = 0.0;
        for v in row {
            s += if *v < 0.0 { -*v } else { *v };
        }
        if s > best {
            best = s;
        }
    }
    best
}

fn matmul<const N: usize>(a: &[[f64; N]; N], b: &[[f64; N]; N]) -> [[f64; N]; N] {
    let mut c = [[0.0; N]; N];
    for (ci, ai) in c.iter_mut().zip(a.iter()) {
        for (k, aik) in ai.iter().enumerate() {
            if let Some(bk) = b.get(k) {
                for (cij, bkj) in ci.iter_mut().zip(bk.iter()) {
                    *cij += aik * bkj;
                }
            }
        }
    }
    c
}

/// `exp(m)`.
pub fn expm<const N: usize>(m: &[[f64; N]; N]) -> [[f64; N]; N] {
    // Number of halvings so that |m| / 2^s <= 0.5 (bounded: 60 halvings cover 1e18).
    let mut s = 0u32;
    let mut scale = 1.0;
    let n = norm_inf(m);
    while n * scale > 0.5 && s < 60 {
        scale *= 0.5;
        s += 1;
    }
    let mut a = *m;
    for row in a.iter_mut() {
        for v in row.iter_mut() {
            *v *= scale;
        }
    }
    // Taylor series, Horner form: I + a(I + a/2 (I + a/3 (...))).
    let mut e = identity::<N>();
    for k in (1..=14u32).rev() {
        let mut t = matmul(&a, &e);
        let inv = 1.0 / f64::from(k);
        for row in t.iter_mut() {
            for v in row.iter_mut() {
                *v *= inv;
            }
        }
        e = identity::<N>();
        for (er, tr) in e.iter_mut().zip(t.iter()) {
            for (ev, tv) in er.iter_mut().zip(tr.iter()) {
                *ev += tv;
            }
        }
    }
    for _ in 0..s {
        e = matmul(&e, &e);
    }
    e
}

/// Identity matrix.
pub fn identity<const N: usize>() -> [[f64; N]; N] {
    let mut m = [[0.0; N]; N];
    for (i, row) in m.iter_mut().enumerate() {
        if let Some(v) = row.get_mut(i) {
            *v = 1.0;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_generator() {
        // exp([[0, w], [-w, 0]] t) is a rotation by w t, even for w t >> 1.
        let wt = 12.3_f64;
        let e = expm(&[[0.0, wt], [-wt, 0.0]]);
        assert!((e[0][0] - wt.cos()).abs() < 1e-12, "{}", e[0][0]);
        assert!((e[0][1] - wt.sin()).abs() < 1e-12);
        assert!((e[1][0] + wt.sin()).abs() < 1e-12);
    }

    #[test]
    fn diagonal_decay() {
        let e = expm(&[[-3.0, 0.0], [0.0, 0.5]]);
        assert!((e[0][0] - (-3.0f64).exp()).abs() < 1e-14);
        assert!((e[1][1] - 0.5f64.exp()).abs() < 1e-14);
        assert_eq!(e[0][1], 0.0);
    }
}
