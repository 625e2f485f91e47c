//! `simrod bench` end to end: the subcommand exists, writes a file the readers load,
//! and refuses bad arguments with exit code 2 before touching the output.

use std::path::Path;
use std::process::{Command, Output};

use workbench::measure::load;

fn simrod(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_simrod")).current_dir(dir).args(args).output().expect("run simrod")
}

#[test]
fn bench_writes_csv_and_mat_that_load_back() {
    let d = tempfile::tempdir().unwrap();
    for out in ["m.csv", "m.mat"] {
        let o = simrod(d.path(), &["bench", "--profile", "tp12", "--seed", "4", "--miscount", "--out", out]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(String::from_utf8_lossy(&o.stdout).contains(out));
    }
    let a = load(&d.path().join("m.csv"), None).unwrap();
    let b = load(&d.path().join("m.mat"), None).unwrap();
    assert_eq!((&a.time_s, &a.signals), (&b.time_s, &b.signals));
    assert_eq!(a.signals.len(), model_core::MEASURED.len() + 3);
    assert_eq!(a.time_s.len(), 26_000);
}

#[test]
fn bad_arguments_exit_2_and_write_nothing() {
    let d = tempfile::tempdir().unwrap();
    let o = simrod(d.path(), &["bench", "--profile", "TP12", "--out", "m.xlsx"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains(".csv or .mat"));
    std::fs::write(d.path().join("n.toml"), "[torque]\nsigma = \"high\"\n").unwrap();
    let o = simrod(d.path(), &["bench", "--profile", "TP12", "--noise", "n.toml", "--out", "m.csv"]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("n.toml:2:9:"), "{e}");
    assert!(!d.path().join("m.csv").exists());
}
