//! `simrod check`: will a test stay inside the bench's limits?
//!
//! A test ([`run::TestRun`]: a profile, or any run of the twin that yields outputs per
//! step, such as a closed XiL loop) is run on the nominal model and every limit of a
//! limits file ([`limits`]) is evaluated on every step ([`monitor`]): the peak, the
//! margin, when and in which part of the test. With an uncertainty ([`uncertainty`]:
//! distributions of parameters and effect parameters, from a file, an identification or
//! a diagnosis) the test runs again for each of N drawn models ([`montecarlo`]): per
//! limit the probability of a violation with its Clopper–Pearson interval
//! ([`binomial`]) and the worst case seen. For what crosses, [`setpoint`] finds the
//! largest throttle or load scale that keeps it inside. [`report`] renders a terminal
//! table, JSON and an HTML page with every limit's margin over time.
//!
//! The verdict a test-approval workflow acts on: without an uncertainty, a limit is
//! inside or crossed; with one, it is *safe* at confidence P when the upper end of the
//! interval of its violation probability is at most 1 − P, *likely crossed* when the
//! estimate itself is above 1 − P, and *undecided* (more samples needed) in between.
//! The test is approved when every limit is inside or safe.

pub mod binomial;
pub mod delay;
pub mod limits;
pub mod monitor;
pub mod montecarlo;
pub mod quantity;
pub mod report;
pub mod run;
pub mod setpoint;
pub mod uncertainty;

use std::time::Instant;

use simrod_io::progress::Progress;

use delay::DelayMargin;
use limits::{Limit, Limits};
use monitor::{evaluate, LimitRun};
use montecarlo::Outcome;
use quantity::Dynamics;
use run::{Scales, TestRun};
use setpoint::SetPoint;
use uncertainty::Uncertainty;

/// How to check.
#[derive(Debug, Clone)]
pub struct CheckOptions<'a> {
    pub limits: &'a Limits,
    /// `None`: the nominal model only.
    pub uncertainty: Option<&'a Uncertainty>,
    pub samples: u64,
    pub seed: u64,
    /// P: a limit is safe when its violation probability is below 1 − P, shown with
    /// confidence P.
    pub confidence: f64,
    pub threads: usize,
    /// Draw a progress bar on stderr (when it is a terminal).
    pub progress: bool,
    /// Search the set points that keep crossed limits inside.
    pub set_points: bool,
    /// A closed loop's delay margin, a condition of approval (found by the caller).
    pub delay: Option<DelayMargin>,
}

/// What a check found out about one limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Nominal model only: inside.
    Inside,
    /// Nominal model only: crossed.
    Crossed,
    /// Violation probability below 1 − P, at confidence P.
    Safe,
    /// Violation probability estimated above 1 − P.
    LikelyCrossed,
    /// Neither shown safe nor likely crossed: more samples needed.
    Undecided,
}

impl Verdict {
    /// Whether the test may run as far as this limit is concerned.
    pub fn passes(self) -> bool {
        matches!(self, Verdict::Inside | Verdict::Safe)
    }

    /// Its name in JSON.
    pub fn key(self) -> &'static str {
        match self {
            Verdict::Inside => "inside",
            Verdict::Crossed => "crossed",
            Verdict::Safe => "safe",
            Verdict::LikelyCrossed => "likely_crossed",
            Verdict::Undecided => "undecided",
        }
    }

    /// One word or two, for tables.
    pub fn word(self) -> &'static str {
        match self {
            Verdict::Inside => "inside",
            Verdict::Crossed => "CROSSED",
            Verdict::Safe => "safe",
            Verdict::LikelyCrossed => "LIKELY CROSSED",
            Verdict::Undecided => "undecided",
        }
    }
}

/// The Monte Carlo's view of one limit.
#[derive(Debug, Clone, PartialEq)]
pub struct LimitMc {
    pub violations: u64,
    pub samples: u64,
    /// Violation probability estimate, `violations / samples`.
    pub p: f64,
    /// Its two-sided Clopper–Pearson interval at the check's confidence.
    pub interval: (f64, f64),
    /// The sample with the smallest margin (lowest index on ties), and where it was.
    pub worst_sample: u64,
    pub worst: Outcome,
    pub worst_phase: String,
    /// Per time bin, the smallest margin of any sample.
    pub envelope: Vec<f32>,
}

