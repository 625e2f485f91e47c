//! Reliability of the commands on clumsy input (issue 13's cases, each as the user typed
//! it). No output ever replaces an input: every command refuses, before any work, an
//! output that is one of its inputs by any name (hard links included), and `compare`
//! records its history only once it has succeeded. Negative numbers are values.

use std::path::Path;
use std::process::{Command, Output};

fn simrod(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_simrod")).current_dir(dir).args(args).output().expect("run simrod")
}

/// Refused as a usage error, naming the input, and `file` left as it was.
fn refused(dir: &Path, args: &[&str], file: &str) {
    let before = std::fs::read(dir.join(file)).unwrap();
    let o = simrod(dir, args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains("is the input") || err.contains("holds the input"), "{args:?}: {err}");
    assert_eq!(std::fs::read(dir.join(file)).unwrap(), before, "{args:?} changed {file}");
}

fn setup() -> tempfile::TempDir {
    let d = tempfile::tempdir().unwrap();
    let o = simrod(
        d.path(),
        &["bench", "--plant", "twin", "--profile", "TP12", "--seed", "1", "-q", "--out", "good.csv"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    d
}

#[test]
fn outputs_that_are_inputs_are_refused() {
    let d = setup();
    let p = d.path();
    assert!(simrod(p, &["compare", "good.csv"]).status.success());
    refused(p, &["history", "good.csv", "--plot", "good.csv"], "good.csv");
    refused(p, &["history", "good.csv", "--plot", "good.simrod-history.jsonl"], "good.simrod-history.jsonl");
    refused(p, &["diagnose", "good.csv", "--write-effects", "good.csv"], "good.csv");
    std::fs::write(p.join("p.toml"), "[[set]]\nduration_s = 1\nthrottle_pct = 50\n").unwrap();
    refused(p, &["simulate", "--profile-file", "p.toml", "--out", "p.toml"], "p.toml");
    std::fs::write(p.join("fx.toml"), "[controller_delay]\ndelay_s = 0.01\n").unwrap();
    refused(p, &["simulate", "--profile", "TP12", "--effects", "fx.toml", "--out", "fx.toml"], "fx.toml");
    // By another name: a hard link to the effect file.
    std::fs::hard_link(p.join("fx.toml"), p.join("link.csv")).unwrap();
    refused(p, &["bench", "--profile", "TP12", "--effects", "fx.toml", "--out", "link.csv"], "fx.toml");
    // identify writes a data directory: not into the directory of its runs.
    std::fs::create_dir(p.join("runs")).unwrap();
    std::fs::copy(p.join("good.csv"), p.join("runs/good.csv")).unwrap();
    std::fs::copy(p.join("good.csv"), p.join("runs/speed_map_fwd.csv")).unwrap();
    refused(
        p,
        &["identify", "speed-map", "runs/good.csv", "runs/speed_map_fwd.csv", "--out", "runs"],
        "runs/speed_map_fwd.csv",
    );
}

#[test]
fn a_failed_compare_records_no_history() {
    let d = setup();
    let p = d.path();
    std::fs::write(p.join("f"), "a file, not a directory").unwrap();
    let o = simrod(p, &["compare", "good.csv", "--report", "f"]);
    assert!(!o.status.success());
    assert!(!p.join("good.simrod-history.jsonl").exists(), "history written by a failed compare");
    assert!(simrod(p, &["compare", "good.csv"]).status.success());
    let lines = std::fs::read_to_string(p.join("good.simrod-history.jsonl")).unwrap();
    assert_eq!(lines.lines().count(), 1);
}

/// A negative number is a value, checked as one, not taken for an unknown flag.
#[test]
fn negative_numbers_are_values_with_their_range() {
    let d = tempfile::tempdir().unwrap();
    for (args, want) in [
        (
            &["bench", "--profile", "TP12", "--seed", "-1", "--out", "x.csv"][..],
            "--seed <N>': expected a whole number",
        ),
        (
            &["bench", "--profile", "TP12", "--supply-v", "-24", "--out", "x.csv"],
            "expected a voltage in [12, 30] V",
        ),
        (
            &["simulate", "--profile", "TP12", "--dt-us", "-5", "--out", "x.csv"],
            "expected a whole number of µs",
        ),
        (&["compare", "x.csv", "--speed-window-s", "-0.1"], "--speed-window-s <S>'"),
    ] {
        let o = simrod(d.path(), args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want) && !err.contains("unexpected argument"), "{args:?}: {err}");
    }
}

/// Garbage is never called a result: effect values that make the twin non-physical are
/// refused with their range, and a run that diverges anyway (here a data directory with
/// a 1e30 N m/rad flange) is an error naming the step, time and channel, with no file.
#[test]
fn diverging_runs_are_errors_and_unstable_effects_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    for (fx, want) in [
        ("[coupling_stiffness]\nstiffness_nm_per_rad = 1e30\n", "stiffness_nm_per_rad must be"),
        ("[inertia_scale]\nsut = 1e-12\n", "sut must be"),
    ] {
        std::fs::write(p.join("fx.toml"), fx).unwrap();
        let o = simrod(p, &["simulate", "--profile", "TP12", "--effects", "fx.toml", "--out", "o.csv"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{fx}: {err}");
        assert!(err.contains("fx.toml:") && err.contains(want), "{fx}: {err}");
    }
    let data = p.join("data");
    std::fs::create_dir(&data).unwrap();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../model-core/data");
    for e in std::fs::read_dir(&src).unwrap().flatten() {
        if e.path().is_file() {
            std::fs::copy(e.path(), data.join(e.file_name())).unwrap();
        }
    }
    let params = std::fs::read_to_string(data.join("parameters.toml")).unwrap();
    let stiff: String = params
        .lines()
        .map(|l| {
            if l.starts_with("flange_stiffness") {
                "flange_stiffness = 1e30".to_owned()
            } else {
                l.to_owned()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(data.join("parameters.toml"), stiff).unwrap();
    for cmd in [&["simulate"][..], &["bench", "--plant", "twin"]] {
        let mut args = cmd.to_vec();
        args.extend(["--profile", "TP12", "--data-dir", "data", "--out", "o.csv"]);
        let o = simrod(p, &args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{cmd:?}: {err}");
        assert!(
            err.contains("diverged at") && err.contains("t = 13.") && err.contains("inf"),
            "{cmd:?}: {err}"
        );
        assert!(!p.join("o.csv").exists(), "{cmd:?} wrote a diverged run");
    }
}

/// A value no sensor could give (one sample of 1e308 N m) stops compare and diagnose
/// with the channel, time and value; a dead channel is named in the report.
#[test]
fn implausible_values_stop_the_analysis_and_dead_channels_are_named() {
    let d = setup();
    let p = d.path();
    let text = std::fs::read_to_string(p.join("good.csv")).unwrap();
    let edit = |col: usize, f: &dyn Fn(usize) -> Option<String>| -> String {
        let mut out = String::new();
        for (k, line) in text.lines().enumerate() {
            let mut cells: Vec<String> = line.split(',').map(str::to_owned).collect();
            if k > 0 {
                if let Some(v) = f(k) {
                    cells[col] = v;
                }
            }
            out.push_str(&cells.join(","));
            out.push('\n');
        }
        out
    };
    // Column 3 is C_Kistler_L (time, Throttle, SuTMotorEnc, C_Kistler_L, ...).
    assert!(text.lines().next().unwrap().split(',').nth(3).unwrap().starts_with("C_Kistler_L"));
    std::fs::write(p.join("bad.csv"), edit(3, &|k| (k == 100).then(|| "1e308".to_owned()))).unwrap();
    for cmd in ["compare", "diagnose"] {
        let o = simrod(p, &[cmd, "bad.csv"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {err}");
        assert!(err.contains("C_Kistler_L at t = 0.1 s is 1e308"), "{cmd}: {err}");
    }
    // With --mask-implausible compare leaves the sample out and says so; the figures
    // are those of the clean run within a sample's share.
    let o = simrod(p, &["compare", "bad.csv", "--no-history", "--mask-implausible", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let masked: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(masked.to_string().contains("C_Kistler_L: 1 sample(s) beyond ±27600 N m masked"), "{masked}");
    let o = simrod(p, &["compare", "good.csv", "--no-history", "--json"]);
    let clean: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rmse = |v: &serde_json::Value| v["channels"]["C_Kistler_L"]["rmse"].as_f64().unwrap();
    let (a, b) = (rmse(&masked), rmse(&clean));
    assert!(a.is_finite() && (a - b).abs() <= 0.01 * b, "masked RMSE {a} vs clean {b}");
    std::fs::write(p.join("dead.csv"), edit(3, &|_| Some("-0".to_owned()))).unwrap();
    let o = simrod(p, &["compare", "dead.csv", "--no-history"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("C_Kistler_L is constant"), "dead channel not named");
}

/// Load: 16 `compare` at once on one file append 16 whole history records (every line
/// valid JSON); 4 `bench` at once to one output leave one complete file and no
/// temporary files.
#[test]
fn concurrent_commands_keep_history_and_output_whole() {
    let d = setup();
    let p = d.path();
    std::thread::scope(|s| {
        let runs: Vec<_> =
            (0..16).map(|_| s.spawn(|| simrod(p, &["compare", "good.csv", "--json"]))).collect();
        for r in runs {
            let o = r.join().unwrap();
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        }
    });
    let history = std::fs::read_to_string(p.join("good.simrod-history.jsonl")).unwrap();
    assert_eq!(history.lines().count(), 16, "{history}");
    assert!(!p.join("good.simrod-history.jsonl.lock").exists(), "the append lock is left");
    for line in history.lines() {
        serde_json::from_str::<serde_json::Value>(line).expect("a whole JSON record");
    }
    std::thread::scope(|s| {
        let runs: Vec<_> = (0..4u32)
            .map(|k| {
                let seed = k.to_string();
                s.spawn(move || {
                    simrod(p, &["bench", "--profile", "TP12", "--seed", &seed, "-q", "--out", "same.csv"])
                })
            })
            .collect();
        for r in runs {
            let o = r.join().unwrap();
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        }
    });
    let o = simrod(p, &["compare", "same.csv", "--no-history", "--json"]);
    assert!(o.status.success(), "the last bench's file is whole: {}", String::from_utf8_lossy(&o.stderr));
    let left: Vec<String> = std::fs::read_dir(p)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "temporary files left behind: {left:?}");
}

/// Refused with the estimate and the flag that lifts it, and nothing written.
fn over_budget(dir: &Path, args: &[&str], estimate: &str) {
    let o = simrod(dir, args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(estimate) && err.contains("--budget-gb"), "{args:?}: {err}");
}

#[test]
fn runs_beyond_the_budget_are_refused_up_front_with_the_estimate() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    // One set of 1e6 s at 10 µs: 1e11 rows.
    std::fs::write(p.join("long.toml"), "[[set]]\nduration_s = 1000000\nthrottle_pct = 10\n").unwrap();
    let sim = ["simulate", "--profile-file", "long.toml", "--dt-us", "10", "--out", "x.csv"];
    over_budget(p, &sim, "100000000000 rows of 10 µs");
    over_budget(
        p,
        &["bench", "--profile-file", "long.toml", "--dt-us", "10", "--out", "x.csv"],
        "rows of 10 µs",
    );
    assert!(!p.join("x.csv").exists());
    // A file sampled every second: 60,000 rows (1 MB) become 6e7 samples on the 1 ms grid.
    let mut csv = String::from("time [s],SuT Throttle [%],Dm Left [%],Dm Right [%],SuTMotorEnc [rpm]\n");
    for k in 0..60_001 {
        csv.push_str(&format!("{k},0,0,0,0\n"));
    }
    std::fs::write(p.join("slow.csv"), csv).unwrap();
    over_budget(p, &["compare", "slow.csv"], "60000001 samples on the twin's grid");
    over_budget(p, &["diagnose", "slow.csv"], "60000001 samples on the twin's grid");
    assert!(!p.join("slow.simrod-history.jsonl").exists());
    // A 10,000 s gap at 1 ms, interpolated across: 1e7 samples × 6 columns.
    let gap = "time [s],SuT Throttle [%],Dm Left [%],Dm Right [%],SuTMotorEnc [rpm]\n\
               0.001,0,0,0,0\n0.002,0,0,0,0\n0.003,0,0,0,0\n0.004,0,0,0,0\n10000.004,0,0,0,0\n";
    std::fs::write(p.join("gap.csv"), gap).unwrap();
    over_budget(p, &["compare", "gap.csv", "--allow-gaps", "--budget-gb", "0.5"], "resampling it would take");
    // The flag lifts the limit: the same gap within a 4 GB budget is loaded (and then
    // refused by the twin's own budget for the comparison, which is larger).
    let o = simrod(p, &["compare", "gap.csv", "--allow-gaps", "--no-history"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("comparing gap.csv would take about 7.0 GB"), "{err}");
}

/// The temporary files in `dir` (atomic writes in progress or left behind).
fn temp_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

#[test]
fn a_signal_during_a_write_leaves_no_temporary_file() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    // 2000 s at 10 µs: minutes of writing, so the signal lands mid-write.
    std::fs::write(p.join("long.toml"), "[[set]]\nduration_s = 2000\nthrottle_pct = 30\n").unwrap();
    for (signal, code) in [("INT", 130), ("TERM", 143), ("HUP", 129)] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_simrod"))
            .current_dir(p)
            .args(["simulate", "--profile-file", "long.toml", "--dt-us", "10", "--budget-gb", "100"])
            .args(["-q", "--out", "out.csv"])
            .spawn()
            .unwrap();
        let start = std::time::Instant::now();
        while temp_files(p).is_empty() && start.elapsed().as_secs() < 60 {
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        assert!(!temp_files(p).is_empty(), "no write in progress to interrupt");
        std::thread::sleep(std::time::Duration::from_millis(300));
        let pid = child.id().to_string();
        assert!(Command::new("kill").args([&format!("-{signal}"), &pid]).status().unwrap().success());
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(code), "SIG{signal}");
        assert!(temp_files(p).is_empty(), "SIG{signal} left {:?}", temp_files(p));
        assert!(!p.join("out.csv").exists(), "SIG{signal}: a half-written output");
    }
}
