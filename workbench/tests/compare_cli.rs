//! `simrod compare` end to end: bench file in, table / JSON / HTML out, bad input
//! refused with exit code 2.

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

fn simrod(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_simrod")).current_dir(dir).args(args).output().expect("run simrod")
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn clean_bench_file_compares_to_zero_in_json() {
    let d = tempfile::tempdir().unwrap();
    ok(&simrod(
        d.path(),
        &["bench", "--plant", "twin", "--profile", "TP12", "--noise", "none", "-q", "--out", "m.mat"],
    ));
    let out = ok(&simrod(d.path(), &["compare", "m.mat", "--json", "--speed-window-s", "0"]));
    let j: Value = serde_json::from_str(&out).expect("stdout is JSON");
    let channels = j["channels"].as_object().unwrap();
    assert_eq!(channels.len(), model_core::MEASURED.len() + 4);
    for (name, c) in channels {
        for key in ["rmse", "nrmse", "fit_percent", "r2", "bias", "max_abs_error", "max_error_time_s"] {
            assert!(c.get(key).is_some(), "{name}.{key}");
        }
        assert_eq!(c["rmse"].as_f64(), Some(0.0), "{name}");
        assert_eq!(c["max_abs_error"].as_f64(), Some(0.0), "{name}");
    }
    for key in ["regions", "worst_spans", "whiteness", "cross_correlation"] {
        assert!(j[key].is_object(), "{key}");
    }
    assert_eq!(j["whiteness"]["SuTMotorEnc"]["verdict"], "negligible");
    assert_eq!(j["setup"]["dt_us"], 1000);
    assert!(j["worst_channel"].is_null());
}

#[test]
fn hidden_offset_is_found_and_reported_in_html() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("fx.toml"), "[sensor_offset]\nc_kistler_l = 2.0\n").unwrap();
    ok(&simrod(
        d.path(),
        &[
            "bench",
            "--plant",
            "twin",
            "--profile",
            "TP12",
            "--noise",
            "none",
            "--effects",
            "fx.toml",
            "-q",
            "--out",
            "m.csv",
        ],
    ));
    let table = ok(&simrod(
        d.path(),
        &["compare", "m.csv", "--report", "rep/sub", "--window-s", "1.5", "--speed-window-s", "0"],
    ));
    assert!(table.contains("WORST CHANNEL: C_Kistler_L"), "{table}");
    assert!(table.contains("Worst 1.5 s spans"), "{table}");
    let html = std::fs::read_to_string(d.path().join("rep/sub/index.html")).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>") && html.trim_end().ends_with("</html>"));
    assert!(html.matches("<svg").count() >= 2 * (model_core::MEASURED.len() + 4));
    assert!(html.contains("C_Kistler_L: error budget"));
    // Self-contained: no script, stylesheet link or fetched resource.
    for bad in ["<script", "<link", "src=", "url(", "@import"] {
        assert!(!html.contains(bad), "{bad}");
    }
    // The effect on the twin side explains it away.
    let out = ok(&simrod(
        d.path(),
        &["compare", "m.csv", "--effects", "fx.toml", "--json", "--speed-window-s", "0"],
    ));
    let j: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(j["channels"]["C_Kistler_L"]["rmse"].as_f64(), Some(0.0));
}

#[test]
fn files_without_set_points_need_a_profile() {
    let d = tempfile::tempdir().unwrap();
    ok(&simrod(
        d.path(),
        &["bench", "--plant", "twin", "--profile", "TP12", "--noise", "none", "-q", "--out", "m.csv"],
    ));
    // Keep time and the measured channels, drop the three set-point columns.
    let text = std::fs::read_to_string(d.path().join("m.csv")).unwrap();
    let cut: String = text
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            f[..f.len() - 3].join(",") + "\n"
        })
        .collect();
    std::fs::write(d.path().join("nosp.csv"), cut).unwrap();
    let o = simrod(d.path(), &["compare", "nosp.csv"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--profile"));
    let out = ok(&simrod(
        d.path(),
        &["compare", "nosp.csv", "--profile", "tp12", "--json", "--speed-window-s", "0"],
    ));
    let j: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(j["channels"]["SuTMotorEnc"]["rmse"].as_f64(), Some(0.0));
    // The wrong scale is visible.
    let out = ok(&simrod(
        d.path(),
        &[
            "compare",
            "nosp.csv",
            "--profile",
            "tp12",
            "--throttle-scale",
            "0.7",
            "--json",
            "--speed-window-s",
            "0",
        ],
    ));
    let j: Value = serde_json::from_str(&out).unwrap();
    assert!(j["channels"]["SuTMotorEnc"]["nrmse"].as_f64().unwrap() > 0.01);
}

#[test]
fn bad_arguments_exit_2() {
    let d = tempfile::tempdir().unwrap();
    for args in [
        &["compare", "missing.csv"][..],
        &["compare", "m.csv", "--window-s", "0"],
        &["compare", "m.csv", "--throttle-scale", "0.5"],
        &["compare", "m.csv", "--supply-v", "40"],
    ] {
        let o = simrod(d.path(), args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
    }
}
