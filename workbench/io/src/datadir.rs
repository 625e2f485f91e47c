//! Model data directories at run time: `parameters.toml`, the CSV maps and (optionally)
//! `profiles/`, in exactly the format `model-core/build.rs` compiles into flash.
//!
//! Why: an altered or identified model must run (`simrod simulate/bench/compare
//! --data-dir DIR`) without rebuilding, and `simrod identify` must write files that
//! both this loader and `build.rs` accept. The parsing rules are a port of `build.rs`
//! (comment and blank lines skipped, first data line is the header, finite numbers,
//! strictly increasing grids, rectangular 2-D tables, profile limits); every error names
//! `file:line`. Loading is stricter in one way: a parameter key the model does not read
//! is an error, and every key of the built-in file must be present (a build with a
//! missing key fails too).
//!
//! The built-in data are embedded as text (`include_str!`) so that [`ModelData::builtin`]
//! is the same files parsed by the same code; a test checks it against the flash
//! statics bit for bit.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use model_core::table::{Table1, Table2};
use model_core::{CouplingStiffness, Maps, Params, ProfileSet, RateSet, SetMode};

use crate::atomic::write_atomic;
use crate::error::FileError;

/// 1-D map files, in `build.rs` order.
pub const FILES_1D: [&str; 5] = [
    "throttle_input_map.csv",
    "speed_map_fwd.csv",
    "speed_map_rev.csv",
    "axle_friction_L.csv",
    "axle_friction_R.csv",
];
/// 2-D map files, in `build.rs` order.
pub const FILES_2D: [&str; 7] = [
    "load_torque_L.csv",
    "load_torque_R.csv",
    "load_current_L.csv",
    "load_current_R.csv",
    "load_power_L.csv",
    "load_power_R.csv",
    "sut_inverter_power.csv",
];
/// The scalar parameter file.
pub const PARAMS_FILE: &str = "parameters.toml";
/// Profiles `build.rs` compiles (optional here).
pub const PROFILES: [&str; 5] = ["TP07", "TP11", "TP12", "TP13", "TP14"];

macro_rules! builtin_text {
    ($f:literal) => {
        ($f, include_str!(concat!("../../../model-core/data/", $f)))
    };
}

/// The built-in data files, as text.
const BUILTIN: [(&str, &str); 13] = [
    builtin_text!("throttle_input_map.csv"),
    builtin_text!("speed_map_fwd.csv"),
    builtin_text!("speed_map_rev.csv"),
    builtin_text!("axle_friction_L.csv"),
    builtin_text!("axle_friction_R.csv"),
    builtin_text!("load_torque_L.csv"),
    builtin_text!("load_torque_R.csv"),
    builtin_text!("load_current_L.csv"),
    builtin_text!("load_current_R.csv"),
    builtin_text!("load_power_L.csv"),
    builtin_text!("load_power_R.csv"),
    builtin_text!("sut_inverter_power.csv"),
    builtin_text!("parameters.toml"),
];
const BUILTIN_PROFILES: [(&str, &str); 5] = [
    ("TP07", include_str!("../../../model-core/data/profiles/TP07.csv")),
    ("TP11", include_str!("../../../model-core/data/profiles/TP11.csv")),
    ("TP12", include_str!("../../../model-core/data/profiles/TP12.csv")),
    ("TP13", include_str!("../../../model-core/data/profiles/TP13.csv")),
    ("TP14", include_str!("../../../model-core/data/profiles/TP14.csv")),
];

pub use model_data::{Map1, Map2, ParamLine};

/// A profile file: its sets and its text (written back unchanged).
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileData {
    pub name: String,
    pub sets: Vec<ProfileSet>,
    pub text: String,
}

/// Everything a model data directory holds.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelData {
    /// Where it was loaded from (`None`: built in).
    pub source: Option<PathBuf>,
    pub throttle_input: Map1,
    pub speed_fwd: Map1,
    pub speed_rev: Map1,
    /// L, R.
    pub friction: [Map1; 2],
    pub load_torque: [Map2; 2],
    pub load_current: [Map2; 2],
    pub load_power: [Map2; 2],
    pub sut_power: Map2,
    pub params: Vec<ParamLine>,
    /// Profiles found under `profiles/` (all five when built in).
    pub profiles: Vec<ProfileData>,
}

