//! The measurement chain on top of a twin run: what the bench's sensors and data
//! acquisition make of the model's exact channels. Which sensor gets which noise is
//! listed in `workbench/examples/noise.toml`.

use std::path::Path;

use model_core::{Channel, Simulation, MEASURED};

use super::encoder::{windowed_rpm, Encoder};
use super::noise::{Gauss, Miscount, NoiseModel};
use simrod_io::measure::{Measurement, Signal, SETPOINT_LOAD_L, SETPOINT_LOAD_R, SETPOINT_THROTTLE};
use simrod_numerics::stats::Rng;

/// A twin run, only what the bench records: measured channels and set points.
#[derive(Debug, Clone, PartialEq)]
pub struct Recorded {
    /// [µs] time of each sample (end of its model step).
    pub t_us: Vec<u64>,
    /// [s] step.
    pub dt_s: f64,
    /// One series per entry of `MEASURED`, in that order.
    pub measured: Vec<Vec<f32>>,
    /// Throttle, load L, load R set points [%], as held over each step.
    pub setpoints: [Vec<f32>; 3],
}

impl Recorded {
    /// Run `sim` to the end of its profile.
    pub fn run(sim: Simulation<'_>) -> Self {
        let dt_s = f64::from(sim.model().dt_us()) * 1e-6;
        let n = usize::try_from(sim.total_steps()).unwrap_or(0);
        let mut r = Self {
            t_us: Vec::with_capacity(n),
            dt_s,
            measured: vec![Vec::with_capacity(n); MEASURED.len()],
            setpoints: std::array::from_fn(|_| Vec::with_capacity(n)),
        };
        for o in sim {
            r.t_us.push(o.t_us);
            for (s, c) in r.measured.iter_mut().zip(MEASURED) {
                s.push(o.get(*c));
            }
            let sp = [Channel::ThrottleSp, Channel::LoadLSp, Channel::LoadRSp];
            for (s, c) in r.setpoints.iter_mut().zip(sp) {
                s.push(o.get(c));
            }
        }
        r
    }

    /// The exact series of a measured channel (empty if it is not measured).
    pub fn get(&self, c: Channel) -> &[f32] {
        MEASURED.iter().position(|m| *m == c).and_then(|i| self.measured.get(i)).map_or(&[], Vec::as_slice)
    }
}

/// What to put between the twin and the file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainOptions {
    /// `None`: the exact model values (no noise, no quantisation).
    pub noise: Option<NoiseModel>,
    pub seed: u64,
    /// Siemens encoder loses pulses at speed.
    pub miscount: bool,
}

/// The value a file holds for an f32 sample: its shortest decimal, read as f64 (or the
/// exact f64 of `v` in the rare case that decimal does not read back to `v` through
/// f64). CSV and MAT files then hold the same number, and `as f32` gives `v` back.
pub fn file_value(v: f32) -> f64 {
    match v.to_string().parse::<f64>() {
        Ok(x) if (x as f32).to_bits() == v.to_bits() => x,
        _ => f64::from(v),
    }
}

/// Stream ids: one per channel and purpose, so the parts are independent.
const STREAM_NOISE: u64 = 0;
const STREAM_PHASE: u64 = 100;
const STREAM_MISCOUNT: u64 = 200;
const STREAM_JITTER: u64 = 300;

/// Pulse channel names (thesis table 5.9): cumulative edge counts of the R flange's
/// Kistler encoder and of the Siemens encoder behind the R coupling, and the latched
/// time of each one's last edge. See [`pulse_channels`].
pub const PULSE_KISTLER: &str = "inc:Kistler";
pub const PULSE_SIEMENS: &str = "inc:SiemensEnc";
pub const EDGE_TIME_KISTLER: &str = "tedge:Kistler";
pub const EDGE_TIME_SIEMENS: &str = "tedge:SiemensEnc";

