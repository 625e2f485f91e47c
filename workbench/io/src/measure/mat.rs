//! MATLAB Level 5 MAT files (`save -v6`/`-v7`, compressed or not, either byte order):
//! a reader of its own, and a small writer for the virtual bench.
//!
//! Convention (MATLAB names cannot hold spaces or dots):
//! - one real numeric vector (1xN or Nx1) per channel, all the length of `time`. Every
//!   numeric class is read as f64: double, single, int8..int64, uint8..uint64 and logical
//!   (uint8 with the logical flag), whatever smaller storage type the file uses (MATLAB
//!   stores a double array of small integers as miUINT8, miINT16, ...);
//! - the variable name is the bench name with every character other than `A-Z a-z 0-9`
//!   replaced by `_` (`I_XLML 2.2` -> `I_XLML_2_2`, `SuT Throttle` -> `SuT_Throttle`);
//!   names of known channels (`model_core::Channel::ALL`, the set points) are mapped
//!   back, other variables keep their MATLAB name;
//! - a vector `time` (or `t`) \[s\];
//! - optional char row vectors `<var>_unit`, e.g. `C_Kistler_L_unit = 'N m'`
//!   (`time_unit` defaults to `s`);
//! - metadata is ignored: numeric scalars (1x1) and char arrays that are not in a
//!   channel's place (see below).
//!
//! Errors, each naming the variable and what was expected: a char array in a channel's
//! place (named `time`/`t`, after a known channel, or with a `<var>_unit`), cell, struct,
//! object and sparse arrays (they may hold the channels, so they are not skipped
//! silently), complex data, other matrices, a vector of the wrong length, a non-finite
//! value, data that contradicts its dimensions. A file cut short anywhere is reported as
//! truncated. v7.3 files (HDF5) are refused with a hint.
//!
//! The `matfile` crate is not used for reading: it drops char arrays, misreads int32
//! (class int32 is checked against miUINT32 storage), accepts only some storage types,
//! stops silently at a broken element, prints to stdout and panics on some damaged input
//! (an overflow in its size arithmetic). No input may panic here (the reader is fuzzed):
//! every read is bounds-checked, every size sum checked.

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

/// Parse MAT bytes; `origin` names the file in errors.
pub(crate) fn parse(origin: &Path, bytes: &[u8]) -> Result<RawTable, FileError> {
    let bad = |m: String| FileError::whole(origin, m);
    let e = header(bytes).map_err(bad)?;
    let vars = variables(e, bytes).map_err(|m| bad(format!("not a readable MAT v5/v7 file: {m}")))?;
    let cols = columns(vars).map_err(bad)?;
    let (time, columns) = split_time(cols).map_err(bad)?;
    Ok(RawTable { source: origin.to_path_buf(), time, columns, rows: Rows::Samples })
}

// ---------------------------------------------------------------- file structure

/// Little or big endian reads, as the header says.
#[derive(Clone, Copy)]
struct Endian(bool);

impl Endian {
    /// `N` bytes at `at` in little-endian order, `None` past the end.
    fn bytes<const N: usize>(self, b: &[u8], at: usize) -> Option<[u8; N]> {
        let mut a: [u8; N] = b.get(at..at.checked_add(N)?)?.try_into().ok()?;
        if !self.0 {
            a.reverse();
        }
        Some(a)
    }

    fn u32(self, b: &[u8], at: usize) -> Option<u32> {
        self.bytes(b, at).map(u32::from_le_bytes)
    }
}

const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;
const HEADER: usize = 128;

/// Check the 128-byte header; its byte order.
fn header(bytes: &[u8]) -> Result<Endian, String> {
    if bytes.is_empty() {
        return Err("empty file".into());
    }
    let magic = b"MATLAB";
    let n = bytes.len().min(magic.len());
    if bytes[..n] != magic[..n] {
        return Err("not a MAT file (no MATLAB header)".into());
    }
    if bytes.len() < HEADER {
        return Err(format!(
            "truncated MAT file: it ends after {} bytes, inside the 128-byte header",
            bytes.len()
        ));
    }
    let e = match &bytes[126..HEADER] {
        b"IM" => Endian(true),
        b"MI" => Endian(false),
        _ => return Err("not a MAT v5/v7 file (no `IM`/`MI` byte-order mark at byte 126)".into()),
    };
    match e.bytes(bytes, 124).map(u16::from_le_bytes) {
        Some(0x0100) => Ok(e),
        Some(0x0200) => Err("MAT v7.3 (HDF5) files are not supported; save with -v7 (or -v6)".into()),
        v => Err(format!("unsupported MAT version {:#06x}; save with -v7 (or -v6)", v.unwrap_or(0))),
    }
}

