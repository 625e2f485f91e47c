//! `simrod diagnose` end to end: a bench run with a hidden effect in, the effect named
//! in JSON and written to an effect file that makes `simrod compare` agree; runs with
//! nothing to find or too little to fit refused or left unwritten.

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;
use workbench::datadir::ModelData;

fn simrod(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_simrod")).current_dir(dir).args(args).output().expect("run simrod")
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The built-in model data changed by `change`, written to `p/dir` for `--data-dir`: a
/// bench whose physics is not the identified data.
fn bench_data(p: &Path, dir: &str, change: impl FnOnce(&mut ModelData)) {
    let mut d = ModelData::builtin().unwrap();
    change(&mut d);
    d.write(&p.join(dir)).unwrap();
}

fn rmse(dir: &Path, args: &[&str], channel: &str) -> f64 {
    let j: Value = serde_json::from_str(&ok(&simrod(dir, args))).expect("compare JSON");
    j["channels"][channel]["rmse"].as_f64().expect("rmse")
}

/// Left axle friction 30 % above the model's map, on a noisy TP12 run: diagnose must
/// name it with a tight interval, and its effect file must close the gap in compare.
#[test]
fn hidden_axle_friction_is_named_and_its_effect_file_closes_the_gap() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("hidden.toml"), "[axle_friction_scale]\nleft = 1.3\nright = 1.0\n").unwrap();
    ok(&simrod(
        p,
        &["bench", "--profile", "TP12", "--effects", "hidden.toml", "--seed", "3", "-q", "--out", "m.csv"],
    ));

    let out =
        ok(&simrod(p, &["diagnose", "m.csv", "--json", "--write-effects", "found.toml", "--threads", "2"]));
    let j: Value = serde_json::from_str(&out).expect("stdout is JSON");
    assert_eq!(j["kind"], "missing", "{}", j["verdict"]);
    assert!(j["verdict"].as_str().unwrap().contains("axle_friction_scale"), "{}", j["verdict"]);
    let lead = &j["ranking"][0];
    assert_eq!(lead["effect"], "axle_friction_scale");
    let left = lead["params"]["left"].as_f64().unwrap();
    let right = lead["params"]["right"].as_f64().unwrap();
    assert!((left - 1.3).abs() < 0.02, "left {left}");
    assert!((right - 1.0).abs() < 0.02, "right {right}");
    // The run pins the scale down (its statistical σ); the identified data's stated
    // uncertainty is in the σ reported too, as far as the run leaves it: it tells the
    // friction map's shapes apart from the scale (the map's friction is in the SuT
    // power map, the scale's is not, so the currents differ), but not the SuT power
    // map's drive scale, which the scale's response is 91 % of in energy. Without that
    // guard (`systematic::ALIASED`) the share read 0.0015; with the whole stated
    // uncertainty, 0.145.
    let sd = lead["uncertainty"]["left"].as_f64().unwrap();
    let data = lead["uncertainty_data"]["left"].as_f64().unwrap();
    let stat = (sd * sd - data * data).sqrt();
    assert!(stat > 0.0 && stat < 0.01, "statistical std {stat}");
    assert!(data > 0.01 && data < 0.1, "the data's share {data}");
    assert!(lead["error_reduction"].as_f64().unwrap() > 0.9);
    assert_eq!(lead["significant"], true);
    // Every physical effect of the library is ranked; a channel's measurement chain only
    // where that channel's error is above its noise (a sensor cause moves nothing else).
    let ranking = j["ranking"].as_array().unwrap();
    let ranked: Vec<&str> = ranking.iter().map(|c| c["effect"].as_str().unwrap()).collect();
    use model_core::effects::{Cause, EFFECTS};
    for e in EFFECTS.iter().filter(|e| e.in_library() && e.cause == Cause::Whole) {
        assert!(ranked.contains(&e.id), "{} not ranked: {ranked:?}", e.id);
    }
    let chain: Vec<&&str> = ranked.iter().filter(|r| r.contains('.')).collect();
    assert!(chain.iter().any(|r| r.ends_with(".c_kistler_l")), "{ranked:?}");
    assert!(chain.len() < 4 * model_core::MEASURED.len(), "quiet channels' chains are fitted: {ranked:?}");
    for c in ranking {
        for key in ["effect", "params", "uncertainty", "error_reduction"] {
            assert!(!c[key].is_null(), "{key} in {c}");
        }
    }
    assert_eq!(j["effects_written"], "found.toml");

    // The written file loads and, in compare, removes most of the flange-torque error.
    let fx = workbench::effects_file::load_effects(&p.join("found.toml")).expect("loadable effect file");
    assert!((fx.axle_friction_scale[0] - 1.3).abs() < 0.02, "{:?}", fx.axle_friction_scale);
    let before = rmse(p, &["compare", "m.csv", "--json"], "C_Kistler_L");
    let after = rmse(p, &["compare", "m.csv", "--json", "--effects", "found.toml"], "C_Kistler_L");
    assert!(after < 0.5 * before, "C_Kistler_L RMSE {before} -> {after}");

    // The terminal report leads with the verdict and shows the evidence.
    let text = ok(&simrod(p, &["diagnose", "m.csv", "--threads", "2"]));
    let verdict_at = text.find("VERDICT (missing): missing effect: axle_friction_scale").expect(&text);
    let ranking_at = text.find("Ranking").expect(&text);
    assert!(verdict_at < ranking_at, "{text}");
    assert!(text.contains("Per channel with axle_friction_scale"), "{text}");
    assert!(text.contains("diagnose took"), "{text}");
}

/// A noise-free run of the model itself: nothing missing, so nothing is written.
#[test]
fn nothing_missing_writes_nothing() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    ok(&simrod(
        p,
        &["bench", "--plant", "twin", "--profile", "TP12", "--noise", "none", "-q", "--out", "m.csv"],
    ));
    let o = simrod(p, &["diagnose", "m.csv", "--json", "--write-effects", "fx.toml"]);
    let j: Value = serde_json::from_str(&ok(&o)).unwrap();
    assert_eq!(j["kind"], "nothing_missing", "{}", j["verdict"]);
    assert!(j["proposed_effects"].is_null());
    assert!(!p.join("fx.toml").exists());
    assert!(String::from_utf8_lossy(&o.stderr).contains("fx.toml not written: nothing is missing"));
}

#[test]
fn bad_input_exits_2_before_any_work() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    ok(&simrod(
        p,
        &["bench", "--plant", "twin", "--profile", "TP12", "--noise", "none", "-q", "--out", "m.csv"],
    ));
    // Keep time, SuTMotorEnc, C_Kistler_L and the set points: too few channels to fit.
    let text = std::fs::read_to_string(p.join("m.csv")).unwrap();
    let cut: String = text
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let n = f.len();
            [f[0], f[2], f[3], f[n - 3], f[n - 2], f[n - 1]].join(",") + "\n"
        })
        .collect();
    std::fs::write(p.join("few.csv"), cut).unwrap();
    let o = simrod(p, &["diagnose", "few.csv"]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("at least 4") && err.contains("C_Kistler_R") && err.contains("V_DC"), "{err}");

    for args in [
        &["diagnose", "missing.csv"][..],
        &["diagnose", "m.csv", "--write-effects", "no/such/dir/fx.toml"],
        &["diagnose", "m.csv", "--speed-window-s", "-1"],
        &["diagnose", "m.csv", "--threads", "0"],
        &["diagnose", "m.csv", "--effects", "missing.toml"],
        &["diagnose", "m.csv", "--sensor-noise", "missing.toml"],
    ] {
        let o = simrod(p, args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
    }
}

/// A 40 ms lag in one torque amplifier (physics plant, seed kept apart from the ones the
/// structure test was tuned on): a large error at transients on one channel, while the
/// whole run's energy stays near the noise's. Neither command may call it noise: compare
/// flags the channel's windows, diagnose locates it instead of "nothing missing".
#[test]
fn a_local_error_is_never_nothing_missing() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("lag.toml"), "[amplifier_lag]\nc_kistler_l = 0.04\n").unwrap();
    ok(&simrod(
        p,
        &["bench", "--profile", "TP07", "--effects", "lag.toml", "--seed", "21", "-q", "--out", "m.csv"],
    ));
    let c: Value =
        serde_json::from_str(&ok(&simrod(p, &["compare", "m.csv", "--no-history", "--json"]))).unwrap();
    let flagged = c["structure"]["flagged"].as_object().expect("flagged windows");
    assert!(flagged.contains_key("C_Kistler_L"), "{}", c["structure"]);
    assert_eq!(flagged.len(), 1, "only the lagged channel: {}", c["structure"]);
    let j: Value = serde_json::from_str(&ok(&simrod(p, &["diagnose", "m.csv", "--json"]))).unwrap();
    assert_ne!(j["kind"], "nothing_missing", "{}", j["verdict"]);
    assert!(j["verdict"].as_str().unwrap().contains("C_Kistler_L"), "{}", j["verdict"]);
}

/// The bench's supply limiting its current (physics plant only, not in the library):
/// for 27 ms at a time the DC current is 110-160 A off the twin's, 400 σ of its noise.
/// The burst passes the noise's moving average and, counted as noise, made the whole
/// run "noise-like" (I_DC's noise read 2.8 A, not 0.3): diagnose said "nothing missing"
/// with I_DC 8.9x the true model's error. Both commands must now see it.
#[test]
fn a_burst_of_error_is_not_taken_for_noise() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("limit.toml"), "[supply_current_limit]\nlimit_a = 250\ndroop_ohm = 0.04\n")
        .unwrap();
    let a = ["bench", "--profile", "TP07", "--throttle-scale", "0.98", "--load-scale", "-0.75"];
    ok(&simrod(p, &[&a[..], &["--effects", "limit.toml", "--seed", "7", "-q", "--out", "m.csv"]].concat()));
    let supply = ["I_DC", "I_DPU 2.7", "V_DC", "V_DC_busbars"];
    let c: Value =
        serde_json::from_str(&ok(&simrod(p, &["compare", "m.csv", "--no-history", "--json"]))).unwrap();
    let flagged = c["structure"]["flagged"].as_object().expect("flagged windows");
    assert!(supply.iter().any(|ch| flagged.contains_key(*ch)), "{}", c["structure"]);
    let j: Value = serde_json::from_str(&ok(&simrod(p, &["diagnose", "m.csv", "--json"]))).unwrap();
    assert_ne!(j["kind"], "nothing_missing", "{}", j["verdict"]);
    let at = j["unexplained"]["channel"].as_str().unwrap_or("");
    assert!(supply.contains(&at), "located on {at:?}: {}", j["verdict"]);
}

