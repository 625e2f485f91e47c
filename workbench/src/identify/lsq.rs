//! Weighted linear least squares with parameter covariance, for the fits of the
//! identifications (grids of a few hundred unknowns at most: dense Cholesky suffices).
//!
//! An optional Gaussian prior per parameter (mean, standard deviation) keeps directions
//! the data do not determine at the prior mean instead of blowing up; comparing a
//! parameter's posterior and prior deviation then tells whether the data determined it.

use crate::linalg::{chol_inverse, chol_solve, cholesky};

/// A row of the design: `(parameter index, coefficient)` pairs, the observation and its
/// standard deviation.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub coef: Vec<(usize, f64)>,
    pub y: f64,
    pub sd: f64,
}

/// A fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub x: Vec<f64>,
    /// Posterior covariance, row-major `n x n`.
    pub cov: Vec<f64>,
    /// Weighted sum of squared residuals of the data rows.
    pub chi2: f64,
    /// Data rows.
    pub m: usize,
}

impl Fit {
    /// Standard deviation of parameter `i`.
    pub fn sd(&self, i: usize) -> f64 {
        let n = self.x.len();
        self.cov.get(i * n + i).map_or(f64::NAN, |v| v.max(0.0).sqrt())
    }

    /// Residual `y - fit` of a row.
    pub fn residual(&self, r: &Row) -> f64 {
        r.y - r.coef.iter().map(|(i, c)| c * self.x.get(*i).copied().unwrap_or(0.0)).sum::<f64>()
    }
}

/// Weighted least squares over `n` parameters; `prior`: per parameter `(mean, sd)`
/// (`sd = inf`: none). `None` when the normal matrix is singular (no prior and a
/// direction the data do not determine) or the input is not finite.
pub fn wls(rows: &[Row], n: usize, prior: Option<&[(f64, f64)]>) -> Option<Fit> {
    let mut g = vec![0.0; n * n];
    let mut b = vec![0.0; n];
    for r in rows {
        if !(r.sd > 0.0 && r.sd.is_finite() && r.y.is_finite()) {
            return None;
        }
        let w = 1.0 / (r.sd * r.sd);
        for &(i, ci) in &r.coef {
            if i >= n || !ci.is_finite() {
                return None;
            }
            b[i] += w * ci * r.y;
            for &(j, cj) in &r.coef {
                g[i * n + j] += w * ci * cj;
            }
        }
    }
    if let Some(p) = prior {
        for (i, &(mu, sd)) in p.iter().enumerate().take(n) {
            if sd.is_finite() && sd > 0.0 {
                g[i * n + i] += 1.0 / (sd * sd);
                b[i] += mu / (sd * sd);
            }
        }
    }
    let l = cholesky(&g, n)?;
    let x = chol_solve(&l, n, &b);
    let cov = chol_inverse(&l, n);
    let mut fit = Fit { x, cov, chi2: 0.0, m: rows.len() };
    fit.chi2 = rows.iter().map(|r| (fit.residual(r) / r.sd).powi(2)).sum();
    Some(fit)
}

/// Straight line `y = a + b x` by weighted least squares: `(a, b, cov(a, b), chi2)`.
pub fn line(x: &[f64], y: &[f64], sd: &[f64]) -> Option<Fit> {
    let rows: Vec<Row> = x
        .iter()
        .zip(y)
        .zip(sd)
        .map(|((x, y), s)| Row { coef: vec![(0, 1.0), (1, *x)], y: *y, sd: *s })
        .collect();
    wls(&rows, 2, None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identify_lsq_recovers_a_line_with_its_uncertainty() {
        // y = 2 + 3x, equal weights: textbook variances.
        let x: Vec<f64> = (0..10).map(f64::from).collect();
        let y: Vec<f64> = x.iter().map(|x| 2.0 + 3.0 * x).collect();
        let sd = vec![0.5; 10];
        let f = line(&x, &y, &sd).unwrap();
        assert!((f.x[0] - 2.0).abs() < 1e-9 && (f.x[1] - 3.0).abs() < 1e-9);
        let sxx: f64 = x.iter().map(|v| (v - 4.5).powi(2)).sum();
        assert!((f.sd(1) - 0.5 / sxx.sqrt()).abs() < 1e-12);
        assert!(f.chi2 < 1e-12);
        // Undetermined without a prior; held at the prior with one.
        let rows = vec![Row { coef: vec![(0, 1.0), (1, 1.0)], y: 4.0, sd: 0.1 }];
        assert!(wls(&rows, 2, None).is_none());
        let f = wls(&rows, 2, Some(&[(1.0, 1e3), (1.0, 1e3)])).unwrap();
        assert!((f.x[0] + f.x[1] - 4.0).abs() < 1e-6 && (f.x[0] - f.x[1]).abs() < 1e-6);
        assert!(f.sd(0) > 100.0, "the split is not determined: {}", f.sd(0));
        assert!(wls(&[Row { coef: vec![(5, 1.0)], y: 1.0, sd: 1.0 }], 2, None).is_none());
    }
}
