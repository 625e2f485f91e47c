//! What is left in the residual: its autocorrelation (is it white, i.e. only noise?)
//! and its cross-correlation with the inputs (does it follow the set points, and how
//! late?).
//!
//! Both are computed through one FFT size for the whole run (zero-padded, so the
//! correlations are linear, not circular): two real signals share one complex FFT
//! (real and imaginary part), two real correlations share one inverse FFT, and the
//! correlation with an input's first difference comes from the one with the input.
//! A 70 s run at 1 kHz with 18 channels takes some 47 FFTs of 72,000 points.
//!
//! Conventions: signals have their mean removed; non-finite residual samples count as
//! 0; `ρ(l) = Σ_k e[k+l] u[k] / √(Σe² Σu²)` (biased estimator), so a **positive lag**
//! means the residual *follows* the input (a controller delay shows up there).
//!
//! Whiteness: the 95 % band of lag `l` is `±1.96 √(Σ_k e_k² e_{k+l}²) / Σ e²`, which is
//! `±1.96/√N` for noise of constant level but stays right when the noise level changes
//! along the run (the bench's sensors are much noisier at the operating limits). A
//! residual is white when at most 10 % of the lags leave their band (5 % expected)
//! and its mean is within ±3σ/√N (an offset is structure too). Encoder speeds counted
//! over a window are correlated from sample to sample and so read as coloured: that
//! is structure too, of the measurement chain.
//!
//! Cross-correlation: the peak is the largest of L lags, so it is significant only
//! beyond the Bonferroni level `z = z(0.025/L)`, as `|ρ(l)| > z √(Σ u_k² ē²_{k+l}) /
//! √(Σe² Σu²)` at the peak's lag, `ē²` the mean of `e²` over ±10 ms (`z/√N` for noise
//! of one level). That assumes a white residual: a coloured one
//! correlates with slow inputs more easily, so read it together with the whiteness.

use std::sync::Arc;

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use serde::Serialize;

/// Residuals with an RMS below this fraction of the channel's normaliser are
/// "negligible": their correlations are rounding noise and get no verdict.
pub const NEGLIGIBLE_REL: f64 = 1e-6;
/// [s] half-width over which the residual's local noise level is averaged for the
/// cross-correlation threshold.
pub const LOCAL_S: f64 = 0.01;
/// Largest fraction of autocorrelation lags outside the 95 % band still called white
/// (5 % are expected; the margin absorbs the estimator's spread over few lags).
pub const WHITE_MAX_OUTSIDE: f64 = 0.10;

/// Verdict on a residual's whiteness.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The residual is ~0: nothing to judge.
    Negligible,
    /// Consistent with white noise: nothing left that the model could explain.
    White,
    /// Structure left: model error, or correlated measurement noise.
    Coloured,
    /// Correlated, but no larger than the sensor's resolution (encoder counting): the
    /// bench cannot tell a model error of this size from its own quantisation.
    Resolution,
}

impl Verdict {
    /// For people.
    pub fn describe(self) -> &'static str {
        match self {
            Verdict::Negligible => "negligible residual",
            Verdict::White => "white (noise only)",
            Verdict::Coloured => "coloured (structure left)",
            Verdict::Resolution => "within counting resolution",
        }
    }
}

/// Whiteness test of one residual.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Whiteness {
    /// Lags tested, 1..=lags.
    pub lags: usize,
    /// Mean over the lags of the 95 % band half-width (1.96/√N for steady noise).
    pub band: f64,
    /// Fraction of lags with |ρ| above the band.
    pub fraction_outside: f64,
    /// ρ at lag 1.
    pub lag1: f64,
    /// The residual's mean is beyond ±3σ/√N: an offset, not zero-mean noise.
    pub bias_significant: bool,
    pub verdict: Verdict,
    /// ρ(1..=lags), for plots.
    #[serde(skip)]
    pub acf: Vec<f64>,
}

