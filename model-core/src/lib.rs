//! # model-core: the SimRod e-powertrain twin
//!
//! A `no_std`, allocation-free, fixed-step model of the SimRod E-powertrain test bench
//! (Kyburz DXP drive: Curtis AC controller in speed mode, gearbox, open differential,
//! torque flanges, flexible couplings, two current-controlled load motors, 24 V supply),
//! after D'Eredità's thesis (chapters 3, 5, appendix A). The same code runs on the host
//! and on a Cortex-M4F and produces the same bits on both: f32 throughout, no FMA, no
//! transcendental functions in the step, f64 only at construction with basic operations.
//!
//! The physics is written once, generic over the scalar [`Real`]: the f32 twin above,
//! and with feature `fixed` a fixed-point twin ([`Fx`], 32-bit `I17F15` signals with
//! 64-bit `I32F32` where a signal needs it, [`FxWide`]) for
//! cores without an FPU (the Cortex-M3 firmware), from the same source
//! ([`Model::new_fx`], [`Simulation::new_fx`]).
//!
//! Structure, one module a block:
//! - [`profile`]: test-profile engine (sets, hold/interpolate, scaling and signs).
//! - [`throttle`]: set point -> voltage -> mapped throttle -> target speed.
//! - [`curtis`]: the Curtis rate logic.
//! - [`controller`]: PID speed controller with torque/power limits.
//! - [`delay`]: the controller-delay line.
//! - [`drivetrain`]: mechanics, discretized exactly (see there for the 2 kHz flange mode).
//! - [`electrics`]: supply, connector, power maps, rate limiters.
//! - [`effects`]: physical effects beyond the thesis, off by default, each declared once.
//! - [`chain`]: each measured channel's sensor, amplifier and acquisition (gain, offset,
//!   lag, delay).
//! - [`outputs`]: the bench's channels.
//! - [`data`]: the maps and parameters, compiled into flash from `data/` by `build.rs`.
//!
//! ```
//! use model_core::{Builtin, Config, Profile, Simulation, Channel};
//! let profile = Profile::builtin(Builtin::TP12, 1.0, 0.0).unwrap();
//! let mut sim = Simulation::new(&Config::default(), profile, 24.0).unwrap();
//! let peak = sim.by_ref().map(|o| o.get(Channel::SuTMotorEnc)).fold(0.0f32, f32::max);
//! assert!(peak > 2000.0);
//! ```

#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]

pub mod backlash;
pub mod chain;
pub mod controller;
pub mod curtis;
pub mod data;
pub mod delay;
pub mod drivetrain;
pub mod effects;
pub mod electrics;
mod expm;
pub mod model;
pub mod num;
pub mod outputs;
pub mod params;
#[cfg(feature = "profile-hooks")]
pub mod probe;
pub mod profile;
pub mod sim;
pub mod table;
pub mod throttle;

pub use data::Maps;
pub use effects::Effects;
pub use model::{Config, ConfigError, Inputs, Model, Snapshot};
pub use num::Real;
#[cfg(feature = "fixed")]
pub use num::{saturations, Fx, FxWide};
pub use outputs::{Channel, Outputs, MEASURED, N_CHANNELS};
pub use params::{CouplingStiffness, Params, RateSet, SpeedTarget};
pub use profile::{Builtin, Profile, ProfileError, ProfileSet, SetMode, SetPoints};
pub use sim::Simulation;