/// One limit's result.
#[derive(Debug, Clone, PartialEq)]
pub struct LimitReport {
    pub limit: Limit,
    pub nominal: LimitRun,
    /// The part of the test where the nominal margin is smallest.
    pub phase: String,
    pub mc: Option<LimitMc>,
    pub verdict: Verdict,
    /// [unit] what the set-point search allowed for (worst sample − nominal).
    pub spread: f64,
    /// Per knob (throttle, load), when the limit does not pass.
    pub set_points: Option<[SetPoint; 2]>,
}

/// The Monte Carlo's set-up, for reports.
#[derive(Debug, Clone, PartialEq)]
pub struct McSetup {
    pub source: String,
    pub samples: u64,
    pub seed: u64,
    /// The distributions, one line each.
    pub items: Vec<String>,
    pub notes: Vec<String>,
}

/// [s] wall time of each phase.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Timing {
    pub nominal_s: f64,
    pub monte_carlo_s: f64,
    pub set_points_s: f64,
}

/// Everything a check found.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    pub title: String,
    pub limits_source: String,
    pub dt_us: u32,
    pub duration_s: f64,
    pub scales: Scales,
    /// [Hz] the torque flange's mode in the nominal model.
    pub flange_hz: f64,
    pub confidence: f64,
    pub mc: Option<McSetup>,
    pub limits: Vec<LimitReport>,
    /// Per knob, what keeps every failing limit inside at once.
    pub set_point_all: Option<[SetPoint; 2]>,
    /// Why the set-point search does not apply to the test, if it does not.
    pub no_set_points: Option<String>,
    /// The closed loop's delay margin, when the test is one.
    pub delay: Option<DelayMargin>,
    pub approved: bool,
    pub threads: usize,
    pub timing: Timing,
}

impl CheckReport {
    /// The limits that keep the test from being approved.
    pub fn failing(&self) -> impl Iterator<Item = &LimitReport> {
        self.limits.iter().filter(|l| !l.verdict.passes())
    }
}

/// Why a check could not be made: the request (exit code 2) or the work (1).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CheckError {
    Usage(String),
    Runtime(String),
}

/// Check `test` against the limits.
pub fn check(test: &dyn TestRun, o: &CheckOptions<'_>) -> Result<CheckReport, CheckError> {
    let limits = &o.limits.limits;
    let t0 = Instant::now();
    let (nominal, dynamics) = evaluate(test, limits, test.config(), test.scales())
        .map_err(|e| CheckError::Usage(format!("nominal run: {e}")))?;
    check_step(o.limits, &dynamics, test.config().dt_us)?;
    let nominal_s = t0.elapsed().as_secs_f64();

    let t1 = Instant::now();
    let mc = match o.uncertainty {
        Some(u) if o.samples > 0 => {
            let bar = if o.progress {
                Progress::new("Monte Carlo", o.samples as usize)
            } else {
                Progress::hidden()
            };
            let r = montecarlo::run(test, limits, u, o.samples, o.seed, o.threads, &bar);
            bar.finish();
            Some(r.map_err(CheckError::Usage)?)
        }
        _ => None,
    };
    let monte_carlo_s = t1.elapsed().as_secs_f64();

    let mut reports: Vec<LimitReport> = limits
        .iter()
        .zip(nominal)
        .enumerate()
        .map(|(i, (l, run))| limit_report(test, l, run, mc.as_ref().map(|m| (m, i)), o.confidence))
        .collect();

    let t2 = Instant::now();
    let mut set_point_all = None;
    let wanted: Vec<usize> = (0..reports.len()).filter(|&i| !reports[i].verdict.passes()).collect();
    let no_set_points = test.no_set_points();
    if o.set_points && no_set_points.is_none() && !wanted.is_empty() {
        let tightened: Vec<Limit> = reports.iter().map(|r| r.limit.tightened(r.spread)).collect();
        let (found, all) =
            setpoint::search(test, &tightened, &wanted, o.threads).map_err(CheckError::Runtime)?;
        for (i, sp) in wanted.iter().zip(found) {
            reports[*i].set_points = Some(sp);
        }
        set_point_all = Some(all);
    }
    let set_points_s = t2.elapsed().as_secs_f64();

    let approved =
        reports.iter().all(|r| r.verdict.passes()) && o.delay.as_ref().is_none_or(DelayMargin::passes);
    Ok(CheckReport {
        title: test.title(),
        limits_source: o.limits.source.clone(),
        dt_us: test.config().dt_us,
        duration_s: test.duration_us() as f64 * 1e-6,
        scales: test.scales(),
        flange_hz: dynamics.flange_hz(),
        confidence: o.confidence,
        mc: o.uncertainty.filter(|_| o.samples > 0).map(|u| {
            let mut notes = u.notes.clone();
            let clipped = mc.as_ref().map_or(0, |m| m.samples.iter().filter(|s| s.clipped).count());
            if clipped > 0 {
                notes.push(format!(
                    "{clipped} of {} samples drew an effect parameter beyond its valid range, clipped to it",
                    o.samples
                ));
            }
            McSetup {
                source: u.source.clone(),
                samples: o.samples,
                seed: o.seed,
                items: u.items.iter().map(|i| i.describe()).collect(),
                notes,
            }
        }),
        limits: reports,
        set_point_all,
        no_set_points,
        delay: o.delay.clone(),
        approved,
        threads: o.threads,
        timing: Timing { nominal_s, monte_carlo_s, set_points_s },
    })
}

