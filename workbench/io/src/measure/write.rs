//! Writing a [`Measurement`] as the readers accept it: CSV (`time [s],Name [unit],...`,
//! decimal point, values in Rust's shortest round-trip form, so reading back gives the
//! same f64 bits) or MAT (see [`super::mat`]). Files are replaced atomically.

use std::io::{self, Write};
use std::path::Path;

use super::{mat, Measurement};
use crate::atomic::write_atomic;

/// Output format, from a file name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Csv,
    Mat,
}

impl Format {
    /// `.csv` or `.mat` (any case); anything else is `None`.
    pub fn of(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
        match ext.as_str() {
            "csv" => Some(Format::Csv),
            "mat" => Some(Format::Mat),
            _ => None,
        }
    }
}

/// Write the CSV form of `m`.
pub fn write_csv(w: &mut dyn Write, m: &Measurement) -> io::Result<()> {
    let mut line = String::from("time [s]");
    for s in &m.signals {
        if s.name.contains([',', '"', '\n', '\r']) || s.unit.contains([',', '"', '\n', '\r', ']']) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("channel \"{}\" [{}] cannot be a CSV header field", s.name, s.unit),
            ));
        }
        if s.values.len() != m.time_s.len() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("channel \"{}\" has {} samples, time has {}", s.name, s.values.len(), m.time_s.len()),
            ));
        }
        line.push(',');
        line.push_str(&s.name);
        if !s.unit.is_empty() {
            line.push_str(&format!(" [{}]", s.unit));
        }
    }
    line.push('\n');
    w.write_all(line.as_bytes())?;
    for (i, t) in m.time_s.iter().enumerate() {
        line.clear();
        use std::fmt::Write as _;
        let _ = write!(line, "{t}");
        for s in &m.signals {
            let _ = write!(line, ",{}", s.values[i]);
        }
        line.push('\n');
        w.write_all(line.as_bytes())?;
    }
    Ok(())
}

/// Save `m` to `path` in the format its extension names, atomically.
pub fn save(path: &Path, m: &Measurement) -> io::Result<()> {
    match Format::of(path) {
        Some(Format::Csv) => write_atomic(path, |w| write_csv(w, m)),
        Some(Format::Mat) => write_atomic(path, |w| mat::write(w, m)),
        None => Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{}: unknown format; use a .csv or .mat file name", path.display()),
        )),
    }
}
