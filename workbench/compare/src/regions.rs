//! Operating regions: every sample is classified from the *measured* and *commanded*
//! signals (never from the twin's outputs, which are what is being judged), so the
//! error budget says where the bench was, not where the model thought it was.
//!
//! Rules (thresholds in [`RegionRules`], limits in [`Limits`]):
//! - motion: the SuT motor speed (`SuTMotorEnc`) is smoothed by a centred moving
//!   average applied twice (`smooth_s` wide); the slope of its magnitude, a central
//!   difference over `smooth_s`, above `+accel_rpm_s` is *accelerating*, below
//!   `−accel_rpm_s` *decelerating*, else *steady*. Magnitude, so speeding up in
//!   reverse is accelerating too.
//! - direction: the throttle set point's sign when `|sp| ≥ deadband_pct`; with the
//!   throttle released, the smoothed speed's sign when `|n| ≥ standstill_rpm`; at
//!   standstill with no throttle the previous direction holds (forward at the start).
//! - load mode: the mean of the two load set points: `> +deadband_pct` *regenerating*,
//!   `< −deadband_pct` *motoring*, else *unloaded*. This is the load motors' mode: the
//!   SuT inverter feeds power back while the loads are *motoring* (they drive it).
//! - at a limit (any of): speed within `speed_margin` (3 %) of the forward/reverse
//!   limit; the commanded load phase current (the twin's current map at the recorded
//!   set points: phase current is not measured) within `limit_margin` (5 %) of the
//!   map's largest magnitude (≈ 60 A); measured `P_SuT_inv` within 5 % of the SuT power
//!   map's extremes (thesis ≈ +6000 / −1600 W); measured |C_Kistler| within 5 % of the
//!   load torque map's largest magnitude on that side.
//!
//! When the file lacks `SuTMotorEnc` the twin's speed stands in (noted in the result).

use model_core::{Maps, Params};
use serde::Serialize;

use simrod_twin::Aligned;

/// Thresholds of the region rules.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RegionRules {
    /// [s] width of the speed smoothing and of the slope's difference.
    pub smooth_s: f64,
    /// [rpm/s] slope of |speed| beyond which the bench is accelerating/decelerating.
    /// The slowest Curtis ramp (low accel, 32 s) is ~100 rpm/s.
    pub accel_rpm_s: f64,
    /// [%] set points closer to 0 than this count as 0.
    pub deadband_pct: f64,
    /// [rpm] motor speed below which the shaft counts as standing.
    pub standstill_rpm: f64,
    /// Fraction of the speed limit counting as "at the limit".
    pub speed_margin: f64,
    /// Fraction of the current, power and torque limits counting as "at the limit".
    pub limit_margin: f64,
}

impl Default for RegionRules {
    fn default() -> Self {
        Self {
            smooth_s: 0.1,
            accel_rpm_s: 50.0,
            deadband_pct: 0.5,
            standstill_rpm: 5.0,
            speed_margin: 0.03,
            limit_margin: 0.05,
        }
    }
}

/// Operating limits used by the "at a limit" rule.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Limits {
    /// [rpm] SuT motor speed limits forward, reverse.
    pub speed_rpm: [f64; 2],
    /// [A] largest commanded load phase current magnitude.
    pub phase_current_a: f64,
    /// [W] SuT inverter power extremes: drawn (max), fed back (min, negative).
    pub sut_power_w: [f64; 2],
    /// [N m] largest load torque magnitude, L and R.
    pub load_torque_nm: [f64; 2],
}

impl Limits {
    /// The limits of a twin, from its own data (`--data-dir` when given).
    pub fn of_model(m: &simrod_twin::ModelOptions) -> Result<Self, simrod_twin::TwinError> {
        Ok(Self::of(&m.params(), &m.maps()?))
    }

    /// The limits of the given parameters and maps.
    pub fn of(p: &Params, maps: &Maps<'_>) -> Self {
        let absmax = |z: &[f32]| z.iter().fold(0.0f64, |a, v| a.max(f64::from(v.abs())));
        let z = maps.sut_power.z();
        Self {
            speed_rpm: [f64::from(p.speed_limit_rpm[0]), f64::from(p.speed_limit_rpm[1])],
            phase_current_a: absmax(maps.load_current[0].z()).max(absmax(maps.load_current[1].z())),
            sut_power_w: [
                z.iter().fold(0.0f64, |a, v| a.max(f64::from(*v))),
                z.iter().fold(0.0f64, |a, v| a.min(f64::from(*v))),
            ],
            load_torque_nm: [absmax(maps.load_torque[0].z()), absmax(maps.load_torque[1].z())],
        }
    }
}

