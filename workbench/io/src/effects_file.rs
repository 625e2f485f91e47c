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
//! Sections are effect ids, keys their parameters (the vocabulary, units and ranges are
//! declared once in `model_core::effects`; `workbench/examples/effects.toml` lists them).
//! Effects not named stay off, parameters not named keep their "off" value. Errors are
//! `file:line:col: message`, naming the unknown effect or parameter with the accepted
//! ones, or the parameter whose value the model refuses and the range it accepts.
//!
//! [`write_effects`] writes the same format (only the effects that are on), so a
//! diagnosis can hand its result to `simulate --effects`.

use std::fmt::Write as _;
use std::path::Path;

use model_core::effects::{self as fxdecl, Cause, EffectKeyError, ParamDecl, EFFECTS};
use model_core::Effects;
use model_data::effects::{parse_effect_file, Pos};

use crate::atomic::write_atomic;
use crate::error::FileError;
use crate::toml_util::toml_f32;

/// Read and parse an effect file.
pub fn load_effects(path: &Path) -> Result<Effects, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::io(path, &e))?;
    parse_effects(&text, path)
}

/// Parse effect-file text; `origin` names the file in errors. The syntax is model-data's
/// (the firmware's build script reads the same files with the same parser), the
/// vocabulary and ranges model-core's declarations.
pub fn parse_effects(text: &str, origin: impl AsRef<Path>) -> Result<Effects, FileError> {
    let origin = origin.as_ref();
    let at = |p: Option<Pos>, msg: String| match p {
        Some(p) => FileError::at(origin, p.line, p.col, msg),
        None => FileError::whole(origin, msg),
    };
    let file = parse_effect_file(text).map_err(|e| at(Some(e.at), e.msg))?;
    for s in &file.sections {
        if fxdecl::effect(&s.id).is_none() {
            return Err(at(Some(s.at), EffectKeyError::UnknownEffect.describe(&s.id, "").to_string()));
        }
    }
    let mut fx = Effects::NONE;
    for e in &file.entries {
        if let Err(k) = fx.set(&e.effect, &e.param, e.value as f32) {
            return Err(at(Some(e.param_at), k.describe(&e.effect, &e.param).to_string()));
        }
    }
    fx.check().map_err(|bad| at(file.locate(bad.effect.id, Some(bad.param.name)), bad.to_string()))?;
    Ok(fx)
}

/// What `Effects::validate` requires of each effect, for error messages (from the
/// declared ranges).
pub fn constraint(id: &str) -> String {
    match fxdecl::effect(id) {
        Some(e) => e.constraint().to_string(),
        None => "the model refuses these values".into(),
    }
}

/// The value of one effect parameter, in effect-file vocabulary: the read side of
/// `Effects::set`. `None` for an unknown name or an effect whose `Option` is unset.
pub fn get_param(fx: &Effects, effect: &str, param: &str) -> Option<f32> {
    fx.get(effect, param).ok().flatten()
}

/// Whether any parameter of effect `e` differs from the thesis model.
fn is_on(fx: &Effects, e: &fxdecl::EffectDecl) -> bool {
    e.params.iter().any(|p| get_param(fx, e.id, p.name) != get_param(&Effects::NONE, e.id, p.name))
}

