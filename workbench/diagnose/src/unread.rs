//! What a twin provably never reads on a campaign, so that changing it leaves every
//! run bit for bit as it was and its response costs no simulation.
//!
//! Only structural facts of the model, from the runs' inputs and the fitted channels,
//! never from a response that happened to be 0 (a delay step shorter than a model step
//! gives 0 at one value and not at another):
//! - the reverse direction: the direction switch is the throttle set point's sign (a
//!   delayed command starts at 0 and the speed command ramps towards a target of that
//!   sign without crossing 0), so a campaign without a negative throttle set point never
//!   reads the reverse speed map, the reverse ramp rates or their scales;
//! - the load motors' phase-current maps feed only their phase-current channels, which a
//!   bench file rarely has (the clamps measure the DC side, `I_XLML`/`I_XLMR`).

use model_core::{Channel, SetPoints};
use simrod_io::datadir::{ModelData, ParamLine};

use super::library::ParamSpec;

/// The reverse speed map's file.
const SPEED_REV: &str = "speed_map_rev.csv";
/// The load motors' phase-current maps' files, L and R.
const LOAD_CURRENT: [&str; 2] = ["load_current_L.csv", "load_current_R.csv"];

/// What one campaign's twin never reads (the default: everything is read).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Unread {
    /// No run has a negative throttle set point.
    reverse: bool,
    /// The phase-current channel of load motor L, R is not fitted.
    phase: [bool; 2],
}

impl Unread {
    /// From the runs' set points and the fitted channels.
    pub fn of(sps: &[SetPoints], channels: &[Channel]) -> Self {
        Self {
            reverse: !sps.iter().any(|sp| sp.throttle_pct < 0.0),
            phase: [Channel::ILmlPhase, Channel::ILmrPhase].map(|c| !channels.contains(&c)),
        }
    }

    /// Whether no value of table `file` (a data directory's file name) is read.
    pub fn table(&self, file: &str) -> bool {
        match LOAD_CURRENT.iter().position(|f| *f == file) {
            Some(i) => self.phase[i],
            None => file == SPEED_REV && self.reverse,
        }
    }

    /// Whether `data` differs from `base` only in what is never read (so a run on it is
    /// the run on `base`): `data` with those tables and keys put back as `base` has them
    /// is `base`.
    pub fn only_unread_differ(&self, base: &ModelData, data: &ModelData) -> bool {
        let mut d = data.clone();
        if self.table(SPEED_REV) {
            d.speed_rev = base.speed_rev.clone();
        }
        for (i, file) in LOAD_CURRENT.iter().enumerate() {
            if self.table(file) {
                d.load_current[i] = base.load_current[i].clone();
            }
        }
        for (line, b) in d.params.iter_mut().zip(&base.params) {
            if matches!(line, ParamLine::Entry { key, .. } if self.key(key)) {
                *line = b.clone();
            }
        }
        d == *base
    }

    /// Whether `parameters.toml` key `key` is not read: the reverse ramp rates.
    pub fn key(&self, key: &str) -> bool {
        self.reverse && key.starts_with("ident.") && key.ends_with("_rev_s")
    }

    /// Whether library parameter `s` is not read: the reverse ramp rates' scales.
    pub fn param(&self, s: &ParamSpec) -> bool {
        self.reverse && s.effect == "inverter_rate_scale" && s.param.ends_with("_rev")
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use model_core::Effects;

    use super::*;
    use crate::engine::Twin;
    use crate::library::{library, with_values};
    use crate::twin::{tp07_run, Campaign};

    /// TP07 forward (and reverse), fitted on the DC-side channels.
    fn twin(throttle: f32) -> Campaign {
        let channels = vec![Channel::SuTMotorEnc, Channel::IDc, Channel::IXlml22, Channel::CKistlerL];
        Campaign::new(vec![tp07_run(throttle, 0.5, channels)]).expect("a campaign")
    }

    #[test]
    fn what_a_forward_run_does_not_read_leaves_it_as_it_was() {
        let (fx, stride) = (Effects::NONE, 3);
        for (throttle, reverse) in [(0.7, false), (-0.7, true)] {
            let t = twin(throttle);
            let u = Unread::of(&t.set_points(), t.channels());
            let base = t.data().expect("the built-in data");
            let sim0 = t.run_data(&base, &fx, stride).expect("base");
            let same = |d: &Arc<_>, fx: &Effects| t.run_data(d, fx, stride).expect("moved") == sim0;
            // Tables: what is said unread leaves the run as it was; what the other
            // direction reads changes it (so the test is not empty).
            let moved =
                |file| Arc::new(crate::empirical::reshaped(&base, file, |v, _| 0.9 * v).expect("a map"));
            for file in ["speed_map_rev.csv", "load_current_L.csv", "load_current_R.csv"] {
                let d = moved(file);
                assert_eq!(u.table(file), same(&d, &fx), "{file}, throttle {throttle}");
                assert_eq!(u.only_unread_differ(&base, &d), u.table(file), "{file}, throttle {throttle}");
            }
            assert!(!u.only_unread_differ(&base, &moved("speed_map_fwd.csv")), "the forward map is read");
            assert_eq!(u.table("speed_map_rev.csv"), !reverse);
            assert!(!u.table("speed_map_fwd.csv") && !u.table("axle_friction_L.csv"));
            // parameters.toml keys (which rates a run uses depends on its speeds: in
            // reverse, some rate of the direction must change it).
            let keys = ["ident.accel_hs_rev_s", "ident.low_accel_rev_s", "ident.partial_decel_rev_s"];
            let mut changed = false;
            for key in keys {
                let mut d = (*base).clone();
                for line in &mut d.params {
                    if let ParamLine::Entry { key: k, value, .. } = line {
                        if k == key {
                            *value *= 1.5;
                        }
                    }
                }
                assert_eq!(u.only_unread_differ(&base, &d), u.key(key), "{key}, throttle {throttle}");
                let unchanged = same(&Arc::new(d), &fx);
                assert_eq!(u.key(key), !reverse, "{key}, throttle {throttle}");
                assert!(!u.key(key) || unchanged, "{key} said unread, throttle {throttle}");
                changed |= !unchanged;
            }
            assert_eq!(changed, reverse, "a reverse rate changes the reverse run");
            assert!(!u.key("ident.accel_hs_fwd_s"));
            // Library parameters: the reverse scales, unread forward, move the reverse run.
            for s in
                library(&model_core::Params::default()).iter().filter(|s| s.effect == "inverter_rate_scale")
            {
                let unchanged = same(&base, &with_values(&fx, &[s], &[s.neutral + 0.2]));
                let rev = s.param.ends_with("_rev");
                assert_eq!(u.param(s), rev && !reverse, "{}, throttle {throttle}", s.param);
                assert!(!u.param(s) || unchanged, "{} said unread, throttle {throttle}", s.param);
                assert!(!(rev && reverse && unchanged), "{} moves the reverse run", s.param);
            }
        }
    }
}
