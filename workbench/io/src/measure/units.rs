//! Units of known channels: which spellings mean the bench unit, and which other units
//! are converted (and by what factor). Anything else on a known channel is an error: a
//! wrong unit is a wrong number, not a guess.
//!
//! | bench unit | accepted as is | converted (factor to the bench unit) |
//! |---|---|---|
//! | `s` (time) | `s`, `sec`, none | `ms` (1e-3), `us`/`µs` (1e-6) |
//! | `rpm` | `rpm`, `RPM`, `1/min`, `min^-1`, `min-1`, `r/min`, `U/min` | `rad/s` (30/π), `rev/s`/`rps` (60) |
//! | `N m` | `N m`, `Nm`, `N.m`, `N*m`, `N·m` | `kN m`/`kNm` (1000), `mN m`/`mNm` (1e-3) |
//! | `A` | `A` | `mA` (1e-3), `kA` (1000) |
//! | `V` | `V` | `mV` (1e-3), `kV` (1000) |
//! | `W` | `W` | `kW` (1000), `mW` (1e-3) |
//! | `%` | `%` | none |
//!
//! `Hz` is refused for speeds (pulse or shaft frequency? the file cannot say). Channels
//! the workbench does not know keep the unit as written and are never converted.

use model_core::Channel;

use super::{SETPOINT_LOAD_L, SETPOINT_LOAD_R, SETPOINT_THROTTLE};

/// The bench unit of a channel the workbench knows (model channels and set points).
pub fn bench_unit(name: &str) -> Option<&'static str> {
    if [SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R].contains(&name) {
        return Some("%");
    }
    Channel::from_name(name).map(Channel::unit)
}

/// Factor that turns a value in `unit` (as written, trimmed) into `bench` units, or
/// `None` when the unit is not one of the spellings or conversions above.
pub fn factor_to(bench: &str, unit: &str) -> Option<f64> {
    let u = unit.trim();
    let same: &[&str] = match bench {
        "s" => &["s", "sec", ""],
        "rpm" => &["rpm", "RPM", "1/min", "min^-1", "min-1", "r/min", "U/min"],
        "N m" => &["N m", "Nm", "N.m", "N*m", "N·m"],
        "A" => &["A"],
        "V" => &["V"],
        "W" => &["W"],
        "%" => &["%"],
        other => return (u == other).then_some(1.0),
    };
    if same.contains(&u) {
        return Some(1.0);
    }
    let conv: &[(&str, f64)] = match bench {
        "s" => &[("ms", 1e-3), ("us", 1e-6), ("µs", 1e-6)],
        "rpm" => &[("rad/s", 30.0 / std::f64::consts::PI), ("rev/s", 60.0), ("rps", 60.0)],
        "N m" => &[("kN m", 1e3), ("kNm", 1e3), ("mN m", 1e-3), ("mNm", 1e-3)],
        "A" => &[("mA", 1e-3), ("kA", 1e3)],
        "V" => &[("mV", 1e-3), ("kV", 1e3)],
        "W" => &[("kW", 1e3), ("mW", 1e-3)],
        _ => &[],
    };
    conv.iter().find(|(s, _)| *s == u).map(|(_, f)| *f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_channels_have_bench_units() {
        assert_eq!(bench_unit("SuTMotorEnc"), Some("rpm"));
        assert_eq!(bench_unit("C_Kistler_L"), Some("N m"));
        assert_eq!(bench_unit("Dm Left"), Some("%"));
        assert_eq!(bench_unit("Accel Motor 1 Z"), None);
    }

    #[test]
    fn conversions() {
        assert_eq!(factor_to("rpm", " 1/min "), Some(1.0));
        let f = factor_to("rpm", "rad/s").unwrap();
        assert!((f * std::f64::consts::PI - 30.0).abs() < 1e-12);
        assert_eq!(factor_to("N m", "kNm"), Some(1000.0));
        assert_eq!(factor_to("s", "ms"), Some(1e-3));
        assert_eq!(factor_to("rpm", "Hz"), None);
        assert_eq!(factor_to("A", "V"), None);
        assert_eq!(factor_to("%", ""), None);
    }
}
