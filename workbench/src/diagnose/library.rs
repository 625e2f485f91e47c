//! The candidate parameters `diagnose` may fit: every parameter of every effect in
//! `model_core::effects::LIBRARY`, with its neutral value, a finite-difference step
//! sized to the effect's realistic magnitude, and physical bounds.

use model_core::effects::{Effects, EFFECT_PARAMS, LIBRARY};
use model_core::Params;

/// One fittable parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSpec {
    /// Effect id, e.g. `differential_friction`.
    pub effect: &'static str,
    /// Parameter name, e.g. `coulomb_nm`.
    pub param: &'static str,
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
}

impl ParamSpec {
    /// The smallest step in which the model can realise the parameter, at time step `dt`
    /// (0 where it is continuous).
    pub fn quantum(&self, dt: f64) -> f64 {
        if self.effect == "controller_delay" {
            dt
        } else {
            0.0
        }
    }
}

/// `(neutral, delta, lower, upper, unit)` of a parameter; `None` for parameters not in
/// the library. Neutral values of overrides come from the model's parameters.
fn spec_numbers(effect: &str, param: &str, p: &Params) -> Option<(f64, f64, f64, f64, &'static str)> {
    let k = f64::from(p.coupling_stiffness);
    Some(match (effect, param) {
        ("differential_friction", "coulomb_nm") => (0.0, 1.0, 0.0, 60.0, "N m"),
        ("differential_friction", "viscous_nm_s_per_rad") => (0.0, 0.2, 0.0, 20.0, "N m s/rad"),
        ("axle_friction_scale", _) => (1.0, 0.05, 0.1, 5.0, "-"),
        ("gear_backlash", "backlash_deg") => (0.0, 0.5, 0.0, 20.0, "deg"),
        ("controller_delay", "delay_s") => (0.0, 0.02, 0.0, 0.25, "s"),
        ("inverter_rate_scale", _) => (1.0, 0.05, 0.2, 5.0, "-"),
        ("coupling_stiffness", _) => (k, 0.2 * k, 300.0, 60_000.0, "N m/rad"),
        ("coupling_damping", _) => (f64::from(p.coupling_damping), 2.0, 0.0, 300.0, "N m s/rad"),
        ("inertia_scale", _) => (1.0, 0.05, 0.1, 5.0, "-"),
        ("connector_resistance", _) => (f64::from(p.connector_resistance), 0.005, 0.0, 0.3, "ohm"),
        ("supply_resistance", _) => (0.0, 0.005, 0.0, 0.5, "ohm"),
        ("regen_efficiency", _) => (0.0, 0.05, 0.0, 0.9, "-"),
        ("torque_sensor_offset", _) => (0.0, 1.0, -60.0, 60.0, "N m"),
        ("torque_sensor_gain", _) | ("current_sensor_gain", _) => (1.0, 0.02, 0.5, 2.0, "-"),
        ("speed_sensor_gain", _) => (1.0, 0.01, 0.5, 2.0, "-"),
        _ => return None,
    })
}

/// Every library parameter, in library order.
pub fn library(p: &Params) -> Vec<ParamSpec> {
    let mut out = Vec::new();
    for id in LIBRARY {
        let Some((effect, params)) = EFFECT_PARAMS.iter().find(|(e, _)| e == id) else { continue };
        for param in params.iter() {
            if let Some((neutral, delta, lower, upper, unit)) = spec_numbers(effect, param, p) {
                out.push(ParamSpec { effect, param, neutral, delta, lower, upper, unit });
            }
        }
    }
    out
}

/// `base` with each `(spec, value)` applied.
pub fn with_values(base: &Effects, specs: &[&ParamSpec], values: &[f64]) -> Effects {
    let mut fx = *base;
    for (s, v) in specs.iter().zip(values) {
        // Every spec comes from EFFECT_PARAMS, so `set` cannot refuse it.
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
}
