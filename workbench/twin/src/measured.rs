//! A measured run as the twin sees it: the comparison grid, the set points on it, the
//! measured channels on it, and the twin's channels paired with them.
//!
//! Measured values within half an f32 ulp of the twin's value count as equal to it
//! (see `snap_to_f32`), so a bit-exact file compares to exactly zero.
//!
//! Timing convention (the one `model_core::Simulation` and `simrod bench` use): row `k`
//! of a file is the state at the *end* of a model step, and the set points in that row
//! are the ones held over that step. The twin starts at rest one step before the first
//! row, so a run must start from rest. In profile mode the profile clock is the row
//! time minus one step (a bench file's first row at `t = dt` is profile time 0).
//!
//! Model step: the measurement's mean sample interval when it is a whole number of
//! microseconds inside `model_core::model::DT_US_RANGE` (whole: the difference to the
//! nearest µs, accumulated over the run, is under 1 % of a step) and the grid is
//! uniform (every interval within 1 % of the mean); otherwise the twin runs at 1 ms and
//! the measured channels and set points are resampled onto a 1 ms grid by linear
//! interpolation.

use model_core::model::DT_US_RANGE;
use model_core::{Builtin, Channel, Effects, Inputs, Profile, ProfileSet, SetPoints, MEASURED};

use super::ModelOptions;
use simrod_io::budget::Budget;
use simrod_io::measure::resample::Interp;
use simrod_io::measure::{Measurement, GAP_CHANNEL, SETPOINT_LOAD_L, SETPOINT_LOAD_R, SETPOINT_THROTTLE};

/// Step used when the measurement's own interval cannot be the model step.
pub const FALLBACK_DT_US: u32 = 1000;

/// Where the twin's set points come from.
#[derive(Debug, Clone, PartialEq)]
pub enum InputSource {
    /// The file's set-point channels (`SuT Throttle`, `Dm Left`, `Dm Right`).
    Recorded,
    /// A built-in profile, scaled, for files without set-point channels.
    Profile { which: Builtin, throttle_scale: f32, load_scale: f32 },
}

/// Why the twin cannot run on a measurement (all user-data problems).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TwinError {
    #[error("the measurement has {0} samples; at least 2 are needed")]
    TooShort(usize),
    #[error("the time axis is not finite and strictly increasing")]
    BadTime,
    #[error(
        "the file spans {span_s:e} s ({rows} rows): shorter than two 1 ms steps of the twin, \
         nothing to compare (is the time column in seconds?)"
    )]
    ShortSpan { span_s: f64, rows: usize },
    #[error("channel {channel} has {got} values for {want} time samples")]
    Length { channel: String, got: usize, want: usize },
    #[error(
        "no set-point channel(s) {} in the file: compare with --profile NAME instead",
        .0.join(", ")
    )]
    NoSetPoints(Vec<String>),
    #[error("the file has none of the twin's measured channels")]
    NoChannels,
    #[error("the twin refused the configuration: {0}")]
    Model(String),
    #[error("profile: {0}")]
    Profile(String),
    #[error("--window-s must be finite and > 0")]
    Window,
    #[error("{0}")]
    Implausible(String),
    #[error("{0}")]
    OverBudget(String),
}

/// One channel, measured and simulated on the comparison grid.
#[derive(Debug, Clone)]
pub struct Paired {
    /// Bench name.
    pub name: String,
    /// Unit (the twin's unit: the file's may be spelled differently).
    pub unit: String,
    /// Computed from other channels (P_DPU, ...) rather than read from the file.
    pub derived: bool,
    /// Measured values.
    pub meas: Vec<f64>,
    /// Twin values, as the bench records them.
    pub sim: Vec<f64>,
}

