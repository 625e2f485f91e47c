//! `simrod simulate` end to end: the built binary, its CSV, its errors.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use model_core::{
    Builtin, Channel, Config, CouplingStiffness, Effects, Params, Profile, ProfileSet, RateSet, SetMode,
    Simulation, SpeedTarget,
};

fn simrod(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_simrod")).current_dir(dir).args(args).output().expect("run simrod")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Files in `dir`, sorted: to check that no temporary file was left behind.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

struct Csv {
    header: Vec<String>,
    times: Vec<String>,
    rows: Vec<Vec<f32>>,
}

fn read_csv(path: &Path) -> Csv {
    let text = fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let mut times = Vec::new();
    let mut rows = Vec::new();
    for line in lines {
        let mut cols = line.split(',');
        times.push(cols.next().unwrap().to_string());
        rows.push(cols.map(|c| c.parse::<f32>().unwrap()).collect());
    }
    Csv { header, times, rows }
}

/// The CSV holds exactly what `Simulation` produces, bit for bit, with exact times.
fn assert_matches_model(csv: &Csv, sim: Simulation<'_>) {
    let expected: Vec<_> = sim.collect();
    assert_eq!(csv.rows.len(), expected.len());
    for (i, ((t, row), o)) in csv.times.iter().zip(&csv.rows).zip(&expected).enumerate() {
        assert_eq!(*t, format!("{}.{:06}", o.t_us / 1_000_000, o.t_us % 1_000_000), "row {i}");
        assert_eq!(row.len(), o.values.len(), "row {i}");
        for (c, (got, want)) in Channel::ALL.iter().zip(row.iter().zip(&o.values)) {
            assert_eq!(got.to_bits(), want.to_bits(), "row {i}, {}: {got} vs {want}", c.name());
        }
    }
}

#[test]
fn tp12_csv_has_every_channel_and_matches_the_model_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let o = simrod(dir.path(), &["simulate", "--profile", "TP12", "--out", "run.csv", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o), "", "--quiet prints nothing");
    assert_eq!(listing(dir.path()), ["run.csv"], "no temporary file left");

    let csv = read_csv(&dir.path().join("run.csv"));
    let mut want_header = vec!["time [s]".to_string()];
    want_header.extend(Channel::ALL.iter().map(|c| format!("{} [{}]", c.name(), c.unit())));
    assert_eq!(csv.header, want_header);
    assert!(csv.header.contains(&"C_Kistler_L [N m]".to_string()));
    assert!(csv.header.contains(&"I_DPU 2.7 [A]".to_string()));

    let profile = Profile::builtin(Builtin::TP12, 1.0, 1.0).unwrap();
    assert_eq!(csv.rows.len() as u64, profile.duration_us() / 1000);
    assert_eq!(csv.times.last().map(String::as_str), Some("26.000000"));
    let sim = Simulation::new(&Config::default(), profile, 24.0).unwrap();
    assert_matches_model(&csv, sim);
}

