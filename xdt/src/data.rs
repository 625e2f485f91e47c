//! The xDT's data compiled into flash by `build.rs`: the vehicle and loop parameters, the
//! drive cycles (speeds in m/s) and the grade profiles (percent, sine, cosine).

#![allow(missing_docs)]

mod generated {
    include!(concat!(env!("OUT_DIR"), "/data.rs"));
}
pub use generated::*;

/// A flat road: grade 0 everywhere (for the cycles without a grade profile).
pub static FLAT_X: [f32; 2] = [0.0, 1.0];
/// Grade [%] of [`FLAT_X`].
pub static FLAT_ZERO: [f32; 2] = [0.0, 0.0];
/// Cosine of [`FLAT_X`]'s slope.
pub static FLAT_ONE: [f32; 2] = [1.0, 1.0];
