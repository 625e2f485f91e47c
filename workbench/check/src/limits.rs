//! The bench's limits: a TOML file of `[[limit]]` tables, each with the value's origin.
//! The built-in file is `workbench/data/limits.toml`; `--limits FILE` replaces it (copy
//! it and add limits of your own).
//!
//! ```toml
//! [[limit]]
//! id = "flange_torque_L"             # unique; what reports name
//! name = "Torque flange L"           # optional, for people (default: the id)
//! quantity = "flange_torque_L"       # a channel (`I_DPU 2.7`) or a derived quantity
//! unit = "N m"                       # must be the quantity's unit
//! min = -200.0                       # a bound: min and/or max ...
//! max = 200.0
//! for_s = 0.5                        # optional: crossed only beyond it longer than this [s]
//! # thermal = { rated = 900.0, tau_s = 876.0, initial = 0.0 }   # ... or a heating rule
//! origin = "Kistler KiTorq 4550A200 measuring range (thesis table 4.2)"
//! assumed = "why this value"         # present exactly when the value is assumed
//! ```
//!
//! A `thermal` limit is a first-order heating model on `(value / rated)²` (copper losses
//! grow with the square of the load): the state `x` follows `τ dx/dt = (v/rated)² − x`
//! from `initial` (0 = cold) and must stay at or below 1; it is reported as the
//! equivalent continuous value `rated √x`, in the quantity's unit.

use std::path::Path;

use serde::Deserialize;
use simrod_io::error::FileError;
use simrod_io::toml_util::{toml_error, Num};
use toml::Spanned;

use crate::quantity::Quantity;

/// The built-in limits, `workbench/data/limits.toml`.
pub const BUILTIN_TOML: &str = include_str!("../../data/limits.toml");
/// How the built-in file is named in messages.
pub const BUILTIN_PATH: &str = "workbench/data/limits.toml";

/// What keeps a quantity inside.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rule {
    /// `min ≤ value ≤ max`; crossed when beyond for longer than `for_s` at a stretch
    /// (0: any sample beyond).
    Bound { min: Option<f64>, max: Option<f64>, for_s: f64 },
    /// First-order heating on `(value / rated)²` with time constant `tau_s`, from the
    /// per-unit state `initial`; crossed when the state exceeds 1.
    Thermal { rated: f64, tau_s: f64, initial: f64 },
}

/// One limit.
#[derive(Debug, Clone, PartialEq)]
pub struct Limit {
    pub id: String,
    pub name: String,
    pub quantity: Quantity,
    pub unit: String,
    pub rule: Rule,
    /// Where the value comes from.
    pub origin: String,
    /// Why an assumed value was chosen; `None` for values with a published origin.
    pub assumed: Option<String>,
    /// `file:line` of its table.
    pub defined_at: String,
}

impl Limit {
    /// The rule in words: `≤ 200 N m`, `-500 … 2100 rpm`, `900 W continuous (τ 876 s)`.
    pub fn describe(&self) -> String {
        let u = &self.unit;
        match self.rule {
            Rule::Bound { min, max, for_s } => {
                let b = match (min, max) {
                    (Some(a), Some(b)) => format!("{a} … {b} {u}"),
                    (Some(a), None) => format!("≥ {a} {u}"),
                    (None, Some(b)) => format!("≤ {b} {u}"),
                    (None, None) => "-".into(),
                };
                if for_s > 0.0 {
                    format!("{b} (beyond ≤ {for_s} s)")
                } else {
                    b
                }
            }
            Rule::Thermal { rated, tau_s, .. } => format!("{rated} {u} continuous (τ {tau_s} s)"),
        }
    }

    /// The size of the limit [unit], for margins in percent: the largest bound's
    /// magnitude, or the rating.
    pub fn size(&self) -> f64 {
        match self.rule {
            Rule::Bound { min, max, .. } => {
                min.map_or(0.0, f64::abs).max(max.map_or(0.0, f64::abs)).max(f64::MIN_POSITIVE)
            }
            Rule::Thermal { rated, .. } => rated,
        }
    }

