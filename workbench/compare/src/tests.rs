//! End-to-end tests of the comparison on runs made in-process: the same rows
//! `simrod bench --noise none` writes (outputs at the end of each step with the set
//! points held over that step, values as f32 printed shortest-round-trip).

use std::path::{Path, PathBuf};

use model_core::{Channel, Config, Effects, Profile, ProfileSet, SetMode, Simulation, MEASURED};

use super::budget::share_of;
use super::residual::Verdict;
use super::*;
use simrod_io::measure::write::save;
use simrod_io::measure::{load, Measurement, Signal, SETPOINT_LOAD_L, SETPOINT_LOAD_R, SETPOINT_THROTTLE};
use simrod_vbench::chain::{measure, ChainOptions, Recorded};
use simrod_vbench::noise::NoiseModel;

/// Options for a run whose speeds are recorded as simulated (`--noise none`).
fn exact() -> CompareOptions {
    let model = simrod_twin::ModelOptions { sensors: simrod_twin::SensorModel::NONE, ..Default::default() };
    CompareOptions { model, ..CompareOptions::default() }
}

/// A short run that visits every region the rules know: forward acceleration with the
/// loads regenerating, a plateau, loads motoring, neutral deceleration, reverse.
fn short_profile() -> Profile {
    use SetMode::*;
    let set = |d: f32, t: f32, l: f32, tm, lm| ProfileSet {
        duration_s: d,
        throttle_pct: t,
        load_l_pct: l,
        load_r_pct: l,
        throttle_mode: tm,
        load_mode: lm,
    };
    Profile::new(
        &[
            set(1.0, 0.0, 0.0, Hold, Hold),
            set(5.0, 70.0, 40.0, Hold, Hold),
            set(5.0, 70.0, -40.0, Hold, Hold),
            set(3.0, 0.0, 0.0, Hold, Hold),
            set(4.0, -60.0, 20.0, Hold, Hold),
            set(3.0, 0.0, 0.0, Hold, Hold),
        ],
        1.0,
        1.0,
    )
    .unwrap()
}

/// What `simrod bench --noise none` records: one row per step.
pub(crate) fn bench_run(profile: Profile, effects: Effects) -> Measurement {
    let cfg = Config { effects, ..Config::default() };
    let sim = Simulation::new(&cfg, profile, 24.0).unwrap();
    let file = |v: f32| format!("{v}").parse::<f64>().unwrap();
    let mut time_s = Vec::new();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); MEASURED.len() + 3];
    for o in sim {
        time_s.push(o.t_s());
        for (c, ch) in cols.iter_mut().zip(MEASURED) {
            c.push(file(o.get(*ch)));
        }
        let n = MEASURED.len();
        cols[n].push(file(o.get(Channel::ThrottleSp)));
        cols[n + 1].push(file(o.get(Channel::LoadLSp)));
        cols[n + 2].push(file(o.get(Channel::LoadRSp)));
    }
    let mut names: Vec<(String, String)> =
        MEASURED.iter().map(|c| (c.name().to_string(), c.unit().to_string())).collect();
    for sp in [SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R] {
        names.push((sp.to_string(), "%".to_string()));
    }
    Measurement {
        source: PathBuf::from("in-process"),
        time_s,
        signals: names
            .into_iter()
            .zip(cols)
            .map(|((name, unit), values)| Signal { name, unit, values })
            .collect(),
    }
}

fn signal_mut<'a>(m: &'a mut Measurement, name: &str) -> &'a mut Vec<f64> {
    &mut m.signals.iter_mut().find(|s| s.name == name).unwrap().values
}

/// Gaussian noise, deterministic (xorshift + Box-Muller).
fn gauss(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed.max(1);
    let mut uni = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let (a, b) = (uni(), uni());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        })
        .collect()
}

fn assert_zero(r: &CompareResult, name: &str) {
    let c = r.channel(name).unwrap();
    assert!(
        c.metrics.rmse == 0.0 && c.metrics.max_abs_error == 0.0,
        "{name}: nrmse {} (rmse {}, max {} at {} s)",
        c.metrics.nrmse,
        c.metrics.rmse,
        c.metrics.max_abs_error,
        c.metrics.max_error_time_s
    );
}

