//! `simrod identify` and `--data-dir` end to end: a small campaign measured with
//! `simrod bench --data-dir` from an altered model, identified by the CLI into a data
//! directory that loads, runs, compares, and compiles with model-core's own build.rs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use workbench::datadir::ModelData;

fn simrod(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_simrod")).current_dir(dir).args(args).output().expect("run simrod")
}

fn ok(o: &Output) -> String {
    assert!(
        o.status.success(),
        "stderr: {}\nstdout: {}",
        String::from_utf8_lossy(&o.stderr),
        String::from_utf8_lossy(&o.stdout)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn model_core() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../model-core")
}

/// Compile model-core/build.rs on its own and run it on `data` (as `data/` of a fake
/// manifest dir): the generated constants prove the files build into flash.
fn build_rs_generates(data: &Path, scratch: &Path) -> String {
    let manifest = scratch.join("manifest");
    let dd = manifest.join("data");
    std::fs::create_dir_all(dd.join("profiles")).unwrap();
    for e in std::fs::read_dir(data).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "csv" || x == "toml") {
            std::fs::copy(&p, dd.join(p.file_name().unwrap())).unwrap();
        }
    }
    for e in std::fs::read_dir(data.join("profiles")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, dd.join("profiles").join(p.file_name().unwrap())).unwrap();
    }
    let exe = scratch.join("build_rs");
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    // build.rs parses with model-data (its build-dependency): compile that first.
    let rlib = scratch.join("libmodel_data.rlib");
    let o = Command::new(&rustc)
        .args(["--edition", "2021", "--crate-type", "rlib", "--crate-name", "model_data", "-o"])
        .arg(&rlib)
        .arg(model_core().join("../model-data/src/lib.rs"))
        .output()
        .expect("rustc");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = Command::new(&rustc)
        .args(["--edition", "2021", "--extern"])
        .arg(format!("model_data={}", rlib.display()))
        .arg("-o")
        .arg(&exe)
        .arg(model_core().join("build.rs"))
        .output()
        .expect("rustc");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = scratch.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let o = Command::new(&exe).env("CARGO_MANIFEST_DIR", &manifest).env("OUT_DIR", &out).output().unwrap();
    assert!(
        o.status.success(),
        "build.rs refused the identified data: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::read_to_string(out.join("data.rs")).unwrap()
}

fn rmse(json: &str, channel: &str) -> f64 {
    let v: serde_json::Value = serde_json::from_str(json).unwrap();
    v["channels"][channel]["rmse"].as_f64().unwrap()
}