    /// The same limit made stricter by `by` [unit] (bounds moved inwards, the rating
    /// lowered): what a nominal run must keep so that a spread of `by` stays inside.
    pub fn tightened(&self, by: f64) -> Limit {
        let by = by.max(0.0);
        let rule = match self.rule {
            Rule::Bound { min, max, for_s } => {
                Rule::Bound { min: min.map(|m| m + by), max: max.map(|m| m - by), for_s }
            }
            Rule::Thermal { rated, tau_s, initial } => {
                // The same heating state limit on a lower rating: x ≤ ((rated − by)/rated)².
                let r = (rated - by).max(rated * 1e-6);
                Rule::Thermal { rated: r, tau_s, initial: initial * (rated / r).powi(2) }
            }
        };
        Limit { rule, ..self.clone() }
    }
}

/// A limits file.
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    /// Where it was read from.
    pub source: String,
    pub limits: Vec<Limit>,
}

impl Limits {
    /// The built-in limits.
    pub fn builtin() -> Result<Self, FileError> {
        parse_limits(BUILTIN_TOML, BUILTIN_PATH)
    }

    /// Read and parse a limits file.
    pub fn load(path: &Path) -> Result<Self, FileError> {
        let text = std::fs::read_to_string(path).map_err(|e| FileError::io(path, &e))?;
        parse_limits(&text, path)
    }

