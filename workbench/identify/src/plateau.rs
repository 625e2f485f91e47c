//! Steady-state plateau extraction, shared by every steady-state identification (thesis
//! 5.2, 5.3.1, 5.5: "the steady state regions of the signal are extracted, the average
//! value ... is extrapolated", with the rms of each plateau as its quality).
//!
//! Where the thesis cut its four TP11 plateaus by hand, a plateau here is found
//! automatically:
//! 1. *Set points constant*: a stretch where throttle and both load set points hold
//!    their values (ramps never qualify).
//! 2. *Response settled*: the stretch is cut into windows (0.5 s) aligned to its end.
//!    The noise of a window mean, `σ_M`, is estimated robustly from the differences of
//!    consecutive window means in the last third (median absolute difference), which also
//!    holds for correlated noise such as encoder counts. Walking back from the end,
//!    windows are accepted while their mean stays within `band = max(4 σ_M, floor)` of
//!    the accepted ones; the settling transient before the first rejected window is
//!    dropped, plus one window of margin. A slope test over the accepted part catches
//!    slow drifts.
//! 3. *Quality*: mean, rms (the thesis' quality figure) and the standard error of the
//!    mean (from the spread of window means, so correlated noise is not under-counted).
//!
//! A candidate is rejected, with the reason kept for the report, when it settles for
//! less than `min_len_s`, drifts, is too noisy, holds non-finite samples, has a clipped
//! (flat-topped) source channel, or its speed encoders disagree (a miscount).

use std::fmt;
use std::ops::Range;

use super::progress::Progress;
use super::run::{sources, Run};
use simrod_numerics::stats::{mean, median};

/// How plateaus are found.
#[derive(Debug, Clone, PartialEq)]
pub struct PlateauOptions {
    /// [s] window of the stationarity test.
    pub window_s: f64,
    /// [s] shortest settled plateau kept.
    pub min_len_s: f64,
    /// Window means within this many `σ_M` of the final level count as settled.
    pub band_sigma: f64,
    /// [s] constant-set-point stretches shorter than this are not candidates (and not
    /// reported: a ramp is a sequence of one-sample stretches).
    pub min_segment_s: f64,
    /// Set points closer than this [%] count as equal.
    pub sp_tol: f64,
    /// SuT gearbox ratio for the encoder cross-check (`None`: no check).
    pub gear_ratio: Option<f64>,
    /// Encoder cross-check tolerance: `abs` rpm (axle) + `rel` of the speed.
    pub encoder_tol: (f64, f64),
}

impl Default for PlateauOptions {
    fn default() -> Self {
        Self {
            window_s: 0.5,
            min_len_s: 2.0,
            band_sigma: 4.0,
            min_segment_s: 1.0,
            sp_tol: 1e-6,
            gear_ratio: None,
            encoder_tol: (1.5, 0.015),
        }
    }
}

/// Largest plateau rms accepted, by unit: about 4x the bench's noise at its limits
/// (`workbench/examples/noise.toml`); a plateau noisier than that is not steady.
pub fn max_rms(unit: &str) -> f64 {
    match unit {
        "N m" => 10.0,
        "rpm" => 100.0,
        "A" => 15.0,
        "V" => 1.0,
        "W" => 500.0,
        _ => f64::INFINITY,
    }
}

/// Smallest settle band, by unit: below the resolution that matters for any map.
fn unit_floor(unit: &str) -> f64 {
    match unit {
        "rpm" => 0.5,
        "N m" => 0.02,
        "A" => 0.02,
        "V" => 0.002,
        "W" => 1.0,
        _ => 1e-9,
    }
}

/// A stretch of constant set points: samples `start..end`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    pub start: usize,
    pub end: usize,
    /// Throttle, load L, load R [%].
    pub sp: [f64; 3],
}

/// Mean, rms and standard error of one channel over a plateau.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChannelStats {
    pub mean: f64,
    /// Standard deviation of the samples about the mean (the thesis' "rms").
    pub rms: f64,
    /// Standard error of the mean.
    pub sem: f64,
}