/// The comparison grid of a measured run and what lies on it besides the channels:
/// shared by the prepared run ([`MeasuredTwin`]) and every alignment made from it.
#[derive(Debug, Clone, Default)]
pub struct RunGrid {
    /// [s] comparison grid (the file's time axis unless resampled).
    pub time_s: Vec<f64>,
    /// [µs] model step.
    pub dt_us: u32,
    /// Whether the measurement was resampled onto a 1 ms grid.
    pub resampled: bool,
    /// How the step was chosen, for the report.
    pub step_note: String,
    /// [%] set points applied at each step: throttle, load L, load R.
    pub set_points: [Vec<f64>; 3],
    /// Samples inside gaps the reader interpolated across (`--allow-gaps`): left out of
    /// every figure.
    pub gaps: Vec<bool>,
    /// What the file's values say about its channels (dead channels), for the report.
    pub data_notes: Vec<String>,
}

impl RunGrid {
    /// [s] model step.
    pub fn dt_s(&self) -> f64 {
        f64::from(self.dt_us) * 1e-6
    }

    /// [s] from the first to the last sample.
    pub fn duration_s(&self) -> f64 {
        self.time_s.last().copied().unwrap_or(0.0) - self.time_s.first().copied().unwrap_or(0.0)
    }
}

/// The twin run paired with the measurement.
#[derive(Debug, Clone)]
pub struct Aligned {
    /// The grid the pairs are on.
    pub grid: RunGrid,
    /// Comparable channels, measured ones in `MEASURED` order, then the derived ones.
    pub channels: Vec<Paired>,
    /// [A] the twin's commanded load phase currents L, R (a function of the set points
    /// only: the bench does not measure phase current), for the limit rule.
    pub phase_current: [Vec<f64>; 2],
    /// [rpm] the twin's SuT motor speed, for region rules when the file has none.
    pub sim_speed: Vec<f64>,
}

/// A measured run prepared for the twin: grid, set points and measured channels, built
/// once; [`MeasuredTwin::simulate`] then runs the twin on it with any effects.
#[derive(Debug, Clone)]
pub struct MeasuredTwin {
    /// The twin (its `effects` are the default of [`MeasuredTwin::align`]).
    pub model: ModelOptions,
    /// The comparison grid, set points and gaps.
    pub grid: RunGrid,
    /// The model's inputs, one per sample.
    pub inputs: Vec<Inputs>,
    /// The file's measured channels on the grid, in `MEASURED` order.
    pub measured: Vec<(Channel, Vec<f64>)>,
}

impl MeasuredTwin {
    /// Put `meas` on the comparison grid and take its set points from `source`.
    pub fn new(meas: &Measurement, model: &ModelOptions, source: &InputSource) -> Result<Self, TwinError> {
        let data_notes = crate::plausible::check(meas)?;
        let grid = choose_grid(&meas.time_s)?;
        let time_s = grid.resample_to.clone().unwrap_or_else(|| meas.time_s.clone());
        let set_points = match source {
            InputSource::Recorded => recorded_set_points(meas, &grid)?,
            InputSource::Profile { which, throttle_scale, load_scale } => profile_set_points(
                model.profile_sets(*which),
                *throttle_scale,
                *load_scale,
                &time_s,
                grid.dt_us,
            )?,
        };
        let inputs = (0..time_s.len())
            .map(|k| {
                let at = |v: &Vec<f64>| v.get(k).copied().unwrap_or(0.0) as f32;
                Inputs {
                    sp: SetPoints {
                        throttle_pct: at(&set_points[0]),
                        load_pct: [at(&set_points[1]), at(&set_points[2])],
                    },
                    supply_v: model.supply_v,
                }
            })
            .collect();
        let mut measured = Vec::new();
        for &ch in MEASURED {
            if let Some(v) = on_grid(meas, ch.name(), &grid)? {
                measured.push((ch, v));
            }
        }
        // Any trace of a gap (also after interpolation onto our grid) marks the sample.
        let gaps = match on_grid(meas, GAP_CHANNEL, &grid)? {
            Some(v) => v.iter().map(|g| *g != 0.0).collect(),
            None => vec![false; time_s.len()],
        };
        Ok(Self {
            model: model.clone(),
            grid: RunGrid {
                time_s,
                dt_us: grid.dt_us,
                resampled: grid.resample_to.is_some(),
                step_note: grid.note,
                set_points,
                gaps,
                data_notes,
            },
            inputs,
            measured,
        })
    }