    /// Whether any limit needs the flange mode resolved.
    pub fn need_flange_mode(&self) -> Vec<&Limit> {
        self.limits.iter().filter(|l| l.quantity.needs_flange_mode()).collect()
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    #[serde(default)]
    limit: Vec<Spanned<RawLimit>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLimit {
    id: Spanned<String>,
    name: Option<String>,
    quantity: Spanned<String>,
    unit: Spanned<String>,
    min: Option<Spanned<Num>>,
    max: Option<Spanned<Num>>,
    for_s: Option<Spanned<Num>>,
    thermal: Option<Spanned<RawThermal>>,
    origin: Spanned<String>,
    assumed: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawThermal {
    rated: Num,
    tau_s: Num,
    initial: Option<Num>,
}

/// Parse limits-file text; `origin` names the file in errors (`file:line:col:`).
pub fn parse_limits(text: &str, origin: impl AsRef<Path>) -> Result<Limits, FileError> {
    let origin = origin.as_ref();
    let raw: RawFile = toml::from_str(text).map_err(|e| toml_error(origin, text, &e))?;
    if raw.limit.is_empty() {
        return Err(FileError::whole(origin, "no limits: expected [[limit]] tables"));
    }
    let mut limits: Vec<Limit> = Vec::with_capacity(raw.limit.len());
    for l in &raw.limit {
        let lim = limit(l, text, origin)?;
        if limits.iter().any(|x| x.id == lim.id) {
            let at = l.get_ref().id.span();
            return Err(FileError::at_span(
                origin,
                text,
                Some(at),
                format!("limit `{}` is defined twice", lim.id),
            ));
        }
        limits.push(lim);
    }
    Ok(Limits { source: origin.display().to_string(), limits })
}

/// One `[[limit]]` table, checked.
fn limit(l: &Spanned<RawLimit>, text: &str, origin: &Path) -> Result<Limit, FileError> {
    let r = l.get_ref();
    let id = r.id.get_ref().trim().to_string();
    let err = |span: std::ops::Range<usize>, key: &str, msg: String| {
        FileError::at_span(origin, text, Some(span), format!("limit `{id}`: {key}: {msg}"))
    };
    if id.is_empty() {
        return Err(FileError::at_span(origin, text, Some(r.id.span()), "id: expected a name".to_string()));
    }
    let quantity = Quantity::from_name(r.quantity.get_ref()).ok_or_else(|| {
        err(
            r.quantity.span(),
            "quantity",
            format!("unknown `{}`; expected {}", r.quantity.get_ref(), Quantity::names()),
        )
    })?;
    if r.unit.get_ref() != quantity.unit() {
        return Err(err(
            r.unit.span(),
            "unit",
            format!("`{}` is not the unit of {} (`{}`)", r.unit.get_ref(), quantity.name(), quantity.unit()),
        ));
    }
    let finite = |v: &Option<Spanned<Num>>, key: &str| -> Result<Option<f64>, FileError> {
        match v {
            Some(x) if !x.get_ref().0.is_finite() => {
                Err(err(x.span(), key, "expected a finite number".into()))
            }
            Some(x) => Ok(Some(x.get_ref().0)),
            None => Ok(None),
        }
    };
    let (min, max, for_s) = (finite(&r.min, "min")?, finite(&r.max, "max")?, finite(&r.for_s, "for_s")?);
    let rule = match (&r.thermal, min.is_some() || max.is_some()) {
        (Some(t), false) => {
            if let Some(f) = &r.for_s {
                return Err(err(
                    f.span(),
                    "for_s",
                    "applies to min/max bounds, not to a thermal limit".into(),
                ));
            }
            thermal(t, &err)?
        }
        (None, true) => {
            if let (Some(a), Some(b), Some(s)) = (min, max, &r.max) {
                if a >= b {
                    return Err(err(s.span(), "max", format!("{b} must be above min = {a}")));
                }
            }
            if let (Some(f), Some(s)) = (for_s, &r.for_s) {
                if f < 0.0 {
                    return Err(err(s.span(), "for_s", format!("{f} s: expected a time ≥ 0")));
                }
            }
            Rule::Bound { min, max, for_s: for_s.unwrap_or(0.0) }
        }
        (Some(t), true) => {
            return Err(err(t.span(), "thermal", "give either min/max or thermal, not both".into()));
        }
        (None, false) => {
            return Err(err(
                l.span(),
                "rule",
                "expected min and/or max, or thermal = { rated, tau_s }".into(),
            ));
        }
    };
    let origin_text = r.origin.get_ref().trim();
    if origin_text.is_empty() {
        return Err(err(r.origin.span(), "origin", "say where the value comes from".into()));
    }
    let assumed = match &r.assumed {
        Some(a) if a.get_ref().trim().is_empty() => {
            return Err(err(a.span(), "assumed", "say why the assumed value was chosen".into()))
        }
        Some(a) => Some(a.get_ref().trim().to_string()),
        None => None,
    };
    let (line, _) = simrod_io::error::line_col(text, l.span().start);
    Ok(Limit {
        name: r.name.clone().filter(|n| !n.trim().is_empty()).unwrap_or_else(|| id.clone()),
        id,
        quantity,
        unit: r.unit.get_ref().clone(),
        rule,
        origin: origin_text.to_string(),
        assumed,
        defined_at: format!("{}:{line}", origin.display()),
    })
}

fn thermal(
    t: &Spanned<RawThermal>,
    err: &dyn Fn(std::ops::Range<usize>, &str, String) -> FileError,
) -> Result<Rule, FileError> {
    let r = t.get_ref();
    let (rated, tau_s, initial) = (r.rated.0, r.tau_s.0, r.initial.map_or(0.0, |n| n.0));
    if !(rated.is_finite() && rated > 0.0 && tau_s.is_finite() && tau_s > 0.0) {
        return Err(err(
            t.span(),
            "thermal",
            format!("rated = {rated} and tau_s = {tau_s} must be finite and > 0"),
        ));
    }
    if !(initial.is_finite() && (0.0..1.0).contains(&initial)) {
        return Err(err(
            t.span(),
            "thermal",
            format!("initial = {initial}: expected a per-unit state in [0, 1)"),
        ));
    }
    Ok(Rule::Thermal { rated, tau_s, initial })
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::Channel;

    fn parse(text: &str) -> Result<Limits, String> {
        parse_limits(text, "l.toml").map_err(|e| e.to_string())
    }

    const OK: &str =
        "[[limit]]\nid = \"dpu\"\nquantity = \"I_DPU 2.7\"\nunit = \"A\"\nmin = -230\nmax = 230\n\
                      for_s = 0.5\norigin = \"x\"\nassumed = \"y\"\n";

    #[test]
    fn builtin_file_parses_and_every_value_has_an_origin() {
        let l = Limits::builtin().unwrap();
        assert!(l.limits.len() >= 15);
        for x in &l.limits {
            assert!(!x.origin.is_empty() && x.defined_at.starts_with(BUILTIN_PATH));
        }
        let f = l.limits.iter().find(|x| x.id == "flange_torque_R").unwrap();
        assert_eq!(f.rule, Rule::Bound { min: Some(-200.0), max: Some(200.0), for_s: 0.0 });
        assert!(f.assumed.is_none());
        assert!(l.limits.iter().any(|x| matches!(x.rule, Rule::Thermal { rated, .. } if rated == 900.0)));
    }

    #[test]
    fn a_bound_parses() {
        let l = parse(OK).unwrap();
        let x = &l.limits[0];
        assert_eq!(x.quantity, Quantity::Channel(Channel::IDpu27));
        assert_eq!(x.rule, Rule::Bound { min: Some(-230.0), max: Some(230.0), for_s: 0.5 });
        assert_eq!(
            (x.name.as_str(), x.assumed.as_deref(), x.defined_at.as_str()),
            ("dpu", Some("y"), "l.toml:1")
        );
        assert_eq!(x.describe(), "-230 … 230 A (beyond ≤ 0.5 s)");
        assert_eq!(x.tightened(30.0).rule, Rule::Bound { min: Some(-200.0), max: Some(200.0), for_s: 0.5 });
    }

    #[test]
    fn errors_name_file_line_and_key() {
        let e = parse(&OK.replace("I_DPU 2.7", "I_DPU")).unwrap_err();
        assert!(e.starts_with("l.toml:3:12: limit `dpu`: quantity: unknown `I_DPU`"), "{e}");
        let e = parse(&OK.replace("unit = \"A\"", "unit = \"kA\"")).unwrap_err();
        assert!(e.starts_with("l.toml:4:8: limit `dpu`: unit: `kA` is not the unit"), "{e}");
        let e = parse(&OK.replace("max = 230", "max = -300")).unwrap_err();
        assert!(e.starts_with("l.toml:6:7: limit `dpu`: max: -300 must be above min"), "{e}");
        let e = parse(&OK.replace("for_s = 0.5", "for_s = -1")).unwrap_err();
        assert!(e.starts_with("l.toml:7:9: limit `dpu`: for_s:"), "{e}");
        let e = parse(&OK.replace("max = 230", "mx = 230")).unwrap_err();
        assert!(e.starts_with("l.toml:6:1: ") && e.contains("mx"), "{e}");
        let e = parse(&OK.replace("origin = \"x\"", "origin = \" \"")).unwrap_err();
        assert!(e.starts_with("l.toml:8:10: limit `dpu`: origin:"), "{e}");
        let e = parse(&format!("{OK}\n{OK}")).unwrap_err();
        assert!(e.starts_with("l.toml:12:6: limit `dpu` is defined twice"), "{e}");
        let e = parse(&OK.replace("max = 230", "max = \"high\"")).unwrap_err();
        assert!(e.starts_with("l.toml:6:7: ") && e.contains("expected a number"), "{e}");
        let e = parse(
            "[[limit]]\nid = \"t\"\nquantity = \"sut_motor_power\"\nunit = \"W\"\norigin = \"o\"\n\
                       thermal = { rated = 900, tau_s = 0 }\n",
        )
        .unwrap_err();
        assert!(e.starts_with("l.toml:6:11: limit `t`: thermal: rated = 900 and tau_s = 0"), "{e}");
        assert!(parse("").unwrap_err().contains("no limits"));
    }
}