/// A shared-parser error, placed in `path`.
fn at(path: &Path, e: model_data::Error) -> FileError {
    if e.line == 0 {
        FileError::whole(path, e.msg)
    } else {
        FileError::at(path, e.line, 1, e.msg)
    }
}

/// Parse a 1-D map (`x,y` rows under a header).
pub fn parse_map1(path: &Path, text: &str) -> Result<Map1, FileError> {
    model_data::parse_map1(text).map_err(|e| at(path, e))
}

/// Parse a 2-D map (header `corner,x1,x2,...`, rows `y,z1,z2,...`).
pub fn parse_map2(path: &Path, text: &str) -> Result<Map2, FileError> {
    model_data::parse_map2(text).map_err(|e| at(path, e))
}

/// The keys `Params::set` accepts (tried on a scratch value).
pub(crate) fn known_key(key: &str) -> bool {
    let mut p = Params::default();
    p.set(key, 1.0, RateSet::Identified, CouplingStiffness::Identified).is_ok()
}

/// Parse `parameters.toml` (`name = number  # comment` lines); unknown keys are errors.
pub fn parse_params(path: &Path, text: &str) -> Result<Vec<ParamLine>, FileError> {
    model_data::parse_params(text, &known_key).map_err(|e| at(path, e))
}

/// Parse a profile file (header, then `duration_s,throttle,load_l,load_r,mode,mode`).
pub fn parse_profile(path: &Path, name: &str, text: &str) -> Result<ProfileData, FileError> {
    let mode = |m: model_data::Mode| match m {
        model_data::Mode::Hold => SetMode::Hold,
        model_data::Mode::Interpolate => SetMode::Interpolate,
    };
    let sets = model_data::parse_profile(text)
        .map_err(|e| at(path, e))?
        .into_iter()
        .map(|r| ProfileSet {
            duration_s: r.duration_s,
            throttle_pct: r.set_points[0],
            load_l_pct: r.set_points[1],
            load_r_pct: r.set_points[2],
            throttle_mode: mode(r.modes[0]),
            load_mode: mode(r.modes[1]),
        })
        .collect();
    Ok(ProfileData { name: name.to_string(), sets, text: text.to_string() })
}

/// Reads a data file by name: its path (for messages) and text.
type Reader<'a, T> = dyn Fn(&str) -> Result<(PathBuf, T), FileError> + 'a;

/// Where a model cannot be built from the data (only after in-memory edits: loaded
/// data are checked on loading).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {msg}")]
pub struct DataError {
    pub file: String,
    pub msg: String,
}

impl ModelData {
    /// The data compiled into model-core (the same files, parsed here).
    pub fn builtin() -> Result<Self, FileError> {
        let get = |f: &str| -> (PathBuf, &'static str) {
            let text = BUILTIN.iter().find(|(n, _)| *n == f).map_or("", |(_, t)| *t);
            (Path::new("model-core/data").join(f), text)
        };
        let profiles = BUILTIN_PROFILES
            .iter()
            .map(|(n, t)| {
                parse_profile(&Path::new("model-core/data/profiles").join(format!("{n}.csv")), n, t)
            })
            .collect::<Result<Vec<_>, _>>()?;
        Self::from_texts(None, &|f| Ok(get(f)), profiles)
    }

    /// Load a data directory; every problem is a [`FileError`] naming file and line.
    pub fn load(dir: &Path) -> Result<Self, FileError> {
        if !dir.is_dir() {
            return Err(FileError::whole(
                dir,
                "not a directory (expected a model data directory like model-core/data)",
            ));
        }
        let read = |f: &str| -> Result<(PathBuf, String), FileError> {
            let p = dir.join(f);
            let text = std::fs::read_to_string(&p).map_err(|e| FileError::io(&p, &e))?;
            Ok((p, text))
        };
        let mut profiles = Vec::new();
        for name in PROFILES {
            let p = dir.join("profiles").join(format!("{name}.csv"));
            if p.is_file() {
                let text = std::fs::read_to_string(&p).map_err(|e| FileError::io(&p, &e))?;
                profiles.push(parse_profile(&p, name, &text)?);
            }
        }
        Self::from_texts(Some(dir.to_path_buf()), &read, profiles)
    }