/// Cross-correlation peak of one residual with one input.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CrossPeak {
    /// Input name, e.g. `SuT Throttle` or `d/dt SuT Throttle`.
    pub input: String,
    /// ρ at the peak (signed).
    pub peak: f64,
    /// [s] lag of the peak; positive: the residual follows the input.
    pub lag_s: f64,
    /// The |ρ| a white residual's peak stays under with 95 % probability.
    pub threshold: f64,
    /// |peak| beyond `threshold` (and the residual not negligible).
    pub significant: bool,
    /// The peak is at the end of the lag range: the correlation still grows beyond it
    /// (typical of a slow input against a slow residual), so the lag means little.
    pub at_edge: bool,
}

/// Correlation results of one residual.
#[derive(Debug, Clone, PartialEq)]
pub struct ResidualStats {
    pub whiteness: Whiteness,
    pub cross: Vec<CrossPeak>,
}

/// Mean removed, non-finite samples set to 0.
fn centred(x: &[f64]) -> Vec<f64> {
    let (s, c) = x.iter().filter(|v| v.is_finite()).fold((0.0, 0usize), |(s, c), v| (s + v, c + 1));
    let mean = if c > 0 { s / c as f64 } else { 0.0 };
    x.iter().map(|v| if v.is_finite() { v - mean } else { 0.0 }).collect()
}

/// Upper-tail normal quantile: z with P(Z > z) = p, for small p (≤ 0.01), solving the
/// tail expansion p = φ(z)/z · (1 − 1/z²) by fixed-point iteration; within 0.5 %.
fn tail_quantile(p: f64) -> f64 {
    let l = 2.0 * (1.0 / p).ln() - (2.0 * std::f64::consts::PI).ln();
    let mut z = l.max(1.0).sqrt();
    for _ in 0..6 {
        let z2 = z * z;
        z = (l - z2.ln() + 2.0 * (1.0 - 1.0 / z2).max(0.1).ln()).max(1.0).sqrt();
    }
    z
}

fn energy(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum()
}

/// The smallest 2^a 3^b 5^c ≥ `min`: FFT sizes rustfft does fast, and for 71,000
/// samples 72,000 instead of the power of two 131,072.
fn fft_len(min: usize) -> usize {
    let mut best = min.max(1).next_power_of_two();
    let mut p5 = 1usize;
    while p5 < best {
        let mut p35 = p5;
        while p35 < best {
            let mut v = p35;
            while v < min {
                v *= 2;
            }
            best = best.min(v);
            p35 *= 3;
        }
        p5 *= 5;
    }
    best
}

/// One correlation to compute: `x · conj(y)` of two spectra.
type Job<'a> = (&'a [Complex<f64>], &'a [Complex<f64>]);

/// One input as the correlator keeps it.
struct Input {
    name: String,
    /// Spectrum of the centred input.
    spec: Vec<Complex<f64>>,
    /// Σu² of the centred input, Σ(Δu)² of its first difference.
    energy: f64,
    energy_d: f64,
    /// First and last centred samples (boundary terms of the difference identity).
    first: f64,
    last: f64,
    /// u² and (Δu)² per sample, for the noise-level-aware threshold.
    u2: Vec<f64>,
    du2: Vec<f64>,
}

/// Correlates residuals with a fixed set of inputs, and with their first differences
/// (`d/dt`), on one FFT size.
///
/// The difference needs no FFT of its own: with `Δu[k] = u[k] − u[k−1]` (`k ≥ 1`),
/// `Σ_k e[k+l] Δu[k] = r(l) − r(l+1) − e[l] u[0] + e[N+l] u[N−1]`, where `r` is the
/// correlation with `u` and `e` is 0 outside the run.
pub struct Correlator {
    n: usize,
    m: usize,
    dt_s: f64,
    max_lag: usize,
    acf_lags: usize,
    fwd: Arc<dyn Fft<f64>>,
    inv: Arc<dyn Fft<f64>>,
    scratch: Vec<Complex<f64>>,
    inputs: Vec<Input>,
}

