//! The statistics every part of the workbench shares: one median, one moving mean, one
//! random-number generator, so that two commands never disagree on what "the median of
//! a run" or "seed 7" means.
//!
//! Empty input and NaN, the same way everywhere:
//! - order statistics ([`median`], [`mad_sigma`]) skip NaN samples (a dropped sample,
//!   not a value) and return `None` when nothing is left: "no data" has no good
//!   default, so each caller says what it means there;
//! - arithmetic reductions ([`mean`], [`rms`]) return NaN for an empty slice and let a
//!   NaN sample propagate, as arithmetic on missing data should;
//! - the filters ([`moving_mean`], [`median_filter`]) skip NaN inside a window and give
//!   NaN only where a whole window is NaN.

use rand_xoshiro::rand_core::{Rng as _, SeedableRng};
use rand_xoshiro::Xoshiro256StarStar;

/// Arithmetic mean; NaN for an empty slice.
pub fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// Root mean square (about zero, not about the mean); NaN for an empty slice.
pub fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
    }
}

/// Sample standard deviation (`n - 1`); 0 for fewer than 2 values, where no spread was
/// observed.
pub fn std_dev(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return 0.0;
    }
    let m = mean(v);
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

/// Median of the non-NaN values (the mean of the middle two for an even count); `None`
/// when there are none.
pub fn median(v: &[f64]) -> Option<f64> {
    let mut w: Vec<f64> = v.iter().copied().filter(|x| !x.is_nan()).collect();
    median_in_place(&mut w)
}

/// Median of a NaN-free buffer, reordering it (selection, not a full sort).
fn median_in_place(w: &mut [f64]) -> Option<f64> {
    let n = w.len();
    if n == 0 {
        return None;
    }
    let (lower, hi, _) = w.select_nth_unstable_by(n / 2, f64::total_cmp);
    let hi = *hi;
    if n % 2 == 1 {
        Some(hi)
    } else {
        let lo = lower.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Some(0.5 * (lo + hi))
    }
}

/// Median absolute deviation from the median, scaled (1.4826) to estimate a standard
/// deviation that a few wild values do not inflate; NaN skipped, `None` when empty.
pub fn mad_sigma(v: &[f64]) -> Option<f64> {
    let m = median(v)?;
    let d: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    median(&d).map(|x| 1.4826 * x)
}

/// Half the central 68 % range of the finite values (a standard deviation that a few
/// wild values do not inflate; linear interpolation between order statistics); 0 for
/// fewer than 2 values.
pub fn spread68(v: &[f64]) -> f64 {
    let mut w: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if w.len() < 2 {
        return 0.0;
    }
    w.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let x = p * (w.len() - 1) as f64;
        let (i, f) = (x.floor() as usize, x - x.floor());
        let a = w[i.min(w.len() - 1)];
        let b = w[(i + 1).min(w.len() - 1)];
        a + f * (b - a)
    };
    0.5 * (q(0.8413) - q(0.1587))
}

/// Centred moving mean over `2 half + 1` samples, shortened at the ends (the mean of
/// what exists there, so the output has the input's length). NaN samples are skipped.
pub fn moving_mean(v: &[f64], half: usize) -> Vec<f64> {
    // Prefix sums: O(n) for any window.
    let mut sum = Vec::with_capacity(v.len() + 1);
    let mut cnt = Vec::with_capacity(v.len() + 1);
    let (mut s, mut c) = (0.0, 0usize);
    sum.push(s);
    cnt.push(c);
    for x in v {
        if !x.is_nan() {
            s += x;
            c += 1;
        }
        sum.push(s);
        cnt.push(c);
    }
    (0..v.len())
        .map(|k| {
            let (a, b) = (k.saturating_sub(half), (k + half + 1).min(v.len()));
            match cnt[b] - cnt[a] {
                0 => f64::NAN,
                m => (sum[b] - sum[a]) / m as f64,
            }
        })
        .collect()
}