    /// The twin's `channels` with `effects`, as the bench records them, one value per
    /// sample of the grid.
    pub fn simulate(&self, effects: Effects, channels: &[Channel]) -> Result<Vec<Vec<f32>>, TwinError> {
        self.model.run(self.grid.dt_us, effects, &self.inputs, channels)
    }

    /// The twin with `effects` paired with every measured channel, plus the derived
    /// powers; the prepared run stays (to run the twin again).
    pub fn align(&self, effects: Effects) -> Result<Aligned, TwinError> {
        let measured = self.measured.iter().map(|(c, m)| (*c, m.clone())).collect();
        self.pair(effects, measured, self.grid.clone())
    }

    /// Per channel of `channels`, the noise σ stated for each sample of the run (the
    /// model's [`crate::SensorModel::stated_sigma`], its limit factor from the recorded
    /// flange torques and SuT motor speed).
    pub fn stated_sigma(&self, channels: &[Channel]) -> Vec<Option<Vec<f64>>> {
        let series = |c: Channel| self.measured.iter().find(|(m, _)| *m == c).map(|(_, v)| v.as_slice());
        let chans: Vec<Option<Channel>> = channels.iter().copied().map(Some).collect();
        self.model.sensors.stated_sigma(&chans, series, self.inputs.len())
    }

    /// As [`MeasuredTwin::align`], consuming the prepared run: its channels and grid
    /// move into the result instead of being copied (a long run held once, not twice).
    pub fn into_aligned(mut self, effects: Effects) -> Result<Aligned, TwinError> {
        let measured = std::mem::take(&mut self.measured);
        let empty = RunGrid { dt_us: self.grid.dt_us, ..RunGrid::default() };
        let grid = std::mem::replace(&mut self.grid, empty);
        self.pair(effects, measured, grid)
    }

    /// As [`MeasuredTwin::align`], moving the measured channels into the pairs: the
    /// prepared run can still run the twin (its inputs and grid stay), and a long run is
    /// not held twice.
    pub fn align_taking(&mut self, effects: Effects) -> Result<Aligned, TwinError> {
        let measured = std::mem::take(&mut self.measured);
        self.pair(effects, measured, self.grid.clone())
    }

    fn pair(
        &self,
        effects: Effects,
        measured: Vec<(Channel, Vec<f64>)>,
        grid: RunGrid,
    ) -> Result<Aligned, TwinError> {
        let mut wanted: Vec<Channel> = measured.iter().map(|(c, _)| *c).collect();
        wanted.extend([Channel::ILmlPhase, Channel::ILmrPhase, Channel::SuTMotorEnc]);
        let mut sim = self.simulate(effects, &wanted)?;
        let widen = |v: Vec<f32>| v.into_iter().map(f64::from).collect::<Vec<f64>>();
        let tail = sim.split_off(measured.len());
        let [phase_l, phase_r, speed]: [Vec<f32>; 3] = tail.try_into().map_err(|_| TwinError::NoChannels)?;
        let mut channels: Vec<Paired> = measured
            .into_iter()
            .zip(sim)
            .map(|((ch, mut m), s)| {
                let s = widen(s);
                snap_to_f32(&mut m, &s);
                Paired {
                    name: ch.name().to_string(),
                    unit: ch.unit().to_string(),
                    derived: false,
                    meas: m,
                    sim: s,
                }
            })
            .collect();
        let derived = derive_powers(&channels);
        channels.extend(derived);
        Ok(Aligned {
            grid,
            channels,
            phase_current: [widen(phase_l), widen(phase_r)],
            sim_speed: widen(speed),
        })
    }
}

/// How the comparison grid relates to the file's.
struct GridChoice {
    dt_us: u32,
    /// `None`: use the file's samples as they are.
    resample_to: Option<Vec<f64>>,
    note: String,
}