/// Model error faster than the noise estimate's moving average (8 Hz, 0.12 A on I_DC,
/// whose sensor is stated at 0.1 A): estimated from the residual, the noise takes it in
/// and the run is "nothing missing"; with the sensors' noise stated (`--sensor-noise`,
/// the bench's file) compare flags I_DC's fast part and diagnose locates it there. The
/// run without it stays "nothing missing" under the same statement: the statement is
/// the bench's own noise, so it raises no false alarm.
#[test]
fn fast_error_is_not_noise_when_the_noise_is_stated() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let bench = ["bench", "--plant", "twin", "--profile", "TP12", "--seed", "31", "-q", "--out", "m.csv"];
    ok(&simrod(p, &bench));
    let text = std::fs::read_to_string(p.join("m.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let col = header.split(',').position(|h| h.starts_with("I_DC")).unwrap();
    let mut out = vec![header.to_owned()];
    for line in lines {
        let mut f: Vec<String> = line.split(',').map(str::to_owned).collect();
        let t: f64 = f[0].parse().unwrap();
        let v: f64 = f[col].parse().unwrap();
        f[col] = (v + 0.12 * (2.0 * std::f64::consts::PI * 8.0 * t).sin()).to_string();
        out.push(f.join(","));
    }
    std::fs::write(p.join("fast.csv"), out.join("\n") + "\n").unwrap();
    let diagnose = |file: &str, stated: bool| -> Value {
        let mut a = vec!["diagnose", file, "--json"];
        a.extend(if stated { &["--sensor-noise", "default"][..] } else { &[] });
        serde_json::from_str(&ok(&simrod(p, &a))).unwrap()
    };
    assert_eq!(diagnose("fast.csv", false)["kind"], "nothing_missing");
    let j = diagnose("fast.csv", true);
    assert_ne!(j["kind"], "nothing_missing", "{}", j["verdict"]);
    assert_eq!(j["unexplained"]["channel"], "I_DC", "{}", j["verdict"]);
    assert!(j["verdict"].as_str().unwrap().contains("the noise stated for the sensor"), "{}", j["verdict"]);
    assert_eq!(j["setup"]["sensor_noise"], "default");
    let j = diagnose("m.csv", true);
    assert_eq!(j["kind"], "nothing_missing", "{}", j["verdict"]);
    let c: Value = serde_json::from_str(&ok(&simrod(
        p,
        &["compare", "fast.csv", "--no-history", "--json", "--sensor-noise", "default"],
    )))
    .unwrap();
    let flagged = c["structure"]["flagged"].as_object().expect("flagged windows");
    let fast = flagged.get("I_DC").and_then(|w| w.as_array()).expect("I_DC flagged");
    assert!(fast.iter().any(|w| w["fast"] == true), "{}", c["structure"]);
    assert_eq!(flagged.len(), 1, "only I_DC: {}", c["structure"]);
}

/// `csv` with `add` added to column `column` on data rows `rows` (0 = the first sample).
fn add_to_column(csv: &str, column: &str, rows: std::ops::Range<usize>, add: f64) -> String {
    let mut lines = csv.lines();
    let header = lines.next().expect("a header");
    let col = header.split(',').position(|h| h.starts_with(column)).expect("the column");
    let mut out = vec![header.to_owned()];
    for (k, line) in lines.enumerate() {
        let mut f: Vec<String> = line.split(',').map(str::to_owned).collect();
        if rows.contains(&k) {
            f[col] = (f[col].parse::<f64>().expect("a number") + add).to_string();
        }
        out.push(f.join(","));
    }
    assert!(out.len() > rows.end, "the run has {} samples, fewer than {}", out.len() - 1, rows.end);
    out.join("\n") + "\n"
}

/// A 40 A spike of 4 ms on I_DC, between the fit samples (one 60 s run is fitted on every
/// 5th sample): `compare` flags it, on every sample. Diagnose said "nothing missing" (its
/// test ran on the fit samples only), as it did in a campaign where the twin misses the
/// plant's current at one transient (a 7 A spike at 41 s of run 3). It must locate it.
#[test]
fn a_spike_between_the_fit_samples_is_located_as_compare_flags_it() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    ok(&simrod(p, &["bench", "--profile", "TP07", "--seed", "31", "-q", "--out", "m.csv"]));
    let text = std::fs::read_to_string(p.join("m.csv")).unwrap();
    std::fs::write(p.join("s.csv"), add_to_column(&text, "I_DC", 30_001..30_005, 40.0)).unwrap();
    let c: Value =
        serde_json::from_str(&ok(&simrod(p, &["compare", "s.csv", "--no-history", "--json"]))).unwrap();
    let flagged = c["structure"]["flagged"].as_object().expect("flagged windows");
    assert!(flagged.contains_key("I_DC"), "{}", c["structure"]);
    let j: Value = serde_json::from_str(&ok(&simrod(p, &["diagnose", "s.csv", "--json"]))).unwrap();
    assert_eq!(j["kind"], "unexplained", "{}", j["verdict"]);
    assert_eq!(j["unexplained"]["channel"], "I_DC", "{}", j["verdict"]);
    let at = j["unexplained"]["window_s"][0].as_f64().unwrap();
    assert!((28.0..=30.005).contains(&at), "located at {at} s: {}", j["verdict"]);
}

/// A 0.5 A mains line on I_DC in a campaign of TP07 and TP11 (130 s): the fit keeps
/// every 11th sample (91 Hz), where a 50 Hz line cannot be seen, so the line is tested
/// on every sample of each run. Diagnose must locate it on I_DC, not call the run noise
/// or point at another channel.
#[test]
fn a_mains_line_in_a_long_campaign_is_located() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("mains.toml"), "[mains_pickup]\ni_dc = 0.5\n").unwrap();
    for (profile, seed, out) in [("TP07", "61", "a.csv"), ("TP11", "62", "b.csv")] {
        let a =
            ["bench", "--profile", profile, "--effects", "mains.toml", "--seed", seed, "-q", "--out", out];
        ok(&simrod(p, &a));
    }
    let j: Value = serde_json::from_str(&ok(&simrod(p, &["diagnose", "a.csv", "b.csv", "--json"]))).unwrap();
    assert_eq!(j["kind"], "unexplained", "{}", j["verdict"]);
    assert_eq!(j["unexplained"]["channel"], "I_DC", "{}", j["verdict"]);
    assert!(j["verdict"].as_str().unwrap().contains("50.00 Hz line"), "{}", j["verdict"]);
}

/// A campaign is fitted jointly: differential friction hidden in TP14 reversed is
/// confounded there with a current-sensor gain; the run the tool names to separate them
/// (TP07 at 0.79 with motoring loads), added as a second file, resolves that pair and
/// narrows the friction's interval (its statistical part: the twin's step bias and the
/// maps' stated uncertainty stay).
#[test]
fn a_campaign_resolves_what_one_run_confounds() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("fx.toml"), "[differential_friction]\ncoulomb_nm = 3.0\n").unwrap();
    let bench = |args: &[&str], seed: &str, out: &str| {
        let mut a = vec!["bench", "--effects", "fx.toml", "--seed", seed, "-q", "--out", out];
        a.extend_from_slice(args);
        ok(&simrod(p, &a));
    };
    bench(&["--profile", "TP14", "--throttle-scale", "-1", "--load-scale", "0"], "51", "rev.csv");
    bench(&["--profile", "TP07", "--throttle-scale", "0.79", "--load-scale", "-1"], "52", "fwd.csv");
    let diag = |files: &[&str]| -> Value {
        let mut a = vec!["diagnose", "--json"];
        a.extend_from_slice(files);
        serde_json::from_str(&ok(&simrod(p, &a))).unwrap()
    };
    let grouped = |j: &Value, effect: &str| {
        j["confounded"]
            .as_array()
            .is_some_and(|g| g.iter().any(|g| g["effects"].to_string().contains(effect)))
    };
    // The half-width of what data can narrow: the reported σ without the twin's declared
    // step bias (`Fit::step_bias`, added in quadrature), which is the same for one run
    // or two.
    let half_width = |j: &Value| -> f64 {
        let lead = &j["ranking"][0];
        assert_eq!(lead["effect"], "differential_friction", "{}", j["verdict"]);
        let v = lead["params"]["coulomb_nm"].as_f64().unwrap();
        let (_, bias) =
            workbench::diagnose::proof::declared_step_bias("differential_friction", "coulomb_nm", v).unwrap();
        let sd = lead["uncertainty"]["coulomb_nm"].as_f64().unwrap();
        let data = lead["uncertainty_data"]["coulomb_nm"].as_f64().unwrap();
        1.96 * (sd * sd - bias * bias / 3.0 - data * data).sqrt()
    };
    let one = diag(&["rev.csv"]);
    assert_eq!(one["kind"], "missing", "{}", one["verdict"]);
    assert!(grouped(&one, "sensor_gain"), "confounded on one run: {}", one["confounded"]);
    let both = diag(&["rev.csv", "fwd.csv"]);
    assert_eq!(both["kind"], "missing", "{}", both["verdict"]);
    assert!(!grouped(&both, "sensor_gain"), "resolved by the campaign: {}", both["confounded"]);
    assert!(half_width(&both) < 0.7 * half_width(&one), "{} vs {}", half_width(&both), half_width(&one));
}

