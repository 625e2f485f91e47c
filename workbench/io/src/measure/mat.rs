//! MATLAB Level 5 MAT files (`save -v6`/`-v7`, compressed or not): reading through the
//! `matfile` crate, and a small writer for the virtual bench.
//!
//! Convention (MATLAB names cannot hold spaces or dots):
//! - one real numeric vector per channel (double preferred; any numeric class is read
//!   as f64), all the length of `time`;
//! - the variable name is the bench name with every character other than `A-Z a-z 0-9`
//!   replaced by `_` (`I_XLML 2.2` -> `I_XLML_2_2`, `SuT Throttle` -> `SuT_Throttle`);
//!   names of known channels (`model_core::Channel::ALL`, the set points) are mapped
//!   back, other variables keep their MATLAB name;
//! - a vector `time` (or `t`) [s];
//! - optional char row vectors `<var>_unit`, e.g. `C_Kistler_L_unit = 'N m'`
//!   (`time_unit` defaults to `s`);
//! - scalars (1x1) are taken as metadata and ignored; other matrices, complex data and a
//!   vector of the wrong length are errors. v7.3 files (HDF5) are refused with a hint.
//!
//! `matfile` skips char arrays, so the units are found by a short walk over the file's
//! elements here ([`char_vars`]); compressed elements are inflated with `libflate`,
//! the same inflater `matfile` uses.

use std::collections::BTreeMap;
use std::io::{self, Read, Write};
use std::path::Path;

use model_core::Channel;

use super::table::{RawColumn, RawTable, Rows};
use super::{is_time, Measurement, SETPOINT_LOAD_L, SETPOINT_LOAD_R, SETPOINT_THROTTLE};
use crate::error::FileError;

/// MATLAB's limit on variable name length.
const MAX_NAME: usize = 63;

/// The MATLAB variable name for a channel: non-alphanumerics become `_`; a name that
/// does not start with a letter gets an `x` in front.
pub fn sanitize(name: &str) -> String {
    let mut s: String = name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    if !s.starts_with(|c: char| c.is_ascii_alphabetic()) {
        s.insert(0, 'x');
    }
    s
}

/// Bench name for a MATLAB variable name, if it stands for a known channel.
fn bench_name(var: &str) -> Option<&'static str> {
    Channel::ALL
        .iter()
        .map(|c| c.name())
        .chain([SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R])
        .find(|n| sanitize(n) == var)
}

fn to_f64(d: &matfile::NumericData) -> Option<Vec<f64>> {
    use matfile::NumericData as N;
    fn conv<T: Copy + Into<f64>>(r: &[T], i: &Option<Vec<T>>) -> Option<Vec<f64>> {
        i.is_none().then(|| r.iter().map(|&x| x.into()).collect())
    }
    match d {
        N::Double { real, imag } => conv(real, imag),
        N::Single { real, imag } => conv(real, imag),
        N::Int8 { real, imag } => conv(real, imag),
        N::UInt8 { real, imag } => conv(real, imag),
        N::Int16 { real, imag } => conv(real, imag),
        N::UInt16 { real, imag } => conv(real, imag),
        N::Int32 { real, imag } => conv(real, imag),
        N::UInt32 { real, imag } => conv(real, imag),
        // 64-bit integers above 2^53 lose digits; sample data never gets there.
        N::Int64 { real, imag } => imag.is_none().then(|| real.iter().map(|&x| x as f64).collect()),
        N::UInt64 { real, imag } => imag.is_none().then(|| real.iter().map(|&x| x as f64).collect()),
    }
}