/// The file's set-point channels on the grid; all three are needed.
fn recorded_set_points(meas: &Measurement, grid: &GridChoice) -> Result<[Vec<f64>; 3], TwinError> {
    let mut got = Vec::with_capacity(3);
    let mut missing = Vec::new();
    for name in [SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R] {
        match on_grid(meas, name, grid)? {
            Some(v) => got.push(v),
            None => missing.push(name.to_string()),
        }
    }
    if !missing.is_empty() {
        return Err(TwinError::NoSetPoints(missing));
    }
    got.try_into().map_err(|_| TwinError::NoSetPoints(vec![SETPOINT_THROTTLE.into()]))
}

/// The comparison grid, planned before anything is allocated.
struct GridPlan {
    dt_us: u32,
    /// `Some((t0, samples))`: a 1 ms grid from `t0`; `None`: the file's samples.
    resample: Option<(f64, usize)>,
    note: String,
}

/// Samples on the comparison grid of a run with sample times `time` (the file's count
/// unless it is resampled to 1 ms), and how the grid was chosen: what a command checks
/// against its memory budget before the run is put on the grid.
pub fn grid_samples(time: &[f64]) -> Result<(usize, String), TwinError> {
    let plan = plan_grid(time)?;
    Ok((plan.resample.map_or(time.len(), |(_, n)| n), plan.note))
}

/// Refuse, before anything is put on the grid, a run whose comparison would hold more
/// than `budget` at `per_sample` bytes per grid sample (`doing` names the command's
/// work in the message).
pub fn check_budget(time: &[f64], budget: &Budget, doing: &str, per_sample: f64) -> Result<(), TwinError> {
    let (n, note) = grid_samples(time)?;
    let why = format!("{n} samples on the twin's grid, {per_sample} bytes each; {note}");
    budget.check(doing, n as f64 * per_sample, &why).map_err(TwinError::OverBudget)
}

fn choose_grid(time: &[f64]) -> Result<GridChoice, TwinError> {
    let plan = plan_grid(time)?;
    let dt = f64::from(plan.dt_us) * 1e-6;
    let resample_to = plan.resample.map(|(t0, n)| (0..n).map(|j| t0 + j as f64 * dt).collect());
    Ok(GridChoice { dt_us: plan.dt_us, resample_to, note: plan.note })
}

fn plan_grid(time: &[f64]) -> Result<GridPlan, TwinError> {
    let n = time.len();
    let (Some(&t0), Some(&t1)) = (time.first(), time.last()) else {
        return Err(TwinError::TooShort(n));
    };
    if n < 2 {
        return Err(TwinError::TooShort(n));
    }
    if !time.iter().all(|t| t.is_finite()) || t1 <= t0 {
        return Err(TwinError::BadTime);
    }
    let mean = (t1 - t0) / (n - 1) as f64;
    let uniform = time.windows(2).all(|w| ((w[1] - w[0]) - mean).abs() <= 0.01 * mean);
    if !time.windows(2).all(|w| w[1] > w[0]) {
        return Err(TwinError::BadTime);
    }
    let us = mean * 1e6;
    let rounded = us.round();
    // Whole: the difference, accumulated over the run, stays within 1 % of a step.
    let whole = (us - rounded).abs() * (n - 1) as f64 <= 0.01 * rounded;
    let in_range = rounded >= f64::from(DT_US_RANGE.0) && rounded <= f64::from(DT_US_RANGE.1);
    if uniform && whole && in_range {
        return Ok(GridPlan {
            dt_us: rounded as u32,
            resample: None,
            note: format!("model step = sample interval = {rounded} µs"),
        });
    }
    let dt = f64::from(FALLBACK_DT_US) * 1e-6;
    let steps = ((t1 - t0) / dt + 1e-9).floor();
    if steps < 1.0 {
        return Err(TwinError::ShortSpan { span_s: t1 - t0, rows: n });
    }
    let why = if !uniform {
        "the time axis is not uniform".to_string()
    } else if !whole {
        format!("the sample interval {us:.4} µs is not a whole number of µs")
    } else {
        format!("the sample interval {rounded} µs is outside {}..{} µs", DT_US_RANGE.0, DT_US_RANGE.1)
    };
    Ok(GridPlan {
        dt_us: FALLBACK_DT_US,
        // Saturating: a span beyond usize is refused by the caller's budget.
        resample: Some((t0, steps.min(usize::MAX as f64 / 2.0) as usize + 1)),
        note: format!("{why}: measurement resampled (linear) to 1 ms, model step 1 ms"),
    })
}

