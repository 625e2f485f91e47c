//! The virtual bench's effect files (`simrod bench --effects FILE.toml`): the twin's
//! library effects (`model_core::effects`), the plant's bench-only effects
//! (`simrod_plant::effects`) and the acquisition's effects ([`crate::daq`]), in one
//! file of the one effect-file syntax (`model_data::effects`). Each id belongs to
//! exactly one vocabulary; errors name the file, line and column and list all three.

use std::fmt::Write as _;
use std::path::Path;

use model_core::effects::{self as fxdecl, EffectKeyError};
use model_core::Effects;
use model_data::effects::{parse_effect_file, Pos};
use simrod_io::effects_file::format_effects;
use simrod_io::error::FileError;
use simrod_plant::{PlantEffects, PLANT_EFFECTS};

use crate::daq::{channel_key, DaqEffects, DAQ_EFFECTS};

/// Everything a virtual bench run can have switched on.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BenchEffects {
    /// Effects the twin's library has (the plant simulates them with its own code).
    pub library: Effects,
    /// Physics the twin does not have (the physics plant only).
    pub plant: PlantEffects,
    /// The acquisition's effects (either plant).
    pub daq: DaqEffects,
}

impl BenchEffects {
    /// Nothing switched on.
    pub fn none() -> Self {
        Self { library: Effects::NONE, plant: PlantEffects::default(), daq: DaqEffects::none() }
    }

    /// True when nothing is switched on.
    pub fn is_none(&self) -> bool {
        self.library.is_none() && self.plant.is_none() && self.daq.is_none()
    }
}

/// The three vocabularies, for messages.
fn vocabulary() -> String {
    let lib: Vec<&str> = fxdecl::EFFECTS.iter().map(|e| e.id).collect();
    let plant: Vec<&str> = PLANT_EFFECTS.iter().map(|e| e.id).collect();
    let daq: Vec<&str> = DAQ_EFFECTS.iter().map(|e| e.id).collect();
    format!(
        "twin effects: {}; bench-only physics: {}; acquisition: {}",
        lib.join(", "),
        plant.join(", "),
        daq.join(", ")
    )
}

/// Read and parse a bench effect file.
pub fn load_bench_effects(path: &Path) -> Result<BenchEffects, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::io(path, &e))?;
    parse_bench_effects(&text, path)
}

/// Parse bench effect-file text; `origin` names the file in errors.
pub fn parse_bench_effects(text: &str, origin: impl AsRef<Path>) -> Result<BenchEffects, FileError> {
    let origin = origin.as_ref();
    let at = |p: Option<Pos>, msg: String| match p {
        Some(p) => FileError::at(origin, p.line, p.col, msg),
        None => FileError::whole(origin, msg),
    };
    let file = parse_effect_file(text).map_err(|e| at(Some(e.at), e.msg))?;
    let known = |id: &str| {
        fxdecl::effect(id).is_some() || PlantEffects::is_plant_effect(id) || DaqEffects::is_daq_effect(id)
    };
    if let Some(s) = file.sections.iter().find(|s| !known(&s.id)) {
        return Err(at(Some(s.at), format!("unknown effect `{}`; {}", s.id, vocabulary())));
    }
    let mut fx = BenchEffects::none();
    for e in &file.entries {
        let here = Some(e.param_at);
        if PlantEffects::is_plant_effect(&e.effect) {
            fx.plant.set(&e.effect, &e.param, e.value).map_err(|k| at(here, k.to_string()))?;
        } else if DaqEffects::is_daq_effect(&e.effect) {
            fx.daq.set(&e.effect, &e.param, e.value).map_err(|k| at(here, k.to_string()))?;
        } else if let Err(k) = fx.library.set(&e.effect, &e.param, e.value as f32) {
            let k: EffectKeyError = k;
            return Err(at(here, k.describe(&e.effect, &e.param).to_string()));
        }
    }
    fx.library
        .check()
        .map_err(|bad| at(file.locate(bad.effect.id, Some(bad.param.name)), bad.to_string()))?;
    fx.plant.check().map_err(|bad| {
        let place = match &bad {
            simrod_plant::effects::KeyError::OutOfRange { effect, param, .. } => {
                file.locate(effect, Some(param))
            }
            _ => None,
        };
        at(place, bad.to_string())
    })?;
    Ok(fx)
}

