//! Stage 3c: a channel's delay or its lag? A channel recorded late by `d` and one seen
//! through a first-order lag of time constant `τ` have the same linearisation at zero
//! (both add `-τ ẏ`), so the linear selection picks one of the two by rounding: a 45 ms
//! amplifier lag was named a 29 ms delay, which leaves a third of the channel's error
//! and reads as noise in the next round. The choice is made on the simulator instead:
//! both are refitted alone and the selected one gives way to its sibling when the
//! sibling's refit leaves less error.

use super::engine::{Candidate, Options, Twin};
use super::preparation::Prepared;
use super::refit::{refit_alone, Fit};
use super::sensitivities::Sensitivities;

const DELAY: &str = "sensor_delay.";
const LAG: &str = "sensor_lag.";

/// The other dynamic cause of the same channel: the lag of a delay and the delay of a lag.
fn sibling(effect: &str) -> Option<String> {
    match (effect.strip_prefix(DELAY), effect.strip_prefix(LAG)) {
        (Some(channel), _) => Some(format!("{LAG}{channel}")),
        (_, Some(channel)) => Some(format!("{DELAY}{channel}")),
        _ => None,
    }
}

/// Replace each selected delay (lag) by the same channel's lag (delay) when the sibling,
/// refitted alone, leaves less weighted error ([`sibling_group`]). Returns the refits
/// done, by candidate index, for the confirmation to reuse.
pub(super) fn choose_dynamics(
    twin: &dyn Twin,
    p: &Prepared,
    s: &Sensitivities,
    o: &Options,
    cands: &[Candidate],
    selected: &mut [(&'static str, f64)],
) -> Vec<(usize, Fit)> {
    let mut done = Vec::new();
    for k in 0..selected.len() {
        let Some(own) = s.groups.iter().position(|(g, _)| *g == selected[k].0) else { continue };
        let Some(sib) = sibling_group(s, own) else { continue };
        if selected.iter().any(|(e, _)| *e == s.groups[sib].0) {
            continue;
        }
        let fit = |g: usize| refit_alone(twin, p, o, s, cands, g);
        let (a, b) = rayon::join(|| fit(own), || fit(sib));
        if let (Some(a), Some(b)) = (&a, &b) {
            if b.energy < a.energy {
                selected[k].0 = s.groups[sib].0;
            }
        }
        done.extend(a.map(|f| (own, f)));
        done.extend(b.map(|f| (sib, f)));
    }
    done
}

/// The leaders `list` (candidate indices) with the sibling of each delay or lag among
/// them added, so that the ranking also compares the two on the simulator: a leader
/// outside the set (a single lead) was otherwise named without its sibling refitted (an
/// 82 ms skew of I_XLMR 2.3 named a 78 ms lag, the delay left at its linear guess).
pub(super) fn with_siblings(s: &Sensitivities, list: &mut Vec<usize>) {
    for k in 0..list.len() {
        if let Some(sib) = sibling_group(s, list[k]).filter(|g| !list.contains(g)) {
            list.push(sib);
        }
    }
}

/// The group of group `g`'s sibling, when both are in the library and neither is in
/// the model yet (one already there is refitted where it stands, not traded).
fn sibling_group(s: &Sensitivities, g: usize) -> Option<usize> {
    let name = sibling(s.groups[g].0)?;
    let sib = s.groups.iter().position(|(x, _)| *x == name)?;
    (neutral(s, g) && neutral(s, sib)).then_some(sib)
}

/// Whether every parameter of group `g` starts at its neutral value (not in the model).
fn neutral(s: &Sensitivities, g: usize) -> bool {
    s.groups[g].1.iter().all(|&i| s.starts[i] == s.specs[i].neutral)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::library::ParamSpec;

    #[test]
    fn a_delay_and_a_lag_of_one_channel_are_siblings() {
        assert_eq!(sibling("sensor_delay.i_dpu_2_7").as_deref(), Some("sensor_lag.i_dpu_2_7"));
        assert_eq!(sibling("sensor_lag.c_kistler_l").as_deref(), Some("sensor_delay.c_kistler_l"));
        assert_eq!(sibling("controller_delay"), None);
        assert_eq!(sibling("sensor_gain.i_dc"), None);
    }

    /// A lag among the leaders brings its delay along (and only once); a physical
    /// leader brings nothing.
    #[test]
    fn a_dynamic_leader_is_refitted_beside_its_sibling() {
        let names = ["controller_delay", "sensor_lag.i_dc", "sensor_delay.i_dc"];
        let specs: Vec<ParamSpec> = names
            .iter()
            .map(|n| {
                let lib = super::super::library::library(&crate::Options::default().params);
                lib.into_iter().find(|sp| sp.cause == *n).expect("in the library")
            })
            .collect();
        let s = Sensitivities {
            starts: specs.iter().map(|sp| sp.neutral).collect(),
            groups: names.iter().enumerate().map(|(i, n)| (*n, vec![i])).collect(),
            specs,
            ..Sensitivities::default()
        };
        let mut list = vec![0, 1];
        with_siblings(&s, &mut list);
        assert_eq!(list, [0, 1, 2]);
        let mut list = vec![2, 1];
        with_siblings(&s, &mut list);
        assert_eq!(list, [2, 1]);
    }
}
