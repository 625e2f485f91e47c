//! Compiles the data files in `data/` into `static` arrays (flash on the target).
//!
//! Why a build script: the maps must live as plain, replaceable data files, yet the
//! target has no file system and no allocator. Every file is validated here (strictly
//! increasing grids, finite values, rectangular 2-D tables, profile limits) so a bad
//! file is a build error naming file and line, never a run-time surprise.
//! The parsing is `model-data`'s, shared with the workbench's run-time data directories,
//! so both accept the same files with the same messages.

use std::env;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

const MAPS_1D: &[(&str, &str)] = &[
    ("THROTTLE_INPUT", "throttle_input_map.csv"),
    ("SPEED_FWD", "speed_map_fwd.csv"),
    ("SPEED_REV", "speed_map_rev.csv"),
    ("FRICTION_L", "axle_friction_L.csv"),
    ("FRICTION_R", "axle_friction_R.csv"),
];
const MAPS_2D: &[(&str, &str)] = &[
    ("LOAD_TORQUE_L", "load_torque_L.csv"),
    ("LOAD_TORQUE_R", "load_torque_R.csv"),
    ("LOAD_CURRENT_L", "load_current_L.csv"),
    ("LOAD_CURRENT_R", "load_current_R.csv"),
    ("LOAD_POWER_L", "load_power_L.csv"),
    ("LOAD_POWER_R", "load_power_R.csv"),
    ("SUT_POWER", "sut_inverter_power.csv"),
];
const PROFILES: &[&str] = &["TP07", "TP11", "TP12", "TP13", "TP14"];

fn fail(file: &Path, e: &model_data::Error) -> ! {
    panic!("{}:{}: {}", file.display(), e.line, e.msg)
}

fn read(path: &Path) -> String {
    fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: cannot read: {e}", path.display()))
}

fn lit(v: f32) -> String {
    format!("{v:?}")
}

fn array(name: &str, vals: &[f32]) -> String {
    let body: Vec<String> = vals.iter().map(|v| lit(*v)).collect();
    format!("pub static {name}: [f32; {}] = [{}];\n", vals.len(), body.join(", "))
}

/// The bits of `v` in the fixed-point signal format `Fx` (I17F15: the value times 2^15),
/// rounded to the nearest, ties to even, as `Fx::lit` rounds (exact in f64: an f32 times
/// 2^15 is an f64). A value beyond the format's range (±2^16) fails the build.
fn fx_bits(v: f32) -> i32 {
    let y = f64::from(v) * 32_768.0;
    let r = y.round();
    let r = if (r - y).abs() == 0.5 && r % 2.0 != 0.0 { r - y.signum() } else { r };
    assert!(
        r >= f64::from(i32::MIN) && r <= f64::from(i32::MAX),
        "{v} is beyond the fixed-point range (±2^16)"
    );
    r as i32
}

fn array_fx(name: &str, vals: &[f32]) -> String {
    let body: Vec<String> = vals.iter().map(|v| format!("Fx::from_bits({})", fx_bits(*v))).collect();
    format!("pub static {name}: [Fx; {}] = [{}];\n", vals.len(), body.join(", "))
}

/// Both formats of one table: f32 into `out`, fixed-point into `fx`.
fn arrays(out: &mut String, fx: &mut String, name: &str, vals: &[f32]) {
    out.push_str(&array(name, vals));
    fx.push_str(&array_fx(name, vals));
}

fn table_1d(out: &mut String, fx: &mut String, name: &str, path: &Path) {
    let m = model_data::parse_map1(&read(path)).unwrap_or_else(|e| fail(path, &e));
    arrays(out, fx, &format!("{name}_X"), &m.x);
    arrays(out, fx, &format!("{name}_Y"), &m.y);
}

fn table_2d(out: &mut String, fx: &mut String, name: &str, path: &Path) {
    let m = model_data::parse_map2(&read(path)).unwrap_or_else(|e| fail(path, &e));
    arrays(out, fx, &format!("{name}_X"), &m.x);
    arrays(out, fx, &format!("{name}_Y"), &m.y);
    arrays(out, fx, &format!("{name}_Z"), &m.z);
}

fn parameters(out: &mut String, path: &Path) {
    // Every key compiles to a constant; the model's code decides which it reads.
    let lines = model_data::parse_params(&read(path), &|_| true).unwrap_or_else(|e| fail(path, &e));
    for l in lines {
        if let model_data::ParamLine::Entry { key, value, .. } = l {
            writeln!(out, "pub const {}: f32 = {};", model_data::const_name(&key), lit(value)).ok();
        }
    }
}

fn profile(out: &mut String, name: &str, path: &Path) {
    let rows = model_data::parse_profile(&read(path)).unwrap_or_else(|e| fail(path, &e));
    let mode = |m: model_data::Mode| match m {
        model_data::Mode::Hold => "Hold",
        model_data::Mode::Interpolate => "Interpolate",
    };
    let sets: Vec<String> = rows
        .iter()
        .map(|r| {
            format!(
                "ProfileSet {{ duration_s: {}, throttle_pct: {}, load_l_pct: {}, load_r_pct: {}, throttle_mode: SetMode::{}, load_mode: SetMode::{} }}",
                lit(r.duration_s),
                lit(r.set_points[0]),
                lit(r.set_points[1]),
                lit(r.set_points[2]),
                mode(r.modes[0]),
                mode(r.modes[1])
            )
        })
        .collect();
    writeln!(out, "pub static PROFILE_{name}: [ProfileSet; {}] = [{}];", sets.len(), sets.join(", ")).ok();
}

fn main() {
    let data =
        PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR")).join("data");
    println!("cargo:rerun-if-changed={}", data.display());
    let mut out = String::from("// @generated by model-core/build.rs from data/. Do not edit.\n");
    out.push_str("#[allow(unused_imports)] use crate::profile::{ProfileSet, SetMode};\n");
    // The same tables in the fixed-point format (`data::fx`, feature `fixed`).
    let mut fx = String::from("// @generated by model-core/build.rs from data/. Do not edit.\n");
    for (name, file) in MAPS_1D {
        let p = data.join(file);
        println!("cargo:rerun-if-changed={}", p.display());
        table_1d(&mut out, &mut fx, name, &p);
    }
    for (name, file) in MAPS_2D {
        let p = data.join(file);
        println!("cargo:rerun-if-changed={}", p.display());
        table_2d(&mut out, &mut fx, name, &p);
    }
    let p = data.join("parameters.toml");
    println!("cargo:rerun-if-changed={}", p.display());
    parameters(&mut out, &p);
    for name in PROFILES {
        let p = data.join("profiles").join(format!("{name}.csv"));
        println!("cargo:rerun-if-changed={}", p.display());
        profile(&mut out, name, &p);
    }
    let dir = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::write(dir.join("data.rs"), out).expect("write generated data.rs");
    fs::write(dir.join("data_fx.rs"), fx).expect("write generated data_fx.rs");
}