/// A steady plateau.
#[derive(Debug, Clone, PartialEq)]
pub struct Plateau {
    /// Index of the run in the campaign.
    pub run: usize,
    /// Samples `start..end` (settled part only).
    pub start: usize,
    pub end: usize,
    /// [s] start and end time.
    pub t0: f64,
    pub t1: f64,
    /// Set points [%]: throttle, load L, load R.
    pub sp: [f64; 3],
    /// [s] settling transient dropped at the start of the stretch.
    pub settle_s: f64,
    /// One per requested channel, in the order requested.
    pub stats: Vec<ChannelStats>,
    /// Things worth knowing that did not reject it (an encoder not used here miscounts).
    pub warnings: Vec<String>,
}

impl Plateau {
    /// Mean of requested channel `i`.
    pub fn mean(&self, i: usize) -> f64 {
        self.stats.get(i).map_or(f64::NAN, |s| s.mean)
    }

    /// Standard error of requested channel `i`.
    pub fn sem(&self, i: usize) -> f64 {
        self.stats.get(i).map_or(f64::NAN, |s| s.sem)
    }
}

/// Why a candidate is not a plateau.
#[derive(Debug, Clone, PartialEq)]
pub enum Reason {
    /// Settled for less than the minimum before the set points changed.
    NotSettled {
        channel: String,
        settled_s: f64,
        min_s: f64,
    },
    /// The settled part still moves.
    Drifting {
        channel: String,
        drift: f64,
        band: f64,
        unit: String,
    },
    TooNoisy {
        channel: String,
        rms: f64,
        limit: f64,
        unit: String,
    },
    /// A flat top: many samples exactly at the extreme of an otherwise noisy channel.
    Saturated {
        channel: String,
        value: f64,
        fraction: f64,
        unit: String,
    },
    NonFinite {
        channel: String,
    },
    /// Speed encoders disagree: one of them loses pulses.
    Encoder {
        channel: String,
        detail: String,
    },
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Reason::NotSettled { channel, settled_s, min_s } => {
                write!(f, "too short: {channel} steady for only {settled_s:.1} s before the set points change (need {min_s} s)")
            }
            Reason::Drifting { channel, drift, band, unit } => write!(
                f,
                "{channel} drifts by {} {unit} over the plateau (noise allows {} {unit})",
                super::report::num(*drift),
                super::report::num(*band)
            ),
            Reason::TooNoisy { channel, rms, limit, unit } => write!(
                f,
                "{channel} too noisy: rms {} {unit} > {} {unit}",
                super::report::num(*rms),
                super::report::num(*limit)
            ),
            Reason::Saturated { channel, value, fraction, unit } => write!(
                f,
                "{channel} saturated: {:.0} % of the samples sit exactly at {} {unit} (flat-topped clipping)",
                100.0 * fraction,
                super::report::num(*value)
            ),
            Reason::NonFinite { channel } => write!(f, "{channel} has non-finite samples"),
            Reason::Encoder { channel, detail } => write!(f, "encoder miscount on {channel}: {detail}"),
        }
    }
}

/// A rejected candidate.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejected {
    pub run: usize,
    pub t0: f64,
    pub t1: f64,
    pub sp: [f64; 3],
    pub reason: Reason,
}

/// Plateaus of a campaign for a set of channels.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Extraction {
    /// The requested channels (order of `Plateau::stats`).
    pub channels: Vec<String>,
    pub plateaus: Vec<Plateau>,
    pub rejected: Vec<Rejected>,
    /// Runs that gave no plateau at all, and why.
    pub runs_without: Vec<(usize, String)>,
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(1.0)
}

/// Stretches of constant set points lasting at least `min_segment_s`.
pub fn segments(run: &Run, opts: &PlateauOptions) -> Vec<Segment> {
    let [thr, ll, lr] = run.setpoints();
    let n = thr.len().min(ll.len()).min(lr.len());
    let at = |k: usize| [thr[k], ll[k], lr[k]];
    let min_len = (opts.min_segment_s / run.dt_s).ceil() as usize;
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=n {
        let same = k < n && {
            let (a, b) = (at(start), at(k));
            (0..3).all(|i| close(a[i], b[i], opts.sp_tol))
        };
        if !same {
            if k - start >= min_len.max(2) {
                out.push(Segment { start, end: k, sp: at(start) });
            }
            start = k;
        }
    }
    out
}

/// Where a channel settles within a segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settle {
    /// First settled sample, relative to the segment start.
    pub offset: usize,
    /// Noise of a window mean.
    pub sigma_m: f64,
    /// Settle band.
    pub band: f64,
}