/// Three effects at once (issue 12's first case, physics plant, a seed of its own):
/// differential friction 3 N m, controller delay 30 ms, a 1.5 N m offset on C_Kistler_R,
/// TP07 at load scale 0.8. Round 1 names the set of the first two, refitted jointly, and
/// the structure they leave on C_Kistler_R; its selection line is that set. Round 2, on
/// top of what round 1 wrote, finds the offset.
#[test]
fn a_set_of_effects_is_named_and_the_rest_located() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let fx = "[differential_friction]\ncoulomb_nm = 3.0\n[controller_delay]\ndelay_s = 0.03\n\
              [sensor_offset]\nc_kistler_r = 1.5\n";
    std::fs::write(p.join("fx.toml"), fx).unwrap();
    let bench = ["bench", "--profile", "TP07", "--load-scale", "0.8", "--effects", "fx.toml", "--seed", "71"];
    ok(&simrod(p, &[&bench[..], &["-q", "--out", "m.csv"]].concat()));
    let one: Value =
        serde_json::from_str(&ok(&simrod(p, &["diagnose", "m.csv", "--json", "--write-effects", "r1.toml"])))
            .unwrap();
    let verdict = one["verdict"].as_str().unwrap();
    assert!(verdict.contains("differential_friction") && verdict.contains("controller_delay"), "{verdict}");
    assert!(verdict.contains("C_Kistler_R"), "the offset's channel is located: {verdict}");
    let selected: Vec<&str> =
        one["selected"].as_array().unwrap().iter().map(|s| s["effect"].as_str().unwrap()).collect();
    assert_eq!(selected, ["differential_friction", "controller_delay"], "{verdict}");
    // What the verdict states of each member is the joint refit: the values r1.toml holds,
    // with intervals that hold the truth. (A member's own refit in the ranking was fitted
    // without the other: there the friction took part of the delay's error.)
    let written: toml::Value = toml::from_str(&std::fs::read_to_string(p.join("r1.toml")).unwrap()).unwrap();
    let stated = one["stated"].as_array().unwrap();
    let names: Vec<&str> = stated.iter().map(|s| s["effect"].as_str().unwrap()).collect();
    assert_eq!(names, selected, "{verdict}");
    for (effect, param, truth) in
        [("differential_friction", "coulomb_nm", 3.0), ("controller_delay", "delay_s", 0.03)]
    {
        let st = stated.iter().find(|s| s["effect"] == effect).unwrap();
        let v = st["params"][param].as_f64().unwrap();
        let file = written[effect][param].as_float().unwrap();
        assert!((v - file).abs() <= 1e-6 * v.abs(), "{effect}.{param}: stated {v}, written {file}");
        let (lo, hi) = (st["ci95"][param][0].as_f64().unwrap(), st["ci95"][param][1].as_f64().unwrap());
        assert!(lo <= truth && truth <= hi, "{effect}.{param}: interval {lo}..{hi} misses {truth}");
    }
    let two: Value =
        serde_json::from_str(&ok(&simrod(p, &["diagnose", "m.csv", "--json", "--effects", "r1.toml"])))
            .unwrap();
    assert_eq!(two["kind"], "missing", "{}", two["verdict"]);
    let lead = &two["ranking"][0];
    assert_eq!(lead["effect"], "sensor_offset.c_kistler_r", "{}", two["verdict"]);
    let (lo, hi) =
        (lead["ci95"]["c_kistler_r"][0].as_f64().unwrap(), lead["ci95"]["c_kistler_r"][1].as_f64().unwrap());
    assert!(lo < 1.5 && 1.5 < hi, "offset interval {lo}..{hi} misses 1.5 N m");
}

/// Diagnose a bench run with the acquisition fault `fault` (the virtual bench's own
/// code, not the twin's chain) hidden on TP07; the JSON.
fn diagnose_fault(fault: &str, seed: &str) -> (Value, tempfile::TempDir) {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("fault.toml"), fault).unwrap();
    let bench =
        ["bench", "--profile", "TP07", "--effects", "fault.toml", "--seed", seed, "-q", "--out", "m.csv"];
    ok(&simrod(p, &bench));
    let out = ok(&simrod(p, &["diagnose", "m.csv", "--json", "--write-effects", "found.toml"]));
    (serde_json::from_str(&out).unwrap(), d)
}

/// The lead of a diagnosis, checked to be a sensor cause on `channel` whose interval
/// holds `truth`.
fn assert_sensor_lead(j: &Value, cause: &str, channel: &str, truth: f64) {
    let verdict = j["verdict"].as_str().unwrap();
    assert_ne!(j["kind"], "nothing_missing", "{verdict}");
    let lead = &j["ranking"][0];
    assert_eq!(lead["effect"], cause, "{verdict}");
    assert_eq!(lead["cause"], "sensor", "{verdict}");
    assert_eq!(lead["moves"], serde_json::json!([channel]), "{verdict}");
    assert!(verdict.contains(&format!("sensor: moves {channel} alone")), "{verdict}");
    let key = cause.split('.').nth(1).unwrap();
    let ci = &lead["ci95"][key];
    let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
    assert!(lo <= truth && truth <= hi, "{cause}: interval {lo}..{hi} misses {truth}");
}

/// Issue 12's amplifier case: C_Kistler_L behind a 40 ms first-order lag. Compare sees
/// large errors at transients; diagnose must not call it "nothing missing" but name
/// the channel's lag, a sensor cause, with the truth in its interval.
#[test]
fn a_lagging_torque_amplifier_is_named_as_a_sensor_cause() {
    let (j, _d) = diagnose_fault("[amplifier_lag]\nc_kistler_l = 0.04\n", "83");
    assert_sensor_lead(&j, "sensor_lag.c_kistler_l", "C_Kistler_L", 0.04);
}

/// Issue 12's DAQ-skew case: SuTMotorEnc recorded 60 ms late. Before, diagnose named
/// `inverter_rate_scale`, which made SiemensEnc and I_DC worse. On TP07 the speed
/// changes slowly, so a 60 ms delay and a 60 ms lag of that one channel look alike
/// (cosine 1.00; no built-in profile tells them apart through the bench's noise). The
/// tool must name a sensor cause on SuTMotorEnc, report the two as confounded, and what
/// it writes must fix that channel without touching the others.
#[test]
fn a_late_channel_is_named_as_its_delay_not_a_physical_effect() {
    let (j, d) = diagnose_fault("[daq_skew]\nsutmotorenc = 0.06\n", "89");
    let verdict = j["verdict"].as_str().unwrap();
    let lead = &j["ranking"][0];
    assert_eq!(lead["cause"], "sensor", "{verdict}");
    assert_eq!(lead["moves"], serde_json::json!(["SuTMotorEnc"]), "{verdict}");
    let effect = lead["effect"].as_str().unwrap();
    if effect != "sensor_delay.sutmotorenc" {
        assert_eq!(effect, "sensor_lag.sutmotorenc", "{verdict}");
        assert!(j["confounded"][0]["effects"].to_string().contains("sensor_delay.sutmotorenc"), "{verdict}");
    }
    let p = d.path();
    let written = std::fs::read_to_string(p.join("found.toml")).unwrap();
    assert!(!written.contains("inverter_rate_scale"), "{written}");
    let err = |channel: &str, fx: Option<&str>| {
        let mut a = vec!["compare", "m.csv", "--json", "--no-history"];
        a.extend(fx.map(|f| ["--effects", f]).into_iter().flatten());
        rmse(p, &a, channel)
    };
    let (before, after) = (err("SuTMotorEnc", None), err("SuTMotorEnc", Some("found.toml")));
    assert!(after < 0.4 * before, "SuTMotorEnc RMSE {before} -> {after}");
    for other in ["SiemensEnc", "I_DC", "T_Kistler_L"] {
        let (b, a) = (err(other, None), err(other, Some("found.toml")));
        assert!(a <= 1.01 * b, "{other} made worse: {b} -> {a}");
    }
}

/// Two acquisition faults at once on a light TP07 (throttle 0.6, loads -0.54): a 45 ms
/// lag on I_DPU 2.7 and SuTMotorEnc recorded 22 ms late. A delay and a lag look alike
/// to first order, and the selection used to name the lag a 29 ms delay, which left
/// I_DPU 2.7 at 1.4x its floor under a noise-like verdict the next round. The set must
/// name the lag with the truth in its interval, and what it writes must bring I_DPU 2.7
/// to within 1.2x the true plant model's error on the file.
#[test]
fn a_lag_beside_a_delay_is_named_as_a_lag_not_the_delay_it_resembles() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(
        p.join("fault.toml"),
        "[amplifier_lag]\ni_dpu_2_7 = 0.045\n[daq_skew]\nsutmotorenc = 0.022\n",
    )
    .unwrap();
    for (noise, out) in [("default", "m.csv"), ("none", "m0.csv")] {
        let scales = ["--throttle-scale", "0.6", "--load-scale", "-0.54", "--seed", "101"];
        let a =
            ["bench", "--profile", "TP07", "--effects", "fault.toml", "--noise", noise, "-q", "--out", out];
        ok(&simrod(p, &[&a[..], &scales[..]].concat()));
    }
    let out = ok(&simrod(p, &["diagnose", "m.csv", "--json", "--write-effects", "found.toml"]));
    let j: Value = serde_json::from_str(&out).unwrap();
    let verdict = j["verdict"].as_str().unwrap();
    let named: Vec<&str> =
        j["selected"].as_array().unwrap().iter().filter_map(|s| s["effect"].as_str()).collect();
    assert!(
        named.contains(&"sensor_lag.i_dpu_2_7") && !named.contains(&"sensor_delay.i_dpu_2_7"),
        "{verdict}"
    );
    let lag =
        j["ranking"].as_array().unwrap().iter().find(|c| c["effect"] == "sensor_lag.i_dpu_2_7").unwrap();
    let ci = &lag["ci95"]["i_dpu_2_7"];
    let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
    assert!(lo <= 0.045 && 0.045 <= hi, "interval {lo}..{hi} misses 0.045 s");
    let floor =
        floors(&p.join("m.csv"), &p.join("m0.csv")).into_iter().find(|(c, _)| c == "I_DPU 2.7").unwrap().1;
    let after =
        rmse(p, &["compare", "m.csv", "--json", "--no-history", "--effects", "found.toml"], "I_DPU 2.7");
    assert!(after <= 1.2 * floor, "I_DPU 2.7 RMSE {after} A against a floor of {floor} A");
}

