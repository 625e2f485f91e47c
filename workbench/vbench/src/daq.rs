//! Bench-only effects of the data acquisition: what a real bench's sensors, amplifiers
//! and converters do to a signal that the model (and the Gaussian/encoder chain of
//! [`crate::chain`]) lacks. Each effect is declared once in [`DAQ_EFFECTS`] (id, physics,
//! unit, which channels, realistic range) and set per channel from an effect file:
//!
//! ```toml
//! [amplifier_lag]
//! c_kistler_l = 0.04   # C_Kistler_L behind a 40 ms first-order amplifier/filter
//! [mains_pickup]
//! i_dc = 0.8           # 0.8 A of 50 Hz on I_DC
//! ```
//!
//! A parameter is named by the channel's key ([`channel_key`]): the bench name
//! lowercased, every run of non-alphanumeric characters replaced by `_`, trimmed
//! (`I_XLML 2.2` → `i_xlml_2_2`). A value of 0 switches the effect off on that channel.
//! "Analog" channels ([`is_analog`]) are those read through an amplifier and an ADC:
//! the torques `C_Kistler_L/R`, the currents, the voltages and `Throttle`; the encoder
//! speeds (`SuTMotorEnc`, `T_Kistler_L/R`, `SiemensEnc`) are counted, so only
//! `daq_skew` applies to them.
//!
//! # Order
//!
//! 1. sensor and amplifier, on the exact signal ([`DaqEffects::apply_before_noise`]):
//!    `amplifier_lag` (the filter acts on the physical signal), then `offset_drift` and
//!    `mains_pickup` added to the amplifier's output (so the pickup amplitude is the
//!    recorded one, not attenuated by the lag);
//! 2. acquisition time: `daq_skew`, the channel sampled at `t − skew`. The lagged exact
//!    series is delayed by linear interpolation; drift and pickup, being known
//!    functions of time, are evaluated at `t − skew` exactly;
//! 3. sensor noise and encoder counting (`chain.rs`, not here);
//! 4. converter, on the file values ([`DaqEffects::apply_after_noise`]):
//!    `sensor_clipping` (clamp to ± full scale), then `adc_quantisation` (round to a
//!    multiple of the LSB). The result is stored as the file value of an f32, as
//!    [`crate::chain::file_value`] does for every other sample.
//!
//! Time base: sample `k` is at `t_us[k]` (the end of model step `k`, so the first sample
//! is at `t = dt`); the run starts at rest at `t = 0`. Lag and skew need the step
//! `dt_s`; if it is not a positive finite number they leave the series unchanged.
//! Nothing here panics, and finite input with finite parameters gives finite output
//! (values beyond the f32 range saturate at ±`f32::MAX`). Internally everything is f64.

use std::collections::BTreeMap;
use std::fmt;

use model_core::{Channel, MEASURED};
use simrod_io::measure::Measurement;

use simrod_plant::sampled::{first_order_lag, fractional_delay};

use crate::chain::{file_value, Recorded};

/// Unit of a DAQ effect's per-channel parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamUnit {
    /// [s]
    Seconds,
    /// The channel's own unit (`N m`, `A`, `V`).
    ChannelUnit,
    /// The channel's unit per minute (`N m/min`, ...).
    ChannelUnitPerMinute,
}

impl ParamUnit {
    /// The unit as text for channel `c`, e.g. `s`, `N m`, `A/min`.
    pub fn symbol(self, c: Channel) -> String {
        match self {
            ParamUnit::Seconds => "s".to_owned(),
            ParamUnit::ChannelUnit => c.unit().to_owned(),
            ParamUnit::ChannelUnitPerMinute => format!("{}/min", c.unit()),
        }
    }
}

/// One DAQ effect, declared once: everything messages, docs and the random-case
/// generator need.
#[derive(Debug, Clone, Copy)]
pub struct DaqDecl {
    /// Section name in effect files.
    pub id: &'static str,
    /// Physics, one or two sentences.
    pub doc: &'static str,
    /// Unit of the per-channel parameter.
    pub unit: ParamUnit,
    /// `true`: analog channels only ([`is_analog`]); `false`: any `MEASURED` channel.
    pub analog_only: bool,
    /// Whether the parameter may be negative (the sign means something).
    pub signed: bool,
    /// Realistic magnitude range (lo, hi) for a channel, in the parameter's unit; per
    /// channel because units differ. `None`: not applicable to that channel.
    pub realistic: fn(Channel) -> Option<(f64, f64)>,
}

impl DaqDecl {
    /// Whether this effect has a parameter for channel `c`.
    pub fn accepts(&self, c: Channel) -> bool {
        MEASURED.contains(&c) && (!self.analog_only || is_analog(c))
    }

    /// The channels this effect has a parameter for, in `MEASURED` order.
    pub fn channels(&self) -> Vec<Channel> {
        MEASURED.iter().copied().filter(|c| self.accepts(*c)).collect()
    }
}

const LAG: usize = 0;
const SKEW: usize = 1;
const QUANT: usize = 2;
const CLIP: usize = 3;
const PICKUP: usize = 4;
const DRIFT: usize = 5;

/// Mains frequency [Hz]: the bench is at ETH Zurich (European grid, 50 Hz).
pub const MAINS_HZ: f64 = 50.0;
/// Mains period [µs], exact: the pickup phase is computed modulo this.
const MAINS_PERIOD_US: f64 = 20_000.0;

