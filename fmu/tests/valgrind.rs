//! Memcheck on the FMU as an importer runs it: valgrind runs Python, FMPy loads the
//! packaged binary and simulates 0.2 s of TP07 (instantiate, set inputs, 200 steps,
//! get every output, terminate, free); any invalid read or write, use of uninitialised
//! memory, bad free or memory definitely lost is an error and fails the test
//! (`--error-exitcode`).
//!
//! CPython is run with `PYTHONMALLOC=malloc`: its own small-object allocator reads
//! memory valgrind considers uninitialised (by design, see CPython's
//! Misc/README.valgrind), which the system allocator avoids. What CPython and its
//! extension modules still do that memcheck flags is suppressed by
//! `tests/valgrind-python.supp`; every entry there is confined to python3.11, libpython,
//! numpy or the dynamic loader, never to the FMU (`simrod.so`).

mod support;

use std::fmt::Write as _;
use std::process::Command;

use model_core::{Builtin, Profile};

#[test]
fn fmpy_simulation_under_valgrind_reports_no_errors() {
    let dir = support::scratch("valgrind");
    let fmu = support::default_fmu();
    let env = support::py_env();
    let valgrind = Command::new("valgrind").arg("--version").output();
    assert!(
        valgrind.as_ref().is_ok_and(|o| o.status.success()),
        "valgrind is missing: install it (scripts/test-all.sh does: apt-get install valgrind)"
    );

    let profile = Profile::builtin(Builtin::TP07, 1.0, 1.0).unwrap();
    let mut table =
        String::from("time,throttle_set_point,load_L_set_point,load_R_set_point,supply_voltage\n");
    for k in 0..200u64 {
        let sp = profile.at(k * 1000);
        let _ = writeln!(
            table,
            "{},{},{},{},24",
            k as f64 * 0.001,
            sp.throttle_pct,
            sp.load_pct[0],
            sp.load_pct[1]
        );
    }
    let input = dir.join("inputs.csv");
    std::fs::write(&input, table).unwrap();

    let t0 = std::time::Instant::now();
    let o = Command::new("valgrind")
        .arg("--error-exitcode=1")
        // Definite leaks count as errors; the FMU's stack traces stay readable after
        // FMPy unloads the library and deletes its extraction.
        .args(["--leak-check=full", "--show-leak-kinds=definite", "--errors-for-leak-kinds=definite"])
        .arg("--keep-debuginfo=yes")
        .arg(format!("--suppressions={}", support::ws("fmu/tests/valgrind-python.supp").display()))
        .arg(env.join("bin/python"))
        .arg(support::ws("fmu/tests/py/fmpy_run.py"))
        .args([fmu, &input])
        .args(["0.2", "0.001"])
        .arg(dir.join("out"))
        .env("PYTHONMALLOC", "malloc")
        .output()
        .expect("valgrind runs");
    let text = support::text(&o);
    let summary = text.lines().filter(|l| l.contains("ERROR SUMMARY")).collect::<Vec<_>>().join("\n");
    assert!(o.status.success(), "valgrind found errors (exit {:?}):\n{text}", o.status.code());
    assert!(text.contains("fmpy: 201 rows"), "the simulation ran to the end:\n{text}");
    assert!(summary.contains("ERROR SUMMARY: 0 errors"), "{summary}");
    eprintln!("valgrind (memcheck), FMPy on 200 steps: {summary} ({:.0} s)", t0.elapsed().as_secs_f64());
}