/// Centred running median over `2 half + 1` samples, shortened at the ends; removes
/// spikes that a moving mean would smear. NaN samples are skipped.
pub fn median_filter(v: &[f64], half: usize) -> Vec<f64> {
    let n = v.len();
    let mut buf = Vec::with_capacity(2 * half + 1);
    (0..n)
        .map(|k| {
            buf.clear();
            buf.extend(v[k.saturating_sub(half)..(k + half + 1).min(n)].iter().filter(|x| !x.is_nan()));
            median_in_place(&mut buf).unwrap_or(f64::NAN)
        })
        .collect()
}

/// The workbench's random numbers: xoshiro256** (Blackman & Vigna, 2018) seeded
/// through SplitMix64, Gaussian samples by Box–Muller. A named algorithm rather than
/// `rand`'s `StdRng` (which may change between releases), so a file made with
/// `--seed N` stays the same file across dependency updates; the reference outputs in
/// the tests pin the stream. Bit-identical across platforms except for the last bits
/// of `ln`/`cos` in [`Rng::gauss`], which come from the platform's libm.
#[derive(Debug, Clone)]
pub struct Rng(Xoshiro256StarStar);

impl Rng {
    /// Stream `stream` of seed `seed`: each user (a bench channel, a bootstrap) takes
    /// its own, so switching one part on or off leaves the others' draws unchanged.
    pub fn new(seed: u64, stream: u64) -> Self {
        Self(Xoshiro256StarStar::seed_from_u64(seed ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03)))
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform index in `0..n` (0 for `n = 0`), for bootstrap resampling.
    pub fn index(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n.saturating_sub(1))
    }

    /// Standard normal (Box–Muller; one of the pair is used, so each call costs two
    /// uniforms and the stream stays simple to reproduce).
    pub fn gauss(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // (0, 1]: ln is finite
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NAN: f64 = f64::NAN;

    #[test]
    fn mean_rms_and_sd() {
        assert_eq!(mean(&[1.0, 2.0, 6.0]), 3.0);
        assert!(mean(&[]).is_nan());
        assert!(mean(&[1.0, NAN]).is_nan(), "a NaN sample propagates");
        assert_eq!(rms(&[3.0, -4.0, 3.0, -4.0]), 12.5f64.sqrt());
        assert!(rms(&[]).is_nan());
        assert!((std_dev(&[1.0, 2.0, 3.0, 4.0]) - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(std_dev(&[5.0]), 0.0);
        assert_eq!(std_dev(&[]), 0.0);
    }

    #[test]
    fn median_odd_even_empty_and_nan() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&[-1.0, 7.0]), Some(3.0));
        assert_eq!(median(&[]), None);
        assert_eq!(median(&[NAN, NAN]), None);
        assert_eq!(median(&[NAN, 5.0, 1.0, NAN, 3.0]), Some(3.0));
        assert_eq!(median(&[f64::INFINITY, 1.0, 2.0]), Some(2.0));
        // Agrees with sorting on random data (selection must not lose a value).
        let mut r = Rng::new(3, 0);
        for n in 1..40 {
            let v: Vec<f64> = (0..n).map(|_| r.gauss()).collect();
            let mut s = v.clone();
            s.sort_by(f64::total_cmp);
            let want = if n % 2 == 1 { s[n / 2] } else { 0.5 * (s[n / 2 - 1] + s[n / 2]) };
            assert_eq!(median(&v), Some(want));
        }
    }

    #[test]
    fn mad_and_spread_resist_outliers() {
        assert!((mad_sigma(&[1.0, 2.0, 3.0, 100.0]).unwrap() - 1.4826).abs() < 1e-12);
        assert_eq!(mad_sigma(&[]), None);
        assert_eq!(mad_sigma(&[NAN]), None);
        assert_eq!(mad_sigma(&[2.0, NAN, 2.0]), Some(0.0));
        let mut r = Rng::new(11, 0);
        let mut v: Vec<f64> = (0..20_000).map(|_| 2.0 * r.gauss()).collect();
        v.extend([1e9, -1e9, NAN, f64::INFINITY]);
        assert!((spread68(&v) - 2.0).abs() < 0.05, "{}", spread68(&v));
        assert!((mad_sigma(&v).unwrap() - 2.0).abs() < 0.05);
        assert_eq!(spread68(&[1.0]), 0.0);
        assert_eq!(spread68(&[]), 0.0);
    }

    #[test]
    fn moving_mean_is_centred_and_skips_nan() {
        let x: Vec<f64> = (0..10).map(f64::from).collect();
        let y = moving_mean(&x, 2);
        assert_eq!(y.len(), 10);
        assert_eq!(&y[2..8], &x[2..8], "a ramp stays a ramp inside");
        assert_eq!(y[0], 1.0); // mean of 0, 1, 2
        assert_eq!(y[9], 8.0); // mean of 7, 8, 9
        assert_eq!(moving_mean(&[1.0, NAN, 3.0], 1), vec![1.0, 2.0, 3.0]);
        let z = moving_mean(&[NAN, NAN, NAN, 4.0], 1);
        assert!(z[0].is_nan() && z[1].is_nan() && z[2] == 4.0 && z[3] == 4.0);
        assert!(moving_mean(&[], 3).is_empty());
        assert_eq!(moving_mean(&[1.0, 2.0], 0), vec![1.0, 2.0]);
    }

    #[test]
    fn median_filter_removes_spikes() {
        let v = [1.0, 1.0, 50.0, 1.0, 1.0, -40.0, 1.0, 1.0];
        assert_eq!(median_filter(&v, 1), vec![1.0; 8]);
        // Two samples at an end: the mean of the two.
        assert_eq!(median_filter(&[1.0, 1.0, -40.0], 1)[2], -19.5);
        assert_eq!(median_filter(&[3.0, 1.0], 5), vec![2.0, 2.0]);
        let f = median_filter(&[NAN, 2.0, NAN, NAN, NAN], 1);
        assert_eq!(&f[..3], &[2.0, 2.0, 2.0]);
        assert!(f[3].is_nan() && f[4].is_nan());
        assert!(median_filter(&[], 2).is_empty());
    }

    #[test]
    fn xoshiro_reference_output() {
        // The reference implementation with state {1, 2, 3, 4} gives 11520, 0, 1509978240.
        let mut seed = [0u8; 32];
        for (k, c) in seed.chunks_exact_mut(8).enumerate() {
            c.copy_from_slice(&(k as u64 + 1).to_le_bytes());
        }
        let mut r = Rng(Xoshiro256StarStar::from_seed(seed));
        assert_eq!([r.next_u64(), r.next_u64(), r.next_u64()], [11520, 0, 1_509_978_240]);
    }

    #[test]
    fn streams_are_those_of_earlier_releases() {
        // From the hand-written generator the virtual bench used before (SplitMix64
        // seeding of `seed ^ stream * 0xD1B54A32D192ED03`): files made with a seed
        // must not change.
        let mut r = Rng::new(7, 0);
        assert_eq!(
            [r.next_u64(), r.next_u64(), r.next_u64()],
            [12_923_355_070_828_475_994, 5_142_052_590_334_782_674, 15_488_392_906_492_639_638]
        );
        let mut r = Rng::new(42, 3);
        assert_eq!(
            [r.next_u64(), r.next_u64(), r.next_u64()],
            [4_393_367_743_702_550_806, 2_083_193_025_902_234_773, 1_613_447_729_919_889_217]
        );
    }

    #[test]
    fn gauss_moments_index_range_and_stream_independence() {
        let mut r = Rng::new(7, 0);
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| r.gauss()).collect();
        let m = mean(&xs);
        let var = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n as f64;
        assert!(m.abs() < 0.01 && (var - 1.0).abs() < 0.02, "{m} {var}");
        assert_ne!(Rng::new(7, 0).next_u64(), Rng::new(7, 1).next_u64());
        assert_ne!(Rng::new(7, 0).next_u64(), Rng::new(8, 0).next_u64());
        let mut hits = [0usize; 7];
        (0..7000).for_each(|_| hits[r.index(7)] += 1);
        assert!(hits.iter().all(|h| (800..1200).contains(h)), "{hits:?}");
        assert_eq!(r.index(0), 0);
        assert_eq!(r.index(1), 0);
    }
}
