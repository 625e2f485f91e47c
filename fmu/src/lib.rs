//! # simrod-fmu: the SimRod twin as an FMI 3.0 Co-Simulation FMU
//!
//! The twin (`model-core`) behind the FMI 3.0 C API, for importers such as Simcenter
//! Amesim, Testlab RT, Simulink or FMPy. `cargo xtask fmu --out simrod.fmu` packages
//! it (see [`package`]).
//!
//! - [`vars`]: the variables, derived from the channel and effect declarations;
//! - [`units`]: their units in SI;
//! - [`spec`]: what an FMU runs, as its resources hold it;
//! - [`description`]: `modelDescription.xml` and the instantiation token;
//! - [`instance`]: one instance's state machine, values and stepping (safe Rust);
//! - [`twin`]: the model with the data it borrows;
//! - `ffi`: the C functions, the only `unsafe` code;
//! - [`package`]: building the binary and zipping the FMU.
//!
//! The twin runs at its fixed step; `fmi3DoStep` takes any communication step that is
//! a whole multiple of it and holds the inputs over it, as `simrod simulate` holds a
//! profile's set points over a step (their value at the step's start).

#![deny(unsafe_code)]

pub mod description;
mod ffi;
pub mod instance;
pub mod package;
pub mod spec;
pub mod twin;
pub mod units;
pub mod vars;