    fn from_texts<T: AsRef<str>>(
        source: Option<PathBuf>,
        read: &Reader<'_, T>,
        profiles: Vec<ProfileData>,
    ) -> Result<Self, FileError> {
        let m1 = |i: usize| -> Result<Map1, FileError> {
            let (p, t) = read(FILES_1D[i])?;
            parse_map1(&p, t.as_ref())
        };
        let m2 = |i: usize| -> Result<Map2, FileError> {
            let (p, t) = read(FILES_2D[i])?;
            parse_map2(&p, t.as_ref())
        };
        let (pp, pt) = read(PARAMS_FILE)?;
        let params = parse_params(&pp, pt.as_ref())?;
        let d = Self {
            source,
            throttle_input: m1(0)?,
            speed_fwd: m1(1)?,
            speed_rev: m1(2)?,
            friction: [m1(3)?, m1(4)?],
            load_torque: [m2(0)?, m2(1)?],
            load_current: [m2(2)?, m2(3)?],
            load_power: [m2(4)?, m2(5)?],
            sut_power: m2(6)?,
            params,
            profiles,
        };
        let missing = d.missing_keys();
        if !missing.is_empty() {
            return Err(FileError::whole(
                &pp,
                format!(
                    "missing parameter(s): {} (every key of model-core/data/parameters.toml is needed)",
                    missing.join(", ")
                ),
            ));
        }
        Ok(d)
    }

    /// Keys of the built-in parameter file that this data set lacks.
    fn missing_keys(&self) -> Vec<String> {
        let Some((_, text)) = BUILTIN.iter().find(|(n, _)| *n == PARAMS_FILE) else {
            return Vec::new();
        };
        let builtin = parse_params(Path::new(PARAMS_FILE), text).unwrap_or_default();
        builtin
            .iter()
            .filter_map(|l| match l {
                ParamLine::Entry { key, .. } if self.param(key).is_none() => Some(key.clone()),
                _ => None,
            })
            .collect()
    }

    /// The value of parameter `key`, if the file has it.
    pub fn param(&self, key: &str) -> Option<f32> {
        self.params.iter().find_map(|l| match l {
            ParamLine::Entry { key: k, value, .. } if k == key => Some(*value),
            _ => None,
        })
    }

    /// Replace a parameter's value and its comment; false if the key is not in the file.
    pub fn set_param(&mut self, key: &str, v: f32, comment: &str) -> bool {
        for l in &mut self.params {
            if let ParamLine::Entry { key: k, value, comment: c } = l {
                if k == key {
                    *value = v;
                    *c = format!("# {}", comment.trim_start_matches('#').trim());
                    return true;
                }
            }
        }
        false
    }

    /// The scalar parameters with the given rate set and coupling stiffness, exactly as
    /// `build.rs` + `Params::thesis` would give them for these files.
    pub fn params(&self, rates: RateSet, coupling: CouplingStiffness) -> Params {
        let mut p = Params::thesis(rates, coupling);
        for l in &self.params {
            if let ParamLine::Entry { key, value, .. } = l {
                // Keys were checked on loading; an unknown one cannot occur here.
                let _ = p.set(key, *value, rates, coupling);
            }
        }
        p
    }

