//! Small dense linear algebra for the fits (a few dozen unknowns at most).

/// Symmetric positive (semi)definite solve by Cholesky with a relative ridge, so that
/// unidentifiable directions give a minimum-norm-like answer instead of a blow-up.
/// `g` is row-major `n x n`. Returns `None` only for empty or non-finite input.
pub fn solve_spd(g: &[f64], b: &[f64], ridge: f64) -> Option<Vec<f64>> {
    let n = b.len();
    if n == 0 || g.len() != n * n || g.iter().chain(b).any(|v| !v.is_finite()) {
        return None;
    }
    let scale = (0..n).map(|i| g[i * n + i]).fold(0.0f64, f64::max).max(1e-300);
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = g[i * n + j];
            if i == j {
                s += ridge * scale;
            }
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                l[i * n + i] = if s > 1e-300 { s.sqrt() } else { 1e-150 };
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
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
    Some(x)
}

/// The sub-matrix of `g` (`n x n`) on the index set `idx`.
pub fn sub_matrix(g: &[f64], n: usize, idx: &[usize]) -> Vec<f64> {
    let m = idx.len();
    let mut out = vec![0.0; m * m];
    for (a, &i) in idx.iter().enumerate() {
        for (c, &j) in idx.iter().enumerate() {
            out[a * m + c] = g[i * n + j];
        }
    }
    out
}

/// `x' g x` for a sub-matrix layout.
pub fn quad(g: &[f64], x: &[f64]) -> f64 {
    let n = x.len();
    let mut s = 0.0;
    for i in 0..n {
        for j in 0..n {
            s += x[i] * g[i * n + j] * x[j];
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_known_system() {
        let g = [4.0, 1.0, 1.0, 3.0];
        let x = solve_spd(&g, &[1.0, 2.0], 0.0).unwrap();
        assert!((4.0 * x[0] + x[1] - 1.0).abs() < 1e-12 && (x[0] + 3.0 * x[1] - 2.0).abs() < 1e-12);
        assert_eq!(sub_matrix(&g, 2, &[1]), vec![3.0]);
        assert!((quad(&g, &[1.0, 1.0]) - 9.0).abs() < 1e-12);
    }

    #[test]
    fn singular_systems_stay_finite() {
        let g = [1.0, 1.0, 1.0, 1.0];
        let x = solve_spd(&g, &[2.0, 2.0], 1e-9).unwrap();
        assert!(x.iter().all(|v| v.is_finite()));
        assert!((x[0] + x[1] - 2.0).abs() < 1e-3);
    }
}
