//! The closed loop on the built-in vehicle and cycles: the road load the bench applies is
//! the vehicle's (hand numbers from `vehicle.toml`), the bench accelerates as the vehicle
//! would, the RT platform's delay and sample time act as stated, the driver follows.

use model_core::{Channel, Config};
use simrod_xdt::margin::{delay_margin, judge, Criterion};
use simrod_xdt::{Cycle, LoopParams, Timing, Vehicle, XilLoop, XilOutputs};

fn run(cycle: Cycle, period: u32, delay: u32) -> Vec<XilOutputs> {
    let timing = Timing::new(period, delay).unwrap();
    XilLoop::builtin(&Config::default(), cycle, timing, 24.0).unwrap().collect()
}

/// On the 8 % climb at a steady 15 km/h each flange carries the vehicle's wheel torque:
/// `r (m g (sin + c_rr cos) + rho c_d A v^2 / 2) / 2`, by hand from vehicle.toml. The
/// bench's own friction is cancelled by the loads, so nothing else may show.
#[test]
fn flange_carries_the_vehicles_wheel_torque_on_the_climb() {
    let out = run(Cycle::Hill, 1, 2);
    let v = Vehicle::default();
    let at = out.iter().find(|o| o.xdt.distance_m > 250.0).expect("reaches 250 m");
    assert!((at.xdt.slope.pct - 8.0).abs() < 1e-3);
    let speed = at.xdt.v_mps;
    assert!((speed * 3.6 - 15.0).abs() < 0.3, "{} km/h", speed * 3.6);
    let (s, c) = (0.08f32 / (1.0f32 + 0.0064).sqrt(), 1.0 / (1.0f32 + 0.0064).sqrt());
    let force = 510.0 * 9.80665 * (s + 0.015 * c) + 0.5 * 1.204 * 0.85 * speed * speed;
    let want = 0.25 * force / 2.0;
    for ch in [Channel::CKistlerL, Channel::CKistlerR] {
        let got = at.bench.get(ch);
        assert!((got - want).abs() < 0.02 * want, "{}: {got} N m, vehicle wheel {want} N m", ch.name());
    }
    assert_eq!(v.mass_kg, 510.0, "the hand numbers assume the built-in vehicle");
}

/// While the loads are not clipped, the bench's shafts accelerate as the vehicle does:
/// the speed's slope equals `(C_L + C_R - r F_road) / (m_eq r^2) r`. Checked on a loop
/// without lag (no torque filter, no delay): a lag `tau` in the loop makes the vehicle's
/// acceleration trail the bench's by about `jerk x tau x J_extra / J_bench` (the
/// inertia ratio, about 34, multiplies it; docs/MODEL.md, "The xDT"), and even this
/// loop has one step of lag (a sample is the last step's outputs): so the points are
/// taken inside the launch, not at its onset or end, where the jerk is highest.
#[test]
fn bench_accelerates_like_the_vehicle() {
    let mut lp = LoopParams::default();
    lp.tuning.torque_filter_hz = 0.0;
    let timing = Timing::new(1, 0).unwrap();
    let cfg = Config::default();
    let route = Cycle::Ece15.route();
    let out: Vec<XilOutputs> =
        XilLoop::new(&cfg, model_core::Maps::builtin(), &Vehicle::default(), &lp.tuning, route, timing, 24.0)
            .unwrap()
            .collect();
    let mut compared = 0;
    for k in (11_750..=13_250).step_by(250) {
        if (k - 50..=k + 50).any(|j| out[j].xdt.clipped != [false; 2]) {
            continue;
        }
        let slope = (out[k + 50].xdt.v_mps - out[k - 50].xdt.v_mps) / 0.1;
        let model = out[k].xdt.accel_mps2;
        assert!(model > 0.3, "t {k} ms: the first acceleration of ECE-15 ({model} m/s^2)");
        assert!((slope - model).abs() < 0.03 * model, "t {k} ms: bench {slope} m/s^2, vehicle {model}");
        compared += 1;
    }
    assert!(compared >= 6, "only {compared} unclipped points in the first acceleration");
}