/// Transient state from the speed slope.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    Accelerating,
    Decelerating,
    Steady,
}

/// Run direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    Forward,
    Reverse,
}

/// Load motors' mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LoadMode {
    Motoring,
    Regenerating,
    Unloaded,
}

impl Motion {
    pub const ALL: [Motion; 3] = [Motion::Accelerating, Motion::Decelerating, Motion::Steady];
    pub fn name(self) -> &'static str {
        match self {
            Motion::Accelerating => "accelerating",
            Motion::Decelerating => "decelerating",
            Motion::Steady => "steady",
        }
    }
}

impl Direction {
    pub const ALL: [Direction; 2] = [Direction::Forward, Direction::Reverse];
    pub fn name(self) -> &'static str {
        match self {
            Direction::Forward => "forward",
            Direction::Reverse => "reverse",
        }
    }
}

impl LoadMode {
    pub const ALL: [LoadMode; 3] = [LoadMode::Motoring, LoadMode::Regenerating, LoadMode::Unloaded];
    pub fn name(self) -> &'static str {
        match self {
            LoadMode::Motoring => "loads motoring",
            LoadMode::Regenerating => "loads regenerating",
            LoadMode::Unloaded => "unloaded",
        }
    }
}

/// Limit flags of one sample (bit set).
pub const LIMIT_SPEED: u8 = 1;
pub const LIMIT_CURRENT: u8 = 2;
pub const LIMIT_POWER: u8 = 4;
pub const LIMIT_TORQUE: u8 = 8;
/// Flag and name of each limit.
pub const LIMIT_NAMES: [(u8, &str); 4] = [
    (LIMIT_SPEED, "speed limit"),
    (LIMIT_CURRENT, "load current limit"),
    (LIMIT_POWER, "SuT power limit"),
    (LIMIT_TORQUE, "load torque limit"),
];

/// The class of one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Class {
    pub motion: Motion,
    pub direction: Direction,
    pub load: LoadMode,
    /// `LIMIT_*` flags.
    pub limits: u8,
}

impl Class {
    /// Index of the combined region direction × motion × load, `0..N_COMBINED`.
    pub fn combined(&self) -> usize {
        let d = self.direction as usize;
        let m = self.motion as usize;
        let l = self.load as usize;
        (d * 3 + m) * 3 + l
    }
}

/// Number of combined regions.
pub const N_COMBINED: usize = 18;

/// The combined region of an index, inverse of [`Class::combined`].
pub fn combined_parts(i: usize) -> (Direction, Motion, LoadMode) {
    let l = LoadMode::ALL[i % 3];
    let m = Motion::ALL[(i / 3) % 3];
    let d = Direction::ALL[(i / 9) % 2];
    (d, m, l)
}

/// Name of a combined region, e.g. `forward / decelerating / loads regenerating`.
pub fn combined_name(i: usize) -> String {
    let (d, m, l) = combined_parts(i);
    format!("{} / {} / {}", d.name(), m.name(), l.name())
}

/// Every sample's class plus what was used to decide it.
#[derive(Debug, Clone)]
pub struct Classification {
    pub classes: Vec<Class>,
    pub rules: RegionRules,
    pub limits: Limits,
    /// Caveats (e.g. a missing channel a rule fell back on).
    pub notes: Vec<String>,
}

/// Replace non-finite samples by the last finite one (0 before any).
fn fill_gaps(x: &[f64]) -> Vec<f64> {
    let mut last = 0.0;
    x.iter()
        .map(|v| {
            if v.is_finite() {
                last = *v;
            }
            last
        })
        .collect()
}

fn measured<'a>(al: &'a Aligned, name: &str) -> Option<&'a [f64]> {
    al.channels.iter().find(|p| p.name == name).map(|p| p.meas.as_slice())
}