/// Every DAQ effect, in the order [`DaqEffects::entries`] lists them.
pub const DAQ_EFFECTS: &[DaqDecl] = &[
    DaqDecl {
        id: "amplifier_lag",
        doc: "First-order lag of the channel's conditioning amplifier / anti-alias filter, \
              time constant tau [s]: tau dy/dt = x - y, starting at rest at the first sample's \
              value (exact discretisation for an input linear between samples). Realistic 1-50 ms.",
        unit: ParamUnit::Seconds,
        analog_only: true,
        signed: false,
        realistic: realistic_lag,
    },
    DaqDecl {
        id: "daq_skew",
        doc: "The channel is recorded late: the value written at t is the signal at t - skew [s] \
              (separate acquisition units or buffered modules not sharing a clock), linear \
              interpolation between samples, the first sample's value before it. Realistic 1-100 ms.",
        unit: ParamUnit::Seconds,
        analog_only: false,
        signed: false,
        realistic: realistic_skew,
    },
    DaqDecl {
        id: "adc_quantisation",
        doc: "ADC step (LSB) [channel unit]: the recorded value is rounded to the nearest multiple. \
              Realistic: 2 x full scale / 2^16 (16-bit) to 2 x full scale / 2^12 (12-bit), e.g. \
              0.006-0.1 N m for a +-200 N m torque channel.",
        unit: ParamUnit::ChannelUnit,
        analog_only: true,
        signed: false,
        realistic: realistic_lsb,
    },
    DaqDecl {
        id: "sensor_clipping",
        doc: "Full scale [channel unit] of the sensor / ADC input range: the recorded value is \
              clamped to +-full scale. Realistic somewhat above the operating range (KiTorq \
              flange rated 200 N m, A622 clamps 100 A, ...).",
        unit: ParamUnit::ChannelUnit,
        analog_only: true,
        signed: false,
        realistic: realistic_full_scale,
    },
    DaqDecl {
        id: "mains_pickup",
        doc: "50 Hz mains pickup on the sensor cable or amplifier (European grid), amplitude A \
              [channel unit]: A sin(2 pi 50 t), phase 0 at t = 0, running before and after the \
              run. Meant for the current probes; realistic 0.1-2 A there.",
        unit: ParamUnit::ChannelUnit,
        analog_only: true,
        signed: false,
        realistic: realistic_pickup,
    },
    DaqDecl {
        id: "offset_drift",
        doc: "Slow linear offset drift [channel unit/min] (thermal drift of a bridge amplifier or \
              Hall probe), zero at t = 0: offset = rate x t / 60 s; negative drifts down. \
              Realistic 0.05-0.5 N m/min on torque, 0.05-0.5 A/min on currents.",
        unit: ParamUnit::ChannelUnitPerMinute,
        analog_only: true,
        signed: true,
        realistic: realistic_drift,
    },
];

/// Whether `c` is a measured channel read through an amplifier and an ADC (torques,
/// currents, voltages, throttle voltage), as opposed to a counted encoder speed. A
/// channel not listed here (e.g. one added to `MEASURED` later) is not analog, so the
/// analog effects do not accept it until it is classified.
pub fn is_analog(c: Channel) -> bool {
    matches!(
        c,
        Channel::Throttle
            | Channel::CKistlerL
            | Channel::CKistlerR
            | Channel::IXlml22
            | Channel::IXlmlBu1
            | Channel::IXlmr23
            | Channel::IDpu27
            | Channel::VDcBusbars
            | Channel::IDc
            | Channel::VDc
    )
}

fn realistic_lag(c: Channel) -> Option<(f64, f64)> {
    is_analog(c).then_some((0.001, 0.05))
}

fn realistic_skew(c: Channel) -> Option<(f64, f64)> {
    MEASURED.contains(&c).then_some((0.001, 0.1))
}

/// Realistic full scale of each analog channel's sensor / input range.
fn realistic_full_scale(c: Channel) -> Option<(f64, f64)> {
    match c {
        // 0-5 V signal on a +-10 V DAQ input, or a range just above 5 V.
        Channel::Throttle => Some((6.0, 10.0)),
        // Kistler KiTorq 4550A200: 200 N m rated; ~137 N m per flange is the motor limit.
        Channel::CKistlerL | Channel::CKistlerR => Some((150.0, 300.0)),
        // Tektronix A622, 100 A peak range; each clamp carries half a load motor's current.
        Channel::IXlml22 | Channel::IXlmlBu1 | Channel::IXlmr23 => Some((50.0, 100.0)),
        // Fluke i1010, 600 A range; supply current of a 24 V bench.
        Channel::IDpu27 => Some((150.0, 600.0)),
        // Danisense DS200ID, 200 A nominal.
        Channel::IDc => Some((150.0, 300.0)),
        // 24 V bus: differential probe on a +-30-60 V range.
        Channel::VDcBusbars => Some((30.0, 60.0)),
        // LEM DVL 50: 50 V nominal, 75 V maximum.
        Channel::VDc => Some((50.0, 75.0)),
        _ => None,
    }
}

/// 16-bit to 12-bit ADC over the realistic full-scale range (bipolar: 2 x full scale).
fn realistic_lsb(c: Channel) -> Option<(f64, f64)> {
    realistic_full_scale(c).map(|(lo, hi)| (2.0 * lo / 65536.0, 2.0 * hi / 4096.0))
}

