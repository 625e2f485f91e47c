//! Confidence interval of a probability estimated by counting: `k` violations in `n`
//! Monte Carlo samples. Clopper–Pearson ("exact"): the interval holds the true
//! probability with at least the stated confidence for every `n`, which a test-approval
//! decision needs (the normal approximation undercovers exactly where it matters, at
//! `k = 0` and small `n`). Its ends are the probabilities at which the observed count
//! becomes a tail event of probability `(1 − confidence)/2`, found by bisection on the
//! binomial distribution function (summed in log space, so large `n` does not
//! underflow). No crate needed for one distribution function: `statrs` would bring a
//! second linear-algebra stack for it.

/// Two-sided Clopper–Pearson interval `(low, high)` for `k` successes in `n` trials at
/// `confidence` (0.5..1). `n = 0` gives `(0, 1)`.
pub fn clopper_pearson(k: u64, n: u64, confidence: f64) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let k = k.min(n);
    let tail = 0.5 * (1.0 - confidence.clamp(0.0, 1.0));
    // low: P(X ≥ k | p) = tail; high: P(X ≤ k | p) = tail.
    let low = if k == 0 { 0.0 } else { solve(|p| 1.0 - cdf(k - 1, n, p), tail, true) };
    let high = if k == n { 1.0 } else { solve(|p| cdf(k, n, p), tail, false) };
    (low, high)
}

/// The p in [0, 1] where `f(p)`, rising or falling in p, crosses `target` (bisection
/// to 1e-18).
fn solve(f: impl Fn(f64) -> f64, target: f64, rising: bool) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if (f(mid) < target) == rising {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// `P(X ≤ k)` for `X ~ Binomial(n, p)`.
pub fn cdf(k: u64, n: u64, p: f64) -> f64 {
    if k >= n || p <= 0.0 {
        return 1.0;
    }
    if p >= 1.0 {
        return 0.0;
    }
    // log pmf(i) by the ratio pmf(i+1)/pmf(i) = (n−i)/(i+1) · p/(1−p), from pmf(0).
    let (lp, lq) = (p.ln(), (-p).ln_1p());
    let mut log_pmf = n as f64 * lq;
    let mut terms = Vec::with_capacity(k as usize + 1);
    terms.push(log_pmf);
    for i in 0..k {
        log_pmf += ((n - i) as f64).ln() - ((i + 1) as f64).ln() + lp - lq;
        terms.push(log_pmf);
    }
    let m = terms.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !m.is_finite() {
        return 0.0;
    }
    let s: f64 = terms.iter().map(|t| (t - m).exp()).sum();
    (m + s.ln()).exp().min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_published_values() {
        // R: binom.test(3, 10)$conf.int = 0.06673951 0.65245285.
        let (lo, hi) = clopper_pearson(3, 10, 0.95);
        assert!((lo - 0.066_739_51).abs() < 1e-7 && (hi - 0.652_452_85).abs() < 1e-7, "{lo} {hi}");
        // scipy.stats.beta.ppf(0.025, 17, 184), beta.ppf(0.975, 18, 183).
        let (lo, hi) = clopper_pearson(17, 200, 0.95);
        assert!((lo - 0.050_295_918_6).abs() < 1e-9 && (hi - 0.132_605_165_8).abs() < 1e-9, "{lo} {hi}");
    }

    #[test]
    fn closed_forms_at_the_ends() {
        // k = 0: high = 1 − (α/2)^(1/n); k = n: low = (α/2)^(1/n).
        for n in [1u64, 7, 200, 5000] {
            let (lo, hi) = clopper_pearson(0, n, 0.95);
            assert_eq!(lo, 0.0);
            assert!((hi - (1.0 - 0.025f64.powf(1.0 / n as f64))).abs() < 1e-10, "{n}: {hi}");
            let (lo, hi) = clopper_pearson(n, n, 0.9);
            assert_eq!(hi, 1.0);
            assert!((lo - 0.05f64.powf(1.0 / n as f64)).abs() < 1e-10, "{n}: {lo}");
        }
        assert_eq!(clopper_pearson(0, 0, 0.95), (0.0, 1.0));
    }

    #[test]
    fn cdf_sums_to_the_binomial() {
        // n = 5, p = 0.3: P(X ≤ 2) = 0.16807 + 0.36015 + 0.3087 = 0.83692.
        assert!((cdf(2, 5, 0.3) - 0.83692).abs() < 1e-12);
        assert_eq!(cdf(5, 5, 0.3), 1.0);
        // Large n without underflow: scipy.stats.binom.cdf(5000, 10000, 0.5).
        let c = cdf(5000, 10_000, 0.5);
        assert!((c - 0.503_989_323_07).abs() < 1e-9, "{c}");
    }
}