/// A signal of the file on the comparison grid; a length mismatch is a user-data error.
fn on_grid(meas: &Measurement, name: &str, grid: &GridChoice) -> Result<Option<Vec<f64>>, TwinError> {
    let Some(sig) = meas.signal(name) else {
        return Ok(None);
    };
    if sig.values.len() != meas.time_s.len() {
        return Err(TwinError::Length {
            channel: name.to_string(),
            got: sig.values.len(),
            want: meas.time_s.len(),
        });
    }
    Ok(Some(match &grid.resample_to {
        None => sig.values.clone(),
        Some(g) => Interp::new(&meas.time_s, g).apply(&sig.values),
    }))
}

/// Measured values that round to the twin's f32 value *are* that value: the twin
/// computes in f32, and a file of f32 decimals reads back as the f64 nearest the
/// decimal, up to half an f32 ulp (~6e-8 relative) away from the f32 itself. Without
/// this a bit-exact run would show a spurious error of that size; real measurement
/// noise is orders of magnitude above it.
fn snap_to_f32(meas: &mut [f64], sim: &[f64]) {
    for (m, s) in meas.iter_mut().zip(sim) {
        if m.is_finite() && (*m as f32) == (*s as f32) {
            *m = *s;
        }
    }
}

/// Set points of a built-in profile at each row: profile clock = row time − one step.
fn profile_set_points(
    sets: &[ProfileSet],
    throttle_scale: f32,
    load_scale: f32,
    time_s: &[f64],
    dt_us: u32,
) -> Result<[Vec<f64>; 3], TwinError> {
    let profile =
        Profile::new(sets, throttle_scale, load_scale).map_err(|e| TwinError::Profile(format!("{e:?}")))?;
    let mut out = [
        Vec::with_capacity(time_s.len()),
        Vec::with_capacity(time_s.len()),
        Vec::with_capacity(time_s.len()),
    ];
    for &t in time_s {
        let t_us = (t * 1e6).round().max(0.0) as u64;
        let sp = profile.at(t_us.saturating_sub(u64::from(dt_us)));
        out[0].push(f64::from(sp.throttle_pct));
        out[1].push(f64::from(sp.load_pct[0]));
        out[2].push(f64::from(sp.load_pct[1]));
    }
    Ok(out)
}

/// A power the bench derives from measured channels (thesis 5.13):
/// `factor × ΣI × V`, the same product the model computes for its output.
pub struct Power {
    pub channel: Channel,
    pub volts: Channel,
    /// Currents summed before the product.
    pub amps: &'static [Channel],
    /// Legs the current stands for (the right load motor's inverter measures one of two).
    pub factor: f64,
}

impl Power {
    /// The power for voltage `v` and summed current `amps`.
    pub fn of(&self, v: f64, amps: f64) -> f64 {
        self.factor * amps * v
    }
}

/// The powers a bench run can derive, each once. (The connector loss needs the busbar
/// and inverter voltages on one time base; the bench does not derive it.)
pub const POWERS: [Power; 4] = [
    Power { channel: Channel::PDpu, volts: Channel::VDcBusbars, amps: &[Channel::IDpu27], factor: 1.0 },
    Power { channel: Channel::PSutInv, volts: Channel::VDc, amps: &[Channel::IDc], factor: 1.0 },
    Power {
        channel: Channel::PLml,
        volts: Channel::VDcBusbars,
        amps: &[Channel::IXlml22, Channel::IXlmlBu1],
        factor: 1.0,
    },
    Power { channel: Channel::PLmr, volts: Channel::VDcBusbars, amps: &[Channel::IXlmr23], factor: 2.0 },
];