/// Parse MAT bytes; `origin` names the file in errors.
pub(crate) fn parse(origin: &Path, bytes: &[u8]) -> Result<RawTable, FileError> {
    let bad = |m: String| FileError::whole(origin, m);
    if bytes.is_empty() {
        return Err(bad("empty file".into()));
    }
    if bytes.len() < 128 || !bytes.starts_with(b"MATLAB") {
        return Err(bad("not a MAT file (no MATLAB header)".into()));
    }
    let version = match &bytes[126..128] {
        b"IM" => u16::from_le_bytes([bytes[124], bytes[125]]),
        _ => u16::from_be_bytes([bytes[124], bytes[125]]),
    };
    if version == 0x0200 {
        return Err(bad("MAT v7.3 (HDF5) files are not supported; save with -v7 (or -v6)".into()));
    }
    // The structure check first: `matfile` prints to stdout about unexpected elements.
    let units = char_vars(bytes).map_err(|e| bad(format!("not a readable MAT v5/v7 file: {e}")))?;
    let mat =
        matfile::MatFile::parse(bytes).map_err(|e| bad(format!("not a readable MAT v5/v7 file: {e}")))?;
    let mut time: Option<RawColumn> = None;
    let mut cols = Vec::new();
    for a in mat.arrays() {
        let var = a.name();
        let size = a.size();
        let n: usize = size.iter().product();
        let vector = size.iter().filter(|&&d| d != 1).count() <= 1;
        if n == 1 || var.is_empty() {
            continue; // metadata scalar, or MATLAB's unnamed subsystem data (objects)
        }
        if !vector {
            let dims: Vec<String> = size.iter().map(usize::to_string).collect();
            return Err(bad(format!(
                "variable `{var}` is a {} array; channels must be vectors",
                dims.join("x")
            )));
        }
        let values = to_f64(a.data())
            .ok_or_else(|| bad(format!("variable `{var}` is complex; channels must be real")))?;
        let name = bench_name(var).map_or_else(|| var.to_owned(), str::to_owned);
        let unit = units.get(&format!("{var}_unit")).cloned();
        let col = RawColumn { alias: (name != var).then(|| var.to_owned()), name, unit, values };
        if is_time(var, col.unit.as_deref()) {
            if time.is_some() {
                return Err(bad(format!("more than one time vector (`{var}`)")));
            }
            time = Some(col);
        } else {
            cols.push(col);
        }
    }
    let time = time.ok_or_else(|| bad("no time vector (a variable named `time` or `t`)".into()))?;
    for c in &cols {
        if c.values.len() != time.values.len() {
            let var = c.alias.as_deref().unwrap_or(&c.name);
            return Err(bad(format!(
                "channel \"{}\" (variable `{var}`) has {} samples, time has {}",
                c.name,
                c.values.len(),
                time.values.len()
            )));
        }
    }
    Ok(RawTable { source: origin.to_path_buf(), time, columns: cols, rows: Rows::Samples })
}

/// Little or big endian reads, as the header says.
#[derive(Clone, Copy)]
struct Endian(bool);

impl Endian {
    fn u32(self, b: &[u8], at: usize) -> Option<u32> {
        let a: [u8; 4] = b.get(at..at + 4)?.try_into().ok()?;
        Some(if self.0 { u32::from_le_bytes(a) } else { u32::from_be_bytes(a) })
    }
}

/// Next sub-element of a matrix at `*p` (normal or small format): `(type, data)`.
fn sub<'a>(e: Endian, b: &'a [u8], p: &mut usize) -> Option<(u32, &'a [u8])> {
    let first = e.u32(b, *p)?;
    if first >> 16 != 0 {
        let size = (first >> 16) as usize;
        let data = b.get(*p + 4..*p + 4 + size.min(4))?;
        *p += 8;
        return Some((first & 0xffff, data));
    }
    let size = e.u32(b, *p + 4)? as usize;
    let data = b.get(*p + 8..*p + 8 + size)?;
    *p += 8 + size.div_ceil(8) * 8;
    Some((first, data))
}

