//! Effect files (`--effects FILE.toml`): which of the model's extra physical effects
//! are on, and with what parameters.
//!
//! ```toml
//! [controller_delay]
//! delay_s = 0.012
//!
//! [differential_friction]
//! coulomb_nm = 0.8
//! viscous_nm_s_per_rad = 0.01
//! ```
//!
//! Sections are effect ids, keys their parameters (the vocabulary is
//! [`model_core::effects::EFFECT_PARAMS`]; units and meaning in
//! `workbench/examples/effects.toml`). Effects not named stay off, parameters not
//! named keep their "off" value. Errors are `file:line:col: message`, naming the
//! unknown effect or parameter with the accepted ones, or the parameter whose value
//! the model refuses.
//!
//! [`write_effects`] writes the same format (only the effects that are on), so a
//! diagnosis can hand its result to `simulate --effects`.

use std::fmt::{self, Write as _};
use std::path::Path;

use model_core::effects::{effect_ids, EffectKeyError, EFFECT_PARAMS};
use model_core::Effects;
use serde::de::{Deserialize, Deserializer, MapAccess, Visitor};
use toml::Spanned;

use crate::atomic::write_atomic;
use crate::error::FileError;
use crate::toml_util::{list, toml_error, toml_f32, Num};

/// One `[effect_id]` section, in file order.
struct Section(Vec<(Spanned<String>, Spanned<Num>)>);

impl<'de> Deserialize<'de> for Section {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Section;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("an effect section: `param = number` lines under an [effect_id] header")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<Section, A::Error> {
                let mut v = Vec::new();
                while let Some(kv) = m.next_entry()? {
                    v.push(kv);
                }
                Ok(Section(v))
            }
        }
        d.deserialize_map(V)
    }
}

/// The whole file, sections in file order (so the first error in the file is reported).
/// Only the keys carry spans: a dotted-key table (`id.param = 1`) has none of its own.
struct Sections(Vec<(Spanned<String>, Section)>);

impl<'de> Deserialize<'de> for Sections {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Sections;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("[effect_id] sections")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<Sections, A::Error> {
                let mut v = Vec::new();
                while let Some(kv) = m.next_entry()? {
                    v.push(kv);
                }
                Ok(Sections(v))
            }
        }
        d.deserialize_map(V)
    }
}

/// Read and parse an effect file.
pub fn load_effects(path: &Path) -> Result<Effects, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::io(path, &e))?;
    parse_effects(&text, path)
}

/// Parse effect-file text; `origin` names the file in errors.
pub fn parse_effects(text: &str, origin: impl AsRef<Path>) -> Result<Effects, FileError> {
    let origin = origin.as_ref();
    let at = |span: std::ops::Range<usize>, msg: String| FileError::at_span(origin, text, Some(span), msg);
    let Sections(sections) = toml::from_str(text).map_err(|e| toml_error(origin, text, &e))?;

    let mut fx = Effects::NONE;
    for (id, section) in &sections {
        let id_str = id.get_ref().as_str();
        for (param, value) in &section.0 {
            let v = value.get_ref().0 as f32;
            match fx.set(id_str, param.get_ref(), v) {
                Ok(()) => {}
                Err(EffectKeyError::UnknownEffect) => {
                    return Err(at(
                        id.span(),
                        format!(
                            "unknown effect `{id_str}`; known effects: {}",
                            list(&effect_ids().collect::<Vec<_>>())
                        ),
                    ))
                }
                Err(EffectKeyError::UnknownParameter(names)) => {
                    return Err(at(
                        param.span(),
                        format!(
                            "[{id_str}]: unknown parameter `{}`; accepted: {}",
                            param.get_ref(),
                            list(names)
                        ),
                    ))
                }
            }
        }
        if section.0.is_empty() && !effect_ids().any(|e| e == id_str) {
            return Err(at(
                id.span(),
                format!(
                    "unknown effect `{id_str}`; known effects: {}",
                    list(&effect_ids().collect::<Vec<_>>())
                ),
            ));
        }
    }

    if let Err(bad) = fx.validate() {
        // Point at the first parameter of the failing effect that is invalid on its own
        // (the model's checks are per parameter), else at the section header.
        let section = sections.iter().find(|(id, _)| id.get_ref() == bad);
        let culprit = section.and_then(|(_, s)| {
            s.0.iter().find(|(p, v)| {
                let mut one = Effects::NONE;
                one.set(bad, p.get_ref(), v.get_ref().0 as f32).is_ok() && one.validate().is_err()
            })
        });
        return Err(match (culprit, section) {
            (Some((p, v)), _) => at(
                v.span(),
                format!("[{bad}]: {} = {} is invalid: {}", p.get_ref(), v.get_ref().0, constraint(bad)),
            ),
            (None, Some((id, _))) => at(id.span(), format!("[{bad}]: {}", constraint(bad))),
            (None, None) => FileError::whole(origin, format!("[{bad}]: {}", constraint(bad))),
        });
    }
    Ok(fx)
}

