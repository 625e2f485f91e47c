//! Stage 3c: a channel's delay or its lag? A channel recorded late by `d` and one seen
//! through a first-order lag of time constant `τ` have the same linearisation at zero
//! (both add `-τ ẏ`), so the linear selection picks one of the two by rounding: a 45 ms
//! amplifier lag was named a 29 ms delay, which leaves a third of the channel's error
//! and reads as noise in the next round. The choice is made on the simulator instead:
//! both are refitted alone and the selected one gives way to its sibling when the
//! sibling's refit leaves less error.

use super::engine::{Candidate, Options, Twin};
use super::library::ParamSpec;
use super::preparation::Prepared;
use super::refit::{refit, Fit};
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
/// refitted alone, leaves less weighted error. Only causes not yet in the model: one
/// that is already there is refitted where it stands, not traded. Returns the refits
/// done, by candidate index, for the confirmation to reuse.
pub(super) fn choose_dynamics(
    twin: &dyn Twin,
    p: &Prepared,
    s: &Sensitivities,
    o: &Options,
    cands: &[Candidate],
    selected: &mut [(&'static str, f64)],
) -> Vec<(usize, Fit)> {
    let group = |name: &str| s.groups.iter().position(|(g, _)| *g == name);
    let mut done = Vec::new();
    for k in 0..selected.len() {
        let Some(other) = sibling(selected[k].0) else { continue };
        let (Some(own), Some(sib)) = (group(selected[k].0), group(&other)) else { continue };
        if selected.iter().any(|(e, _)| *e == s.groups[sib].0) || !neutral(s, own) || !neutral(s, sib) {
            continue;
        }
        let (a, b) = rayon::join(|| alone(twin, p, s, o, cands, own), || alone(twin, p, s, o, cands, sib));
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
    let group = |name: &str| s.groups.iter().position(|(g, _)| *g == name);
    let mut k = 0;
    while k < list.len() {
        let own = list[k];
        let sib = sibling(s.groups[own].0).and_then(|o| group(&o));
        if let Some(sib) = sib.filter(|g| !list.contains(g) && neutral(s, own) && neutral(s, *g)) {
            list.push(sib);
        }
        k += 1;
    }
}

/// Whether every parameter of group `g` starts at its neutral value (not in the model).
fn neutral(s: &Sensitivities, g: usize) -> bool {
    s.groups[g].1.iter().all(|&i| s.starts[i] == s.specs[i].neutral)
}

/// Group `g` refitted alone from its linear estimate.
fn alone(
    twin: &dyn Twin,
    p: &Prepared,
    s: &Sensitivities,
    o: &Options,
    cands: &[Candidate],
    g: usize,
) -> Option<Fit> {
    let specs: Vec<&ParamSpec> = s.groups[g].1.iter().map(|&i| &s.specs[i]).collect();
    let start: Vec<f64> = cands.get(g)?.params.iter().map(|f| f.value).collect();
    refit(twin, p, o, &specs, &start)
}

#[cfg(test)]
mod tests {
    use super::*;

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