fn realistic_pickup(c: Channel) -> Option<(f64, f64)> {
    match c {
        Channel::IXlml22 | Channel::IXlmlBu1 | Channel::IXlmr23 | Channel::IDpu27 | Channel::IDc => {
            Some((0.1, 2.0))
        }
        Channel::CKistlerL | Channel::CKistlerR => Some((0.02, 0.5)),
        Channel::VDcBusbars | Channel::VDc => Some((0.005, 0.1)),
        Channel::Throttle => Some((0.001, 0.02)),
        _ => None,
    }
}

fn realistic_drift(c: Channel) -> Option<(f64, f64)> {
    match c {
        Channel::CKistlerL | Channel::CKistlerR => Some((0.05, 0.5)),
        Channel::IXlml22 | Channel::IXlmlBu1 | Channel::IXlmr23 | Channel::IDpu27 | Channel::IDc => {
            Some((0.05, 0.5))
        }
        Channel::VDcBusbars | Channel::VDc => Some((0.005, 0.05)),
        Channel::Throttle => Some((0.0005, 0.005)),
        _ => None,
    }
}

/// The parameter name of channel `c` in effect files ([`Channel::key`], the twin's
/// measurement-chain vocabulary: `I_XLML 2.2` → `i_xlml_2_2`).
pub fn channel_key(c: Channel) -> String {
    c.key().to_owned()
}

/// The measured channel whose key is `key`.
pub fn channel_from_key(key: &str) -> Option<Channel> {
    Channel::from_key(key).filter(|c| MEASURED.contains(c))
}

fn effect_index(id: &str) -> Option<usize> {
    DAQ_EFFECTS.iter().position(|d| d.id == id)
}

/// The declaration of effect `id`.
pub fn decl(id: &str) -> Option<&'static DaqDecl> {
    DAQ_EFFECTS.iter().find(|d| d.id == id)
}

/// A rejected `(id, param, value)`; the message names what is accepted.
#[derive(Debug, Clone, PartialEq)]
pub enum DaqKeyError {
    /// No DAQ effect has this id.
    UnknownEffect { id: String },
    /// The effect has no parameter of this name (not a channel key, or a channel the
    /// effect does not apply to).
    UnknownParam { id: &'static str, param: String },
    /// Not finite, or negative where the sign means nothing.
    BadValue { id: &'static str, param: String, value: f64 },
}

impl fmt::Display for DaqKeyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DaqKeyError::UnknownEffect { id } => {
                let ids: Vec<&str> = DAQ_EFFECTS.iter().map(|d| d.id).collect();
                write!(f, "unknown DAQ effect `[{id}]`; the DAQ effects are: {}", ids.join(", "))
            }
            DaqKeyError::UnknownParam { id, param } => {
                let Some(d) = decl(id) else {
                    return write!(f, "unknown DAQ effect `[{id}]`");
                };
                let keys: Vec<String> = d.channels().into_iter().map(channel_key).collect();
                let which = if d.analog_only { "analog channel" } else { "measured channel" };
                match channel_from_key(param) {
                    Some(c) => write!(
                        f,
                        "[{id}] does not apply to `{param}` ({} is a counted encoder speed, not an \
                         analog channel); it accepts one parameter per {which}: {}",
                        c.name(),
                        keys.join(", ")
                    ),
                    None => write!(
                        f,
                        "[{id}] has no parameter `{param}`; it accepts one per {which} (the channel \
                         name lowercased, non-alphanumerics as `_`): {}",
                        keys.join(", ")
                    ),
                }
            }
            DaqKeyError::BadValue { id, param, value } => {
                let d = decl(id);
                let unit = match (d, channel_from_key(param)) {
                    (Some(d), Some(c)) => format!(" [{}]", d.unit.symbol(c)),
                    _ => String::new(),
                };
                if d.is_some_and(|d| d.signed) {
                    write!(
                        f,
                        "[{id}] {param} = {value}: must be a finite number{unit} (may be negative: \
                         the offset drifts down; 0 = off)"
                    )
                } else {
                    write!(f, "[{id}] {param} = {value}: must be a finite number >= 0{unit} (0 = off)")
                }
            }
        }
    }
}

impl std::error::Error for DaqKeyError {}

/// Values of all DAQ effects: per effect one f64 per `MEASURED` channel, 0 = off. Only
/// non-zero values are stored, so two sets of equal values compare equal.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DaqEffects {
    /// (index in `DAQ_EFFECTS`, index in `MEASURED`) → non-zero value.
    values: BTreeMap<(usize, usize), f64>,
}

impl DaqEffects {
    /// No effect on any channel.
    pub fn none() -> Self {
        Self::default()
    }

    /// Whether every parameter is 0 (the effects change nothing).
    pub fn is_none(&self) -> bool {
        self.values.is_empty()
    }

    /// Whether `id` names a DAQ effect.
    pub fn is_daq_effect(id: &str) -> bool {
        effect_index(id).is_some()
    }

    /// Set effect `id`'s parameter `param` (a channel key). 0 switches it off (for
    /// `sensor_clipping`, 0 means no clipping, not a full scale of 0).
    pub fn set(&mut self, id: &str, param: &str, value: f64) -> Result<(), DaqKeyError> {
        let e = effect_index(id).ok_or_else(|| DaqKeyError::UnknownEffect { id: id.to_owned() })?;
        let d = &DAQ_EFFECTS[e];
        let ci = MEASURED
            .iter()
            .position(|c| d.accepts(*c) && channel_key(*c) == param)
            .ok_or_else(|| DaqKeyError::UnknownParam { id: d.id, param: param.to_owned() })?;
        if !value.is_finite() || (!d.signed && value < 0.0) {
            return Err(DaqKeyError::BadValue { id: d.id, param: param.to_owned(), value });
        }
        if value == 0.0 {
            self.values.remove(&(e, ci));
        } else {
            self.values.insert((e, ci), value);
        }
        Ok(())
    }