/// A TP07 run of the bench whose model data is `p/data`: `m.csv` with the default
/// noise, `m0.csv` without (its floor).
fn noisy_and_exact(p: &Path, data: &str, seed: &str) {
    for (noise, out) in [("default", "m.csv"), ("none", "m0.csv")] {
        let a = ["bench", "--profile", "TP07", "--data-dir", data, "--seed", seed, "--noise", noise];
        ok(&simrod(p, &[&a[..], &["-q", "--out", out]].concat()));
    }
}

/// Per channel of `run`: the RMS difference to the noise-free run `exact` of the same
/// bench (the error of the true plant model on the file: the floor).
fn floors(run: &Path, exact: &Path) -> Vec<(String, f64)> {
    use workbench::measure::load;
    let (m, e) = (load(run, None).unwrap(), load(exact, None).unwrap());
    m.signals
        .iter()
        .filter_map(|s| {
            let x = e.signal(&s.name)?;
            let n = s.values.len().min(x.values.len()).max(1);
            let sq: f64 = s.values.iter().zip(&x.values).map(|(a, b)| (a - b) * (a - b)).sum();
            Some((s.name.clone(), (sq / n as f64).sqrt()))
        })
        .collect()
}

/// A TP07 run to fit (`m.csv`) and one it does not see (`h.csv`, 0.9 load scale), each
/// with its noise-free twin (`m0.csv`, `h0.csv`: the floors), on the bench `bench` says
/// (its data flags) with noise seeds `seeds`.
fn fitted_and_unseen(p: &Path, bench: &[&str], seeds: [&str; 2]) {
    let run = |extra: &[&str], out: &str| {
        let a = [&["bench", "--profile", "TP07", "-q", "--out", out], bench, extra].concat();
        ok(&simrod(p, &a));
    };
    run(&["--seed", seeds[0]], "m.csv");
    run(&["--noise", "none"], "m0.csv");
    run(&["--load-scale", "0.9", "--seed", seeds[1]], "h.csv");
    run(&["--load-scale", "0.9", "--noise", "none"], "h0.csv");
}

/// Per channel of `run`: (name, RMSE with the built-in data, RMSE with the `model` flags
/// (`--data-dir`, `--effects`), the floor from the noise-free `exact`), for the channels
/// compare reports.
fn errors_with(p: &Path, (run, exact): (&str, &str), model: &[&str]) -> Vec<(String, f64, f64, f64)> {
    let compare = |args: &[&str]| -> Value {
        let a = [&["compare", run, "--no-history", "--json"], args].concat();
        serde_json::from_str(&ok(&simrod(p, &a))).unwrap()
    };
    let (c0, c1) = (compare(&[]), compare(model));
    let rmse = |c: &Value, ch: &str| c["channels"][ch]["rmse"].as_f64();
    let per = floors(&p.join(run), &p.join(exact)).into_iter();
    per.filter_map(|(ch, floor)| Some((ch.clone(), rmse(&c0, &ch)?, rmse(&c1, &ch)?, floor))).collect()
}

/// The bench's throttle chain gives 0.0506 V per percent, not the identified 0.05: the
/// recorded Throttle and the controller's command are both 1.2 % high. No library effect
/// is that data value; diagnose must claim none and correct the parameter empirically
/// (to the bench's value within 0.3 %, labelled in parameters.toml), and the corrected
/// data must bring Throttle and the SuT speed to the true plant's error on the file.
#[test]
fn a_throttle_chain_off_by_one_percent_is_an_empirical_parameter_correction() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    bench_data(p, "chain", |d| {
        assert!(d.set_param("throttle_volts_per_pct", 0.0506, "[V/%] the bench's chain"));
    });
    noisy_and_exact(p, "chain", "71");
    let j: Value =
        serde_json::from_str(&ok(&simrod(p, &["diagnose", "m.csv", "--json", "--write-data", "fixed"])))
            .unwrap();
    let verdict = j["verdict"].as_str().unwrap();
    assert_ne!(j["kind"], "missing", "{verdict}");
    assert!(j.get("effects_written").is_none(), "{verdict}");
    assert_eq!(j["empirical"]["maps"][0]["file"], "parameters.toml:throttle_volts_per_pct", "{verdict}");
    let fixed = ModelData::load(&p.join("fixed")).unwrap();
    let k = fixed.param("throttle_volts_per_pct").unwrap();
    assert!((k / 0.0506 - 1.0).abs() < 0.003, "corrected to {k}");
    let text = std::fs::read_to_string(p.join("fixed").join("parameters.toml")).unwrap();
    let line = text.lines().find(|l| l.starts_with("throttle_volts_per_pct")).unwrap();
    assert!(line.contains("[V/%]") && line.contains("EMPIRICAL CORRECTION"), "{line}");
    let floor: std::collections::HashMap<String, f64> =
        floors(&p.join("m.csv"), &p.join("m0.csv")).into_iter().collect();
    for ch in ["Throttle", "SuTMotorEnc"] {
        let before = rmse(p, &["compare", "m.csv", "--json", "--no-history"], ch);
        let after = rmse(p, &["compare", "m.csv", "--json", "--no-history", "--data-dir", "fixed"], ch);
        assert!(before > 1.5 * floor[ch], "{ch} is not off before: {before} vs floor {}", floor[ch]);
        assert!(after <= 1.2 * floor[ch], "{ch}: {before} -> {after}, floor {}", floor[ch]);
    }
}

/// A real library effect whose error a wrong map partly cancels (issue 12, items 2 and
/// 5), on the physics plant: the bench's connectors add 0.036 ohm and its inverter draws
/// 4 % less power than the model's map says. The resistance alone makes I_DPU 2.7 worse
/// (the map's error, no longer cancelled, shows), so on its own it is refused; round 1
/// must still name it, beside a correction of the inverter map, and the two together
/// must make no channel worse than 1.10x and cut V_DC's error at least fivefold.
#[test]
fn an_effect_a_wrong_map_hides_is_named_beside_the_maps_correction() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    bench_data(p, "weak", |d| d.sut_power.z.iter_mut().for_each(|z| *z *= 0.96));
    std::fs::write(p.join("hidden.toml"), "[connector_resistance]\nresistance_ohm = 0.036\n").unwrap();
    let a = ["bench", "--profile", "TP12", "--data-dir", "weak", "--effects", "hidden.toml", "--seed", "5"];
    ok(&simrod(p, &[&a[..], &["-q", "--out", "m.csv"]].concat()));
    let diagnose = ["diagnose", "m.csv", "--json", "--write-effects", "fx.toml", "--write-data", "fixed"];
    let j: Value = serde_json::from_str(&ok(&simrod(p, &diagnose))).unwrap();
    let verdict = j["verdict"].as_str().unwrap();
    assert_eq!(j["kind"], "partial", "{verdict}");
    let fx = std::fs::read_to_string(p.join("fx.toml")).unwrap();
    let r: f64 = fx
        .lines()
        .find_map(|l| l.strip_prefix("resistance_ohm = "))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("no connector resistance written: {fx}\n{verdict}"));
    assert!((r / 0.036 - 1.0).abs() < 0.10, "resistance {r} ohm");
    assert_eq!(j["empirical"]["maps"][0]["file"], "sut_inverter_power.csv", "{verdict}");
    let compare = ["compare", "m.csv", "--json", "--no-history"];
    let fixed = [&compare[..], &["--effects", "fx.toml", "--data-dir", "fixed"]].concat();
    let errors = |args: &[&str]| -> Vec<(String, f64)> {
        let c: Value = serde_json::from_str(&ok(&simrod(p, args))).unwrap();
        let chans = c["channels"].as_object().unwrap();
        chans.iter().map(|(k, v)| (k.clone(), v["rmse"].as_f64().unwrap())).collect()
    };
    let (before, after) = (errors(&compare), errors(&fixed));
    assert!(before.iter().any(|(ch, _)| ch == "V_DC"));
    for ((ch, b), (_, a)) in before.iter().zip(&after) {
        assert!(*a <= 1.10 * b, "{ch} made worse: {b} -> {a}");
        if ch == "V_DC" {
            assert!(*a <= b / 5.0, "V_DC: {b} -> {a}");
        }
    }
}

/// A wrong map the library has no effect for (issue 12, item 5), on the physics plant:
/// the bench's left load torque is 8 % stronger wherever it regenerates. Round 1 claims
/// no library effect (the best, a friction scale, removes less than a table of the map
/// does on held-out data), locates the rest (a channel, an operating region, the flange
/// torque it follows) and offers an empirical correction of load_torque_L, labelled
/// as such in the data it writes; following the loop, every channel ends within 1.2x
/// the true plant model's error on the file and on a run the fits never saw (another
/// load scale, other noise), and none is made worse.
#[test]
fn a_wrong_map_gets_a_located_empirical_correction_that_holds_on_unseen_data() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    bench_data(p, "strong", |d| d.load_torque[0].z.iter_mut().filter(|z| **z > 0.0).for_each(|z| *z *= 1.08));
    fitted_and_unseen(p, &["--data-dir", "strong"], ["91", "92"]);

    let mut data: Option<String> = None;
    for round in 1..=4 {
        let out = format!("d{round}");
        let mut a = vec!["diagnose", "m.csv", "--json", "--write-data", &out, "--write-effects", "fx.toml"];
        if let Some(dd) = &data {
            a.extend(["--data-dir", dd.as_str()]);
        }
        let j: Value = serde_json::from_str(&ok(&simrod(p, &a))).unwrap();
        let verdict = j["verdict"].as_str().unwrap().to_owned();
        assert!(j.get("effects_written").is_none(), "round {round} claims a library effect: {verdict}");
        if round == 1 {
            assert_eq!(j["kind"], "unexplained", "{verdict}");
            assert!(verdict.contains("EMPIRICAL") && verdict.contains("not a physical effect"), "{verdict}");
            let maps: Vec<&str> = j["empirical"]["maps"]
                .as_array()
                .unwrap()
                .iter()
                .map(|m| m["file"].as_str().unwrap())
                .collect();
            assert_eq!(maps.first(), Some(&"load_torque_L.csv"), "{verdict}");
            // Located beyond its channel: the residual follows the flange torque, the
            // input of the block whose map is wrong.
            let follows = &j["unexplained"]["follows"];
            let signal = follows[0].as_str().unwrap_or("");
            assert!(signal.starts_with("C_Kistler_"), "follows {follows}: {verdict}");
            assert!(follows[1].as_f64().unwrap().abs() >= 0.5, "follows {follows}");
            assert!(j["unexplained"]["region"][0].is_string(), "{verdict}");
            let text = std::fs::read_to_string(p.join(&out).join("load_torque_L.csv")).unwrap();
            assert!(text.contains("# EMPIRICAL CORRECTION"), "the written map is labelled");
            let untouched = std::fs::read_to_string(p.join(&out).join("load_current_L.csv")).unwrap();
            assert!(!untouched.contains("EMPIRICAL"), "only corrected maps are labelled");
        }
        if j.get("data_written").is_none() {
            assert_eq!(j["kind"], "nothing_missing", "round {round} ends without a correction: {verdict}");
            break;
        }
        data = Some(out);
    }
    let data = data.expect("a correction was written");
    for run in [("m.csv", "m0.csv"), ("h.csv", "h0.csv")] {
        let errors = errors_with(p, run, &["--data-dir", &data]);
        for (ch, e0, e1, floor) in &errors {
            assert!(*e1 <= 1.2 * floor, "{run:?} {ch}: {e1} vs floor {floor} (before {e0})");
            assert!(*e1 <= 1.15 * e0, "{run:?} {ch} made worse: {e0} -> {e1}");
        }
        assert!(errors.len() >= 13, "{run:?}: {} channels compared", errors.len());
    }
}

