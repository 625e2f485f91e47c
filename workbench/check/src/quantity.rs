//! What a limit is on: a channel of the twin, or a quantity derived from the channels
//! and the model's mechanical parameters. Each step gives the interval the quantity
//! spans since the previous sample, so a peak between two samples is not missed.
//!
//! **The torque flange between samples.** `J_f = 0.0023 kg m²` between the flange's
//! 349 kN m/rad and the coupling rings near 2 kHz. The twin integrates that mode exactly
//! (`model-core/src/drivetrain.rs`) but only *samples* it: at 1 ms a 0.5 ms oscillation
//! is aliased and its peaks fall between samples. The mode is excited by steps of the
//! torque on the SuT side (a share `J_f / (J_a + J_f)`, under 1 %, of each step) and by
//! gear-backlash impacts (tens of N m), so it matters where impacts happen. A flange
//! limit therefore needs a step that resolves the mode, at least 4 samples a period
//! ([`Dynamics::max_dt_us`], 126 µs; `check` runs at 100 µs by default), and the peak
//! between samples is bounded analytically: a sinusoid of amplitude `A` sampled at
//! phase steps `θ = ω_h dt` peaks at most `A (1 − cos θ/2)` above its larger sample.
//! `A` is estimated per step from three samples (second difference for the in-phase,
//! centred first difference for the quadrature part); the slow part's slope only
//! inflates it, so the bound stays conservative. A smooth part's own peak between
//! samples is at most `|x''| dt² / 8`, the second difference over 8, which is added
//! too (three samples cannot tell curvature from oscillation, so both are assumed).
//! At 100 µs the allowance is at most 36 % of the mode's amplitude, at 20 µs 1.5 %;
//! where nothing rings it is the smooth part's curvature alone, thousandths of a N m.

use model_core::drivetrain::{SideParams, RAD_S_PER_RPM};
use model_core::{Channel, Outputs};

/// A quantity a limit can be on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// A channel of the twin, as it reports it.
    Channel(Channel),
    /// [W] SuT motor shaft power, `SuT_torque × SuTMotorEnc` (+ motoring, − generating).
    SutMotorPower,
    /// [N m] torque-flange torque L (0) / R (1), `C_Kistler_*` with the flange mode's
    /// peaks between samples.
    FlangeTorque(usize),
    /// [N m] coupling torque L (0) / R (1): the step's mean flange torque minus what
    /// accelerates the flange inertia, `J_f Δω_f / dt`.
    CouplingTorque(usize),
}

/// The derived quantities: name, quantity, unit, meaning.
pub const DERIVED: [(&str, Quantity, &str, &str); 5] = [
    ("sut_motor_power", Quantity::SutMotorPower, "W", "SuT motor shaft power, SuT_torque x SuTMotorEnc"),
    (
        "flange_torque_L",
        Quantity::FlangeTorque(0),
        "N m",
        "C_Kistler_L with the 2 kHz flange mode's peaks between samples",
    ),
    ("flange_torque_R", Quantity::FlangeTorque(1), "N m", "as flange_torque_L, right side"),
    (
        "coupling_torque_L",
        Quantity::CouplingTorque(0),
        "N m",
        "flange torque L minus the flange inertia's share, J_f dω/dt",
    ),
    ("coupling_torque_R", Quantity::CouplingTorque(1), "N m", "as coupling_torque_L, right side"),
];

impl Quantity {
    /// A channel name or a derived quantity's name.
    pub fn from_name(name: &str) -> Option<Self> {
        DERIVED
            .iter()
            .find(|d| d.0 == name)
            .map(|d| d.1)
            .or_else(|| Channel::from_name(name).map(Quantity::Channel))
    }

    /// Its name in limit files.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Channel(c) => c.name(),
            q => DERIVED.iter().find(|d| d.1 == q).map_or("?", |d| d.0),
        }
    }

    /// Its unit.
    pub fn unit(self) -> &'static str {
        match self {
            Quantity::Channel(c) => c.unit(),
            q => DERIVED.iter().find(|d| d.1 == q).map_or("?", |d| d.2),
        }
    }

    /// Whether it needs the flange mode resolved (a step of at most
    /// [`Dynamics::max_dt_us`]).
    pub fn needs_flange_mode(self) -> bool {
        matches!(self, Quantity::FlangeTorque(_) | Quantity::CouplingTorque(_))
    }

    /// Every name a limit file may use, for error messages.
    pub fn names() -> String {
        let derived: Vec<&str> = DERIVED.iter().map(|d| d.0).collect();
        format!(
            "the derived quantities {} or a channel name (e.g. `C_Kistler_L`, `I_DPU 2.7`)",
            derived.join(", ")
        )
    }
}

