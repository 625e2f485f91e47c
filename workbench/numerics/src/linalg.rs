//! Dense linear algebra for every fit of the workbench (diagnose, identify), on
//! `nalgebra`: Cholesky factorisation and SPD solves, rank-revealing least squares by
//! SVD, and the weighted least squares with optional Gaussian priors that the
//! identifications use. A few hundred unknowns at most, so dense is enough.
//!
//! Matrices cross this module's boundary as row-major `&[f64]` with their size, so the
//! callers need no matrix type; inside, they are `nalgebra` matrices.

use nalgebra::{Cholesky, DMatrix, DMatrixView, DVector, Dyn, SVD};

/// A Cholesky pivot below this share of its diagonal element counts as lost to
/// rounding: a direction the data do not determine.
const PIVOT_RTOL: f64 = 1e-13;

/// Singular values below this share of the largest (after scaling every column to unit
/// length) count as zero. The square root of [`PIVOT_RTOL`]: the same resolution in the
/// design matrix as the Cholesky test has in its normal matrix `A'A`, so both paths call
/// the same fits undetermined.
const RANK_RTOL: f64 = 3.2e-7;

/// Factor a row-major SPD matrix; `None` if a pivot is lost to rounding or anything is
/// not finite. Only the lower triangle is read.
fn factor(g: &[f64], n: usize) -> Option<Cholesky<f64, Dyn>> {
    if g.len() != n * n {
        return None;
    }
    let m = DMatrix::from_row_slice(n, n, g);
    factor_matrix(m)
}

fn factor_matrix(m: DMatrix<f64>) -> Option<Cholesky<f64, Dyn>> {
    let diag: Vec<f64> = m.diagonal().iter().copied().collect();
    let c = Cholesky::new(m)?;
    let l = c.l_dirty();
    let ok = (0..diag.len()).all(|i| {
        let p = l[(i, i)] * l[(i, i)];
        p.is_finite() && p > PIVOT_RTOL * diag[i].abs()
    }) && (0..diag.len()).all(|i| (0..=i).all(|j| l[(i, j)].is_finite()));
    ok.then_some(c)
}

/// Row-major `L` of a Cholesky decomposition handed in by a caller.
fn packed(l: &[f64], n: usize) -> Cholesky<f64, Dyn> {
    Cholesky::pack_dirty(DMatrix::from_row_slice(n, n, l).lower_triangle())
}

