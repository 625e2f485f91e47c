//! Measured run vs twin: run the twin on the run's own inputs and show where, when and
//! in which operating region the two disagree.
//!
//! Pipeline: [`simrod_twin`] (twin on the recorded set points, as the bench records it,
//! paired samples) →
//! [`metrics`] per channel → [`regions`] (classify every sample from measured and
//! commanded signals) → [`budget`] (each region's share of the squared error) →
//! [`spans`] (worst windows) → [`residual`] (whiteness, input cross-correlation).
//! The residual is `sim − meas` throughout.

pub mod budget;
pub mod metrics;
pub mod regions;
pub mod residual;
pub mod spans;
pub mod structure;

#[cfg(test)]
mod tests;

use std::path::Path;
use std::time::Instant;

use model_core::{Channel, RateSet, SpeedTarget, MEASURED};

use budget::RegionShare;
use metrics::Metrics;
use regions::{Classification, RegionRules};
use residual::{CrossPeak, Whiteness};
use simrod_io::measure::Measurement;
pub use simrod_twin::{Aligned, InputSource, Paired, TwinError as CompareError};
use simrod_twin::{MeasuredTwin, ModelOptions};
use spans::Span;

/// How to compare.
#[derive(Debug, Clone, PartialEq)]
pub struct CompareOptions {
    /// The twin and how the bench records it.
    pub model: ModelOptions,
    pub inputs: InputSource,
    /// [s] width of the worst-span windows.
    pub window_s: f64,
    /// Worst spans per channel.
    pub spans: usize,
    /// Autocorrelation lags of the whiteness test.
    pub whiteness_lags: usize,
    /// [s] largest |lag| searched for the input cross-correlation peak.
    pub max_lag_s: f64,
    /// Top combined regions listed per channel.
    pub top_regions: usize,
    pub rules: RegionRules,
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self {
            model: ModelOptions::default(),
            inputs: InputSource::Recorded,
            window_s: 2.0,
            spans: 3,
            whiteness_lags: 200,
            max_lag_s: 1.0,
            top_regions: 3,
            rules: RegionRules::default(),
        }
    }
}

/// Everything about one channel.
#[derive(Debug, Clone)]
pub struct ChannelResult {
    pub name: String,
    pub unit: String,
    /// Computed from measured channels (P_DPU, P_SuT_inv, P_LML, P_LMR).
    pub derived: bool,
    /// Measured values; NaN inside gaps interpolated across (`--allow-gaps`).
    pub meas: Vec<f64>,
    pub sim: Vec<f64>,
    pub metrics: Metrics,
    /// Every region's share of this channel's squared error.
    pub budget: Vec<RegionShare>,
    /// The combined regions with the largest error share.
    pub top_regions: Vec<RegionShare>,
    pub worst_spans: Vec<Span>,
    pub whiteness: Whiteness,
    pub cross: Vec<CrossPeak>,
    /// Windows of this channel's residual with structure beyond noise (the test of
    /// [`structure`], at [`structure::ALPHA`] over every window of every measured
    /// channel), in time order; derived channels are not tested (their inputs are).
    pub structure: Vec<structure::Window>,
}

impl ChannelResult {
    /// `sim − meas`, NaN where either is not finite (inside gaps too). Computed when
    /// asked, not stored: a long run's residuals would double what a result holds.
    pub fn residual(&self) -> Vec<f64> {
        metrics::residual(&self.meas, &self.sim)
    }

    /// The residual has structure a model could explain (not white, not negligible).
    pub fn structured(&self) -> bool {
        self.whiteness.verdict == residual::Verdict::Coloured
    }
}

/// How the comparison was set up, for the report.
#[derive(Debug, Clone)]
pub struct Setup {
    pub source: String,
    pub dt_us: u32,
    pub resampled: bool,
    pub step_note: String,
    pub samples: usize,
    pub duration_s: f64,
    pub inputs: String,
    pub rates: RateSet,
    pub speed_target: SpeedTarget,
    pub supply_v: f32,
    pub effects_on: bool,
    pub window_s: f64,
    /// [s] the bench's speed-counting window applied to the twin's speeds (0: none).
    pub speed_window_s: f64,
}

