//! Channel mapping files: for benches (or exports) that name, scale or label channels
//! differently from the SimRod bench. Example: `workbench/examples/mapping.toml`.
//!
//! ```toml
//! [rename]                    # name in the file -> bench name
//! "Torque L" = "C_Kistler_L"
//! "Speed L" = "T_Kistler_L"
//!
//! [scale]                     # multiply the values as read (e.g. a flange mounted reversed)
//! "Torque L" = -1.0
//!
//! [unit]                      # the unit the file's values are in, where the file gives none
//! "Speed L" = "rad/s"         #   (or gives a wrong one); then converted as usual
//! ```
//!
//! Every key is a column name as it appears in the file (for MAT files: the variable name
//! or the bench name it stands for). Order of operations per column: `[unit]` replaces the
//! unit as read, `[scale]` multiplies the values, `[rename]` sets the name, then the usual
//! unit check/conversion of known channels applies (see [`super::units`]). Unknown tables
//! or keys of the wrong type are errors; a key that matches no column is only a note,
//! so one mapping file can serve exports with different channel sets.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

use crate::error::FileError;
use crate::toml_util::{toml_error, Num};

/// A loaded mapping file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mapping {
    /// File name -> bench name.
    pub rename: BTreeMap<String, String>,
    /// File name -> factor on the values.
    pub scale: BTreeMap<String, f64>,
    /// File name -> unit of the values in the file.
    pub unit: BTreeMap<String, String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    #[serde(default)]
    rename: BTreeMap<String, String>,
    #[serde(default)]
    scale: BTreeMap<String, toml::Spanned<Num>>,
    #[serde(default)]
    unit: BTreeMap<String, String>,
}

impl Mapping {
    /// Read and check a mapping file.
    pub fn load(path: &Path) -> Result<Self, FileError> {
        let text = std::fs::read_to_string(path).map_err(|e| FileError::io(path, &e))?;
        Self::parse(path, &text)
    }

    /// Parse mapping text; `origin` names it in errors.
    pub fn parse(origin: &Path, text: &str) -> Result<Self, FileError> {
        let raw: Raw = toml::from_str(text).map_err(|e| toml_error(origin, text, &e))?;
        let mut scale = BTreeMap::new();
        for (k, v) in raw.scale {
            let f = v.get_ref().0;
            if !(f.is_finite() && f != 0.0) {
                return Err(FileError::at_span(
                    origin,
                    text,
                    Some(v.span()),
                    format!("scale of \"{k}\" must be finite and non-zero, got {f}"),
                ));
            }
            scale.insert(k, f);
        }
        Ok(Self { rename: raw.rename, scale, unit: raw.unit })
    }

    /// Every key the mapping mentions, for "matches no column" notes.
    pub fn keys(&self) -> impl Iterator<Item = &str> {
        self.rename.keys().chain(self.scale.keys()).chain(self.unit.keys()).map(String::as_str)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_all_tables() {
        let m = Mapping::parse(
            Path::new("m.toml"),
            "[rename]\n\"Torque L\" = \"C_Kistler_L\"\n[scale]\n\"Torque L\" = -1\n[unit]\nw = \"rad/s\"\n",
        )
        .unwrap();
        assert_eq!(m.rename["Torque L"], "C_Kistler_L");
        assert_eq!(m.scale["Torque L"], -1.0);
        assert_eq!(m.unit["w"], "rad/s");
    }

    #[test]
    fn the_example_file_parses() {
        let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/mapping.toml"));
        let m = Mapping::load(p).unwrap();
        assert_eq!(m.rename["Speed R"], "T_Kistler_R");
        assert_eq!(m.scale["Torque R"], -1.0);
        assert_eq!(m.unit["Speed L"], "rad/s");
    }

    #[test]
    fn errors_are_located() {
        let e = Mapping::parse(Path::new("m.toml"), "[scale]\nx = 0\n").unwrap_err();
        assert_eq!(e.to_string(), "m.toml:2:5: scale of \"x\" must be finite and non-zero, got 0");
        let e = Mapping::parse(Path::new("m.toml"), "[renames]\na = \"b\"\n").unwrap_err();
        assert!(e.to_string().starts_with("m.toml:1:"), "{e}");
        assert!(e.to_string().contains("renames"), "{e}");
    }
}