/// The char row vectors of a MAT file, by name (multi-row char arrays are skipped).
/// Also checks the element structure: only miMATRIX and miCOMPRESSED at the top level.
pub fn char_vars(bytes: &[u8]) -> Result<BTreeMap<String, String>, String> {
    let e = Endian(bytes.get(126..128) == Some(b"IM"));
    let mut out = BTreeMap::new();
    let mut p = 128;
    while p + 8 <= bytes.len() {
        let ty = e.u32(bytes, p).ok_or("truncated element")?;
        let size = e.u32(bytes, p + 4).ok_or("truncated element")? as usize;
        let data = bytes.get(p + 8..p + 8 + size).ok_or("element runs past the end of the file")?;
        match ty {
            14 => matrix_char(e, data, &mut out),
            15 => {
                let mut inflated = Vec::new();
                libflate::zlib::Decoder::new(data)
                    .and_then(|mut d| d.read_to_end(&mut inflated))
                    .map_err(|err| format!("corrupt compressed element at byte {p}: {err}"))?;
                let ity = e.u32(&inflated, 0).unwrap_or(0);
                let isz = e.u32(&inflated, 4).unwrap_or(0) as usize;
                match (ity, inflated.get(8..8 + isz)) {
                    (14, Some(d)) => matrix_char(e, d, &mut out),
                    _ => return Err(format!("corrupt compressed element at byte {p}")),
                }
            }
            // Checked here so that `matfile` never meets (and prints about) other types.
            _ => return Err(format!("unexpected element type {ty} at byte {p}")),
        }
        p += 8 + if ty == 15 { size } else { size.div_ceil(8) * 8 };
    }
    Ok(out)
}

/// If `m` (a miMATRIX body) is a char row vector, record it.
fn matrix_char(e: Endian, m: &[u8], out: &mut BTreeMap<String, String>) {
    let mut p = 0;
    let Some((_, flags)) = sub(e, m, &mut p) else {
        return;
    };
    const MX_CHAR: u32 = 4;
    if e.u32(flags, 0).map(|f| f & 0xff) != Some(MX_CHAR) {
        return;
    }
    let Some((_, dims)) = sub(e, m, &mut p) else {
        return;
    };
    if e.u32(dims, 0).is_some_and(|rows| rows > 1) {
        return;
    }
    let Some((_, name)) = sub(e, m, &mut p) else {
        return;
    };
    let Some((ty, data)) = sub(e, m, &mut p) else {
        return;
    };
    let text = match ty {
        // miINT8, miUINT8, miUTF8
        1 | 2 | 16 => String::from_utf8_lossy(data).into_owned(),
        // miUINT16, miUTF16
        4 | 17 => {
            let units: Vec<u16> =
                data.chunks_exact(2)
                    .map(|c| {
                        if e.0 {
                            u16::from_le_bytes([c[0], c[1]])
                        } else {
                            u16::from_be_bytes([c[0], c[1]])
                        }
                    })
                    .collect();
            String::from_utf16_lossy(&units)
        }
        _ => return,
    };
    out.insert(String::from_utf8_lossy(name).into_owned(), text);
}

// ---------------------------------------------------------------- writer

const MI_INT8: u32 = 1;
const MI_UINT16: u32 = 4;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_DOUBLE: u32 = 9;
const MI_MATRIX: u32 = 14;
const MX_CHAR_CLASS: u32 = 4;
const MX_DOUBLE_CLASS: u32 = 6;

fn pad8(v: &mut Vec<u8>) {
    v.resize(v.len().div_ceil(8) * 8, 0);
}

fn element(out: &mut Vec<u8>, ty: u32, data: &[u8]) -> io::Result<()> {
    let len = u32::try_from(data.len())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "MAT element over 4 GiB"))?;
    out.extend_from_slice(&ty.to_le_bytes());
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(data);
    pad8(out);
    Ok(())
}

/// One miMATRIX: a column vector of doubles or a char row vector.
fn matrix(w: &mut dyn Write, name: &str, class: u32, dims: [u32; 2], data: (u32, &[u8])) -> io::Result<()> {
    let mut body = Vec::with_capacity(64 + data.1.len());
    let mut flags = Vec::with_capacity(8);
    flags.extend_from_slice(&class.to_le_bytes());
    flags.extend_from_slice(&0u32.to_le_bytes());
    element(&mut body, MI_UINT32, &flags)?;
    let d: Vec<u8> = dims.iter().flat_map(|x| x.to_le_bytes()).collect();
    element(&mut body, MI_INT32, &d)?;
    element(&mut body, MI_INT8, name.as_bytes())?;
    element(&mut body, data.0, data.1)?;
    let mut head = Vec::with_capacity(8);
    element(&mut head, MI_MATRIX, &[])?;
    let len = u32::try_from(body.len())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "MAT variable over 4 GiB"))?;
    head[4..8].copy_from_slice(&len.to_le_bytes());
    w.write_all(&head)?;
    w.write_all(&body)
}