    /// The model's tables, borrowing this data.
    pub fn maps(&self) -> Result<Maps<'_>, DataError> {
        fn t1<'a>(m: &'a Map1, f: &str) -> Result<Table1<'a>, DataError> {
            Table1::new(&m.x, &m.y).map_err(|e| DataError { file: f.to_string(), msg: format!("{e:?}") })
        }
        fn t2<'a>(m: &'a Map2, f: &str) -> Result<Table2<'a>, DataError> {
            Table2::new(&m.x, &m.y, &m.z)
                .map_err(|e| DataError { file: f.to_string(), msg: format!("{e:?}") })
        }
        Ok(Maps {
            throttle_input: t1(&self.throttle_input, FILES_1D[0])?,
            speed_fwd: t1(&self.speed_fwd, FILES_1D[1])?,
            speed_rev: t1(&self.speed_rev, FILES_1D[2])?,
            friction: [t1(&self.friction[0], FILES_1D[3])?, t1(&self.friction[1], FILES_1D[4])?],
            load_torque: [t2(&self.load_torque[0], FILES_2D[0])?, t2(&self.load_torque[1], FILES_2D[1])?],
            load_current: [t2(&self.load_current[0], FILES_2D[2])?, t2(&self.load_current[1], FILES_2D[3])?],
            load_power: [t2(&self.load_power[0], FILES_2D[4])?, t2(&self.load_power[1], FILES_2D[5])?],
            sut_power: t2(&self.sut_power, FILES_2D[6])?,
        })
    }

    /// The sets of profile `name` from `profiles/`, if this data set has it.
    pub fn profile(&self, name: &str) -> Option<&[ProfileSet]> {
        self.profiles.iter().find(|p| p.name.eq_ignore_ascii_case(name)).map(|p| p.sets.as_slice())
    }

    /// The 1-D maps with their file names.
    pub fn maps_1d(&self) -> [(&'static str, &Map1); 5] {
        [
            (FILES_1D[0], &self.throttle_input),
            (FILES_1D[1], &self.speed_fwd),
            (FILES_1D[2], &self.speed_rev),
            (FILES_1D[3], &self.friction[0]),
            (FILES_1D[4], &self.friction[1]),
        ]
    }

    /// Every map mutably, the 1-D ones in [`FILES_1D`] order and the 2-D ones in
    /// [`FILES_2D`] order.
    pub fn maps_mut(&mut self) -> ([&mut Map1; 5], [&mut Map2; 7]) {
        let [fl, fr] = &mut self.friction;
        let [tl, tr] = &mut self.load_torque;
        let [cl, cr] = &mut self.load_current;
        let [pl, pr] = &mut self.load_power;
        (
            [&mut self.throttle_input, &mut self.speed_fwd, &mut self.speed_rev, fl, fr],
            [tl, tr, cl, cr, pl, pr, &mut self.sut_power],
        )
    }

    /// Every map's values (`y` of a 1-D map, `z` of a 2-D one), in [`FILES_1D`] then
    /// [`FILES_2D`] order.
    pub fn map_values(&self) -> Vec<&[f32]> {
        let ones = self.maps_1d().into_iter().map(|(_, m)| m.y.as_slice());
        ones.chain(self.maps_2d().into_iter().map(|(_, m)| m.z.as_slice())).collect()
    }

    /// The 2-D maps with their file names.
    pub fn maps_2d(&self) -> [(&'static str, &Map2); 7] {
        [
            (FILES_2D[0], &self.load_torque[0]),
            (FILES_2D[1], &self.load_torque[1]),
            (FILES_2D[2], &self.load_current[0]),
            (FILES_2D[3], &self.load_current[1]),
            (FILES_2D[4], &self.load_power[0]),
            (FILES_2D[5], &self.load_power[1]),
            (FILES_2D[6], &self.sut_power),
        ]
    }

    /// Write every file into `dir` (created if missing), each atomically; profiles go
    /// to `dir/profiles/`. The result loads here and compiles with `build.rs`.
    pub fn write(&self, dir: &Path) -> io::Result<Vec<PathBuf>> {
        // Refuse to write what could not be read back.
        self.maps().map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e.to_string()))?;
        std::fs::create_dir_all(dir)?;
        let mut files = Vec::new();
        let mut put = |p: PathBuf, f: &dyn Fn(&mut dyn Write) -> io::Result<()>| -> io::Result<()> {
            write_atomic(&p, |w| f(w))?;
            files.push(p);
            Ok(())
        };
        for (f, m) in self.maps_1d() {
            put(dir.join(f), &|w| write_map1(w, m))?;
        }
        for (f, m) in self.maps_2d() {
            put(dir.join(f), &|w| write_map2(w, m))?;
        }
        put(dir.join(PARAMS_FILE), &|w| write_params(w, &self.params))?;
        if !self.profiles.is_empty() {
            let pd = dir.join("profiles");
            std::fs::create_dir_all(&pd)?;
            for p in &self.profiles {
                put(pd.join(format!("{}.csv", p.name)), &|w| w.write_all(p.text.as_bytes()))?;
            }
        }
        Ok(files)
    }
}