/// Settling of `v` (one channel over one segment), windows of `w` samples; `None` if
/// fewer than 3 windows fit.
pub fn settle(v: &[f64], w: usize, band_sigma: f64, floor: f64) -> Option<Settle> {
    let w = w.max(1);
    let n = v.len();
    let k = n / w;
    if k < 3 {
        return None;
    }
    let first = n - k * w;
    let means: Vec<f64> = (0..k).map(|j| mean(&v[first + j * w..first + (j + 1) * w])).collect();
    let tail = (k / 3).max(2).min(k - 1);
    let diffs: Vec<f64> = (k - 1 - tail..k - 1).map(|j| (means[j + 1] - means[j]).abs()).collect();
    // Robust to correlated noise (encoder counts), but from few windows; the pooled
    // within-window scatter bounds it from below for white noise.
    let robust = 1.4826 * median(&diffs).unwrap_or(0.0) / std::f64::consts::SQRT_2;
    let white = {
        let (mut ss, mut cnt) = (0.0, 0usize);
        for j in k - 1 - tail..k {
            let win = &v[first + j * w..first + (j + 1) * w];
            let m = means[j];
            ss += win.iter().map(|x| (x - m) * (x - m)).sum::<f64>();
            cnt += win.len() - 1;
        }
        (ss / cnt.max(1) as f64 / w as f64).sqrt()
    };
    let sigma_m = robust.max(white);
    let band = (band_sigma * sigma_m).max(floor);
    let (mut sum, mut cnt, mut j0, mut stopped) = (means[k - 1], 1.0, k - 1, false);
    for j in (0..k - 1).rev() {
        if (means[j] - sum / cnt).abs() <= band {
            sum += means[j];
            cnt += 1.0;
            j0 = j;
        } else {
            stopped = true;
            break;
        }
    }
    // One window of margin after a detected transient.
    let j_start = if stopped { (j0 + 1).min(k - 1) } else { j0 };
    Some(Settle { offset: first + j_start * w, sigma_m, band })
}

/// Smallest non-zero step between consecutive samples: the quantum of a counted
/// channel (encoder speeds), negligible for analog ones.
fn quantum(v: &[f64]) -> f64 {
    v.windows(2).map(|p| (p[1] - p[0]).abs()).filter(|d| *d > 0.0).fold(f64::INFINITY, f64::min)
}

/// Stats over a settled range; `w` samples per window.
fn stats(v: &[f64], w: usize) -> ChannelStats {
    let m = mean(v);
    let n = v.len().max(1) as f64;
    let rms = (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n).sqrt();
    let k = v.len() / w.max(1);
    let sem_white = rms / n.sqrt();
    let sem = if k >= 2 {
        let wm: Vec<f64> = (0..k).map(|j| mean(&v[j * w..(j + 1) * w])).collect();
        let mm = mean(&wm);
        let sd = (wm.iter().map(|x| (x - mm) * (x - mm)).sum::<f64>() / (k - 1) as f64).sqrt();
        (sd / (k as f64).sqrt()).max(sem_white)
    } else {
        sem_white
    };
    ChannelStats { mean: m, rms, sem }
}

/// A flat top: the extreme value repeated in many samples of a channel whose other
/// samples are mostly distinct (an analog channel; encoder counts repeat by nature).
pub fn flat_top(v: &[f64]) -> Option<(f64, f64)> {
    let n = v.len();
    if n < 50 {
        return None;
    }
    let (lo, hi) = v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
    if hi.is_nan() || lo.is_nan() || hi <= lo {
        return None; // exactly constant: noise-free data cannot be told from a stuck probe
    }
    for ext in [hi, lo] {
        let count = v.iter().filter(|x| **x == ext).count();
        if count < 5.max(n / 50) {
            continue;
        }
        let mut others: Vec<f64> = v.iter().copied().filter(|x| *x != ext).collect();
        let n_others = others.len();
        others.sort_by(f64::total_cmp);
        others.dedup();
        if n_others >= 10 && others.len() * 2 >= n_others {
            return Some((ext, count as f64 / n as f64));
        }
    }
    None
}

