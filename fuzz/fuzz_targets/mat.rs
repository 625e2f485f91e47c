//! The MAT (Level 5) measurement reader: `simrod_io::measure::parse_bytes` on
//! `fuzz.mat` (the `matfile` crate, the unit-variable walk with its inflater, then the
//! same pipeline as CSV).
#![no_main]

use libfuzzer_sys::fuzz_target;

mod common;

fuzz_target!(|data: &[u8]| {
    common::check_measurement("fuzz.mat", data);
});
