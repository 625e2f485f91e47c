//! User test profiles (`--profile-file FILE.toml`): the same sets the PLC takes, in a
//! file an engineer can write by hand.
//!
//! ```toml
//! name = "my profile"          # optional; defaults to the file name
//! throttle_scale = 1.0          # optional, in [-1.5, 1.5]; --throttle-scale overrides
//! load_scale = 1.0              # optional, in [-1.5, 1.5]; --load-scale overrides
//!
//! [[set]]                       # 1 to 10 sets, run in order
//! duration_s = 3                # required, 1e-6 s to 1e6 s
//! throttle_pct = 50             # [-100, 100] %, + forward, - reverse (default 0)
//! load_l_pct = 0                # [-100, 100] %, + regenerating, - motoring (default 0)
//! load_r_pct = 0                # same, right load motor (default 0)
//! throttle = "hold"             # "hold" this value, or "interp" to the next set's
//! load = "interp"               # same for both loads (default "hold")
//! ```
//!
//! `interp` ramps linearly to the next set's value over the set (to 0 after the last
//! set), exactly as the bench's PLC does. Integers and floats are both accepted.
//! Unknown keys are errors, so a typo never silently becomes a default. Every error is
//! reported as `file:line:col: message`. A complete example: `workbench/examples/profile.toml`.

use std::path::Path;

use model_core::profile::MAX_SETS;
use model_core::{Profile, ProfileError, ProfileSet, SetMode};
use serde::Deserialize;
use toml::Spanned;

use crate::error::FileError;
use crate::toml_util::{toml_error, Num};

/// Shortest set duration [s]: the profile clock counts whole microseconds.
const MIN_DURATION_S: f64 = 1e-6;
/// Largest set duration the model accepts [s].
const MAX_DURATION_S: f64 = 1.0e6;
/// Scale range of the PLC (and of `--throttle-scale`/`--load-scale`).
pub const SCALE_RANGE: (f64, f64) = (-1.5, 1.5);

/// A loaded, validated profile file.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileFile {
    /// `name`, if the file gives one.
    pub name: Option<String>,
    /// `throttle_scale`, if the file gives one.
    pub throttle_scale: Option<f32>,
    /// `load_scale`, if the file gives one.
    pub load_scale: Option<f32>,
    /// The sets, 1 to [`MAX_SETS`], each already within the model's limits.
    pub sets: Vec<ProfileSet>,
}