/// Encoder cross-check over `range`: SiemensEnc vs T_Kistler_R (the same shaft at steady
/// state), SuTMotorEnc / gear ratio vs the mean of T_Kistler_L/R (open differential).
/// Returns the channels implicated and what was seen.
pub fn encoder_check(
    run: &Run,
    range: Range<usize>,
    opts: &PlateauOptions,
) -> Option<(Vec<&'static str>, String)> {
    let m = |name: &str| run.signal(name).and_then(|v| v.get(range.clone())).map(mean);
    let tol = |a: f64, b: f64| opts.encoder_tol.0 + opts.encoder_tol.1 * a.abs().max(b.abs());
    let (tl, tr, sie, mot) = (m("T_Kistler_L"), m("T_Kistler_R"), m("SiemensEnc"), m("SuTMotorEnc"));
    let c1 = match (sie, tr) {
        (Some(s), Some(r)) => {
            Some(((s - r).abs() > tol(s, r), format!("SiemensEnc {s:.1} rpm vs T_Kistler_R {r:.1} rpm")))
        }
        _ => None,
    };
    let c2 = match (mot, tl, tr, opts.gear_ratio) {
        (Some(mo), Some(l), Some(r), Some(n)) if n > 0.0 => {
            let (a, b) = (mo / n, 0.5 * (l + r));
            Some((
                (a - b).abs() > tol(a, b),
                format!("SuTMotorEnc/{n:.3} = {a:.1} rpm vs mean T_Kistler {b:.1} rpm"),
            ))
        }
        _ => None,
    };
    let bad = |c: &Option<(bool, String)>| c.as_ref().is_some_and(|x| x.0);
    let said = |c: &Option<(bool, String)>| c.as_ref().map_or(String::new(), |x| x.1.clone());
    let who: Vec<&'static str> = match (bad(&c1), bad(&c2), c1.is_some(), c2.is_some()) {
        (true, false, _, true) => vec!["SiemensEnc"],
        (true, false, _, false) => vec!["SiemensEnc", "T_Kistler_R"],
        (false, true, true, _) => vec!["SuTMotorEnc", "T_Kistler_L"],
        (false, true, false, _) => vec!["SuTMotorEnc", "T_Kistler_L", "T_Kistler_R"],
        (true, true, _, _) => vec!["T_Kistler_R"],
        _ => return None,
    };
    let detail = [said(&c1), said(&c2)].into_iter().filter(|s| !s.is_empty()).collect::<Vec<_>>().join("; ");
    Some((who, detail))
}

/// Plateaus of one run for `channels` (appended to `out`).
fn extract_run(run: &Run, idx: usize, channels: &[&str], opts: &PlateauOptions, out: &mut Extraction) {
    if let Some(c) = channels.iter().find(|c| run.signal(c).is_none()) {
        out.runs_without.push((idx, format!("no channel \"{c}\"")));
        return;
    }
    let series: Vec<&[f64]> = channels.iter().map(|c| run.signal(c).unwrap_or(&[])).collect();
    let w = ((opts.window_s / run.dt_s).round() as usize).max(5);
    let min_len = (opts.min_len_s / run.dt_s).round() as usize;
    let t = run.time();
    let segs = segments(run, opts);
    let before = out.plateaus.len();
    let mut reasons = Vec::new();
    for seg in &segs {
        let time = |k: usize| t.get(k.min(t.len().saturating_sub(1))).copied().unwrap_or(f64::NAN);
        let reject = |reason: Reason| Rejected {
            run: idx,
            t0: time(seg.start),
            t1: time(seg.end - 1),
            sp: seg.sp,
            reason,
        };
        match candidate(run, seg, channels, &series, w, min_len, opts) {
            Ok(p) => out.plateaus.push(Plateau { run: idx, ..p }),
            Err(r) => {
                reasons.push(r.to_string());
                out.rejected.push(reject(r));
            }
        }
    }
    if out.plateaus.len() == before {
        let why = if segs.is_empty() {
            format!("no plateau: the set points never hold for {} s", opts.min_segment_s)
        } else {
            format!("no plateau ({} candidate(s) rejected: {})", segs.len(), reasons.join("; "))
        };
        out.runs_without.push((idx, why));
    }
}