/// Classify every sample of an aligned run.
pub fn classify(al: &Aligned, rules: &RegionRules, limits: &Limits) -> Classification {
    let n = al.grid.time_s.len();
    let mut notes = Vec::new();
    let speed_raw = match measured(al, "SuTMotorEnc") {
        Some(v) => v,
        None => {
            notes.push("no SuTMotorEnc in the file: regions use the twin's speed".to_string());
            al.sim_speed.as_slice()
        }
    };
    let dt = al.grid.dt_s();
    let w = ((rules.smooth_s / dt).round() as usize).max(1) | 1;
    let speed = simrod_numerics::stats::moving_mean(
        &simrod_numerics::stats::moving_mean(&fill_gaps(speed_raw), w / 2),
        w / 2,
    );
    let h = (w / 2).max(1);
    let p_sut = measured(al, "P_SuT_inv");
    if p_sut.is_none() {
        notes.push("no V_DC/I_DC in the file: the SuT power limit rule is off".to_string());
    }
    let torque = [measured(al, "C_Kistler_L"), measured(al, "C_Kistler_R")];
    let [thr, ll, lr] = &al.grid.set_points;
    let db = rules.deadband_pct;
    let mut dir = Direction::Forward;
    let mut classes = Vec::with_capacity(n);
    let sv = |i: usize| speed.get(i).copied().unwrap_or(0.0);
    for k in 0..n {
        let at = |v: &[f64]| v.get(k).copied().unwrap_or(0.0);
        let a = k.saturating_sub(h);
        let b = (k + h).min(n.saturating_sub(1));
        let span =
            al.grid.time_s.get(b).copied().unwrap_or(0.0) - al.grid.time_s.get(a).copied().unwrap_or(0.0);
        let slope = if span > 0.0 { (sv(b).abs() - sv(a).abs()) / span } else { 0.0 };
        let motion = if slope > rules.accel_rpm_s {
            Motion::Accelerating
        } else if slope < -rules.accel_rpm_s {
            Motion::Decelerating
        } else {
            Motion::Steady
        };
        let sp = at(thr);
        let n_k = sv(k);
        if sp >= db {
            dir = Direction::Forward;
        } else if sp <= -db {
            dir = Direction::Reverse;
        } else if n_k >= rules.standstill_rpm {
            dir = Direction::Forward;
        } else if n_k <= -rules.standstill_rpm {
            dir = Direction::Reverse;
        }
        let load_mean = 0.5 * (at(ll) + at(lr));
        let load = if load_mean > db {
            LoadMode::Regenerating
        } else if load_mean < -db {
            LoadMode::Motoring
        } else {
            LoadMode::Unloaded
        };
        let mut flags = 0u8;
        let lim_n = limits.speed_rpm[dir as usize];
        if lim_n > 0.0 && n_k.abs() >= (1.0 - rules.speed_margin) * lim_n {
            flags |= LIMIT_SPEED;
        }
        let near = 1.0 - rules.limit_margin;
        let i_ph = at(&al.phase_current[0]).abs().max(at(&al.phase_current[1]).abs());
        if limits.phase_current_a > 0.0 && i_ph >= near * limits.phase_current_a {
            flags |= LIMIT_CURRENT;
        }
        if let Some(p) = p_sut {
            let pk = at(p);
            let [hi, lo] = limits.sut_power_w;
            if (hi > 0.0 && pk >= near * hi) || (lo < 0.0 && pk <= near * lo) {
                flags |= LIMIT_POWER;
            }
        }
        for (t, lim) in torque.iter().zip(limits.load_torque_nm) {
            if let Some(t) = t {
                if lim > 0.0 && at(t).abs() >= near * lim {
                    flags |= LIMIT_TORQUE;
                }
            }
        }
        classes.push(Class { motion, direction: dir, load, limits: flags });
    }
    Classification { classes, rules: *rules, limits: *limits, notes }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn combined_index_round_trips() {
        let mut seen = [false; N_COMBINED];
        for d in Direction::ALL {
            for m in Motion::ALL {
                for l in LoadMode::ALL {
                    let c = Class { motion: m, direction: d, load: l, limits: 0 };
                    let i = c.combined();
                    assert_eq!(combined_parts(i), (d, m, l));
                    seen[i] = true;
                }
            }
        }
        assert!(seen.iter().all(|s| *s));
    }

    #[test]
    fn builtin_limits_are_the_thesis_magnitudes() {
        let l = Limits::of(&Params::default(), &Maps::builtin());
        assert_eq!(l.speed_rpm, [2100.0, 500.0]);
        assert!((55.0..=65.0).contains(&l.phase_current_a), "{l:?}");
        assert!(l.sut_power_w[0] > 4000.0 && l.sut_power_w[1] < -1000.0, "{l:?}");
        assert!(l.load_torque_nm.iter().all(|t| *t > 10.0), "{l:?}");
    }
}
