//! `simrod check` end to end: the built binary, its exit codes, its JSON and its HTML
//! page rendered by a headless Chromium.

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

fn limit<'a>(v: &'a Value, id: &str) -> &'a Value {
    v["limits"].as_array().and_then(|a| a.iter().find(|l| l["id"] == id)).unwrap_or_else(|| panic!("no {id}"))
}

/// The built-in limits file's blocks whose id starts with `prefix`: the same values the
/// check uses by default, on their own.
fn builtin_limits(prefix: &str) -> String {
    let text = fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("data/limits.toml")).unwrap();
    let blocks: Vec<String> = text
        .split("[[limit]]")
        .skip(1)
        .filter(|b| b.contains(&format!("id = \"{prefix}")))
        .map(|b| format!("[[limit]]{b}"))
        .collect();
    assert!(!blocks.is_empty(), "no built-in limit {prefix}*");
    blocks.concat()
}

/// A hard load step at full throttle: loads motoring at -100 %, then regenerating at
/// +100 % (set 3 starts at 3.5 s).
const STEP: &str = "name = \"hard load step\"\n\
    [[set]]\nduration_s = 0.5\n\
    [[set]]\nduration_s = 3\nthrottle_pct = 100\nload_l_pct = -100\nload_r_pct = -100\n\
    [[set]]\nduration_s = 1.5\nthrottle_pct = 100\nload_l_pct = 100\nload_r_pct = 100\n\
    [[set]]\nduration_s = 0.5\n";

/// Largest |C_Kistler_L| in a `simrod simulate` CSV, and when.
fn csv_peak(path: &Path, channel: &str) -> (f64, f64) {
    let text = fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let col = lines.next().unwrap().split(',').position(|h| h.starts_with(&format!("{channel} ["))).unwrap();
    lines
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (c[col].parse::<f64>().unwrap().abs(), c[0].parse::<f64>().unwrap())
        })
        .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a })
}

