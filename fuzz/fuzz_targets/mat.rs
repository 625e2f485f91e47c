//! The MAT (Level 5) measurement reader: `simrod_io::measure::parse_bytes` on
//! `fuzz.mat` (our element walk over the file, with libflate for compressed elements,
//! then the same pipeline as CSV).
#![no_main]

use libfuzzer_sys::fuzz_target;

mod common;

fuzz_target!(|data: &[u8]| {
    common::check_measurement("fuzz.mat", data);
});
