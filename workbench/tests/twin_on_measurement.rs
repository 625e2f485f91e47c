//! One twin on a measurement: `compare` and `diagnose` run the same model on the same
//! file with the same flags, and a run the model reproduces up to the bench's own noise
//! raises no alarm.

use std::path::Path;
use std::process::{Command, Output};

use std::sync::Arc;

use serde_json::Value;
use workbench::compare::{compare, CompareOptions};
use workbench::datadir::ModelData;
use workbench::diagnose::twin::{fitted_channels, RecordedTwin};
use workbench::diagnose::Twin;
use workbench::effects_file::load_effects;
use workbench::measure::load;
use workbench::twin::{InputSource, MeasuredTwin, ModelOptions, SensorModel};

fn simrod(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_simrod")).current_dir(dir).args(args).output().expect("run simrod")
}

fn json(o: &Output) -> Value {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("JSON on stdout")
}

/// A noise-only virtual-bench run (default measurement chain: Gaussian sensors and encoder
/// counting) of a model with nothing missing: every residual is noise or within the
/// encoders' counting resolution, and nothing is headlined. On the twin's own bits: on the
/// physics plant TP07's I_DC and P_SuT_inv residuals read coloured, rightly — the twin's
/// 1 ms step lags the continuous inverter power by up to 4 A in the load steps' fast
/// transients (NRMSE 4e-4, ten times less at 100 µs; `workbench/plant/tests/conformance.rs`).
#[test]
fn noise_only_runs_raise_no_alarm() {
    let d = tempfile::tempdir().unwrap();
    for (profile, seed) in [("TP07", "11"), ("TP11", "12")] {
        let file = format!("{profile}.csv");
        let args = ["bench", "--plant", "twin", "--profile", profile, "--seed", seed, "-q", "--out", &file];
        let o = simrod(d.path(), &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let j = json(&simrod(d.path(), &["compare", &file, "--json", "--no-history"]));
        for (name, w) in j["whiteness"].as_object().unwrap() {
            let v = w["verdict"].as_str().unwrap();
            assert!(["white", "resolution"].contains(&v), "{profile} {name}: {v}");
        }
        assert!(j["worst_channel"].is_null(), "{profile}: {}", j["worst_channel"]);
        let busbars = &j["channels"]["V_DC_busbars"];
        assert_eq!(busbars["normalised_by"], "span", "{profile}: {busbars}");
        assert!(busbars["nrmse"].as_f64().unwrap() < 0.05, "{profile}: {busbars}");
        assert!(busbars["fit_percent"].is_null());
        let table = String::from_utf8_lossy(&simrod(d.path(), &["compare", &file, "--no-history"]).stdout)
            .into_owned();
        assert!(!table.contains("WORST"), "{profile}:\n{table}");
    }
}

/// `compare` and `diagnose` see the same residuals: with the options both commands build
/// from the same flags (data directory, effect file, speed window), the diagnosis twin's
/// channels are, sample for sample, the ones `compare` subtracts the measurement from.
#[test]
fn compare_and_diagnose_see_the_same_twin() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("fx.toml"), "[sensor_offset]\nc_kistler_l = 1.5\n").unwrap();
    std::fs::write(d.path().join("now.toml"), "[regen_efficiency]\nextra_loss = 0.05\n").unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../model-core/data");
    let o = simrod(
        d.path(),
        &["bench", "--profile", "TP12", "--seed", "5", "--effects", "fx.toml", "-q", "--out", "m.csv"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let model = ModelOptions {
        data: Some(Arc::new(ModelData::load(&data).unwrap())),
        effects: load_effects(&d.path().join("now.toml")).unwrap(),
        sensors: SensorModel::bench(),
        ..ModelOptions::default()
    };
    let meas = load(&d.path().join("m.csv"), None).unwrap();
    let r = compare(&meas, &CompareOptions { model: model.clone(), ..CompareOptions::default() }).unwrap();
    let twin = RecordedTwin::new(
        MeasuredTwin::new(&meas, &model, &InputSource::Recorded).unwrap(),
        fitted_channels(),
    );
    let sim = twin.run(&model.effects).unwrap();
    for (ch, s) in twin.channels().iter().zip(&sim) {
        let c = r.channel(ch.name()).unwrap();
        let m = &meas.signal(ch.name()).unwrap().values;
        for (k, (s, e)) in s.iter().zip(&c.residual()).enumerate() {
            let want = if (m[k] as f32) == *s { 0.0 } else { f64::from(*s) - m[k] };
            assert_eq!(e.to_bits(), want.to_bits(), "{} at sample {k}", ch.name());
        }
    }
    assert!(r.channel("C_Kistler_L").unwrap().metrics.rmse > 1.0, "the offset the model lacks shows");

    // And the CLI takes the same flags for both commands.
    let data = data.to_str().unwrap();
    let flags = ["--data-dir", data, "--effects", "now.toml", "--speed-window-s", "0.1"];
    for cmd in [
        &["compare", "m.csv", "--json", "--no-history"][..],
        &["diagnose", "m.csv", "--json", "--threads", "2"],
    ] {
        let args: Vec<&str> = cmd.iter().chain(&flags).copied().collect();
        json(&simrod(d.path(), &args));
    }
}
