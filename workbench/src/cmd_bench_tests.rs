//! `simrod bench` tests: exactness without noise, the configured noise levels, encoder
//! quantisation, the Siemens miscount, determinism, and a file that tells nothing.

use std::path::Path;

use clap::Parser;
use model_core::{Builtin, Channel, Config, Profile, Simulation, MEASURED};

use super::*;
use crate::measure::{load, SETPOINT_LOAD_L, SETPOINT_LOAD_R, SETPOINT_THROTTLE};
use crate::vbench::chain::{measure, ChainOptions, Recorded};
use crate::vbench::noise::{Gauss, NoiseModel};
use crate::vbench::scenario::Scenario;

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    a: BenchArgs,
}

fn args(list: &[&str]) -> BenchArgs {
    Cli::try_parse_from(std::iter::once("bench").chain(list.iter().copied())).unwrap().a
}

fn recorded(b: Builtin) -> Recorded {
    let p = Profile::builtin(b, 1.0, 1.0).unwrap();
    Recorded::run(Simulation::new(&Config::default(), p, 24.0).unwrap())
}

fn chain(noise: Option<NoiseModel>, seed: u64, miscount: bool) -> ChainOptions {
    ChainOptions { noise, seed, miscount }
}

fn series(m: &Measurement, c: Channel) -> &[f64] {
    &m.signal(c.name()).unwrap().values
}

#[test]
fn noise_none_gives_the_twin_bit_for_bit_in_csv_and_mat() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("m.csv");
    let mat = d.path().join("m.mat");
    for out in [&csv, &mat] {
        let o = out.to_str().unwrap();
        execute(&args(&["--profile", "TP12", "--plant", "twin", "--noise", "none", "-q", "--out", o]))
            .unwrap();
    }
    let a = load(&csv, None).unwrap();
    let b = load(&mat, None).unwrap();
    assert_eq!((&a.time_s, &a.signals), (&b.time_s, &b.signals));

    let p = Profile::builtin(Builtin::TP12, 1.0, 1.0).unwrap();
    let sim = Simulation::new(&Config::default(), p, 24.0).unwrap();
    let mut n = 0;
    for (k, o) in sim.enumerate() {
        assert_eq!(a.time_s[k], o.t_us as f64 / 1e6);
        for c in MEASURED {
            let v = series(&a, *c)[k] as f32;
            assert_eq!(v.to_bits(), o.get(*c).to_bits(), "{} at {k}", c.name());
        }
        let sp = [
            (SETPOINT_THROTTLE, Channel::ThrottleSp),
            (SETPOINT_LOAD_L, Channel::LoadLSp),
            (SETPOINT_LOAD_R, Channel::LoadRSp),
        ];
        for (name, c) in sp {
            assert_eq!((a.signal(name).unwrap().values[k] as f32).to_bits(), o.get(c).to_bits());
        }
        n += 1;
    }
    assert_eq!(n, a.time_s.len());
    assert!(n > 20_000);
}

/// The configured Gaussian channels and their parameters.
fn gaussian(nm: &NoiseModel) -> Vec<(Channel, Gauss)> {
    vec![
        (Channel::CKistlerL, nm.torque),
        (Channel::CKistlerR, nm.torque),
        (Channel::IXlml22, nm.current.xlml),
        (Channel::IXlmlBu1, nm.current.xlml),
        (Channel::IXlmr23, nm.current.xlmr),
        (Channel::IDpu27, nm.current.dpu),
        (Channel::IDc, nm.current.dc),
        (Channel::VDcBusbars, nm.voltage.busbars),
        (Channel::VDc, nm.voltage.dc),
        (Channel::Throttle, nm.voltage.throttle),
    ]
}