impl Correlator {
    /// `inputs`: name and samples (length `n`); lags in samples, capped at `n / 2`.
    pub fn new(inputs: &[(&str, &[f64])], n: usize, dt_s: f64, max_lag: usize, acf_lags: usize) -> Self {
        let max_lag = max_lag.min(n / 2);
        let acf_lags = acf_lags.min(n / 2);
        // Linear (not circular) correlation for lags -(max_lag+1)..=max_lag+1.
        let m = fft_len(n + max_lag.max(acf_lags) + 2);
        let mut planner = FftPlanner::new();
        let fwd = planner.plan_fft_forward(m);
        let inv = planner.plan_fft_inverse(m);
        let scratch_len = fwd.get_inplace_scratch_len().max(inv.get_inplace_scratch_len());
        let mut me = Self {
            n,
            m,
            dt_s,
            max_lag,
            acf_lags,
            fwd,
            inv,
            scratch: vec![Complex::default(); scratch_len],
            inputs: Vec::new(),
        };
        let centred_inputs: Vec<(&str, Vec<f64>)> =
            inputs.iter().map(|(name, x)| (*name, centred(x))).collect();
        for pair in centred_inputs.chunks(2) {
            let a = &pair[0];
            let b = pair.get(1);
            let (sa, sb) = me.spectra(&a.1, b.map(|b| b.1.as_slice()));
            me.inputs.push(Input::new(a.0, &a.1, sa));
            if let (Some(b), Some(sb)) = (b, sb) {
                me.inputs.push(Input::new(b.0, &b.1, sb));
            }
        }
        me
    }

    /// Spectra of one or two real signals through one complex FFT.
    fn spectra(&mut self, a: &[f64], b: Option<&[f64]>) -> (Vec<Complex<f64>>, Option<Vec<Complex<f64>>>) {
        let m = self.m;
        let mut z = vec![Complex::default(); m];
        for (zk, v) in z.iter_mut().zip(a) {
            zk.re = *v;
        }
        if let Some(b) = b {
            for (zk, v) in z.iter_mut().zip(b) {
                zk.im = *v;
            }
        }
        self.fwd.process_with_scratch(&mut z, &mut self.scratch);
        if b.is_none() {
            return (z, None);
        }
        let mut sa = vec![Complex::default(); m];
        let mut sb = vec![Complex::default(); m];
        for f in 0..m {
            let zf = z[f];
            let zc = z[(m - f) % m].conj();
            sa[f] = (zf + zc) * 0.5;
            // (zf − zc) / 2i
            let d = zf - zc;
            sb[f] = Complex::new(d.im * 0.5, -d.re * 0.5);
        }
        (sa, Some(sb))
    }

    /// Two real correlations through one inverse FFT: `x1·conj(y1) + i·x2·conj(y2)`
    /// (each product is Hermitian, so the real part of the result is the first
    /// correlation and the imaginary part the second). `buf` is reused between calls.
    fn correlations(
        inv: &dyn Fft<f64>,
        scratch: &mut [Complex<f64>],
        p: Job<'_>,
        q: Option<Job<'_>>,
        buf: &mut Vec<Complex<f64>>,
    ) {
        buf.clear();
        match q {
            Some((x2, y2)) => {
                buf.extend(p.0.iter().zip(p.1).zip(x2.iter().zip(y2)).map(|((x1, y1), (x2, y2))| {
                    let a = x1 * y1.conj();
                    let b = x2 * y2.conj();
                    Complex::new(a.re - b.im, a.im + b.re)
                }))
            }
            None => buf.extend(p.0.iter().zip(p.1).map(|(x, y)| x * y.conj())),
        }
        inv.process_with_scratch(buf, scratch);
        let k = 1.0 / buf.len().max(1) as f64;
        for c in buf.iter_mut() {
            *c *= k;
        }
    }

    /// Autocorrelation and input cross-correlations of each residual (paired up to
    /// share FFTs). `scale`: each residual's normaliser, to tell a negligible residual.
    pub fn analyse(&mut self, residuals: &[(&[f64], f64)]) -> Vec<ResidualStats> {
        let mut out = Vec::with_capacity(residuals.len());
        for pair in residuals.chunks(2) {
            let a = centred(pair[0].0);
            let b = pair.get(1).map(|p| centred(p.0));
            let (sa, sb) = self.spectra(&a, b.as_deref());
            let sq = |x: &[f64]| x.iter().map(|v| v * v).collect::<Vec<f64>>();
            let b2 = b.as_deref().map(sq);
            let (qa, qb) = self.spectra(&sq(&a), b2.as_deref());
            out.push(self.one(&a, &sa, &qa, pair[0].1, pair[0].0));
            if let (Some(b), Some(sb), Some(qb), Some(p)) = (b, sb, qb, pair.get(1)) {
                out.push(self.one(&b, &sb, &qb, p.1, p.0));
            }
        }
        out
    }

