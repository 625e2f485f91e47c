//! Compiles the data files in `data/` into `static` arrays (flash on the target).
//!
//! Why a build script: the maps must live as plain, replaceable data files, yet the
//! target has no file system and no allocator. Every file is validated here (strictly
//! increasing grids, finite values, rectangular 2-D tables, profile limits) so a bad
//! file is a build error naming file and line, never a run-time surprise.
//! No dependencies: the formats are tiny and a parser here keeps the build lean.

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
const MAX_SETS: usize = 10;

fn fail(file: &Path, line: usize, msg: &str) -> ! {
    panic!("{}:{}: {}", file.display(), line, msg)
}

/// Non-comment, non-empty lines with their 1-based line numbers.
fn data_lines(path: &Path) -> Vec<(usize, String)> {
    let text = fs::read_to_string(path).unwrap_or_else(|e| fail(path, 0, &format!("cannot read: {e}")));
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim().to_string()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
        .collect()
}

fn num(path: &Path, line: usize, field: &str, what: &str) -> f32 {
    match field.trim().parse::<f32>() {
        Ok(v) if v.is_finite() => v,
        _ => fail(path, line, &format!("{what}: expected a finite number, found `{}`", field.trim())),
    }
}

fn check_increasing(path: &Path, line: usize, xs: &[f32], what: &str) {
    if xs.len() < 2 {
        fail(path, line, &format!("{what}: need at least 2 grid points"));
    }
    for w in xs.windows(2) {
        if w[1] <= w[0] {
            fail(path, line, &format!("{what}: grid must be strictly increasing ({} then {})", w[0], w[1]));
        }
    }
}

fn lit(v: f32) -> String {
    format!("{v:?}")
}

fn array(name: &str, vals: &[f32]) -> String {
    let body: Vec<String> = vals.iter().map(|v| lit(*v)).collect();
    format!("pub static {name}: [f32; {}] = [{}];\n", vals.len(), body.join(", "))
}

fn table_1d(out: &mut String, name: &str, path: &Path) {
    let lines = data_lines(path);
    let (hl, _header) = lines.first().cloned().unwrap_or_else(|| fail(path, 0, "empty file"));
    let mut xs = Vec::new();
    let mut ys = Vec::new();
    for (ln, l) in lines.iter().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != 2 {
            fail(path, *ln, &format!("expected 2 columns (x,y), found {}", f.len()));
        }
        xs.push(num(path, *ln, f[0], "x"));
        ys.push(num(path, *ln, f[1], "y"));
    }
    check_increasing(path, hl, &xs, "x column");
    out.push_str(&array(&format!("{name}_X"), &xs));
    out.push_str(&array(&format!("{name}_Y"), &ys));
}

fn table_2d(out: &mut String, name: &str, path: &Path) {
    let lines = data_lines(path);
    let (hl, header) = lines.first().cloned().unwrap_or_else(|| fail(path, 0, "empty file"));
    let xs: Vec<f32> = header.split(',').skip(1).map(|f| num(path, hl, f, "column grid")).collect();
    check_increasing(path, hl, &xs, "column grid (throttle set point)");
    let mut ys = Vec::new();
    let mut zs = Vec::new();
    for (ln, l) in lines.iter().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != xs.len() + 1 {
            fail(path, *ln, &format!("expected {} columns, found {}", xs.len() + 1, f.len()));
        }
        ys.push(num(path, *ln, f[0], "row grid"));
        for v in &f[1..] {
            zs.push(num(path, *ln, v, "value"));
        }
    }
    check_increasing(path, hl, &ys, "row grid (load set point)");
    out.push_str(&array(&format!("{name}_X"), &xs));
    out.push_str(&array(&format!("{name}_Y"), &ys));
    out.push_str(&array(&format!("{name}_Z"), &zs));
}

fn parameters(out: &mut String, path: &Path) {
    let mut seen = Vec::new();
    for (ln, l) in data_lines(path) {
        let l = l.split('#').next().unwrap_or("").trim().to_string();
        if l.is_empty() {
            continue;
        }
        let (k, v) = l.split_once('=').unwrap_or_else(|| fail(path, ln, "expected `name = number`"));
        let key = k.trim();
        if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.') {
            fail(path, ln, &format!("bad parameter name `{key}`"));
        }
        let name = key.replace('.', "_").to_ascii_uppercase();
        if seen.contains(&name) {
            fail(path, ln, &format!("parameter `{key}` given twice"));
        }
        let value = num(path, ln, v, key);
        writeln!(out, "pub const {name}: f32 = {};", lit(value)).ok();
        seen.push(name);
    }
}

fn profile(out: &mut String, name: &str, path: &Path) {
    let lines = data_lines(path);
    let mut sets = Vec::new();
    for (ln, l) in lines.iter().skip(1) {
        let f: Vec<&str> = l.split(',').map(str::trim).collect();
        if f.len() != 6 {
            fail(path, *ln, &format!("expected 6 columns, found {}", f.len()));
        }
        let dur = num(path, *ln, f[0], "duration_s");
        if dur <= 0.0 {
            fail(path, *ln, "duration_s must be > 0");
        }
        let mut sp = [0.0f32; 3];
        for (i, s) in sp.iter_mut().enumerate() {
            *s = num(path, *ln, f[i + 1], "set point");
            if !(-100.0..=100.0).contains(s) {
                fail(path, *ln, "set points must lie in [-100, 100] %");
            }
        }
        let mode = |m: &str| match m {
            "hold" => "Hold",
            "interp" => "Interpolate",
            _ => fail(path, *ln, &format!("mode must be `hold` or `interp`, found `{m}`")),
        };
        sets.push(format!(
            "ProfileSet {{ duration_s: {}, throttle_pct: {}, load_l_pct: {}, load_r_pct: {}, throttle_mode: SetMode::{}, load_mode: SetMode::{} }}",
            lit(dur), lit(sp[0]), lit(sp[1]), lit(sp[2]), mode(f[4]), mode(f[5])
        ));
    }
    if sets.is_empty() || sets.len() > MAX_SETS {
        fail(path, 0, &format!("a profile has 1 to {MAX_SETS} sets, found {}", sets.len()));
    }
    writeln!(out, "pub static PROFILE_{name}: [ProfileSet; {}] = [{}];", sets.len(), sets.join(", ")).ok();
}

fn main() {
    let data =
        PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR")).join("data");
    println!("cargo:rerun-if-changed={}", data.display());
    let mut out = String::from("// @generated by model-core/build.rs from data/. Do not edit.\n");
    out.push_str("#[allow(unused_imports)] use crate::profile::{ProfileSet, SetMode};\n");
    for (name, file) in MAPS_1D {
        let p = data.join(file);
        println!("cargo:rerun-if-changed={}", p.display());
        table_1d(&mut out, name, &p);
    }
    for (name, file) in MAPS_2D {
        let p = data.join(file);
        println!("cargo:rerun-if-changed={}", p.display());
        table_2d(&mut out, name, &p);
    }
    let p = data.join("parameters.toml");
    println!("cargo:rerun-if-changed={}", p.display());
    parameters(&mut out, &p);
    for name in PROFILES {
        let p = data.join("profiles").join(format!("{name}.csv"));
        println!("cargo:rerun-if-changed={}", p.display());
        profile(&mut out, name, &p);
    }
    let dest = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("data.rs");
    fs::write(&dest, out).expect("write generated data.rs");
}
