//! Small helpers shared by the TOML file loaders (profiles, effects).

use std::fmt;
use std::path::Path;

use serde::de::{self, Deserialize, Deserializer, Visitor};

use crate::error::FileError;

/// A TOML number, integer or float (`3` and `3.0` both mean 3): users write whole
/// durations and percentages without a decimal point. Any other type is refused with
/// "expected a number".
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64);

impl<'de> Deserialize<'de> for Num {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Num;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Num, E> {
                Ok(Num(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Num, E> {
                Ok(Num(v as f64))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Num, E> {
                Ok(Num(v))
            }
        }
        d.deserialize_any(V)
    }
}

/// A `toml` error as a located [`FileError`]; the message is flattened to one line
/// so the `file:line:col: message` form stays greppable.
pub fn toml_error(origin: &Path, text: &str, e: &toml::de::Error) -> FileError {
    let msg = e.message().lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join("; ");
    FileError::at_span(origin, text, e.span(), msg)
}

/// `a`, `b`, `c` as a comma-separated list of back-quoted names, for error messages.
pub fn list(names: &[&str]) -> String {
    names.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ")
}

/// A finite f32 as a TOML float: the shortest form that reads back (through f64,
/// as TOML readers do) as the same bits, always with a `.` so it is a float (keeps the
/// sign of -0 and cannot overflow TOML's 64-bit integers).
pub fn toml_f32(v: f32) -> String {
    let short = v.to_string();
    let mut s = match short.parse::<f64>() {
        Ok(back) if (back as f32).to_bits() == v.to_bits() => short,
        // Double rounding (decimal -> f64 -> f32) can miss by one ulp: fall back to the
        // exact f64 value of `v`, which converts back exactly.
        _ => f64::from(v).to_string(),
    };
    if !s.contains('.') {
        s.push_str(".0");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn toml_f32_round_trips_through_toml() {
        let mut vals = vec![0.0f32, -0.0, 0.1, 1.0, 1e20, -3.5e-7, f32::MAX, f32::from_bits(1)];
        let mut x = 0x1234_5678u32;
        while vals.len() < 20_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let v = f32::from_bits(x);
            if v.is_finite() {
                vals.push(v);
            }
        }
        for v in vals {
            let text = format!("x = {}", toml_f32(v));
            let t: toml::Table = toml::from_str(&text).unwrap();
            let back = t["x"].as_float().unwrap() as f32;
            assert_eq!(back.to_bits(), v.to_bits(), "{text}");
        }
    }

    #[test]
    fn num_accepts_integers_and_floats_only() {
        #[derive(Debug, serde::Deserialize)]
        struct T {
            a: Num,
        }
        assert_eq!(toml::from_str::<T>("a = 3").unwrap().a, Num(3.0));
        assert_eq!(toml::from_str::<T>("a = -2.5").unwrap().a, Num(-2.5));
        let e = toml::from_str::<T>("a = \"x\"").unwrap_err();
        assert!(e.message().contains("expected a number"), "{}", e.message());
        let fe = toml_error(Path::new("f.toml"), "a = \"x\"", &e);
        assert!(fe.to_string().starts_with("f.toml:1:5: "), "{fe}");
    }
}