    /// Effect `id`'s parameter `param` (0 when off); `None` if there is no such parameter.
    pub fn get(&self, id: &str, param: &str) -> Option<f64> {
        let e = effect_index(id)?;
        let d = &DAQ_EFFECTS[e];
        let ci = MEASURED.iter().position(|c| d.accepts(*c) && channel_key(*c) == param)?;
        Some(self.value(e, ci))
    }

    fn value(&self, e: usize, ci: usize) -> f64 {
        self.values.get(&(e, ci)).copied().unwrap_or(0.0)
    }

    /// (id, channel, value) of every non-zero parameter, effects in `DAQ_EFFECTS` order,
    /// channels in `MEASURED` order: for truth files and reports.
    pub fn entries(&self) -> Vec<(&'static str, Channel, f64)> {
        self.values
            .iter()
            .filter_map(|((e, ci), v)| Some((DAQ_EFFECTS.get(*e)?.id, *MEASURED.get(*ci)?, *v)))
            .collect()
    }

    /// Effects on the exact signal, before sensor noise: lag, drift, pickup, then skew
    /// (see the module doc). `rec` is modified in place; channels without an effect are
    /// not touched.
    pub fn apply_before_noise(&self, rec: &mut Recorded) {
        let dt = rec.dt_s;
        let dt_ok = dt.is_finite() && dt > 0.0;
        for ci in 0..MEASURED.len() {
            let (lag, skew) = (self.value(LAG, ci), self.value(SKEW, ci));
            let (pickup, drift) = (self.value(PICKUP, ci), self.value(DRIFT, ci));
            if lag == 0.0 && skew == 0.0 && pickup == 0.0 && drift == 0.0 {
                continue;
            }
            let Some(series) = rec.measured.get_mut(ci) else { continue };
            let mut x: Vec<f64> = series.iter().map(|v| f64::from(*v)).collect();
            if lag > 0.0 && dt_ok {
                first_order_lag(&mut x, dt, lag);
            }
            let skew = if dt_ok { skew } else { 0.0 };
            if skew > 0.0 {
                x = fractional_delay(&x, skew / dt);
            }
            if pickup != 0.0 || drift != 0.0 {
                for (k, v) in x.iter_mut().enumerate() {
                    // [µs] the time this sample was taken at.
                    let t_us = sample_time_us(&rec.t_us, k, dt) - skew * 1e6;
                    *v += drift_offset(drift, t_us) + mains(pickup, t_us);
                }
            }
            for (s, v) in series.iter_mut().zip(&x) {
                *s = to_f32(*v);
            }
        }
    }

    /// Effects of the converter on the recorded file values, after noise: clipping then
    /// quantisation, on the signal of each channel (matched by `Channel::name()`).
    /// Changed values are stored as [`file_value`]s of f32, like the rest of the file.
    pub fn apply_after_noise(&self, m: &mut Measurement) {
        for (ci, c) in MEASURED.iter().enumerate() {
            let (fs, lsb) = (self.value(CLIP, ci), self.value(QUANT, ci));
            if fs <= 0.0 && lsb <= 0.0 {
                continue;
            }
            for s in m.signals.iter_mut().filter(|s| s.name == c.name()) {
                for v in &mut s.values {
                    *v = file_value(to_f32(convert(*v, fs, lsb)));
                }
            }
        }
    }
}

/// [µs] time of sample `k`: `t_us[k]`, or `(k + 1) dt` past the end of `t_us`.
fn sample_time_us(t_us: &[u64], k: usize, dt: f64) -> f64 {
    match t_us.get(k) {
        Some(t) => *t as f64,
        None if dt.is_finite() => (k as f64 + 1.0) * dt * 1e6,
        None => 0.0,
    }
}

/// Offset [unit] of a drift of `rate` [unit/min] at `t_us`: 0 up to t = 0 (the run
/// starts there), linear after. Saturates instead of overflowing.
fn drift_offset(rate: f64, t_us: f64) -> f64 {
    if rate == 0.0 {
        return 0.0;
    }
    (rate * (t_us.max(0.0) * 1e-6 / 60.0)).clamp(-f64::MAX, f64::MAX)
}

/// Mains pickup of amplitude `amp` at `t_us`: `amp sin(2 pi 50 t)`, phase 0 at t = 0.
/// The phase is taken modulo the exact 20 ms period, so it stays exact on long runs.
fn mains(amp: f64, t_us: f64) -> f64 {
    if amp == 0.0 || !t_us.is_finite() {
        return 0.0;
    }
    let cycles = t_us.rem_euclid(MAINS_PERIOD_US) / MAINS_PERIOD_US;
    amp * (std::f64::consts::TAU * cycles).sin()
}

/// f64 → f32, saturating at ±`f32::MAX` instead of overflowing to infinity (NaN stays NaN).
fn to_f32(v: f64) -> f32 {
    if v.is_nan() {
        f32::NAN
    } else {
        v.clamp(-f64::from(f32::MAX), f64::from(f32::MAX)) as f32
    }
}