/// One candidate segment: a plateau or the reason it is not one.
fn candidate(
    run: &Run,
    seg: &Segment,
    channels: &[&str],
    series: &[&[f64]],
    w: usize,
    min_len: usize,
    opts: &PlateauOptions,
) -> Result<Plateau, Reason> {
    let dt = run.dt_s;
    let mut start = seg.start;
    let mut settles = Vec::with_capacity(channels.len());
    for (c, v) in channels.iter().zip(series) {
        let seg_v = &v[seg.start..seg.end];
        if seg_v.iter().any(|x| !x.is_finite()) {
            return Err(Reason::NonFinite { channel: (*c).to_string() });
        }
        let floor = unit_floor(run.unit(c)).max(0.5 * quantum(seg_v)).min(f64::MAX);
        let Some(s) = settle(seg_v, w, opts.band_sigma, floor) else {
            return Err(Reason::NotSettled {
                channel: (*c).to_string(),
                settled_s: (seg.end - seg.start) as f64 * dt,
                min_s: opts.min_len_s,
            });
        };
        start = start.max(seg.start + s.offset);
        settles.push((c, s));
    }
    if seg.end - start < min_len.max(1) {
        let slowest = settles.iter().max_by_key(|(_, s)| s.offset).map_or("?", |(c, _)| **c);
        return Err(Reason::NotSettled {
            channel: slowest.to_string(),
            settled_s: (seg.end - start) as f64 * dt,
            min_s: opts.min_len_s,
        });
    }
    let mut stats_out = Vec::with_capacity(channels.len());
    for ((c, v), (_, s)) in channels.iter().zip(series).zip(&settles) {
        let part = &v[start..seg.end];
        let unit = run.unit(c).to_string();
        // Drift: slope of the window means over the settled part.
        let k = part.len() / w;
        if k >= 3 {
            let wm: Vec<f64> = (0..k).map(|j| mean(&part[j * w..(j + 1) * w])).collect();
            let xm = (k as f64 - 1.0) / 2.0;
            let ym = mean(&wm);
            let sxx: f64 = (0..k).map(|j| (j as f64 - xm).powi(2)).sum();
            let sxy: f64 = wm.iter().enumerate().map(|(j, y)| (j as f64 - xm) * (y - ym)).sum();
            let drift = (sxy / sxx * k as f64).abs();
            let allowed = s.band + 2.0 * s.sigma_m * (12.0 / k as f64).sqrt();
            if drift > allowed {
                return Err(Reason::Drifting { channel: (*c).to_string(), drift, band: allowed, unit });
            }
        }
        let st = stats(part, w);
        if st.rms > max_rms(&unit) {
            return Err(Reason::TooNoisy {
                channel: (*c).to_string(),
                rms: st.rms,
                limit: max_rms(&unit),
                unit,
            });
        }
        for src in sources(c) {
            if let Some((value, fraction)) =
                run.signal(src).and_then(|v| v.get(start..seg.end)).and_then(flat_top)
            {
                let unit = run.unit(src).to_string();
                return Err(Reason::Saturated { channel: src.to_string(), value, fraction, unit });
            }
        }
        stats_out.push(st);
    }
    let mut warnings = Vec::new();
    if opts.gear_ratio.is_some() {
        if let Some((who, detail)) = encoder_check(run, start..seg.end, opts) {
            let used = channels.iter().flat_map(|c| sources(c)).find(|s| who.contains(s));
            if let Some(u) = used {
                return Err(Reason::Encoder { channel: u.to_string(), detail });
            }
            warnings.push(format!("encoder miscount on {} (not used here): {detail}", who.join("/")));
        }
    }
    let t = run.time();
    Ok(Plateau {
        run: 0,
        start,
        end: seg.end,
        t0: t.get(start).copied().unwrap_or(f64::NAN),
        t1: t.get(seg.end - 1).copied().unwrap_or(f64::NAN),
        sp: seg.sp,
        settle_s: (start - seg.start) as f64 * dt,
        stats: stats_out,
        warnings,
    })
}

/// Plateaus of every run for `channels` (measured or derived names).
pub fn extract(runs: &[Run], channels: &[&str], opts: &PlateauOptions, progress: &Progress) -> Extraction {
    let mut out =
        Extraction { channels: channels.iter().map(|c| (*c).to_string()).collect(), ..Extraction::default() };
    for (i, run) in runs.iter().enumerate() {
        extract_run(run, i, channels, opts, &mut out);
        progress.tick(&run.name);
    }
    progress.finish();
    out
}