/// Effect-file text for `fx`: one section per effect that differs from
/// `Effects::NONE`, with all of that effect's parameters (a section is the unit a
/// user switches on or off). Refuses effects the model would refuse.
pub fn format_effects(fx: &Effects) -> Result<String, String> {
    fx.check().map_err(|bad| format!("effect `{}` is invalid: {bad}", bad.effect.id))?;
    let mut out = String::from(
        "# simrod effect file: the effects that differ from the thesis model.\n\
         # Units and meaning of every parameter: workbench/examples/effects.toml\n",
    );
    for e in EFFECTS.iter().filter(|e| is_on(fx, e)) {
        // Writing to a String cannot fail.
        let _ = write!(out, "\n[{}]\n", e.id);
        for p in e.params {
            if let Some(v) = get_param(fx, e.id, p.name) {
                let _ = writeln!(out, "{} = {}", p.name, toml_f32(v));
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
    for e in EFFECTS.iter().filter(|e| is_on(fx, e)) {
        // A per-channel effect (the measurement chain) names only the channels it is on.
        let shown = |p: &&ParamDecl| {
            e.cause != Cause::PerParameter
                || get_param(fx, e.id, p.name) != get_param(&Effects::NONE, e.id, p.name)
        };
        let values: Vec<String> = e
            .params
            .iter()
            .filter(shown)
            .filter_map(|p| get_param(fx, e.id, p.name).map(|v| format!("{}={v}", p.name)))
            .collect();
        parts.push(format!("{}({})", e.id, values.join(", ")));
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
    use model_core::effects::{effect_ids, EFFECT_PARAMS};

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
        // Dotted keys and inline tables are the same thing in TOML.
        assert_eq!(parse("controller_delay.delay_s = 0.012\n").unwrap().controller_delay_s, 0.012);
        assert_eq!(
            parse(
                "controller_delay.delay_s = 0.012\ndifferential_friction = { coulomb_nm = 1, \
                 viscous_nm_s_per_rad = 0.01 }\ncoupling_stiffness.stiffness_nm_per_rad = 10_310\n"
            )
            .unwrap(),
            want
        );
    }

    #[test]
    fn errors_name_place_and_vocabulary() {
        let e = parse("[controller_delay]\ndelay_s = 0.01\n\n[warp_drive]\nfactor = 9\n").unwrap_err();
        assert!(
            e.starts_with("fx.toml:4:2: unknown effect `warp_drive`; known effects: `differential_friction`"),
            "{e}"
        );
        assert!(e.contains("`sensor_gain`"), "{e}");
        let e = parse("[warp_drive]\n").unwrap_err();
        assert!(e.starts_with("fx.toml:1:2: unknown effect `warp_drive`"), "{e}");

        let e = parse("[controller_delay]\ndelay = 0.01\n").unwrap_err();
        assert_eq!(e, "fx.toml:2:1: [controller_delay]: unknown parameter `delay`; accepted: `delay_s`");

        let e = parse("[supply_resistance]\nresistance_ohm = 2\n").unwrap_err();
        assert_eq!(
            e,
            "fx.toml:2:18: [supply_resistance]: resistance_ohm = 2 is invalid: resistance_ohm must be in [0, 1)"
        );
        let e = parse("[inertia_scale]\nsut = 1\nload_l = 1.1\nload_r = -1\n").unwrap_err();
        assert!(e.starts_with("fx.toml:4:10: [inertia_scale]: load_r = -1 is invalid"), "{e}");

        let e = parse("[controller_delay]\ndelay_s = \"long\"\n").unwrap_err();
        assert!(e.starts_with("fx.toml:2:11: ") && e.contains("expected a number"), "{e}");
        let e = parse("delay_s = 0.01\n").unwrap_err();
        assert!(e.starts_with("fx.toml:1:1: ") && e.contains("[effect_id]"), "{e}");
        // Bench-only physics is not the twin's: named with the twin's vocabulary.
        let e = parse("[stribeck_friction]\npeak_nm = 0.5\n").unwrap_err();
        assert!(e.starts_with("fx.toml:1:2: ") && e.contains("stribeck_friction"), "{e}");
        let e = parse("[controller_delay]\ndelay_s = 0.01\n[controller_delay]\n").unwrap_err();
        assert!(e.starts_with("fx.toml:3:"), "{e}");
    }

    /// The file the firmware's build compiles in reads the same here.
    #[test]
    fn firmware_example_file_parses() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../firmware/effects/example.toml");
        let fx = load_effects(&path).unwrap();
        assert_eq!(fx.controller_delay_s.to_bits(), 0.012f32.to_bits());
        assert_eq!(fx.coupling_stiffness, Some(7000.0));
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
                // A value inside the parameter's declared range, different per parameter.
                let r = fxdecl::effect(id).unwrap().params[k].range;
                let v = if r.min.is_finite() && r.max.is_finite() {
                    r.min + (0.3 + 0.05 * k as f32) * (r.max - r.min)
                } else {
                    0.1 + 0.137 * k as f32
                };
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
        (fx.sensor_offset[2], fx.sensor_offset[3]) = (-0.0, 1.5e-7);
        write_effects(&fx, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.matches('[').count(), 1, "{text}");
        let back = load_effects(&path).unwrap();
        assert_eq!(back.sensor_offset[3].to_bits(), 1.5e-7f32.to_bits());
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
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/effects.toml");
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
