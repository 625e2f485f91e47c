//! The set point that keeps a limit inside: per limit and per knob (throttle scale with
//! the load scale kept, load scale with the throttle scale kept), the largest fraction
//! of the requested scale at which the nominal model stays inside the limit made
//! stricter by the spread the Monte Carlo showed (worst sample − nominal), so the worst
//! case seen would stay inside too, assuming the spread does not grow as the scale
//! falls. Bisection on the fraction in [0, 1] ([`STEPS`] halvings, resolution 1/256 of
//! the requested scale), assuming the peak grows with the scale; the fraction reported
//! is one that was run and passed. Runs are shared between limits (a run evaluates every
//! limit), and bisections run on the worker pool.

use std::collections::HashMap;
use std::sync::Mutex;

use rayon::prelude::*;

use crate::limits::Limit;
use crate::monitor::evaluate;
use crate::run::{Knob, TestRun};

/// Halvings of the fraction.
pub const STEPS: usize = 8;

/// What keeps one limit inside by one knob.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SetPoint {
    /// The knob's scale at most this (and the fraction of the requested scale).
    Scale { scale: f32, fraction: f32 },
    /// Already inside at the requested scale once the spread is allowed for: more
    /// samples, not a lower set point, are what the check lacks.
    AtRequested,
    /// Not inside even at scale 0 of this knob.
    Unreachable,
    /// The knob is at 0 already.
    Off,
}

/// Pass flags of every (tightened) limit, per run, shared by the searches.
struct Cache<'a> {
    test: &'a dyn TestRun,
    limits: &'a [Limit],
    runs: Mutex<HashMap<(u8, u32), Vec<bool>>>,
}

impl Cache<'_> {
    /// Whether every limit of `which` stays inside with `knob` at `fraction` of its
    /// requested scale.
    fn passes(&self, knob: Knob, fraction: f32, which: &[usize]) -> Result<bool, String> {
        let key = (knob as u8, fraction.to_bits());
        let all = |v: &[bool]| which.iter().all(|&i| v.get(i).copied().unwrap_or(false));
        if let Some(v) = self.runs.lock().map_err(|e| e.to_string())?.get(&key) {
            return Ok(all(v));
        }
        let scales = knob.scaled(self.test.scales(), fraction);
        let (runs, _) = evaluate(self.test, self.limits, self.test.config(), scales)?;
        let pass: Vec<bool> = runs.iter().map(|r| !r.crossed).collect();
        let out = all(&pass);
        self.runs.lock().map_err(|e| e.to_string())?.insert(key, pass);
        Ok(out)
    }

    fn search(&self, which: &[usize], knob: Knob) -> Result<SetPoint, String> {
        let requested = knob.of(self.test.scales());
        if requested == 0.0 {
            return Ok(SetPoint::Off);
        }
        if self.passes(knob, 1.0, which)? {
            return Ok(SetPoint::AtRequested);
        }
        if !self.passes(knob, 0.0, which)? {
            return Ok(SetPoint::Unreachable);
        }
        let (mut lo, mut hi) = (0.0f32, 1.0f32);
        for _ in 0..STEPS {
            let mid = 0.5 * (lo + hi);
            if self.passes(knob, mid, which)? {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Ok(SetPoint::Scale { scale: requested * lo, fraction: lo })
    }
}

/// Set points per knob in [`Knob::BOTH`] order: for each of `wanted` (indices into
/// `tightened`, the limits made stricter by their spread) alone, and for all of them
/// together.
pub fn search(
    test: &dyn TestRun,
    tightened: &[Limit],
    wanted: &[usize],
    threads: usize,
) -> Result<(Vec<[SetPoint; 2]>, [SetPoint; 2]), String> {
    let cache = Cache { test, limits: tightened, runs: Mutex::new(HashMap::new()) };
    let mut groups: Vec<Vec<usize>> = wanted.iter().map(|&l| vec![l]).collect();
    groups.push(wanted.to_vec());
    let jobs: Vec<(usize, Knob)> = (0..groups.len()).flat_map(|g| Knob::BOTH.map(|k| (g, k))).collect();
    let work =
        || jobs.par_iter().map(|&(g, k)| cache.search(&groups[g], k)).collect::<Result<Vec<_>, String>>();
    let found = match rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build() {
        Ok(pool) => pool.install(work),
        Err(_) => work(),
    }?;
    let mut pairs: Vec<[SetPoint; 2]> =
        found.chunks(2).map(|c| [c[0], c.get(1).copied().unwrap_or(SetPoint::Off)]).collect();
    let all = pairs.pop().unwrap_or([SetPoint::Off; 2]);
    Ok((pairs, all))
}
