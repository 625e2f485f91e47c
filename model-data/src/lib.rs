//! The formats of the model's data files (`model-core/data/`), parsed in one place.
//!
//! `model-core`'s `build.rs` compiles the files into flash tables and the workbench loads
//! altered or identified data directories at run time; both use this parser, so a file
//! one accepts the other accepts, with the same messages. Dependency-free: it is a
//! build-dependency of the target crate.
//!
//! [`effects`] is the effect-file format, shared the same way by the firmware's
//! `build.rs` (`$SIMROD_EFFECTS`) and the workbench (`--effects`).
//!
//! Errors carry the 1-based line (0 for the whole file) and what was expected; the
//! callers add the file name.

pub mod effects;

/// Most sets a profile may have (the PLC's limit, thesis 4.1).
pub const MAX_SETS: usize = 10;

/// A data-file error: line (1-based, 0 = the whole file) and message.
#[derive(Debug, Clone, PartialEq)]
pub struct Error {
    /// 1-based line, 0 for the whole file.
    pub line: usize,
    /// What is wrong and what was expected.
    pub msg: String,
}

fn err(line: usize, msg: impl Into<String>) -> Error {
    Error { line, msg: msg.into() }
}

/// A 1-D map: grid `x`, values `y`, and the text around them.
#[derive(Debug, Clone, PartialEq)]
pub struct Map1 {
    /// Comment lines before the header (each starting with `#`).
    pub comments: Vec<String>,
    /// The header line, e.g. `mapped_throttle [%],speed [rpm]`.
    pub header: String,
    /// Grid, strictly increasing.
    pub x: Vec<f32>,
    /// Values.
    pub y: Vec<f32>,
}

/// A 2-D map: column grid `x` (throttle set point), row grid `y` (load set point),
/// values row-major `z[iy * nx + ix]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Map2 {
    /// Comment lines before the header.
    pub comments: Vec<String>,
    /// First header field, e.g. `load_sp\throttle_sp`.
    pub corner: String,
    /// Column grid, strictly increasing.
    pub x: Vec<f32>,
    /// Row grid, strictly increasing.
    pub y: Vec<f32>,
    /// Values, row-major.
    pub z: Vec<f32>,
}

impl Map2 {
    /// Value at row `iy`, column `ix`.
    pub fn at(&self, ix: usize, iy: usize) -> f32 {
        self.z.get(iy * self.x.len() + ix).copied().unwrap_or(f32::NAN)
    }
}

/// One line of `parameters.toml`: kept verbatim unless a value is replaced.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamLine {
    /// Comment or blank line.
    Text(String),
    /// `key = value  # comment`.
    Entry {
        /// Key, e.g. `ident.accel_hs_fwd_s`.
        key: String,
        /// Value.
        value: f32,
        /// The comment, with its `#`, or empty.
        comment: String,
    },
}

/// What a profile set point does during its set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// `hold`.
    Hold,
    /// `interp`.
    Interpolate,
}

/// One row of a profile file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfileRow {
    /// Duration \[s\], > 0.
    pub duration_s: f32,
    /// Set points \[%\]: throttle, load L, load R, each in [-100, 100].
    pub set_points: [f32; 3],
    /// Throttle mode, load mode.
    pub modes: [Mode; 2],
}

/// Non-comment, non-empty lines with their 1-based numbers, and the leading comments.
fn data_lines(text: &str) -> (Vec<String>, Vec<(usize, String)>) {
    let mut comments = Vec::new();
    let mut lines = Vec::new();
    for (i, l) in text.lines().enumerate() {
        let t = l.trim();
        if t.is_empty() || t.starts_with('#') {
            if lines.is_empty() && t.starts_with('#') {
                comments.push(t.to_string());
            }
            continue;
        }
        lines.push((i + 1, t.to_string()));
    }
    (comments, lines)
}

fn num(line: usize, field: &str, what: &str) -> Result<f32, Error> {
    match field.trim().parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(err(line, format!("{what}: expected a finite number, found `{}`", field.trim()))),
    }
}

fn check_increasing(lines: &[usize], xs: &[f32], what: &str) -> Result<(), Error> {
    let first = lines.first().copied().unwrap_or(0);
    if xs.len() < 2 {
        return Err(err(first, format!("{what}: need at least 2 grid points")));
    }
    for (i, w) in xs.windows(2).enumerate() {
        if w[1] <= w[0] {
            let line = lines.get(i + 1).copied().unwrap_or(first);
            return Err(err(
                line,
                format!("{what}: grid must be strictly increasing ({} then {})", w[0], w[1]),
            ));
        }
    }
    Ok(())
}

fn empty() -> Error {
    err(0, "empty file (expected a header line and data rows)")
}

/// Parse a 1-D map (`x,y` rows under a header).
pub fn parse_map1(text: &str) -> Result<Map1, Error> {
    let (comments, lines) = data_lines(text);
    let Some((_, header)) = lines.first().cloned() else {
        return Err(empty());
    };
    let (mut xs, mut ys, mut at) = (Vec::new(), Vec::new(), Vec::new());
    for (ln, l) in lines.iter().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != 2 {
            return Err(err(*ln, format!("expected 2 columns (x,y), found {}", f.len())));
        }
        xs.push(num(*ln, f[0], "x")?);
        ys.push(num(*ln, f[1], "y")?);
        at.push(*ln);
    }
    check_increasing(&at, &xs, "x column")?;
    Ok(Map1 { comments, header, x: xs, y: ys })
}