#[test]
fn identify_cli_writes_a_data_dir_that_loads_runs_and_builds() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let mut truth = ModelData::builtin().unwrap();
    assert!(truth.set_param("connector_resistance", 0.03, "[ohm] altered for the test"));
    truth.write(&dir.join("truth")).unwrap();

    // The campaign, measured from the altered model without rebuilding it.
    let runs = [("0.6", "0", "r1.csv"), ("1", "0", "r2.csv"), ("1", "1", "r3.mat")];
    for (i, (ts, ls, out)) in runs.iter().enumerate() {
        let seed = (i + 1).to_string();
        let args = [
            "bench",
            "--profile",
            "TP11",
            "--throttle-scale",
            ts,
            "--load-scale",
            ls,
            "--data-dir",
            "truth",
            "--seed",
            &seed,
            "--out",
            out,
        ];
        ok(&simrod(dir, &args));
    }
    // Chained as a user would: friction (loads-0 runs), speed map on top, resistance last.
    let text = ok(&simrod(dir, &["identify", "friction", "r1.csv", "r2.csv", "--out", "id1"]));
    assert!(text.contains("identified axle_friction_L.csv, axle_friction_R.csv"), "{text}");
    let text = ok(&simrod(
        dir,
        &["identify", "speed-map", "r1.csv", "r2.csv", "r3.mat", "--data-dir", "id1", "--out", "id2"],
    ));
    assert!(text.contains("speed_map_fwd.csv"), "{text}");
    let o = simrod(
        dir,
        &["identify", "resistance", "r1.csv", "r2.csv", "r3.mat", "--data-dir", "id2", "--out", "ident"],
    );
    let text = ok(&o);
    assert!(
        text.contains("identify resistance: 3 run(s); identified parameters.toml: connector_resistance"),
        "{text}"
    );
    let ident = ModelData::load(&dir.join("ident")).unwrap();
    let r = f64::from(ident.param("connector_resistance").unwrap());
    assert!((r - 0.03).abs() < 1e-4, "{r}");
    let report = std::fs::read_to_string(dir.join("ident/report.md")).unwrap();
    assert!(report.contains("## Plateaus") && report.contains("Thesis method"), "{report}");
    assert!(dir.join("ident/resistance.svg").is_file() && dir.join("id1/friction_L.svg").is_file());
    // The chain carried the friction and speed maps through; the rest is the base model.
    let id1 = ModelData::load(&dir.join("id1")).unwrap();
    assert_eq!(ident.friction, id1.friction);
    assert_ne!(id1.friction[0].x, truth.friction[0].x, "the friction map gets its own grid");
    assert_eq!(ident.load_torque, truth.load_torque);
    assert_eq!(ident.sut_power, truth.sut_power);

    // The identified directory (new friction grids, fitted speed maps, new resistance)
    // compiles with model-core's build.rs, and runs without rebuilding.
    let generated = build_rs_generates(&dir.join("ident"), &dir.join("scratch"));
    let want = format!("pub const CONNECTOR_RESISTANCE: f32 = {:?};", r as f32);
    assert!(generated.contains(&want), "{want} not in generated data.rs");
    let fl: Vec<String> = ident.friction[0].x.iter().map(|v| format!("{v:?}")).collect();
    assert!(generated.contains(&format!(
        "pub static FRICTION_L_X: [f32; {}] = [{}];",
        fl.len(),
        fl.join(", ")
    )));
    ok(&simrod(dir, &["simulate", "--profile", "TP07", "-q", "--data-dir", "ident", "--out", "tp07.csv"]));

    // compare --data-dir: the true model explains the run's connector drop, the
    // built-in one (0.0196 ohm) does not.
    let with = ok(&simrod(dir, &["compare", "r3.mat", "--data-dir", "ident", "--json"]));
    let without = ok(&simrod(dir, &["compare", "r3.mat", "--json"]));
    let (a, b) = (rmse(&with, "V_DC"), rmse(&without, "V_DC"));
    assert!(a < 0.025 && b > 4.0 * a, "V_DC RMSE with identified data {a}, built-in {b}");

    // simulate --data-dir model-core/data is the built-in run, byte for byte.
    let md = model_core().join("data");
    ok(&simrod(dir, &["simulate", "--profile", "TP12", "-q", "--out", "a.csv"]));
    ok(&simrod(
        dir,
        &["simulate", "--profile", "TP12", "-q", "--data-dir", md.to_str().unwrap(), "--out", "b.csv"],
    ));
    assert_eq!(std::fs::read(dir.join("a.csv")).unwrap(), std::fs::read(dir.join("b.csv")).unwrap());
}

#[test]
fn identify_cli_refuses_bad_inputs_with_exit_2() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let o = simrod(dir, &["identify", "friction", "nope.csv", "--out", "x"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("nope.csv"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!dir.join("x").exists());
    // A run without the PLC's set points.
    std::fs::write(dir.join("m.csv"), "time [s],C_Kistler_L [N m]\n0.001,1\n0.002,2\n").unwrap();
    let o = simrod(dir, &["identify", "speed-map", "m.csv", "--out", "x"]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("m.csv: no set-point channel(s) SuT Throttle, Dm Left, Dm Right"), "{e}");
    // A bad base data directory, for identify and for simulate.
    let o = simrod(dir, &["identify", "speed-map", "m.csv", "--data-dir", "nodir", "--out", "x"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("nodir: not a directory"));
    ModelData::builtin().unwrap().write(&dir.join("bad")).unwrap();
    std::fs::write(dir.join("bad/speed_map_rev.csv"), "x,y\n0,0\n0,1\n").unwrap();
    let o = simrod(dir, &["simulate", "--profile", "TP12", "--data-dir", "bad", "--out", "s.csv"]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("speed_map_rev.csv:3:") && e.contains("strictly increasing"), "{e}");
    assert!(!dir.join("s.csv").exists());
}