/// The comparison.
#[derive(Debug, Clone)]
pub struct CompareResult {
    pub setup: Setup,
    /// Comparison grid [s].
    pub time_s: Vec<f64>,
    /// Set points the twin ran on: throttle, load L, load R [%].
    pub inputs: [Vec<f64>; 3],
    pub channels: Vec<ChannelResult>,
    /// Windows tested for structure over all measured channels (the multiple-testing
    /// family of [`ChannelResult::structure`]).
    pub structure_tested: usize,
    pub regions: Classification,
    /// Caveats worth telling the user.
    pub notes: Vec<String>,
    /// [s] wall time: twin run, analysis.
    pub timing: (f64, f64),
}

impl CompareResult {
    /// The channel where the model is most wrong: the largest NRMSE among channels whose
    /// residual has structure (coloured). A white residual is noise no model explains,
    /// however large, so a run whose residuals are all noise-like has no worst channel.
    pub fn worst_channel(&self) -> Option<&ChannelResult> {
        self.channels
            .iter()
            .filter(|c| c.metrics.nrmse.is_finite() && c.structured())
            .max_by(|a, b| a.metrics.nrmse.total_cmp(&b.metrics.nrmse))
    }

    /// The channel called `name`.
    pub fn channel(&self, name: &str) -> Option<&ChannelResult> {
        self.channels.iter().find(|c| c.name == name)
    }
}

/// How much larger than the counting error's RMS a counted speed's residual may be and
/// still be called resolution: 15 %, so a model error hides only below about half the
/// counting RMS (√(1.15² − 1) ≈ 0.57), a few rpm on the bench's encoders.
pub const RESOLUTION_MARGIN: f64 = 1.15;

/// The residual of channel `name` (RMS `rmse`) is no larger than its sensor's counting
/// resolution.
fn within_resolution(opts: &CompareOptions, name: &str, rmse: f64) -> bool {
    model_core::Channel::from_name(name)
        .and_then(|c| opts.model.sensors.counting_rms(c))
        .is_some_and(|q| rmse <= RESOLUTION_MARGIN * q)
}

/// Samples inside gaps are not measurements: NaN, as the residual has them.
fn mask_gaps(meas: &mut [f64], gaps: &[bool]) {
    for (m, gap) in meas.iter_mut().zip(gaps) {
        if *gap {
            *m = f64::NAN;
        }
    }
}

/// Compare a measured run with the twin.
pub fn compare(meas: &Measurement, opts: &CompareOptions) -> Result<CompareResult, CompareError> {
    compare_prepared(MeasuredTwin::new(meas, &opts.model, &opts.inputs)?, &meas.source, opts)
}