#[test]
fn default_noise_has_the_configured_sigma_at_and_away_from_the_limits() {
    let rec = recorded(Builtin::TP11);
    let nm = NoiseModel::default();
    let m = measure(&rec, &chain(Some(nm), 42, false), Path::new("x.csv"));
    let g: Vec<f64> = (0..rec.t_us.len())
        .map(|k| {
            nm.limits.factor(
                f64::from(rec.get(Channel::CKistlerL)[k]),
                f64::from(rec.get(Channel::CKistlerR)[k]),
                f64::from(rec.get(Channel::SuTMotorEnc)[k]),
            )
        })
        .collect();
    let at_limit = g.iter().filter(|g| **g >= 0.999).count();
    let away = g.iter().filter(|g| **g == 0.0).count();
    assert!(at_limit > 5_000 && away > 5_000, "{at_limit} {away}");
    for (c, p) in gaussian(&nm) {
        let exact = rec.get(c);
        let noisy = series(&m, c);
        for (sel, sigma) in [(0.0, p.sigma), (1.0, p.sigma + p.at_limit)] {
            let dev: Vec<f64> = (0..exact.len())
                .filter(|&k| if sel == 0.0 { g[k] == 0.0 } else { g[k] >= 0.999 })
                .map(|k| noisy[k] - f64::from(exact[k]))
                .collect();
            let rms = (dev.iter().map(|d| d * d).sum::<f64>() / dev.len() as f64).sqrt();
            let ratio = rms / sigma;
            assert!((0.9..1.1).contains(&ratio), "{}: rms {rms} vs sigma {sigma}", c.name());
        }
    }
    // The set points are logged exactly.
    for (name, sp) in [SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R].iter().zip(&rec.setpoints) {
        let v = &m.signal(name).unwrap().values;
        assert!(v.iter().zip(sp).all(|(a, b)| *a as f32 == *b), "{name}");
    }
}

#[test]
fn encoder_speeds_are_whole_pulses_per_window_and_track_the_speed() {
    let rec = recorded(Builtin::TP11);
    let nm = NoiseModel::default();
    let m = measure(&rec, &chain(Some(nm), 5, false), Path::new("x.csv"));
    let window = 0.1;
    for (c, ppr) in [
        (Channel::TKistlerL, 60.0),
        (Channel::TKistlerR, 60.0),
        (Channel::SuTMotorEnc, 64.0),
        (Channel::SiemensEnc, 128.0),
    ] {
        let q = 60.0 / (ppr * window);
        let v = series(&m, c);
        let exact = rec.get(c);
        let interior = 50..v.len() - 50;
        let mut err_sum = 0.0;
        let mut distinct = std::collections::BTreeSet::new();
        for k in interior.clone() {
            let pulses = v[k] / q;
            assert!((pulses - pulses.round()).abs() < 1e-4, "{} at {k}: {} rpm", c.name(), v[k]);
            distinct.insert(pulses.round() as i64);
            err_sum += (v[k] - f64::from(exact[k])).abs();
        }
        let mean_err = err_sum / interior.len() as f64;
        assert!(mean_err < q, "{}: mean |error| {mean_err} rpm, quantum {q}", c.name());
        assert!(distinct.len() > 10, "{}", c.name());
    }
}

#[test]
fn miscount_lowers_siemens_only_above_the_threshold() {
    let rec = recorded(Builtin::TP11);
    let nm = NoiseModel::default();
    let a = measure(&rec, &chain(Some(nm), 9, false), Path::new("x.csv"));
    let b = measure(&rec, &chain(Some(nm), 9, true), Path::new("x.csv"));
    for (sa, sb) in a.signals.iter().zip(&b.signals) {
        if sa.name != Channel::SiemensEnc.name() {
            assert_eq!(sa, sb);
        }
    }
    let exact = rec.get(Channel::SiemensEnc);
    let (va, vb) = (series(&a, Channel::SiemensEnc), series(&b, Channel::SiemensEnc));
    let h = 50;
    let (mut below, mut above, mut sum_a, mut sum_b) = (0, 0, 0.0, 0.0);
    for k in 0..exact.len() {
        let win = &exact[k.saturating_sub(h + 1)..(k + h + 1).min(exact.len())];
        let peak = win.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        if peak < nm.miscount.threshold_rpm as f32 {
            assert_eq!(va[k], vb[k], "below the threshold at {k}");
            below += 1;
        } else if win.iter().all(|v| v.abs() >= nm.miscount.full_rpm as f32) {
            sum_a += va[k];
            sum_b += vb[k];
            above += 1;
        }
    }
    assert!(below > 5_000 && above > 5_000, "{below} {above}");
    // Above `full_rpm`, `max_drop` (20 %) of the pulses are lost.
    let ratio = sum_b / sum_a;
    assert!((ratio - (1.0 - nm.miscount.max_drop)).abs() < 0.02, "{ratio}");
}

