//! The candidate parameters `diagnose` may fit: every parameter of every effect in
//! `model_core::effects::LIBRARY`, with its neutral value, a finite-difference step
//! sized to the effect's realistic magnitude, and physical bounds — all from the
//! effect's declaration in `model_core::effects` (its `Fit`), so there is no table here
//! to keep in step with the model.

use model_core::effects::{Cause, Effects, InSteps, Side, Step, EFFECTS};
use model_core::Params;

/// One fittable parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSpec {
    /// Effect id, e.g. `differential_friction`.
    pub effect: &'static str,
    /// Parameter name, e.g. `coulomb_nm`.
    pub param: &'static str,
    /// The candidate cause it belongs to: the effect id, or `effect.param` where each
    /// parameter is a cause of its own (the measurement chain's, one channel each).
    pub cause: &'static str,
    /// Value that leaves the model as it is.
    pub neutral: f64,
    /// Finite-difference step (also the scale used to condition the fit).
    pub delta: f64,
    /// Physical bounds.
    pub lower: f64,
    /// Physical bounds.
    pub upper: f64,
    /// Unit, for reports.
    pub unit: &'static str,
    /// How far the twin's step alone may move a fit of it
    /// ([`model_core::effects::Fit::step_bias`]).
    pub step_bias: Step,
    /// Which side of the truth it puts a fit ([`model_core::effects::Fit::step_bias_side`]).
    pub step_bias_side: Side,
}

impl ParamSpec {
    /// The twin's step bias of a fit at `v` as `(centre, half-width)` ([`Side::split`]).
    pub fn bias_at(&self, v: f64) -> (f64, f64) {
        self.step_bias_side.split(self.step_bias.at(v))
    }

    /// The 95 % interval of the truth for a fit `v` reported at σ `sd` (which counts the
    /// bias' half-width), within the search bounds: centred on `v` less the bias' centre
    /// ([`Self::bias_at`]).
    pub fn ci95(&self, v: f64, sd: f64) -> (f64, f64) {
        let mid = v - self.bias_at(v).0;
        ((mid - 1.96 * sd).max(self.lower), (mid + 1.96 * sd).min(self.upper))
    }

    /// The finite-difference step from value `v`: `delta`, or `-delta` where that would
    /// pass the upper bound.
    pub fn step_from(&self, v: f64) -> f64 {
        if v + self.delta <= self.upper {
            self.delta
        } else {
            -self.delta
        }
    }

    /// Whether it is a cause of the measurement chain (one parameter of one channel's
    /// gain, offset, delay or lag), not of the physics.
    pub fn is_chain(&self) -> bool {
        self.cause != self.effect
    }

    /// Whether `self` fitted at `(a, σa)` and `other` at `(b, σb)` are one kind of
    /// measurement-chain fault on two channels, agreeing as one cause acting on both
    /// would make them: within a tenth of the smaller departure from the thesis value and
    /// within 2 σ of their difference. Sensors fail apart; two that fail alike to a tenth
    /// is what a cause upstream of both does (a map feeding both flange torques, a delay
    /// of the physics seen on several speeds), and a sensor cause moves one channel alone.
    pub fn alike(&self, (a, sa): (f64, f64), other: &ParamSpec, (b, sb): (f64, f64)) -> bool {
        let kin = self.is_chain()
            && other.is_chain()
            && self.cause != other.cause
            && self.effect == other.effect
            && self.unit == other.unit;
        let diff = (a - b).abs();
        kin && diff < 0.1 * (a - self.neutral).abs().min((b - self.neutral).abs())
            && diff < 2.0 * sa.hypot(sb)
    }

    /// The declared scan grid `(step, to)` of a parameter whose objective has narrow
    /// valleys ([`model_core::effects::Fit::scan`]).
    pub fn scan(&self) -> Option<(f64, f64)> {
        model_core::effects::effect(self.effect).and_then(|e| e.param(self.param)).and_then(|p| p.fit)?.scan
    }

    /// Whether `v` is off the neutral value by more than rounding (a millionth of the
    /// sensitivity step): the effect is in a model that holds it there.
    pub fn off_neutral(&self, v: f64) -> bool {
        (v - self.neutral).abs() > 1e-6 * self.delta
    }

    /// Whether `v` of a physical parameter sits at an end of the search range away from
    /// the neutral value: the data asks for more than the effect can physically give, so
    /// a fit that ends there stands in for something else (a coupling damping at
    /// 300 N m s/rad, 80x the thesis's, for a stiffer coupling). Not for the measurement
    /// chain, whose ranges end at what a bench realistically has (a channel recorded
    /// 99 ms late fits the delay's 0.1 s end).
    pub fn at_end(&self, v: f64) -> bool {
        let tol = 1e-6 * self.delta;
        !self.is_chain() && self.off_neutral(v) && (v >= self.upper - tol || v <= self.lower + tol)
    }