/// A top-level variable as stored.
struct Var {
    name: String,
    dims: Dims,
    kind: Kind,
}

enum Kind {
    Numeric {
        complex: bool,
        values: Vec<f64>,
    },
    Char(String),
    /// Cell, struct, sparse, ...: the mxCLASS number.
    Other(u32),
}

/// Array dimensions (at least two), displayed MATLAB style: `100x2`.
struct Dims(Vec<usize>);

impl Dims {
    /// At least two non-negative miINT32.
    fn read(e: Endian, d: &[u8]) -> Option<Self> {
        let dims: Option<Vec<usize>> = d
            .chunks_exact(4)
            .map(|c| e.bytes(c, 0).map(i32::from_le_bytes).and_then(|x| usize::try_from(x).ok()))
            .collect();
        dims.filter(|d| d.len() >= 2).map(Dims)
    }

    /// Number of elements (saturating: a corrupt product is caught by the data check).
    fn count(&self) -> u64 {
        self.0.iter().try_fold(1u64, |n, &d| n.checked_mul(d as u64)).unwrap_or(u64::MAX)
    }

    /// At most one dimension other than 1.
    fn is_vector(&self) -> bool {
        self.0.iter().filter(|&&d| d != 1).count() <= 1
    }
}

impl std::fmt::Display for Dims {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let d: Vec<String> = self.0.iter().map(usize::to_string).collect();
        f.write_str(&d.join("x"))
    }
}

/// The top-level elements after the header: miMATRIX or miCOMPRESSED (one miMATRIX).
fn variables(e: Endian, bytes: &[u8]) -> Result<Vec<Var>, String> {
    let mut vars = Vec::new();
    let mut p = HEADER;
    while p < bytes.len() {
        let (ty, data, next) = top_element(e, bytes, p)?;
        vars.push(match ty {
            MI_MATRIX => read_matrix(e, data, p)?,
            MI_COMPRESSED => read_matrix(e, &inflate(e, data, p)?, p)?,
            _ => return Err(format!("unexpected element type {ty} at byte {p}")),
        });
        p = next;
    }
    Ok(vars)
}

/// The element at `p`: type, data, and where the next one starts. Uncompressed elements
/// are padded to 8 bytes; missing padding at the very end is accepted.
fn top_element(e: Endian, b: &[u8], p: usize) -> Result<(u32, &[u8], usize), String> {
    let (Some(ty), Some(size)) = (e.u32(b, p), e.u32(b, p + 4)) else {
        return Err(format!("the element tag at byte {p} is cut short: the file is truncated"));
    };
    let size = size as usize;
    let start = p + 8;
    let Some(data) = start.checked_add(size).and_then(|end| b.get(start..end)) else {
        return Err(format!(
            "element runs past the end of the file (the element at byte {p} declares {size} bytes, {} remain): \
             the file is truncated",
            b.len() - start
        ));
    };
    let padded = if ty == MI_COMPRESSED { size } else { size.div_ceil(8) * 8 };
    Ok((ty, data, start.saturating_add(padded)))
}

/// The body of the miMATRIX element inside a miCOMPRESSED one at byte `at`.
fn inflate(e: Endian, z: &[u8], at: usize) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    libflate::zlib::Decoder::new(z).and_then(|mut d| d.read_to_end(&mut out)).map_err(|err| {
        match err.kind() {
            io::ErrorKind::UnexpectedEof => {
                format!("the compressed element at byte {at} ends early: the file is truncated")
            }
            _ => format!("corrupt compressed element at byte {at}: {err}"),
        }
    })?;
    let (ty, size) = (e.u32(&out, 0), e.u32(&out, 4).map(|s| s as usize));
    match (ty, size) {
        (Some(MI_MATRIX), Some(n)) if n <= out.len() - 8 => {
            out.truncate(8 + n);
            out.drain(..8);
            Ok(out)
        }
        (Some(MI_MATRIX), _) => {
            Err(format!("corrupt compressed element at byte {at}: its matrix is cut short"))
        }
        _ => Err(format!("compressed element at byte {at} does not hold a matrix")),
    }
}

