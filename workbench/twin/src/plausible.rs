//! Garbage is not a measurement: before the twin runs on a file, every measured value
//! must be within [`IMPLAUSIBLE_SPANS`] times its channel's operating span (a corrupt
//! sample such as 1e308, or a unit mistake such as kN m read as N m, is far beyond) and
//! every set point within ±100 %; a channel that never moves is reported as dead, and
//! one that stays below a hundredth of its span is reported with the unit it may really
//! be in. `compare --mask-implausible` masks such samples instead ([`mask`]).

use simrod_io::measure::{Measurement, SETPOINT_LOAD_L, SETPOINT_LOAD_R, SETPOINT_THROTTLE};

use crate::measured::TwinError;
use crate::spans::operating_span;

/// How many operating spans from zero a value may be and still be a measurement.
pub const IMPLAUSIBLE_SPANS: f64 = 100.0;

/// Check `meas`; the notes are for the report (dead channels), the error names the
/// channel, time and value that cannot be a measurement.
pub fn check(meas: &Measurement) -> Result<Vec<String>, TwinError> {
    let mut notes = Vec::new();
    let at = |k: usize| meas.time_s.get(k).copied().unwrap_or(f64::NAN);
    for s in &meas.signals {
        let set_point = is_set_point(&s.name);
        let Some(limit) = limit_of(&s.name) else { continue };
        if let Some(k) = s.values.iter().position(|v| beyond(*v, limit)) {
            let why = if set_point {
                "set points are within ±100 %".to_string()
            } else {
                let span = limit / IMPLAUSIBLE_SPANS;
                format!(
                    "{IMPLAUSIBLE_SPANS} times its operating span of {span} {} (workbench/data/channel_spans.toml): \
                     a corrupt sample (`compare --mask-implausible` leaves such samples out) or a unit mistake{} \
                     (check the file's unit, or its --mapping)",
                    s.unit,
                    unit_hint(s.values[k].abs() / span, &s.unit)
                )
            };
            return Err(TwinError::Implausible(format!(
                "{} at t = {} s is {} {}, beyond ±{limit} {}: {why}",
                s.name,
                at(k),
                readable(s.values[k]),
                s.unit,
                s.unit
            )));
        }
        if set_point {
            continue;
        }
        let peak = s.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let span = limit / IMPLAUSIBLE_SPANS;
        if s.values.len() > 1 && s.values.iter().all(|v| *v == s.values[0]) {
            notes.push(format!(
                "{} is constant ({} {}) over the whole run: a dead channel? its errors say nothing",
                s.name, s.values[0], s.unit
            ));
        } else if peak < span / IMPLAUSIBLE_SPANS {
            notes.push(format!(
                "{} never exceeds {} {}, under a hundredth of its operating span of {span} {}: \
                 an idle channel, or a unit mistake{}",
                s.name,
                readable(peak),
                s.unit,
                s.unit,
                unit_hint(peak / span, &s.unit)
            ));
        }
    }
    Ok(notes)
}

/// Replace every sample that [`check`] would refuse in a measured channel by NaN (left
/// out of every figure, as gaps are) and say how many, per channel. Set points cannot
/// be masked: the twin runs on them.
pub fn mask(meas: &mut Measurement) -> Vec<String> {
    let mut notes = Vec::new();
    for s in &mut meas.signals {
        let Some(limit) = limit_of(&s.name).filter(|_| !is_set_point(&s.name)) else { continue };
        let mut count = 0usize;
        let mut first = None;
        for (k, v) in s.values.iter_mut().enumerate() {
            if beyond(*v, limit) {
                count += 1;
                first.get_or_insert((k, *v));
                *v = f64::NAN;
            }
        }
        if let Some((k, v)) = first {
            let t = meas.time_s.get(k).copied().unwrap_or(f64::NAN);
            notes.push(format!(
                "{}: {count} sample(s) beyond ±{limit} {} masked (--mask-implausible), the first {} {} at t = {t} s",
                s.name,
                s.unit,
                readable(v),
                s.unit
            ));
        }
    }
    notes
}

fn is_set_point(name: &str) -> bool {
    [SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R].contains(&name)
}

/// The largest magnitude channel `name` may have: ±100 % for set points,
/// [`IMPLAUSIBLE_SPANS`] operating spans for measured channels.
fn limit_of(name: &str) -> Option<f64> {
    if is_set_point(name) {
        Some(100.0)
    } else {
        operating_span(name).map(|sp| IMPLAUSIBLE_SPANS * sp)
    }
}