/// The mechanical constants the derived quantities need, per side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dynamics {
    /// [kg m²] flange inertia.
    pub j_f: [f64; 2],
    /// [rad/s] the highest mode of the side's chain (the flange mode).
    pub omega_h: [f64; 2],
}

impl Dynamics {
    /// From the model's side parameters (after effects).
    pub fn of(sides: &[SideParams; 2]) -> Self {
        Self { j_f: sides.map(|s| f64::from(s.j_f)), omega_h: sides.map(|s| flange_mode(&s)) }
    }

    /// The largest step [µs] that samples the flange mode at least 4 times a period.
    pub fn max_dt_us(&self) -> u32 {
        let w = self.omega_h[0].max(self.omega_h[1]);
        (std::f64::consts::FRAC_PI_2 / w * 1e6).floor() as u32
    }

    /// [Hz] the flange mode's frequency (the higher side's).
    pub fn flange_hz(&self) -> f64 {
        self.omega_h[0].max(self.omega_h[1]) / std::f64::consts::TAU
    }
}

/// [rad/s] the highest undamped mode of `J_a —k_f— J_f —k_c— J_l`: the larger root of
/// `ω⁴ − b ω² + c = 0` (the free chain's characteristic equation without its rigid mode).
pub fn flange_mode(s: &SideParams) -> f64 {
    let (ja, jf, jl) = (f64::from(s.j_a), f64::from(s.j_f), f64::from(s.j_l));
    let (kf, kc) = (f64::from(s.k_f), f64::from(s.k_c));
    let b = kf / ja + kf / jf + kc / jf + kc / jl;
    let c = kf * kc * (ja + jf + jl) / (ja * jf * jl);
    (0.5 * (b + (b * b - 4.0 * c).max(0.0).sqrt())).sqrt()
}

/// Turns each step's outputs into the interval a quantity spans since the last sample.
#[derive(Debug, Clone)]
pub struct Estimator {
    q: Quantity,
    dt_s: f64,
    /// Inter-sample allowance per unit of the flange mode's amplitude, `1 − cos θ/2`.
    allowance: f64,
    /// `2 (cos θ − 1)` and `2 sin θ`: the three-sample amplitude estimate.
    d2_gain: f64,
    d1_gain: f64,
    j_f: f64,
    /// The last two samples of the channel the quantity reads (newest first) and of
    /// the flange speed; how many are valid.
    hist: [f64; 2],
    speed: f64,
    n: usize,
}

impl Estimator {
    /// For quantity `q` at step `dt_s` with the model's `dynamics`.
    pub fn new(q: Quantity, dt_s: f64, dynamics: &Dynamics) -> Self {
        let side = match q {
            Quantity::FlangeTorque(s) | Quantity::CouplingTorque(s) => s.min(1),
            _ => 0,
        };
        let theta = dynamics.omega_h[side] * dt_s;
        Self {
            q,
            dt_s,
            allowance: 1.0 - (0.5 * theta).cos(),
            d2_gain: 2.0 * (theta.cos() - 1.0),
            d1_gain: 2.0 * theta.sin(),
            j_f: dynamics.j_f[side],
            hist: [0.0; 2],
            speed: 0.0,
            n: 0,
        }
    }

    /// `(low, high)` of the quantity since the previous sample.
    pub fn step(&mut self, o: &Outputs) -> (f64, f64) {
        let v = |c: Channel| f64::from(o.get(c));
        match self.q {
            Quantity::Channel(c) => (v(c), v(c)),
            Quantity::SutMotorPower => {
                let p = v(Channel::SuTTorque) * v(Channel::SuTMotorEnc) * f64::from(RAD_S_PER_RPM);
                (p, p)
            }
            Quantity::FlangeTorque(s) => self.flange(v(kistler(s))),
            Quantity::CouplingTorque(s) => {
                let (t, w) = (v(kistler(s)), v(flange_speed(s)) * f64::from(RAD_S_PER_RPM));
                let c = if self.n == 0 {
                    t
                } else {
                    0.5 * (t + self.hist[0]) - self.j_f * (w - self.speed) / self.dt_s
                };
                self.push(t);
                self.speed = w;
                (c, c)
            }
        }
    }

