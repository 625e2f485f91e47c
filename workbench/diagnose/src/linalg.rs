//! Matrix helpers of the diagnosis; the factorisation and solves are shared
//! (`simrod_numerics::linalg`).

pub use simrod_numerics::linalg::{chol_solve, cholesky, solve_spd};

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

/// `a · b`, summed in order.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
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
