//! The code that runs inside every step's time budget, under fixed symbol names.
//!
//! `#[no_mangle]` + `#[inline(never)]` keep each one a separate function in the ELF,
//! so `host-tests/tests/firmware_elf.rs` can find it and walk its call graph: nothing
//! reachable from these may be a panic path (an `unwrap`, an unchecked index, a
//! `clamp` with unproven bounds...). A panic in the loop would stop the bench.

use model_core::{Inputs, Model, Outputs, Profile, SetPoints};

use crate::Scalar;

/// One model step: inputs in, outputs of the step's end out.
#[inline(never)]
#[no_mangle]
pub fn simrod_step(model: &mut Model<'static, Scalar>, inputs: &Inputs, out: &mut Outputs<Scalar>) {
    *out = model.step(inputs);
}

/// The built-in profile's set points at `t_us`.
#[inline(never)]
#[no_mangle]
pub fn simrod_profile_at(profile: &Profile, t_us: u64) -> SetPoints {
    profile.at(t_us)
}
