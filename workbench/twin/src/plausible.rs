//! Garbage is not a measurement: before the twin runs on a file, every measured value
//! must be within [`IMPLAUSIBLE_SPANS`] times its channel's operating span (a corrupt
//! sample such as 1e308, or a unit mistake such as kN m read as N m, is far beyond) and
//! every set point within ±100 %; a channel that never moves is reported as dead.

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
        let set_point = [SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R].contains(&s.name.as_str());
        let limit =
            if set_point { Some(100.0) } else { operating_span(&s.name).map(|sp| IMPLAUSIBLE_SPANS * sp) };
        let Some(limit) = limit else { continue };
        if let Some(k) = s.values.iter().position(|v| v.abs() > limit * (1.0 + 1e-9)) {
            let why = if set_point {
                "set points are within ±100 %".to_string()
            } else {
                format!(
                    "{IMPLAUSIBLE_SPANS} times its operating span of {} {} (workbench/data/channel_spans.toml): \
                     a corrupt sample or a unit mistake (check the file's unit, or its --mapping)",
                    limit / IMPLAUSIBLE_SPANS,
                    s.unit
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
        if !set_point && s.values.len() > 1 && s.values.iter().all(|v| *v == s.values[0]) {
            notes.push(format!(
                "{} is constant ({} {}) over the whole run: a dead channel? its errors say nothing",
                s.name, s.values[0], s.unit
            ));
        }
    }
    Ok(notes)
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
}
