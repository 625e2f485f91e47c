//! # simrod-xdt: the vehicle-and-road twin that closes the XiL loop
//!
//! In XiL mode the SimRod bench is driven by an executable digital twin (xDT) of the
//! vehicle and its road instead of a test profile (thesis 2.2): the xDT reads the bench's
//! measured axle speeds and torques and writes the set points, the throttle from a driver
//! following a drive cycle and the load motors' torques from the road load. This crate is
//! that xDT for the Kyburz DXP and the closed loop with the bench twin (`model-core`),
//! under the same rules: `no_std`, no allocation, no unsafe code, f32 with basic
//! operations only in the step (same bits on host and Cortex-M4F), no panic path.
//!
//! - [`vehicle`]: the DXP's longitudinal dynamics (`data/vehicle.toml`).
//! - [`cycle`]: drive cycles and grade profiles (`data/cycles/`, `data/grades/`).
//! - [`driver`]: PI with feed-forward through the inverse throttle chain.
//! - [`loadmap`]: road-load torque -> load set point, the load map inverted.
//! - [`xdt`]: one sample of the xDT.
//! - [`xil`]: the closed loop (twin + xDT + the RT platform's delay and sample time).
//! - [`checks`]: top speed and gradeability from the force balance.
//! - [`margin`]: the loop's delay margin.
//!
//! ```
//! use model_core::Config;
//! use simrod_xdt::{Cycle, Timing, XilLoop};
//! let timing = Timing::new(1, 2).unwrap();
//! let run = XilLoop::builtin(&Config::default(), Cycle::Ece15, timing, 24.0).unwrap();
//! let peak = run.map(|o| o.xdt.v_mps * 3.6).fold(0.0f32, f32::max);
//! assert!(peak > 14.0 && peak < 18.0); // ECE-15 capped at the bench's reach
//! ```

#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]

pub mod checks;
pub mod cycle;
pub mod data;
pub mod driver;
pub mod loadmap;
pub mod margin;
mod num;
pub mod vehicle;
pub mod xdt;
pub mod xil;

pub use cycle::{Cycle, Route, Slope};
pub use vehicle::Vehicle;
pub use xdt::{XdtConfig, XdtError, XdtSignals, XdtState, XdtTuning};
pub use xil::{LoopParams, Timing, XilError, XilLoop, XilOutputs, DELAY_CAPACITY, SIGNALS};
