//! Many runs of one test, each with its own draw of the uncertain parameters, on a
//! worker pool. Sample `i` draws from stream `i` of the seed, and the results are
//! reduced with operations that do not depend on their order (counts, minima, then a
//! sort by sample index), so a seed gives the same numbers on any number of threads.

use rayon::prelude::*;
use simrod_io::progress::Progress;

use crate::limits::Limit;
use crate::monitor::{evaluate, LimitRun};
use crate::run::TestRun;
use crate::uncertainty::Uncertainty;

/// One limit in one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcome {
    pub margin: f64,
    pub peak: f64,
    pub t_s: f64,
    pub crossed: bool,
}

impl From<&LimitRun> for Outcome {
    fn from(r: &LimitRun) -> Self {
        Self { margin: r.margin, peak: r.peak, t_s: r.t_s, crossed: r.crossed }
    }
}

/// One sample: its draw and every limit's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// 1-based (0 is the nominal model).
    pub index: u64,
    pub values: Vec<f64>,
    /// An effect parameter was drawn beyond its range and clipped to it.
    pub clipped: bool,
    pub limits: Vec<Outcome>,
}

/// All samples, in index order, and per limit the smallest margin any sample had in
/// each time bin.
#[derive(Debug, Clone, PartialEq)]
pub struct MonteCarlo {
    pub samples: Vec<Sample>,
    pub envelope: Vec<Vec<f32>>,
}

/// What the workers reduce: order-independent by construction.
#[derive(Debug, Clone, Default)]
struct Acc {
    samples: Vec<Sample>,
    envelope: Vec<Vec<f32>>,
    /// The failed sample with the lowest index, and why.
    error: Option<(u64, String)>,
}

impl Acc {
    fn add(mut self, r: Result<(Sample, Vec<LimitRun>), (u64, String)>) -> Self {
        match r {
            Ok((s, runs)) => {
                if self.envelope.is_empty() {
                    self.envelope = runs.iter().map(|r| r.trace.clone()).collect();
                } else {
                    for (e, r) in self.envelope.iter_mut().zip(&runs) {
                        min_into(e, &r.trace);
                    }
                }
                self.samples.push(s);
            }
            Err(e) => self.error = first(self.error.take(), Some(e)),
        }
        self
    }

    fn merge(mut self, o: Acc) -> Self {
        if self.envelope.is_empty() {
            self.envelope = o.envelope;
        } else {
            for (e, x) in self.envelope.iter_mut().zip(&o.envelope) {
                min_into(e, x);
            }
        }
        self.samples.extend(o.samples);
        self.error = first(self.error, o.error);
        self
    }
}

fn min_into(e: &mut [f32], x: &[f32]) {
    for (a, b) in e.iter_mut().zip(x) {
        // NaN-free minimum, so the order of merging cannot matter.
        if b < a || a.is_nan() {
            *a = *b;
        }
    }
}

fn first(a: Option<(u64, String)>, b: Option<(u64, String)>) -> Option<(u64, String)> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if x.0 <= y.0 { x } else { y }),
        (x, y) => x.or(y),
    }
}

/// Run samples `1..=n` of `test` under `u` with `seed` on `threads` workers.
pub fn run(
    test: &dyn TestRun,
    limits: &[Limit],
    u: &Uncertainty,
    n: u64,
    seed: u64,
    threads: usize,
    progress: &Progress,
) -> Result<MonteCarlo, String> {
    let one = |i: u64| -> Result<(Sample, Vec<LimitRun>), (u64, String)> {
        let values = u.draw(seed, i);
        let fail = |m: String| {
            let drawn: Vec<String> =
                u.items.iter().zip(&values).map(|(it, v)| format!("{} = {v}", it.target.name())).collect();
            (i, format!("sample {i} ({}): {m}", drawn.join(", ")))
        };
        let (config, clipped) = u.apply(test.config(), &values).map_err(fail)?;
        let (runs, _) = evaluate(test, limits, &config, test.scales()).map_err(fail)?;
        progress.tick(&format!("sample {i}"));
        let outcomes = runs.iter().map(Outcome::from).collect();
        Ok((Sample { index: i, values, clipped, limits: outcomes }, runs))
    };
    let work =
        || (1..=n).into_par_iter().map(one).fold(Acc::default, Acc::add).reduce(Acc::default, Acc::merge);
    let acc = match rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build() {
        Ok(pool) => pool.install(work),
        Err(_) => work(),
    };
    if let Some((_, e)) = acc.error {
        return Err(e);
    }
    let mut samples = acc.samples;
    samples.sort_by_key(|s| s.index);
    Ok(MonteCarlo { samples, envelope: acc.envelope })
}
