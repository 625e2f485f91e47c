//! The effect library's vocabulary: every parameter can be set, read back, and validated.

use model_core::effects::*;
use model_core::Effects;

#[test]
fn every_listed_parameter_can_be_set_and_changes_something() {
    for (id, params) in EFFECT_PARAMS {
        for p in *params {
            let mut fx = Effects::NONE;
            fx.set(id, p, 0.5).unwrap_or_else(|e| panic!("{id}.{p}: {e:?}"));
            assert_ne!(fx, Effects::NONE, "{id}.{p} changed nothing");
        }
    }
    assert!(LIBRARY.iter().all(|id| effect_ids().any(|e| e == *id)), "a library effect without parameters");
}

#[test]
fn get_reads_what_set_wrote() {
    for (id, params) in EFFECT_PARAMS {
        for p in *params {
            let mut fx = Effects::NONE;
            fx.set(id, p, 0.25).unwrap();
            assert_eq!(fx.get(id, p), Ok(Some(0.25)), "{id}.{p}");
        }
    }
    assert_eq!(Effects::NONE.get("coupling_stiffness", "stiffness_nm_per_rad"), Ok(None));
    assert_eq!(Effects::NONE.get("inertia_scale", "sut"), Ok(Some(1.0)));
}

#[test]
fn unknown_names_are_refused() {
    let mut fx = Effects::NONE;
    assert_eq!(fx.set("warp_drive", "x", 1.0), Err(EffectKeyError::UnknownEffect));
    assert!(matches!(
        fx.set("controller_delay", "delay", 1.0),
        Err(EffectKeyError::UnknownParameter(["delay_s"]))
    ));
}

#[test]
fn validate_names_the_bad_effect() {
    let mut fx = Effects::NONE;
    fx.set("regen_efficiency", "extra_loss", 1.5).unwrap();
    assert_eq!(fx.validate(), Err("regen_efficiency"));
}

/// Every declared effect has a row in docs/MODEL.md's effect table naming its
/// parameters and saying whether diagnose may propose it.
#[test]
fn effects_are_documented() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/MODEL.md");
    let doc = std::fs::read_to_string(path).unwrap();
    for e in EFFECTS {
        let row = doc
            .lines()
            .find(|l| l.starts_with(&format!("| `{}` |", e.id)))
            .unwrap_or_else(|| panic!("{} has no row in the effect table of {path}", e.id));
        for p in e.params {
            assert!(
                row.contains(&format!("`{}`", p.name)),
                "{}.{} missing from its row: {row}",
                e.id,
                p.name
            );
        }
        let in_lib = row.trim_end().trim_end_matches('|').trim_end().ends_with("| yes");
        assert_eq!(in_lib, e.in_library(), "{}: the table's diagnose-library column is wrong", e.id);
    }
}

/// The declarations are consistent: the library is exactly the effects with a proof
/// case; a proof hides a declared parameter inside its range; fit bounds hold the
/// neutral value and lie within what the model accepts.
#[test]
fn declarations_are_consistent() {
    let p = model_core::Params::default();
    assert_eq!(LIBRARY.len(), EFFECTS.iter().filter(|e| e.proof.is_some()).count());
    for e in EFFECTS {
        assert_eq!(e.in_library(), e.proof.is_some(), "{}: a proof case exactly for library effects", e.id);
        assert!(
            e.params.iter().all(|d| d.fit.is_some()) || e.params.iter().all(|d| d.fit.is_none()),
            "{}",
            e.id
        );
        if let Some(pr) = e.proof {
            let d = e.param(pr.param).unwrap_or_else(|| panic!("{}: proof hides unknown {}", e.id, pr.param));
            assert!(pr.lo < pr.hi && d.range.contains(pr.lo) && d.range.contains(pr.hi), "{}", e.id);
        }
        for d in e.params {
            let neutral = d.neutral(e.id, &p);
            assert!(d.range.contains(neutral), "{}.{}: neutral {neutral} refused", e.id, d.name);
            assert_eq!(d.model.is_some(), Effects::NONE.get(e.id, d.name) == Ok(None), "{}.{}", e.id, d.name);
            if let Some(f) = d.fit {
                let (lo, hi) = (f.lower as f32, f.upper as f32);
                assert!(
                    f.lower <= f64::from(neutral) && f64::from(neutral) <= f.upper,
                    "{}.{}",
                    e.id,
                    d.name
                );
                assert!(
                    d.range.contains(lo) && d.range.contains(hi),
                    "{}.{}: fit bounds outside range",
                    e.id,
                    d.name
                );
                assert!(f.delta(f64::from(neutral)) > 0.0, "{}.{}", e.id, d.name);
            }
        }
    }
}

#[test]
fn check_names_the_parameter_and_its_range() {
    let mut fx = Effects::NONE;
    fx.set("supply_resistance", "resistance_ohm", 2.0).unwrap();
    let bad = fx.check().unwrap_err();
    assert_eq!(
        bad.to_string(),
        "[supply_resistance]: resistance_ohm = 2 is invalid: resistance_ohm must be in [0, 1)"
    );
    assert_eq!(effect("gear_backlash").unwrap().constraint().to_string(), "backlash_deg must be in [0, 30]");
    assert_eq!(
        EffectKeyError::UnknownParameter(&["delay_s"]).describe("controller_delay", "delay").to_string(),
        "[controller_delay]: unknown parameter `delay`; accepted: `delay_s`"
    );
    assert!(EffectKeyError::UnknownEffect
        .describe("warp", "")
        .to_string()
        .starts_with("unknown effect `warp`; known effects: `differential_friction`, `axle_friction_scale`"));
}