    /// The flange torque between the last sample and `x`, with the mode's allowance.
    fn flange(&mut self, x: f64) -> (f64, f64) {
        let (x1, x2) = (self.hist[0], self.hist[1]);
        let out = match self.n {
            0 => (x, x),
            1 => (x.min(x1), x.max(x1)),
            _ => {
                let d2 = x - 2.0 * x1 + x2;
                let (osc, quad) = (d2 / self.d2_gain, (x - x2) / self.d1_gain);
                // The mode's peak between samples, and a smooth part's (|x''| dt² / 8).
                let a = (osc * osc + quad * quad).sqrt() * self.allowance + 0.125 * d2.abs();
                (x.min(x1) - a, x.max(x1) + a)
            }
        };
        self.push(x);
        out
    }

    fn push(&mut self, x: f64) {
        self.hist = [x, self.hist[0]];
        self.n = (self.n + 1).min(2);
    }
}

fn kistler(side: usize) -> Channel {
    if side == 0 {
        Channel::CKistlerL
    } else {
        Channel::CKistlerR
    }
}

fn flange_speed(side: usize) -> Channel {
    if side == 0 {
        Channel::TKistlerL
    } else {
        Channel::TKistlerR
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The L side of the thesis model, as the twin builds it from its parameters.
    fn thesis_side() -> SideParams {
        let model = model_core::Model::new(&model_core::Config::default()).expect("the thesis model");
        model.side_params()[0]
    }

    #[test]
    fn flange_mode_is_near_2_khz_and_solves_the_chain() {
        let s = thesis_side();
        let w = flange_mode(&s);
        assert!((w / std::f64::consts::TAU - 1980.0).abs() < 5.0, "{}", w / std::f64::consts::TAU);
        // det(K - w² M) = 0 for the 3-mass chain: an independent check of the root.
        let (ja, jf, jl, kf, kc) =
            (f64::from(s.j_a), f64::from(s.j_f), f64::from(s.j_l), f64::from(s.k_f), f64::from(s.k_c));
        let l = w * w;
        let det = (kf - l * ja) * ((kf + kc - l * jf) * (kc - l * jl) - kc * kc) - kf * kf * (kc - l * jl);
        let scale = kf * kf * kc;
        assert!(det.abs() < 1e-6 * scale, "{det}");
        let d = Dynamics::of(&[s, s]);
        assert_eq!(d.max_dt_us(), 126);
    }

    #[test]
    fn names_round_trip() {
        for (n, q, u, _) in DERIVED {
            assert_eq!(Quantity::from_name(n), Some(q));
            assert_eq!((q.name(), q.unit()), (n, u));
        }
        assert_eq!(Quantity::from_name("I_DPU 2.7"), Some(Quantity::Channel(Channel::IDpu27)));
        assert_eq!(Quantity::from_name("nope"), None);
    }

    #[test]
    fn flange_bound_covers_a_sampled_sinusoid() {
        // x(t) = 40 + 25 cos(ω t + φ) sampled at 100 µs: the continuous peak (65) must lie
        // within the intervals, and the allowance must stay small.
        let s = thesis_side();
        let d = Dynamics::of(&[s, s]);
        let w = d.omega_h[0];
        for phi in [0.0, 0.7, 1.9, 3.0] {
            let mut e = Estimator::new(Quantity::FlangeTorque(0), 1e-4, &d);
            let mut hi = f64::MIN;
            let mut o = Outputs::default();
            for k in 0..200 {
                let x = 40.0 + 25.0 * (w * k as f64 * 1e-4 + phi).cos();
                o.values[Channel::CKistlerL as usize] = x as f32;
                hi = hi.max(e.step(&o).1);
            }
            assert!(hi >= 65.0 - 1e-3, "phi {phi}: {hi}");
            // At most (1 − cos θ/2) + (1 − cos θ)/4 of the amplitude above the peak.
            let theta = w * 1e-4;
            let most = (1.0 - (0.5 * theta).cos()) + 0.25 * (1.0 - theta.cos());
            assert!(hi <= 65.0 + most * 25.0 + 1e-3, "phi {phi}: {hi}");
        }
    }
}
