//! # simrod-plant: the SimRod bench as continuous physics, independent of the twin
//!
//! `simrod bench --plant physics` runs this plant to make a "measurement": the bench's
//! physics in f64, integrated finely enough to converge, written from the physical
//! description (`docs/MODEL.md`, the thesis) and not from `model-core`'s code. It has
//! its own implementation of every effect of the twin's library (so an effect measured
//! here is found by a twin that implements it differently) and effects the twin lacks
//! ([`effects`]). The measurement chain (noise, encoders, the acquisition's effects) is
//! the virtual bench's (`simrod-vbench`), applied to this plant's output.
//!
//! [`reference`] is the same plant with no effects at the thesis values: the f64
//! reference `host-tests` measures the twin's discretization against.

pub mod effects;
mod electrics;
pub mod plant;
pub mod profile;
pub mod reference;
pub mod sampled;
mod tables;

pub use effects::{EffectDecl, ParamDecl, PlantEffects, PLANT_EFFECTS};
pub use plant::{step_for, Plant, Sample, Setup, SetupError, CHANNELS};