#[test]
fn same_seed_same_file_other_seed_other_file() {
    let d = tempfile::tempdir().unwrap();
    for ext in ["csv", "mat"] {
        let run = |seed: &str, name: &str| {
            let p = d.path().join(format!("{name}.{ext}"));
            let o = p.to_str().unwrap();
            execute(&args(&["--profile", "TP12", "--seed", seed, "-q", "--out", o])).unwrap();
            std::fs::read(&p).unwrap()
        };
        let (a, b, c) = (run("7", "a"), run("7", "b"), run("8", "c"));
        assert!(a == b, "{ext}: same seed, different files");
        assert!(a != c, "{ext}: different seeds, same file");
    }
}

#[test]
fn the_file_names_no_effect_and_no_noise_setting() {
    let d = tempfile::tempdir().unwrap();
    let fx = d.path().join("fx.toml");
    std::fs::write(
        &fx,
        "[differential_friction]\ncoulomb_nm = 0.8\n[controller_delay]\ndelay_s = 0.02\n\
         [sensor_offset]\nc_kistler_l = 1.5\n",
    )
    .unwrap();
    let noise = d.path().join("my_noise.toml");
    std::fs::write(&noise, "[torque]\nsigma = 0.7\n").unwrap();
    for ext in ["csv", "mat"] {
        let out = d.path().join(format!("run.{ext}"));
        let a = args(&[
            "--profile",
            "TP12",
            "--effects",
            fx.to_str().unwrap(),
            "--noise",
            noise.to_str().unwrap(),
            "--miscount",
            "--seed",
            "3",
            "-q",
            "--out",
            out.to_str().unwrap(),
        ]);
        execute(&a).unwrap();
        let bytes = std::fs::read(&out).unwrap();
        let text = String::from_utf8_lossy(&bytes).to_ascii_lowercase();
        let mut words: Vec<&str> = model_core::effects::effect_ids().collect();
        // Parameter names specific enough to mean something (not `left`, `dc`, ...), and
        // not a channel's key (the measurement chain's parameters: the header has them).
        let params = model_core::effects::EFFECT_PARAMS.iter().flat_map(|(_, p)| p.iter().copied());
        words.extend(params.filter(|p| p.contains('_') && model_core::Channel::from_key(p).is_none()));
        words.extend(["effect", "noise", "seed", "miscount", "sigma", "fx.toml", "tp12"]);
        for w in words {
            assert!(!text.contains(w), "{ext} contains `{w}`");
        }
        let m = load(&out, None).unwrap();
        let names: Vec<&str> = m.signals.iter().map(|s| s.name.as_str()).collect();
        let mut expect: Vec<&str> = MEASURED.iter().map(|c| c.name()).collect();
        expect.extend([SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R]);
        assert_eq!(names, expect);
    }
    // The CSV header is exactly the bench's.
    let head = std::fs::read_to_string(d.path().join("run.csv")).unwrap();
    let first = head.lines().next().unwrap();
    assert!(first.starts_with("time [s],Throttle [V],SuTMotorEnc [rpm],C_Kistler_L [N m],"), "{first}");
    assert!(first.ends_with(",SuT Throttle [%],Dm Left [%],Dm Right [%]"), "{first}");
}

