//! Uncertainty files (`simrod check --uncertainty FILE.toml`): how far the model's
//! parameters and effect parameters may be off, as distributions a Monte Carlo check
//! draws from. `simrod identify` writes the same format (`DIR/uncertainty.toml`) for the
//! parameters it determines, so a check can start from an identification's intervals.
//!
//! ```toml
//! [params.coupling_stiffness_identified]    # a key of model-core/data/parameters.toml
//! normal = { mean = 4369.434, sd = 1906 }    # mean optional: the model's own value
//!
//! [params.load_inertia_l]
//! uniform = { min = 0.40, max = 0.50 }
//!
//! [effects.differential_friction.coulomb_nm] # an effect parameter (examples/effects.toml)
//! normal = { mean = 3.0, sd = 0.3 }
//!
//! [params."ident.accel_hs_fwd_s"]           # keys with a dot are quoted
//! normal = { sd = 0.2 }
//! ```
//!
//! Every table holds exactly one of `normal` (mean, standard deviation) or `uniform`
//! (inclusive bounds). Unknown keys, parameters and effects are errors, reported as
//! `file:line:col: message` with what was expected.

use std::fmt::Write as _;
use std::path::Path;

use model_core::Effects;
use serde::Deserialize;
use toml::Spanned;

use crate::datadir::known_key;
use crate::error::FileError;
use crate::toml_util::{toml_error, Num};

/// A distribution of one value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Dist {
    /// Gaussian; `mean: None` is the model's own value.
    Normal { mean: Option<f64>, sd: f64 },
    /// Uniform on `[min, max]`.
    Uniform { min: f64, max: f64 },
}

/// What a distribution varies.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Target {
    /// A `parameters.toml` key.
    Param(String),
    /// An effect parameter, in effect-file vocabulary.
    Effect { effect: String, param: String },
}

impl Target {
    /// `key` or `effect.param`.
    pub fn name(&self) -> String {
        match self {
            Target::Param(k) => k.clone(),
            Target::Effect { effect, param } => format!("{effect}.{param}"),
        }
    }
}

/// One uncertain value.
#[derive(Debug, Clone, PartialEq)]
pub struct Uncertain {
    pub target: Target,
    pub dist: Dist,
    /// Where it was given (`file:line`), for messages.
    pub origin: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDist {
    normal: Option<Spanned<RawNormal>>,
    uniform: Option<Spanned<RawUniform>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNormal {
    mean: Option<Num>,
    sd: Num,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawUniform {
    min: Num,
    max: Num,
}

/// Read and parse an uncertainty file.
pub fn load_uncertainty(path: &Path) -> Result<Vec<Uncertain>, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::io(path, &e))?;
    parse_uncertainty(&text, path)
}

/// Tables as ordered `(key, value)` pairs: the draws keep the file's order.
fn pairs<'de, D, V>(d: D) -> Result<Vec<(Spanned<String>, V)>, D::Error>
where
    D: serde::Deserializer<'de>,
    V: Deserialize<'de>,
{
    struct Visit<V>(std::marker::PhantomData<V>);
    impl<'de, V: Deserialize<'de>> serde::de::Visitor<'de> for Visit<V> {
        type Value = Vec<(Spanned<String>, V)>;
        fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("a table")
        }
        fn visit_map<A: serde::de::MapAccess<'de>>(self, mut m: A) -> Result<Self::Value, A::Error> {
            let mut out = Vec::new();
            while let Some(kv) = m.next_entry()? {
                out.push(kv);
            }
            Ok(out)
        }
    }
    d.deserialize_map(Visit(std::marker::PhantomData))
}

/// The file's tables in order (serde's maps would sort or hash them).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OrderedFile {
    #[serde(default, deserialize_with = "pairs")]
    params: Vec<(Spanned<String>, Spanned<RawDist>)>,
    #[serde(default, deserialize_with = "pairs")]
    effects: Vec<(Spanned<String>, OrderedEffect)>,
}

struct OrderedEffect(Vec<(Spanned<String>, Spanned<RawDist>)>);

impl<'de> Deserialize<'de> for OrderedEffect {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        pairs(d).map(OrderedEffect)
    }
}