#[test]
fn flange_crossing_is_flagged_and_its_set_point_passes() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    fs::write(dir.join("step.toml"), STEP).unwrap();
    fs::write(dir.join("flange.toml"), builtin_limits("flange_torque_")).unwrap();
    // Worn gears: 4° of backlash at the differential, whose impacts load the flanges.
    fs::write(dir.join("backlash.toml"), "[gear_backlash]\nbacklash_deg = 4\n").unwrap();
    let common = ["check", "--profile-file", "step.toml", "--limits", "flange.toml"];

    let o = simrod(dir, &[&common[..], &["--effects", "backlash.toml", "--json", "cross.json"]].concat());
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("NOT APPROVED: flange_torque_L crossed"), "{}", text(&o));
    let v = json(&dir.join("cross.json"));
    let l = limit(&v, "flange_torque_L");
    let (peak, t) = (l["nominal"]["peak"].as_f64().unwrap(), l["nominal"]["t_s"].as_f64().unwrap());
    assert_eq!(l["verdict"], "crossed");
    assert!(peak > 200.0 && l["nominal"]["margin"].as_f64().unwrap() < 0.0, "{l}");
    assert_eq!(l["nominal"]["phase"], "set 3/4", "the step into regeneration");
    // The same run's raw samples, written by `simulate`: the check's peak is theirs, or
    // above by the flange mode's allowance between samples, and at their time.
    let o = simrod(
        dir,
        &[
            "simulate",
            "--profile-file",
            "step.toml",
            "--effects",
            "backlash.toml",
            "--dt-us",
            "100",
            "-q",
            "--out",
            "s.csv",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let (raw, t_raw) = csv_peak(&dir.join("s.csv"), "C_Kistler_L");
    assert!(peak >= raw && peak <= raw + 1.0, "check {peak} N m vs samples {raw} N m");
    assert!((t - t_raw).abs() <= 1e-4 + 1e-9, "check at {t} s, samples at {t_raw} s");

    // The set point it proposes for both flanges keeps them inside: run the check there.
    let sp = &v["set_point_all"]["load"]["scale"];
    let scale = sp.as_f64().unwrap_or_else(|| panic!("no load scale proposed: {v}"));
    assert!(scale > 0.0 && scale < 1.0, "{scale}");
    let s = format!("{scale}");
    let o = simrod(dir, &[&common[..], &["--effects", "backlash.toml", "--load-scale", &s]].concat());
    assert_eq!(o.status.code(), Some(0), "at load x{s}: {}", text(&o));

    // Without the backlash the same step stays inside: approved.
    let o = simrod(dir, &[&common[..], &["--json", "pass.json"]].concat());
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(text(&o).contains("APPROVED: all 2 limits inside"), "{}", text(&o));
    let v = json(&dir.join("pass.json"));
    let peak = limit(&v, "flange_torque_R")["nominal"]["peak"].as_f64().unwrap();
    assert!(peak > 100.0 && peak < 200.0, "{peak}");
}

#[test]
fn bad_limits_and_flags_are_exit_2_naming_file_line_and_key() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let bad = "[[limit]]\nid = \"x\"\nquantity = \"C_Kistler\"\nunit = \"N m\"\nmax = 200\norigin = \"o\"\n";
    fs::write(dir.join("bad.toml"), bad).unwrap();
    let o = simrod(dir, &["check", "--profile", "TP12", "--limits", "bad.toml"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("bad.toml:3:12: limit `x`: quantity: unknown `C_Kistler`"), "{}", text(&o));
    fs::write(
        dir.join("bad.toml"),
        bad.replace("C_Kistler\"", "C_Kistler_L\"").replace("max = 200", "max = 2e"),
    )
    .unwrap();
    let o = simrod(dir, &["check", "--profile", "TP12", "--limits", "bad.toml"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("bad.toml:5:"), "{}", text(&o));
    // The flange limits need the 2 kHz mode resolved.
    let o = simrod(dir, &["check", "--profile", "TP12", "--dt-us", "1000"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("--dt-us 126 or less"), "{}", text(&o));
    // An uncertainty file with a key the model does not have.
    fs::write(dir.join("u.toml"), "[params.coupling_stiffnes]\nnormal = { sd = 1 }\n").unwrap();
    let o = simrod(dir, &["check", "--profile", "TP12", "--uncertainty", "u.toml"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("u.toml:1:9: [params.coupling_stiffnes]"), "{}", text(&o));
    // No output replaces an input.
    let o = simrod(dir, &["check", "--profile", "TP12", "--limits", "bad.toml", "--json", "bad.toml"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert_eq!(fs::read_to_string(dir.join("bad.toml")).unwrap().lines().count(), 6);
    // An output into a directory that does not exist: refused before any run.
    let o = simrod(dir, &["check", "--profile", "TP12", "--html", "nodir/p.html"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("--html nodir/p.html: directory nodir does not exist"), "{}", text(&o));
}

/// A short profile and a small uncertainty for the Monte Carlo tests.
fn mc_setup(dir: &Path) {
    fs::write(
        dir.join("short.toml"),
        "[[set]]\nduration_s = 0.3\n[[set]]\nduration_s = 1.2\nthrottle_pct = 80\nload_l_pct = 40\nload_r_pct = 40\n",
    )
    .unwrap();
    fs::write(
        dir.join("u.toml"),
        "[params.coupling_stiffness_identified]\nnormal = { sd = 1149 }\n[params.load_inertia_l]\n\
         uniform = { min = 0.40, max = 0.50 }\n[effects.axle_friction_scale.left]\nnormal = { sd = 0.09 }\n",
    )
    .unwrap();
}

/// The JSON without what may differ between equal runs (wall times, thread count).
fn deterministic(path: &Path) -> Value {
    let mut v = json(path);
    let m = v.as_object_mut().unwrap();
    m.remove("timing_s");
    m.remove("threads");
    v
}

#[test]
fn monte_carlo_is_reproducible_by_seed_on_any_number_of_threads() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    mc_setup(dir);
    let run = |seed: &str, threads: &str, out: &str| {
        let args = [
            "check",
            "--profile-file",
            "short.toml",
            "--uncertainty",
            "u.toml",
            "--samples",
            "24",
            "--seed",
            seed,
            "--threads",
            threads,
            "--no-set-points",
            "-q",
            "--json",
            out,
        ];
        let o = simrod(dir, &args);
        assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
        deterministic(&dir.join(out))
    };
    let one = run("7", "1", "a.json");
    let two = run("7", "2", "b.json");
    assert_eq!(one, two, "one and two threads differ");
    assert_eq!(one["monte_carlo"]["samples"], 24);
    let other = run("8", "2", "c.json");
    assert_ne!(one["limits"], other["limits"], "another seed draws other models");
    // Every sample ran: the counts are out of 24, and the worst sample is one of them.
    for l in one["limits"].as_array().unwrap() {
        assert_eq!(l["monte_carlo"]["samples"], 24);
        let w = l["monte_carlo"]["worst"]["sample"].as_u64().unwrap();
        assert!((1..=24).contains(&w), "{l}");
    }
}

/// Standard normal upper tail at 1: 1 − Φ(1) (Abramowitz & Stegun table 26.1).
const TAIL_AT_1_SIGMA: f64 = 0.158_655_253_931_457;

#[test]
fn violation_probability_matches_a_known_quantile() {
    // Throttle [V] = set point x throttle_volts_per_pct, exactly (below the 5 V clamp).
    // With the gain ~ N(0.05, 0.0025) V/% and 80 % held, a 4.2 V limit sits one standard
    // deviation above the nominal 4.0 V: P(violation) = 1 − Φ(1).
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    fs::write(dir.join("p.toml"), "[[set]]\nduration_s = 0.2\nthrottle_pct = 80\n").unwrap();
    fs::write(dir.join("u.toml"), "[params.throttle_volts_per_pct]\nnormal = { mean = 0.05, sd = 0.0025 }\n")
        .unwrap();
    fs::write(
        dir.join("l.toml"),
        "[[limit]]\nid = \"throttle_v\"\nquantity = \"Throttle\"\nunit = \"V\"\nmax = 4.2\norigin = \"test\"\n",
    )
    .unwrap();
    let n = 600u64;
    let o = simrod(
        dir,
        &[
            "check",
            "--profile-file",
            "p.toml",
            "--limits",
            "l.toml",
            "--uncertainty",
            "u.toml",
            "--samples",
            &n.to_string(),
            "--seed",
            "3",
            "--confidence",
            "0.99",
            "--no-set-points",
            "-q",
            "--json",
            "p.json",
        ],
    );
    assert_eq!(o.status.code(), Some(1), "a 16 % chance is not safe: {}", text(&o));
    let v = json(&dir.join("p.json"));
    let mc = &limit(&v, "throttle_v")["monte_carlo"];
    let p = mc["p"].as_f64().unwrap();
    let (lo, hi) = (mc["interval"][0].as_f64().unwrap(), mc["interval"][1].as_f64().unwrap());
    let sigma = (TAIL_AT_1_SIGMA * (1.0 - TAIL_AT_1_SIGMA) / n as f64).sqrt();
    assert!((p - TAIL_AT_1_SIGMA).abs() <= 3.0 * sigma, "estimate {p} vs {TAIL_AT_1_SIGMA} (σ {sigma})");
    assert!(lo <= TAIL_AT_1_SIGMA && TAIL_AT_1_SIGMA <= hi, "[{lo}, {hi}] misses {TAIL_AT_1_SIGMA}");
    assert_eq!(limit(&v, "throttle_v")["verdict"], "likely_crossed");
    // The worst sample is the largest gain drawn: its peak is 80 x that gain.
    assert!(mc["worst"]["peak"].as_f64().unwrap() > 4.2);
}

#[test]
fn from_identify_and_from_diagnose_draw_their_intervals() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    mc_setup(dir);
    // A campaign for `identify resistance`, then its uncertainty.toml.
    for (ls, seed, out) in [("0", "1", "r1.csv"), ("1", "2", "r2.csv")] {
        let o = simrod(
            dir,
            &[
                "bench",
                "--profile",
                "TP11",
                "--throttle-scale",
                "1",
                "--load-scale",
                ls,
                "--seed",
                seed,
                "--out",
                out,
            ],
        );
        assert!(o.status.success(), "{}", text(&o));
    }
    let o = simrod(dir, &["identify", "resistance", "r1.csv", "r2.csv", "--out", "ident", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    let u = fs::read_to_string(dir.join("ident/uncertainty.toml")).unwrap();
    assert!(u.contains("[params.connector_resistance]\nnormal = { mean = "), "{u}");
    let o = simrod(
        dir,
        &[
            "check",
            "--profile-file",
            "short.toml",
            "--data-dir",
            "ident",
            "--from-identify",
            "ident",
            "--samples",
            "8",
            "--no-set-points",
            "-q",
            "--json",
            "i.json",
        ],
    );
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
    let v = json(&dir.join("i.json"));
    let dists = v["monte_carlo"]["distributions"].to_string();
    assert!(dists.contains("connector_resistance ~ N("), "{dists}");

    // A diagnosis of a run with friction the model lacks, and its intervals.
    fs::write(dir.join("hidden.toml"), "[differential_friction]\ncoulomb_nm = 4\n").unwrap();
    let o = simrod(
        dir,
        &["bench", "--profile", "TP07", "--effects", "hidden.toml", "--seed", "1", "--out", "run.csv"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let o = simrod(dir, &["diagnose", "run.csv", "--json", "--write-effects", "found.toml"]);
    assert!(o.status.success(), "{}", text(&o));
    fs::write(dir.join("d.json"), &o.stdout).unwrap();
    let o = simrod(
        dir,
        &[
            "check",
            "--profile-file",
            "short.toml",
            "--effects",
            "found.toml",
            "--from-diagnose",
            "d.json",
            "--samples",
            "8",
            "--no-set-points",
            "-q",
            "--json",
            "dg.json",
        ],
    );
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
    let v = json(&dir.join("dg.json"));
    let dists = v["monte_carlo"]["distributions"].to_string();
    assert!(dists.contains("differential_friction.coulomb_nm ~ N("), "{dists}");
}

/// Chromium, as installed by scripts/test-all.sh (Debian's `chromium` package).
const CHROMIUM: &str = "/usr/bin/chromium";

/// A page that loads the report in a frame and writes, per SVG, its label, rendered
/// size and its title's rendered width; and any script error.
const PROBE: &str = r#"<!DOCTYPE html><html><body><pre id="out">not measured</pre><pre id="errors"></pre>
<script>
window.onerror = function (m) { document.getElementById('errors').textContent += 'error: ' + m + '\n'; };
function measure(f) {
  var doc = f.contentDocument, rows = [];
  if (!doc) { document.getElementById('errors').textContent += 'error: no access to the report\n'; return; }
  doc.querySelectorAll('svg').forEach(function (s) {
    var label = s.getAttribute('aria-label');
    var t = Array.from(s.querySelectorAll('text')).find(function (x) { return x.textContent === label; });
    var b = s.getBoundingClientRect(), w = t ? t.getBBox().width : 0;
    rows.push(label + '|' + Math.round(b.width) + '|' + Math.round(b.height) + '|' + Math.round(w));
  });
  document.getElementById('out').textContent = rows.join('\n');
}
</script>
<iframe src="report.html" width="1000" height="900" onload="measure(this)"></iframe></body></html>"#;

#[test]
fn html_page_renders_every_limits_margin_chart_in_chromium() {
    assert!(
        Path::new(CHROMIUM).is_file(),
        "{CHROMIUM} is missing: this test renders the check's HTML page in headless Chromium; install Debian's \
         `chromium` package (scripts/test-all.sh does: apt-get install chromium)"
    );
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    mc_setup(dir);
    let o = simrod(
        dir,
        &[
            "check",
            "--profile-file",
            "short.toml",
            "--uncertainty",
            "u.toml",
            "--samples",
            "6",
            "--no-set-points",
            "-q",
            "--html",
            "report.html",
            "--json",
            "r.json",
        ],
    );
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
    let page = fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(!page.contains("<script"), "the report is script-free");
    fs::write(dir.join("probe.html"), PROBE).unwrap();
    let profile = dir.join("chromium-profile");
    let out = Command::new(CHROMIUM)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--allow-file-access-from-files",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", dir.join("probe.html").display()))
        .output()
        .expect("run chromium");
    assert!(out.status.success(), "chromium failed: {}", String::from_utf8_lossy(&out.stderr));
    let dom = String::from_utf8_lossy(&out.stdout);
    let between =
        |a: &str, b: &str| dom.split(a).nth(1).and_then(|s| s.split(b).next()).unwrap_or("").to_string();
    let measured = between("<pre id=\"out\">", "</pre>");
    let errors = between("<pre id=\"errors\">", "</pre>");
    assert!(errors.trim().is_empty(), "script errors: {errors}");
    let v = json(&dir.join("r.json"));
    let limits = v["limits"].as_array().unwrap();
    assert!(limits.len() >= 15);
    for l in limits {
        let title = format!("{}: margin to", l["name"].as_str().unwrap());
        let row = measured
            .lines()
            .find(|r| r.starts_with(&title.replace('&', "&amp;")))
            .unwrap_or_else(|| panic!("no rendered chart '{title}…' in:\n{measured}"));
        let f: Vec<f64> = row.rsplitn(4, '|').take(3).map(|x| x.parse().unwrap()).collect();
        // [title width, height, width]: laid out at full size, its title drawn in a font.
        assert!(f[2] >= 800.0 && f[1] >= 150.0 && f[0] > 100.0, "{row}");
    }
}
