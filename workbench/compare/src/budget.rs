//! Error budget: which operating regions a channel's squared error comes from.
//!
//! For a region R: `error_share = Σ_{k∈R} e² / Σ_k e²` and `sample_share = |R| / N`
//! over the samples with a finite residual. A region whose error share is much larger
//! than its sample share is where the model is wrong ("72 % of the error in 15 % of
//! the time"). Single regions overlap (a sample is in one motion, one direction, one
//! load mode); the combined regions direction × motion × load partition the run.

use serde::Serialize;

use super::regions::{combined_name, Class, Direction, LoadMode, Motion, LIMIT_NAMES, N_COMBINED};

/// What kind of region a share belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RegionKind {
    /// One dimension (motion, direction, load mode or a limit).
    Single,
    /// Direction × motion × load mode.
    Combined,
}

/// One region's share of a channel's error.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegionShare {
    /// E.g. `decelerating` or `forward / decelerating / loads regenerating`.
    pub region: String,
    pub kind: RegionKind,
    /// Σe² in the region / Σe² of the run (0 when the run has no error).
    pub error_share: f64,
    /// Samples in the region / samples of the run.
    pub sample_share: f64,
    /// Samples in the region.
    pub samples: usize,
}

/// The budget of one residual over the classified samples. Regions without samples
/// are left out.
pub fn budget(classes: &[Class], e: &[f64]) -> Vec<RegionShare> {
    let mut comb_e = [0.0f64; N_COMBINED];
    let mut comb_n = [0usize; N_COMBINED];
    let mut lim_e = [0.0f64; LIMIT_NAMES.len()];
    let mut lim_n = [0usize; LIMIT_NAMES.len()];
    let (mut any_e, mut any_n) = (0.0f64, 0usize);
    let (mut total_e, mut total_n) = (0.0f64, 0usize);
    for (c, &r) in classes.iter().zip(e) {
        if !r.is_finite() {
            continue;
        }
        let e2 = r * r;
        total_e += e2;
        total_n += 1;
        let i = c.combined();
        if let (Some(se), Some(sn)) = (comb_e.get_mut(i), comb_n.get_mut(i)) {
            *se += e2;
            *sn += 1;
        }
        if c.limits != 0 {
            any_e += e2;
            any_n += 1;
        }
        for ((flag, _), (le, ln)) in LIMIT_NAMES.iter().zip(lim_e.iter_mut().zip(lim_n.iter_mut())) {
            if c.limits & flag != 0 {
                *le += e2;
                *ln += 1;
            }
        }
    }
    let share = |se: f64, sn: usize| {
        (
            if total_e > 0.0 { se / total_e } else { 0.0 },
            if total_n > 0 { sn as f64 / total_n as f64 } else { 0.0 },
        )
    };
    let mut out = Vec::new();
    let mut push = |name: String, kind: RegionKind, se: f64, sn: usize| {
        if sn == 0 {
            return;
        }
        let (error_share, sample_share) = share(se, sn);
        out.push(RegionShare { region: name, kind, error_share, sample_share, samples: sn });
    };
    let sum_where = |f: &dyn Fn(Direction, Motion, LoadMode) -> bool| {
        let mut se = 0.0;
        let mut sn = 0;
        for (i, (e, n)) in comb_e.iter().zip(comb_n.iter()).enumerate() {
            let (d, m, l) = super::regions::combined_parts(i);
            if f(d, m, l) {
                se += e;
                sn += n;
            }
        }
        (se, sn)
    };
    for m in Motion::ALL {
        let (se, sn) = sum_where(&|_, mm, _| mm == m);
        push(m.name().to_string(), RegionKind::Single, se, sn);
    }
    for d in Direction::ALL {
        let (se, sn) = sum_where(&|dd, _, _| dd == d);
        push(d.name().to_string(), RegionKind::Single, se, sn);
    }
    for l in LoadMode::ALL {
        let (se, sn) = sum_where(&|_, _, ll| ll == l);
        push(l.name().to_string(), RegionKind::Single, se, sn);
    }
    push("at a limit".to_string(), RegionKind::Single, any_e, any_n);
    push("within limits".to_string(), RegionKind::Single, total_e - any_e, total_n - any_n);
    for ((_, name), (se, sn)) in LIMIT_NAMES.iter().zip(lim_e.iter().zip(lim_n.iter())) {
        push((*name).to_string(), RegionKind::Single, *se, *sn);
    }
    for (i, (se, sn)) in comb_e.iter().zip(comb_n.iter()).enumerate() {
        push(combined_name(i), RegionKind::Combined, *se, *sn);
    }
    out
}

/// The `k` combined regions with the largest error share, largest first.
pub fn top_combined(shares: &[RegionShare], k: usize) -> Vec<RegionShare> {
    let mut v: Vec<RegionShare> = shares.iter().filter(|s| s.kind == RegionKind::Combined).cloned().collect();
    v.sort_by(|a, b| b.error_share.total_cmp(&a.error_share));
    v.truncate(k);
    v
}

/// Share of the error in the single region called `name` (0 if it has no samples).
pub fn share_of(shares: &[RegionShare], name: &str) -> f64 {
    shares.iter().find(|s| s.kind == RegionKind::Single && s.region == name).map_or(0.0, |s| s.error_share)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn class(m: Motion, d: Direction, l: LoadMode, limits: u8) -> Class {
        Class { motion: m, direction: d, load: l, limits }
    }

    #[test]
    fn shares_add_up_and_locate_the_error() {
        use Direction::*;
        use LoadMode::*;
        use Motion::*;
        let mut classes = vec![class(Steady, Forward, Unloaded, 0); 80];
        classes.extend(vec![class(Decelerating, Forward, Regenerating, 1); 20]);
        let mut e = vec![0.1; 80];
        e.extend(vec![1.0; 20]);
        let b = budget(&classes, &e);
        let total = 80.0 * 0.01 + 20.0;
        let regen = share_of(&b, "loads regenerating");
        assert!((regen - 20.0 / total).abs() < 1e-12);
        assert!((share_of(&b, "speed limit") - regen).abs() < 1e-12);
        let comb_sum: f64 = b.iter().filter(|s| s.kind == RegionKind::Combined).map(|s| s.error_share).sum();
        assert!((comb_sum - 1.0).abs() < 1e-12);
        let top = top_combined(&b, 3);
        assert_eq!(top.len(), 2); // regions without samples are left out
        assert_eq!(top[0].region, "forward / decelerating / loads regenerating");
        assert!((top[0].sample_share - 0.2).abs() < 1e-12);
    }

    #[test]
    fn zero_residual_gives_zero_shares() {
        let classes = vec![class(Motion::Steady, Direction::Forward, LoadMode::Unloaded, 0); 10];
        let b = budget(&classes, &[0.0; 10]);
        assert!(b.iter().all(|s| s.error_share == 0.0));
        assert_eq!(share_of(&b, "steady"), 0.0);
    }
}