/// Parse uncertainty-file text; `origin` names the file in errors.
pub fn parse_uncertainty(text: &str, origin: impl AsRef<Path>) -> Result<Vec<Uncertain>, FileError> {
    let origin = origin.as_ref();
    // `[params.ident.x]` is a table `ident` holding `x`: the rate keys' dot must be quoted.
    if let Some(pos) = ["[params.prog.", "[params.ident."].iter().find_map(|p| text.find(p)) {
        return Err(FileError::at_offset(
            origin,
            text,
            pos + 1,
            "a key with a dot is quoted: [params.\"ident.accel_hs_fwd_s\"]",
        ));
    }
    let raw: OrderedFile = toml::from_str(text).map_err(|e| toml_error(origin, text, &e))?;
    let at = |span: std::ops::Range<usize>, msg: String| FileError::at_span(origin, text, Some(span), msg);
    let place = |span: &std::ops::Range<usize>| {
        let (line, _) = crate::error::line_col(text, span.start);
        format!("{}:{line}", origin.display())
    };
    let mut out = Vec::new();
    for (key, d) in &raw.params {
        if !known_key(key.get_ref()) {
            return Err(at(
                key.span(),
                format!("[params.{}]: not a key of model-core/data/parameters.toml", key.get_ref()),
            ));
        }
        let dist = dist(d, &format!("params.{}", key.get_ref()), &at)?;
        out.push(Uncertain {
            target: Target::Param(key.get_ref().clone()),
            dist,
            origin: place(&key.span()),
        });
    }
    for (effect, params) in &raw.effects {
        for (param, d) in &params.0 {
            let (e, p) = (effect.get_ref(), param.get_ref());
            let mut scratch = Effects::NONE;
            if let Err(k) = scratch.set(e, p, 0.0) {
                let span = if matches!(k, model_core::effects::EffectKeyError::UnknownEffect) {
                    effect.span()
                } else {
                    param.span()
                };
                return Err(at(span, format!("[effects.{e}.{p}]: {}", k.describe(e, p))));
            }
            let dist = dist(d, &format!("effects.{e}.{p}"), &at)?;
            out.push(Uncertain {
                target: Target::Effect { effect: e.clone(), param: p.clone() },
                dist,
                origin: place(&param.span()),
            });
        }
    }
    Ok(out)
}

/// One table's distribution, checked.
fn dist(
    d: &Spanned<RawDist>,
    name: &str,
    at: &dyn Fn(std::ops::Range<usize>, String) -> FileError,
) -> Result<Dist, FileError> {
    match (&d.get_ref().normal, &d.get_ref().uniform) {
        (Some(n), None) => {
            let (mean, sd) = (n.get_ref().mean.map(|m| m.0), n.get_ref().sd.0);
            if !(sd.is_finite() && sd > 0.0) || mean.is_some_and(|m| !m.is_finite()) {
                return Err(at(
                    n.span(),
                    format!("[{name}]: normal needs a finite mean and sd > 0, got sd = {sd}"),
                ));
            }
            Ok(Dist::Normal { mean, sd })
        }
        (None, Some(u)) => {
            let (min, max) = (u.get_ref().min.0, u.get_ref().max.0);
            if !(min.is_finite() && max.is_finite() && min < max) {
                return Err(at(
                    u.span(),
                    format!("[{name}]: uniform needs finite min < max, got [{min}, {max}]"),
                ));
            }
            Ok(Dist::Uniform { min, max })
        }
        _ => Err(at(
            d.span(),
            format!("[{name}]: give exactly one of normal = {{ mean, sd }} or uniform = {{ min, max }}"),
        )),
    }
}

/// The file's text for `items` (the format [`parse_uncertainty`] reads), after the
/// comment lines of `header`.
pub fn format_uncertainty(items: &[Uncertain], header: &str) -> String {
    let mut s = String::new();
    for l in header.lines() {
        let _ = writeln!(s, "# {l}");
    }
    for u in items {
        let table = match &u.target {
            Target::Param(k) if k.contains('.') => format!("params.\"{k}\""),
            Target::Param(k) => format!("params.{k}"),
            Target::Effect { effect, param } => format!("effects.{effect}.{param}"),
        };
        let body = match u.dist {
            Dist::Normal { mean: Some(m), sd } => {
                format!("normal = {{ mean = {}, sd = {} }}", num(m), num(sd))
            }
            Dist::Normal { mean: None, sd } => format!("normal = {{ sd = {} }}", num(sd)),
            Dist::Uniform { min, max } => format!("uniform = {{ min = {}, max = {} }}", num(min), num(max)),
        };
        let _ = write!(s, "\n[{table}]\n{body}\n");
    }
    s
}