fn check_name(var: &str, seen: &mut Vec<String>) -> io::Result<()> {
    let invalid = |m: String| io::Error::new(io::ErrorKind::InvalidInput, m);
    if var.len() > MAX_NAME {
        return Err(invalid(format!("MATLAB variable name `{var}` is longer than {MAX_NAME} characters")));
    }
    if seen.iter().any(|s| s == var) {
        return Err(invalid(format!("two channels become the MATLAB variable `{var}`")));
    }
    seen.push(var.to_owned());
    Ok(())
}

fn double_var(w: &mut dyn Write, var: &str, v: &[f64]) -> io::Result<()> {
    let n = u32::try_from(v.len())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "too many samples for MAT"))?;
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    matrix(w, var, MX_DOUBLE_CLASS, [n, 1], (MI_DOUBLE, &bytes))
}

fn char_var(w: &mut dyn Write, var: &str, text: &str) -> io::Result<()> {
    let units: Vec<u16> = text.encode_utf16().collect();
    let bytes: Vec<u8> = units.iter().flat_map(|u| u.to_le_bytes()).collect();
    matrix(w, var, MX_CHAR_CLASS, [1, units.len() as u32], (MI_UINT16, &bytes))
}

/// Write `m` as an uncompressed Level 5 MAT file in the convention above: `time`,
/// `time_unit`, then per signal its vector and `<var>_unit`.
pub fn write(w: &mut dyn Write, m: &Measurement) -> io::Result<()> {
    let mut header = [b' '; 128];
    let text = b"MATLAB 5.0 MAT-file, written by simrod";
    header[..text.len()].copy_from_slice(text);
    header[116..124].fill(0);
    header[124..126].copy_from_slice(&0x0100u16.to_le_bytes());
    header[126..128].copy_from_slice(b"IM");
    w.write_all(&header)?;
    let mut seen = Vec::new();
    check_name("time", &mut seen)?;
    double_var(w, "time", &m.time_s)?;
    char_var(w, "time_unit", "s")?;
    for s in &m.signals {
        if s.values.len() != m.time_s.len() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("channel \"{}\" has {} samples, time has {}", s.name, s.values.len(), m.time_s.len()),
            ));
        }
        let var = sanitize(&s.name);
        check_name(&var, &mut seen)?;
        check_name(&format!("{var}_unit"), &mut seen)?;
        double_var(w, &var, &s.values)?;
        if !s.unit.is_empty() {
            char_var(w, &format!("{var}_unit"), &s.unit)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_names_sanitize_uniquely_and_map_back() {
        let names: Vec<&str> = Channel::ALL
            .iter()
            .map(|c| c.name())
            .chain([SETPOINT_THROTTLE, SETPOINT_LOAD_L, SETPOINT_LOAD_R])
            .collect();
        for n in &names {
            let v = sanitize(n);
            assert!(v.len() <= MAX_NAME && v.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'));
            assert_eq!(bench_name(&v), Some(*n), "{n} -> {v}");
        }
        assert_eq!(sanitize("I_XLML 2.2"), "I_XLML_2_2");
        assert_eq!(sanitize("2nd"), "x2nd");
    }

    #[test]
    fn writer_output_reads_back_with_matfile_and_units() {
        let m = Measurement {
            source: "x".into(),
            time_s: vec![0.001, 0.002, 0.003],
            signals: vec![super::super::Signal {
                name: "I_XLML 2.2".into(),
                unit: "A".into(),
                values: vec![1.5, -2.25, 1e-300],
            }],
        };
        let mut buf = Vec::new();
        write(&mut buf, &m).unwrap();
        let mf = matfile::MatFile::parse(buf.as_slice()).unwrap();
        let a = mf.find_by_name("I_XLML_2_2").unwrap();
        assert_eq!(a.size(), &vec![3, 1]);
        assert_eq!(to_f64(a.data()).unwrap(), m.signals[0].values);
        assert_eq!(to_f64(mf.find_by_name("time").unwrap().data()).unwrap(), m.time_s);
        let units = char_vars(&buf).unwrap();
        assert_eq!(units["I_XLML_2_2_unit"], "A");
        assert_eq!(units["time_unit"], "s");
    }
}