    /// The smallest step in which the model can realise the parameter, at time step `dt`
    /// (0 where it is continuous).
    pub fn quantum(&self, dt: f64) -> f64 {
        match self.in_steps() {
            Some(InSteps::Whole) => dt,
            _ => 0.0,
        }
    }

    /// The finite-difference step that gives the parameter's slope at time step `dt`
    /// where the model is linear in it over a known span (a sensor delay between whole
    /// steps: one step); `None` elsewhere. The delay's half sensitivity step (10 ms)
    /// spans several turns of a signal and gives a secant, not the slope.
    pub fn slope_step(&self, dt: f64) -> Option<f64> {
        (self.in_steps() == Some(InSteps::Linear)).then_some(dt)
    }

    fn in_steps(&self) -> Option<InSteps> {
        let fit = model_core::effects::effect(self.effect).and_then(|e| e.param(self.param))?.fit?;
        Some(fit.in_steps)
    }
}

/// Every library parameter, in library (declaration) order. Neutral values of
/// overrides come from the model's parameters `p`.
pub fn library(p: &Params) -> Vec<ParamSpec> {
    let mut out = Vec::new();
    for e in EFFECTS.iter().filter(|e| e.in_library()) {
        for d in e.params {
            let Some(fit) = d.fit else { continue };
            let neutral = f64::from(d.neutral(e.id, p));
            out.push(ParamSpec {
                effect: e.id,
                param: d.name,
                cause: if e.cause == Cause::PerParameter { d.path } else { e.id },
                neutral,
                delta: fit.delta(neutral),
                lower: fit.lower,
                upper: fit.upper,
                unit: d.unit,
                step_bias: fit.step_bias,
                step_bias_side: fit.step_bias_side,
            });
        }
    }
    out
}

/// The cause that parameter `param` of effect `effect` belongs to ([`ParamSpec::cause`]).
pub fn cause_of(effect: &str, param: &str) -> Option<&'static str> {
    let e = model_core::effects::effect(effect)?;
    let d = e.param(param)?;
    Some(if e.cause == Cause::PerParameter { d.path } else { e.id })
}

/// Whether the model already holds `cause`: some parameter of it (`specs`, each started
/// at its `starts`) starts off its neutral value.
pub fn holds(specs: &[ParamSpec], starts: &[f64], cause: &str) -> bool {
    specs.iter().zip(starts).any(|(sp, s0)| sp.cause == cause && sp.off_neutral(*s0))
}

/// `base` with each `(spec, value)` applied.
pub fn with_values(base: &Effects, specs: &[&ParamSpec], values: &[f64]) -> Effects {
    let mut fx = *base;
    for (s, v) in specs.iter().zip(values) {
        // Every spec comes from the declarations, so `set` cannot refuse it.
        let _ = fx.set(s.effect, s.param, *v as f32);
    }
    fx
}