/// A finite f64 as a TOML float that reads back as the same value.
fn num(v: f64) -> String {
    let s = format!("{v:?}");
    if s.contains(['.', 'e', 'E']) {
        s
    } else {
        format!("{s}.0")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<Uncertain>, String> {
        parse_uncertainty(text, "u.toml").map_err(|e| e.to_string())
    }

    #[test]
    fn parses_params_then_effects_in_file_order() {
        let u = parse(
            "[params.load_inertia_l]\nuniform = { min = 0.4, max = 0.5 }\n\n\
             [params.coupling_stiffness_identified]\nnormal = { sd = 1906 }\n\n\
             [effects.differential_friction.coulomb_nm]\nnormal = { mean = 3, sd = 0.3 }\n\n\
             [params.\"ident.accel_hs_fwd_s\"]\nnormal = { mean = 4, sd = 0.2 }\n",
        )
        .unwrap();
        // Parameters first, then effects, each in the file's order.
        assert_eq!(u.len(), 4);
        assert_eq!(u[0].target, Target::Param("load_inertia_l".into()));
        assert_eq!(u[0].dist, Dist::Uniform { min: 0.4, max: 0.5 });
        assert_eq!(u[1].dist, Dist::Normal { mean: None, sd: 1906.0 });
        assert_eq!(u[2].target, Target::Param("ident.accel_hs_fwd_s".into()));
        assert_eq!(u[3].target.name(), "differential_friction.coulomb_nm");
        assert_eq!(u[3].origin, "u.toml:7");
        // What the writer writes reads back the same.
        let again = parse(&format_uncertainty(&u, "a header\nof two lines")).unwrap();
        assert_eq!(
            again.iter().map(|x| (&x.target, x.dist)).collect::<Vec<_>>(),
            u.iter().map(|x| (&x.target, x.dist)).collect::<Vec<_>>()
        );
        assert!(parse("").unwrap().is_empty());
    }

    #[test]
    fn errors_name_line_and_key() {
        let e = parse("[params.load_inertia]\nnormal = { sd = 1 }\n").unwrap_err();
        assert!(e.starts_with("u.toml:1:9: [params.load_inertia]: not a key"), "{e}");
        let e = parse("[effects.warp.factor]\nnormal = { sd = 1 }\n").unwrap_err();
        assert!(e.starts_with("u.toml:1:10: ") && e.contains("unknown effect `warp`"), "{e}");
        let e = parse("[effects.controller_delay.delay]\nnormal = { sd = 1 }\n").unwrap_err();
        assert!(e.starts_with("u.toml:1:27: ") && e.contains("`delay_s`"), "{e}");
        let e = parse("[params.sut_inertia]\nnormal = { mean = 1, sd = 0 }\n").unwrap_err();
        assert!(e.starts_with("u.toml:2:10: [params.sut_inertia]: normal needs"), "{e}");
        let e = parse("[params.sut_inertia]\nuniform = { min = 2, max = 1 }\n").unwrap_err();
        assert!(e.starts_with("u.toml:2:11: ") && e.contains("min < max"), "{e}");
        let e = parse("[params.sut_inertia]\n").unwrap_err();
        assert!(e.starts_with("u.toml:") && e.contains("exactly one of"), "{e}");
        let e = parse("[params.sut_inertia]\nnormal = { sd = 1, mode = 2 }\n").unwrap_err();
        assert!(e.starts_with("u.toml:2:") && e.contains("mode"), "{e}");
        let e = parse("[params.ident.accel_hs_fwd_s]\nnormal = { sd = 1 }\n").unwrap_err();
        assert!(e.starts_with("u.toml:1:2: a key with a dot is quoted"), "{e}");
        let e = parse("[param.sut_inertia]\n").unwrap_err();
        assert!(e.starts_with("u.toml:1:") && e.contains("param"), "{e}");
    }
}