#[test]
fn bad_arguments_are_usage_errors() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("m.txt");
    let e = bench(&args(&["--profile", "TP12", "--out", out.to_str().unwrap()])).unwrap_err();
    assert!(e.to_string().contains(".csv or .mat") && e.exit_code() == 2, "{e}");
    let out = d.path().join("m.csv");
    let missing = d.path().join("nope.toml");
    let a =
        args(&["--profile", "TP12", "--noise", missing.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let e = bench(&a).unwrap_err();
    assert!(e.to_string().contains("nope.toml") && e.exit_code() == 2, "{e}");
    assert!(!out.exists());
}

#[test]
fn pulse_channels_are_opt_in_and_match_the_speed_channels() {
    use crate::vbench::chain::{EDGE_TIME_KISTLER, EDGE_TIME_SIEMENS, PULSE_KISTLER, PULSE_SIEMENS};
    use crate::vbench::encoder::windowed_rpm;
    let plain =
        bench(&args(&["--profile", "TP12", "--miscount", "-q", "--out", "x.csv"])).unwrap().measurement;
    let with = bench(&args(&["--profile", "TP12", "--miscount", "--pulses", "-q", "--out", "x.csv"]))
        .unwrap()
        .measurement;
    // Off by default; on, the other channels are exactly as without.
    assert!(plain.signal(PULSE_KISTLER).is_none());
    assert_eq!(with.signals.len(), plain.signals.len() + 4);
    assert_eq!(&with.signals[..plain.signals.len()], &plain.signals[..]);
    let dt = 1e-3;
    for (count, time, speed, ppr) in [
        (PULSE_KISTLER, EDGE_TIME_KISTLER, Channel::TKistlerR, 60),
        (PULSE_SIEMENS, EDGE_TIME_SIEMENS, Channel::SiemensEnc, 128),
    ] {
        let c = &with.signal(count).unwrap().values;
        let t = &with.signal(time).unwrap().values;
        assert_eq!(with.signal(time).unwrap().unit, "s");
        // The counts are those behind the speed channel (lost pulses included).
        let counts: Vec<i64> = std::iter::once(0).chain(c.iter().map(|v| *v as i64)).collect();
        let rpm = windowed_rpm(&counts, ppr, dt, 50);
        for (k, (a, b)) in rpm.iter().zip(series(&with, speed)).enumerate() {
            assert_eq!((*a as f32).to_bits(), (*b as f32).to_bits(), "{count} vs {} at {k}", speed.name());
        }
        assert!(*c.last().unwrap() > 100.0);
        // Each change of count has its edge time inside that sample, on the 1 µs clock.
        let mut changes = 0;
        for k in 1..c.len() {
            if c[k] != c[k - 1] {
                changes += 1;
                let tk = with.time_s[k];
                assert!(
                    t[k] > tk - dt - 1e-12 && t[k] <= tk + 1e-12,
                    "{time} at {k}: {} not in ({}, {tk}]",
                    t[k],
                    tk - dt
                );
                assert!(((t[k] * 1e6).round() - t[k] * 1e6).abs() < 1e-6, "{}", t[k]);
            } else {
                assert_eq!(t[k], t[k - 1], "{time} holds its last edge");
            }
        }
        assert!(changes > 100);
    }
    // The miscounting Siemens encoder falls short of 128 pulses per 60 Kistler pulses at speed.
    let kc = &with.signal(PULSE_KISTLER).unwrap().values;
    let sc = &with.signal(PULSE_SIEMENS).unwrap().values;
    let n = kc.len();
    let ratio = (sc[n - 1] - sc[0]) / (kc[n - 1] - kc[0]);
    assert!(ratio < 128.0 / 60.0 * 0.98, "{ratio}");
}

#[test]
fn pulse_timing_keys_are_checked() {
    let e = NoiseModel::parse(Path::new("n.toml"), "[encoders]\ntimer_s = 0\n").unwrap_err();
    assert_eq!(e.to_string(), "n.toml: encoders.timer_s: expected a clock period in (0, 1e-3] s");
    let e = NoiseModel::parse(Path::new("n.toml"), "[encoders]\nedge_jitter_deg = 5\n").unwrap_err();
    assert!(e.to_string().contains("edge_jitter_deg"));
}

#[test]
fn the_physics_plant_is_the_default_and_close_to_the_twin() {
    let d = tempfile::tempdir().unwrap();
    let run = |plant: &str| {
        let out = d.path().join(format!("run-{plant}.csv"));
        let o = out.to_str().unwrap();
        let mut a = vec!["--profile", "TP12", "--noise", "none", "-q", "--out", o];
        if !plant.is_empty() {
            a.extend(["--plant", plant]);
        }
        execute(&args(&a)).unwrap();
        load(&out, None).unwrap()
    };
    let (default, physics, twin) = (run(""), run("physics"), run("twin"));
    assert_eq!(default.signals, physics.signals, "physics is the default");
    assert_ne!(physics.signals, twin.signals, "two plants, two codes");
    // The same bench: within 1e-3 of each channel's span (the conformance bound).
    for c in MEASURED {
        let (p, t) = (series(&physics, *c), series(&twin, *c));
        let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let rms = (p.iter().zip(t).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / p.len() as f64).sqrt();
        assert!(rms <= 1e-3 * (hi - lo).max(1e-3 * hi.abs().max(1.0)), "{}: rms {rms}", c.name());
    }
}

#[test]
fn bench_only_physics_needs_the_physics_plant_and_acquisition_effects_act() {
    let d = tempfile::tempdir().unwrap();
    let fx = d.path().join("fx.toml");
    std::fs::write(&fx, "[gear_mesh_ripple]\namplitude_nm = 1\nrelative = 0.02\nperiods_per_rev = 17\n")
        .unwrap();
    let out = d.path().join("m.csv");
    let (f, o) = (fx.to_str().unwrap(), out.to_str().unwrap());
    let e = bench(&args(&["--profile", "TP12", "--plant", "twin", "--effects", f, "--out", o])).unwrap_err();
    assert!(e.to_string().contains("gear_mesh_ripple") && e.to_string().contains("--plant physics"), "{e}");
    std::fs::write(&fx, "[sensor_clipping]\nc_kistler_l = 10\n").unwrap();
    for plant in ["twin", "physics"] {
        let m = bench(&args(&["--profile", "TP12", "--plant", plant, "--effects", f, "-q", "--out", o]))
            .unwrap()
            .measurement;
        let v = series(&m, Channel::CKistlerL);
        assert!(v.iter().all(|x| x.abs() <= 10.0 + 1e-6) && v.iter().any(|x| x.abs() >= 9.99), "{plant}");
    }
}

#[test]
fn perturbed_maps_change_the_bench_reproducibly() {
    let d = tempfile::tempdir().unwrap();
    let o = d.path().join("m.csv");
    let o = o.to_str().unwrap();
    let run = |extra: &[&str]| {
        let mut a = vec!["--profile", "TP12", "--noise", "none", "-q", "--out", o];
        a.extend(extra);
        bench(&args(&a)).unwrap().measurement
    };
    let (base, p1, p1_again, p2) = (
        run(&[]),
        run(&["--perturb-maps", "1"]),
        run(&["--perturb-maps", "1"]),
        run(&["--perturb-maps", "2"]),
    );
    assert_eq!(p1.signals, p1_again.signals);
    assert_ne!(p1.signals, base.signals);
    assert_ne!(p1.signals, p2.signals);
}

#[test]
fn written_bench_data_is_the_bench_s_model() {
    let d = tempfile::tempdir().unwrap();
    let (o, dir) = (d.path().join("m.csv"), d.path().join("truth-data"));
    let (o, dir) = (o.to_str().unwrap(), dir.to_str().unwrap());
    let run = |extra: &[&str]| {
        let mut a = vec!["--plant", "twin", "--profile", "TP12", "--noise", "none", "-q", "--out", o];
        a.extend(extra);
        execute(&args(&a)).unwrap();
        load(Path::new(o), None).unwrap().signals
    };
    let perturbed = run(&["--perturb-maps", "7", "--write-data", dir]);
    // The twin on the written files makes the perturbed bench's run, bit for bit.
    assert_eq!(run(&["--data-dir", dir]), perturbed);
    assert_ne!(run(&[]), perturbed, "the written data is not the identified data");
    let over = args(&["--profile", "TP12", "-q", "--out", o, "--data-dir", dir, "--write-data", dir]);
    let err = execute(&over).unwrap_err().to_string();
    assert!(err.contains("--write-data"), "the data it reads is not written over: {err}");
}

#[test]
fn scenarios_are_reproducible_and_keep_their_truth_apart() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("case.csv");
    let o = out.to_str().unwrap();
    // A seed whose case hides at least one effect.
    let seed = (0..50u64).find(|s| !Scenario::draw(*s).picks.is_empty()).unwrap().to_string();
    execute(&args(&["--scenario", "random", "--seed", &seed, "-q", "--out", o])).unwrap();
    let (run1, truth1) =
        (std::fs::read(&out).unwrap(), std::fs::read_to_string(d.path().join("case.truth.toml")).unwrap());
    execute(&args(&["--scenario", "random", "--seed", &seed, "-q", "--out", o])).unwrap();
    assert_eq!(std::fs::read(&out).unwrap(), run1, "same seed, same run");
    assert_eq!(std::fs::read_to_string(d.path().join("case.truth.toml")).unwrap(), truth1);
    let s = Scenario::draw(seed.parse().unwrap());
    let text = String::from_utf8_lossy(&run1).to_ascii_lowercase();
    for p in &s.picks {
        assert!(truth1.contains(&format!("id = \"{}\"", p.id())), "{truth1}");
        assert!(!text.contains(p.id()), "the run names no effect");
    }
    let e = bench(&args(&["--scenario", "random", "--profile", "TP07", "--out", o])).unwrap_err();
    assert!(e.to_string().contains("--scenario random draws"), "{e}");
    let e = bench(&args(&["--out", o])).unwrap_err();
    assert!(e.to_string().contains("--scenario random"), "{e}");
}
