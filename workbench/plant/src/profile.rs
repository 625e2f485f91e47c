//! The test profile as functions of time, scaled and clamped as the PLC does it.

use model_core::{ProfileSet, SetMode};

struct Segment {
    /// [ns] start and duration: integers, so set boundaries fall exactly on step times.
    start_ns: u64,
    duration_ns: u64,
    throttle: (f64, f64, SetMode),
    load: [(f64, f64, SetMode); 2],
}

/// Set points [%] at one instant: throttle (+ forward), loads (+ regenerating).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SetPoints {
    pub throttle: f64,
    pub load: [f64; 2],
}

/// A profile: sets held or interpolated to the next one (the last one to zero).
pub(crate) struct TimeProfile {
    segments: Vec<Segment>,
    throttle_scale: f64,
    load_scale: f64,
}

impl TimeProfile {
    /// `sets` scaled by the throttle and load scales (a negative scale flips the sign).
    pub(crate) fn new(sets: &[ProfileSet], throttle_scale: f64, load_scale: f64) -> Self {
        let mut segments = Vec::with_capacity(sets.len());
        let mut start_ns = 0;
        for (i, s) in sets.iter().enumerate() {
            let next = sets.get(i + 1);
            let nt = next.map_or(0.0, |n| f64::from(n.throttle_pct));
            let nl = next.map_or(0.0, |n| f64::from(n.load_l_pct));
            let nr = next.map_or(0.0, |n| f64::from(n.load_r_pct));
            // Whole µs, as the PLC's clock counts them.
            let duration_ns = ((f64::from(s.duration_s) * 1e6).round() as u64).max(1) * 1000;
            segments.push(Segment {
                start_ns,
                duration_ns,
                throttle: (f64::from(s.throttle_pct), nt, s.throttle_mode),
                load: [
                    (f64::from(s.load_l_pct), nl, s.load_mode),
                    (f64::from(s.load_r_pct), nr, s.load_mode),
                ],
            });
            start_ns += duration_ns;
        }
        Self { segments, throttle_scale, load_scale }
    }

    pub(crate) fn duration_ns(&self) -> u64 {
        self.segments.last().map_or(0, |s| s.start_ns + s.duration_ns)
    }

    /// Index of the segment that contains `t_ns` (the last one at or beyond the end,
    /// `None` before the start or for an empty profile).
    pub(crate) fn segment_at(&self, t_ns: i128) -> Option<usize> {
        if t_ns < 0 || self.segments.is_empty() {
            return None;
        }
        let t = t_ns as u64;
        let mut k = 0;
        while k + 1 < self.segments.len() && t >= self.segments[k + 1].start_ns {
            k += 1;
        }
        Some(k)
    }

    /// Set points at `t_ns` as segment `k` defines them (all zero for `None`, before the
    /// start): at the end of the segment this is the left limit, so an integration step
    /// that starts inside `k` never sees the next set's jump. `t_ns` may be fractional
    /// (RK4 stages).
    pub(crate) fn at(&self, k: Option<usize>, t_ns: f64) -> SetPoints {
        let Some(s) = k.and_then(|k| self.segments.get(k)) else {
            return SetPoints::default();
        };
        let frac = ((t_ns - s.start_ns as f64) / s.duration_ns as f64).clamp(0.0, 1.0);
        let value = |(a, b, mode): (f64, f64, SetMode)| match mode {
            SetMode::Hold => a,
            SetMode::Interpolate => a + frac * (b - a),
        };
        let clamp = |v: f64| v.clamp(-100.0, 100.0);
        SetPoints {
            throttle: clamp(value(s.throttle) * self.throttle_scale),
            load: [clamp(value(s.load[0]) * self.load_scale), clamp(value(s.load[1]) * self.load_scale)],
        }
    }

    /// Set points at `t_ns` (right-continuous at set boundaries), zero before the start.
    pub(crate) fn value(&self, t_ns: i128) -> SetPoints {
        self.at(self.segment_at(t_ns), t_ns as f64)
    }
}
