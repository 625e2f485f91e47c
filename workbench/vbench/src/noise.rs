//! The measurement-chain parameters (`--noise default|none|FILE.toml`). Every number,
//! its origin and the file format are in `workbench/examples/noise.toml`, whose values
//! are these defaults (a test keeps the two equal).
//!
//! Gaussian noise of a channel has standard deviation `sigma + g * at_limit`, where
//! `g` in [0, 1] says how close the bench is to its operating limits at that sample:
//! `g = max(ramp(max |C_Kistler_L|, |C_Kistler_R|), ramp(|SuTMotorEnc|))` with each ramp
//! 0 below the first value of its `[limits]` pair, 1 above the second, linear between.
//! The thesis reports noise "very high" at the limits (6.1, fig. 6.4, 6.6, 6.7) without
//! numbers; table 5.7's friction fits have an RMSE of 1.8–2.2 N m including model error.

use std::path::Path;

use model_core::Channel;
use serde::Deserialize;

use simrod_io::error::FileError;
use simrod_io::toml_util::toml_error;

/// Gaussian noise of one sensor.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gauss {
    /// Standard deviation away from the limits, in the channel's unit.
    pub sigma: f64,
    /// Added to `sigma` at the operating limits (`g = 1`).
    #[serde(default)]
    pub at_limit: f64,
}

impl Gauss {
    const fn new(sigma: f64, at_limit: f64) -> Self {
        Self { sigma, at_limit }
    }

    /// Standard deviation at limit factor `g`.
    pub fn sigma_at(&self, g: f64) -> f64 {
        self.sigma + g * self.at_limit
    }
}

/// Where the operating limits start and are fully reached.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Limits {
    /// [N m] |flange torque|.
    pub torque_nm: [f64; 2],
    /// [rpm] |SuT motor speed|.
    pub motor_rpm: [f64; 2],
}

impl Default for Limits {
    fn default() -> Self {
        Self { torque_nm: [60.0, 130.0], motor_rpm: [1800.0, 2100.0] }
    }
}

fn ramp(x: f64, [a, b]: [f64; 2]) -> f64 {
    ((x - a) / (b - a)).clamp(0.0, 1.0)
}

impl Limits {
    /// The limit factor `g` for one sample.
    pub fn factor(&self, torque_l: f64, torque_r: f64, motor_rpm: f64) -> f64 {
        let t = torque_l.abs().max(torque_r.abs());
        ramp(t, self.torque_nm).max(ramp(motor_rpm.abs(), self.motor_rpm))
    }
}

/// Pulse encoders and their counting window.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Encoders {
    /// [s] speed = pulses counted in a window centred on the sample / window.
    pub window_s: f64,
    /// Kistler flanges (T_Kistler_L/R).
    pub kistler_ppr: u32,
    /// SuT motor encoder (SuTMotorEnc).
    pub sut_motor_ppr: u32,
    /// Siemens encoder behind the R coupling (SiemensEnc).
    pub siemens_ppr: u32,
    /// [s] clock of the pulse timestamps (`simrod bench --pulses` only).
    pub timer_s: f64,
    /// [deg] standard deviation of where an edge sits on the shaft (disc pitch error and
    /// trigger jitter, independent per edge; `--pulses` only).
    pub edge_jitter_deg: f64,
}

impl Default for Encoders {
    fn default() -> Self {
        Self {
            window_s: 0.1,
            kistler_ppr: 60,
            sut_motor_ppr: 64,
            siemens_ppr: 128,
            timer_s: 1e-6,
            edge_jitter_deg: 0.02,
        }
    }
}

/// `--miscount`: the Siemens encoder loses pulses at speed.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Miscount {
    /// [rpm] no pulse is lost below this |speed|.
    pub threshold_rpm: f64,
    /// [rpm] from this |speed| on, `max_drop` of the pulses are lost.
    pub full_rpm: f64,
    /// Fraction of pulses lost at `full_rpm` and above.
    pub max_drop: f64,
}

impl Default for Miscount {
    fn default() -> Self {
        Self { threshold_rpm: 100.0, full_rpm: 190.0, max_drop: 0.2 }
    }
}

impl Miscount {
    /// Probability that a pulse at `rpm` is lost.
    pub fn drop_probability(&self, rpm: f64) -> f64 {
        self.max_drop * ramp(rpm.abs(), [self.threshold_rpm, self.full_rpm])
    }
}

/// Current probes.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Currents {
    /// I_XLML 2.2 and I_XLML BU1 (each its own probe).
    pub xlml: Gauss,
    /// I_XLMR 2.3.
    pub xlmr: Gauss,
    /// I_DPU 2.7.
    pub dpu: Gauss,
    /// I_DC.
    pub dc: Gauss,
}

impl Default for Currents {
    fn default() -> Self {
        Self {
            xlml: Gauss::new(0.5, 1.0),
            xlmr: Gauss::new(0.5, 1.0),
            dpu: Gauss::new(1.0, 2.0),
            dc: Gauss::new(0.1, 0.5),
        }
    }
}

/// Voltage probes.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Voltages {
    /// V_DC_busbars.
    pub busbars: Gauss,
    /// V_DC.
    pub dc: Gauss,
    /// Throttle (the controller's throttle input).
    pub throttle: Gauss,
}

impl Default for Voltages {
    fn default() -> Self {
        Self { busbars: Gauss::new(0.05, 0.0), dc: Gauss::new(0.02, 0.0), throttle: Gauss::new(0.005, 0.0) }
    }
}

