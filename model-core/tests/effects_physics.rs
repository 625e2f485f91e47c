//! Each effect does what its documentation says, and nothing when off.

mod common;
use common::*;
use model_core::*;

fn tp07(fx: Effects) -> Vec<Outputs> {
    let cfg = Config { effects: fx, ..Config::default() };
    Simulation::new(&cfg, Profile::builtin(Builtin::TP07, 1.0, 1.0).unwrap(), 24.0).unwrap().collect()
}

fn max_abs_diff(a: &[Outputs], b: &[Outputs], c: Channel) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x.get(c) - y.get(c)).abs()).fold(0.0, f32::max)
}

#[test]
fn every_effect_changes_the_outputs_and_none_is_bit_identical() {
    let base = tp07(Effects::NONE);
    let cases: &[(&str, &str, f32)] = &[
        ("differential_friction", "coulomb_nm", 3.0),
        ("axle_friction_scale", "left", 1.3),
        ("gear_backlash", "backlash_deg", 2.0),
        ("controller_delay", "delay_s", 0.1),
        ("inverter_rate_scale", "decel_fwd", 0.7),
        ("coupling_stiffness", "stiffness_nm_per_rad", 10310.0),
        ("coupling_damping", "damping_nm_s_per_rad", 20.0),
        ("inertia_scale", "sut", 1.5),
        ("connector_resistance", "resistance_ohm", 0.04),
        ("supply_resistance", "resistance_ohm", 0.01),
        ("regen_efficiency", "extra_loss", 0.2),
        ("sensor_offset", "c_kistler_l", 1.0),
        ("sensor_gain", "c_kistler_r", 1.05),
        ("sensor_gain", "sutmotorenc", 1.02),
        ("sensor_gain", "i_dpu_2_7", 1.03),
    ];
    for (id, param, v) in cases {
        let mut fx = Effects::NONE;
        fx.set(id, param, *v).unwrap();
        let out = tp07(fx);
        let changed = Channel::ALL.iter().any(|c| max_abs_diff(&base, &out, *c) > 1e-3);
        assert!(changed, "{id}.{param} = {v} changed nothing");
        assert!(out.iter().all(|o| o.values.iter().all(|v| v.is_finite())), "{id}: non-finite output");
    }
    // Off means off: the same bits as the thesis model.
    let again = tp07(Effects::NONE);
    assert!(base.iter().zip(&again).all(|(a, b)| a.values.map(f32::to_bits) == b.values.map(f32::to_bits)));
}

#[test]
fn backlash_parts_the_motor_from_the_axles_only_at_torque_reversals() {
    let mut fx = Effects::NONE;
    fx.gear_backlash.backlash_deg = 3.0;
    let with = tp07(fx);
    let base = tp07(Effects::NONE);
    let ratio = Params::default().sut_gear_ratio;
    // Mismatch between the motor encoder and the axle speeds: zero in contact (up to the
    // shafts' own twist), large while the gears are apart.
    let mismatch = |o: &Outputs| (o.get(Channel::SuTMotorEnc) - ratio * o.get(Channel::SpeedTot)).abs();
    let worst_with = with.iter().map(mismatch).fold(0.0, f32::max);
    let worst_base = base.iter().map(mismatch).fold(0.0, f32::max);
    assert!(worst_with > 2.0 * worst_base + 5.0, "backlash mismatch {worst_with} vs base {worst_base}");
    // Steady plateaus are unchanged (the gears are engaged there).
    let (a, b) =
        (mean(&with, Channel::SuTMotorEnc, 14.0, 16.0), mean(&base, Channel::SuTMotorEnc, 14.0, 16.0));
    assert!((a - b).abs() < 1.0, "{a} vs {b}");
}

/// While the gears are apart the motor encoder reads the motor, which the speed
/// controller keeps on its command, not the differential coasting on the other side of
/// the gap (the physics plant's encoder does the same).
#[test]
fn the_motor_encoder_follows_the_free_motor_not_the_coasting_axles() {
    let mut fx = Effects::NONE;
    fx.gear_backlash.backlash_deg = 3.0;
    let with = tp07(fx);
    let ratio = Params::default().sut_gear_ratio;
    let (mut to_motor, mut to_axles, mut free) = (0.0, 0.0, 0);
    for o in &with {
        let (enc, cmd, axles) =
            (o.get(Channel::SuTMotorEnc), o.get(Channel::SpeedCmd), ratio * o.get(Channel::SpeedTot));
        if (enc - axles).abs() > 10.0 {
            to_motor += (enc - cmd).abs();
            to_axles += (axles - cmd).abs();
            free += 1;
        }
    }
    assert!(free > 10, "the gears never parted ({free} samples)");
    assert!(to_motor < 0.25 * to_axles, "encoder off its command by {to_motor}, the axles by {to_axles}");
}

#[test]
fn controller_delay_shifts_the_speed_response() {
    let mut fx = Effects::NONE;
    fx.controller_delay_s = 0.2;
    let cfg = Config { effects: fx, ..Config::default() };
    let sets = steps(&[(1.0, 0.0, 0.0), (4.0, 100.0, 0.0)]);
    let with = run(&cfg, &sets);
    let base = run(&Config::default(), &sets);
    let cross = |out: &[Outputs]| out.iter().find(|o| o.get(Channel::SuTMotorEnc) > 1000.0).unwrap().t_s();
    let shift = cross(&with) - cross(&base);
    assert!((shift - 0.2).abs() < 0.01, "shift {shift}");
}
