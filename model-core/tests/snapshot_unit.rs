//! A model resumed from another's snapshot steps on bit for bit as that model does.

mod common;

use model_core::*;

/// TP07 at 70 % throttle and loads at -0.6, with the effects that carry state of their
/// own (the controller's delay line, the gear backlash, sensor lags and delays, the
/// supply's sag): every part of the state must travel in the snapshot.
#[test]
fn a_resumed_model_continues_bit_for_bit() {
    let mut fx = Effects::NONE;
    fx.controller_delay_s = 0.03;
    fx.gear_backlash.backlash_deg = 2.0;
    fx.sensor_lag_s[0] = 0.02;
    fx.sensor_delay_s[3] = 0.015;
    fx.supply_resistance = 0.02;
    let cfg = Config { effects: fx, ..common::config(RateSet::Identified, 1000) };
    let profile = Profile::builtin(Builtin::TP07, 0.7, -0.6).expect("a built-in profile");
    let inputs: Vec<Inputs> =
        (0..20_000u64).map(|k| Inputs { sp: profile.at(k * 1000), supply_v: 24.0 }).collect();
    let bits = |o: &Outputs| MEASURED.iter().map(|c| o.get(*c).to_bits()).collect::<Vec<u32>>();
    let mut whole = Model::new(&cfg).expect("a model");
    let mut snaps = Vec::new();
    let mut out = Vec::new();
    for (k, inp) in inputs.iter().enumerate() {
        if k % 4_999 == 0 {
            snaps.push((k, whole.snapshot()));
        }
        out.push(bits(&whole.step(inp)));
    }
    assert!(snaps.len() >= 4);
    for (k, snap) in &snaps {
        let mut resumed = Model::new(&cfg).expect("a model");
        resumed.resume(snap);
        assert_eq!(resumed.t_us(), *k as u64 * 1000, "the snapshot holds the time");
        for (j, inp) in inputs.iter().enumerate().skip(*k) {
            assert_eq!(bits(&resumed.step(inp)), out[j], "resumed at step {k}, step {j}");
        }
    }
    // A model started afresh differs: the snapshot is what carries the past.
    let mut fresh = Model::new(&cfg).expect("a model");
    let (k, _) = snaps[2];
    let later: Vec<_> = inputs[k..k + 2000].iter().map(|inp| bits(&fresh.step(inp))).collect();
    assert_ne!(later, out[k..k + 2000].to_vec());
}
