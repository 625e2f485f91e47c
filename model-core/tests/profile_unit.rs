//! The profile engine: hold/interpolate, scaling, limits, built-ins.

use model_core::profile::*;

fn set(d: f32, t: f32, l: f32, tm: SetMode, lm: SetMode) -> ProfileSet {
    ProfileSet {
        duration_s: d,
        throttle_pct: t,
        load_l_pct: l,
        load_r_pct: -l,
        throttle_mode: tm,
        load_mode: lm,
    }
}

#[test]
fn hold_interpolate_scale_and_end() {
    use SetMode::*;
    let p = Profile::new(
        &[set(1.0, 50.0, 20.0, Hold, Interpolate), set(2.0, 100.0, 60.0, Interpolate, Hold)],
        0.5,
        -1.0,
    )
    .unwrap();
    assert_eq!(p.duration_us(), 3_000_000);
    let a = p.at(500_000);
    assert_eq!(a.throttle_pct, 25.0);
    assert_eq!(a.load_pct, [-40.0, 40.0]); // halfway 20 -> 60, scaled by -1
    let b = p.at(2_000_000); // halfway through the last set: 100 -> 0
    assert_eq!(b.throttle_pct, 25.0);
    assert_eq!(b.load_pct, [-60.0, 60.0]);
    assert_eq!(p.at(3_000_000), SetPoints::default());
}

#[test]
fn rejects_invalid_profiles() {
    use SetMode::*;
    assert_eq!(Profile::new(&[], 1.0, 1.0).unwrap_err(), ProfileError::SetCount(0));
    let eleven = [set(1.0, 0.0, 0.0, Hold, Hold); 11];
    assert_eq!(Profile::new(&eleven, 1.0, 1.0).unwrap_err(), ProfileError::SetCount(11));
    assert_eq!(
        Profile::new(&[set(0.0, 0.0, 0.0, Hold, Hold)], 1.0, 1.0).unwrap_err(),
        ProfileError::Duration(0)
    );
    assert_eq!(
        Profile::new(&[set(1.0, 101.0, 0.0, Hold, Hold)], 1.0, 1.0).unwrap_err(),
        ProfileError::SetPoint(0)
    );
    assert_eq!(
        Profile::new(&[set(1.0, 1.0, 0.0, Hold, Hold)], f32::NAN, 1.0).unwrap_err(),
        ProfileError::Scale
    );
}

#[test]
fn builtins_exist_and_fit_the_plc() {
    for b in Builtin::ALL {
        assert!(!b.sets().is_empty() && b.sets().len() <= MAX_SETS, "{}", b.name());
        assert_eq!(Builtin::from_name(&b.name().to_ascii_lowercase()), Some(b));
        Profile::builtin(b, 1.0, 1.0).unwrap();
    }
}