/// A wrong map beside two library effects, on the physics plant: the bench's forward
/// speed map is 3 % high between 10 and 70 % throttle, with differential friction
/// (3 N m) and a 30 ms controller delay hidden (TP07). A one-channel cause (the SuT
/// inverter's rate scale moves SuTMotorEnc alone) took part of the map's error there
/// and was claimed beside the friction; now the loop writes no effect outside the
/// truth, writes both hidden effects within 15 % of their values and an empirical
/// correction of the speed map beside them, and ends with every channel within 1.2x the
/// true plant model's error on the file.
#[test]
fn a_wrong_map_beside_library_effects_gets_the_effects_and_a_table_and_nothing_else() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    bench_data(p, "fast", |d| {
        for (x, y) in d.speed_fwd.x.iter().zip(d.speed_fwd.y.iter_mut()) {
            if (10.0..=70.0).contains(x) {
                *y *= 1.03;
            }
        }
    });
    std::fs::write(
        p.join("hidden.toml"),
        "[differential_friction]\ncoulomb_nm = 3.0\n[controller_delay]\ndelay_s = 0.03\n",
    )
    .unwrap();
    let bench = |extra: &[&str], out: &str| {
        let mut a =
            vec!["bench", "--profile", "TP07", "--data-dir", "fast", "--effects", "hidden.toml", "-q"];
        a.extend_from_slice(extra);
        a.extend(["--out", out]);
        ok(&simrod(p, &a));
    };
    bench(&["--seed", "91"], "m.csv");
    bench(&["--noise", "none"], "m0.csv");

    let (mut fx, mut data): (Option<String>, Option<String>) = (None, None);
    for round in 1..=5 {
        let (out_fx, out_data) = (format!("r{round}.toml"), format!("d{round}"));
        let mut a =
            vec!["diagnose", "m.csv", "--json", "--write-effects", &out_fx, "--write-data", &out_data];
        if let Some(f) = &fx {
            a.extend(["--effects", f.as_str()]);
        }
        if let Some(dd) = &data {
            a.extend(["--data-dir", dd.as_str()]);
        }
        let j: Value = serde_json::from_str(&ok(&simrod(p, &a))).unwrap();
        let (wrote_fx, wrote_data) = (j.get("effects_written").is_some(), j.get("data_written").is_some());
        if wrote_fx {
            let text = std::fs::read_to_string(p.join(&out_fx)).unwrap();
            let ids: Vec<&str> =
                text.lines().filter_map(|l| l.trim().strip_prefix('[')?.strip_suffix(']')).collect();
            for id in &ids {
                assert!(
                    ["differential_friction", "controller_delay"].contains(id),
                    "round {round} writes {id}: {}",
                    j["verdict"]
                );
            }
            fx = Some(out_fx);
        }
        if wrote_data {
            data = Some(out_data);
        }
        if j["kind"] == "nothing_missing" || !(wrote_fx || wrote_data) {
            break;
        }
    }
    let fx = fx.expect("an effect file was written");
    let found: toml::Value = toml::from_str(&std::fs::read_to_string(p.join(&fx)).unwrap()).unwrap();
    let value = |e: &str, k: &str| found.get(e).and_then(|t| t.get(k)).and_then(|v| v.as_float());
    let coulomb = value("differential_friction", "coulomb_nm").expect("differential friction found");
    let delay = value("controller_delay", "delay_s").expect("controller delay found");
    assert!((coulomb - 3.0).abs() <= 0.45, "coulomb {coulomb} N m");
    assert!((delay - 0.03).abs() <= 0.0045, "delay {delay} s");
    let data = data.expect("an empirical correction was written");
    let speed_map = std::fs::read_to_string(p.join(&data).join("speed_map_fwd.csv")).unwrap();
    assert!(speed_map.contains("# EMPIRICAL CORRECTION"), "the speed map is corrected");
    let compare = |args: &[&str]| -> Value {
        let mut a = vec!["compare", "m.csv", "--no-history", "--json"];
        a.extend_from_slice(args);
        serde_json::from_str(&ok(&simrod(p, &a))).unwrap()
    };
    let c1 = compare(&["--effects", &fx, "--data-dir", &data]);
    let mut checked = 0;
    for (ch, floor) in floors(&p.join("m.csv"), &p.join("m0.csv")) {
        let Some(e1) = c1["channels"][&ch]["rmse"].as_f64() else { continue };
        assert!(e1 <= 1.2 * floor, "{ch}: {e1} vs floor {floor}");
        checked += 1;
    }
    assert!(checked >= 13, "{checked} channels compared");
}

/// A wrong map that a sensor gain mimics (the physics plant's SuT inverter power map 2 %
/// low, TP14 seed 5): a gain of the I_DC sensor removes 99 % of the error on I_DC and
/// was claimed. One shape of the map (a scale of sut_inverter_power.csv, recovered within
/// 0.2 % of the true −2 %) removes as much, so the gain is refused and the map named in
/// the reason. (A lower axle friction then leads, which the map also explains: a
/// physical effect absorbing a map's error is not caught by this test.)
#[test]
fn a_wrong_map_is_not_claimed_as_the_sensor_gain_it_looks_like() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    bench_data(p, "low", |d| d.sut_power.z.iter_mut().for_each(|z| *z *= 0.98));
    ok(&simrod(
        p,
        &["bench", "--profile", "TP14", "--data-dir", "low", "--seed", "5", "-q", "--out", "m.csv"],
    ));
    let diagnose = ["diagnose", "m.csv", "--json", "--write-effects", "fx.toml"];
    let j: Value = serde_json::from_str(&ok(&simrod(p, &diagnose))).unwrap();
    let verdict = j["verdict"].as_str().unwrap();
    let gain = j["ranking"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["effect"] == "sensor_gain.i_dc")
        .unwrap_or_else(|| panic!("no I_DC gain ranked: {verdict}"));
    assert_eq!(gain["significant"], true, "{verdict}");
    assert!(gain["error_reduction"].as_f64().unwrap() > 0.8, "the gain fits: {gain}");
    let a = &gain["map_alias"];
    assert_eq!(a["file"], "sut_inverter_power.csv", "{a}");
    assert_eq!(a["shape"], "scale", "{a}");
    assert!((a["value"].as_f64().unwrap() + 0.02).abs() < 0.002, "{a}");
    assert!(a["share"].as_f64().unwrap() >= 2.0 / 3.0, "{a}");
    let written = std::fs::read_to_string(p.join("fx.toml")).unwrap_or_default();
    assert!(!written.contains("[sensor_gain]"), "a gain is written: {written}\n{verdict}");
}

/// The bench's throttle chain gives 0.0501 V per percent (0.2 % above the identified
/// 0.05) and its forward speed map is 2 % fast. The volts per percent moves the recorded
/// Throttle and the controller's command, the speed map only the command: fitted apart,
/// one absorbs the other's error on the speed (here the speed map took it all and left
/// the volts per percent, and Throttle 1.5x its noise, for a later round to read as a
/// Throttle offset). The chain's tables are fitted together, so the volts per percent
/// must land within 0.05 % of the bench's (the Throttle channel measures it that well),
/// with Throttle at the true plant's error on the file and the SuT speed's error at
/// least halved.
#[test]
fn the_volts_per_percent_is_fitted_with_the_speed_map_it_shares_the_command_with() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    bench_data(p, "chain", |d| {
        assert!(d.set_param("throttle_volts_per_pct", 0.0501, "[V/%] the bench's chain"));
        d.speed_fwd.y.iter_mut().for_each(|y| *y *= 1.02);
    });
    noisy_and_exact(p, "chain", "73");
    let j: Value =
        serde_json::from_str(&ok(&simrod(p, &["diagnose", "m.csv", "--json", "--write-data", "fixed"])))
            .unwrap();
    let verdict = j["verdict"].as_str().unwrap();
    let k = ModelData::load(&p.join("fixed")).unwrap().param("throttle_volts_per_pct").unwrap();
    assert!((k / 0.0501 - 1.0).abs() < 0.0005, "corrected to {k}: {verdict}");
    let floor: std::collections::HashMap<String, f64> =
        floors(&p.join("m.csv"), &p.join("m0.csv")).into_iter().collect();
    let after = |ch| rmse(p, &["compare", "m.csv", "--json", "--no-history", "--data-dir", "fixed"], ch);
    let throttle = after("Throttle");
    assert!(
        throttle <= 1.2 * floor["Throttle"],
        "Throttle {throttle}, floor {}: {verdict}",
        floor["Throttle"]
    );
    let speed =
        (rmse(p, &["compare", "m.csv", "--json", "--no-history"], "SuTMotorEnc"), after("SuTMotorEnc"));
    assert!(speed.1 <= 0.5 * speed.0, "SuTMotorEnc {} -> {}: {verdict}", speed.0, speed.1);
}