/// What `Effects::validate` requires of each effect, for error messages.
pub fn constraint(id: &str) -> &'static str {
    match id {
        "differential_friction" => "coulomb_nm and viscous_nm_s_per_rad must be finite and >= 0",
        "axle_friction_scale" => "left and right must be finite and >= 0",
        "controller_delay" => "delay_s must be finite and >= 0",
        "inverter_rate_scale" => "every scale must be finite and > 0",
        "coupling_stiffness" => "stiffness_nm_per_rad must be finite and > 0",
        "coupling_damping" => "damping_nm_s_per_rad must be finite and >= 0",
        "inertia_scale" => "sut, load_l and load_r must be finite and > 0",
        "connector_resistance" => "resistance_ohm must be finite and >= 0",
        "supply_resistance" => "resistance_ohm must be in [0, 1) ohm",
        "regen_efficiency" => "extra_loss must be in [0, 1)",
        "torque_sensor_offset" => "left_nm and right_nm must be finite",
        "torque_sensor_gain" | "speed_sensor_gain" | "current_sensor_gain" => {
            "every gain must be finite and > 0"
        }
        "gear_backlash" => "backlash_deg must be in [0, 30] deg",
        "stribeck_friction" => "peak_nm must be finite and >= 0, and speed_rpm > 0 when peak_nm > 0",
        "connector_resistance_drift" => {
            "alpha_per_k must be finite, k_per_w finite and >= 0, and time_constant_s > 0 when k_per_w > 0"
        }
        _ => "the model refuses these values",
    }
}

/// The value of one effect parameter, in effect-file vocabulary: the read side of
/// `Effects::set`. `None` for an unknown name or an effect whose `Option` is unset.
pub fn get_param(fx: &Effects, effect: &str, param: &str) -> Option<f32> {
    fx.get(effect, param).ok().flatten()
}

/// Effect-file text for `fx`: one section per effect that differs from
/// `Effects::NONE`, with all of that effect's parameters (a section is the unit a
/// user switches on or off). Refuses effects the model would refuse.
pub fn format_effects(fx: &Effects) -> Result<String, String> {
    fx.validate().map_err(|bad| format!("effect `{bad}` is invalid: {}", constraint(bad)))?;
    let mut out = String::from(
        "# simrod effect file: the effects that differ from the thesis model.\n\
         # Units and meaning of every parameter: workbench/examples/effects.toml\n",
    );
    for (id, params) in EFFECT_PARAMS {
        let differs = params.iter().any(|p| get_param(fx, id, p) != get_param(&Effects::NONE, id, p));
        if !differs {
            continue;
        }
        // Writing to a String cannot fail.
        let _ = write!(out, "\n[{id}]\n");
        for p in *params {
            if let Some(v) = get_param(fx, id, p) {
                let _ = writeln!(out, "{p} = {}", toml_f32(v));
            }
        }
    }
    Ok(out)
}

