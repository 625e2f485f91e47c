//! Drive cycles (target speed against time) and grade profiles (grade against
//! distance), compiled in from `data/cycles/` and `data/grades/`; origins in the files'
//! headers.

use model_core::table::locate_hinted;

use crate::data as d;

/// The built-in scenarios: a cycle and the road it is driven on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Cycle {
    /// ECE-15, the urban cycle of UN ECE R83 (195 s, peak 50 km/h), on the flat.
    Ece15,
    /// A constructed delivery round: ten stops, 0 -> 25 km/h -> 0, on the flat.
    Delivery,
    /// 15 km/h over the grade profile `grades/hill.csv` (8 % up, -6 % down).
    Hill,
}

impl Cycle {
    /// Every built-in scenario.
    pub const ALL: [Cycle; 3] = [Cycle::Ece15, Cycle::Delivery, Cycle::Hill];

    /// Name on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            Cycle::Ece15 => "ece15",
            Cycle::Delivery => "delivery",
            Cycle::Hill => "hill",
        }
    }

    /// One line for help texts.
    pub const fn description(self) -> &'static str {
        match self {
            Cycle::Ece15 => "ECE-15 urban cycle (UN ECE R83), 195 s, on the flat",
            Cycle::Delivery => "delivery round: 10 stops, 0 -> 25 km/h -> 0 (constructed), on the flat",
            Cycle::Hill => "15 km/h over 8 % up and -6 % down (constructed)",
        }
    }

    /// Look up by name (case-insensitive).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name().eq_ignore_ascii_case(name))
    }

    /// The scenario's tables.
    pub fn route(self) -> Route<'static> {
        let (t, v): (&[f32], &[f32]) = match self {
            Cycle::Ece15 => (&d::CYCLE_ECE15_T, &d::CYCLE_ECE15_V),
            Cycle::Delivery => (&d::CYCLE_DELIVERY_T, &d::CYCLE_DELIVERY_V),
            Cycle::Hill => (&d::CYCLE_HILL_T, &d::CYCLE_HILL_V),
        };
        let grade = match self {
            Cycle::Hill => Grade {
                x: &d::GRADE_HILL_X,
                pct: &d::GRADE_HILL_PCT,
                sin: &d::GRADE_HILL_SIN,
                cos: &d::GRADE_HILL_COS,
            },
            _ => Grade { x: &d::FLAT_X, pct: &d::FLAT_ZERO, sin: &d::FLAT_ZERO, cos: &d::FLAT_ONE },
        };
        Route { t, v, grade }
    }
}

/// A grade profile: distance [m] and, per point, grade [%] and the slope's sine and
/// cosine (all linear between points, the ends held).
#[derive(Debug, Clone, Copy)]
pub struct Grade<'a> {
    pub x: &'a [f32],
    pub pct: &'a [f32],
    pub sin: &'a [f32],
    pub cos: &'a [f32],
}

/// The road at one point.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Slope {
    /// [%] grade, rise / run.
    pub pct: f32,
    /// Sine of the slope angle.
    pub sin: f32,
    /// Cosine of the slope angle.
    pub cos: f32,
}

/// A cycle (time [s] -> target speed [m/s]) and its grade profile.
#[derive(Debug, Clone, Copy)]
pub struct Route<'a> {
    /// [s] time grid, from 0.
    pub t: &'a [f32],
    /// [m/s] target speed at each time.
    pub v: &'a [f32],
    pub grade: Grade<'a>,
}

/// Interpolate `y` at a location found on its grid.
#[inline]
fn at(y: &[f32], (i, f): (usize, f32)) -> f32 {
    let y0 = y.get(i).copied().unwrap_or(0.0);
    let y1 = y.get(i + 1).copied().unwrap_or(y0);
    y0 + f * (y1 - y0)
}