#[test]
fn clean_bench_run_reproduces_exactly() {
    let meas = bench_run(short_profile(), Effects::NONE);
    let r = compare(&meas, &exact()).unwrap();
    assert_eq!(r.setup.dt_us, 1000);
    assert!(!r.setup.resampled);
    assert_eq!(r.channels.len(), MEASURED.len() + 4);
    for c in &r.channels {
        assert_zero(&r, &c.name);
        assert_eq!(c.whiteness.verdict, Verdict::Negligible, "{}", c.name);
        assert!(c.cross.iter().all(|x| !x.significant), "{}", c.name);
    }
    // The channels moved: zero error is not zero signal.
    let speed = r.channel("SuTMotorEnc").unwrap();
    assert!(speed.meas.iter().any(|v| *v > 1000.0));
    assert!(speed.meas.iter().any(|v| *v < -200.0));
    // Every direction, motion and load mode occurs in this run.
    let b = &speed.budget;
    for region in [
        "accelerating",
        "decelerating",
        "steady",
        "forward",
        "reverse",
        "loads motoring",
        "loads regenerating",
        "unloaded",
    ] {
        assert!(b.iter().any(|s| s.region == region && s.sample_share > 0.02), "{region} missing: {b:?}");
    }
}

#[test]
fn set_points_one_step_late_are_not_reproduced() {
    // The alignment matters: the same file with the set points shifted by one row
    // (recorded after the step instead of with it) must show an error.
    let mut meas = bench_run(short_profile(), Effects::NONE);
    for name in [SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R] {
        let v = signal_mut(&mut meas, name);
        v.insert(0, 0.0);
        v.pop();
    }
    let r = compare(&meas, &exact()).unwrap();
    assert!(r.channel("SuTMotorEnc").unwrap().metrics.rmse > 1e-3);
    assert!(r.channel("Throttle").unwrap().metrics.max_abs_error > 1.0);
}

#[test]
fn profile_mode_matches_recorded_set_points() {
    let mut meas = bench_run(short_profile(), Effects::NONE);
    meas.signals.retain(|s| !s.name.starts_with("SuT Thr") && !s.name.starts_with("Dm "));
    assert!(matches!(
        compare(&meas, &exact()),
        Err(CompareError::NoSetPoints(v)) if v.len() == 3
    ));
    // `short_profile` is not a built-in, so compare a built-in run in profile mode.
    let which = model_core::Builtin::TP12;
    let meas = bench_run(Profile::builtin(which, 0.8, 0.0).unwrap(), Effects::NONE);
    let opts = CompareOptions {
        inputs: InputSource::Profile { which, throttle_scale: 0.8, load_scale: 0.0 },
        ..exact()
    };
    let r = compare(&meas, &opts).unwrap();
    for c in &r.channels {
        assert_zero(&r, &c.name);
    }
    // A wrong scale is visible.
    let opts = CompareOptions {
        inputs: InputSource::Profile { which, throttle_scale: 1.0, load_scale: 0.0 },
        ..opts
    };
    let r = compare(&meas, &opts).unwrap();
    assert!(r.channel("SuTMotorEnc").unwrap().metrics.nrmse > 0.01);
}

#[test]
fn noise_level_is_what_the_rmse_reports() {
    let mut meas = bench_run(short_profile(), Effects::NONE);
    let n = meas.time_s.len();
    let sigma = [
        ("SuTMotorEnc", 5.0),
        ("C_Kistler_L", 0.5),
        ("T_Kistler_R", 1.0),
        ("I_DPU 2.7", 0.2),
        ("V_DC_busbars", 0.05),
    ];
    for (i, (name, s)) in sigma.iter().enumerate() {
        let g = gauss(n, 17 + i as u64);
        for (v, w) in signal_mut(&mut meas, name).iter_mut().zip(g) {
            *v += s * w;
        }
    }
    let r = compare(&meas, &exact()).unwrap();
    for (name, s) in sigma {
        let c = r.channel(name).unwrap();
        let rel = c.metrics.rmse / s;
        assert!((0.97..1.03).contains(&rel), "{name}: rmse {} vs {s}", c.metrics.rmse);
        assert!(c.metrics.bias.abs() < 4.0 * s / (n as f64).sqrt(), "{name}");
        assert_eq!(c.whiteness.verdict, Verdict::White, "{name}: {:?}", c.whiteness);
        assert!((c.metrics.nrmse - c.metrics.rmse / c.metrics.normaliser).abs() < 1e-12);
    }
    // Channels without noise stay exact, P_DPU picks up the noise of its factors.
    assert_zero(&r, "C_Kistler_R");
    assert_zero(&r, "I_DC");
    assert!(r.channel("P_DPU").unwrap().metrics.rmse > 1.0);
}

#[test]
fn offset_on_one_channel_is_reported_on_that_channel_only() {
    // Once added to the measurement, once as the model-core effect.
    let mut added = bench_run(short_profile(), Effects::NONE);
    for v in signal_mut(&mut added, "C_Kistler_L") {
        *v += 2.0;
    }
    let mut fx = Effects::NONE;
    fx.sensor_offset[2] = 2.0;
    let effect = bench_run(short_profile(), fx);
    for meas in [added, effect] {
        let r = compare(&meas, &exact()).unwrap();
        let c = r.channel("C_Kistler_L").unwrap();
        assert!((c.metrics.rmse - 2.0).abs() < 1e-4, "{:?}", c.metrics);
        assert!((c.metrics.bias + 2.0).abs() < 1e-4, "twin reads low: {:?}", c.metrics);
        assert_eq!(r.worst_channel().unwrap().name, "C_Kistler_L");
        for other in r.channels.iter().filter(|c| c.name != "C_Kistler_L") {
            assert_zero(&r, &other.name);
        }
    }
}