/// Left axle friction 35 % strong and a regenerating loss of 0.25 on the physics plant
/// (TP07, as proof case 1,002,539 drew them): round 1 names the friction, which leaves
/// the loss 2.4x the noise, and writes no table on top of it — a load power map fitted
/// there absorbed the loss, which was then never found. Round 2, with the friction in,
/// names the loss.
#[test]
fn a_second_effect_gets_its_round_before_a_table() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(
        p.join("fx.toml"),
        "[axle_friction_scale]\nleft = 1.35\n[regen_efficiency]\nextra_loss = 0.25\n",
    )
    .unwrap();
    let bench =
        ["bench", "--profile", "TP07", "--throttle-scale", "0.65", "--load-scale", "0.5", "--seed", "73"];
    ok(&simrod(p, &[&bench[..], &["--effects", "fx.toml", "-q", "--out", "m.csv"]].concat()));
    let round = |args: &[&str]| -> Value {
        let base = ["diagnose", "m.csv", "--json", "--write-effects"];
        serde_json::from_str(&ok(&simrod(p, &[&base[..], args].concat()))).unwrap()
    };
    let one = round(&["r1.toml", "--write-data", "d1"]);
    assert_eq!(one["ranking"][0]["effect"], "axle_friction_scale", "{}", one["verdict"]);
    assert!(one["empirical"].is_null(), "a table on top of the proposal: {}", one["verdict"]);
    assert!(!p.join("d1").exists(), "no data directory is written");
    let two = round(&["r2.toml", "--effects", "r1.toml"]);
    let lead = &two["ranking"][0];
    assert_eq!(lead["effect"], "regen_efficiency", "{}", two["verdict"]);
    let ci = &lead["ci95"]["extra_loss"];
    let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
    assert!(lo < 0.25 && 0.25 < hi, "loss interval {lo}..{hi} misses 0.25");
}

/// A skew of a fraction of a step: Throttle recorded 2.3 ms late by the physics plant's
/// acquisition (its own interpolation, `plant::sampled::fractional_delay`), TP07 whose
/// throttle steps on whole seconds. Before, the twin's delay came in whole steps and the
/// fit kept every 5th sample, so every step edge fell on one phase: the delay fitted
/// anywhere in 2–5 ms at one energy and a lag was claimed (2.5 ms [1.4, 3.5], a false
/// claim). Now no lag is claimed: the delay fits 2.6 ms, within Throttle's declared step
/// bias (5.0 ms), so it is not named either, and the verdict locates the error on
/// Throttle; a delay stated would have to hold the truth.
#[test]
fn a_skew_of_a_fraction_of_a_step_is_not_claimed_as_a_lag() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("skew.toml"), "[daq_skew]\nthrottle = 0.0023\n").unwrap();
    let bench =
        ["bench", "--profile", "TP07", "--effects", "skew.toml", "--seed", "9071", "-q", "--out", "m.csv"];
    ok(&simrod(p, &bench));
    let args = ["diagnose", "m.csv", "--json", "--sensor-noise", "default"];
    let j: Value = serde_json::from_str(&ok(&simrod(p, &args))).unwrap();
    let verdict = j["verdict"].as_str().unwrap();
    let delay = j["ranking"].as_array().unwrap().iter().find(|c| c["effect"] == "sensor_delay.throttle");
    let fitted = delay.and_then(|c| c["params"]["throttle"].as_f64()).expect("the delay is refitted");
    assert!((fitted - 0.0023).abs() < 0.001, "delay fitted {fitted} s: {verdict}");
    for stated in j["stated"].as_array().unwrap() {
        assert_eq!(stated["effect"], "sensor_delay.throttle", "{verdict}");
        let ci = &stated["ci95"]["throttle"];
        let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
        assert!(lo <= 0.0023 && 0.0023 <= hi, "interval {lo}..{hi} misses 2.3 ms: {verdict}");
    }
    if j["stated"].as_array().unwrap().is_empty() {
        assert_eq!(j["unexplained"]["channel"], "Throttle", "{verdict}");
    }
}

/// A recording delay beside wrong maps (tuning case 500,633: SuTMotorEnc recorded 72 ms
/// late, the maps perturbed, TP14): the delay removes most of its channel's error, but
/// the speed map's error keeps the channel above the noise. A delay acts on transients,
/// which no static map reproduces, so it is named (partly explaining) with the truth in
/// its interval; a gain or offset would have been refused as absorbing part of the
/// channel's error, as the delay was too before.
#[test]
fn a_recording_delay_beside_wrong_maps_is_named() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let bench =
        ["bench", "--scenario", "random", "--seed", "500633", "-q", "--out", "m.csv", "--truth", "t.toml"];
    ok(&simrod(p, &bench));
    let truth: toml::Value = toml::from_str(&std::fs::read_to_string(p.join("t.toml")).unwrap()).unwrap();
    assert!(truth.get("perturb_maps").is_some(), "the maps are perturbed");
    let delay = truth["effect"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["id"].as_str() == Some("sensor_delay"))
        .and_then(|e| e["params"]["sutmotorenc"].as_float())
        .expect("a SuTMotorEnc delay is hidden");
    let j: Value = serde_json::from_str(&ok(&simrod(p, &["diagnose", "m.csv", "--json"]))).unwrap();
    let verdict = j["verdict"].as_str().unwrap();
    assert_eq!(j["kind"], "partial", "{verdict}");
    let stated = &j["stated"][0];
    assert_eq!(stated["effect"], "sensor_delay.sutmotorenc", "{verdict}");
    let ci = &stated["ci95"]["sutmotorenc"];
    let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
    assert!(lo <= delay && delay <= hi, "interval {lo}..{hi} misses {delay} s: {verdict}");
}

/// An effect already in the model is refitted with the next one (the refit of the whole
/// set at each stage). A connector resistance and a 3.2 N m differential friction are
/// hidden in a campaign of two runs; the model already holds the resistance at 0.0379 Ω,
/// what a round fitting it without the friction gave on tuning case 500,616 (truth
/// 0.0354 Ω). Against that biased value the friction made V_DC worse and was refused, and
/// the verdict was "unexplained"; refitted beside it, the friction is named with the
/// truth in its interval, and the resistance is stated and written at its new value.
#[test]
fn an_effect_in_the_model_is_refitted_with_its_partner() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(
        p.join("fx.toml"),
        "[connector_resistance]\nresistance_ohm = 0.0354\n[differential_friction]\ncoulomb_nm = 3.2\n",
    )
    .unwrap();
    std::fs::write(p.join("base.toml"), "[connector_resistance]\nresistance_ohm = 0.0379\n").unwrap();
    for (out, profile, throttle, load, seed) in
        [("a.csv", "TP14", "0.93", "0.61", "72"), ("b.csv", "TP11", "0.64", "0.46", "73")]
    {
        let bench = ["bench", "--profile", profile, "--throttle-scale", throttle, "--load-scale", load];
        ok(&simrod(p, &[&bench[..], &["--effects", "fx.toml", "--seed", seed, "-q", "--out", out]].concat()));
    }
    let diagnose =
        ["diagnose", "a.csv", "b.csv", "--json", "--effects", "base.toml", "--write-effects", "r.toml"];
    let j: Value = serde_json::from_str(&ok(&simrod(p, &diagnose))).unwrap();
    let verdict = j["verdict"].as_str().unwrap();
    assert_eq!(j["kind"], "missing", "{verdict}");
    let written: toml::Value = toml::from_str(&std::fs::read_to_string(p.join("r.toml")).unwrap()).unwrap();
    let stated = j["stated"].as_array().unwrap();
    let names: Vec<&str> = stated.iter().map(|s| s["effect"].as_str().unwrap()).collect();
    assert_eq!(names, ["differential_friction", "connector_resistance"], "{verdict}");
    let lead =
        j["ranking"].as_array().unwrap().iter().find(|c| c["effect"] == "differential_friction").unwrap();
    assert_eq!(lead["held"][0]["effect"], "connector_resistance", "the ranking says what it refitted beside");
    for (st, param, truth) in [(&stated[0], "coulomb_nm", 3.2), (&stated[1], "resistance_ohm", 0.0354)] {
        let effect = st["effect"].as_str().unwrap();
        let v = st["params"][param].as_f64().unwrap();
        let file = written[effect][param].as_float().unwrap();
        assert!((v - file).abs() <= 1e-6 * v.abs(), "{effect}.{param}: stated {v}, written {file}");
        let (lo, hi) = (st["ci95"][param][0].as_f64().unwrap(), st["ci95"][param][1].as_f64().unwrap());
        assert!(
            lo <= truth && truth <= hi,
            "{effect}.{param}: interval {lo}..{hi} misses {truth}: {verdict}"
        );
    }
}

/// The members of the set `--maps-within-uncertainty` refits beside its estimate, in order:
/// `verdict` selects the ordinary verdict's (its first stage) or those credited beyond the
/// estimate.
fn members(j: &Value, verdict: bool) -> Vec<String> {
    let set = j["within_uncertainty"]["set"].as_array().unwrap();
    let mine = set.iter().filter(|c| c["verdict"].as_bool() == Some(verdict));
    mine.map(|c| c["cause"].as_str().unwrap().to_owned()).collect()
}

/// The causes `--maps-within-uncertainty` selects beyond its estimate, in order.
fn credited(j: &Value) -> Vec<String> {
    members(j, false)
}

/// The verdict's members the estimate alone credits with less than the bar: the maps and
/// parameters within their uncertainty take them as well.
fn taken_by_the_maps(j: &Value) -> Vec<String> {
    let w = &j["within_uncertainty"];
    let bar = w["bar"].as_f64().unwrap();
    let alone = |cause: &str| {
        let c = w["credits"].as_array().unwrap().iter().find(|c| c["cause"] == cause)?;
        c["confirmed"].as_f64().or(c["linear"].as_f64())
    };
    members(j, true).into_iter().filter(|c| alone(c).is_some_and(|v| v < bar)).collect()
}