#[test]
fn every_option_reaches_the_model() {
    let dir = tempfile::tempdir().unwrap();
    fs::write(
        dir.path().join("fx.toml"),
        "[controller_delay]\ndelay_s = 0.02\n\n[supply_resistance]\nresistance_ohm = 0.05\n",
    )
    .unwrap();
    let o = simrod(
        dir.path(),
        &[
            "simulate",
            "--profile",
            "tp13",
            "--throttle-scale",
            "-0.8",
            "--load-scale",
            "0.5",
            "--params",
            "programmed",
            "--speed-target",
            "parameter",
            "--coupling",
            "datasheet",
            "--dt-us",
            "500",
            "--supply-v",
            "20",
            "--effects",
            "fx.toml",
            "-o",
            "run.csv",
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let mut effects = Effects::NONE;
    effects.controller_delay_s = 0.02;
    effects.supply_resistance = 0.05;
    let cfg = Config {
        dt_us: 500,
        params: Params::thesis(RateSet::Programmed, CouplingStiffness::Datasheet),
        speed_target: SpeedTarget::Parameter,
        effects,
    };
    let profile = Profile::builtin(Builtin::TP13, -0.8, 0.5).unwrap();
    let csv = read_csv(&dir.path().join("run.csv"));
    assert_eq!(csv.rows.len() as u64, profile.duration_us() / 500);
    assert_matches_model(&csv, Simulation::new(&cfg, profile, 20.0).unwrap());
}

#[test]
fn profile_file_runs_its_sets_with_its_scales_and_cli_overrides() {
    let dir = tempfile::tempdir().unwrap();
    fs::write(
        dir.path().join("p.toml"),
        "name = \"short\"\nthrottle_scale = 0.5\nload_scale = 1.2\n\n\
         [[set]]\nduration_s = 1\nthrottle_pct = 40\nthrottle = \"interp\"\n\n\
         [[set]]\nduration_s = 2.5\nthrottle_pct = 80\nload_l_pct = 30\nload_r_pct = -10\nload = \"interp\"\n",
    )
    .unwrap();
    let sets = [
        ProfileSet {
            duration_s: 1.0,
            throttle_pct: 40.0,
            load_l_pct: 0.0,
            load_r_pct: 0.0,
            throttle_mode: SetMode::Interpolate,
            load_mode: SetMode::Hold,
        },
        ProfileSet {
            duration_s: 2.5,
            throttle_pct: 80.0,
            load_l_pct: 30.0,
            load_r_pct: -10.0,
            throttle_mode: SetMode::Hold,
            load_mode: SetMode::Interpolate,
        },
    ];
    // The file's scales...
    let o = simrod(dir.path(), &["simulate", "--profile-file", "p.toml", "--out", "a.csv"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).starts_with("short: throttle x0.5, load x1.2"), "{}", stdout(&o));
    let sim = Simulation::new(&Config::default(), Profile::new(&sets, 0.5, 1.2).unwrap(), 24.0);
    assert_matches_model(&read_csv(&dir.path().join("a.csv")), sim.unwrap());
    // ...and the command line's over them.
    let o = simrod(
        dir.path(),
        &["simulate", "--profile-file", "p.toml", "--throttle-scale", "1", "--out", "b.csv", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let sim = Simulation::new(&Config::default(), Profile::new(&sets, 1.0, 1.2).unwrap(), 24.0);
    assert_matches_model(&read_csv(&dir.path().join("b.csv")), sim.unwrap());
}

#[test]
fn summary_lists_the_main_channels() {
    let dir = tempfile::tempdir().unwrap();
    let o = simrod(dir.path(), &["simulate", "--profile", "TP12", "--load-scale", "0", "--out", "r.csv"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.starts_with("TP12: throttle x1, load x0 | dt 1000 µs | supply 24 V"), "{out}");
    assert!(out.contains("duration 26.000 s, 26000 steps"), "{out}");
    assert!(out.contains("steps/s") && out.contains("real-time factor"), "{out}");
    for name in [
        "SuTMotorEnc",
        "C_Kistler_L",
        "C_Kistler_R",
        "T_Kistler_L",
        "T_Kistler_R",
        "P_SuT_inv",
        "P_LML",
        "P_LMR",
        "P_DPU",
        "I_DPU 2.7",
        "V_DC ",
    ] {
        assert!(out.lines().any(|l| l.trim_start().starts_with(name)), "{name} missing:\n{out}");
    }
    assert!(out.contains("wrote r.csv (26000 rows x 37 channels"), "{out}");
}

/// Each invalid request: exit code 2, a message naming the argument and what was
/// expected, and the previous output untouched.
#[test]
fn invalid_arguments_are_refused_with_specific_messages() {
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join("run.csv"), "previous run").unwrap();
    fs::write(dir.path().join("p.toml"), "[[set]]\nduration_s = 1\n").unwrap();
    fs::write(dir.path().join("long_delay.toml"), "[controller_delay]\ndelay_s = 0.5\n").unwrap();
    let cases: &[(&[&str], &[&str])] = &[
        (
            &["--profile", "TP99"],
            &["'--profile <NAME>'", "unknown profile; known: TP07, TP11, TP12, TP13, TP14"],
        ),
        (&[], &["required arguments were not provided", "--profile <NAME>|--profile-file"]),
        (
            &["--profile", "TP07", "--profile-file", "p.toml"],
            &["'--profile <NAME>' cannot be used with '--profile-file <FILE.toml>'"],
        ),
        (
            &["--profile", "TP07", "--throttle-scale", "1.6"],
            &["'--throttle-scale <X>'", "expected a number in [-1.5, 1.5], got 1.6"],
        ),
        (
            &["--profile", "TP07", "--load-scale", "-2"],
            &["'--load-scale <Y>'", "expected a number in [-1.5, 1.5], got -2"],
        ),
        (
            &["--profile", "TP07", "--throttle-scale", "nan"],
            &["'--throttle-scale <X>'", "[-1.5, 1.5], got NaN"],
        ),
        (&["--profile", "TP07", "--throttle-scale", "inf"], &["'--throttle-scale <X>'", "got inf"]),
        (&["--profile", "TP07", "--throttle-scale", "abc"], &["'--throttle-scale <X>'", "expected a number"]),
        (
            &["--profile", "TP07", "--dt-us", "9"],
            &["'--dt-us <US>'", "expected a step in [10, 10000] µs, got 9"],
        ),
        (&["--profile", "TP07", "--dt-us", "10001"], &["'--dt-us <US>'", "got 10001"]),
        (
            &["--profile", "TP07", "--supply-v", "11.9"],
            &["'--supply-v <V>'", "expected a voltage in [12, 30] V", "got 11.9"],
        ),
        (&["--profile", "TP07", "--supply-v", "30.1"], &["'--supply-v <V>'", "got 30.1"]),
        (&["--profile", "TP07", "--params", "guessed"], &["'--params <PARAMS>'", "programmed, identified"]),
        (&["--profile-file", "missing.toml"], &["--profile-file missing.toml: cannot read"]),
        (&["--profile", "TP07", "--effects", "missing.toml"], &["--effects missing.toml: cannot read"]),
        (
            &["--profile", "TP07", "--effects", "long_delay.toml", "--dt-us", "1000"],
            &["long_delay.toml: controller_delay.delay_s = 0.5 s is 500 steps", "at most 256 steps"],
        ),
    ];
    for (args, expected) in cases {
        let mut full = vec!["simulate"];
        full.extend_from_slice(args);
        full.extend_from_slice(&["--out", "run.csv"]);
        let o = simrod(dir.path(), &full);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        for e in *expected {
            assert!(err.contains(e), "{args:?}: expected {e:?} in:\n{err}");
        }
        assert_eq!(stdout(&o), "", "{args:?}");
    }
    // The output's directory must exist: a typo must not create directories.
    let o = simrod(dir.path(), &["simulate", "--profile", "TP07", "--out", "nodir/run.csv"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--out nodir/run.csv: directory nodir does not exist"), "{}", stderr(&o));
    assert!(!dir.path().join("nodir").exists());
    let o = simrod(dir.path(), &["simulate", "--profile", "TP07", "--out", "."]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--out .: "), "{}", stderr(&o));

    assert_eq!(fs::read_to_string(dir.path().join("run.csv")).unwrap(), "previous run");
    assert_eq!(listing(dir.path()), ["long_delay.toml", "p.toml", "run.csv"]);
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    fs::write(&p, text).unwrap();
    p
}

#[test]
fn bad_profile_files_give_file_line_col() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(
        d,
        "range.toml",
        "name = \"bad\"\n\n[[set]]\nduration_s = 3\nthrottle_pct = 50\n\n[[set]]\nduration_s = 3\n\n\
         [[set]]\nduration_s = 2\nload_l_pct = 10\n\nthrottle_pct = 150\n",
    );
    write(d, "key.toml", "[[set]]\nduration_s = 3\n\n[[set]]\nduration_s = 3\nthrotle = \"hold\"\n");
    write(d, "syntax.toml", "[[set]]\nduration_s = 3\nthrottle_pct = 5 5\n");
    write(d, "eleven.toml", &"[[set]]\nduration_s = 1\n".repeat(11));
    let cases = [
        ("range.toml", "range.toml:14:16: set 3: throttle_pct = 150 is outside [-100, 100] %"),
        ("key.toml", "key.toml:6:1: unknown field `throtle`, expected one of"),
        ("syntax.toml", "syntax.toml:3:"),
        ("eleven.toml", "eleven.toml:21:1: set 11: a profile has at most 10 sets"),
    ];
    for (file, expected) in cases {
        let o = simrod(d, &["simulate", "--profile-file", file, "--out", "run.csv"]);
        assert_eq!(o.status.code(), Some(2), "{file}");
        let err = stderr(&o);
        assert!(err.contains(&format!("error: {expected}")), "{file}: expected {expected:?} in:\n{err}");
    }
    let o = simrod(d, &["simulate", "--profile-file", "key.toml", "--out", "run.csv"]);
    assert!(stderr(&o).contains("`throttle`"), "lists the accepted keys: {}", stderr(&o));
    assert!(!d.join("run.csv").exists());
}

#[test]
fn bad_effect_files_give_file_line_col() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(
        d,
        "effect.toml",
        "[controller_delay]\ndelay_s = 0.01\n\n# typo\n[diferential_friction]\ncoulomb_nm = 1\n",
    );
    write(d, "param.toml", "[controller_delay]\ndelay_s = 0.01\n\n[inertia_scale]\nsut = 1.1\nload = 1.0\n");
    write(d, "value.toml", "[controller_delay]\ndelay_s = 0.01\n\n[regen_efficiency]\nextra_loss = 1.5\n");
    write(d, "type.toml", "[controller_delay]\n\ndelay_s = true\n");
    let cases = [
        (
            "effect.toml",
            "effect.toml:5:2: unknown effect `diferential_friction`; known effects: `differential_friction`",
        ),
        (
            "param.toml",
            "param.toml:6:1: [inertia_scale]: unknown parameter `load`; accepted: `sut`, `load_l`, `load_r`",
        ),
        (
            "value.toml",
            "value.toml:5:14: [regen_efficiency]: extra_loss = 1.5 is invalid: extra_loss must be in [0, 1)",
        ),
        ("type.toml", "type.toml:3:11: "),
    ];
    for (file, expected) in cases {
        let o = simrod(d, &["simulate", "--profile", "TP12", "--effects", file, "--out", "run.csv"]);
        assert_eq!(o.status.code(), Some(2), "{file}");
        let err = stderr(&o);
        assert!(err.contains(&format!("error: {expected}")), "{file}: expected {expected:?} in:\n{err}");
    }
    assert!(!d.join("run.csv").exists());
}

#[test]
fn example_files_run() {
    let dir = tempfile::tempdir().unwrap();
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let o = simrod(
        dir.path(),
        &[
            "simulate",
            "--profile-file",
            examples.join("profile.toml").to_str().unwrap(),
            "--effects",
            examples.join("effects.toml").to_str().unwrap(),
            "--out",
            "run.csv",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).starts_with("warm-up, load step, reverse:"), "{}", stdout(&o));
}

#[test]
fn a_successful_run_replaces_the_previous_output() {
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join("run.csv"), "previous run").unwrap();
    let o = simrod(dir.path(), &["simulate", "--profile", "TP12", "--dt-us", "10000", "-o", "run.csv", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = fs::read_to_string(dir.path().join("run.csv")).unwrap();
    assert!(text.starts_with("time [s],Throttle [V],"));
    assert_eq!(text.lines().count(), 1 + 2600);
    assert_eq!(listing(dir.path()), ["run.csv"]);
}
