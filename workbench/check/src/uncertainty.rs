//! The model's uncertainty as distributions of its parameters and effect parameters, and
//! where they come from: an uncertainty file (`--uncertainty`), an identification's
//! `uncertainty.toml` (`--from-identify DIR`), or a diagnosis's intervals
//! (`--from-diagnose FILE.json`, what `simrod diagnose --json` prints).
//!
//! A sample draws every value from its own stream of the one RNG (`Rng::new(seed,
//! sample)`), so sample `i` is the same whatever the number of threads or samples.

use std::path::Path;

use model_core::{Config, CouplingStiffness, Effects, Params, RateSet};
use serde_json::Value;
use simrod_io::datadir::ModelData;
use simrod_io::effects_file::{get_param, parse_effects};
use simrod_io::error::FileError;
use simrod_io::uncertainty_file::{load_uncertainty, Dist, Target, Uncertain};
use simrod_numerics::stats::Rng;

/// The model's choices a parameter key depends on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Choice {
    pub rates: RateSet,
    pub coupling: CouplingStiffness,
}

/// One uncertain value, resolved against the model: its mean is known.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    pub target: Target,
    pub dist: Dist,
    /// The model's own value.
    pub nominal: f64,
    /// Where it was given.
    pub origin: String,
}

/// Distributions to draw the model from.
#[derive(Debug, Clone, PartialEq)]
pub struct Uncertainty {
    /// Where they came from (a file, an identification, a diagnosis).
    pub source: String,
    pub items: Vec<Item>,
    pub choice: Choice,
    /// What was left out, and why.
    pub notes: Vec<String>,
}

impl Item {
    /// `name ~ N(mean, sd)` / `name ~ U[min, max]`.
    pub fn describe(&self) -> String {
        match self.dist {
            Dist::Normal { mean: Some(m), sd } => format!("{} ~ N({m}, {sd})", self.target.name()),
            // The model's own value came from an f32: shown as that f32.
            Dist::Normal { mean: None, sd } => {
                format!("{} ~ N({}, {sd})", self.target.name(), self.nominal as f32)
            }
            Dist::Uniform { min, max } => format!("{} ~ U[{min}, {max}]", self.target.name()),
        }
    }

    fn draw(&self, rng: &mut Rng) -> f64 {
        match self.dist {
            Dist::Normal { mean, sd } => mean.unwrap_or(self.nominal) + sd * rng.gauss(),
            Dist::Uniform { min, max } => min + (max - min) * rng.uniform(),
        }
    }
}

impl Uncertainty {
    /// Resolve `raw` against the nominal model `config` (its parameters from `data`, or
    /// the built-in file): every parameter key must be one the model uses with `choice`,
    /// and a normal without a mean takes the model's value.
    pub fn resolve(
        raw: Vec<Uncertain>,
        source: &str,
        config: &Config,
        data: Option<&ModelData>,
        choice: Choice,
    ) -> Result<Self, String> {
        let builtin;
        let data = match data {
            Some(d) => d,
            None => {
                builtin = ModelData::builtin().map_err(|e| e.to_string())?;
                &builtin
            }
        };
        let mut items = Vec::with_capacity(raw.len());
        for u in raw {
            let name = u.target.name();
            let nominal = match &u.target {
                Target::Param(k) => param_nominal(k, config, data, choice),
                Target::Effect { effect, param } => effect_nominal(&config.effects, effect, param, &u.dist),
            }
            .map_err(|m| format!("{}: {name}: {m}", u.origin))?;
            if items.iter().any(|i: &Item| i.target == u.target) {
                return Err(format!("{}: {name} is given twice", u.origin));
            }
            items.push(Item { target: u.target, dist: u.dist, nominal, origin: u.origin });
        }
        Ok(Self { source: source.to_string(), items, choice, notes: Vec::new() })
    }

    /// Sample `index`'s values, one per item.
    pub fn draw(&self, seed: u64, index: u64) -> Vec<f64> {
        let mut rng = Rng::new(seed, index);
        self.items.iter().map(|i| i.draw(&mut rng)).collect()
    }

    /// `config` with the drawn `values` set, and whether a value was clipped. An effect
    /// parameter drawn beyond its valid range is clipped to it (a friction cannot be
    /// negative: the distribution's mass beyond the bound sits at the bound); a model
    /// parameter drawn at or below zero is an error naming it (its distribution is too
    /// wide for the model).
    pub fn apply(&self, config: &Config, values: &[f64]) -> Result<(Config, bool), String> {
        let mut c = *config;
        let mut clipped = false;
        for (i, v) in self.items.iter().zip(values) {
            let x = *v as f32;
            match &i.target {
                Target::Param(k) => {
                    if !(x.is_finite() && x > 0.0) {
                        return Err(format!("{k} = {v} (parameters must be finite and > 0)"));
                    }
                    let _ = c.params.set(k, x, self.choice.rates, self.choice.coupling);
                }
                Target::Effect { effect, param } => {
                    let y = clip(effect, param, x);
                    clipped |= y != x;
                    let _ = c.effects.set(effect, param, y);
                }
            }
        }
        c.effects.check().map_err(|bad| format!("effect `{}`: {bad}", bad.effect.id))?;
        Ok((c, clipped))
    }
}