    /// `spec`: spectrum of the centred residual `e`, `sq`: of its square.
    fn one(
        &mut self,
        e: &[f64],
        spec: &[Complex<f64>],
        sq: &[Complex<f64>],
        scale: f64,
        raw: &[f64],
    ) -> ResidualStats {
        let n = self.n as f64;
        let ee = energy(e);
        let (sum, sum2, cnt) = raw
            .iter()
            .filter(|v| v.is_finite())
            .fold((0.0, 0.0, 0usize), |(s, s2, c), v| (s + v, s2 + v * v, c + 1));
        let cnt = cnt.max(1) as f64;
        let rms = (sum2 / cnt).sqrt();
        let negligible = rms.is_nan() || !scale.is_finite() || rms <= NEGLIGIBLE_REL * scale;
        let bias_significant = (sum / cnt).abs() > 3.0 * (ee / cnt).sqrt() / cnt.sqrt();

        // Correlations: the residual with itself, then with every input; two per
        // inverse FFT. Only the lags in range are kept.
        // Jobs: e with itself, e with every input, e² with itself (for the band).
        let mut jobs: Vec<Job<'_>> = vec![(spec, spec)];
        jobs.extend(self.inputs.iter().map(|i| (spec, i.spec.as_slice())));
        jobs.push((sq, sq));
        let mut corr: Vec<Lags> = Vec::with_capacity(jobs.len());
        let mut buf = Vec::with_capacity(self.m);
        let read = self.max_lag.max(self.acf_lags) + 2;
        for pair in jobs.chunks(2) {
            Self::correlations(self.inv.as_ref(), &mut self.scratch, pair[0], pair.get(1).copied(), &mut buf);
            corr.push(Lags::keep(&buf, read, |c| c.re));
            if pair.len() > 1 {
                corr.push(Lags::keep(&buf, read, |c| c.im));
            }
        }

        let none = Lags::default();
        let acf_raw = corr.first().unwrap_or(&none);
        let r0 = acf_raw.at(0);
        let acf: Vec<f64> =
            (1..=self.acf_lags as i64).map(|l| if r0 > 0.0 { acf_raw.at(l) / r0 } else { 0.0 }).collect();
        // Per-lag band from Σ e_k² e_{k+l}² (the autocorrelation of e² at lag l).
        let sq_acf = corr.last().unwrap_or(&none);
        let bands: Vec<f64> = (1..=self.acf_lags as i64)
            .map(|l| {
                let v = sq_acf.at(l).max(0.0);
                if ee > 0.0 {
                    1.96 * v.sqrt() / ee
                } else {
                    1.96 / n.sqrt()
                }
            })
            .collect();
        let band =
            if bands.is_empty() { 1.96 / n.sqrt() } else { bands.iter().sum::<f64>() / bands.len() as f64 };
        let outside = acf.iter().zip(&bands).filter(|(r, b)| r.abs() > **b).count();
        let fraction_outside = if acf.is_empty() { 0.0 } else { outside as f64 / acf.len() as f64 };
        let verdict = if negligible {
            Verdict::Negligible
        } else if fraction_outside <= WHITE_MAX_OUTSIDE && !bias_significant {
            Verdict::White
        } else {
            Verdict::Coloured
        };
        let whiteness = Whiteness {
            lags: acf.len(),
            band,
            fraction_outside,
            lag1: acf.first().copied().unwrap_or(0.0),
            bias_significant,
            verdict,
            acf,
        };

        let lags = 2 * self.max_lag + 1;
        let z = tail_quantile(0.025 / lags as f64).max(1.96);
        // Threshold at the peak's lag l: z·√(Σ_k u_k² ē²_{k+l}) / √(Σe² Σu²), with ē² the
        // mean of e² over ±LOCAL_S: the standard deviation of Σ e_{k+l} u_k for a white
        // e whose level changes along the run (z/√N for one level). Sparse inputs (a few
        // set-point steps) meet the noise at a few instants only, so its level there
        // is what counts.
        let mut prefix = Vec::with_capacity(e.len() + 1);
        prefix.push(0.0);
        let mut acc = 0.0;
        for v in e {
            acc += v * v;
            prefix.push(acc);
        }
        let h = ((LOCAL_S / self.dt_s).round() as usize).max(1);
        let local_e2: Vec<f64> = (0..e.len())
            .map(|k| {
                let (a, b) = (k.saturating_sub(h), (k + h + 1).min(e.len()));
                (prefix.get(b).copied().unwrap_or(0.0) - prefix.get(a).copied().unwrap_or(0.0))
                    / (b - a).max(1) as f64
            })
            .collect();
        let ne = e.len() as i64;
        let threshold_at = |u2: &[f64], eu: f64, l: i64| {
            let s: f64 = u2
                .iter()
                .enumerate()
                .filter_map(|(k, w)| {
                    let j = k as i64 + l;
                    (0..ne).contains(&j).then(|| w * local_e2[j as usize])
                })
                .sum();
            if s > 0.0 && ee * eu > 0.0 {
                z * (s / (ee * eu)).sqrt()
            } else {
                z / n.sqrt()
            }
        };
        let max_lag = self.max_lag as i64;
        let e_at = |k: i64| if (0..ne).contains(&k) { e[k as usize] } else { 0.0 };
        let peak_of = |name: String, norm: f64, u2: &[f64], eu: f64, f: &dyn Fn(i64) -> f64| {
            let mut best = (0.0f64, 0i64);
            for l in -max_lag..=max_lag {
                let v = if norm > 0.0 { f(l) / norm } else { 0.0 };
                if v.abs() > best.0.abs() {
                    best = (v, l);
                }
            }
            let threshold = threshold_at(u2, eu, best.1);
            CrossPeak {
                input: name,
                peak: best.0,
                lag_s: best.1 as f64 * self.dt_s,
                threshold,
                significant: !negligible && best.0.abs() > threshold,
                at_edge: max_lag > 0 && best.1.abs() == max_lag,
            }
        };
        let mut plain = Vec::with_capacity(self.inputs.len());
        let mut diffs = Vec::with_capacity(self.inputs.len());
        // (`corr` ends with the e² autocorrelation: the zip stops at the inputs.)
        for (inp, r) in self.inputs.iter().zip(corr.iter().skip(1)) {
            let norm = (ee * inp.energy).sqrt();
            plain.push(peak_of(inp.name.clone(), norm, &inp.u2, inp.energy, &|l| r.at(l)));
            let norm_d = (ee * inp.energy_d).sqrt();
            diffs.push(peak_of(format!("d/dt {}", inp.name), norm_d, &inp.du2, inp.energy_d, &|l| {
                r.at(l) - r.at(l + 1) - e_at(l) * inp.first + e_at(ne + l) * inp.last
            }));
        }
        plain.extend(diffs);
        ResidualStats { whiteness, cross: plain }
    }
}

