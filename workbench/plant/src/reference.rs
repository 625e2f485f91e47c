//! The plant with no effects at the thesis values, built in maps and a built-in
//! profile: the independent f64 reference `host-tests` measures the twin's
//! discretization against (`host-tests/tests/reference_accuracy.rs`).

use model_core::{Builtin, CouplingStiffness, Effects, Maps, Params, RateSet, SpeedTarget};

use crate::effects::PlantEffects;
use crate::plant::{Plant, Setup};

pub use crate::plant::{Sample, CHANNELS};

/// What to simulate: a built-in profile, its scaling, the Curtis rate set and the supply.
#[derive(Debug, Clone, Copy)]
pub struct Case {
    pub profile: Builtin,
    pub throttle_scale: f32,
    pub load_scale: f32,
    pub rates: RateSet,
    /// [V] DPU voltage.
    pub supply_v: f64,
}

/// The reference simulation: the plant of [`Case`].
pub struct Reference(Plant);

impl Reference {
    /// A reference at rest at t = 0, integrating with step `h_ns` [ns].
    ///
    /// # Panics
    /// On a zero step or a supply voltage that is not finite and positive (test input).
    pub fn new(case: &Case, h_ns: u64) -> Self {
        let setup = Setup {
            params: Params::thesis(case.rates, CouplingStiffness::Identified),
            maps: Maps::builtin(),
            speed_target: SpeedTarget::Map,
            sets: case.profile.sets(),
            throttle_scale: f64::from(case.throttle_scale),
            load_scale: f64::from(case.load_scale),
            supply_v: case.supply_v,
            library: Effects::NONE,
            bench: PlantEffects::default(),
        };
        match Plant::new(&setup, h_ns) {
            Ok(p) => Self(p),
            Err(e) => panic!("reference case: {e}"),
        }
    }

    /// Profile duration [µs].
    pub fn duration_us(&self) -> u64 {
        self.0.duration_us()
    }

    /// Run to the end of the profile; a sample every `every_us` [µs] (a multiple of the
    /// step), the first at `every_us`, as the twin emits its outputs at the end of each
    /// step.
    ///
    /// # Panics
    /// If `every_us` is not a multiple of the step or the run diverges (test input).
    pub fn run(self, every_us: u64) -> Vec<Sample> {
        match self.0.run(every_us) {
            Ok(s) => s,
            Err(e) => panic!("reference run: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tables::Tables;
    use model_core::Channel;

    #[test]
    fn steady_state_balances_the_shaft_torques() {
        // End of TP12's 100 % plateau (t = 16 s): the command is at the 2100 rpm limit,
        // and on each side the flange carries what the load node takes: the friction map
        // at the side's own speed (the open differential lets them differ) plus the load
        // map's torque at load set point 0 (2 N m regenerating at full throttle).
        let case = Case {
            profile: Builtin::TP12,
            throttle_scale: 1.0,
            load_scale: 0.0,
            rates: RateSet::Identified,
            supply_v: 24.0,
        };
        let out = Reference::new(&case, 20_000).run(100_000);
        let s = out.iter().find(|s| s.t_us == 16_000_000).unwrap();
        let speed = s.get(Channel::SuTMotorEnc).unwrap();
        assert!((speed - 2100.0).abs() < 0.01, "{speed}");
        let tab = Tables::new(&Maps::builtin());
        let sides =
            [(0, Channel::TKistlerL, Channel::CKistlerL), (1, Channel::TKistlerR, Channel::CKistlerR)];
        for (i, w, c) in sides {
            let want = tab.friction[i].at(s.get(w).unwrap()) + tab.load_torque[i].at(100.0, 0.0);
            let torque = s.get(c).unwrap();
            assert!((torque - want).abs() < 0.01, "side {i}: {torque} vs {want}");
        }
        // The open differential balances torque, not speed: L, with less friction at a
        // given speed, runs faster than R.
        let (l, r) = (s.get(Channel::TKistlerL).unwrap(), s.get(Channel::TKistlerR).unwrap());
        assert!(l > r + 1.0, "L {l} rpm, R {r} rpm");
    }
}
