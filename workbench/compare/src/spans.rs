//! Worst time spans: the sliding-window RMS of a residual and its highest
//! non-overlapping windows, so a user can go straight to the seconds that matter.
//! Prefix sums make every window O(1): the whole search is O(N) per pick.

use serde::Serialize;

/// One window of the residual.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Span {
    /// [s] time of the window's first sample.
    pub start_s: f64,
    /// [s] time of its last sample.
    pub end_s: f64,
    /// RMS of the residual in the window.
    pub rms: f64,
}

/// The `count` windows of `window` samples with the highest residual RMS, no two
/// overlapping, highest first. Non-finite residual samples are left out of a window's
/// mean. Fewer are returned when the run is too short.
pub fn worst_spans(time_s: &[f64], e: &[f64], window: usize, count: usize) -> Vec<Span> {
    let n = e.len().min(time_s.len());
    if n == 0 {
        return Vec::new();
    }
    let w = window.clamp(1, n);
    let mut sum = Vec::with_capacity(n + 1);
    let mut cnt = Vec::with_capacity(n + 1);
    sum.push(0.0f64);
    cnt.push(0usize);
    let (mut s, mut c) = (0.0, 0usize);
    for v in e.iter().take(n) {
        if v.is_finite() {
            s += v * v;
            c += 1;
        }
        sum.push(s);
        cnt.push(c);
    }
    let starts = n - w + 1;
    // Mean square of every window, NaN where it has no finite sample.
    let ms: Vec<f64> = (0..starts)
        .map(|j| {
            let c = cnt.get(j + w).copied().unwrap_or(0) - cnt.get(j).copied().unwrap_or(0);
            let s = sum.get(j + w).copied().unwrap_or(0.0) - sum.get(j).copied().unwrap_or(0.0);
            if c == 0 {
                f64::NAN
            } else {
                s.max(0.0) / c as f64
            }
        })
        .collect();
    let mut blocked = vec![false; starts];
    let mut out = Vec::new();
    for _ in 0..count {
        let mut best: Option<(usize, f64)> = None;
        for (j, (b, r)) in blocked.iter().zip(&ms).enumerate() {
            if *b || !r.is_finite() {
                continue;
            }
            if best.is_none_or(|(_, br)| *r > br) {
                best = Some((j, *r));
            }
        }
        let Some((j, r)) = best else { break };
        let r = r.sqrt();
        // Any start within w of j would overlap this window.
        let lo = j.saturating_sub(w - 1);
        let hi = (j + w).min(starts);
        for b in blocked.iter_mut().take(hi).skip(lo) {
            *b = true;
        }
        out.push(Span {
            start_s: time_s.get(j).copied().unwrap_or(f64::NAN),
            end_s: time_s.get(j + w - 1).copied().unwrap_or(f64::NAN),
            rms: r,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_bursts_in_order_without_overlap() {
        let n = 1000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
        let mut e = vec![0.01; n];
        e[100..150].fill(1.0);
        e[600..650].fill(3.0);
        let s = worst_spans(&t, &e, 50, 3);
        assert_eq!(s.len(), 3);
        assert_eq!(s[0].start_s, 6.0);
        assert!((s[0].rms - 3.0).abs() < 1e-12);
        assert_eq!(s[1].start_s, 1.0);
        assert!((s[0].end_s - 6.49).abs() < 1e-12);
        for (i, a) in s.iter().enumerate() {
            for b in s.iter().skip(i + 1) {
                assert!(a.end_s < b.start_s || b.end_s < a.start_s, "{a:?} {b:?}");
            }
        }
        // The third is the best window touching neither burst.
        assert!(s[2].rms < 1.0);
    }

    #[test]
    fn short_or_empty_runs() {
        assert!(worst_spans(&[], &[], 10, 3).is_empty());
        let s = worst_spans(&[0.0, 1.0], &[1.0, f64::NAN], 10, 3);
        assert_eq!(s.len(), 1);
        assert_eq!(s[0].rms, 1.0);
    }
}
