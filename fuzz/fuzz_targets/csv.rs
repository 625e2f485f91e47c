//! The CSV measurement reader: `simrod_io::measure::parse_bytes` on `fuzz.csv`, the
//! whole pipeline `simrod compare`/`identify` run on a file (decoding, header and unit
//! row, separators, numbers, units, time checks, resampling).
#![no_main]

use libfuzzer_sys::fuzz_target;

mod common;

fuzz_target!(|data: &[u8]| {
    common::check_measurement("fuzz.csv", data);
});