/// The lags of a correlation that are read, `0..k` and `−k..−1`, out of the `m` values
/// of its inverse FFT (circular layout): a long run's `m` is millions, `k` a few hundred.
#[derive(Default)]
struct Lags {
    head: Vec<f64>,
    tail: Vec<f64>,
}

impl Lags {
    fn keep(buf: &[Complex<f64>], k: usize, part: fn(&Complex<f64>) -> f64) -> Self {
        let k = k.min(buf.len());
        Self {
            head: buf[..k].iter().map(part).collect(),
            tail: buf[buf.len() - k..].iter().map(part).collect(),
        }
    }

    /// The correlation at lag `l` (0 beyond the kept lags).
    fn at(&self, l: i64) -> f64 {
        let (v, i) = if l >= 0 { (&self.head, l) } else { (&self.tail, self.tail.len() as i64 + l) };
        usize::try_from(i).ok().and_then(|i| v.get(i)).copied().unwrap_or(0.0)
    }
}

impl Input {
    fn new(name: &str, u: &[f64], spec: Vec<Complex<f64>>) -> Self {
        Self {
            name: name.to_string(),
            spec,
            energy: energy(u),
            energy_d: u.windows(2).map(|w| (w[1] - w[0]) * (w[1] - w[0])).sum(),
            first: u.first().copied().unwrap_or(0.0),
            last: u.last().copied().unwrap_or(0.0),
            u2: u.iter().map(|v| v * v).collect(),
            du2: std::iter::once(0.0).chain(u.windows(2).map(|w| (w[1] - w[0]) * (w[1] - w[0]))).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random noise in [-1, 1).
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
            })
            .collect()
    }

    fn direct(e: &[f64], u: &[f64], l: i64) -> f64 {
        let e = centred(e);
        let u = centred(u);
        let mut s = 0.0;
        for k in 0..u.len() as i64 {
            if let Some(v) = e.get((k + l) as usize).filter(|_| k + l >= 0) {
                s += v * u[k as usize];
            }
        }
        s / (energy(&e) * energy(&u)).sqrt()
    }

    #[test]
    fn fft_len_is_5_smooth_and_small() {
        assert_eq!(fft_len(71_002), 72_000);
        assert_eq!(fft_len(1), 1);
        assert_eq!(fft_len(1000), 1000);
        for min in [7usize, 97, 1001, 65_537] {
            let v = fft_len(min);
            let mut r = v;
            for p in [2, 3, 5] {
                while r.rem_euclid(p) == 0 {
                    r /= p;
                }
            }
            assert!(v >= min && r == 1 && v < min + min / 4 + 8, "{min} -> {v}");
        }
    }

    #[test]
    fn fft_correlation_matches_the_direct_sum_and_finds_the_delay() {
        let n = 3000;
        let u = noise(n, 7);
        // Residual = input delayed by 25 samples, plus a little noise.
        let w = noise(n, 99);
        let e: Vec<f64> = (0..n).map(|k| if k >= 25 { u[k - 25] } else { 0.0 } + 0.1 * w[k]).collect();
        let v = noise(n, 3);
        // A step input: its difference is one impulse, the residual a delayed step.
        let step: Vec<f64> = (0..n).map(|k| if k >= 1000 { 1.0 } else { 0.0 }).collect();
        let inputs: Vec<(&str, &[f64])> = vec![("u", &u), ("v", &v), ("step", &step)];
        let mut c = Correlator::new(&inputs, n, 1e-3, 100, 50);
        let two = c.analyse(&[(&e, 1.0), (&w, 1.0)]);
        let s = &two[0];
        let names: Vec<&str> = s.cross.iter().map(|x| x.input.as_str()).collect();
        assert_eq!(names, ["u", "v", "step", "d/dt u", "d/dt v", "d/dt step"]);
        assert_eq!(s.cross[0].lag_s, 0.025);
        assert!((s.cross[0].peak - direct(&e, &u, 25)).abs() < 1e-9);
        assert!(s.cross[0].significant);
        assert!(!s.cross[1].significant, "{:?}", s.cross[1]);
        // The difference identity against the direct sum, at the peak and elsewhere.
        let du: Vec<f64> = (0..n).map(|k| if k == 0 { 0.0 } else { u[k] - u[k - 1] }).collect();
        let direct_d = |l: i64| {
            let ec = centred(&e);
            let s: f64 = (1..n as i64)
                .filter(|k| (0..n as i64).contains(&(k + l)))
                .map(|k| ec[(k + l) as usize] * du[k as usize])
                .sum();
            s / (energy(&ec) * energy(&du)).sqrt()
        };
        let d = &s.cross[3];
        let l = (d.lag_s / 1e-3).round() as i64;
        assert!((d.peak - direct_d(l)).abs() < 1e-9, "{d:?} vs {}", direct_d(l));
        for l in [-100i64, -3, 0, 7, 100] {
            assert!(d.peak.abs() >= direct_d(l).abs() - 1e-12);
        }
        // A residual pulse 40 samples after the step peaks at +40 ms on d/dt.
        let late: Vec<f64> = (0..n)
            .map(|k| match k {
                1040 => 1.0,
                1039 | 1041 => 0.5,
                _ => 0.0,
            })
            .collect();
        let r = c.analyse(&[(&late, 1.0)]);
        assert_eq!(r[0].cross[5].lag_s, 0.04, "{:?}", r[0].cross[5]);
        assert!(r[0].cross[5].significant);
        // The noise residual (second of the pair) is white and uncorrelated with u.
        assert_eq!(two[1].whiteness.verdict, Verdict::White);
        assert!(two[1].cross[0].peak.abs() < 0.1);
        // A random walk is not white.
        let mut acc = 0.0;
        let walk: Vec<f64> = w
            .iter()
            .map(|x| {
                acc += x;
                acc
            })
            .collect();
        let one = c.analyse(&[(&walk, 1.0)]);
        assert_eq!(one[0].whiteness.verdict, Verdict::Coloured);
        assert!(one[0].whiteness.lag1 > 0.9);
        assert_eq!(one.len(), 1);
    }

    #[test]
    fn noise_louder_in_places_is_still_white() {
        // 10x the noise in 5 % of the run, as at the bench's operating limits.
        let n = 20_000;
        let w = noise(n, 5);
        let e: Vec<f64> =
            w.iter().enumerate().map(|(k, v)| if k % 2000 < 100 { 10.0 * v } else { *v }).collect();
        let mut c = Correlator::new(&[("u", &noise(n, 8))], n, 1e-3, 10, 200);
        let r = c.analyse(&[(&e, 1.0)]);
        assert_eq!(r[0].whiteness.verdict, Verdict::White, "{:?}", r[0].whiteness.fraction_outside);
        // Wider than the steady-noise band (where two loud samples meet, lags < 100).
        assert!(r[0].whiteness.band > 1.3 * 1.96 / (n as f64).sqrt());
        // With the plain 1.96/√N band it would not be.
        let plain = 1.96 / (n as f64).sqrt();
        let out = r[0].whiteness.acf.iter().filter(|v| v.abs() > plain).count();
        assert!(out as f64 / 200.0 > WHITE_MAX_OUTSIDE, "{out}");
    }

    #[test]
    fn tail_quantile_is_close() {
        // Exact values: P(Z > 3.0902) = 1e-3, P(Z > 4.2649) = 1e-5.
        assert!((tail_quantile(1e-3) - 3.0902).abs() < 0.015, "{}", tail_quantile(1e-3));
        assert!((tail_quantile(1e-5) - 4.2649).abs() < 0.02, "{}", tail_quantile(1e-5));
        assert!((tail_quantile(2.5e-3 / 41.0) - 3.8418).abs() < 0.02);
    }

    #[test]
    fn an_offset_is_not_white() {
        let n = 5000;
        let w = noise(n, 11);
        let e: Vec<f64> = w.iter().map(|v| 0.1 * v + 0.05).collect();
        let mut c = Correlator::new(&[("u", &noise(n, 2))], n, 1e-3, 10, 50);
        let r = c.analyse(&[(&e, 1.0), (&w, 1.0)]);
        assert!(r[0].whiteness.bias_significant);
        assert_eq!(r[0].whiteness.verdict, Verdict::Coloured);
        assert!(!r[1].whiteness.bias_significant);
        assert_eq!(r[1].whiteness.verdict, Verdict::White);
        // A pure offset (no variation at all) too.
        let r = c.analyse(&[(&vec![2.0; n], 1.0)]);
        assert_eq!(r[0].whiteness.verdict, Verdict::Coloured);
    }

    #[test]
    fn zero_residual_is_negligible() {
        let n = 500;
        let u = noise(n, 1);
        let inputs: Vec<(&str, &[f64])> = vec![("u", &u)];
        let mut c = Correlator::new(&inputs, n, 1e-3, 10, 10);
        let z = vec![0.0; n];
        let r = c.analyse(&[(&z, 1.0)]);
        assert_eq!(r[0].whiteness.verdict, Verdict::Negligible);
        assert!(!r[0].cross[0].significant);
    }
}