/// Apply the chain; the result has time, `MEASURED` and the three set points.
pub fn measure(rec: &Recorded, opts: &ChainOptions, source: &Path) -> Measurement {
    let n = rec.t_us.len();
    let mut signals = Vec::with_capacity(MEASURED.len() + 3);
    let g: Vec<f64> = match &opts.noise {
        Some(nm) => {
            let (tl, tr, w) =
                (rec.get(Channel::CKistlerL), rec.get(Channel::CKistlerR), rec.get(Channel::SuTMotorEnc));
            (0..n).map(|k| nm.limits.factor(f64::from(tl[k]), f64::from(tr[k]), f64::from(w[k]))).collect()
        }
        None => Vec::new(),
    };
    for (i, (c, exact)) in MEASURED.iter().zip(&rec.measured).enumerate() {
        let values: Vec<f64> = match &opts.noise {
            None => exact.iter().map(|v| file_value(*v)).collect(),
            Some(nm) => sensor(*c, i as u64, exact, &g, nm, rec.dt_s, opts)
                .into_iter()
                .map(|v| file_value(v as f32))
                .collect(),
        };
        signals.push(Signal { name: c.name().to_owned(), unit: c.unit().to_owned(), values });
    }
    for (name, sp) in [SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R].into_iter().zip(&rec.setpoints) {
        signals.push(Signal {
            name: name.to_owned(),
            unit: "%".to_owned(),
            values: sp.iter().map(|v| file_value(*v)).collect(),
        });
    }
    Measurement {
        source: source.to_path_buf(),
        time_s: rec.t_us.iter().map(|t| *t as f64 / 1e6).collect(),
        signals,
    }
}

/// Counts of one encoder over a run (`counts[0] = 0` at rest at t = 0, then one per
/// sample), from the shaft speed `exact` [rpm] of the channel at `idx` in `MEASURED`.
/// The start phase and the lost pulses come from that channel's own random streams, so
/// the speed channel and its pulse channels see the same edges. `edge(k, fraction, count)`
/// is told every counted edge: in sample interval `k`, at `fraction` of it.
fn count_pulses(
    exact: &[f32],
    dt: f64,
    ppr: u32,
    seed: u64,
    idx: u64,
    miscount: Option<&Miscount>,
    edge: &mut dyn FnMut(usize, f64, i64),
) -> Vec<i64> {
    let phase = Rng::new(seed, STREAM_PHASE + idx).uniform();
    let mut lose = Rng::new(seed, STREAM_MISCOUNT + idx);
    let mut lost = |rpm: f64| match miscount {
        Some(m) => {
            let p = m.drop_probability(rpm);
            p > 0.0 && lose.uniform() < p
        }
        None => false,
    };
    let mut e = Encoder::new(ppr, phase);
    let mut counts = Vec::with_capacity(exact.len() + 1);
    counts.push(0);
    let mut prev = 0.0; // the run starts at rest
    for (k, v) in exact.iter().enumerate() {
        let v = f64::from(*v);
        counts.push(e.advance_edges(prev, v, dt, &mut lost, &mut |f, c| edge(k, f, c)));
        prev = v;
    }
    counts
}