#[test]
fn regen_loss_is_located_in_the_regenerating_region() {
    let mut fx = Effects::NONE;
    fx.regen_loss = 0.3;
    let meas = bench_run(short_profile(), fx);
    let r = compare(&meas, &exact()).unwrap();
    // The load motors regenerate while their set point is positive.
    for name in ["I_XLML 2.2", "I_XLMR 2.3", "P_LML", "P_LMR"] {
        let c = r.channel(name).unwrap();
        assert!(c.metrics.rmse > 0.1, "{name}: {:?}", c.metrics);
        let share = share_of(&c.budget, "loads regenerating");
        assert!(share >= 0.8, "{name}: {share} {:?}", c.top_regions);
        assert!(c.top_regions[0].region.ends_with("loads regenerating"));
        assert_eq!(c.whiteness.verdict, Verdict::Coloured);
    }
    // The SuT inverter feeds back while the loads motor (they drive it).
    for name in ["I_DC", "P_SuT_inv"] {
        let c = r.channel(name).unwrap();
        let share = share_of(&c.budget, "loads motoring");
        assert!(share >= 0.8, "{name}: {share} {:?}", c.top_regions);
    }
    // The mechanics do not see an electrical loss.
    for name in ["SuTMotorEnc", "C_Kistler_L", "T_Kistler_R", "SiemensEnc"] {
        assert_zero(&r, name);
    }
}

#[test]
fn uneven_time_axis_is_resampled_to_1ms() {
    let mut meas = bench_run(short_profile(), Effects::NONE);
    // A logger clock 0.05 % slow: 1000.5 µs per sample is no model step.
    for t in meas.time_s.iter_mut() {
        *t *= 1.0005;
    }
    let r = compare(&meas, &exact()).unwrap();
    assert!(r.setup.resampled);
    assert_eq!(r.setup.dt_us, 1000);
    assert_eq!(r.time_s.len(), (meas.time_s.len() as f64 * 1.0005) as usize);
    // The twin now runs 0.05 % faster than the stretched run: small, not zero.
    let c = r.channel("SuTMotorEnc").unwrap();
    assert!(c.metrics.nrmse < 0.02 && c.metrics.nrmse > 1e-6, "{:?}", c.metrics);
}

#[test]
fn samples_in_gaps_are_left_out() {
    let mut meas = bench_run(short_profile(), Effects::NONE);
    let n = meas.time_s.len();
    // A wild value inside a marked gap does not count; outside one it does.
    signal_mut(&mut meas, "C_Kistler_L")[5000] += 100.0;
    let mut gap = vec![0.0; n];
    gap[4990..5010].fill(1.0);
    meas.signals.push(Signal {
        name: simrod_io::measure::GAP_CHANNEL.to_string(),
        unit: String::new(),
        values: gap,
    });
    let r = compare(&meas, &exact()).unwrap();
    let c = r.channel("C_Kistler_L").unwrap();
    assert_eq!(c.metrics.n, n - 20);
    assert_eq!(c.metrics.rmse, 0.0);
    assert!(r.notes.iter().any(|s| s.contains("20 samples inside interpolated gaps")));
    signal_mut(&mut meas, "C_Kistler_L")[6000] += 100.0;
    let r = compare(&meas, &exact()).unwrap();
    assert_eq!(r.channel("C_Kistler_L").unwrap().metrics.max_error_time_s, meas.time_s[6000]);
}

#[test]
fn bad_user_data_is_an_error() {
    let mut meas = bench_run(short_profile(), Effects::NONE);
    signal_mut(&mut meas, "C_Kistler_L").pop();
    assert!(matches!(compare(&meas, &exact()), Err(CompareError::Length { .. })));
    let mut meas = bench_run(short_profile(), Effects::NONE);
    meas.time_s.truncate(1);
    for s in &mut meas.signals {
        s.values.truncate(1);
    }
    assert!(compare(&meas, &exact()).is_err());
    let mut meas = bench_run(short_profile(), Effects::NONE);
    meas.signals.retain(|s| s.name.starts_with("SuT Thr") || s.name.starts_with("Dm "));
    assert_eq!(compare(&meas, &exact()).unwrap_err(), CompareError::NoChannels);
    let meas = bench_run(short_profile(), Effects::NONE);
    let opts = CompareOptions { window_s: f64::NAN, ..exact() };
    assert_eq!(compare(&meas, &opts).unwrap_err(), CompareError::Window);
}