/// The current value of a parameter in `fx` (the neutral value when an override is unset).
pub fn current_value(fx: &Effects, s: &ParamSpec) -> f64 {
    fx.get(s.effect, s.param).ok().flatten().map_or(s.neutral, f64::from)
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::effects::LIBRARY;

    /// A step bias of known sign (the controller delay's: the 1 ms twin fits it long)
    /// moves the truth's interval off the fit by half the bias and keeps half of it as
    /// unknown: the truth is held whether the fit fell at the bias' near end, its middle
    /// or its far end, by an interval half as wide as the same bias of unknown sign needs.
    #[test]
    fn a_bias_of_known_sign_shifts_the_interval() {
        let lib = library(&Params::default());
        let d = lib.iter().find(|s| s.effect == "controller_delay").unwrap().clone();
        assert_eq!(d.step_bias_side, Side::Above, "the controller delay's bias is declared above");
        let either = ParamSpec { step_bias_side: Side::Either, ..d.clone() };
        let t = 0.1;
        let b = d.step_bias.at(t);
        for k in [0.0, 0.5, 1.0] {
            let v = t + k * b;
            // The reported σ of a fit whose scatter is negligible: the bias' unknown part.
            let sd = |s: &ParamSpec| s.bias_at(v).1 / 3f64.sqrt();
            let (lo, hi) = d.ci95(v, sd(&d));
            assert!(lo <= t && t <= hi, "fit {v}: [{lo}, {hi}] misses {t}");
            let (elo, ehi) = either.ci95(v, sd(&either));
            assert!((ehi - elo - 2.0 * (hi - lo)).abs() < 1e-12, "[{elo}, {ehi}] vs [{lo}, {hi}]");
        }
        // Below the truth is where the twin does not put it: a fit a whole bias short is
        // outside.
        let short = t - b;
        let (lo, hi) = d.ci95(short, d.bias_at(short).1 / 3f64.sqrt());
        assert!(hi < t, "fit {short}: [{lo}, {hi}] holds {t}");
    }

    /// The numbers derive from the declarations as the old hand-kept table had them.
    #[test]
    fn specs_follow_the_declarations() {
        let p = Params::default();
        let lib = library(&p);
        let spec = |e: &str, q: &str| lib.iter().find(|s| s.effect == e && s.param == q).cloned();
        let k = spec("coupling_stiffness", "stiffness_nm_per_rad").unwrap();
        assert_eq!(
            (k.neutral, k.delta),
            (f64::from(p.coupling_stiffness), 0.2 * f64::from(p.coupling_stiffness))
        );
        assert_eq!(
            spec("coupling_damping", "damping_nm_s_per_rad").unwrap().neutral,
            f64::from(p.coupling_damping)
        );
        let d = spec("controller_delay", "delay_s").unwrap();
        assert_eq!((d.neutral, d.delta, d.lower, d.upper, d.quantum(1e-3)), (0.0, 0.02, 0.0, 0.25, 1e-3));
        let g = spec("sensor_gain", "siemensenc").unwrap();
        assert_eq!(
            (g.neutral, g.delta, g.lower, g.upper, g.unit, g.quantum(1e-3)),
            (1.0, 0.01, 0.5, 2.0, "-", 0.0)
        );
        assert!(spec("stribeck_friction", "peak_nm").is_none(), "bench-only physics is not the twin's");
        // Library order is declaration order.
        let order: Vec<&str> = lib.iter().map(|s| s.effect).fold(Vec::new(), |mut v, e| {
            if v.last() != Some(&e) {
                v.push(e);
            }
            v
        });
        assert_eq!(order, LIBRARY);
        // 18 physical parameters, and the four measurement-chain effects on each measured
        // channel, each channel's a cause of its own.
        let chain = 4 * model_core::MEASURED.len();
        assert_eq!(lib.len(), 18 + chain);
        let per_param = lib.iter().filter(|s| s.cause != s.effect).count();
        assert_eq!(per_param, chain);
        assert_eq!(cause_of("sensor_lag", "c_kistler_l"), Some("sensor_lag.c_kistler_l"));
        assert_eq!(cause_of("differential_friction", "coulomb_nm"), Some("differential_friction"));
    }

    #[test]
    fn library_covers_every_library_effect_and_round_trips() {
        let p = Params::default();
        let lib = library(&p);
        for id in LIBRARY {
            assert!(lib.iter().any(|s| s.effect == *id), "{id} has no fittable parameter");
        }
        for s in &lib {
            assert!(s.lower <= s.neutral && s.neutral <= s.upper, "{}.{}", s.effect, s.param);
            let v = (s.neutral + s.delta).min(s.upper);
            let fx = with_values(&Effects::NONE, &[s], &[v]);
            assert!(
                ((current_value(&fx, s) - v) / v.abs().max(1e-9)).abs() < 1e-6,
                "{}.{}",
                s.effect,
                s.param
            );
            assert_eq!(current_value(&Effects::NONE, s), s.neutral, "{}.{}", s.effect, s.param);
        }
    }

    /// A physical fit at either end of its range away from neutral is at its end; one
    /// inside, one at a neutral end, and a measurement-chain one are not.
    #[test]
    fn only_a_physical_fit_at_its_range_end_is_at_its_end() {
        let lib = library(&Params::default());
        let spec = |e: &str, q: &str| lib.iter().find(|s| s.effect == e && s.param == q).cloned().unwrap();
        let damping = spec("coupling_damping", "damping_nm_s_per_rad");
        assert!(damping.at_end(damping.upper));
        assert!(!damping.at_end(0.99 * damping.upper));
        assert!(!damping.at_end(damping.neutral));
        let inertia = spec("inertia_scale", "sut");
        assert!(inertia.at_end(inertia.lower) && inertia.at_end(inertia.upper));
        let coulomb = spec("differential_friction", "coulomb_nm");
        assert_eq!(coulomb.lower, coulomb.neutral);
        assert!(!coulomb.at_end(coulomb.lower) && coulomb.at_end(coulomb.upper));
        let delay = spec("sensor_delay", "c_kistler_r");
        assert!(!delay.at_end(delay.upper));
    }
}