/// The whole measurement chain.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseModel {
    pub limits: Limits,
    /// C_Kistler_L, C_Kistler_R.
    pub torque: Gauss,
    pub encoders: Encoders,
    pub miscount: Miscount,
    pub current: Currents,
    pub voltage: Voltages,
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self {
            limits: Limits::default(),
            torque: Gauss::new(0.3, 2.5),
            encoders: Encoders::default(),
            miscount: Miscount::default(),
            current: Currents::default(),
            voltage: Voltages::default(),
        }
    }
}

impl NoiseModel {
    /// The Gaussian noise of analog channel `c`; `None` for a counted speed (its error
    /// is the encoder's counting, [`Encoders`]) or a channel without a sensor model.
    pub fn gauss(&self, c: Channel) -> Option<Gauss> {
        Some(match c {
            Channel::CKistlerL | Channel::CKistlerR => self.torque,
            Channel::IXlml22 | Channel::IXlmlBu1 => self.current.xlml,
            Channel::IXlmr23 => self.current.xlmr,
            Channel::IDpu27 => self.current.dpu,
            Channel::IDc => self.current.dc,
            Channel::VDcBusbars => self.voltage.busbars,
            Channel::VDc => self.voltage.dc,
            Channel::Throttle => self.voltage.throttle,
            _ => return None,
        })
    }

    /// Read a noise file; unknown keys and out-of-range values are errors.
    pub fn load(path: &Path) -> Result<Self, FileError> {
        let text = std::fs::read_to_string(path).map_err(|e| FileError::io(path, &e))?;
        Self::parse(path, &text)
    }

    /// Parse noise TOML; `origin` names it in errors.
    pub fn parse(origin: &Path, text: &str) -> Result<Self, FileError> {
        let m: Self = toml::from_str(text).map_err(|e| toml_error(origin, text, &e))?;
        m.validate().map_err(|msg| FileError::whole(origin, msg))?;
        Ok(m)
    }

    /// Range checks, naming the key.
    pub fn validate(&self) -> Result<(), String> {
        let gauss = [
            ("torque", self.torque),
            ("current.xlml", self.current.xlml),
            ("current.xlmr", self.current.xlmr),
            ("current.dpu", self.current.dpu),
            ("current.dc", self.current.dc),
            ("voltage.busbars", self.voltage.busbars),
            ("voltage.dc", self.voltage.dc),
            ("voltage.throttle", self.voltage.throttle),
        ];
        let nonneg = |v: f64| v.is_finite() && v >= 0.0;
        for (k, g) in gauss {
            if !(nonneg(g.sigma) && nonneg(g.at_limit)) {
                return Err(format!("{k}: sigma and at_limit must be finite and >= 0"));
            }
        }
        let pair = |[a, b]: [f64; 2]| a.is_finite() && b.is_finite() && 0.0 <= a && a < b;
        if !pair(self.limits.torque_nm) {
            return Err("limits.torque_nm: expected [start, full] with 0 <= start < full".into());
        }
        if !pair(self.limits.motor_rpm) {
            return Err("limits.motor_rpm: expected [start, full] with 0 <= start < full".into());
        }
        let e = &self.encoders;
        if !(e.window_s.is_finite() && e.window_s > 0.0 && e.window_s <= 10.0) {
            return Err("encoders.window_s: expected a window in (0, 10] s".into());
        }
        if [e.kistler_ppr, e.sut_motor_ppr, e.siemens_ppr].contains(&0) {
            return Err("encoders: pulses per revolution must be >= 1".into());
        }
        if !(e.timer_s.is_finite() && e.timer_s > 0.0 && e.timer_s <= 1e-3) {
            return Err("encoders.timer_s: expected a clock period in (0, 1e-3] s".into());
        }
        if !(e.edge_jitter_deg.is_finite() && (0.0..=1.0).contains(&e.edge_jitter_deg)) {
            return Err("encoders.edge_jitter_deg: expected 0 to 1 degree".into());
        }
        let mc = &self.miscount;
        if !pair([mc.threshold_rpm, mc.full_rpm]) {
            return Err("miscount: expected 0 <= threshold_rpm < full_rpm".into());
        }
        if !(mc.max_drop.is_finite() && (0.0..1.0).contains(&mc.max_drop)) {
            return Err("miscount.max_drop: expected a fraction in [0, 1)".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_example_file_is_the_default() {
        let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/noise.toml"));
        assert_eq!(NoiseModel::load(p).unwrap(), NoiseModel::default());
    }

    #[test]
    fn partial_files_and_errors() {
        let m = NoiseModel::parse(Path::new("n.toml"), "[torque]\nsigma = 1\n").unwrap();
        assert_eq!(m.torque, Gauss::new(1.0, 0.0));
        assert_eq!(m.current, Currents::default());
        let e = NoiseModel::parse(Path::new("n.toml"), "[torque]\nsigmaa = 1\n").unwrap_err();
        assert!(e.to_string().starts_with("n.toml:2:1: "), "{e}");
        let e = NoiseModel::parse(Path::new("n.toml"), "[miscount]\nmax_drop = 1.0\n").unwrap_err();
        assert_eq!(e.to_string(), "n.toml: miscount.max_drop: expected a fraction in [0, 1)");
    }

    #[test]
    fn limit_factor_ramps() {
        let l = Limits::default();
        assert_eq!(l.factor(10.0, -20.0, 500.0), 0.0);
        assert_eq!(l.factor(-95.0, 0.0, 0.0), 0.5);
        assert_eq!(l.factor(0.0, 0.0, 1950.0), 0.5);
        assert_eq!(l.factor(200.0, 0.0, 2100.0), 1.0);
    }
}