fn to_row_major(m: &DMatrix<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

/// Cholesky factor `L` (row-major, lower) of an SPD matrix, or `None` if not SPD (a
/// pivot lost to rounding counts as not SPD).
pub fn cholesky(g: &[f64], n: usize) -> Option<Vec<f64>> {
    factor(g, n).map(|c| to_row_major(&c.l()))
}

/// Solve `L L' x = b` for a factor from [`cholesky`].
pub fn chol_solve(l: &[f64], n: usize, b: &[f64]) -> Vec<f64> {
    packed(l, n).solve(&DVector::from_column_slice(b)).as_slice().to_vec()
}

/// `(L L')^-1`, row-major, for a factor from [`cholesky`].
pub fn chol_inverse(l: &[f64], n: usize) -> Vec<f64> {
    to_row_major(&packed(l, n).inverse())
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
    let mut gr = DMatrix::from_row_slice(n, n, g);
    for i in 0..n {
        gr[(i, i)] += ridge * scale;
        // A parameter with no information at all (an all-zero row) stays at its start.
        if gr[(i, i)] <= 0.0 {
            gr[(i, i)] = 1e-12 * scale;
        }
    }
    let c = factor_matrix(gr)?;
    Some(c.solve(&DVector::from_column_slice(b)).as_slice().to_vec())
}

/// Rows of one block of [`weighted_products`]: its two packed blocks stay in the cache
/// (256 rows of a few hundred columns: well under a megabyte each).
const PRODUCT_ROWS: usize = 256;

/// Every weighted inner product `Σ_c Σ_t w[c][t] a_i[c][t] b_j[c][t]` of the columns `a`
/// and `b` (each `[block][row]`, shaped as `w`), row-major `a.len() x b.len()`: the
/// normal matrix `A'WB` of a weighted least-squares fit. Formed as a blocked matrix
/// product (`matrixmultiply`, through `nalgebra`), not one column pair at a time: there
/// each pair's sequential sum of ~50,000 products waits on every addition, and the
/// estimate within the maps' uncertainty spent a third of its time in them. The sum's
/// order is fixed by the shapes alone, so the bits repeat from run to run on one
/// machine (the product's kernel follows the CPU's features). `None` when a column is
/// not shaped as `w`.
pub fn weighted_products(a: &[&[Vec<f64>]], b: &[&[Vec<f64>]], w: &[Vec<f64>]) -> Option<Vec<f64>> {
    let shaped = |c: &&[Vec<f64>]| c.len() == w.len() && c.iter().zip(w).all(|(x, q)| x.len() == q.len());
    if !a.iter().chain(b).all(shaped) {
        return None;
    }
    let (na, nb) = (a.len(), b.len());
    if na == 0 || nb == 0 {
        return Some(Vec::new());
    }
    let mut sum = DMatrix::<f64>::zeros(na, nb);
    let (mut wa, mut bb) = (Vec::new(), Vec::new());
    for (c, wc) in w.iter().enumerate() {
        for start in (0..wc.len()).step_by(PRODUCT_ROWS) {
            let rows = start..(start + PRODUCT_ROWS).min(wc.len());
            let len = rows.len();
            // Column-major `na x len` (`(w a)'`) and `len x nb` (`b`).
            wa.clear();
            for t in rows.clone() {
                wa.extend(a.iter().map(|col| wc[t] * col[c][t]));
            }
            bb.clear();
            for col in b {
                bb.extend_from_slice(&col[c][rows.clone()]);
            }
            let wat = DMatrixView::from_slice(&wa, na, len);
            let bm = DMatrixView::from_slice(&bb, len, nb);
            sum.gemm(1.0, &wat, &bm, 1.0);
        }
    }
    Some(to_row_major(&sum))
}

/// A least-squares solution with its rank.
#[derive(Debug, Clone, PartialEq)]
pub struct LeastSquares {
    /// The solution; for a rank-deficient design the one of minimum norm in
    /// column-scaled coordinates (undetermined combinations set to zero).
    pub x: Vec<f64>,
    /// Numerical rank of the design (columns scaled to unit length, [`RANK_RTOL`]).
    pub rank: usize,
    /// `(A'A)^+`, row-major `n x n`: the covariance of `x` for unit-variance rows.
    pub cov: Vec<f64>,
}

impl LeastSquares {
    /// Is every parameter determined?
    pub fn full_rank(&self) -> bool {
        self.rank == self.x.len()
    }
}

/// Least squares `min |A x - y|` by SVD, rank-deficient designs included; `a` is
/// row-major `m x n`. Columns are scaled to unit length first, so the rank does not
/// depend on the parameters' units. `None` for empty, mismatched or non-finite input.
pub fn lstsq(a: &[f64], m: usize, n: usize, y: &[f64]) -> Option<LeastSquares> {
    if m == 0 || n == 0 || a.len() != m * n || y.len() != m || a.iter().chain(y).any(|v| !v.is_finite()) {
        return None;
    }
    let mut am = DMatrix::from_row_slice(m, n, a);
    let scale: Vec<f64> = (0..n)
        .map(|j| {
            let norm = am.column(j).norm();
            if norm > 0.0 {
                1.0 / norm
            } else {
                1.0
            }
        })
        .collect();
    for (j, s) in scale.iter().enumerate() {
        am.column_mut(j).scale_mut(*s);
    }
    let svd = SVD::try_new(am, true, true, 5.0 * f64::EPSILON, 10_000)?;
    let (u, vt) = (svd.u.as_ref()?, svd.v_t.as_ref()?);
    let sv = &svd.singular_values;
    let cut = RANK_RTOL * sv.max();
    let keep: Vec<usize> = (0..sv.len()).filter(|&k| sv[k] > cut).collect();
    let yv = DVector::from_column_slice(y);
    // x = D V S^+ U' y and cov = D V S^-2 V' D, over the kept singular values.
    let mut xs = DVector::zeros(n);
    let mut cs = DMatrix::zeros(n, n);
    for &k in &keep {
        let v = vt.row(k).transpose();
        xs += &v * (u.column(k).dot(&yv) / sv[k]);
        cs += &v * v.transpose() / (sv[k] * sv[k]);
    }
    let x = (0..n).map(|j| xs[j] * scale[j]).collect();
    let mut cov = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            cov[i * n + j] = cs[(i, j)] * scale[i] * scale[j];
        }
    }
    Some(LeastSquares { x, rank: keep.len(), cov })
}