/// `diagnose --maps-within-uncertainty --json --write-estimate est` on a TP07 bench run
/// (`m.csv`, its noise-free twin `m0.csv`) with `effects` (TOML text) hidden beside maps
/// perturbed with seed `seeds[0]`, noise seed `seeds[1]`.
fn beside_perturbed_maps(p: &Path, effects: &str, seeds: [&str; 2]) -> Value {
    std::fs::write(p.join("hidden.toml"), effects).unwrap();
    let a = ["bench", "--profile", "TP07", "--perturb-maps", seeds[0], "--effects", "hidden.toml", "-q"];
    ok(&simrod(p, &[&a[..], &["--seed", seeds[1], "--out", "m.csv"]].concat()));
    ok(&simrod(p, &[&a[..], &["--noise", "none", "--out", "m0.csv"]].concat()));
    let diagnose = ["diagnose", "m.csv", "--json", "--maps-within-uncertainty", "--write-estimate", "est"];
    serde_json::from_str(&ok(&simrod(p, &diagnose))).unwrap()
}

/// A connector resistance twice the identified one (0.039 ohm for 0.0196: 3 σ of its stated
/// uncertainty), the maps as identified (TP07, the physics plant, noise seed 9031 chosen
/// once). The estimate alone takes it into the parameter group (x1.99, inside the wall)
/// and credits nothing beyond; the set beside it starts from the ordinary verdict's, which
/// names it, and keeps it: a member the runs tell from absent, refitted with the maps, its
/// interval holding the truth, written to the estimate's effect file.
#[test]
fn the_estimate_keeps_what_the_verdict_found_on_the_identified_maps() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("hidden.toml"), "[connector_resistance]\nresistance_ohm = 0.039\n").unwrap();
    let bench = ["bench", "--profile", "TP07", "--effects", "hidden.toml", "-q", "--seed", "9031"];
    ok(&simrod(p, &[&bench[..], &["--out", "m.csv"]].concat()));
    let diagnose = ["diagnose", "m.csv", "--json", "--maps-within-uncertainty", "--write-estimate", "est"];
    let j: Value = serde_json::from_str(&ok(&simrod(p, &diagnose))).unwrap();
    let stated: Vec<&str> =
        j["stated"].as_array().unwrap().iter().map(|s| s["effect"].as_str().unwrap()).collect();
    assert_eq!(stated, ["connector_resistance"], "{}", j["verdict"]);
    let member = &j["within_uncertainty"]["set"][0];
    assert_eq!(member["cause"], "connector_resistance", "credited {:?}", credited(&j));
    assert_eq!(member["verdict"], true, "the verdict's member, not a credit beyond the estimate");
    let r = member["params"][0][1].as_f64().unwrap();
    let (lo, hi) = (member["ci95"][0][0].as_f64().unwrap(), member["ci95"][0][1].as_f64().unwrap());
    assert!(lo <= 0.039 && 0.039 <= hi, "interval [{lo}, {hi}] ohm for 0.039 (refitted {r})");
    let written: toml::Value = std::fs::read_to_string(p.join("est/effects.toml")).unwrap().parse().unwrap();
    let in_file = written["connector_resistance"]["resistance_ohm"].as_float().unwrap();
    assert!((in_file - r).abs() <= 1e-6 * r, "written {in_file} ohm, refitted {r}");
}

/// A torque amplifier lagging 40 ms (the bench's acquisition) on a TP14 run, the maps as
/// identified (noise seed 9041, chosen once). The verdict names the lag; the set's refit
/// with the maps estimated beside it needs it less than the material bar (the maps and
/// parameters within their uncertainty take most of its energy over the run), but the
/// model without it leaves C_Kistler_L with structure at the transients: the lag stays,
/// named as kept for that, its interval holding the truth, and the estimate it writes
/// brings C_Kistler_L within 1.2x the true plant model's error on the file.
#[test]
fn a_lag_the_estimated_maps_could_take_is_kept_for_the_structure_it_clears() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("fault.toml"), "[amplifier_lag]\nc_kistler_l = 0.04\n").unwrap();
    let a = ["bench", "--profile", "TP14", "--throttle-scale", "0.99", "--load-scale", "0.88"];
    let a = [&a[..], &["--effects", "fault.toml", "--seed", "9041", "-q"]].concat();
    ok(&simrod(p, &[&a[..], &["--out", "m.csv"]].concat()));
    ok(&simrod(p, &[&a[..], &["--noise", "none", "--out", "m0.csv"]].concat()));
    let diagnose = ["diagnose", "m.csv", "--json", "--maps-within-uncertainty", "--write-estimate", "est"];
    let j: Value = serde_json::from_str(&ok(&simrod(p, &diagnose))).unwrap();
    let w = &j["within_uncertainty"];
    assert_eq!(w["located"], serde_json::json!(["sensor_lag.c_kistler_l"]), "{}", j["verdict"]);
    let member = w["set"].as_array().unwrap().iter().find(|c| c["cause"] == "sensor_lag.c_kistler_l");
    let member = member.unwrap_or_else(|| panic!("set {:?}", credited(&j)));
    let (lo, hi) = (member["ci95"][0][0].as_f64().unwrap(), member["ci95"][0][1].as_f64().unwrap());
    assert!(lo <= 0.04 && 0.04 <= hi, "interval [{lo}, {hi}] s for 0.04");
    let floor =
        floors(&p.join("m.csv"), &p.join("m0.csv")).into_iter().find(|(c, _)| c == "C_Kistler_L").unwrap().1;
    let compare = ["compare", "m.csv", "--json", "--no-history", "--data-dir", "est"];
    let after = rmse(p, &[&compare[..], &["--effects", "est/effects.toml"]].concat(), "C_Kistler_L");
    assert!(after <= 1.2 * floor, "C_Kistler_L RMSE {after} N m against a floor of {floor} N m");
}

/// A torque amplifier lagging 40 ms (the bench's acquisition, not the twin's library)
/// beside maps and parameters perturbed within their uncertainty (seed 9011, TP07): the
/// estimate of the maps takes the maps' error, and what adds beyond it is that channel's
/// chain alone — its lag or delay, no physical cause. Seeds 9011–9012, chosen once.
#[test]
fn a_lag_beside_perturbed_maps_is_credited_beyond_the_maps_uncertainty() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let j = beside_perturbed_maps(p, "[amplifier_lag]\nc_kistler_l = 0.04\n", ["9011", "9012"]);
    let credited = credited(&j);
    let first = credited.first().map(String::as_str);
    assert!(
        matches!(first, Some("sensor_lag.c_kistler_l" | "sensor_delay.c_kistler_l")),
        "credited {credited:?}"
    );
    assert!(credited.iter().all(|c| c.ends_with(".c_kistler_l")), "credited {credited:?}");
    // The verdict read the maps' error as library causes; the estimate keeps them as its
    // first stage and says that the maps within their uncertainty take them as well.
    assert_eq!(taken_by_the_maps(&j), members(&j, true), "the verdict's members");
    // Refitted with the maps from the identified data, the lag comes back within 25 %.
    if first == Some("sensor_lag.c_kistler_l") {
        let set = j["within_uncertainty"]["set"].as_array().unwrap();
        let member = set.iter().find(|c| c["cause"] == "sensor_lag.c_kistler_l").unwrap();
        let lag = member["params"][0][1].as_f64().unwrap();
        assert!((0.03..=0.05).contains(&lag), "refitted lag {lag} s for 0.04 s");
    }
}

/// A 120 ms controller delay beside maps and parameters perturbed within their
/// uncertainty (the physics plant, TP07, seeds 9021–9022 chosen once): the estimate of the
/// maps takes part of the delay, so the delay credited beyond it is refitted with the maps
/// from the identified data. Its value comes back within 25 % of the truth, no inverter
/// rate scale stands beside it for the remainder, and with it the speeds it moves are
/// within 1.2x the noise's RMS.
#[test]
fn a_controller_delay_beside_perturbed_maps_is_refitted_with_them() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let j = beside_perturbed_maps(p, "[controller_delay]\ndelay_s = 0.12\n", ["9021", "9022"]);
    let w = &j["within_uncertainty"];
    let set = [members(&j, true), credited(&j)].concat();
    assert_eq!(set.first().map(String::as_str), Some("controller_delay"), "set {set:?}");
    assert!(!set.iter().any(|c| c == "inverter_rate_scale"), "set {set:?}");
    let delay = w["set"][0]["params"][0][1].as_f64().unwrap();
    assert!((0.09..=0.15).contains(&delay), "refitted delay {delay} s for 0.12 s");
    // The estimate stays within the prior's wall (4 σ; soft: half a σ beyond costs a
    // quarter of the material bar). Without it a load inertia went to 5.6 σ here.
    let (name, far) = (&w["furthest"][0], w["furthest"][1].as_f64().unwrap());
    assert!(far <= 4.5, "{name} at {far} σ");
    // Its 95 % interval, the maps estimated beside it, holds the value and says something.
    let ci = &w["set"][0]["ci95"][0];
    let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
    assert!(lo <= delay && delay <= hi && hi - lo < delay, "interval [{lo}, {hi}] s for {delay} s");
    let names = w["channels"].as_array().unwrap().iter().map(|c| c[0].as_str().unwrap());
    let after = w["after_set"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap());
    for (ch, e) in names.zip(after) {
        if ["SuTMotorEnc", "SiemensEnc"].contains(&ch) {
            assert!(e <= 1.44, "{ch}: {e} of the noise's energy with the delay refitted");
        }
    }
    // What --write-estimate wrote is that refit: its effect file holds the delay at the
    // refitted value, and the twin run by `compare` on the two files brings the speeds
    // the delay moves within 1.2x the true plant model's error.
    let written: toml::Value = std::fs::read_to_string(p.join("est/effects.toml")).unwrap().parse().unwrap();
    let in_file = written["controller_delay"]["delay_s"].as_float().unwrap();
    assert!((in_file - delay).abs() <= 1e-6 * delay, "written delay {in_file} s, refitted {delay} s");
    let a =
        ["compare", "m.csv", "--no-history", "--json", "--data-dir", "est", "--effects", "est/effects.toml"];
    let c: Value = serde_json::from_str(&ok(&simrod(p, &a))).unwrap();
    for (ch, floor) in floors(&p.join("m.csv"), &p.join("m0.csv")) {
        if ["SuTMotorEnc", "SiemensEnc"].contains(&ch.as_str()) {
            let e = c["channels"][&ch]["rmse"].as_f64().unwrap();
            assert!(e <= 1.2 * floor, "{ch}: {e} with the estimate's files, floor {floor}");
        }
    }
}