/// Effect-file text for `fx` (what [`parse_bench_effects`] reads back): the twin's
/// effects that are on, then the bench-only ones, then the acquisition's.
pub fn format_bench_effects(fx: &BenchEffects) -> Result<String, String> {
    let mut out = format_effects(&fx.library)?;
    // Entries come grouped by effect, in declaration order: a header where the id changes.
    let plant = fx.plant.entries().into_iter().map(|(id, p, v)| (id, p.to_owned(), v));
    let daq = fx.daq.entries().into_iter().map(|(id, c, v)| (id, channel_key(c), v));
    let mut last = "";
    for (id, param, v) in plant.chain(daq) {
        if id != last {
            let _ = write!(out, "\n[{id}]\n");
            last = id;
        }
        let _ = writeln!(out, "{param} = {v:?}");
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn routes_each_id_to_its_vocabulary_and_round_trips() {
        let text = "[controller_delay]\ndelay_s = 0.05\n\n[gear_mesh_ripple]\namplitude_nm = 0.8\n\
                    relative = 0.02\nperiods_per_rev = 17\n\n[amplifier_lag]\nc_kistler_l = 0.04\n";
        let fx = parse_bench_effects(text, "fx.toml").unwrap();
        assert_eq!(fx.library.controller_delay_s, 0.05);
        assert_eq!(fx.plant.gear_mesh_ripple.periods_per_rev, 17.0);
        assert_eq!(fx.daq.get("amplifier_lag", "c_kistler_l"), Some(0.04));
        let back = parse_bench_effects(&format_bench_effects(&fx).unwrap(), "back.toml").unwrap();
        assert_eq!(back, fx);
    }

    #[test]
    fn errors_name_the_place_and_the_vocabularies() {
        let e = parse_bench_effects("\n[nonsense]\nx = 1\n", "fx.toml").unwrap_err().to_string();
        assert!(
            e.starts_with("fx.toml:2:2: unknown effect `nonsense`; twin effects: differential_friction"),
            "{e}"
        );
        assert!(
            e.contains("bench-only physics: stribeck_friction") && e.contains("acquisition: amplifier_lag"),
            "{e}"
        );
        let e = parse_bench_effects("[stribeck_friction]\npeak_nm = 5\n", "fx.toml").unwrap_err().to_string();
        assert!(e.starts_with("fx.toml:1:2: [stribeck_friction]: speed_rpm = 0 is invalid"), "{e}");
        let e =
            parse_bench_effects("[amplifier_lag]\nsut_motor_enc = 0.1\n", "fx.toml").unwrap_err().to_string();
        assert!(e.starts_with("fx.toml:2:1:"), "{e}");
    }
}

#[cfg(test)]
mod example_file {
    use super::*;

    /// `workbench/examples/bench_effects.toml` lists every bench-only and acquisition
    /// effect and its parameters, and, uncommented, is a valid file.
    #[test]
    fn the_example_lists_every_effect_and_parses() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/bench_effects.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        for e in PLANT_EFFECTS {
            assert!(text.contains(&format!("#[{}]\n", e.id)), "{} missing", e.id);
            for p in e.params {
                assert!(text.contains(&format!("\n#{} = ", p.name)), "{}.{} missing", e.id, p.name);
            }
        }
        for d in DAQ_EFFECTS {
            assert!(text.contains(&format!("#[{}]\n", d.id)), "{} missing", d.id);
        }
        let live: String = text
            .lines()
            .filter(|l| l.starts_with("#[") || (l.starts_with('#') && l.contains(" = ")))
            .map(|l| format!("{}\n", &l[1..]))
            .collect();
        let fx = parse_bench_effects(&live, &path).unwrap();
        assert!(!fx.plant.is_none() && !fx.daq.is_none());
        for e in PLANT_EFFECTS {
            assert!(fx.plant.is_on(e.id), "{} is on in the example", e.id);
        }
    }
}
