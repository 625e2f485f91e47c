//! Peak memory of `simrod compare` and `simrod diagnose` on a long bench run, as
//! `/usr/bin/time -v` reports it (maximum resident set size), against the aims of
//! issue 13: compare ≤ 4 × the file + 200 MB, diagnose ≤ 8 × the file + 200 MB.
//!
//! ```text
//! cargo build -p workbench --bin simrod && cargo run -p workbench --example memory -- --mb 300
//! cargo run -p workbench --example memory -- --mb 40 --guard   # CI: fail above the aims
//! ```
//!
//! The run is made by `simrod bench --plant twin` (a long profile of held and ramped
//! sets, at 1 ms) next to this example's binary; the `simrod` measured is the one in the
//! same target directory (`target/<profile>/simrod`), so build it first.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::sibling;

/// One command's peak, measured.
struct Peak {
    what: &'static str,
    rss_mb: f64,
    wall_s: f64,
    aim_mb: f64,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mb = flag(&args, "--mb").unwrap_or(300.0);
    let guard = args.iter().any(|a| a == "--guard");
    let simrod = sibling("simrod");
    let dir = tempfile::tempdir().expect("a temporary directory");
    let file = make_run(&simrod, dir.path(), mb);
    let size_mb = std::fs::metadata(&file).expect("the run").len() as f64 / 1e6;
    println!("run: {} ({size_mb:.1} MB)", file.display());
    let peaks = [
        measure(&simrod, "compare", &["compare", "--no-history"], &file, 4.0 * size_mb + 200.0),
        measure(&simrod, "diagnose", &["diagnose"], &file, 8.0 * size_mb + 200.0),
    ];
    println!("{:<10} {:>12} {:>12} {:>10} {:>9}", "command", "peak [MB]", "aim [MB]", "x file", "wall [s]");
    for p in &peaks {
        println!(
            "{:<10} {:>12.0} {:>12.0} {:>10.2} {:>9.1}",
            p.what,
            p.rss_mb,
            p.aim_mb,
            p.rss_mb / size_mb,
            p.wall_s
        );
    }
    let over: Vec<&Peak> = peaks.iter().filter(|p| p.rss_mb > p.aim_mb).collect();
    if guard && !over.is_empty() {
        for p in over {
            eprintln!("{}: peak {:.0} MB above the aim {:.0} MB", p.what, p.rss_mb, p.aim_mb);
        }
        std::process::exit(1);
    }
}

fn flag(args: &[String], name: &str) -> Option<f64> {
    let i = args.iter().position(|a| a == name)?;
    args.get(i + 1).and_then(|v| v.parse().ok())
}

/// A bench run of about `mb` MB: 141 bytes a row at 1 ms, so `mb` × 7.1 s of bench time,
/// in five sets (standstill, ramp, loaded cruise ramping up, a load step, part load).
fn make_run(simrod: &Path, dir: &Path, mb: f64) -> PathBuf {
    let total_s = (mb * 1e6 / 141.0 / 1000.0).max(20.0);
    let parts = [0.005, 0.14, 0.28, 0.28, 0.295];
    let sets = [
        "throttle_pct = 0",
        "throttle_pct = 0\nthrottle = \"interp\"",
        "throttle_pct = 60\nload_l_pct = 20\nload_r_pct = 20\nload = \"interp\"",
        "throttle_pct = 60\nload_l_pct = 40\nload_r_pct = 40",
        "throttle_pct = 30",
    ];
    let mut toml = String::from("name = \"memory benchmark\"\n");
    for (share, body) in parts.iter().zip(sets) {
        toml.push_str(&format!("[[set]]\nduration_s = {:.3}\n{body}\n", share * total_s));
    }
    let profile = dir.join("long.toml");
    std::fs::write(&profile, toml).expect("write the profile");
    let out = dir.join("long.csv");
    let o = Command::new(simrod)
        .args(["bench", "--plant", "twin", "--seed", "1", "-q", "--profile-file"])
        .arg(&profile)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("run simrod bench");
    assert!(o.status.success(), "bench: {}", String::from_utf8_lossy(&o.stderr));
    out
}

/// Peak RSS and wall time of `simrod ARGS FILE` under `/usr/bin/time -v`.
fn measure(simrod: &Path, what: &'static str, args: &[&str], file: &Path, aim_mb: f64) -> Peak {
    let start = std::time::Instant::now();
    let o = Command::new("/usr/bin/time")
        .arg("-v")
        .arg(simrod)
        .args(args)
        .arg(file)
        .output()
        .expect("/usr/bin/time (Debian package `time`)");
    let wall_s = start.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{what}: {err}");
    let kb: f64 = err
        .lines()
        .find_map(|l| l.trim().strip_prefix("Maximum resident set size (kbytes):"))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("{what}: no peak in /usr/bin/time's report: {err}"));
    Peak { what, rss_mb: kb * 1024.0 / 1e6, wall_s, aim_mb }
}
