//! `simrod demo` end to end in a temporary directory: the hidden effect is found, the
//! error falls, and the files it promises are there. Timings in its output are not
//! asserted on.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

/// The NRMSE pair `before → after` [%] the demo prints for `channel` in step 5.
fn printed_change(out: &str, channel: &str) -> (f64, f64) {
    let line = out
        .lines()
        .find(|l| l.trim_start().starts_with(&format!("{channel} ")) && l.contains('→'))
        .unwrap_or_else(|| panic!("no line for {channel}:\n{out}"));
    let rest = line.trim_start()[channel.len()..].trim();
    let (a, b) = rest.split_once('→').unwrap();
    let num = |s: &str| {
        s.trim().split(' ').next().unwrap().parse::<f64>().unwrap_or_else(|e| panic!("{line}: {e}"))
    };
    (num(a), num(b))
}

fn nrmse(rec: &Value, channel: &str) -> f64 {
    rec["channels"].as_array().unwrap().iter().find(|c| c["name"] == channel).unwrap()["nrmse"]
        .as_f64()
        .unwrap()
}

#[test]
fn demo_finds_the_hidden_effect_and_the_error_falls() {
    let d = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_simrod"))
        .current_dir(d.path())
        .args(["demo", "--dir", "out", "--threads", "2"])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{out}\n{}", String::from_utf8_lossy(&o.stderr));

    // Found, with the right value.
    assert!(out.contains("VERDICT: missing effect: differential_friction"), "{out}");
    let reveal = out.lines().find(|l| l.contains("6. Reveal")).expect(&out);
    let found: f64 = reveal
        .split("found coulomb_nm = ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{reveal}"));
    assert!((found - 4.0).abs() < 0.3, "{reveal}");

    // The error falls where differential friction shows (SuT electrics), as printed...
    for ch in ["I_DC", "P_SuT_inv"] {
        let (before, after) = printed_change(&out, ch);
        assert!(after < 0.3 * before, "{ch}: {before} -> {after}");
    }
    // ...and as recorded in the history.
    let p = d.path().join("out");
    let hist = std::fs::read_to_string(p.join("measured.simrod-history.jsonl")).unwrap();
    let recs: Vec<Value> = hist.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(recs.len(), 2);
    assert_eq!(recs[0]["effects"]["summary"], "none");
    assert!(recs[1]["effects"]["summary"].as_str().unwrap().starts_with("differential_friction("));
    assert!(nrmse(&recs[1], "I_DC") < 0.3 * nrmse(&recs[0], "I_DC"));
    // The flanges do not see differential friction: their error stays.
    let (a, b) = (nrmse(&recs[0], "C_Kistler_L"), nrmse(&recs[1], "C_Kistler_L"));
    assert!((b - a).abs() < 0.05 * a, "C_Kistler_L {a} -> {b}");

    // The files it lists.
    let fx = workbench::effects_file::load_effects(&p.join("effects.toml")).unwrap();
    assert!((fx.differential_friction.coulomb_nm - 4.0).abs() < 0.3);
    let html = std::fs::read_to_string(p.join("report/index.html")).unwrap();
    assert!(html.contains("Before / after") && html.contains("I_DC: measured, before, after"));
    assert!(std::fs::read_to_string(p.join("history.svg")).unwrap().contains(">I_DC<"));
    assert!(Path::new(&p.join("measured.csv")).exists());

    // Run again: a fresh history, not an accumulated one.
    let o = Command::new(env!("CARGO_BIN_EXE_simrod"))
        .current_dir(d.path())
        .args(["demo", "--dir", "out", "--threads", "2"])
        .output()
        .unwrap();
    assert!(o.status.success());
    let hist = std::fs::read_to_string(p.join("measured.simrod-history.jsonl")).unwrap();
    assert_eq!(hist.lines().count(), 2);
}