/// A value as the files hold it: the shortest decimal that reads back to the same f32.
pub fn fmt_f32(v: f32) -> String {
    if v == 0.0 {
        "0".into()
    } else {
        format!("{v}")
    }
}

fn write_comments(w: &mut dyn Write, comments: &[String]) -> io::Result<()> {
    for c in comments {
        let c = c.trim();
        if c.starts_with('#') {
            writeln!(w, "{c}")?;
        } else {
            writeln!(w, "# {c}")?;
        }
    }
    Ok(())
}

/// Write a 1-D map in the `build.rs` format.
pub fn write_map1(w: &mut dyn Write, m: &Map1) -> io::Result<()> {
    write_comments(w, &m.comments)?;
    writeln!(w, "{}", m.header)?;
    for (x, y) in m.x.iter().zip(&m.y) {
        writeln!(w, "{},{}", fmt_f32(*x), fmt_f32(*y))?;
    }
    Ok(())
}

/// Write a 2-D map in the `build.rs` format.
pub fn write_map2(w: &mut dyn Write, m: &Map2) -> io::Result<()> {
    write_comments(w, &m.comments)?;
    let head: Vec<String> = m.x.iter().map(|v| fmt_f32(*v)).collect();
    writeln!(w, "{},{}", m.corner, head.join(","))?;
    let nx = m.x.len();
    for (iy, y) in m.y.iter().enumerate() {
        let row: Vec<String> = (0..nx).map(|ix| fmt_f32(m.at(ix, iy))).collect();
        writeln!(w, "{},{}", fmt_f32(*y), row.join(","))?;
    }
    Ok(())
}