/// Next sub-element of a matrix at `*p` (normal or small format): `(type, data)`.
fn sub<'a>(e: Endian, b: &'a [u8], p: &mut usize) -> Option<(u32, &'a [u8])> {
    let first = e.u32(b, *p)?;
    let small = first >> 16;
    let (ty, start, len, step) = if small != 0 {
        (first & 0xffff, *p + 4, small as usize, 8)
    } else {
        let len = e.u32(b, *p + 4)? as usize;
        (first, *p + 8, len, len.div_ceil(8).checked_mul(8)?.checked_add(8)?)
    };
    if small > 4 {
        return None;
    }
    let data = b.get(start..start.checked_add(len)?)?;
    *p = p.checked_add(step)?;
    Some((ty, data))
}

const MX_CHAR: u32 = 4;
/// mxDOUBLE_CLASS ..= mxUINT64_CLASS (logical is mxUINT8 with a flag).
const MX_NUMERIC: std::ops::RangeInclusive<u32> = 6..=15;
const FLAG_COMPLEX: u32 = 0x0800;

/// One miMATRIX body (the element at byte `at`): flags, dimensions, name, then the data
/// of the classes read here.
fn read_matrix(e: Endian, m: &[u8], at: usize) -> Result<Var, String> {
    let corrupt = |what: &str| format!("the matrix at byte {at} is corrupt: {what}");
    let mut p = 0;
    let flags = sub(e, m, &mut p).and_then(|(_, f)| e.u32(f, 0)).ok_or_else(|| corrupt("no array flags"))?;
    let dims =
        sub(e, m, &mut p).and_then(|(_, d)| Dims::read(e, d)).ok_or_else(|| corrupt("bad dimensions"))?;
    let (_, name) = sub(e, m, &mut p).ok_or_else(|| corrupt("no name"))?;
    let name = String::from_utf8_lossy(name).trim_end_matches('\0').to_owned();
    let kind = data(e, flags, sub(e, m, &mut p))
        .and_then(|k| check_count(&dims, k))
        .map_err(|what| format!("variable `{name}` (at byte {at}) is corrupt: {what}"))?;
    Ok(Var { name, dims, kind })
}

/// The data `d` of the numeric and char classes; other classes by name only.
fn data(e: Endian, flags: u32, d: Option<(u32, &[u8])>) -> Result<Kind, String> {
    let class = flags & 0xff;
    if class != MX_CHAR && !MX_NUMERIC.contains(&class) {
        return Ok(Kind::Other(class));
    }
    let (ty, d) = d.ok_or("its data runs past its element")?;
    if class == MX_CHAR {
        return text(e, ty, d).map(Kind::Char).ok_or_else(|| format!("char data of element type {ty}"));
    }
    let values = numbers(e, ty, d).ok_or_else(|| {
        format!("its data (element type {ty}, {} bytes) is not a whole number of numeric values", d.len())
    })?;
    Ok(Kind::Numeric { complex: flags & FLAG_COMPLEX != 0, values })
}

/// Numeric data must hold exactly one value per element of the dimensions.
fn check_count(dims: &Dims, k: Kind) -> Result<Kind, String> {
    match &k {
        Kind::Numeric { values, .. } if values.len() as u64 != dims.count() => {
            Err(format!("it holds {} values, its dimensions {dims} need {}", values.len(), dims.count()))
        }
        _ => Ok(k),
    }
}

/// The class of an array not read here, with its article: "a struct".
fn class_name(class: u32) -> String {
    match class {
        1 => "a cell".into(),
        2 => "a struct".into(),
        3 => "an object".into(),
        5 => "a sparse".into(),
        16 => "a function handle".into(),
        17 => "an opaque (string, datetime, table, ...)".into(),
        _ => format!("an unknown class-{class}"),
    }
}