/// The bench gets the set points computed `delay` steps earlier, and the xDT computes
/// new ones only every `period` steps.
#[test]
fn delay_and_sample_time_act_as_stated() {
    let (period, delay) = (4usize, 7usize);
    let out = run(Cycle::Delivery, period as u32, delay as u32);
    let applied = |o: &XilOutputs| {
        [o.bench.get(Channel::ThrottleSp), o.bench.get(Channel::LoadLSp), o.bench.get(Channel::LoadRSp)]
    };
    let computed = |o: &XilOutputs| [o.computed.throttle_pct, o.computed.load_pct[0], o.computed.load_pct[1]];
    for k in 0..40_000 {
        if k >= delay {
            assert_eq!(applied(&out[k]), computed(&out[k - delay]), "step {k}");
        } else {
            assert_eq!(applied(&out[k]), [0.0; 3], "step {k}");
        }
        if k % period != 0 && k > 0 {
            assert_eq!(computed(&out[k]), computed(&out[k - 1]), "step {k}: a new sample between samples");
        }
    }
    assert!(out.iter().any(|o| o.computed.throttle_pct > 50.0));
}

/// Every cycle is followed within 1 km/h RMS (of the capped target), its targets are
/// capped at the bench's reach, and every channel stays finite.
#[test]
fn driver_follows_every_cycle_within_the_bench_reach() {
    let p = model_core::Params::default();
    let reach = 0.95 * p.speed_limit_rpm[0] / p.sut_gear_ratio * std::f32::consts::PI / 30.0 * 0.25;
    for cycle in Cycle::ALL {
        let out = run(cycle, 1, 2);
        assert_eq!(out.len() as u64, cycle.route().duration_us().div_ceil(1000), "{}", cycle.name());
        let mut sq = 0.0f64;
        for o in &out {
            assert!(o.bench.non_finite().is_none(), "{}", cycle.name());
            assert!(o.xdt.target_mps <= reach * 1.000_001, "{}: target {}", cycle.name(), o.xdt.target_mps);
            assert!(o.xdt.target_mps <= o.xdt.cycle_mps + 1e-6);
            sq += f64::from((o.xdt.target_mps - o.xdt.v_mps) * 3.6).powi(2);
        }
        let rms = (sq / out.len() as f64).sqrt();
        assert!(rms < 1.0, "{}: tracking RMS {rms} km/h", cycle.name());
    }
}

/// The delay margin of the built-in loop: at half of it the flange torques' oscillation
/// stays small on every cycle, at twice of it the loop is unstable on every cycle.
#[test]
fn delay_margin_separates_stable_from_unstable() {
    let c = Criterion::default();
    let lp = LoopParams::default();
    let maps = model_core::Maps::builtin();
    let cfg = Config::default();
    let m =
        delay_margin(&cfg, maps, &Vehicle::default(), &lp.tuning, Cycle::Ece15.route(), 1, 24.0, c).unwrap();
    let margin = m.stable_steps.expect("stable without delay");
    assert!((5..=200).contains(&margin), "margin {margin} steps");
    let (first_bad, verdict) = m.unstable.expect("unstable within the delay line");
    assert_eq!(first_bad, margin + 1);
    assert!(!verdict.is_stable());
    for cycle in Cycle::ALL {
        let judged = |d: u32| {
            let timing = Timing::new(1, d).unwrap();
            judge(XilLoop::builtin(&cfg, cycle, timing, 24.0).unwrap(), c)
        };
        let low = judged(margin / 2);
        assert!(low.is_stable() && low.max_envelope_nm < 0.5 * c.floor_nm, "{}: {low:?}", cycle.name());
        let high = judged(2 * margin);
        assert!(!high.is_stable(), "{}: {high:?}", cycle.name());
    }
}