/// `simrod bench` with its default measurement chain, in-process.
fn bench_chain_run(profile: Profile, effects: Effects) -> (Measurement, Recorded) {
    let cfg = Config { effects, ..Config::default() };
    let rec = Recorded::run(Simulation::new(&cfg, profile, 24.0).unwrap());
    let chain = ChainOptions { noise: Some(NoiseModel::default()), seed: 7, miscount: false };
    (measure(&rec, &chain, Path::new("virtual")), rec)
}

#[test]
fn bench_noise_level_is_what_the_rmse_reports() {
    // The chain's Gaussian sensors: the twin's RMSE is the RMS of their σ over the run
    // (σ grows towards the operating limits); the residual is white.
    let nm = NoiseModel::default();
    let (meas, rec) = bench_chain_run(short_profile(), Effects::NONE);
    let r = compare(&meas, &CompareOptions::default()).unwrap();
    let (tl, tr, w) =
        (rec.get(Channel::CKistlerL), rec.get(Channel::CKistlerR), rec.get(Channel::SuTMotorEnc));
    let g: Vec<f64> = (0..tl.len())
        .map(|k| nm.limits.factor(f64::from(tl[k]), f64::from(tr[k]), f64::from(w[k])))
        .collect();
    assert!(g.iter().any(|v| *v > 0.5), "the run reaches the limits");
    let (mut significant, mut tested) = (0, 0);
    for (name, gauss) in [
        ("C_Kistler_L", nm.torque),
        ("C_Kistler_R", nm.torque),
        ("I_XLMR 2.3", nm.current.xlmr),
        ("I_DPU 2.7", nm.current.dpu),
        ("V_DC", nm.voltage.dc),
        ("V_DC_busbars", nm.voltage.busbars),
    ] {
        let expect = (g.iter().map(|g| gauss.sigma_at(*g).powi(2)).sum::<f64>() / g.len() as f64).sqrt();
        let c = r.channel(name).unwrap();
        let rel = c.metrics.rmse / expect;
        assert!((0.96..1.04).contains(&rel), "{name}: rmse {} vs σ {expect}", c.metrics.rmse);
        assert_eq!(c.whiteness.verdict, Verdict::White, "{name}: {:?}", c.whiteness);
        significant += c.cross.iter().filter(|x| x.significant).count();
        tested += c.cross.len();
    }
    // Each peak is tested at 5 %: about 2 of the 36 false alarms are expected.
    assert!(significant <= 4, "{significant} of {tested} cross-correlation peaks significant");
    // Only noise: the counted encoder speeds are correlated but within their counting
    // resolution, so no channel is "worst" for a model error.
    for name in ["SuTMotorEnc", "T_Kistler_L", "T_Kistler_R", "SiemensEnc"] {
        let v = r.channel(name).unwrap().whiteness.verdict;
        assert!(matches!(v, Verdict::White | Verdict::Resolution), "{name}: {v:?}");
    }
    assert!(r.worst_channel().is_none(), "{:?}", r.worst_channel().map(|c| &c.name));
}

#[test]
fn csv_and_mat_of_the_same_run_compare_the_same() {
    let mut fx = Effects::NONE;
    fx.regen_loss = 0.3;
    let (meas, _) = bench_chain_run(short_profile(), fx);
    let dir = tempfile::tempdir().unwrap();
    let mut results = Vec::new();
    for name in ["run.csv", "run.mat"] {
        let path = dir.path().join(name);
        save(&path, &meas).unwrap();
        let loaded = load(&path, None).unwrap();
        results.push(compare(&loaded, &CompareOptions::default()).unwrap());
    }
    let (a, b) = (&results[0], &results[1]);
    assert_eq!(a.time_s, b.time_s);
    assert_eq!(a.channels.len(), MEASURED.len() + 4);
    assert_eq!(a.channels.len(), b.channels.len());
    for (x, y) in a.channels.iter().zip(&b.channels) {
        assert_eq!(x.name, y.name);
        assert_eq!(x.metrics, y.metrics, "{}", x.name);
        assert_eq!(x.budget, y.budget, "{}", x.name);
        assert_eq!(x.worst_spans, y.worst_spans, "{}", x.name);
        assert_eq!(x.whiteness, y.whiteness, "{}", x.name);
        assert_eq!(x.cross, y.cross, "{}", x.name);
    }
    // And the file round trip loses nothing: the in-memory run compares the same.
    let direct = compare(&meas, &CompareOptions::default()).unwrap();
    for (x, y) in a.channels.iter().zip(&direct.channels) {
        assert_eq!(x.metrics, y.metrics, "{}", x.name);
    }
    assert!(a.channel("P_LML").unwrap().metrics.rmse > 1.0);
}
