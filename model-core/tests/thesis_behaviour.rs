//! The behaviour the thesis measured, reproduced by the twin (issue: model-core tests).

mod common;
use common::*;
use model_core::*;

const RATIO: f32 = 2100.0 / 190.0;

#[test]
fn full_throttle_steady_state_forward_and_reverse() {
    for (thr, motor, axle_lo, axle_hi) in [(100.0, 2100.0, 186.0, 194.0), (-100.0, -500.0, -55.0, -40.0)] {
        let out = run(&config(RateSet::Identified, 1000), &steps(&[(15.0, thr, 0.0)]));
        let n = mean(&out, Channel::SuTMotorEnc, 12.0, 15.0);
        assert!((n - motor).abs() < 0.005 * motor.abs(), "throttle {thr}: motor {n} rpm, want {motor}");
        let axle = mean(&out, Channel::SpeedTot, 12.0, 15.0);
        // The thesis gives 190 / 50 rpm at the axle (tables 5.3/5.4); with one gearbox
        // ratio (2100/190) the reverse axle speed is 45 rpm: 50 is the thesis's rounding.
        assert!(axle > axle_lo && axle < axle_hi, "throttle {thr}: axle {axle} rpm");
        assert!((axle * RATIO - n).abs() < 0.01 * n.abs(), "gearbox kinematics: {axle} x {RATIO} vs {n}");
    }
}

#[test]
fn full_throttle_acceleration_slope_matches_the_rate_parameter() {
    for (set, accel_s) in [(RateSet::Identified, 3.9845f64), (RateSet::Programmed, 3.8)] {
        let out = run(&config(set, 1000), &steps(&[(1.0, 0.0, 0.0), (5.0, 100.0, 0.0)]));
        let slope = slope_between(&out, Channel::SuTMotorEnc, 400.0, 1900.0, 1.0, 6.0);
        let want = 3300.0 / accel_s;
        assert!((slope - want).abs() < 0.02 * want, "{set:?}: slope {slope:.1} rpm/s, want {want:.1}");
    }
}

#[test]
fn reverse_full_throttle_acceleration_uses_reverse_rate() {
    let out = run(&config(RateSet::Identified, 1000), &steps(&[(1.0, 0.0, 0.0), (4.0, -100.0, 0.0)]));
    // The reverse ramp lasts ~0.5 s, too short for the motor speed to show the rate
    // through the controller's transient: check the rate logic's command.
    let slope = slope_between(&out, Channel::SpeedCmd, -450.0, -100.0, 1.0, 5.0);
    let want = -3300.0 / 3.5125;
    assert!((slope - want).abs() < 0.02 * want.abs(), "slope {slope:.1}, want {want:.1}");
}

#[test]
fn neutral_and_partial_deceleration_slopes() {
    let cfg = config(RateSet::Identified, 1000);
    // Neutral: from 2100 rpm, throttle released. Below LS (40 % of 3300 = 1320 rpm) the
    // LS rate holds; between LS and HS (70 %) the rates blend.
    let out = run(&cfg, &steps(&[(8.0, 100.0, 0.0), (5.0, 0.0, 0.0)]));
    let slope = slope_between(&out, Channel::SuTMotorEnc, 200.0, 1200.0, 8.0, 13.0);
    let want = -3300.0 / 3.1399;
    assert!((slope - want).abs() < 0.02 * want.abs(), "neutral LS slope {slope:.1}, want {want:.1}");
    // Partial: from 2100 rpm to 50 % set point (target ~1023 rpm).
    let out = run(&cfg, &steps(&[(8.0, 100.0, 0.0), (6.0, 50.0, 0.0)]));
    let slope = slope_between(&out, Channel::SuTMotorEnc, 1200.0, 1950.0, 8.0, 14.0);
    let want = -3300.0 / 9.9752;
    assert!((slope - want).abs() < 0.02 * want.abs(), "partial decel slope {slope:.1}, want {want:.1}");
    // Reverse neutral deceleration: identified LS Rev 20 %: below 660 rpm the LS rate.
    let out = run(&cfg, &steps(&[(5.0, -100.0, 0.0), (3.0, 0.0, 0.0)]));
    let slope = slope_between(&out, Channel::SpeedCmd, -450.0, -80.0, 5.0, 8.0);
    let want = 3300.0 / 2.2993;
    assert!((slope - want).abs() < 0.02 * want, "reverse neutral slope {slope:.1}, want {want:.1}");
}