/// Derived power channels ([`POWERS`]), computed from measured channels exactly as the
/// twin's outputs define them, on both sides; only those whose inputs exist.
pub fn derive_powers(channels: &[Paired]) -> Vec<Paired> {
    let get = |c: Channel| channels.iter().find(|p| p.name == c.name());
    let n = channels.first().map_or(0, |p| p.meas.len());
    let side = |p: &Paired, sim: bool, k: usize| {
        let v = if sim { &p.sim } else { &p.meas };
        v.get(k).copied().unwrap_or(f64::NAN)
    };
    POWERS
        .iter()
        .filter_map(|pw| {
            let v = get(pw.volts)?;
            let amps: Vec<&Paired> = pw.amps.iter().map(|&a| get(a)).collect::<Option<_>>()?;
            let (first, rest) = amps.split_first()?;
            let series = |sim: bool| -> Vec<f64> {
                (0..n)
                    .map(|k| {
                        let i = rest.iter().fold(side(first, sim, k), |s, a| s + side(a, sim, k));
                        pw.of(side(v, sim, k), i)
                    })
                    .collect()
            };
            Some(Paired {
                name: pw.channel.name().to_string(),
                unit: pw.channel.unit().to_string(),
                derived: true,
                meas: series(false),
                sim: series(true),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_microsecond_grid_is_kept() {
        let t: Vec<f64> = (1..=100).map(|k| k as f64 * 1e-3).collect();
        let g = choose_grid(&t).unwrap();
        assert_eq!(g.dt_us, 1000);
        assert!(g.resample_to.is_none());
        let t: Vec<f64> = (1..=100).map(|k| k as f64 * 1e-4).collect();
        assert_eq!(choose_grid(&t).unwrap().dt_us, 100);
    }

    #[test]
    fn odd_interval_is_resampled_to_1ms() {
        let t: Vec<f64> = (0..300).map(|k| k as f64 * 1.5005e-3 + 0.0000007).collect();
        let g = choose_grid(&t).unwrap();
        assert_eq!(g.dt_us, 1000);
        let grid = g.resample_to.unwrap();
        assert_eq!(grid.len(), (299.0 * 1.5005) as usize + 1);
        let y: Vec<f64> = t.iter().map(|x| 3.0 * x + 1.0).collect();
        let r = Interp::new(&t, &grid).apply(&y);
        for (g, v) in grid.iter().zip(&r) {
            assert!((v - (3.0 * g + 1.0)).abs() < 1e-12);
        }
        // 20 ms is beyond the model's range.
        let t: Vec<f64> = (0..10).map(|k| k as f64 * 0.02).collect();
        assert!(choose_grid(&t).unwrap().resample_to.is_some());
    }

    #[test]
    fn bad_time_axes_are_errors_not_panics() {
        assert!(matches!(choose_grid(&[]), Err(TwinError::TooShort(0))));
        assert!(matches!(choose_grid(&[1.0]), Err(TwinError::TooShort(1))));
        assert!(matches!(choose_grid(&[0.0, f64::NAN, 2.0]), Err(TwinError::BadTime)));
        assert!(matches!(choose_grid(&[0.0, 0.002, 0.001, 0.003]), Err(TwinError::BadTime)));
        // 1000 rows 1 ns apart (a time column in the wrong unit) span 1 µs: refused, not
        // "1 samples".
        let ns: Vec<f64> = (0..1000).map(|k| k as f64 * 1e-9).collect();
        let Err(e) = choose_grid(&ns) else { panic!("a 1 µs file was accepted") };
        assert!(matches!(e, TwinError::ShortSpan { rows: 1000, .. }), "{e}");
        assert!(e.to_string().contains("is the time column in seconds?"), "{e}");
    }
}