/// One line naming the effects that differ from the thesis model, for tables and
/// history records: `differential_friction(coulomb_nm=4, viscous_nm_s_per_rad=0)`, or
/// `none`. Same selection as [`format_effects`] (a whole section per effect that is on).
pub fn summarize_effects(fx: &Effects) -> String {
    let mut parts = Vec::new();
    for (id, params) in EFFECT_PARAMS {
        if !params.iter().any(|p| get_param(fx, id, p) != get_param(&Effects::NONE, id, p)) {
            continue;
        }
        let values: Vec<String> =
            params.iter().filter_map(|p| get_param(fx, id, p).map(|v| format!("{p}={v}"))).collect();
        parts.push(format!("{id}({})", values.join(", ")));
    }
    if parts.is_empty() {
        "none".into()
    } else {
        parts.join(" + ")
    }
}

/// Write an effect file atomically (see [`format_effects`]); `load_effects` gives
/// back the same `Effects`.
pub fn write_effects(fx: &Effects, path: &Path) -> Result<(), FileError> {
    let text = format_effects(fx).map_err(|m| FileError::whole(path, m))?;
    write_atomic(path, |w| w.write_all(text.as_bytes()))
        .map_err(|e| FileError::whole(path, format!("cannot write: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Effects, String> {
        parse_effects(text, "fx.toml").map_err(|e| e.to_string())
    }

    #[test]
    fn parses_sections_and_parameters() {
        let fx = parse(
            "# comment\n[controller_delay]\ndelay_s = 0.012\n\n[differential_friction]\n\
             coulomb_nm = 1\nviscous_nm_s_per_rad = 0.01\n\n[coupling_stiffness]\n\
             stiffness_nm_per_rad = 10310\n",
        )
        .unwrap();
        let mut want = Effects::NONE;
        want.controller_delay_s = 0.012;
        want.differential_friction.coulomb_nm = 1.0;
        want.differential_friction.viscous_nm_s = 0.01;
        want.coupling_stiffness = Some(10310.0);
        assert_eq!(fx, want);
        assert_eq!(parse("").unwrap(), Effects::NONE);
        // Dotted keys are the same thing in TOML.
        assert_eq!(parse("controller_delay.delay_s = 0.012\n").unwrap().controller_delay_s, 0.012);
    }

    #[test]
    fn errors_name_place_and_vocabulary() {
        let e = parse("[controller_delay]\ndelay_s = 0.01\n\n[warp_drive]\nfactor = 9\n").unwrap_err();
        assert!(
            e.starts_with("fx.toml:4:2: unknown effect `warp_drive`; known effects: `differential_friction`"),
            "{e}"
        );
        assert!(e.contains("`current_sensor_gain`"), "{e}");
        let e = parse("[warp_drive]\n").unwrap_err();
        assert!(e.starts_with("fx.toml:1:2: unknown effect `warp_drive`"), "{e}");

        let e = parse("[controller_delay]\ndelay = 0.01\n").unwrap_err();
        assert_eq!(e, "fx.toml:2:1: [controller_delay]: unknown parameter `delay`; accepted: `delay_s`");

        let e = parse("[supply_resistance]\nresistance_ohm = 2\n").unwrap_err();
        assert_eq!(
            e,
            "fx.toml:2:18: [supply_resistance]: resistance_ohm = 2 is invalid: resistance_ohm must be in [0, 1) ohm"
        );
        let e = parse("[inertia_scale]\nsut = 1\nload_l = 1.1\nload_r = -1\n").unwrap_err();
        assert!(e.starts_with("fx.toml:4:10: [inertia_scale]: load_r = -1 is invalid"), "{e}");

        let e = parse("[controller_delay]\ndelay_s = \"long\"\n").unwrap_err();
        assert!(e.starts_with("fx.toml:2:11: ") && e.contains("expected a number"), "{e}");
        let e = parse("delay_s = 0.01\n").unwrap_err();
        assert!(e.starts_with("fx.toml:1:11: ") && e.contains("[effect_id]"), "{e}");
        let e = parse("[controller_delay]\ndelay_s = 0.01\n[controller_delay]\n").unwrap_err();
        assert!(e.starts_with("fx.toml:3:"), "{e}");
    }

    #[test]
    fn every_effect_has_a_constraint_text() {
        for id in effect_ids() {
            assert_ne!(constraint(id), constraint("no such effect"), "{id}");
        }
    }

    #[test]
    fn getter_mirrors_setter() {
        for (id, params) in EFFECT_PARAMS {
            for p in *params {
                let mut fx = Effects::NONE;
                fx.set(id, p, 0.625).unwrap();
                for (id2, params2) in EFFECT_PARAMS {
                    for p2 in *params2 {
                        let want = if (id, p) == (id2, p2) {
                            Some(0.625)
                        } else {
                            get_param(&Effects::NONE, id2, p2)
                        };
                        assert_eq!(get_param(&fx, id2, p2), want, "set {id}.{p}, read {id2}.{p2}");
                    }
                }
            }
        }
    }

    #[test]
    fn write_then_load_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fx.toml");
        // Each parameter on its own, then all together.
        let mut all = Effects::NONE;
        for (id, params) in EFFECT_PARAMS {
            for (k, p) in params.iter().enumerate() {
                let v = 0.1 + 0.137 * k as f32;
                let mut one = Effects::NONE;
                one.set(id, p, v).unwrap();
                all.set(id, p, v).unwrap();
                if one.validate().is_err() {
                    continue; // needs a companion parameter; covered by `all` below
                }
                write_effects(&one, &path).unwrap();
                assert_eq!(load_effects(&path).unwrap(), one, "{id}.{p}");
            }
        }
        all.validate().unwrap();
        write_effects(&all, &path).unwrap();
        assert_eq!(load_effects(&path).unwrap(), all);
        let text = std::fs::read_to_string(&path).unwrap();
        for id in effect_ids() {
            assert!(text.contains(&format!("[{id}]")), "{id} missing:\n{text}");
        }

        // Nothing on: no sections at all.
        write_effects(&Effects::NONE, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(!text.contains('['), "{text}");
        assert_eq!(load_effects(&path).unwrap(), Effects::NONE);

        // Only the effect that differs is written.
        let mut fx = Effects::NONE;
        fx.torque_sensor_offset = [-0.0, 1.5e-7];
        write_effects(&fx, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.matches('[').count(), 1, "{text}");
        let back = load_effects(&path).unwrap();
        assert_eq!(back.torque_sensor_offset[1].to_bits(), 1.5e-7f32.to_bits());
    }

    #[test]
    fn summary_names_only_effects_that_are_on() {
        assert_eq!(summarize_effects(&Effects::NONE), "none");
        let mut fx = Effects::NONE;
        fx.differential_friction.coulomb_nm = 4.0;
        fx.controller_delay_s = 0.012;
        assert_eq!(
            summarize_effects(&fx),
            "differential_friction(coulomb_nm=4, viscous_nm_s_per_rad=0) + controller_delay(delay_s=0.012)"
        );
    }

    #[test]
    fn invalid_effects_are_not_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fx.toml");
        let mut fx = Effects::NONE;
        fx.regen_loss = 2.0;
        let e = write_effects(&fx, &path).unwrap_err().to_string();
        assert!(e.contains("regen_efficiency"), "{e}");
        assert!(!path.exists());
    }

    /// The example file lists every effect and parameter, commented out; uncommented it
    /// must be a valid file that sets every parameter.
    #[test]
    fn example_file_lists_every_parameter() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/effects.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(parse_effects(&text, &path).unwrap(), Effects::NONE);
        // Commented-out TOML is written `#[id]` / `#param = value`; prose is `# ...`.
        let uncommented: String = text
            .lines()
            .map(|l| match l.strip_prefix('#') {
                Some(rest) if rest.starts_with(|c: char| c == '[' || c.is_ascii_lowercase()) => rest,
                _ => l,
            })
            .map(|l| format!("{l}\n"))
            .collect();
        let fx = parse_effects(&uncommented, "uncommented example").unwrap();
        for (id, params) in EFFECT_PARAMS {
            for p in *params {
                assert!(
                    uncommented.lines().any(|l| l.starts_with(&format!("{p} ="))),
                    "{id}.{p} missing from the example"
                );
                assert!(get_param(&fx, id, p).is_some(), "{id}.{p}");
            }
            assert!(uncommented.contains(&format!("[{id}]")), "{id} missing");
        }
    }
}
