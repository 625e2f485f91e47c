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