/// A limit on the torque flange or the coupling needs the flange mode resolved.
fn check_step(limits: &Limits, d: &Dynamics, dt_us: u32) -> Result<(), CheckError> {
    let need = limits.need_flange_mode();
    if dt_us <= d.max_dt_us() || need.is_empty() {
        return Ok(());
    }
    let ids: Vec<&str> = need.iter().map(|l| l.id.as_str()).collect();
    Err(CheckError::Usage(format!(
        "--dt-us {dt_us}: the limits {} need the {:.0} Hz torque-flange mode resolved, at least 4 samples a period: --dt-us {} or less",
        ids.join(", "),
        d.flange_hz(),
        d.max_dt_us()
    )))
}

/// One limit's nominal result, Monte Carlo statistics and verdict.
fn limit_report(
    test: &dyn TestRun,
    l: &Limit,
    nominal: LimitRun,
    mc: Option<(&montecarlo::MonteCarlo, usize)>,
    confidence: f64,
) -> LimitReport {
    let phase = test.phase((nominal.t_s * 1e6).round() as u64);
    let risk = 1.0 - confidence;
    let stats = mc.and_then(|(m, i)| {
        let n = m.samples.len() as u64;
        let k = m.samples.iter().filter(|s| s.limits.get(i).is_some_and(|o| o.crossed)).count() as u64;
        let worst = m
            .samples
            .iter()
            .filter_map(|s| s.limits.get(i).map(|o| (s.index, *o)))
            .min_by(|a, b| a.1.margin.total_cmp(&b.1.margin).then(a.0.cmp(&b.0)))?;
        Some(LimitMc {
            violations: k,
            samples: n,
            p: k as f64 / n.max(1) as f64,
            interval: binomial::clopper_pearson(k, n, confidence),
            worst_sample: worst.0,
            worst: worst.1,
            worst_phase: test.phase((worst.1.t_s * 1e6).round() as u64),
            envelope: m.envelope.get(i).cloned().unwrap_or_default(),
        })
    });
    let verdict = match &stats {
        None if nominal.crossed => Verdict::Crossed,
        None => Verdict::Inside,
        Some(s) if s.interval.1 <= risk => Verdict::Safe,
        Some(s) if s.p > risk => Verdict::LikelyCrossed,
        Some(_) => Verdict::Undecided,
    };
    let spread = stats.as_ref().map_or(0.0, |s| (nominal.margin - s.worst.margin).max(0.0));
    LimitReport { limit: l.clone(), nominal, phase, mc: stats, verdict, spread, set_points: None }
}

/// Samples a limit without violations needs before it can be shown safe at
/// `confidence`: the smallest n with `1 − (α/2)^(1/n) ≤ 1 − P`.
pub fn samples_needed(confidence: f64) -> u64 {
    let risk = (1.0 - confidence).clamp(1e-9, 1.0);
    let tail = 0.5 * risk;
    (tail.ln() / (1.0 - risk).ln()).ceil().max(1.0) as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_needed_matches_the_interval() {
        for p in [0.9, 0.95, 0.99] {
            let n = samples_needed(p);
            assert!(binomial::clopper_pearson(0, n, p).1 <= 1.0 - p + 1e-12, "{p}: {n}");
            assert!(binomial::clopper_pearson(0, n - 1, p).1 > 1.0 - p, "{p}: {n}");
        }
        assert_eq!(samples_needed(0.95), 72);
    }
}
