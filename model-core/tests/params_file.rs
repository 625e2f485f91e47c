//! `Params::set` accepts every key of `data/parameters.toml` and, fed the file, gives
//! exactly what `build.rs` compiled in.

use model_core::params::ParamKeyError;
use model_core::{CouplingStiffness, Params, RateSet};

fn entries() -> Vec<(String, f32)> {
    let text = include_str!("../data/parameters.toml");
    text.lines()
        .filter_map(|l| {
            let l = l.split('#').next()?.trim();
            let (k, v) = l.split_once('=')?;
            Some((k.trim().to_string(), v.trim().parse().expect("number")))
        })
        .collect()
}

#[test]
fn the_parameter_file_round_trips_through_set() {
    for rates in [RateSet::Programmed, RateSet::Identified] {
        for coupling in [CouplingStiffness::Identified, CouplingStiffness::Datasheet] {
            let want = Params::thesis(rates, coupling);
            // Start from something different everywhere, then apply the file.
            let mut p = Params::thesis(
                if rates == RateSet::Programmed { RateSet::Identified } else { RateSet::Programmed },
                if coupling == CouplingStiffness::Identified {
                    CouplingStiffness::Datasheet
                } else {
                    CouplingStiffness::Identified
                },
            );
            p.pid_kp = -1.0;
            for (k, v) in entries() {
                p.set(&k, v, rates, coupling).unwrap_or_else(|e| panic!("{k}: {e:?}"));
            }
            assert_eq!(p, want, "{rates:?} {coupling:?}");
        }
    }
}

#[test]
fn unknown_keys_are_refused() {
    let mut p = Params::default();
    let (r, c) = (RateSet::Identified, CouplingStiffness::Identified);
    for k in ["pid_kq", "ident.accel_hs_up_s", "ident.hs_fwd_s", "prog.partial_decel_fwd_pct", "foo.bar"] {
        assert_eq!(p.set(k, 1.0, r, c), Err(ParamKeyError::Unknown), "{k}");
    }
    p.set("ident.accel_hs_fwd_s", 5.0, r, c).unwrap();
    assert_eq!(p.rates.dir[0].accel_hs_s, 5.0);
    p.set("prog.accel_hs_fwd_s", 7.0, r, c).unwrap();
    assert_eq!(p.rates.dir[0].accel_hs_s, 5.0, "a programmed value must not touch the identified set");
}