/// The converter: clamp to ±`fs` (if > 0), then round to a multiple of `lsb` (if > 0).
fn convert(v: f64, fs: f64, lsb: f64) -> f64 {
    let mut v = v;
    if fs > 0.0 {
        v = v.clamp(-fs, fs);
    }
    if lsb > 0.0 {
        let q = (v / lsb).round() * lsb;
        if q.is_finite() {
            v = q;
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use simrod_io::measure::Signal;
    use std::path::PathBuf;

    fn idx(c: Channel) -> usize {
        MEASURED.iter().position(|m| *m == c).unwrap()
    }

    /// A Recorded with every channel `f(k)` (plus the channel index, so they differ).
    fn recorded(n: usize, dt_us: u64, f: impl Fn(usize) -> f32) -> Recorded {
        Recorded {
            t_us: (1..=n as u64).map(|k| k * dt_us).collect(),
            dt_s: dt_us as f64 * 1e-6,
            measured: (0..MEASURED.len()).map(|i| (0..n).map(|k| f(k) + i as f32).collect()).collect(),
            setpoints: [vec![1.0; n], vec![2.0; n], vec![3.0; n]],
        }
    }

    fn measurement(n: usize, f: impl Fn(usize) -> f64) -> Measurement {
        Measurement {
            source: PathBuf::from("test"),
            time_s: (1..=n).map(|k| k as f64 * 1e-3).collect(),
            signals: MEASURED
                .iter()
                .map(|c| Signal {
                    name: c.name().to_owned(),
                    unit: c.unit().to_owned(),
                    values: (0..n).map(&f).collect(),
                })
                .collect(),
        }
    }

    fn bits(r: &Recorded) -> Vec<Vec<u32>> {
        r.measured.iter().map(|s| s.iter().map(|v| v.to_bits()).collect()).collect()
    }

    fn mbits(m: &Measurement) -> Vec<Vec<u64>> {
        m.signals.iter().map(|s| s.values.iter().map(|v| v.to_bits()).collect()).collect()
    }

    #[test]
    fn declarations_match_the_indices() {
        let ids: Vec<&str> = DAQ_EFFECTS.iter().map(|d| d.id).collect();
        assert_eq!(
            ids,
            [
                "amplifier_lag",
                "daq_skew",
                "adc_quantisation",
                "sensor_clipping",
                "mains_pickup",
                "offset_drift"
            ]
        );
        assert_eq!(DAQ_EFFECTS[LAG].id, "amplifier_lag");
        assert_eq!(DAQ_EFFECTS[SKEW].id, "daq_skew");
        assert_eq!(DAQ_EFFECTS[QUANT].id, "adc_quantisation");
        assert_eq!(DAQ_EFFECTS[CLIP].id, "sensor_clipping");
        assert_eq!(DAQ_EFFECTS[PICKUP].id, "mains_pickup");
        assert_eq!(DAQ_EFFECTS[DRIFT].id, "offset_drift");
        // Realistic ranges: given exactly for the accepted channels, positive and ordered.
        for d in DAQ_EFFECTS {
            for c in Channel::ALL {
                match (d.realistic)(*c) {
                    Some((lo, hi)) => {
                        assert!(d.accepts(*c), "{} {}", d.id, c.name());
                        assert!(lo > 0.0 && lo < hi && hi.is_finite(), "{} {}", d.id, c.name());
                    }
                    None => assert!(!d.accepts(*c), "{} {} has no range", d.id, c.name()),
                }
            }
        }
        // Ranges named in the brief.
        let (lo, hi) = (DAQ_EFFECTS[QUANT].realistic)(Channel::CKistlerL).unwrap();
        assert!(lo <= 400.0 / 65536.0 && hi >= 400.0 / 4096.0);
        assert_eq!((DAQ_EFFECTS[PICKUP].realistic)(Channel::IDc), Some((0.1, 2.0)));
        assert_eq!((DAQ_EFFECTS[LAG].realistic)(Channel::SiemensEnc), None);
        assert_eq!((DAQ_EFFECTS[SKEW].realistic)(Channel::SiemensEnc), Some((0.001, 0.1)));
    }

    #[test]
    fn channel_keys_are_unique_and_map_back() {
        assert_eq!(channel_key(Channel::CKistlerL), "c_kistler_l");
        assert_eq!(channel_key(Channel::IXlml22), "i_xlml_2_2");
        assert_eq!(channel_key(Channel::IXlmlBu1), "i_xlml_bu1");
        assert_eq!(channel_key(Channel::IDpu27), "i_dpu_2_7");
        assert_eq!(channel_key(Channel::VDcBusbars), "v_dc_busbars");
        assert_eq!(channel_key(Channel::SuTMotorEnc), "sutmotorenc");
        let mut keys: Vec<String> = MEASURED.iter().map(|c| channel_key(*c)).collect();
        for (c, k) in MEASURED.iter().zip(&keys) {
            assert_eq!(channel_from_key(k), Some(*c));
            assert!(k.chars().all(|ch| ch.is_ascii_lowercase() || ch.is_ascii_digit() || ch == '_'));
            assert!(!k.starts_with('_') && !k.ends_with('_') && !k.contains("__"));
        }
        keys.sort();
        keys.dedup();
        assert_eq!(keys.len(), MEASURED.len());
        // Unique among all channels too.
        let mut all: Vec<String> = Channel::ALL.iter().map(|c| channel_key(*c)).collect();
        all.sort();
        all.dedup();
        assert_eq!(all.len(), Channel::ALL.len());
    }

    #[test]
    fn analog_channels() {
        let analog: Vec<&str> = MEASURED.iter().filter(|c| is_analog(**c)).map(|c| c.name()).collect();
        assert_eq!(
            analog,
            [
                "Throttle",
                "C_Kistler_L",
                "C_Kistler_R",
                "I_XLML 2.2",
                "I_XLML BU1",
                "I_XLMR 2.3",
                "I_DPU 2.7",
                "V_DC_busbars",
                "I_DC",
                "V_DC"
            ]
        );
        assert_eq!(DAQ_EFFECTS[SKEW].channels().len(), MEASURED.len());
    }

    #[test]
    fn set_get_entries() {
        let mut e = DaqEffects::none();
        assert!(e.is_none());
        e.set("amplifier_lag", "c_kistler_l", 0.04).unwrap();
        e.set("mains_pickup", "i_dc", 0.8).unwrap();
        e.set("offset_drift", "i_dpu_2_7", -0.2).unwrap();
        e.set("daq_skew", "siemensenc", 0.01).unwrap();
        assert!(!e.is_none());
        assert_eq!(e.get("amplifier_lag", "c_kistler_l"), Some(0.04));
        assert_eq!(e.get("amplifier_lag", "c_kistler_r"), Some(0.0));
        assert_eq!(e.get("amplifier_lag", "t_kistler_l"), None);
        assert_eq!(e.get("nope", "c_kistler_l"), None);
        assert_eq!(
            e.entries(),
            vec![
                ("amplifier_lag", Channel::CKistlerL, 0.04),
                ("daq_skew", Channel::SiemensEnc, 0.01),
                ("mains_pickup", Channel::IDc, 0.8),
                ("offset_drift", Channel::IDpu27, -0.2),
            ]
        );
        // 0 switches off; all off equals none.
        for (id, c, _) in e.entries() {
            e.set(id, &channel_key(c), 0.0).unwrap();
        }
        assert!(e.is_none());
        assert_eq!(e, DaqEffects::default());
        assert!(DaqEffects::is_daq_effect("sensor_clipping"));
        assert!(!DaqEffects::is_daq_effect("coupling_damping"));
    }

    #[test]
    fn set_errors_name_the_vocabulary() {
        let mut e = DaqEffects::none();
        let msg = e.set("amplifier_lagg", "c_kistler_l", 0.01).unwrap_err().to_string();
        assert!(msg.contains("amplifier_lagg"), "{msg}");
        for d in DAQ_EFFECTS {
            assert!(msg.contains(d.id), "{msg}");
        }
        let msg = e.set("amplifier_lag", "C_Kistler_L", 0.01).unwrap_err().to_string();
        assert!(
            msg.contains("C_Kistler_L") && msg.contains("c_kistler_l") && msg.contains("i_xlml_2_2"),
            "{msg}"
        );
        assert!(!msg.contains("t_kistler_l"), "{msg}");
        let msg = e.set("adc_quantisation", "t_kistler_l", 0.01).unwrap_err().to_string();
        assert!(
            msg.contains("t_kistler_l") && msg.contains("encoder") && msg.contains("v_dc_busbars"),
            "{msg}"
        );
        // daq_skew accepts the encoder speeds.
        e.set("daq_skew", "t_kistler_l", 0.01).unwrap();
        let msg = e.set("daq_skew", "p_dpu", 0.01).unwrap_err().to_string();
        assert!(msg.contains("p_dpu") && msg.contains("sutmotorenc"), "{msg}");
        // Values.
        for id in ["amplifier_lag", "daq_skew", "adc_quantisation", "sensor_clipping", "mains_pickup"] {
            let msg = e.set(id, "i_dc", -1.0).unwrap_err().to_string();
            assert!(msg.contains(id) && msg.contains(">= 0") && msg.contains("i_dc"), "{msg}");
        }
        let msg = e.set("amplifier_lag", "i_dc", -1.0).unwrap_err().to_string();
        assert!(msg.contains("[s]"), "{msg}");
        let msg = e.set("offset_drift", "c_kistler_l", f64::NAN).unwrap_err().to_string();
        assert!(msg.contains("negative") && msg.contains("N m/min"), "{msg}");
        assert!(e.set("mains_pickup", "i_dc", f64::INFINITY).is_err());
        e.set("offset_drift", "c_kistler_l", -0.3).unwrap();
        // Rejected sets change nothing.
        assert_eq!(e.entries().len(), 2);
    }

    #[test]
    fn none_leaves_everything_bit_identical() {
        let mut r = recorded(500, 1000, |k| (k as f32 * 0.37).sin() * 100.0);
        r.measured[3][7] = f32::NAN;
        let before = bits(&r);
        let e = DaqEffects::none();
        e.apply_before_noise(&mut r);
        assert_eq!(bits(&r), before);
        let mut m = measurement(500, |k| file_value((k as f32 * 0.11).cos() * 70.0));
        let mb = mbits(&m);
        e.apply_after_noise(&mut m);
        assert_eq!(mbits(&m), mb);
        // An effect on one channel leaves the others (and the set points) untouched.
        let mut e = DaqEffects::none();
        for d in DAQ_EFFECTS {
            e.set(d.id, "i_dc", 0.5).unwrap();
        }
        let sp = r.setpoints.clone();
        e.apply_before_noise(&mut r);
        e.apply_after_noise(&mut m);
        let (ai, bi) = (bits(&r), mbits(&m));
        for i in 0..MEASURED.len() {
            if i == idx(Channel::IDc) {
                assert_ne!(ai[i], before[i]);
                assert_ne!(bi[i], mb[i]);
            } else {
                assert_eq!(ai[i], before[i]);
                assert_eq!(bi[i], mb[i]);
            }
        }
        assert_eq!(r.setpoints, sp);
    }

    #[test]
    fn lag_of_a_ramp_is_tau_in_steady_state() {
        for (dt, tau) in [(1e-3, 0.02), (1e-3, 0.0005), (1e-5, 0.001), (1e-3, 1e-7)] {
            let n = 2000;
            let mut x: Vec<f64> = (0..n).map(|k| 3.0 * k as f64 * dt).collect();
            first_order_lag(&mut x, dt, tau);
            for (k, y) in x.iter().enumerate() {
                let t = k as f64 * dt;
                let exact = 3.0 * (t - tau + tau * (-t / tau).exp());
                assert!((y - exact).abs() < 1e-9, "dt {dt} tau {tau} k {k}: {y} vs {exact}");
            }
            let t = (n - 1) as f64 * dt;
            if t > 30.0 * tau {
                assert!((x[n - 1] - 3.0 * (t - tau)).abs() < 1e-9);
            }
        }
        // Through the Recorded API (f32): C_Kistler_L follows a ramp 40 ms late.
        let mut r = recorded(3000, 1000, |k| k as f32 * 0.01);
        let mut e = DaqEffects::none();
        e.set("amplifier_lag", "c_kistler_l", 0.04).unwrap();
        let exact = r.clone();
        e.apply_before_noise(&mut r);
        let i = idx(Channel::CKistlerL);
        let lagged = &r.measured[i];
        // In steady state the ramp is 40 ms = 40 samples late.
        for (y, x) in lagged.iter().zip(&exact.measured[i]).skip(1000) {
            assert!((f64::from(*y) - (f64::from(*x) - 0.4)).abs() < 1e-4, "{y} {x}");
        }
        assert_eq!(lagged[0], exact.measured[i][0]);
    }

    #[test]
    fn skew_whole_and_half_samples() {
        let r0 = recorded(200, 1000, |k| ((k * k) % 97) as f32 * 0.5);
        let i = idx(Channel::TKistlerR);
        let mut e = DaqEffects::none();
        e.set("daq_skew", "t_kistler_r", 0.003).unwrap();
        let mut r = r0.clone();
        e.apply_before_noise(&mut r);
        let x = &r0.measured[i];
        for k in 0..200 {
            let want = if k < 3 { x[0] } else { x[k - 3] };
            assert_eq!(r.measured[i][k].to_bits(), want.to_bits(), "k {k}");
        }
        // Half a sample: the mean of the neighbours.
        let mut e = DaqEffects::none();
        e.set("daq_skew", "t_kistler_r", 0.0005).unwrap();
        let mut r = r0.clone();
        e.apply_before_noise(&mut r);
        assert_eq!(r.measured[i][0], x[0]);
        for k in 1..200 {
            let want = 0.5 * (f64::from(x[k - 1]) + f64::from(x[k]));
            assert!((f64::from(r.measured[i][k]) - want).abs() <= 1e-5 * want.abs().max(1.0), "k {k}");
        }
        // A skew longer than the run: everything at the initial value.
        let mut e = DaqEffects::none();
        e.set("daq_skew", "t_kistler_r", 1.0).unwrap();
        let mut r = r0.clone();
        e.apply_before_noise(&mut r);
        assert!(r.measured[i].iter().all(|v| *v == x[0]));
    }

    #[test]
    fn quantisation_and_clipping() {
        let lsb = 0.05;
        let mut m = measurement(2000, |k| file_value(((k as f32) * 0.0123).sin() * 250.0));
        let orig = m.clone();
        let mut e = DaqEffects::none();
        e.set("adc_quantisation", "c_kistler_l", lsb).unwrap();
        e.set("sensor_clipping", "c_kistler_r", 200.0).unwrap();
        e.set("sensor_clipping", "i_dc", 180.0).unwrap();
        e.set("adc_quantisation", "i_dc", 0.1).unwrap();
        e.apply_after_noise(&mut m);
        let sig = |m: &Measurement, c: Channel| m.signals[idx(c)].values.clone();
        let (q, x) = (sig(&m, Channel::CKistlerL), sig(&orig, Channel::CKistlerL));
        for (q, x) in q.iter().zip(&x) {
            let n = q / lsb;
            assert!((n - n.round()).abs() < 1e-4, "{q} not a multiple of {lsb}");
            assert!((q - x).abs() <= lsb / 2.0 + 1e-5, "{q} vs {x}");
            assert_eq!(*q, file_value(*q as f32));
        }
        let (c, x) = (sig(&m, Channel::CKistlerR), sig(&orig, Channel::CKistlerR));
        assert!(x.iter().any(|v| v.abs() > 200.0));
        for (c, x) in c.iter().zip(&x) {
            assert!(c.abs() <= 200.0);
            if x.abs() <= 200.0 {
                assert_eq!(c, x);
            } else {
                assert_eq!(c.abs(), 200.0);
                assert_eq!(c.signum(), x.signum());
            }
        }
        // Clipping then quantisation: within ±180 and on the 0.1 grid.
        let d = sig(&m, Channel::IDc);
        assert!(d.iter().all(|v| v.abs() <= 180.0 + 1e-4 && ((v / 0.1) - (v / 0.1).round()).abs() < 1e-4));
        assert!(d.iter().any(|v| (v.abs() - 180.0).abs() < 1e-4));
        // A signal not in the file is simply not there: no panic.
        let mut empty = Measurement { source: PathBuf::new(), time_s: vec![], signals: vec![] };
        e.apply_after_noise(&mut empty);
    }

    #[test]
    fn mains_pickup_frequency_and_amplitude() {
        // 10 µs steps over 1 s, constant channel value 0 (Throttle is channel 0).
        let n = 100_000;
        let mut r = recorded(n, 10, |_| 0.0);
        let i = idx(Channel::IDc);
        let base = r.measured[i][0];
        let mut e = DaqEffects::none();
        e.set("mains_pickup", "i_dc", 0.8).unwrap();
        e.apply_before_noise(&mut r);
        let p: Vec<f64> = r.measured[i].iter().map(|v| f64::from(*v) - f64::from(base)).collect();
        let max = p.iter().copied().fold(f64::MIN, f64::max);
        let min = p.iter().copied().fold(f64::MAX, f64::min);
        assert!((max - 0.8).abs() < 1e-5 && (min + 0.8).abs() < 1e-5, "{min} {max}");
        // Zero crossings every 10 ms: at t = 10 ms * j, j = 1..=100 (the last at 1 s).
        let mut crossings = vec![];
        for k in 1..n {
            if (p[k - 1] < 0.0) != (p[k] < 0.0) {
                crossings.push(r.t_us[k]);
            }
        }
        assert_eq!(crossings.len(), 100, "{crossings:?}");
        for (j, t) in crossings.iter().enumerate() {
            assert!(t.abs_diff(10_000 * (j as u64 + 1)) <= 10, "{j}: {t}");
        }
        // Phase 0 at t = 0: rising first, peak at 5 ms.
        assert!((p[499] - 0.8).abs() < 1e-6, "{}", p[499]);
    }

    #[test]
    fn offset_drift_per_minute() {
        let mut r = recorded(1201, 100_000, |_| 10.0); // 0.1 s steps, to 120.1 s
        let i = idx(Channel::CKistlerL);
        let base = f64::from(r.measured[i][0]);
        let mut e = DaqEffects::none();
        e.set("offset_drift", "c_kistler_l", -0.3).unwrap();
        e.apply_before_noise(&mut r);
        let at = |t_us: u64| {
            let k = r.t_us.iter().position(|t| *t == t_us).unwrap();
            f64::from(r.measured[i][k]) - base
        };
        assert!((at(60_000_000) + 0.3).abs() < 1e-5, "{}", at(60_000_000));
        assert!((at(120_000_000) + 0.6).abs() < 1e-5);
        assert!((at(30_000_000) + 0.15).abs() < 1e-5);
    }

    #[test]
    fn skew_moves_drift_and_pickup_in_time() {
        let mut r = recorded(100, 1000, |_| 0.0);
        let i = idx(Channel::IXlmr23);
        let base = r.measured[i][0];
        let mut e = DaqEffects::none();
        e.set("mains_pickup", "i_xlmr_2_3", 1.0).unwrap();
        e.set("daq_skew", "i_xlmr_2_3", 0.005).unwrap(); // a quarter mains period
        e.apply_before_noise(&mut r);
        for (k, v) in r.measured[i].iter().enumerate() {
            let t = r.t_us[k] as f64 * 1e-6 - 0.005;
            let want = -(std::f64::consts::TAU * 50.0 * (t + 0.005)).cos();
            assert!((f64::from(*v - base) - want).abs() < 1e-5, "k {k}");
        }
    }

    #[test]
    fn degenerate_inputs_do_not_panic_and_stay_finite() {
        let mut e = DaqEffects::none();
        for d in DAQ_EFFECTS {
            for c in d.channels() {
                let v = if d.id == "offset_drift" { -f64::MAX } else { f64::MAX };
                e.set(d.id, &channel_key(c), v).unwrap();
            }
        }
        // Empty.
        let mut r = Recorded { t_us: vec![], dt_s: 0.0, measured: vec![], setpoints: Default::default() };
        e.apply_before_noise(&mut r);
        let mut r = recorded(0, 1000, |_| 0.0);
        e.apply_before_noise(&mut r);
        // Zero, negative, NaN dt; t_us shorter than the series.
        for dt in [0.0, -1e-3, f64::NAN, f64::INFINITY, 1e-3] {
            let mut r = recorded(50, 1000, |k| k as f32 * 1e30);
            r.dt_s = dt;
            r.t_us.truncate(10);
            e.apply_before_noise(&mut r);
            assert!(r.measured.iter().flatten().all(|v| v.is_finite()), "dt {dt}");
        }
        // Tiny parameters.
        let mut e2 = DaqEffects::none();
        for d in DAQ_EFFECTS {
            for c in d.channels() {
                e2.set(d.id, &channel_key(c), 1e-300).unwrap();
            }
        }
        let mut r = recorded(50, 1000, |k| k as f32 * (3.0e38 / 50.0));
        e2.apply_before_noise(&mut r);
        assert!(r.measured.iter().flatten().all(|v| v.is_finite()));
        let mut m = measurement(50, |k| k as f64 * 1e300);
        e2.apply_after_noise(&mut m);
        e.apply_after_noise(&mut m);
        assert!(m.signals.iter().flat_map(|s| &s.values).all(|v| v.is_finite()));
    }
}