/// `x` within the declared range of an effect parameter (an open end: the nearest f32
/// inside it).
fn clip(effect: &str, param: &str, x: f32) -> f32 {
    let Some(r) = model_core::effects::effect(effect).and_then(|e| e.params.iter().find(|p| p.name == param))
    else {
        return x;
    };
    let r = r.range;
    if r.contains(x) {
        return x;
    }
    let inward = |b: f32, up: bool| {
        let bits = b.to_bits();
        // One ulp towards the inside of the range (b finite: the declared ranges are).
        let next = if (b >= 0.0) == up { bits + 1 } else { bits.saturating_sub(1) };
        if b == 0.0 {
            if up {
                f32::from_bits(1)
            } else {
                -f32::from_bits(1)
            }
        } else {
            f32::from_bits(next)
        }
    };
    if x.is_nan() || x < r.min || (x == r.min && !r.min_inclusive) {
        if r.min_inclusive {
            r.min
        } else {
            inward(r.min, true)
        }
    } else if r.max_inclusive {
        r.max
    } else {
        inward(r.max, false)
    }
}

/// The model's value of parameter `key`; an error when the model in use ignores it
/// (`ident.*` under programmed rates, the other coupling stiffness).
fn param_nominal(key: &str, config: &Config, data: &ModelData, choice: Choice) -> Result<f64, String> {
    let v = data.param(key).ok_or("not in the model's parameters.toml")?;
    let mut probe: Params = config.params;
    let _ = probe.set(key, v * 2.0 + 1.0, choice.rates, choice.coupling);
    if probe == config.params {
        return Err(format!(
            "the model in use does not read it (rates {:?}, coupling {:?}): see --params / --coupling",
            choice.rates, choice.coupling
        ));
    }
    Ok(f64::from(v))
}

/// The current value of an effect parameter; an effect that is off has none, so a
/// normal around "the model's value" needs an explicit mean there.
fn effect_nominal(fx: &Effects, effect: &str, param: &str, dist: &Dist) -> Result<f64, String> {
    match (get_param(fx, effect, param), dist) {
        (Some(v), _) => Ok(f64::from(v)),
        (None, Dist::Normal { mean: Some(m), .. }) => Ok(*m),
        (None, Dist::Uniform { min, max }) => Ok(0.5 * (min + max)),
        (None, Dist::Normal { mean: None, .. }) => {
            Err("the effect is off in this model: give the normal's mean".to_string())
        }
    }
}

/// An uncertainty file.
pub fn from_file(path: &Path) -> Result<Vec<Uncertain>, FileError> {
    load_uncertainty(path)
}

/// The file `simrod identify` writes into its output directory.
pub const IDENTIFY_FILE: &str = "uncertainty.toml";

/// An identification's intervals: `DIR/uncertainty.toml`.
pub fn from_identify(dir: &Path) -> Result<Vec<Uncertain>, FileError> {
    let p = dir.join(IDENTIFY_FILE);
    if !p.is_file() {
        return Err(FileError::whole(
            &p,
            "not found: expected the output directory of `simrod identify` (it writes the identified values' standard uncertainties there)",
        ));
    }
    load_uncertainty(&p)
}

/// A diagnosis's intervals, from `simrod diagnose --json` output: the effects its
/// verdict names (`selected`), centred on the values it proposes
/// (`proposed_effects`), each parameter with the standard deviation of its refit
/// (`ranking[].uncertainty`). Parameters without a finite one are held at the proposed
/// value (returned in the notes).
pub fn from_diagnose(path: &Path) -> Result<(Vec<Uncertain>, Vec<String>), FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::io(path, &e))?;
    let v: Value =
        serde_json::from_str(&text).map_err(|e| FileError::at(path, e.line(), e.column(), e.to_string()))?;
    let field = |name: &str| {
        v.get(name).ok_or_else(|| {
            FileError::whole(path, format!("no `{name}`: expected the output of `simrod diagnose --json`"))
        })
    };
    let proposed = match field("proposed_effects")? {
        Value::String(s) => parse_effects(s, format!("{} (proposed_effects)", path.display()))?,
        _ => return Err(FileError::whole(path, "the diagnosis proposes no effect: nothing to draw from")),
    };
    let selected: Vec<&str> = field("selected")?
        .as_array()
        .map(|a| a.iter().filter_map(|s| s.get("effect").and_then(Value::as_str)).collect())
        .unwrap_or_default();
    if selected.is_empty() {
        return Err(FileError::whole(path, "`selected` names no effect: nothing to draw from"));
    }
    let ranking = field("ranking")?.as_array().cloned().unwrap_or_default();
    let mut out = Vec::new();
    let mut notes = Vec::new();
    if selected.len() > 1 {
        notes.push(format!(
            "{} effects were refitted jointly; the JSON holds each one's own refit standard deviation, used here (the joint fit's can be larger where they are confounded)",
            selected.len()
        ));
    }
    for e in selected {
        let entry = ranking.iter().find(|r| r.get("effect").and_then(Value::as_str) == Some(e));
        let sds = entry.and_then(|r| r.get("uncertainty")).and_then(Value::as_object);
        let Some(sds) = sds else {
            return Err(FileError::whole(path, format!("`ranking` has no uncertainty for `{e}`")));
        };
        for (p, sd) in sds {
            let mean = get_param(&proposed, e, p).map(f64::from);
            match (mean, sd.as_f64().filter(|s| s.is_finite() && *s > 0.0)) {
                (Some(m), Some(sd)) => out.push(Uncertain {
                    target: Target::Effect { effect: e.to_string(), param: p.clone() },
                    dist: Dist::Normal { mean: Some(m), sd },
                    origin: format!("{} ({e}.{p})", path.display()),
                }),
                _ => notes.push(format!(
                    "{e}.{p}: no finite standard deviation in the diagnosis; held at its proposed value"
                )),
            }
        }
    }
    Ok((out, notes))
}