fn write_params(w: &mut dyn Write, lines: &[ParamLine]) -> io::Result<()> {
    for l in lines {
        match l {
            ParamLine::Text(t) => writeln!(w, "{t}")?,
            ParamLine::Entry { key, value, comment } => {
                let entry = format!("{key} = {}", fmt_f32(*value));
                if comment.is_empty() {
                    writeln!(w, "{entry}")?;
                } else {
                    writeln!(w, "{entry:<34} {comment}")?;
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {

    #[test]
    fn the_file_format_and_the_model_agree_on_the_set_limit() {
        assert_eq!(model_data::MAX_SETS, model_core::profile::MAX_SETS);
    }

    use super::*;
    use model_core::{Builtin, Config, Model, Profile, Simulation};

    fn model_core_data() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../model-core/data")
    }

    fn bits(v: &[f32]) -> Vec<u32> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    fn same_maps(a: &Maps<'_>, b: &Maps<'_>) {
        fn ones<'a>(m: &Maps<'a>) -> Vec<Table1<'a>> {
            let mut v = vec![m.throttle_input, m.speed_fwd, m.speed_rev];
            v.extend(m.friction);
            v
        }
        for (x, y) in ones(a).iter().zip(ones(b).iter()) {
            assert_eq!(bits(x.x()), bits(y.x()));
            assert_eq!(bits(x.y()), bits(y.y()));
        }
        for (x, y) in a.tables_2d().iter().zip(b.tables_2d().iter()) {
            assert_eq!(bits(x.x()), bits(y.x()));
            assert_eq!(bits(x.y()), bits(y.y()));
            assert_eq!(bits(x.z()), bits(y.z()));
        }
    }

    #[test]
    fn datadir_model_core_data_is_the_builtin_model_bit_for_bit() {
        let d = ModelData::load(&model_core_data()).unwrap();
        same_maps(&d.maps().unwrap(), &Maps::builtin());
        for rates in [RateSet::Programmed, RateSet::Identified] {
            for c in [CouplingStiffness::Identified, CouplingStiffness::Datasheet] {
                let (a, b) = (d.params(rates, c), Params::thesis(rates, c));
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "{rates:?} {c:?}");
            }
        }
        for b in Builtin::ALL {
            assert_eq!(d.profile(b.name()), Some(b.sets()), "{}", b.name());
        }
        assert_eq!(ModelData::builtin().unwrap(), ModelData { source: None, ..d.clone() });

        // A run on the loaded data equals the built-in run, every channel, every step.
        let cfg = Config {
            params: d.params(RateSet::Identified, CouplingStiffness::Identified),
            ..Config::default()
        };
        let p = Profile::builtin(Builtin::TP07, 1.0, 1.0).unwrap();
        let a = Simulation::from_model(Model::with_maps(&cfg, d.maps().unwrap()).unwrap(), p.clone(), 24.0);
        let b = Simulation::new(&Config::default(), p, 24.0).unwrap();
        let mut n = 0;
        for (x, y) in a.zip(b) {
            assert_eq!(bits(&x.values), bits(&y.values), "t = {} µs", x.t_us);
            n += 1;
        }
        assert_eq!(n, 60_000);
    }

    #[test]
    fn datadir_written_files_load_back_identically() {
        let d = ModelData::builtin().unwrap();
        let tmp = tempfile::tempdir().unwrap();
        let mut e = d.clone();
        e.sut_power.z[3] = 1234.5678;
        e.friction[0].y[5] = -7.000001;
        assert!(e.set_param("connector_resistance", 0.025, "[ohm] test"));
        e.write(tmp.path()).unwrap();
        let back = ModelData::load(tmp.path()).unwrap();
        assert_eq!(ModelData { source: None, ..back.clone() }, e);
        assert_eq!(back.param("connector_resistance"), Some(0.025));
        let text = std::fs::read_to_string(tmp.path().join(PARAMS_FILE)).unwrap();
        assert!(text.contains("connector_resistance = 0.025"), "{text}");
        assert!(text.contains("# [ohm] test"));
        assert_eq!(
            back.params(RateSet::Identified, CouplingStiffness::Identified).connector_resistance,
            0.025
        );
    }

    fn load_err(dir: &Path) -> String {
        match ModelData::load(dir) {
            Ok(_) => panic!("{} loaded but should not", dir.display()),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn datadir_errors_name_file_and_line() {
        let tmp = tempfile::tempdir().unwrap();
        ModelData::builtin().unwrap().write(tmp.path()).unwrap();
        let f = tmp.path().join("speed_map_fwd.csv");
        let good = std::fs::read_to_string(&f).unwrap();
        std::fs::write(&f, good.replace("\n20,680\n", "\n20,abc\n")).unwrap();
        let e = load_err(tmp.path());
        assert!(e.contains("speed_map_fwd.csv:8:") && e.contains("`abc`"), "{e}");
        std::fs::write(&f, good.replace("\n20,680\n", "\n9,680\n")).unwrap();
        let e = load_err(tmp.path());
        assert!(e.contains("speed_map_fwd.csv:8:") && e.contains("strictly increasing"), "{e}");
        std::fs::write(&f, &good).unwrap();

        let f = tmp.path().join("load_power_R.csv");
        let good = std::fs::read_to_string(&f).unwrap();
        let bad: String = good
            .lines()
            .map(|l| if l.starts_with("40,") { "40,1,2\n".to_string() } else { format!("{l}\n") })
            .collect();
        std::fs::write(&f, bad).unwrap();
        let e = load_err(tmp.path());
        assert!(e.contains("load_power_R.csv:") && e.contains("expected 20 columns, found 3"), "{e}");
        std::fs::write(&f, &good).unwrap();

        let f = tmp.path().join(PARAMS_FILE);
        let good = std::fs::read_to_string(&f).unwrap();
        std::fs::write(&f, format!("{good}pid_kq = 3\n")).unwrap();
        let e = load_err(tmp.path());
        assert!(e.contains("unknown parameter `pid_kq`"), "{e}");
        let no_kd: String =
            good.lines().filter(|l| !l.starts_with("pid_kd ")).map(|l| format!("{l}\n")).collect();
        std::fs::write(&f, no_kd).unwrap();
        let e = load_err(tmp.path());
        assert!(e.contains("missing parameter(s): pid_kd"), "{e}");
        std::fs::write(&f, format!("{good}pid_kd = 1\n")).unwrap();
        let e = load_err(tmp.path());
        assert!(e.contains("given twice"), "{e}");
        std::fs::write(&f, &good).unwrap();

        std::fs::write(tmp.path().join("profiles/TP12.csv"), "h\n1,0,0,0,hold,maybe\n").unwrap();
        let e = load_err(tmp.path());
        assert!(e.contains("TP12.csv:2:") && e.contains("`maybe`"), "{e}");
        assert!(ModelData::load(&tmp.path().join("nope")).is_err());
    }
}
