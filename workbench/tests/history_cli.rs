//! The compare history end to end: one valid line per `simrod compare`, a torn last
//! line survived, `simrod history` listing the iterations in order (table, JSON, plot),
//! and the report's before/after overlay and history section.

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

fn lines(p: &Path) -> Vec<String> {
    std::fs::read_to_string(p).unwrap().lines().map(str::to_string).collect()
}

#[test]
fn every_compare_appends_one_record_and_history_lists_them_in_order() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("fx.toml"), "[sensor_offset]\nc_kistler_l = 2.0\n").unwrap();
    ok(&simrod(
        p,
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
    let hist = p.join("m.simrod-history.jsonl");

    // Iteration 1: the model as it is. Iteration 2: with the effect, and a report.
    let o = simrod(p, &["compare", "m.csv"]);
    ok(&o);
    assert!(String::from_utf8_lossy(&o.stderr).contains("history: m.simrod-history.jsonl"));
    assert_eq!(lines(&hist).len(), 1);
    ok(&simrod(p, &["compare", "m.csv", "--effects", "fx.toml", "--report", "rep"]));
    let recs = lines(&hist);
    assert_eq!(recs.len(), 2);
    let sha = workbench::sha256::hex_digest(&std::fs::read(p.join("m.csv")).unwrap());
    for (i, l) in recs.iter().enumerate() {
        let j: Value = serde_json::from_str(l).unwrap_or_else(|e| panic!("line {}: {e}", i + 1));
        assert_eq!(j["simrod_history"], 1);
        assert_eq!(j["options"]["speed_window_s"], 0.1, "the sensor model is part of the record");
        assert_eq!(j["measurement"]["sha256"], sha.as_str());
        assert!(j["timestamp"].as_str().unwrap().ends_with('Z'));
        let kl = j["channels"].as_array().unwrap().iter().find(|c| c["name"] == "C_Kistler_L").unwrap();
        assert!(kl["rmse"].is_f64() && kl["nrmse"].is_f64());
    }
    let second: Value = serde_json::from_str(&recs[1]).unwrap();
    assert!(second["effects"]["toml"].as_str().unwrap().contains("[sensor_offset]"));
    assert_eq!(second["effects"]["file"]["path"], "fx.toml");

    // The report of iteration 2 draws iteration 1's twin as "before".
    let html = std::fs::read_to_string(p.join("rep/index.html")).unwrap();
    assert!(html.contains("Before / after") && html.contains("C_Kistler_L: measured, before, after"));
    assert!(!html.contains("I_DC: measured, before, after"), "I_DC did not change");
    assert!(html.contains("id=\"history\"") && html.contains("NRMSE per iteration"));

    // --no-history leaves the file alone.
    ok(&simrod(p, &["compare", "m.csv", "--no-history"]));
    assert_eq!(lines(&hist).len(), 2);

    // A crash halfway through a record: readers skip it, the next record is intact.
    let torn = &recs[0][..recs[0].len() / 2];
    let mut f = std::fs::OpenOptions::new().append(true).open(&hist).unwrap();
    std::io::Write::write_all(&mut f, torn.as_bytes()).unwrap();
    drop(f);
    let o = simrod(p, &["history", "m.csv", "--json"]);
    let j: Value = serde_json::from_str(&ok(&o)).unwrap();
    assert_eq!(j["iterations"].as_array().unwrap().len(), 2);
    assert!(String::from_utf8_lossy(&o.stderr).contains("incomplete last line"));

    ok(&simrod(p, &["compare", "m.csv", "--effects", "fx.toml"]));
    let recs = lines(&hist);
    assert_eq!(recs.len(), 4, "the torn fragment stays on its own line");
    assert!(serde_json::from_str::<Value>(&recs[3]).is_ok());

    let o = simrod(p, &["history", "m.csv", "--json"]);
    let j: Value = serde_json::from_str(&ok(&o)).unwrap();
    let its = j["iterations"].as_array().unwrap();
    let summaries: Vec<&str> = its.iter().map(|e| e["effects"]["summary"].as_str().unwrap()).collect();
    assert_eq!(summaries.len(), 3);
    assert_eq!(summaries[0], "none");
    assert!(summaries[1].starts_with("sensor_offset(c_kistler_l=2") && summaries[2] == summaries[1]);
    let kl = |e: &Value| {
        e["channels"].as_array().unwrap().iter().find(|c| c["name"] == "C_Kistler_L").unwrap()["rmse"]
            .as_f64()
            .unwrap()
    };
    assert!(kl(&its[0]) > 1.9 && kl(&its[1]) == 0.0, "{} {}", kl(&its[0]), kl(&its[1]));
    assert!(String::from_utf8_lossy(&o.stderr).contains(":3: not a history record"));

    // The table: one row per iteration in order, and the change from first to last.
    let table = ok(&simrod(p, &["history", "m.csv", "--plot", "h.svg"]));
    let rows: Vec<&str> = table.lines().filter(|l| l.trim_start().starts_with(char::is_numeric)).collect();
    assert_eq!(rows.len(), 4, "{table}"); // three iterations and the 1→3 change
    assert!(rows[0].trim_end().ends_with("none") && rows[1].contains("sensor_offset"), "{table}");
    assert!(rows[3].starts_with("1→3") && rows[3].contains("-100 %"), "{table}");
    let svg = std::fs::read_to_string(p.join("h.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains(">C_Kistler_L<"));
}

#[test]
fn history_of_an_unrecorded_measurement_is_a_usage_error() {
    let d = tempfile::tempdir().unwrap();
    let o = simrod(d.path(), &["history", "never.csv"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("simrod compare never.csv"));
}