fn beyond(v: f64, limit: f64) -> bool {
    v.abs() > limit * (1.0 + 1e-9)
}

/// For a magnitude `ratio` times the expected one: the unit mix-up a whole power of
/// 1000 would be, as a hint; empty otherwise.
fn unit_hint(ratio: f64, unit: &str) -> String {
    if !(ratio.is_finite() && ratio > 0.0) {
        return String::new();
    }
    let thousands = (ratio.log10() / 3.0).round() as i32;
    let (big, small) = match thousands.abs() {
        1 => ("k", "m"),
        2 => ("M", "µ"),
        _ => return String::new(),
    };
    let factor = 3 * thousands.abs();
    if thousands > 0 {
        format!(" (10^{factor} times too large: values in {small}{unit} labelled {unit}, or {unit} values labelled {big}{unit}?)")
    } else {
        format!(" (10^{factor} times too small: values in {big}{unit} labelled {unit}, or {unit} values labelled {small}{unit}?)")
    }
}

/// A value as a person reads it: plain for everyday magnitudes, in exponent form beyond.
fn readable(v: f64) -> String {
    if v != 0.0 && !(1e-3..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use simrod_io::measure::Signal;

    fn meas(name: &str, unit: &str, values: Vec<f64>) -> Measurement {
        Measurement {
            source: "m.csv".into(),
            time_s: (0..values.len()).map(|k| k as f64 * 1e-3).collect(),
            signals: vec![Signal { name: name.into(), unit: unit.into(), values }],
        }
    }

    #[test]
    fn corrupt_samples_unit_mistakes_set_points_and_dead_channels() {
        let e = check(&meas("C_Kistler_L", "N m", vec![1.0, 1e308, 2.0])).unwrap_err().to_string();
        assert!(e.contains("C_Kistler_L at t = 0.001 s is 1e308 N m") && e.contains("unit mistake"), "{e}");
        // 30 N m read as kN m and converted: 30000 N m, beyond 100 x 276 N m.
        assert!(check(&meas("C_Kistler_R", "N m", vec![30.0e3, 10.0])).is_err());
        let e = check(&meas(SETPOINT_THROTTLE, "%", vec![10.0, 1e6])).unwrap_err().to_string();
        assert!(e.contains("set points are within ±100 %"), "{e}");
        let notes = check(&meas("C_Kistler_L", "N m", vec![-0.0, -0.0, 0.0])).unwrap();
        assert!(notes[0].contains("dead channel"), "{notes:?}");
        assert!(check(&meas("C_Kistler_L", "N m", vec![-120.0, 130.0])).unwrap().is_empty());
    }

    #[test]
    fn the_likely_unit_mistake_is_named() {
        // 35 N m written in kN m and read as N m would be 35000: refused, naming kN m.
        let e = check(&meas("C_Kistler_L", "N m", vec![1.0, 35.0e3])).unwrap_err().to_string();
        assert!(e.contains("10^3 times too large") && e.contains("N m values labelled kN m?"), "{e}");
        // The other way: N m values in a column labelled kN m and converted: 1000 x small.
        let notes = check(&meas("C_Kistler_L", "N m", vec![0.03, -0.02, 0.01])).unwrap();
        assert!(notes[0].contains("under a hundredth of its operating span"), "{notes:?}");
        assert!(notes[0].contains("10^3 times too small: values in kN m labelled N m"), "{notes:?}");
        assert_eq!(unit_hint(7.0, "N m"), "");
    }

    #[test]
    fn masking_leaves_implausible_samples_out_and_counts_them() {
        let mut m = meas("C_Kistler_L", "N m", vec![1.0, 1e308, 2.0, -1e30]);
        let notes = mask(&mut m);
        assert!(notes[0].contains("C_Kistler_L: 2 sample(s) beyond"), "{notes:?}");
        assert!(notes[0].contains("the first 1e308 N m at t = 0.001 s"), "{notes:?}");
        let v = &m.signals[0].values;
        assert_eq!((v[0], v[2]), (1.0, 2.0));
        assert!(v[1].is_nan() && v[3].is_nan());
        assert!(check(&m).is_ok());
        // Set points are never masked.
        let mut sp = meas(SETPOINT_THROTTLE, "%", vec![10.0, 1e6]);
        assert!(mask(&mut sp).is_empty() && check(&sp).is_err());
    }
}