/// Stored numbers (any numeric storage type) as f64; `None` for a non-numeric type or a
/// byte count that is not a whole number of values. 64-bit integers above 2^53 lose
/// digits; sample data never gets there.
fn numbers(e: Endian, ty: u32, d: &[u8]) -> Option<Vec<f64>> {
    match ty {
        1 => each(e, d, |b| f64::from(i8::from_le_bytes(b))),
        2 => each(e, d, |b| f64::from(u8::from_le_bytes(b))),
        3 => each(e, d, |b| f64::from(i16::from_le_bytes(b))),
        4 => each(e, d, |b| f64::from(u16::from_le_bytes(b))),
        5 => each(e, d, |b| f64::from(i32::from_le_bytes(b))),
        6 => each(e, d, |b| f64::from(u32::from_le_bytes(b))),
        7 => each(e, d, |b| f64::from(f32::from_le_bytes(b))),
        9 => each(e, d, f64::from_le_bytes),
        12 => each(e, d, |b| i64::from_le_bytes(b) as f64),
        13 => each(e, d, |b| u64::from_le_bytes(b) as f64),
        _ => None,
    }
}

/// `f` of every `N`-byte value of `d` (in little-endian order).
fn each<const N: usize>(e: Endian, d: &[u8], f: impl Fn([u8; N]) -> f64) -> Option<Vec<f64>> {
    let chunks = d.chunks_exact(N);
    if !chunks.remainder().is_empty() {
        return None;
    }
    chunks.map(|c| e.bytes(c, 0).map(&f)).collect()
}

/// Char data: miINT8/miUINT8/miUTF8, miUINT16/miUTF16 or miUTF32.
fn text(e: Endian, ty: u32, d: &[u8]) -> Option<String> {
    match ty {
        1 | 2 | 16 => Some(String::from_utf8_lossy(d).into_owned()),
        4 | 17 => {
            let units: Option<Vec<u16>> =
                (0..d.len() / 2).map(|i| e.bytes(d, 2 * i).map(u16::from_le_bytes)).collect();
            Some(String::from_utf16_lossy(&units?))
        }
        18 => (0..d.len() / 4)
            .map(|i| {
                e.bytes(d, 4 * i).map(u32::from_le_bytes).map(|c| char::from_u32(c).unwrap_or('\u{fffd}'))
            })
            .collect(),
        _ => None,
    }
}

// ---------------------------------------------------------------- convention

/// The channels (time among them) of the variables, in file order, with their units.
fn columns(vars: Vec<Var>) -> Result<Vec<RawColumn>, String> {
    if vars.iter().all(|v| v.name.is_empty()) {
        return Err("no variables (an empty MAT file, or one truncated after its header)".into());
    }
    let units = units(&vars)?;
    let mut cols = Vec::new();
    // Unnamed variables are MATLAB's subsystem data (objects).
    for v in vars.into_iter().filter(|v| !v.name.is_empty()) {
        match v.kind {
            Kind::Numeric { complex, values } => {
                if let Some(c) = column(&v.name, &v.dims, complex, values, &units)? {
                    cols.push(c);
                }
            }
            Kind::Char(_) => char_in_place(&v, &units)?,
            Kind::Other(class) => {
                return Err(format!(
                    "variable `{}` is {} array; a numeric vector (channel) was expected \
                     (cell, struct, object and sparse arrays are not read: save each channel as a vector)",
                    v.name,
                    class_name(class)
                ))
            }
        }
    }
    Ok(cols)
}

/// The `<var>_unit` char arrays, by the name of the variable they belong to.
fn units(vars: &[Var]) -> Result<BTreeMap<String, String>, String> {
    let mut units = BTreeMap::new();
    for v in vars {
        let (Kind::Char(t), Some(of)) = (&v.kind, v.name.strip_suffix("_unit")) else { continue };
        if !v.dims.is_vector() {
            return Err(format!(
                "variable `{}` is a {} char array; a unit must be one row of text, e.g. 'N m'",
                v.name, v.dims
            ));
        }
        units.insert(of.to_owned(), t.clone());
    }
    Ok(units)
}

/// A char array is metadata, unless it stands where a channel is expected.
fn char_in_place(v: &Var, units: &BTreeMap<String, String>) -> Result<(), String> {
    let unit = v.name.strip_suffix("_unit").is_some_and(|of| units.contains_key(of));
    let channel = is_time(&v.name, None) || bench_name(&v.name).is_some() || units.contains_key(&v.name);
    if channel && !unit {
        return Err(format!(
            "variable `{}` is a {} char array; a numeric vector (channel) was expected",
            v.name, v.dims
        ));
    }
    Ok(())
}