impl Route<'_> {
    /// [µs] the cycle's length.
    pub fn duration_us(&self) -> u64 {
        let end = self.t.last().copied().unwrap_or(0.0);
        (f64::from(end) * 1e6 + 0.5) as u64
    }

    /// [m/s] target speed at `t_s`, 0 after the end; `hint` speeds up the search.
    #[inline]
    pub fn target(&self, t_s: f32, hint: &mut usize) -> f32 {
        if t_s >= self.t.last().copied().unwrap_or(0.0) {
            return self.v.last().copied().unwrap_or(0.0);
        }
        at(self.v, locate_hinted(self.t, t_s, hint))
    }

    /// The road at distance `x_m` along the route.
    #[inline]
    pub fn slope(&self, x_m: f32, hint: &mut usize) -> Slope {
        let g = &self.grade;
        let loc = locate_hinted(g.x, x_m, hint);
        Slope { pct: at(g.pct, loc), sin: at(g.sin, loc), cos: at(g.cos, loc) }
    }

    /// Grid consistency (the flash tables are checked by `build.rs`; this guards tables
    /// made at run time): lengths agree, at least two points.
    pub fn is_consistent(&self) -> bool {
        let g = &self.grade;
        self.t.len() >= 2
            && self.t.len() == self.v.len()
            && g.x.len() >= 2
            && [g.pct.len(), g.sin.len(), g.cos.len()].iter().all(|n| *n == g.x.len())
    }

    /// [m] the cycle's distance (trapezoids of the speed table).
    pub fn distance_m(&self) -> f64 {
        self.t
            .windows(2)
            .zip(self.v.windows(2))
            .map(|(t, v)| match (t, v) {
                ([t0, t1], [v0, v1]) => f64::from(t1 - t0) * 0.5 * f64::from(v0 + v1),
                _ => 0.0,
            })
            .sum()
    }

    /// [m/s] the cycle's highest target.
    pub fn peak(&self) -> f32 {
        self.v.iter().copied().fold(0.0, f32::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// R83 gives the elementary urban cycle as 195 s and 1.013 km; the operations' nominal
    /// speeds give 1.0146 km (accelerations rounded to 0.01 m/s^2 in the regulation).
    #[test]
    fn ece15_matches_the_regulation() {
        let r = Cycle::Ece15.route();
        assert!(r.is_consistent());
        assert_eq!(r.duration_us(), 195_000_000);
        let d = r.distance_m();
        assert!((d - 1013.0).abs() < 0.005 * 1013.0, "{d} m");
        assert!((r.peak() * 3.6 - 50.0).abs() < 1e-4);
        let mut h = 0;
        assert!((r.target(150.0, &mut h) * 3.6 - 50.0).abs() < 1e-4);
        assert!((r.target(13.0, &mut h) * 3.6 - 7.5).abs() < 1e-4);
        assert_eq!(r.target(1000.0, &mut h), 0.0);
    }

    #[test]
    fn delivery_round_has_ten_stops_at_25_kmh() {
        let r = Cycle::Delivery.route();
        assert!(r.is_consistent());
        let starts = r.v.windows(2).filter(|w| matches!(w, [a, b] if *a == 0.0 && *b > 0.0)).count();
        assert_eq!(starts, 10);
        assert!((r.peak() * 3.6 - 25.0).abs() < 1e-4);
        assert!((r.distance_m() - 1220.0).abs() < 0.5, "{}", r.distance_m());
    }

    #[test]
    fn hill_grade_profile() {
        let r = Cycle::Hill.route();
        assert!(r.is_consistent());
        let mut h = 0;
        let s = r.slope(250.0, &mut h);
        assert!((s.pct - 8.0).abs() < 1e-5);
        assert!((s.sin - 0.079_745).abs() < 1e-5 && (s.cos - 0.996_815).abs() < 1e-5, "{s:?}");
        assert!((r.slope(500.0, &mut h).pct + 6.0).abs() < 1e-5);
        assert_eq!(r.slope(5000.0, &mut h).pct, 0.0);
        assert_eq!(Cycle::Ece15.route().slope(123.0, &mut h), Slope { pct: 0.0, sin: 0.0, cos: 1.0 });
        assert!((r.distance_m() - 850.0).abs() < 0.1);
    }

    #[test]
    fn names_round_trip() {
        for c in Cycle::ALL {
            assert_eq!(Cycle::from_name(&c.name().to_uppercase()), Some(c));
        }
        assert_eq!(Cycle::from_name("udds"), None);
    }
}