/// A row of a weighted least-squares design: `(parameter index, coefficient)` pairs
/// (sparse: a map node's interpolation weights touch few parameters), the observation
/// and its standard deviation.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub coef: Vec<(usize, f64)>,
    pub y: f64,
    pub sd: f64,
}

/// A weighted least-squares fit.
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

/// Weighted least squares over `n` parameters, with an optional Gaussian prior per
/// parameter, `(mean, sd)` (`sd = inf`: none). `None` when a direction is undetermined
/// (no prior holds it), a row names a parameter `>= n`, or the input is not finite.
///
/// With a prior (the map fits: hundreds of nodes, rows touching four) the normal
/// matrix is positive definite by construction and assembled from the sparse rows, so
/// it is factored by Cholesky. Without one (a handful of parameters) the whitened
/// design goes to the rank-revealing [`lstsq`].
pub fn wls(rows: &[Row], n: usize, prior: Option<&[(f64, f64)]>) -> Option<Fit> {
    for r in rows {
        if !(r.sd > 0.0 && r.sd.is_finite() && r.y.is_finite())
            || r.coef.iter().any(|(i, c)| *i >= n || !c.is_finite())
        {
            return None;
        }
    }
    let has_prior = prior.is_some_and(|p| p.iter().take(n).any(|(_, sd)| sd.is_finite() && *sd > 0.0));
    let (x, cov) = if let (true, Some(p)) = (has_prior, prior) {
        let mut g = DMatrix::zeros(n, n);
        let mut b = DVector::zeros(n);
        for r in rows {
            let w = 1.0 / (r.sd * r.sd);
            for &(i, ci) in &r.coef {
                b[i] += w * ci * r.y;
                for &(j, cj) in &r.coef {
                    g[(i, j)] += w * ci * cj;
                }
            }
        }
        for (i, &(mu, sd)) in p.iter().enumerate().take(n) {
            if sd.is_finite() && sd > 0.0 {
                g[(i, i)] += 1.0 / (sd * sd);
                b[i] += mu / (sd * sd);
            }
        }
        let c = factor_matrix(g)?;
        (c.solve(&b).as_slice().to_vec(), to_row_major(&c.inverse()))
    } else {
        let m = rows.len();
        let mut a = vec![0.0; m * n];
        let mut y = vec![0.0; m];
        for (k, r) in rows.iter().enumerate() {
            for &(i, c) in &r.coef {
                a[k * n + i] += c / r.sd;
            }
            y[k] = r.y / r.sd;
        }
        let ls = lstsq(&a, m, n, &y)?;
        if !ls.full_rank() {
            return None;
        }
        (ls.x, ls.cov)
    };
    let mut fit = Fit { x, cov, chi2: 0.0, m: rows.len() };
    fit.chi2 = rows.iter().map(|r| (fit.residual(r) / r.sd).powi(2)).sum();
    Some(fit)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
    }

    #[test]
    fn cholesky_factor_solve_and_inverse() {
        let g = [4.0, 2.0, 0.4, 2.0, 5.0, 1.0, 0.4, 1.0, 3.0];
        let l = cholesky(&g, 3).unwrap();
        // L L' = G, L lower.
        assert_eq!([l[1], l[2], l[5]], [0.0; 3]);
        for i in 0..3 {
            for j in 0..3 {
                let s: f64 = (0..3).map(|k| l[i * 3 + k] * l[j * 3 + k]).sum();
                assert!((s - g[i * 3 + j]).abs() < 1e-14);
            }
        }
        let x = chol_solve(&l, 3, &[1.0, 2.0, 3.0]);
        for i in 0..3 {
            let s: f64 = (0..3).map(|k| g[i * 3 + k] * x[k]).sum();
            assert!((s - (i + 1) as f64).abs() < 1e-13);
        }
        let inv = chol_inverse(&l, 3);
        for i in 0..3 {
            for j in 0..3 {
                let s: f64 = (0..3).map(|k| g[i * 3 + k] * inv[k * 3 + j]).sum();
                assert!((s - f64::from(u8::from(i == j))).abs() < 1e-14);
            }
        }
        // Not SPD, singular, lost to rounding, wrong size, not finite.
        assert!(cholesky(&[1.0, 2.0, 2.0, 1.0], 2).is_none());
        assert!(cholesky(&[1.0, 1.0, 1.0, 1.0], 2).is_none());
        assert!(cholesky(&[1.0, 1.0, 1.0, 1.0 + 1e-15], 2).is_none());
        assert!(cholesky(&[1.0, 0.0, 0.0], 2).is_none());
        assert!(cholesky(&[f64::NAN, 0.0, 0.0, 1.0], 2).is_none());
        assert!(cholesky(&[1.0, 0.0, f64::INFINITY, 1.0], 2).is_none());
    }

    #[test]
    fn spd_solve_with_ridge() {
        let g = [4.0, 1.0, 1.0, 3.0];
        let x = solve_spd(&g, &[1.0, 2.0], 0.0).unwrap();
        assert!((4.0 * x[0] + x[1] - 1.0).abs() < 1e-12 && (x[0] + 3.0 * x[1] - 2.0).abs() < 1e-12);
        // Singular: the ridge gives the minimum-norm split.
        let x = solve_spd(&[1.0, 1.0, 1.0, 1.0], &[2.0, 2.0], 1e-9).unwrap();
        assert!(close(&x, &[1.0, 1.0], 1e-6), "{x:?}");
        // A parameter with no information stays at zero.
        let x = solve_spd(&[0.0, 0.0, 0.0, 2.0], &[0.0, 4.0], 0.0).unwrap();
        assert!(close(&x, &[0.0, 2.0], 1e-12), "{x:?}");
        assert!(solve_spd(&[], &[], 0.0).is_none());
        assert!(solve_spd(&[1.0, 0.0, 0.0, f64::NAN], &[1.0, 1.0], 0.0).is_none());
        assert!(solve_spd(&[1.0, 0.0, 0.0], &[1.0, 1.0], 0.0).is_none());
    }

    #[test]
    fn lstsq_full_rank_matches_the_normal_equations() {
        // y = 1 + 2 t - 0.5 t^2, exact; columns of very different scale.
        let t: Vec<f64> = (0..8).map(|k| f64::from(k) * 100.0).collect();
        let a: Vec<f64> = t.iter().flat_map(|t| [1.0, *t, t * t]).collect();
        let y: Vec<f64> = t.iter().map(|t| 1.0 + 2.0 * t - 0.5 * t * t).collect();
        let f = lstsq(&a, 8, 3, &y).unwrap();
        assert_eq!(f.rank, 3);
        assert!(f.full_rank());
        assert!((f.x[0] - 1.0).abs() < 1e-6 && (f.x[1] - 2.0).abs() < 1e-9 && (f.x[2] + 0.5).abs() < 1e-12);
        // cov = (A'A)^-1.
        let mut g = vec![0.0; 9];
        for r in a.chunks(3) {
            for i in 0..3 {
                for j in 0..3 {
                    g[i * 3 + j] += r[i] * r[j];
                }
            }
        }
        let inv = chol_inverse(&cholesky(&g, 3).unwrap(), 3);
        for (c, i) in f.cov.iter().zip(&inv) {
            assert!((c - i).abs() <= 1e-6 * i.abs().max(1e-300), "{c} {i}");
        }
    }

    #[test]
    fn lstsq_reports_rank_deficiency() {
        // Columns 0 and 1 equal: rank 2 of 3, the two share the effect equally.
        let a = [1.0, 1.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 2.0, 1.0, 1.0, 3.0];
        let y = [2.0, 3.0, 4.0, 5.0];
        let f = lstsq(&a, 4, 3, &y).unwrap();
        assert_eq!(f.rank, 2);
        assert!(!f.full_rank());
        assert!(close(&f.x, &[1.0, 1.0, 1.0], 1e-12), "{:?}", f.x);
        // Fewer rows than columns.
        let f = lstsq(&[1.0, 2.0], 1, 2, &[5.0]).unwrap();
        assert_eq!(f.rank, 1);
        assert!(close(&f.x, &[2.5, 1.25], 1e-12), "{:?}", f.x);
        // A zero column is undetermined, not a failure.
        let f = lstsq(&[1.0, 0.0, 2.0, 0.0], 2, 2, &[1.0, 2.0]).unwrap();
        assert_eq!((f.rank, f.x.clone()), (1, vec![1.0, 0.0]));
        assert!(lstsq(&[], 0, 0, &[]).is_none());
        assert!(lstsq(&[1.0, f64::NAN], 2, 1, &[1.0, 1.0]).is_none());
        assert!(lstsq(&[1.0, 1.0], 2, 1, &[1.0]).is_none());
    }

    #[test]
    fn wls_recovers_a_line_with_its_uncertainty() {
        // y = 2 + 3x, equal weights: textbook variances.
        let x: Vec<f64> = (0..10).map(f64::from).collect();
        let rows: Vec<Row> =
            x.iter().map(|x| Row { coef: vec![(0, 1.0), (1, *x)], y: 2.0 + 3.0 * x, sd: 0.5 }).collect();
        let f = wls(&rows, 2, None).unwrap();
        assert!((f.x[0] - 2.0).abs() < 1e-9 && (f.x[1] - 3.0).abs() < 1e-9);
        let sxx: f64 = x.iter().map(|v| (v - 4.5).powi(2)).sum();
        assert!((f.sd(1) - 0.5 / sxx.sqrt()).abs() < 1e-12);
        assert!(f.chi2 < 1e-12);
        // The prior path gives the same fit when the prior is negligible.
        let p = wls(&rows, 2, Some(&[(0.0, 1e9), (0.0, 1e9)])).unwrap();
        assert!(close(&p.x, &f.x, 1e-9) && (p.sd(1) - f.sd(1)).abs() < 1e-12);
        // Undetermined without a prior; held at the prior with one.
        let rows = vec![Row { coef: vec![(0, 1.0), (1, 1.0)], y: 4.0, sd: 0.1 }];
        assert!(wls(&rows, 2, None).is_none());
        let f = wls(&rows, 2, Some(&[(1.0, 1e3), (1.0, 1e3)])).unwrap();
        assert!((f.x[0] + f.x[1] - 4.0).abs() < 1e-6 && (f.x[0] - f.x[1]).abs() < 1e-6);
        assert!(f.sd(0) > 100.0, "the split is not determined: {}", f.sd(0));
        assert!(wls(&[Row { coef: vec![(5, 1.0)], y: 1.0, sd: 1.0 }], 2, None).is_none());
        assert!(wls(&[Row { coef: vec![(0, 1.0)], y: 1.0, sd: 0.0 }], 1, None).is_none());
        assert!(wls(&[Row { coef: vec![(0, 1.0)], y: f64::NAN, sd: 1.0 }], 1, None).is_none());
    }

    #[test]
    fn weighted_products_equal_the_sums_they_stand_for() {
        fn refs(v: &[Vec<Vec<f64>>]) -> Vec<&[Vec<f64>]> {
            v.iter().map(Vec::as_slice).collect()
        }
        // Two blocks of 700 rows (not a multiple of the product's block) and one of 3.
        let mut rng = crate::stats::Rng::new(7, 1);
        let shape = [700usize, 3, 700];
        let mut col = || -> Vec<Vec<f64>> {
            shape.iter().map(|&n| (0..n).map(|_| rng.gauss() * 10.0).collect()).collect()
        };
        let a: Vec<Vec<Vec<f64>>> = (0..9).map(|_| col()).collect();
        let b: Vec<Vec<Vec<f64>>> = (0..4).map(|_| col()).collect();
        let w: Vec<Vec<f64>> = col().into_iter().map(|c| c.into_iter().map(f64::abs).collect()).collect();
        let got = weighted_products(&refs(&a), &refs(&b), &w).unwrap();
        for (i, ai) in a.iter().enumerate() {
            for (j, bj) in b.iter().enumerate() {
                let terms = ai
                    .iter()
                    .zip(bj)
                    .zip(&w)
                    .flat_map(|((x, y), q)| x.iter().zip(y).zip(q).map(|((u, v), r)| r * u * v));
                let (sum, size) = terms.fold((0.0, 0.0), |(s, m), t: f64| (s + t, m + t.abs()));
                assert!((got[i * b.len() + j] - sum).abs() <= 1e-12 * size, "({i}, {j})");
            }
        }
        // The same inputs give the same bits.
        assert_eq!(weighted_products(&refs(&a), &refs(&b), &w).unwrap(), got);
        // A column not shaped as the weights.
        let short = vec![vec![1.0; 700], vec![1.0; 3]];
        assert!(weighted_products(&[short.as_slice()], &refs(&b), &w).is_none());
        assert_eq!(weighted_products(&[], &refs(&b), &w), Some(Vec::new()));
    }
}