#[cfg(test)]
mod tests {
    use super::*;
    use simrod_io::uncertainty_file::parse_uncertainty;

    fn choice() -> Choice {
        Choice { rates: RateSet::Identified, coupling: CouplingStiffness::Identified }
    }

    #[test]
    fn resolves_means_and_refuses_keys_the_model_ignores() {
        let raw = parse_uncertainty(
            "[params.load_inertia_l]\nnormal = { sd = 0.05 }\n[effects.differential_friction.coulomb_nm]\n\
             uniform = { min = 1, max = 3 }\n",
            "u.toml",
        )
        .unwrap();
        let u = Uncertainty::resolve(raw, "u.toml", &Config::default(), None, choice()).unwrap();
        assert_eq!(u.items[0].nominal, f64::from(0.4543f32));
        assert_eq!(u.items[1].nominal, 0.0, "the effect's current value");
        let raw =
            parse_uncertainty("[params.\"prog.accel_hs_fwd_s\"]\nnormal = { sd = 0.1 }\n", "u.toml").unwrap();
        let e = Uncertainty::resolve(raw, "u.toml", &Config::default(), None, choice()).unwrap_err();
        assert!(e.starts_with("u.toml:1: prog.accel_hs_fwd_s: the model in use does not read it"), "{e}");
        let raw = parse_uncertainty(
            "[effects.coupling_stiffness.stiffness_nm_per_rad]\nnormal = { sd = 100 }\n",
            "u.toml",
        )
        .unwrap();
        let e = Uncertainty::resolve(raw, "u.toml", &Config::default(), None, choice()).unwrap_err();
        assert!(e.contains("give the normal's mean"), "{e}");
    }

    #[test]
    fn draws_are_per_sample_streams_and_apply_to_the_config() {
        let raw = parse_uncertainty(
            "[params.load_inertia_l]\nuniform = { min = 0.4, max = 0.5 }\n\
             [params.coupling_stiffness_identified]\nnormal = { mean = 4000, sd = 100 }\n",
            "u.toml",
        )
        .unwrap();
        let u = Uncertainty::resolve(raw, "u.toml", &Config::default(), None, choice()).unwrap();
        let a = u.draw(7, 3);
        assert_eq!(a, u.draw(7, 3));
        assert_ne!(a, u.draw(7, 4));
        assert!((0.4..0.5).contains(&a[0]));
        let (c, clipped) = u.apply(&Config::default(), &a).unwrap();
        assert!(!clipped);
        assert_eq!(c.params.load_inertia[0], a[0] as f32);
        assert_eq!(c.params.coupling_stiffness, a[1] as f32);
        let e = u.apply(&Config::default(), &[-1.0, 4000.0]).unwrap_err();
        assert!(e.contains("load_inertia_l = -1"), "{e}");
        // An effect parameter beyond its range is clipped to it.
        let raw = parse_uncertainty(
            "[effects.differential_friction.viscous_nm_s_per_rad]\nnormal = { mean = 0, sd = 1 }\n\
             [effects.supply_resistance.resistance_ohm]\nuniform = { min = 0.5, max = 2 }\n",
            "u.toml",
        )
        .unwrap();
        let u = Uncertainty::resolve(raw, "u.toml", &Config::default(), None, choice()).unwrap();
        let (c, clipped) = u.apply(&Config::default(), &[-0.3, 1.5]).unwrap();
        assert!(clipped);
        assert_eq!(c.effects.differential_friction.viscous_nm_s, 0.0);
        assert!(
            c.effects.supply_resistance < 1.0 && c.effects.supply_resistance > 0.999_999,
            "[0, 1) ends below 1"
        );
    }
}
