//! The text-file parsers. The first byte picks the parser (its value modulo
//! [`PARSERS`]), the rest is the file's text (inputs that are not UTF-8 are skipped:
//! every caller reads these files with `read_to_string`).
//!
//! Besides "no panic", an `Ok` must keep the parser's documented promises, and the
//! writers must read back: `format_effects`/`format_bench_effects` ("what
//! parse_*effects reads back"; bench-only effects that are off are not written) and
//! `write_map1`/`write_map2` (the data directory's writer; `fmt_f32` is the shortest
//! decimal that reads back to the same f32).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use model_core::profile::MAX_SETS;
use simrod_io::datadir::ParamLine;
use simrod_io::error::FileError;
use simrod_io::{datadir, effects_file, measure::Mapping, profile_file};
use simrod_vbench::{bench_effects, noise::NoiseModel};

/// Selector values (first byte modulo the count), in this order.
pub const PARSERS: [&str; 9] = [
    "profile_file", // 0: simrod_io::profile_file::parse_profile (--profile-file)
    "effects",      // 1: simrod_io::effects_file::parse_effects (--effects)
    "mapping",      // 2: simrod_io::measure::Mapping::parse (--mapping)
    "params",       // 3: simrod_io::datadir::parse_params (parameters.toml)
    "map1",         // 4: simrod_io::datadir::parse_map1 (1-D map CSV)
    "map2",         // 5: simrod_io::datadir::parse_map2 (2-D map CSV)
    "dd_profile",   // 6: simrod_io::datadir::parse_profile (profiles/*.csv)
    "noise",        // 7: simrod_vbench::noise::NoiseModel::parse (--noise)
    "bench_fx",     // 8: simrod_vbench::bench_effects::parse_bench_effects
];

fn err(e: FileError) {
    // Errors carry line/column computed from spans: formatting must not panic.
    let _ = e.to_string();
}

fn increasing(v: &[f32]) -> bool {
    v.iter().all(|x| x.is_finite()) && v.windows(2).all(|w| w[0] < w[1])
}

fuzz_target!(|data: &[u8]| {
    let Some((&sel, rest)) = data.split_first() else { return };
    let Ok(text) = std::str::from_utf8(rest) else { return };
    let toml = Path::new("fuzz.toml");
    let csv = Path::new("fuzz.csv");
    match usize::from(sel) % PARSERS.len() {
        0 => match profile_file::parse_profile(text, toml) {
            Err(e) => err(e),
            // "The sets, 1 to MAX_SETS, each already within the model's limits."
            Ok(p) => {
                if let Err(e) = p.profile(None, None) {
                    panic!("profile file accepted but the model refuses it: {e:?}; {p:?}");
                }
            }
        },
        1 => match effects_file::parse_effects(text, toml) {
            Err(e) => err(e),
            Ok(fx) => {
                let out = effects_file::format_effects(&fx)
                    .unwrap_or_else(|m| panic!("parsed effects do not format: {m}; {fx:?}"));
                let back = effects_file::parse_effects(&out, toml)
                    .unwrap_or_else(|e| panic!("formatted effects do not parse: {e}\n{out}"));
                assert_eq!(back, fx, "effects change in a format/parse round trip:\n{out}");
            }
        },
        2 => match Mapping::parse(toml, text) {
            Err(e) => err(e),
            Ok(m) => assert!(m.scale.values().all(|f| f.is_finite() && *f != 0.0), "{m:?}"),
        },
        3 => match datadir::parse_params(toml, text) {
            Err(e) => err(e),
            Ok(lines) => {
                for l in &lines {
                    if let ParamLine::Entry { value, .. } = l {
                        assert!(value.is_finite(), "{l:?}");
                    }
                }
            }
        },
        4 => match datadir::parse_map1(csv, text) {
            Err(e) => err(e),
            Ok(m) => {
                assert!(m.x.len() >= 2 && m.x.len() == m.y.len(), "{m:?}");
                assert!(increasing(&m.x) && m.y.iter().all(|v| v.is_finite()), "{m:?}");
                let mut out = Vec::new();
                datadir::write_map1(&mut out, &m).expect("write to a Vec");
                let out = String::from_utf8(out).expect("written map is UTF-8");
                let back = datadir::parse_map1(csv, &out)
                    .unwrap_or_else(|e| panic!("written 1-D map does not parse: {e}\n{out}"));
                assert_eq!(back, m, "1-D map changes in a write/parse round trip:\n{out}");
            }
        },
        5 => match datadir::parse_map2(csv, text) {
            Err(e) => err(e),
            Ok(m) => {
                assert!(increasing(&m.x) && increasing(&m.y), "{m:?}");
                assert!(m.x.len() >= 2 && m.y.len() >= 2, "{m:?}");
                assert_eq!(m.z.len(), m.x.len() * m.y.len(), "{m:?}");
                assert!(m.z.iter().all(|v| v.is_finite()), "{m:?}");
                let mut out = Vec::new();
                datadir::write_map2(&mut out, &m).expect("write to a Vec");
                let out = String::from_utf8(out).expect("written map is UTF-8");
                let back = datadir::parse_map2(csv, &out)
                    .unwrap_or_else(|e| panic!("written 2-D map does not parse: {e}\n{out}"));
                assert_eq!(back, m, "2-D map changes in a write/parse round trip:\n{out}");
            }
        },
        6 => match datadir::parse_profile(csv, "FUZZ", text) {
            Err(e) => err(e),
            Ok(p) => {
                assert!((1..=MAX_SETS).contains(&p.sets.len()), "{p:?}");
                for s in &p.sets {
                    assert!(s.duration_s.is_finite() && s.duration_s > 0.0, "{s:?}");
                    for v in [s.throttle_pct, s.load_l_pct, s.load_r_pct] {
                        assert!(v.is_finite() && (-100.0..=100.0).contains(&v), "{s:?}");
                    }
                }
            }
        },
        7 => match NoiseModel::parse(toml, text) {
            Err(e) => err(e),
            Ok(m) => {
                if let Err(msg) = m.validate() {
                    panic!("noise model accepted but invalid: {msg}");
                }
            }
        },
        _ => match bench_effects::parse_bench_effects(text, toml) {
            Err(e) => err(e),
            Ok(fx) => {
                let out = bench_effects::format_bench_effects(&fx)
                    .unwrap_or_else(|m| panic!("parsed bench effects do not format: {m}; {fx:?}"));
                let back = bench_effects::parse_bench_effects(&out, toml)
                    .unwrap_or_else(|e| panic!("formatted bench effects do not parse: {e}\n{out}"));
                // The writer leaves out bench-only effects that are off (first parameter
                // 0, "an effect is on while its first parameter is non-zero"), so those
                // come back at their defaults; everything else comes back exactly.
                assert_eq!(back.library, fx.library, "twin effects change in a round trip:\n{out}");
                assert_eq!(back.daq, fx.daq, "acquisition effects change in a round trip:\n{out}");
                assert_eq!(
                    back.plant.entries(),
                    fx.plant.entries(),
                    "bench-only effects that are on change in a round trip:\n{out}"
                );
            }
        },
    }
});