/// Parse a 2-D map (header `corner,x1,x2,...`, rows `y,z1,z2,...`).
pub fn parse_map2(text: &str) -> Result<Map2, Error> {
    let (comments, lines) = data_lines(text);
    let Some((hl, header)) = lines.first().cloned() else {
        return Err(empty());
    };
    let mut hf = header.split(',');
    let corner = hf.next().unwrap_or("").trim().to_string();
    let xs = hf.map(|f| num(hl, f, "column grid")).collect::<Result<Vec<f32>, _>>()?;
    check_increasing(&[hl], &xs, "column grid (throttle set point)")?;
    let (mut ys, mut zs, mut at) = (Vec::new(), Vec::new(), Vec::new());
    for (ln, l) in lines.iter().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != xs.len() + 1 {
            return Err(err(*ln, format!("expected {} columns, found {}", xs.len() + 1, f.len())));
        }
        ys.push(num(*ln, f[0], "row grid")?);
        for v in &f[1..] {
            zs.push(num(*ln, v, "value")?);
        }
        at.push(*ln);
    }
    check_increasing(&at, &ys, "row grid (load set point)")?;
    Ok(Map2 { comments, corner, x: xs, y: ys, z: zs })
}

/// Parse `parameters.toml` (`name = number  # comment` lines); `known` says which keys
/// the model reads (the build script, which compiles the model, accepts every key).
pub fn parse_params(text: &str, known: &dyn Fn(&str) -> bool) -> Result<Vec<ParamLine>, Error> {
    let mut out = Vec::new();
    let mut seen: Vec<String> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let ln = i + 1;
        let (body, comment) = match raw.split_once('#') {
            Some((b, c)) => (b.trim(), format!("#{c}")),
            None => (raw.trim(), String::new()),
        };
        if body.is_empty() {
            out.push(ParamLine::Text(raw.to_string()));
            continue;
        }
        let Some((k, v)) = body.split_once('=') else {
            return Err(err(ln, "expected `name = number`"));
        };
        let key = k.trim();
        if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.') {
            return Err(err(ln, format!("bad parameter name `{key}`")));
        }
        if !known(key) {
            return Err(err(ln, format!("unknown parameter `{key}` (the model reads no such key)")));
        }
        let norm = const_name(key);
        if seen.contains(&norm) {
            return Err(err(ln, format!("parameter `{key}` given twice")));
        }
        seen.push(norm);
        let value = num(ln, v, key)?;
        out.push(ParamLine::Entry { key: key.to_string(), value, comment });
    }
    Ok(out)
}

/// The constant a parameter key compiles to: `ident.accel_hs_fwd_s` -> `IDENT_ACCEL_HS_FWD_S`.
pub fn const_name(key: &str) -> String {
    key.replace('.', "_").to_ascii_uppercase()
}

/// Parse a profile file (header, then `duration_s,throttle,load_l,load_r,mode,mode` rows).
pub fn parse_profile(text: &str) -> Result<Vec<ProfileRow>, Error> {
    let (_, lines) = data_lines(text);
    let mut rows = Vec::new();
    for (ln, l) in lines.iter().skip(1) {
        let f: Vec<&str> = l.split(',').map(str::trim).collect();
        if f.len() != 6 {
            return Err(err(*ln, format!("expected 6 columns, found {}", f.len())));
        }
        let duration_s = num(*ln, f[0], "duration_s")?;
        if duration_s <= 0.0 {
            return Err(err(*ln, "duration_s must be > 0"));
        }
        let mut set_points = [0.0f32; 3];
        for (i, s) in set_points.iter_mut().enumerate() {
            *s = num(*ln, f[i + 1], "set point")?;
            if !(-100.0..=100.0).contains(s) {
                return Err(err(*ln, "set points must lie in [-100, 100] %"));
            }
        }
        let mode = |m: &str| match m {
            "hold" => Ok(Mode::Hold),
            "interp" => Ok(Mode::Interpolate),
            _ => Err(err(*ln, format!("mode must be `hold` or `interp`, found `{m}`"))),
        };
        rows.push(ProfileRow { duration_s, set_points, modes: [mode(f[4])?, mode(f[5])?] });
    }
    if rows.is_empty() || rows.len() > MAX_SETS {
        return Err(err(0, format!("a profile has 1 to {MAX_SETS} sets, found {}", rows.len())));
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_the_line() {
        assert_eq!(parse_map1("# c\nx,y\n0,1\n0,2\n").unwrap_err().line, 4);
        assert_eq!(parse_map1("x,y\n0,1\n1\n").unwrap_err().line, 3);
        assert_eq!(parse_map2("c,0,1\n0,1\n").unwrap_err().line, 2);
        assert_eq!(parse_params("a = 1\nb = x\n", &|_| true).unwrap_err().line, 2);
        assert_eq!(parse_params("a = 1\na = 2\n", &|_| true).unwrap_err().line, 2);
        assert_eq!(parse_profile("h\n1,0,0,0,hold,hold\n1,101,0,0,hold,hold\n").unwrap_err().line, 3);
        assert_eq!(parse_profile("h\n").unwrap_err().line, 0);
        assert_eq!(parse_map1("").unwrap_err().line, 0);
    }

    #[test]
    fn maps_keep_their_comments_and_values() {
        let m = parse_map2("# a\n# b\nc,0,1\n-1,1,2\n1,3,4\n").unwrap();
        assert_eq!(m.comments, vec!["# a", "# b"]);
        assert_eq!((m.at(1, 0), m.at(0, 1)), (2.0, 3.0));
        let p = parse_params("# head\nk = 2.5 # unit\n", &|_| true).unwrap();
        assert_eq!(p[1], ParamLine::Entry { key: "k".into(), value: 2.5, comment: "# unit".into() });
    }
}
