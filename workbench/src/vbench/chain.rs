//! The measurement chain on top of a twin run: what the bench's sensors and data
//! acquisition make of the model's exact channels. Which sensor gets which noise is
//! listed in `workbench/examples/noise.toml`.

use std::path::Path;

use model_core::{Channel, Simulation, MEASURED};

use super::encoder::{windowed_rpm, Encoder};
use super::noise::{Gauss, NoiseModel};
use super::rng::Rng;
use crate::measure::{Measurement, Signal, SETPOINT_LOAD_L, SETPOINT_LOAD_R, SETPOINT_THROTTLE};

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
        let phase = Rng::new(opts.seed, STREAM_PHASE + idx).uniform();
        let mut lose = Rng::new(opts.seed, STREAM_MISCOUNT + idx);
        let mut lost = |rpm: f64| {
            let p = nm.miscount.drop_probability(rpm);
            miscount && p > 0.0 && lose.uniform() < p
        };
        let mut e = Encoder::new(ppr, phase);
        let mut counts = Vec::with_capacity(exact.len() + 1);
        counts.push(0);
        let mut prev = 0.0; // the run starts at rest
        for v in exact {
            let v = f64::from(*v);
            counts.push(e.advance(prev, v, dt, &mut lost));
            prev = v;
        }
        let half = ((enc.window_s / (2.0 * dt)).round() as usize).max(1);
        windowed_rpm(&counts, ppr, dt, half)
    };
    match c {
        Channel::CKistlerL | Channel::CKistlerR => gauss(nm.torque),
        Channel::TKistlerL | Channel::TKistlerR => encoder(enc.kistler_ppr, false),
        Channel::SuTMotorEnc => encoder(enc.sut_motor_ppr, false),
        Channel::SiemensEnc => encoder(enc.siemens_ppr, opts.miscount),
        Channel::IXlml22 | Channel::IXlmlBu1 => gauss(nm.current.xlml),
        Channel::IXlmr23 => gauss(nm.current.xlmr),
        Channel::IDpu27 => gauss(nm.current.dpu),
        Channel::IDc => gauss(nm.current.dc),
        Channel::VDcBusbars => gauss(nm.voltage.busbars),
        Channel::VDc => gauss(nm.voltage.dc),
        Channel::Throttle => gauss(nm.voltage.throttle),
        // A channel added to MEASURED later has no sensor model yet: exact.
        _ => exact.iter().map(|v| f64::from(*v)).collect(),
    }
}