/// The channel of numeric variable `var`; `None` for a scalar, which is metadata.
fn column(
    var: &str,
    dims: &Dims,
    complex: bool,
    values: Vec<f64>,
    units: &BTreeMap<String, String>,
) -> Result<Option<RawColumn>, String> {
    if dims.count() == 1 {
        return Ok(None);
    }
    if complex {
        return Err(format!("variable `{var}` is complex; a channel must be a real numeric vector"));
    }
    if !dims.is_vector() {
        return Err(format!("variable `{var}` is a {dims} array; a channel must be a vector (1xN or Nx1)"));
    }
    let name = bench_name(var).unwrap_or(var).to_owned();
    let alias = (name != var).then(|| var.to_owned());
    if let Some(i) = values.iter().position(|x| !x.is_finite()) {
        let of = alias.as_ref().map(|a| format!(" (variable `{a}`)")).unwrap_or_default();
        return Err(format!("channel \"{name}\"{of}, sample {}: value {} is not finite", i + 1, values[i]));
    }
    let unit = units.get(var).cloned();
    Ok(Some(RawColumn { name, alias, unit, values }))
}

/// The time vector (`time` or `t`, in a time unit) and the other channels, which must
/// be as long.
fn split_time(cols: Vec<RawColumn>) -> Result<(RawColumn, Vec<RawColumn>), String> {
    let var = |c: &RawColumn| c.alias.clone().unwrap_or_else(|| c.name.clone());
    let (times, cols): (Vec<_>, Vec<_>) = cols.into_iter().partition(|c| is_time(&var(c), c.unit.as_deref()));
    let mut times = times.into_iter();
    let time = times.next().ok_or("no time vector (a variable named `time` or `t`)")?;
    if let Some(t) = times.next() {
        return Err(format!("more than one time vector (`{}`)", var(&t)));
    }
    for c in &cols {
        if c.values.len() != time.values.len() {
            return Err(format!(
                "channel \"{}\" (variable `{}`) has {} samples, time has {}",
                c.name,
                var(c),
                c.values.len(),
                time.values.len()
            ));
        }
    }
    Ok((time, cols))
}

// ---------------------------------------------------------------- writer

const MI_INT8: u32 = 1;
const MI_UINT16: u32 = 4;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_DOUBLE: u32 = 9;
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
    fn header_errors_say_what_is_wrong() {
        let mut h = vec![b' '; HEADER];
        h[..6].copy_from_slice(b"MATLAB");
        h[124..126].copy_from_slice(&0x0100u16.to_le_bytes());
        let err = |b: &[u8]| header(b).err().unwrap_or_default();
        assert!(err(b"MAT").contains("truncated MAT file: it ends after 3 bytes"));
        assert!(err(b"%%MatrixMarket").contains("not a MAT file"));
        assert!(err(&h).contains("no `IM`/`MI` byte-order mark"));
        h[126..].copy_from_slice(b"IM");
        assert!(header(&h).is_ok());
        h[124..126].copy_from_slice(&0x0300u16.to_le_bytes());
        assert!(err(&h).contains("unsupported MAT version 0x0300"));
    }

    #[test]
    fn writer_output_reads_back_with_matfile_and_here() {
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
        // An independent reader first (`matfile` reads doubles well; it skips chars).
        let mf = matfile::MatFile::parse(buf.as_slice()).unwrap();
        let doubles = |name: &str| match mf.find_by_name(name).map(|a| (a.size().clone(), a.data())) {
            Some((size, matfile::NumericData::Double { real, imag: None })) => (size, real.clone()),
            other => panic!("{name}: {other:?}"),
        };
        assert_eq!(doubles("I_XLML_2_2"), (vec![3, 1], m.signals[0].values.clone()));
        assert_eq!(doubles("time").1, m.time_s);
        let raw = parse(Path::new("x.mat"), &buf).unwrap();
        assert_eq!((raw.time.values, raw.time.unit.as_deref()), (m.time_s, Some("s")));
        let c = &raw.columns[0];
        assert_eq!((c.name.as_str(), c.alias.as_deref()), ("I_XLML 2.2", Some("I_XLML_2_2")));
        assert_eq!((c.unit.as_deref(), &c.values), (Some("A"), &m.signals[0].values));
    }
}