/// `a.csv` and `b.csv` from the physics plant with `hidden.toml` and the bench options
/// `extra`: each run's profile, throttle and load scales and noise seed.
fn two_runs(p: &Path, extra: &[&str], runs: [(&str, &str, &str, &str); 2]) {
    for ((profile, throttle, load, seed), out) in runs.into_iter().zip(["a.csv", "b.csv"]) {
        let scales = ["--throttle-scale", throttle, "--load-scale", load];
        let a =
            ["bench", "--profile", profile, "--effects", "hidden.toml", "-q", "--seed", seed, "--out", out];
        ok(&simrod(p, &[&a[..], &scales[..], extra].concat()));
    }
}

/// A connector resistance that drifts with its temperature (bench-only physics: the
/// library's resistance is constant) over a campaign of two runs, TP07 and TP11 at
/// different loads (the physics plant, noise seeds 9043–9044 chosen once). The estimate
/// within the maps' uncertainty takes part of the drift into the resistance's group, and
/// what fits run 2's supply voltage makes run 1's worse: the verdict would not propose
/// such a change, so `--write-estimate` writes nothing and says why (proof 28's three
/// dishonest cases went on from estimates like it).
#[test]
fn an_estimate_that_trades_one_runs_error_for_anothers_is_not_written() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let drift = "[connector_resistance_drift]\nk_per_w = 0.08\nalpha_per_k = 0.004\ntime_constant_s = 48.0\n";
    std::fs::write(p.join("hidden.toml"), drift).unwrap();
    two_runs(p, &[], [("TP07", "0.9", "0.84", "9043"), ("TP11", "1", "0.6", "9044")]);
    let a = ["diagnose", "a.csv", "b.csv", "--json", "--maps-within-uncertainty", "--write-estimate", "est"];
    let j: Value = serde_json::from_str(&ok(&simrod(p, &a))).unwrap();
    let refused = j["within_uncertainty"]["refused"].as_str().unwrap_or_default();
    assert!(refused.contains("x worse on run"), "refused: {refused:?}; verdict {}", j["verdict"]);
    assert!(j.get("estimate_written").is_none(), "the estimate was reported written");
    assert!(!p.join("est").exists(), "the estimate was written");
}

/// Nothing hidden, the bench's maps and parameters perturbed within their uncertainty
/// (seed 9112, the first of 9111–9170 whose verdict refuses a candidate as a trade; TP07
/// and TP11, noise seeds 9212 and 9312): its connector resistance is 0.0148 ohm, and
/// the resistance that fits makes I_DPU 2.7 worse on run 1 beside the perturbed maps, so
/// the verdict proposes nothing. Beside the maps estimated within their uncertainty the
/// trade goes: the set starts from that candidate (not as the verdict's member), keeps
/// it with an interval holding the bench's own value (`bench --write-data`), and the
/// estimate is written with it.
#[test]
fn a_candidate_refused_as_a_trade_is_refitted_beside_the_estimated_maps() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("hidden.toml"), "# nothing hidden\n").unwrap();
    let perturbed = ["--perturb-maps", "9112"];
    two_runs(p, &perturbed, [("TP07", "0.9", "0.8", "9212"), ("TP11", "1", "0.6", "9312")]);
    ok(&simrod(
        p,
        &[&["bench", "--profile", "TP07", "-q", "--write-data", "bench", "--out", "z.csv"], &perturbed[..]]
            .concat(),
    ));
    let params: toml::Value =
        std::fs::read_to_string(p.join("bench/parameters.toml")).unwrap().parse().unwrap();
    let truth = params["connector_resistance"].as_float().unwrap();
    let a = ["diagnose", "a.csv", "b.csv", "--json", "--maps-within-uncertainty", "--write-estimate", "est"];
    let j: Value = serde_json::from_str(&ok(&simrod(p, &a))).unwrap();
    let best = &j["ranking"][0];
    let why = best["refused"].as_str().unwrap_or_default();
    assert!(best["effect"] == "connector_resistance" && why.contains("worse on run"), "{}", j["verdict"]);
    assert!(j["stated"].as_array().unwrap().is_empty(), "the verdict proposes nothing: {}", j["verdict"]);
    let member = &j["within_uncertainty"]["set"][0];
    assert_eq!(member["cause"], "connector_resistance", "set {:?}", credited(&j));
    assert_eq!(member["verdict"], false, "refitted as a candidate, not as the verdict's member");
    let r = member["params"][0][1].as_f64().unwrap();
    let (lo, hi) = (member["ci95"][0][0].as_f64().unwrap(), member["ci95"][0][1].as_f64().unwrap());
    assert!(lo <= truth && truth <= hi, "interval [{lo}, {hi}] ohm for the bench's {truth} (refitted {r})");
    assert_eq!(j["estimate_written"], "est", "refused: {}", j["within_uncertainty"]["refused"]);
    let written: toml::Value = std::fs::read_to_string(p.join("est/effects.toml")).unwrap().parse().unwrap();
    let in_file = written["connector_resistance"]["resistance_ohm"].as_float().unwrap();
    assert!((in_file - r).abs() <= 1e-6 * r, "written {in_file} ohm, refitted {r}");
}

/// A V_DC offset that drifts 0.05 V a minute (the acquisition's, not in the library: its
/// offsets are constant) over a campaign of TP11 and TP07 runs (the physics plant, noise
/// seeds 9051–9052 chosen once). Beyond the estimate the nearest constant, a V_DC offset,
/// adds more than the bar (it was credited at 0.031 V before the test below); at the
/// estimated maps its value walks from one fifth of the runs to the next, so it is
/// refused as drifting, not credited, and the report says why.
#[test]
fn a_drifting_offset_is_not_credited_beyond_the_estimate() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("hidden.toml"), "[offset_drift]\nv_dc = 0.05\n").unwrap();
    two_runs(p, &[], [("TP11", "0.93", "0.4", "9051"), ("TP07", "1", "0.8", "9052")]);
    let j: Value = serde_json::from_str(&ok(&simrod(
        p,
        &["diagnose", "a.csv", "b.csv", "--json", "--maps-within-uncertainty"],
    )))
    .unwrap();
    let set = [members(&j, true), credited(&j)].concat();
    assert!(!set.iter().any(|c| c.ends_with(".v_dc")), "set {set:?}");
    let drifting = j["within_uncertainty"]["drifting"].as_array().unwrap();
    let named = drifting.iter().find(|d| d[0].as_str().is_some_and(|c| c.ends_with(".v_dc")));
    let why = named.and_then(|d| d[1].as_str()).unwrap_or_default();
    assert!(why.contains("drifts over the run"), "drifting {drifting:?}");
}

/// The maps and parameters within their stated uncertainty (`--maps-within-uncertainty`):
/// the physics plant on data perturbed as the thesis' σ allow (`--perturb-maps`, nothing
/// else hidden), TP07. The estimate is fitted on one run; the data and effects it writes
/// (the verdict's connector resistance, the perturbed parameter's own value, refitted
/// beside the maps) are checked by `compare` on that run and on a run it did not see (TP07 at 0.9 load scale): the
/// flanges and speeds within 1.2x the true plant model's error on the fitted run, every
/// channel's error down on the unseen one, none made worse than 1.15x on either, the
/// changed tables labelled. Seeds 9001–9003, chosen once, not tuned.
#[test]
fn perturbed_maps_are_estimated_within_their_uncertainty_and_hold_on_an_unseen_run() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    fitted_and_unseen(p, &["--perturb-maps", "9001"], ["9002", "9003"]);
    let a = ["diagnose", "m.csv", "--json", "--maps-within-uncertainty", "--write-estimate", "est"];
    let j: Value = serde_json::from_str(&ok(&simrod(p, &a))).unwrap();
    assert_eq!(j["estimate_written"], "est", "{}", j["verdict"]);
    let channels = j["within_uncertainty"]["channels"].as_array().unwrap();
    let before = |c: &Value| c[1].as_f64().unwrap();
    assert!(channels.iter().any(|c| before(c) > 4.0), "the perturbation shows: {channels:?}");
    let text = std::fs::read_to_string(p.join("est").join("load_torque_L.csv")).unwrap();
    assert!(text.contains("# ESTIMATED within the stated uncertainty"), "the written map is labelled");
    // Nothing else is hidden: no library cause adds the material bar beyond the estimate,
    // and what the verdict read on the identified maps the maps within their uncertainty
    // take as well.
    assert!(credited(&j).is_empty(), "credited beyond the estimate: {:?}", credited(&j));
    assert_eq!(taken_by_the_maps(&j), members(&j, true), "the verdict's members");
    for (run, fitted) in [(("m.csv", "m0.csv"), true), (("h.csv", "h0.csv"), false)] {
        let errors = errors_with(p, run, &["--data-dir", "est", "--effects", "est/effects.toml"]);
        for (ch, e0, e1, floor) in &errors {
            assert!(*e1 <= 1.15 * e0.max(*floor), "{run:?} {ch} made worse: {e0} -> {e1} (floor {floor})");
            let moved = ["C_Kistler_L", "C_Kistler_R", "SiemensEnc", "SuTMotorEnc"].contains(&ch.as_str());
            if fitted && moved {
                assert!(*e1 <= 1.2 * floor, "{run:?} {ch}: {e1} vs floor {floor} (before {e0})");
            }
            if !fitted && *e0 > 1.2 * floor {
                assert!(e1 < e0, "{run:?} {ch}: {e0} -> {e1} (floor {floor})");
            }
        }
        assert!(errors.len() >= 13, "{run:?}: {} channels compared", errors.len());
    }
}