/// Pulse channels of the R shaft (`simrod bench --pulses`), as a DAQ counter/timer input
/// exports them (thesis table 5.9): per encoder, the signed cumulative edge count at each
/// sample ([`PULSE_KISTLER`], [`PULSE_SIEMENS`]; quadrature, so reverse counts down) and
/// the time [s] of the last edge counted up to that sample, latched on the timer clock
/// ([`EDGE_TIME_KISTLER`], [`EDGE_TIME_SIEMENS`]; 0 before the first edge). The counts are
/// those behind `T_Kistler_R` and `SiemensEnc`, lost pulses included (`--miscount`).
/// When two edges fall into one sample only the later one's time is kept, as a latch
/// does. With `--noise none` the times are exact and nothing is lost.
pub fn pulse_channels(rec: &Recorded, opts: &ChainOptions) -> Vec<Signal> {
    let nm = opts.noise;
    let enc = nm.map(|m| m.encoders).unwrap_or_default();
    let n = rec.t_us.len();
    let mut out = Vec::with_capacity(4);
    let shafts = [
        (Channel::TKistlerR, enc.kistler_ppr, false, PULSE_KISTLER, EDGE_TIME_KISTLER),
        (Channel::SiemensEnc, enc.siemens_ppr, opts.miscount, PULSE_SIEMENS, EDGE_TIME_SIEMENS),
    ];
    for (c, ppr, miscount, count_name, time_name) in shafts {
        let idx = MEASURED.iter().position(|m| *m == c).unwrap_or(0) as u64;
        let exact = rec.get(c);
        let lose = match (&nm, miscount) {
            (Some(m), true) => Some(&m.miscount),
            _ => None,
        };
        let mut jitter = Rng::new(opts.seed, STREAM_JITTER + idx);
        let mut latched = vec![0.0f64; n];
        let mut last = 0.0f64;
        let mut at = |k: usize, frac: f64, _count: i64| {
            let t1 = rec.t_us.get(k).map_or(0.0, |t| *t as f64 * 1e-6);
            let t0 = t1 - rec.dt_s;
            let mut t = t0 + frac * rec.dt_s;
            if let Some(m) = &nm {
                // Edge position noise, as a time shift at the interval's mean pulse rate.
                let v0 = if k > 0 { exact.get(k - 1).map_or(0.0, |v| f64::from(*v)) } else { 0.0 };
                let v1 = exact.get(k).map_or(0.0, |v| f64::from(*v));
                let rate = (0.5 * (v0 + v1) / 60.0 * f64::from(ppr)).abs();
                let shift = m.encoders.edge_jitter_deg / 360.0 * f64::from(ppr) * jitter.gauss();
                if rate > 0.0 {
                    t += shift / rate;
                }
                let clock = m.encoders.timer_s;
                t = (t / clock).round() * clock;
            }
            last = t.max(t0).max(last).min(t1);
            if let Some(slot) = latched.get_mut(k) {
                *slot = last;
            }
        };
        let counts = count_pulses(exact, rec.dt_s, ppr, opts.seed, idx, lose, &mut at);
        // Carry the latch forward over samples without an edge.
        let mut held = 0.0;
        for (k, v) in latched.iter_mut().enumerate() {
            if counts.get(k + 1) != counts.get(k) {
                held = *v;
            }
            *v = held;
        }
        out.push(Signal {
            name: count_name.to_owned(),
            unit: "pulses".to_owned(),
            values: counts.iter().skip(1).map(|c| *c as f64).collect(),
        });
        out.push(Signal { name: time_name.to_owned(), unit: "s".to_owned(), values: latched });
    }
    out
}

/// The noisy series of one measured channel (`idx` = its position in `MEASURED`).
fn sensor(
    c: Channel,
    idx: u64,
    exact: &[f32],
    g: &[f64],
    nm: &NoiseModel,
    dt: f64,
    opts: &ChainOptions,
) -> Vec<f64> {
    let gauss = |p: Gauss| {
        let mut rng = Rng::new(opts.seed, STREAM_NOISE + idx);
        exact.iter().zip(g).map(|(v, g)| f64::from(*v) + p.sigma_at(*g) * rng.gauss()).collect()
    };
    let enc = &nm.encoders;
    let encoder = |ppr: u32, miscount: bool| {
        let lose = miscount.then_some(&nm.miscount);
        let counts = count_pulses(exact, dt, ppr, opts.seed, idx, lose, &mut |_, _, _| {});
        let half = ((enc.window_s / (2.0 * dt)).round() as usize).max(1);
        windowed_rpm(&counts, ppr, dt, half)
    };
    if let Some(p) = nm.gauss(c) {
        return gauss(p);
    }
    match c {
        Channel::TKistlerL | Channel::TKistlerR => encoder(enc.kistler_ppr, false),
        Channel::SuTMotorEnc => encoder(enc.sut_motor_ppr, false),
        Channel::SiemensEnc => encoder(enc.siemens_ppr, opts.miscount),
        // A channel added to MEASURED later has no sensor model yet: exact.
        _ => exact.iter().map(|v| f64::from(*v)).collect(),
    }
}
