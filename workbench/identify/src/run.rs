//! One measured run of a campaign, with the derived channels the identifications use
//! (thesis tables 5.2, 5.6, 5.13) computed once, sample by sample, from the measured ones.
//!
//! Derived channels are products and differences of measured ones; their plateau means
//! are computed from the per-sample products (an unbiased estimate: the probes' noises
//! are independent), not as products of means.

use std::path::Path;

use simrod_io::error::{CmdError, FileError};
use simrod_io::measure::{
    self, Mapping, Measurement, Signal, SETPOINT_LOAD_L, SETPOINT_LOAD_R, SETPOINT_THROTTLE,
};

/// Connector voltage drop `V_DC_busbars − V_DC` [V] (thesis eq. 5.5).
pub const DV_CONN: &str = "V_DC_busbars - V_DC";
/// The set-point channels, in the order throttle, load L, load R.
pub const SETPOINTS: [&str; 3] = [SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R];

/// Derived channels: name, unit, measured channels it is computed from.
const DERIVED: [(&str, &str, &[&str]); 4] = [
    ("P_SuT_inv", "W", &["V_DC", "I_DC"]),
    ("P_LML", "W", &["I_XLML 2.2", "I_XLML BU1", "V_DC_busbars"]),
    ("P_LMR", "W", &["I_XLMR 2.3", "V_DC_busbars"]),
    (DV_CONN, "V", &["V_DC_busbars", "V_DC"]),
];

/// The measured channels a channel rests on (itself when measured): where to look for
/// clipping and miscounting.
pub fn sources(name: &str) -> Vec<&str> {
    DERIVED.iter().find(|d| d.0 == name).map_or_else(|| vec![name], |d| d.2.to_vec())
}

/// A loaded run.
#[derive(Debug, Clone)]
pub struct Run {
    /// Short name for reports (the file name).
    pub name: String,
    pub meas: Measurement,
    /// [s] sample interval.
    pub dt_s: f64,
}

impl Run {
    /// Check a measurement and add the derived channels.
    pub fn new(name: impl Into<String>, mut meas: Measurement) -> Result<Self, FileError> {
        let n = meas.time_s.len();
        let (Some(&t0), Some(&t1)) = (meas.time_s.first(), meas.time_s.last()) else {
            return Err(FileError::whole(&meas.source, "no samples"));
        };
        if n < 2 || t0.is_nan() || t1.is_nan() || t1 <= t0 {
            return Err(FileError::whole(
                &meas.source,
                "fewer than 2 samples or a time axis that does not increase",
            ));
        }
        let missing: Vec<&str> = SETPOINTS.iter().copied().filter(|s| meas.signal(s).is_none()).collect();
        if !missing.is_empty() {
            return Err(FileError::whole(
                &meas.source,
                format!(
                    "no set-point channel(s) {}: identification needs the set points the PLC logged (rename them with --mapping)",
                    missing.join(", ")
                ),
            ));
        }
        for s in &meas.signals {
            if s.values.len() != n {
                return Err(FileError::whole(
                    &meas.source,
                    format!("channel \"{}\" has {} values for {n} time samples", s.name, s.values.len()),
                ));
            }
        }
        for (name, unit, from) in DERIVED {
            if meas.signal(name).is_some() {
                continue;
            }
            let cols: Option<Vec<&[f64]>> =
                from.iter().map(|c| meas.signal(c).map(|s| s.values.as_slice())).collect();
            let Some(cols) = cols else { continue };
            let values: Vec<f64> = (0..n)
                .map(|k| {
                    let v = |i: usize| cols.get(i).and_then(|c| c.get(k)).copied().unwrap_or(f64::NAN);
                    match name {
                        "P_SuT_inv" => v(0) * v(1),
                        "P_LML" => (v(0) + v(1)) * v(2),
                        "P_LMR" => 2.0 * v(0) * v(1),
                        _ => v(0) - v(1),
                    }
                })
                .collect();
            meas.signals.push(Signal { name: name.to_string(), unit: unit.to_string(), values });
        }
        Ok(Self { name: name.into(), dt_s: (t1 - t0) / (n - 1) as f64, meas })
    }

    /// Load a run file (CSV or MAT), with an optional channel mapping.
    pub fn load(path: &Path, mapping: Option<&Mapping>) -> Result<Self, CmdError> {
        let opts = measure::LoadOptions { mapping: mapping.cloned(), ..measure::LoadOptions::default() };
        let loaded = measure::load_with(path, &opts)?;
        let name =
            path.file_name().map_or_else(|| path.display().to_string(), |f| f.to_string_lossy().into_owned());
        Ok(Self::new(name, loaded.measurement)?)
    }

    /// A channel's values (measured or derived).
    pub fn signal(&self, name: &str) -> Option<&[f64]> {
        self.meas.signal(name).map(|s| s.values.as_slice())
    }

    /// The unit of a channel ("" if unknown).
    pub fn unit(&self, name: &str) -> &str {
        self.meas.signal(name).map_or("", |s| s.unit.as_str())
    }

    /// Set points [%]: throttle, load L, load R.
    pub fn setpoints(&self) -> [&[f64]; 3] {
        SETPOINTS.map(|s| self.signal(s).unwrap_or(&[]))
    }

    /// Sample times [s].
    pub fn time(&self) -> &[f64] {
        &self.meas.time_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn meas(names: &[&str]) -> Measurement {
        Measurement {
            source: PathBuf::from("r.csv"),
            time_s: vec![0.001, 0.002, 0.003],
            signals: names
                .iter()
                .map(|n| Signal { name: (*n).into(), unit: "x".into(), values: vec![1.0, 2.0, 3.0] })
                .collect(),
        }
    }

    #[test]
    fn identify_run_derives_powers_and_needs_set_points() {
        let mut all: Vec<&str> = SETPOINTS.to_vec();
        all.extend(["V_DC", "I_DC", "V_DC_busbars", "I_XLMR 2.3"]);
        let r = Run::new("r", meas(&all)).unwrap();
        assert_eq!(r.signal("P_SuT_inv"), Some(&[1.0, 4.0, 9.0][..]));
        assert_eq!(r.signal("P_LMR"), Some(&[2.0, 8.0, 18.0][..]));
        assert_eq!(r.signal(DV_CONN), Some(&[0.0, 0.0, 0.0][..]));
        assert!(r.signal("P_LML").is_none(), "I_XLML 2.2 is missing");
        assert!((r.dt_s - 0.001).abs() < 1e-12);
        let e = Run::new("r", meas(&["V_DC"])).unwrap_err().to_string();
        assert!(e.starts_with("r.csv: no set-point channel(s) SuT Throttle, Dm Left, Dm Right"), "{e}");
        assert_eq!(sources("P_LML"), vec!["I_XLML 2.2", "I_XLML BU1", "V_DC_busbars"]);
        assert_eq!(sources("C_Kistler_L"), vec!["C_Kistler_L"]);
    }
}