/// Compare a run already put on the twin's grid (from the file `source`): the caller may
/// drop the measurement first, so a long run is not held twice.
pub fn compare_prepared(
    twin: MeasuredTwin,
    source: &Path,
    opts: &CompareOptions,
) -> Result<CompareResult, CompareError> {
    if !(opts.window_s.is_finite() && opts.window_s > 0.0) {
        return Err(CompareError::Window);
    }
    let t0 = Instant::now();
    let present: Vec<Channel> = twin.measured.iter().map(|(c, _)| *c).collect();
    let stated = twin.stated_sigma(&present);
    let stated_of = |name: &str| {
        let i = present.iter().position(|c| c.name() == name)?;
        stated[i].as_deref()
    };
    let al = twin.into_aligned(opts.model.effects)?;
    if al.channels.is_empty() {
        return Err(CompareError::NoChannels);
    }
    let t1 = Instant::now();
    let n = al.grid.time_s.len();
    let dt_s = al.grid.dt_s();

    let limits = regions::Limits::of_model(&opts.model)?;
    let classes = regions::classify(&al, &opts.rules, &limits);

    // Inputs for the cross-correlation: the set points (the correlator adds their
    // step-to-step change: the change at row k drove the step ending at row k).
    let names = ["SuT Throttle", "Dm Left", "Dm Right"];
    let xin: Vec<(&str, &[f64])> =
        names.iter().zip(&al.grid.set_points).map(|(n, u)| (*n, u.as_slice())).collect();
    let max_lag = (opts.max_lag_s / dt_s).round().max(0.0) as usize;
    let mut corr = residual::Correlator::new(&xin, n, dt_s, max_lag, opts.whiteness_lags);
    let window = ((opts.window_s / dt_s).round() as usize).max(1);

    // Two channels at a time (the correlator shares FFTs by pairs): a long run's
    // residuals are never all held at once.
    let (time_s, gaps) = (&al.grid.time_s, &al.grid.gaps);
    let mut channels = Vec::with_capacity(al.channels.len());
    let mut tested_windows: Vec<Option<structure::ChannelWindows>> = Vec::with_capacity(al.channels.len());
    let mut pending = al.channels.into_iter();
    while let Some(first) = pending.next() {
        let pair: Vec<(Paired, Vec<f64>, Metrics)> = std::iter::once(first)
            .chain(pending.next())
            .map(|mut p| {
                let (e, m) = metrics::paired(&p, time_s, gaps);
                mask_gaps(&mut p.meas, gaps);
                (p, e, m)
            })
            .collect();
        let refs: Vec<(&[f64], f64)> = pair.iter().map(|(_, e, m)| (e.as_slice(), m.normaliser)).collect();
        let stats = corr.analyse(&refs);
        for ((p, e, m), st) in pair.into_iter().zip(stats) {
            let b = budget::budget(&classes.classes, &e);
            let top = budget::top_combined(&b, opts.top_regions);
            let worst = spans::worst_spans(time_s, &e, window, opts.spans);
            let resolution = Channel::from_name(&p.name).and_then(|c| opts.model.sensors.counting_step(c));
            tested_windows.push(
                (!p.derived)
                    .then(|| structure::windows(&e, dt_s, resolution.unwrap_or(0.0), stated_of(&p.name))),
            );
            let mut whiteness = st.whiteness;
            if whiteness.verdict == residual::Verdict::Coloured && within_resolution(opts, &p.name, m.rmse) {
                whiteness.verdict = residual::Verdict::Resolution;
            }
            channels.push(ChannelResult {
                name: p.name,
                unit: p.unit,
                derived: p.derived,
                meas: p.meas,
                sim: p.sim,
                metrics: m,
                budget: b,
                top_regions: top,
                worst_spans: worst,
                whiteness,
                cross: st.cross,
                structure: Vec::new(),
            });
        }
    }
    let structure_tested: usize = tested_windows.iter().flatten().map(|w| w.windows.len()).sum();
    let th = structure::threshold(structure_tested);
    for (c, w) in channels.iter_mut().zip(&tested_windows) {
        c.structure = w.iter().flat_map(|w| w.flagged(th)).copied().collect();
    }
    let t2 = Instant::now();

    let mut notes = vec![al.grid.step_note.clone()];
    notes.extend(al.grid.data_notes.iter().cloned());
    let in_gaps = al.grid.gaps.iter().filter(|g| **g).count();
    if in_gaps > 0 {
        notes.push(format!("{in_gaps} samples inside interpolated gaps are left out"));
    }
    notes.extend(classes.notes.iter().cloned());
    let missing: Vec<&str> = MEASURED.iter().filter(|c| !present.contains(c)).map(|c| c.name()).collect();
    if !missing.is_empty() {
        notes.push(format!("not in the file: {}", missing.join(", ")));
    }
    let inputs = match &opts.inputs {
        InputSource::Recorded => "recorded set points".to_string(),
        InputSource::Profile { which, throttle_scale, load_scale } => {
            format!("profile {} (throttle scale {throttle_scale}, load scale {load_scale})", which.name())
        }
    };
    Ok(CompareResult {
        setup: Setup {
            source: source.display().to_string(),
            dt_us: al.grid.dt_us,
            resampled: al.grid.resampled,
            step_note: al.grid.step_note.clone(),
            samples: n,
            duration_s: al.grid.duration_s(),
            inputs,
            rates: opts.model.rates,
            speed_target: opts.model.speed_target,
            supply_v: opts.model.supply_v,
            effects_on: !opts.model.effects.is_none(),
            speed_window_s: opts.model.sensors.speed_window_s,
            window_s: opts.window_s,
        },
        time_s: al.grid.time_s,
        inputs: al.grid.set_points,
        channels,
        structure_tested,
        regions: classes,
        notes,
        timing: (t1.duration_since(t0).as_secs_f64(), t2.duration_since(t1).as_secs_f64()),
    })
}
