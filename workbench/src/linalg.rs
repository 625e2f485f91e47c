//! Small dense linear algebra shared by the fits (diagnose, identify): a few hundred
//! unknowns at most, so a dense Cholesky factorisation suffices.

/// Cholesky factor `L` (row-major, lower) of an SPD matrix, or `None` if not SPD.
pub fn cholesky(g: &[f64], n: usize) -> Option<Vec<f64>> {
    if g.len() != n * n {
        return None;
    }
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = g[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                // A pivot lost to rounding means a direction the data do not determine.
                if !(s > 1e-13 * g[i * n + i].abs()) || !s.is_finite() {
                    return None;
                }
                l[i * n + i] = s.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    Some(l)
}

/// Solve `L L' x = b`.
pub fn chol_solve(l: &[f64], n: usize, b: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; n];
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * n + k] * y[k];
        }
        y[i] = s / l[i * n + i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let mut s = y[i];
        for k in i + 1..n {
            s -= l[k * n + i] * x[k];
        }
        x[i] = s / l[i * n + i];
    }
    x
}

/// `(L L')^-1`.
pub fn chol_inverse(l: &[f64], n: usize) -> Vec<f64> {
    let mut inv = vec![0.0; n * n];
    let mut e = vec![0.0; n];
    for j in 0..n {
        e.iter_mut().for_each(|v| *v = 0.0);
        e[j] = 1.0;
        let col = chol_solve(l, n, &e);
        for i in 0..n {
            inv[i * n + j] = col[i];
        }
    }
    inv
}

/// Symmetric positive (semi)definite solve with a relative ridge, so that directions the
/// data do not determine give a minimum-norm-like answer instead of a failure. `g` is
/// row-major `n x n`. `None` only for empty or non-finite input.
pub fn solve_spd(g: &[f64], b: &[f64], ridge: f64) -> Option<Vec<f64>> {
    let n = b.len();
    if n == 0 || g.len() != n * n || g.iter().chain(b).any(|v| !v.is_finite()) {
        return None;
    }
    let scale = (0..n).map(|i| g[i * n + i]).fold(0.0f64, f64::max).max(1e-300);
    let mut gr = g.to_vec();
    for i in 0..n {
        gr[i * n + i] += ridge * scale;
        // A parameter with no information at all (an all-zero row) stays at its start.
        if gr[i * n + i] <= 0.0 {
            gr[i * n + i] = 1e-12 * scale;
        }
    }
    Some(chol_solve(&cholesky(&gr, n)?, n, b))
}
