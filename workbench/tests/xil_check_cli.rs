//! `simrod check --cycle`: the closed XiL loop as the checked test (its delay margin a
//! condition of approval, its Monte Carlo), and `simrod xil`'s table of check margins.

use std::fs;
use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

fn simrod(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_simrod")).current_dir(dir).args(args).output().expect("run simrod")
}

fn text(o: &Output) -> String {
    format!(
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&fs::read_to_string(path).expect("JSON written")).expect("valid JSON")
}

/// The hill cycle stays inside every built-in limit at the default 2 ms loop delay
/// (margin 31 ms >= 3 x 2 ms); at 15 ms the same loop is refused for its delay margin
/// alone (31 ms < 3 x 15 ms = 45 ms), the message naming both numbers and the factor.
#[test]
fn the_delay_margin_decides_a_closed_loop() {
    let d = tempfile::tempdir().unwrap();
    let j = d.path().join("ok.json");
    let o = simrod(d.path(), &["check", "--cycle", "hill", "--json", j.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let v = json(&j);
    let dm = &v["delay_margin"];
    assert_eq!((dm["margin_ms"].as_f64(), dm["loop_delay_ms"].as_f64()), (Some(31.0), Some(2.0)), "{dm}");
    assert_eq!((dm["factor"].as_f64(), dm["passes"].as_bool()), (Some(3.0), Some(true)), "{dm}");
    assert!(v["limits"].as_array().unwrap().iter().all(|l| l["verdict"] == "inside"), "{v}");
    assert!(v["set_points_not_applicable"].as_str().unwrap().contains("closed loop"), "{v}");

    let j = d.path().join("late.json");
    let o = simrod(
        d.path(),
        &["check", "--cycle", "hill", "--loop-delay-ms", "15", "--json", j.to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("DELAY MARGIN 31 ms < 3 x the 15 ms loop delay = 45 ms: refused"), "{}", text(&o));
    let v = json(&j);
    assert_eq!((v["approved"].as_bool(), v["delay_margin"]["passes"].as_bool()), (Some(false), Some(false)));
    assert!(v["limits"].as_array().unwrap().iter().all(|l| l["verdict"] == "inside"), "only the delay: {v}");
    // A smaller factor lets the same loop through (the factor is what refused it).
    let o =
        simrod(d.path(), &["check", "--cycle", "hill", "--loop-delay-ms", "15", "--delay-safety", "2", "-q"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
}

/// The Monte Carlo draws the loop's twin: every sample runs the whole cycle, and the
/// drawn parameters move the peaks away from the nominal run's.
#[test]
fn the_monte_carlo_runs_the_closed_loop() {
    let d = tempfile::tempdir().unwrap();
    let j = d.path().join("mc.json");
    let u = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/uncertainty.toml");
    let o = simrod(
        d.path(),
        &[
            "check",
            "--cycle",
            "hill",
            "--uncertainty",
            u.to_str().unwrap(),
            "--samples",
            "3",
            "--threads",
            "2",
            "-q",
            "--json",
            j.to_str().unwrap(),
        ],
    );
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
    let v = json(&j);
    assert_eq!(v["monte_carlo"]["samples"].as_u64(), Some(3), "{v}");
    let moved = v["limits"].as_array().unwrap().iter().any(|l| {
        let (n, w) = (l["nominal"]["peak"].as_f64(), l["monte_carlo"]["worst"]["peak"].as_f64());
        l["monte_carlo"]["samples"].as_u64() == Some(3)
            && n.zip(w).is_some_and(|(n, w)| (n - w).abs() > 1e-3 * n.abs())
    });
    assert!(moved, "no drawn model moved a peak: {v}");
    // The scales of a profile do not apply to a loop.
    let o = simrod(d.path(), &["check", "--cycle", "hill", "--throttle-scale", "0.5"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
}

/// `simrod xil` appends the table of check margins of its loop.
#[test]
fn xil_reports_the_check_margins() {
    let d = tempfile::tempdir().unwrap();
    let o = simrod(d.path(), &["xil", "--cycle", "ece15"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("check margins (the same loop at the 100 µs twin step"), "{out}");
    let row = out.lines().find(|l| l.starts_with("flange_torque_L ")).unwrap_or_else(|| panic!("{out}"));
    assert!(row.contains("-200 … 200 N m") && row.contains("inside"), "{row}");
    assert!(out.lines().any(|l| l.starts_with("load_current_L ") && l.contains("CROSSED")), "{out}");
    assert!(out.contains("NOT APPROVED: load_current_L crossed"), "{out}");
}