#[test]
fn throttle_inside_the_deadband_moves_nothing() {
    for thr in [25.0, -25.0, 29.9] {
        let out = run(&config(RateSet::Identified, 1000), &steps(&[(5.0, thr, 0.0)]));
        for o in &out {
            assert_eq!(o.get(Channel::ThrottleMapped), 0.0);
            assert_eq!(o.get(Channel::SuTMotorEnc), 0.0, "t={}", o.t_s());
            assert_eq!(o.get(Channel::CKistlerL), 0.0);
        }
        // ...while the voltage is there (25 % -> 1.25 V).
        assert!((out[10].get(Channel::Throttle) - thr.abs() / 20.0).abs() < 1e-6);
    }
    // Just above the deadband something moves.
    let out = run(&config(RateSet::Identified, 1000), &steps(&[(3.0, 35.0, 0.0)]));
    assert!(out.last().unwrap().get(Channel::SuTMotorEnc) > 100.0);
}

#[test]
fn parameter_speed_target_overshoots_the_map_like_fig_6_3() {
    // Thesis 6.1: the Max Speed approach asks for more speed at partial throttle than
    // the identified map, and both end at the measured limit.
    let mut cfg = config(RateSet::Identified, 1000);
    let sets = steps(&[(12.0, 45.0, 0.0)]);
    let map = mean(&run(&cfg, &sets), Channel::SuTMotorEnc, 10.0, 12.0);
    cfg.speed_target = SpeedTarget::Parameter;
    let par = mean(&run(&cfg, &sets), Channel::SuTMotorEnc, 10.0, 12.0);
    // 45 % -> 2.25 V -> 25 % mapped -> 1250 rpm by Max Speed 5000; ~810 rpm by the map.
    assert!((par - 1250.0).abs() < 5.0, "parameter approach {par}");
    assert!(map < par - 200.0, "map {map} vs parameter {par}");
}

#[test]
fn open_differential_splits_torque_equally_and_lets_speeds_differ() {
    let out = run(&config(RateSet::Identified, 1000), &steps(&[(15.0, 80.0, 40.0)]));
    let (t0, t1) = (12.0, 15.0);
    let tl = mean(&out, Channel::CKistlerL, t0, t1);
    let tr = mean(&out, Channel::CKistlerR, t0, t1);
    let tm = mean(&out, Channel::SuTTorque, t0, t1);
    let ratio = model_core::Params::default().sut_gear_ratio;
    // Steady state: each flange carries half the motor torque through the gearbox (the
    // axle friction sits downstream of the flange, so the flange measures it).
    assert!((tl - tr).abs() < 0.005 * tl.abs(), "L {tl} vs R {tr}");
    assert!((tl + tr - ratio * tm).abs() < 0.005 * (ratio * tm).abs(), "{tl}+{tr} vs {}", ratio * tm);
    // Kinematics: motor speed = ratio x mean axle speed, while L and R differ (L != R friction).
    let n = mean(&out, Channel::SuTMotorEnc, t0, t1);
    let axle = mean(&out, Channel::SpeedTot, t0, t1);
    assert!((n - ratio * axle).abs() < 0.002 * n, "{n} vs {ratio} x {axle}");
    let diff = mean(&out, Channel::SpeedDiff, t0, t1);
    assert!(diff.abs() > 0.5, "open diff with unequal friction must let speeds differ: {diff}");
}

#[test]
fn differential_friction_takes_its_torque_before_the_split() {
    let mut cfg = config(RateSet::Identified, 1000);
    cfg.effects.differential_friction.coulomb_nm = 6.0;
    let out = run(&cfg, &steps(&[(12.0, 80.0, 20.0)]));
    let (tl, tr, tm) = (
        mean(&out, Channel::CKistlerL, 10.0, 12.0),
        mean(&out, Channel::CKistlerR, 10.0, 12.0),
        mean(&out, Channel::SuTTorque, 10.0, 12.0),
    );
    let ratio = model_core::Params::default().sut_gear_ratio;
    assert!((ratio * tm - (tl + tr) - 6.0).abs() < 0.1, "motor {} flanges {}", ratio * tm, tl + tr);
}

