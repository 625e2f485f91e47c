//! Test-profile engine (thesis 4.1): up to 10 sets of duration, throttle and two load
//! set points, each with hold/interpolate flags, scaled and signed by the operator.
//!
//! Time is kept in integer microseconds so that set boundaries fall on the same step
//! on every target, whatever the step size.

use heapless::Vec;

use crate::data;

/// The PLC's limit on sets per profile.
pub const MAX_SETS: usize = 10;

/// What a set point does during its set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SetMode {
    /// Keep this set's value until the next set.
    Hold,
    /// Ramp linearly from this set's value to the next set's (to 0 after the last set).
    Interpolate,
}

/// One set of a test profile. Set points in percent, signed: throttle + forward,
/// − reverse; load + regenerating, − motoring.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ProfileSet {
    pub duration_s: f32,
    pub throttle_pct: f32,
    pub load_l_pct: f32,
    pub load_r_pct: f32,
    pub throttle_mode: SetMode,
    pub load_mode: SetMode,
}

/// Why a profile was rejected.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ProfileError {
    /// No sets, or more than [`MAX_SETS`].
    SetCount(usize),
    /// Set `n` (0-based) has a duration that is not finite and > 0 (or above 1e6 s).
    Duration(usize),
    /// Set `n` has a set point outside [-100, 100] % or not finite.
    SetPoint(usize),
    /// A scaling factor is not finite or outside [-1.5, 1.5].
    Scale,
}

/// The built-in profiles, compiled from `data/profiles/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Builtin {
    TP07,
    TP11,
    TP12,
    TP13,
    TP14,
}

impl Builtin {
    /// All built-in profiles.
    pub const ALL: [Builtin; 5] = [Builtin::TP07, Builtin::TP11, Builtin::TP12, Builtin::TP13, Builtin::TP14];

    /// The profile's sets.
    pub fn sets(self) -> &'static [ProfileSet] {
        match self {
            Builtin::TP07 => &data::PROFILE_TP07,
            Builtin::TP11 => &data::PROFILE_TP11,
            Builtin::TP12 => &data::PROFILE_TP12,
            Builtin::TP13 => &data::PROFILE_TP13,
            Builtin::TP14 => &data::PROFILE_TP14,
        }
    }

    /// Name as the thesis writes it.
    pub fn name(self) -> &'static str {
        match self {
            Builtin::TP07 => "TP07",
            Builtin::TP11 => "TP11",
            Builtin::TP12 => "TP12",
            Builtin::TP13 => "TP13",
            Builtin::TP14 => "TP14",
        }
    }

    /// Look up by name (case-insensitive).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|b| b.name().eq_ignore_ascii_case(name))
    }
}

/// Set points at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SetPoints {
    /// [%] signed throttle set point.
    pub throttle_pct: f32,
    /// [%] signed load set points L, R.
    pub load_pct: [f32; 2],
}

#[derive(Debug, Clone, Copy)]
struct TimedSet {
    set: ProfileSet,
    start_us: u64,
    dur_us: u64,
}

/// A validated, scaled profile.
#[derive(Debug, Clone)]
pub struct Profile {
    sets: Vec<TimedSet, MAX_SETS>,
    throttle_scale: f32,
    load_scale: f32,
    end_us: u64,
}

fn valid_pct(v: f32) -> bool {
    v.is_finite() && (-100.0..=100.0).contains(&v)
}

impl Profile {
    /// Build a profile; scales multiply the set points (a negative scale flips the sign:
    /// reverse for the throttle, motoring/regenerating for the loads). Scaled set points
    /// are clamped to [-100, 100] %.
    pub fn new(sets: &[ProfileSet], throttle_scale: f32, load_scale: f32) -> Result<Self, ProfileError> {
        if sets.is_empty() || sets.len() > MAX_SETS {
            return Err(ProfileError::SetCount(sets.len()));
        }
        let scale_ok = |s: f32| s.is_finite() && (-1.5..=1.5).contains(&s);
        if !scale_ok(throttle_scale) || !scale_ok(load_scale) {
            return Err(ProfileError::Scale);
        }
        let mut out = Vec::new();
        let mut start_us = 0u64;
        for (i, s) in sets.iter().enumerate() {
            if !(s.duration_s.is_finite() && s.duration_s > 0.0 && s.duration_s <= 1.0e6) {
                return Err(ProfileError::Duration(i));
            }
            if !(valid_pct(s.throttle_pct) && valid_pct(s.load_l_pct) && valid_pct(s.load_r_pct)) {
                return Err(ProfileError::SetPoint(i));
            }
            // f64 product then round: exact for any duration written with <= 6 decimals.
            let dur_us = (f64::from(s.duration_s) * 1.0e6 + 0.5) as u64;
            let timed = TimedSet { set: *s, start_us, dur_us: dur_us.max(1) };
            start_us += timed.dur_us;
            out.push(timed).map_err(|_| ProfileError::SetCount(sets.len()))?;
        }
        Ok(Self { sets: out, throttle_scale, load_scale, end_us: start_us })
    }

    /// A built-in profile, scaled.
    pub fn builtin(which: Builtin, throttle_scale: f32, load_scale: f32) -> Result<Self, ProfileError> {
        Self::new(which.sets(), throttle_scale, load_scale)
    }

    /// The sets, unscaled, in order.
    pub fn sets(&self) -> impl Iterator<Item = ProfileSet> + '_ {
        self.sets.iter().map(|t| t.set)
    }

    /// Throttle and load scales.
    pub fn scales(&self) -> (f32, f32) {
        (self.throttle_scale, self.load_scale)
    }

    /// Total duration [µs].
    pub fn duration_us(&self) -> u64 {
        self.end_us
    }

    /// The scaled set points at time `t_us`; zero after the end.
    pub fn at(&self, t_us: u64) -> SetPoints {
        let mut iter = self.sets.iter().enumerate();
        let found = iter.find(|(_, s)| t_us < s.start_us + s.dur_us);
        let Some((k, cur)) = found else {
            return SetPoints::default();
        };
        let next = self.sets.get(k + 1).map(|n| n.set);
        let frac = (t_us.saturating_sub(cur.start_us)) as f32 / cur.dur_us as f32;
        let blend = |mode: SetMode, a: f32, b: f32| match mode {
            SetMode::Hold => a,
            SetMode::Interpolate => a + frac * (b - a),
        };
        let s = &cur.set;
        let thr = blend(s.throttle_mode, s.throttle_pct, next.map_or(0.0, |n| n.throttle_pct));
        let ll = blend(s.load_mode, s.load_l_pct, next.map_or(0.0, |n| n.load_l_pct));
        let lr = blend(s.load_mode, s.load_r_pct, next.map_or(0.0, |n| n.load_r_pct));
        let clamp = |v: f32| v.clamp(-100.0, 100.0);
        SetPoints {
            throttle_pct: clamp(thr * self.throttle_scale),
            load_pct: [clamp(ll * self.load_scale), clamp(lr * self.load_scale)],
        }
    }
}