impl ProfileFile {
    /// The runnable profile. Scales: the caller's (command line) first, then the
    /// file's, then 1.
    pub fn profile(
        &self,
        throttle_scale: Option<f32>,
        load_scale: Option<f32>,
    ) -> Result<Profile, ProfileError> {
        Profile::new(
            &self.sets,
            throttle_scale.or(self.throttle_scale).unwrap_or(1.0),
            load_scale.or(self.load_scale).unwrap_or(1.0),
        )
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    name: Option<String>,
    throttle_scale: Option<Spanned<Num>>,
    load_scale: Option<Spanned<Num>>,
    #[serde(default)]
    set: Vec<Spanned<RawSet>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSet {
    duration_s: Spanned<Num>,
    throttle_pct: Option<Spanned<Num>>,
    load_l_pct: Option<Spanned<Num>>,
    load_r_pct: Option<Spanned<Num>>,
    #[serde(default)]
    throttle: Mode,
    #[serde(default)]
    load: Mode,
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum Mode {
    #[default]
    Hold,
    #[serde(alias = "interpolate")]
    Interp,
}

impl From<Mode> for SetMode {
    fn from(m: Mode) -> Self {
        match m {
            Mode::Hold => SetMode::Hold,
            Mode::Interp => SetMode::Interpolate,
        }
    }
}

/// Read and parse a profile file.
pub fn load_profile(path: &Path) -> Result<ProfileFile, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::io(path, &e))?;
    parse_profile(&text, path)
}

/// Parse profile text; `origin` names the file in errors.
pub fn parse_profile(text: &str, origin: impl AsRef<Path>) -> Result<ProfileFile, FileError> {
    let origin = origin.as_ref();
    let raw: RawFile = toml::from_str(text).map_err(|e| toml_error(origin, text, &e))?;
    let err = |span: std::ops::Range<usize>, msg: String| FileError::at_span(origin, text, Some(span), msg);

    let scale = |key: &str, v: &Option<Spanned<Num>>| -> Result<Option<f32>, FileError> {
        let Some(v) = v else { return Ok(None) };
        let x = v.get_ref().0;
        if !(x.is_finite() && (SCALE_RANGE.0..=SCALE_RANGE.1).contains(&x)) {
            return Err(err(
                v.span(),
                format!("{key} = {x} is outside [{}, {}]", SCALE_RANGE.0, SCALE_RANGE.1),
            ));
        }
        Ok(Some(x as f32))
    };
    let throttle_scale = scale("throttle_scale", &raw.throttle_scale)?;
    let load_scale = scale("load_scale", &raw.load_scale)?;

    if raw.set.is_empty() {
        return Err(FileError::whole(
            origin,
            format!("no sets: a profile needs 1 to {MAX_SETS} [[set]] tables"),
        ));
    }
    if let Some(extra) = raw.set.get(MAX_SETS) {
        return Err(err(
            extra.span(),
            format!(
                "set {}: a profile has at most {MAX_SETS} sets (the PLC's limit), this file has {}",
                MAX_SETS + 1,
                raw.set.len()
            ),
        ));
    }

    let mut sets = Vec::with_capacity(raw.set.len());
    for (i, s) in raw.set.iter().enumerate() {
        let n = i + 1;
        let s = s.get_ref();
        let d = s.duration_s.get_ref().0;
        // At least the profile clock's 1 µs: shorter sets vanish (and 1e-50 s is 0 as
        // the model's f32, found by the fuzzer).
        if !(d.is_finite() && (MIN_DURATION_S..=MAX_DURATION_S).contains(&d)) {
            return Err(err(
                s.duration_s.span(),
                format!("set {n}: duration_s = {d} must be at least {MIN_DURATION_S} s and at most {MAX_DURATION_S} s"),
            ));
        }
        let pct = |key: &str, v: &Option<Spanned<Num>>| -> Result<f32, FileError> {
            let Some(v) = v else { return Ok(0.0) };
            let x = v.get_ref().0;
            if !(x.is_finite() && (-100.0..=100.0).contains(&x)) {
                return Err(err(v.span(), format!("set {n}: {key} = {x} is outside [-100, 100] %")));
            }
            Ok(x as f32)
        };
        sets.push(ProfileSet {
            duration_s: d as f32,
            throttle_pct: pct("throttle_pct", &s.throttle_pct)?,
            load_l_pct: pct("load_l_pct", &s.load_l_pct)?,
            load_r_pct: pct("load_r_pct", &s.load_r_pct)?,
            throttle_mode: s.throttle.into(),
            load_mode: s.load.into(),
        });
    }
    Ok(ProfileFile { name: raw.name.filter(|n| !n.trim().is_empty()), throttle_scale, load_scale, sets })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<ProfileFile, String> {
        parse_profile(text, "p.toml").map_err(|e| e.to_string())
    }

    #[test]
    fn full_file_parses_with_defaults() {
        let p = parse(
            "name = \"ramp\"\nload_scale = -0.5\n\n[[set]]\nduration_s = 3\nthrottle_pct = 50\n\
             load = \"interp\"\n\n[[set]]\nduration_s = 1.5\nthrottle_pct = -20.5\n\
             load_l_pct = 10\nload_r_pct = -10\nthrottle = \"interpolate\"\n",
        )
        .unwrap();
        assert_eq!(p.name.as_deref(), Some("ramp"));
        assert_eq!((p.throttle_scale, p.load_scale), (None, Some(-0.5)));
        assert_eq!(
            p.sets,
            [
                ProfileSet {
                    duration_s: 3.0,
                    throttle_pct: 50.0,
                    load_l_pct: 0.0,
                    load_r_pct: 0.0,
                    throttle_mode: SetMode::Hold,
                    load_mode: SetMode::Interpolate,
                },
                ProfileSet {
                    duration_s: 1.5,
                    throttle_pct: -20.5,
                    load_l_pct: 10.0,
                    load_r_pct: -10.0,
                    throttle_mode: SetMode::Interpolate,
                    load_mode: SetMode::Hold,
                },
            ]
        );
        let prof = p.profile(Some(0.5), None).unwrap();
        assert_eq!(prof.duration_us(), 4_500_000);
        // CLI throttle scale 0.5, file load scale -0.5.
        let sp = prof.at(0);
        assert_eq!(sp.throttle_pct, 25.0);
    }

    #[test]
    fn semantic_errors_point_at_the_value() {
        let text = "[[set]]\nduration_s = 1\n\n[[set]]\nduration_s = 1\n\n[[set]]\nduration_s = 2\nthrottle_pct = 150\n";
        assert_eq!(
            parse(text).unwrap_err(),
            "p.toml:9:16: set 3: throttle_pct = 150 is outside [-100, 100] %"
        );
        assert_eq!(
            parse("[[set]]\nduration_s = 0\n").unwrap_err(),
            "p.toml:2:14: set 1: duration_s = 0 must be at least 0.000001 s and at most 1000000 s"
        );
        // Fuzzer regression (fuzz/regressions/toml_files/): positive as f64, 0 as f32.
        assert!(parse("[[set]]\nduration_s = 1e-50\n").unwrap_err().contains("must be at least"));
        assert_eq!(
            parse("[[set]]\nduration_s = 1\nload_r_pct = nan\n").unwrap_err(),
            "p.toml:3:14: set 1: load_r_pct = NaN is outside [-100, 100] %"
        );
        assert_eq!(
            parse("throttle_scale = 2\n[[set]]\nduration_s = 1\n").unwrap_err(),
            "p.toml:1:18: throttle_scale = 2 is outside [-1.5, 1.5]"
        );
    }

    #[test]
    fn structural_errors_are_located() {
        let e = parse("[[set]]\nduration_s = 1\nthrotle_pct = 5\n").unwrap_err();
        assert!(e.starts_with("p.toml:3:1: unknown field `throtle_pct`"), "{e}");
        assert!(e.contains("`throttle_pct`") && e.contains("`load`"), "{e}");
        let e = parse("[[set]]\nduration_s = 1\nthrottle = \"ramp\"\n").unwrap_err();
        assert!(e.starts_with("p.toml:3:12: unknown variant `ramp`"), "{e}");
        assert!(e.contains("`hold`") && e.contains("`interp`"), "{e}");
        let e = parse("[[set]]\nduration_s = \"long\"\n").unwrap_err();
        assert!(e.starts_with("p.toml:2:14: ") && e.contains("expected a number"), "{e}");
        let e = parse("[[set]]\nduration_s = 1\nthrottle_pct = \n").unwrap_err();
        assert!(e.starts_with("p.toml:3:16: "), "{e}");
        let e = parse("\n[[set]]\nthrottle_pct = 5\n").unwrap_err();
        assert!(e.starts_with("p.toml:2:1: ") && e.contains("duration_s"), "{e}");
        let e = parse("speed = 3\n").unwrap_err();
        assert!(e.starts_with("p.toml:1:1: unknown field `speed`"), "{e}");
    }

    #[test]
    fn set_count_is_limited() {
        assert_eq!(
            parse("name = \"x\"\n").unwrap_err(),
            "p.toml: no sets: a profile needs 1 to 10 [[set]] tables"
        );
        let eleven = "[[set]]\nduration_s = 1\n".repeat(11);
        assert_eq!(
            parse(&eleven).unwrap_err(),
            "p.toml:21:1: set 11: a profile has at most 10 sets (the PLC's limit), this file has 11"
        );
        assert_eq!(parse(&"[[set]]\nduration_s = 1\n".repeat(10)).unwrap().sets.len(), 10);
    }

    #[test]
    fn example_file_is_valid() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/profile.toml");
        let p = load_profile(&path).unwrap();
        assert!(p.name.is_some());
        assert!(p.sets.len() >= 3);
        p.profile(None, None).unwrap();
    }
}
