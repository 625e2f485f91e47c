//! Property test: random valid profiles over the whole set-point range, 60 s simulated,
//! never produce NaN/inf and never leave physical bounds, at 1 ms and at 100 µs; the
//! fixed-point twin (`Fx`) on the same profiles too, where additionally not a single
//! operation may saturate (every signal stays inside its format's range).

use model_core::*;
use proptest::prelude::*;

fn mode() -> impl Strategy<Value = SetMode> {
    prop_oneof![Just(SetMode::Hold), Just(SetMode::Interpolate)]
}

fn set() -> impl Strategy<Value = ProfileSet> {
    (0.2f32..15.0, -100.0f32..=100.0, -100.0f32..=100.0, -100.0f32..=100.0, mode(), mode()).prop_map(
        |(duration_s, throttle_pct, load_l_pct, load_r_pct, throttle_mode, load_mode)| ProfileSet {
            duration_s,
            throttle_pct,
            load_l_pct,
            load_r_pct,
            throttle_mode,
            load_mode,
        },
    )
}

fn scenario() -> impl Strategy<Value = Scenario> {
    (
        prop::collection::vec(set(), 1..=profile::MAX_SETS),
        -1.5f32..=1.5,
        -1.5f32..=1.5,
        12.0f32..=30.0,
        any::<bool>(),
        any::<bool>(),
    )
}

/// Bounds every physically meaningful run must respect (see the test name).
fn check(o: &Outputs, supply_v: f32, p: &Params) -> Result<(), String> {
    for c in Channel::ALL {
        let v = o.get(*c);
        if !v.is_finite() {
            return Err(format!("{} = {v} at t={}", c.name(), o.t_s()));
        }
    }
    // Open differential: a side turns at twice the case less the other side. The case is
    // bounded by the motor (1.25 x its limit, below), and a motoring load can drive its
    // side backwards up to its no-load speed (its torque fades to 0 there), so one side
    // may reach twice the case plus that: e.g. reverse at full motoring load R from
    // forward speed, L at 461 rpm with R at -199 rpm and the case at 131 rpm (a case the
    // property test found against the former bound, twice the limit + 40 = 420 rpm).
    let case_max = 1.25 * p.speed_limit_rpm[0] / p.sut_gear_ratio;
    let axle_max = 2.0 * case_max + p.load_no_load_rpm / p.load_gear_ratio;
    let bounds: [(Channel, f32); 10] = [
        // A speed-controlled motor overshoots its target when the loads drop at once
        // (a full regenerating load of ~160 N m at the axle released in one step gives
        // ~+5 %); the controller must keep even that within 25 % of the limit.
        (Channel::SuTMotorEnc, 1.25 * p.speed_limit_rpm[0]),
        (Channel::TKistlerL, axle_max),
        (Channel::TKistlerR, axle_max),
        (Channel::SiemensEnc, axle_max),
        (Channel::SuTTorque, p.motor_torque_max_nm),
        (Channel::CKistlerL, 400.0),
        (Channel::CKistlerR, 400.0),
        (Channel::IDc, supply_v / (2.0 * p.connector_resistance)),
        (Channel::IDpu27, 1000.0),
        (Channel::Throttle, 5.0),
    ];
    for (c, b) in bounds {
        let v = o.get(c);
        if v.abs() > b {
            return Err(format!("|{}| = {} > {b} at t={}", c.name(), v.abs(), o.t_s()));
        }
    }
    let vdc = o.get(Channel::VDc);
    if !(vdc > 0.0 && vdc < supply_v + 5.0) {
        return Err(format!("V_DC = {vdc} outside (0, {}) at t={}", supply_v + 5.0, o.t_s()));
    }
    Ok(())
}

type Scenario = (Vec<ProfileSet>, f32, f32, f32, bool, bool);

fn run_60s(dt_us: u32, sc: &Scenario, fixed: bool) -> Result<(), TestCaseError> {
    let (sets, ts, ls, supply_v, programmed, parameter) = sc;
    let params = Params::thesis(
        if *programmed { RateSet::Programmed } else { RateSet::Identified },
        CouplingStiffness::Identified,
    );
    let speed_target = if *parameter { SpeedTarget::Parameter } else { SpeedTarget::Map };
    let cfg = Config { dt_us, params, speed_target, effects: Effects::NONE };
    let profile = Profile::new(sets, *ts, *ls).expect("generated profiles are valid");
    let steps = 60_000_000 / u64::from(dt_us);
    if fixed {
        let mut model = Model::new_fx(&cfg).expect("valid config");
        for _ in 0..steps {
            let inp = Inputs { sp: profile.at(model.t_us()), supply_v: *supply_v };
            let o = model.step(&inp).to_f32();
            check(&o, *supply_v, &params).map_err(TestCaseError::fail)?;
        }
        // Counted over the whole test binary: any saturation so far fails.
        prop_assert_eq!(saturations(), 0, "fixed-point operations saturated");
    } else {
        let mut model = Model::new(&cfg).expect("valid config");
        for _ in 0..steps {
            let inp = Inputs { sp: profile.at(model.t_us()), supply_v: *supply_v };
            let o = model.step(&inp);
            check(&o, *supply_v, &params).map_err(TestCaseError::fail)?;
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
    #[test]
    fn random_profiles_stay_physical_at_1ms(sc in scenario()) {
        run_60s(1000, &sc, false)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]
    #[test]
    fn random_profiles_stay_physical_at_100us(sc in scenario()) {
        run_60s(100, &sc, false)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
    #[test]
    fn random_profiles_stay_physical_and_in_range_fixed_point_at_1ms(sc in scenario()) {
        run_60s(1000, &sc, true)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]
    #[test]
    fn random_profiles_stay_physical_and_in_range_fixed_point_at_100us(sc in scenario()) {
        run_60s(100, &sc, true)?;
    }
}