#[test]
fn friction_maps_are_odd_symmetric() {
    let maps = Maps::builtin();
    for side in 0..2 {
        let t = &maps.friction[side];
        for &w in t.x() {
            assert_eq!(t.eval(-w), -t.eval(w), "side {side} at {w} rpm");
        }
        for k in 0..500 {
            let w = k as f32 * 0.53;
            assert!((t.eval(-w) + t.eval(w)).abs() <= 1e-5 * t.eval(w).abs().max(1.0), "side {side} at {w}");
        }
        // Cubic near zero: the slope at 0 exceeds the slope of the linear part.
        assert!(t.eval(2.0) / 2.0 > (t.eval(150.0) - t.eval(100.0)) / 50.0);
    }
    // L and R differ (thesis fig. 5.24/5.25).
    assert_ne!(maps.friction[0].eval(150.0), maps.friction[1].eval(150.0));
}

#[test]
fn power_balance_holds_every_step() {
    for (b, ts, ls) in [(Builtin::TP07, 1.0, 1.0), (Builtin::TP11, 0.79, 1.0), (Builtin::TP11, -0.79, -1.0)] {
        let sim = Simulation::new(&Config::default(), Profile::builtin(b, ts, ls).unwrap(), 24.0).unwrap();
        for o in sim {
            let parts = [Channel::PSutInv, Channel::PLml, Channel::PLmr, Channel::PConn].map(|c| o.get(c));
            let sum: f32 = parts.iter().sum();
            let scale: f32 = parts.iter().map(|p| p.abs()).sum();
            let err = (o.get(Channel::PDpu) - sum).abs();
            assert!(
                err <= 1e-3 * scale,
                "{} t={}: P_DPU {} vs parts {parts:?}",
                b.name(),
                o.t_s(),
                o.get(Channel::PDpu)
            );
            // Kirchhoff: supply current is the sum of the branch currents.
            let i_sum = o.get(Channel::IDc) + 2.0 * o.get(Channel::IXlml22) + 2.0 * o.get(Channel::IXlmr23);
            assert!((o.get(Channel::IDpu27) - i_sum).abs() <= 1e-4 * i_sum.abs().max(1.0));
        }
    }
}

#[test]
fn connector_drop_matches_its_resistance() {
    let out = run(&config(RateSet::Identified, 1000), &steps(&[(6.0, 100.0, 60.0)]));
    let o = out.last().unwrap();
    let r = (o.get(Channel::VDcBusbars) - o.get(Channel::VDc)) / o.get(Channel::IDc);
    assert!((r - 0.0196).abs() < 1e-4, "R = {r}");
    assert!(o.get(Channel::IDc) > 100.0);
}

#[test]
fn runs_are_deterministic_and_step_sizes_agree() {
    let sets = Builtin::TP12.sets();
    let a = run(&config(RateSet::Identified, 1000), sets);
    let b = run(&config(RateSet::Identified, 1000), sets);
    assert!(a.iter().zip(&b).all(|(x, y)| x.values.map(f32::to_bits) == y.values.map(f32::to_bits)));
    // 100 µs vs 1 ms: speeds agree to within 0.5 % of full scale at the common instants.
    let fine = run(&config(RateSet::Identified, 100), sets);
    for o in &a {
        let f = &fine[(o.t_us / 100 - 1) as usize];
        assert_eq!(f.t_us, o.t_us);
        let d = (f.get(Channel::SuTMotorEnc) - o.get(Channel::SuTMotorEnc)).abs();
        assert!(
            d < 0.005 * 2100.0,
            "t={} {} vs {}",
            o.t_s(),
            f.get(Channel::SuTMotorEnc),
            o.get(Channel::SuTMotorEnc)
        );
    }
}

#[test]
fn invalid_configurations_are_rejected() {
    let mut cfg = Config { dt_us: 5, ..Config::default() };
    assert_eq!(Model::new(&cfg).unwrap_err(), ConfigError::StepSize(5));
    cfg.dt_us = 1000;
    cfg.params.sut_inertia = -1.0;
    assert_eq!(Model::new(&cfg).unwrap_err(), ConfigError::Parameter("sut_inertia"));
    let mut cfg = Config::default();
    cfg.effects.inertia_scale[1] = 0.0;
    assert_eq!(Model::new(&cfg).unwrap_err(), ConfigError::Effect("inertia_scale"));
}