/// A settling transient after a set-point change: for the transient identifications.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transient {
    /// First sample with the new set points.
    pub change: usize,
    /// First settled sample (all `channels` within their band), or the segment end.
    pub settled: usize,
    /// End of the constant-set-point stretch.
    pub end: usize,
    /// Set points before (`None` at the start of the run) and after the change.
    pub sp_before: Option<[f64; 3]>,
    pub sp_after: [f64; 3],
}

/// The settling transients of a run: every constant-set-point stretch, from the change
/// to where `channels` settle (same test as the plateaus).
pub fn transients(run: &Run, channels: &[&str], opts: &PlateauOptions) -> Vec<Transient> {
    let w = ((opts.window_s / run.dt_s).round() as usize).max(5);
    let [thr, ll, lr] = run.setpoints();
    segments(run, opts)
        .iter()
        .map(|seg| {
            let mut settled = seg.start;
            for c in channels {
                if let Some(v) = run.signal(c).and_then(|v| v.get(seg.start..seg.end)) {
                    let floor = unit_floor(run.unit(c)).max(0.5 * quantum(v));
                    settled = settled
                        .max(settle(v, w, opts.band_sigma, floor).map_or(seg.end, |s| seg.start + s.offset));
                }
            }
            let k = seg.start.checked_sub(1);
            let sp_before = k.and_then(|k| Some([*thr.get(k)?, *ll.get(k)?, *lr.get(k)?]));
            Transient { change: seg.start, settled, end: seg.end, sp_before, sp_after: seg.sp }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use simrod_io::measure::{Measurement, Signal};
    use simrod_numerics::stats::Rng;
    use std::path::PathBuf;

    /// A run with set points `sp(t)` and one channel `y(t)` plus white noise.
    fn synth(n: usize, sp: &dyn Fn(f64) -> f64, y: &dyn Fn(f64) -> f64, sigma: f64) -> Run {
        let dt = 1e-3;
        let t: Vec<f64> = (1..=n).map(|k| k as f64 * dt).collect();
        let mut rng = Rng::new(7, 0);
        let sig =
            |name: &str, unit: &str, v: Vec<f64>| Signal { name: name.into(), unit: unit.into(), values: v };
        let meas = Measurement {
            source: PathBuf::from("synth.csv"),
            signals: vec![
                sig("SuT Throttle", "%", t.iter().map(|t| sp(*t)).collect()),
                sig("Dm Left", "%", vec![0.0; n]),
                sig("Dm Right", "%", vec![0.0; n]),
                sig("C_Kistler_L", "N m", t.iter().map(|t| y(*t) + sigma * rng.gauss()).collect()),
            ],
            time_s: t,
        };
        Run::new("synth.csv", meas).unwrap()
    }

    fn step_sp(t: f64) -> f64 {
        if t < 5.0 {
            30.0
        } else {
            60.0
        }
    }

    /// First-order response to the step at 5 s (time constant 0.4 s).
    fn step_y(t: f64) -> f64 {
        if t < 5.0 {
            10.0 - 10.0 * (-t / 0.4).exp()
        } else {
            20.0 - 10.0 * (-(t - 5.0) / 0.4).exp()
        }
    }

    #[test]
    fn identify_plateau_drops_the_settling_transient() {
        let run = synth(15_000, &step_sp, &step_y, 0.3);
        let ex = extract(&[run], &["C_Kistler_L"], &PlateauOptions::default(), &Progress::hidden());
        assert_eq!(ex.plateaus.len(), 2, "{:?}", ex.rejected);
        let p = &ex.plateaus[1];
        assert_eq!(p.sp, [60.0, 0.0, 0.0]);
        // 4 σ of a 0.5 s window mean is 0.054 N m: the exponential is that close after
        // ~2.6 s, plus one window of margin.
        assert!((2.0..4.0).contains(&p.settle_s), "settle {}", p.settle_s);
        let s = p.stats[0];
        assert!((s.mean - 20.0).abs() < 4.0 * s.sem, "{s:?}");
        assert!((s.rms - 0.3).abs() < 0.02, "{s:?}");
        assert!((s.sem - 0.3 / (p.end as f64 - p.start as f64).sqrt()).abs() < 0.5 * s.sem, "{s:?}");
        // Noise-free: the band floor decides, and the mean is the level.
        let run = synth(15_000, &step_sp, &step_y, 0.0);
        let ex = extract(&[run], &["C_Kistler_L"], &PlateauOptions::default(), &Progress::hidden());
        assert_eq!(ex.plateaus.len(), 2);
        assert!((ex.plateaus[1].mean(0) - 20.0).abs() < 0.01, "{:?}", ex.plateaus[1]);
    }

    #[test]
    fn identify_plateau_rejects_ramps_drifts_noise_and_clipping() {
        // A ramp of set points: no candidate at all.
        let run = synth(10_000, &|t| 10.0 * t, &|t| t, 0.1);
        let ex = extract(&[run], &["C_Kistler_L"], &PlateauOptions::default(), &Progress::hidden());
        assert!(ex.plateaus.is_empty());
        assert!(ex.runs_without[0].1.contains("never hold"), "{:?}", ex.runs_without);
        // Constant set point, response still ramping: drifting or unsettled.
        let run = synth(10_000, &|_| 50.0, &|t| 0.5 * t, 0.1);
        let ex = extract(&[run], &["C_Kistler_L"], &PlateauOptions::default(), &Progress::hidden());
        assert!(ex.plateaus.is_empty());
        assert!(
            matches!(ex.rejected[0].reason, Reason::Drifting { .. } | Reason::NotSettled { .. }),
            "{:?}",
            ex.rejected
        );
        assert!(
            ex.runs_without[0].1.starts_with("no plateau (1 candidate(s) rejected"),
            "{:?}",
            ex.runs_without
        );
        // Too noisy.
        let run = synth(10_000, &|_| 50.0, &|_| 5.0, 20.0);
        let ex = extract(&[run], &["C_Kistler_L"], &PlateauOptions::default(), &Progress::hidden());
        assert!(matches!(ex.rejected[0].reason, Reason::TooNoisy { .. }), "{:?}", ex.rejected);
        // Clipped at 5.2 N m (an ADC range): a flat top.
        let mut run = synth(10_000, &|_| 50.0, &|_| 5.0, 0.3);
        for s in &mut run.meas.signals {
            if s.name == "C_Kistler_L" {
                s.values.iter_mut().for_each(|v| *v = v.min(5.2));
            }
        }
        let ex = extract(&[run], &["C_Kistler_L"], &PlateauOptions::default(), &Progress::hidden());
        match &ex.rejected[0].reason {
            Reason::Saturated { channel, value, fraction, .. } => {
                assert_eq!(channel, "C_Kistler_L");
                assert_eq!(*value, 5.2);
                assert!((0.2..0.35).contains(fraction), "{fraction}");
            }
            r => panic!("{r:?}"),
        }
        assert!(ex.rejected[0].reason.to_string().contains("flat-topped clipping"));
        // A missing channel rejects the run.
        let run = synth(10_000, &|_| 50.0, &|_| 5.0, 0.3);
        let ex = extract(&[run], &["I_DC"], &PlateauOptions::default(), &Progress::hidden());
        assert_eq!(ex.runs_without, vec![(0, "no channel \"I_DC\"".to_string())]);
    }

    #[test]
    fn identify_flat_top_ignores_counted_and_constant_channels() {
        // Encoder-like: two values alternate; not a flat top.
        let v: Vec<f64> = (0..1000).map(|k| if k % 3 == 0 { 110.0 } else { 100.0 }).collect();
        assert_eq!(flat_top(&v), None);
        assert_eq!(flat_top(&[3.0; 1000]), None);
        let v: Vec<f64> = (0..1000).map(|k| (k as f64 * 0.37).sin().min(0.9)).collect();
        let (value, fraction) = flat_top(&v).unwrap();
        assert_eq!(value, 0.9);
        assert!(fraction > 0.1);
    }

    #[test]
    fn identify_transients_mark_the_settling_part() {
        let run = synth(15_000, &step_sp, &step_y, 0.3);
        let tr = transients(&run, &["C_Kistler_L"], &PlateauOptions::default());
        assert_eq!(tr.len(), 2);
        assert_eq!(tr[1].change, 4999);
        assert_eq!(tr[1].sp_before, Some([30.0, 0.0, 0.0]));
        assert!(tr[1].settled > tr[1].change + 1500 && tr[1].settled < tr[1].change + 4000, "{:?}", tr[1]);
    }
}
