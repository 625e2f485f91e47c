//! CSV as data-acquisition systems export it.
//!
//! Accepted:
//! - Encoding UTF-8 (a BOM is skipped); a file that is not UTF-8 is read as Latin-1, as
//!   older Windows exports are (`µs`, `°C`).
//! - Lines starting with `#` and blank lines are skipped (before the header too).
//! - Header: one column per channel, `Name [unit]`, `Name (unit)` or just `Name`; units
//!   may instead (or also, if equal) come from a second header row, detected by a time
//!   field that is not a number (`s`, `[s]`). Any column order.
//! - A time column named `time`, `t` or `zeit` (any case), unit `s` (default), `ms` or
//!   `us`. Exactly one. (`T [°C]` is not a time column: its unit is not a time.)
//! - Separator: `;` if the header line contains one, else a tab if it contains one, else
//!   `,`. With `;` or tab, a `,` in a number is a decimal comma (`1,5` = 1.5); a
//!   number with both `.` and `,` is refused (thousands separators are not guessed).
//! - Quoted fields (`"a;b"`), CRLF line ends, trailing separators (empty last fields).
//!
//! Refused, with file, line, column and channel: a row with fewer fields than the header
//! (truncated) or with extra non-empty fields, an empty or non-numeric value, NaN/inf.

use std::path::Path;

use super::is_time;
use super::table::{RawColumn, RawTable, Rows};
use super::units::factor_to;
use crate::error::FileError;

/// Read CSV bytes (UTF-8, else Latin-1) into columns; `origin` names the file in errors.
pub(crate) fn read_bytes(origin: &Path, bytes: Vec<u8>) -> Result<RawTable, FileError> {
    let text = match String::from_utf8(bytes) {
        Ok(s) => s,
        Err(e) => e.into_bytes().iter().map(|&b| char::from(b)).collect(),
    };
    parse(origin, text.strip_prefix('\u{feff}').unwrap_or(&text))
}

/// Split `Name [unit]` / `Name (unit)` into name and unit (`None` when absent or empty).
fn split_unit(h: &str) -> (String, Option<String>) {
    let h = h.trim();
    for (open, close) in [('[', ']'), ('(', ')')] {
        if let Some(inner) = h.strip_suffix(close) {
            if let Some(p) = inner.rfind(open) {
                let name = inner[..p].trim();
                if !name.is_empty() {
                    let unit = inner[p + open.len_utf8()..].trim();
                    return (name.to_owned(), (!unit.is_empty()).then(|| unit.to_owned()));
                }
            }
        }
    }
    (h.to_owned(), None)
}

/// A unit-row entry: `s`, `[s]` or `(s)`.
fn unit_cell(s: &str) -> Option<String> {
    let s = s.trim();
    let s = s
        .strip_prefix('[')
        .and_then(|x| x.strip_suffix(']'))
        .or_else(|| s.strip_prefix('(').and_then(|x| x.strip_suffix(')')))
        .unwrap_or(s)
        .trim();
    (!s.is_empty()).then(|| s.to_owned())
}

fn parse_num(s: &str, decimal_comma: bool) -> Option<f64> {
    let s = s.trim();
    if decimal_comma && s.contains(',') {
        if s.contains('.') || s.matches(',').count() > 1 {
            return None;
        }
        return s.replace(',', ".").parse().ok();
    }
    s.parse().ok()
}

/// 1-based character column where field `k` starts in `line` (quotes respected).
fn field_col(line: &str, sep: u8, k: usize) -> usize {
    let mut field = 0;
    let mut quoted = false;
    for (col, ch) in line.chars().enumerate() {
        if field == k {
            return col + 1;
        }
        match ch {
            '"' => quoted = !quoted,
            '\n' => break,
            c if !quoted && c == char::from(sep) => field += 1,
            _ => {}
        }
    }
    line.lines().next().map_or(0, |l| l.chars().count()) + 1
}

/// Parse CSV text; `origin` names it in errors.
pub(crate) fn parse(origin: &Path, text: &str) -> Result<RawTable, FileError> {
    // Skip the preamble: blank lines and `#` comments.
    let mut offset = 0;
    let mut header_line = 1;
    for l in text.split_inclusive('\n') {
        let t = l.trim();
        if !(t.is_empty() || t.starts_with('#')) {
            break;
        }
        offset += l.len();
        header_line += 1;
    }
    let body = &text[offset..];
    let first = body.lines().next().unwrap_or("");
    if first.trim().is_empty() {
        return Err(FileError::whole(origin, "empty file: no header line"));
    }
    let sep = if first.contains(';') {
        b';'
    } else if first.contains('\t') {
        b'\t'
    } else {
        b','
    };
    let decimal_comma = sep != b',';
    let mut rdr = csv::ReaderBuilder::new()
        .delimiter(sep)
        .has_headers(false)
        .flexible(true)
        .comment(Some(b'#'))
        .from_reader(body.as_bytes());
    let line_of =
        |r: &csv::StringRecord| r.position().map_or(header_line, |p| p.line() as usize + header_line - 1);
    let col_of = |r: &csv::StringRecord, k: usize| {
        let start = r.position().map_or(0, |p| p.byte() as usize);
        field_col(body.get(start..).unwrap_or(""), sep, k)
    };
    let csv_err = |e: csv::Error| {
        let line = e.position().map_or(header_line, |p| p.line() as usize + header_line - 1);
        FileError {
            file: origin.to_path_buf(),
            line: Some(line),
            col: None,
            message: format!("not readable as CSV: {e}"),
        }
    };
    let mut records = rdr.records();
    let header = match records.next() {
        Some(r) => r.map_err(csv_err)?,
        None => return Err(FileError::whole(origin, "empty file: no header line")),
    };
    // Trailing empty header fields come from trailing separators: not columns.
    let n_cols = (0..header.len()).rev().find(|&k| !header[k].trim().is_empty()).map_or(0, |p| p + 1);
    let mut cols: Vec<RawColumn> = Vec::with_capacity(n_cols);
    for (k, h) in header.iter().take(n_cols).enumerate() {
        let (name, unit) = split_unit(h);
        if name.is_empty() {
            return Err(FileError::at(
                origin,
                header_line,
                col_of(&header, k),
                format!("column {} has no name", k + 1),
            ));
        }
        cols.push(RawColumn { name, alias: None, unit, values: Vec::new() });
    }
    let time_cols: Vec<usize> =
        (0..cols.len()).filter(|&k| is_time(&cols[k].name, cols[k].unit.as_deref())).collect();
    let tc = match time_cols.as_slice() {
        [k] => *k,
        [] => {
            return Err(FileError::at(
                origin,
                header_line,
                1,
                "no time column (one named `time`, `Time [s]` or `t`)",
            ))
        }
        [_, k, ..] => {
            return Err(FileError::at(origin, header_line, col_of(&header, *k), "more than one time column"))
        }
    };
    let mut lines = Vec::new();
    let mut unit_row_seen = false;
    for rec in records {
        let rec = rec.map_err(csv_err)?;
        let line = line_of(&rec);
        if rec.iter().all(|f| f.trim().is_empty()) {
            continue;
        }
        // A unit row: before any data, with a time field that is a time unit or empty.
        let is_unit_row = !unit_row_seen
            && lines.is_empty()
            && rec.get(tc).is_some_and(|f| {
                parse_num(f, decimal_comma).is_none()
                    && unit_cell(f).is_none_or(|u| factor_to("s", &u).is_some())
            });
        if is_unit_row {
            unit_row_seen = true;
            for (k, c) in cols.iter_mut().enumerate() {
                let Some(u) = rec.get(k).and_then(unit_cell) else {
                    continue;
                };
                match &c.unit {
                    Some(h) if *h != u => {
                        return Err(FileError::at(
                            origin,
                            line,
                            col_of(&rec, k),
                            format!("channel \"{}\": unit row says `{u}`, header says `{h}`", c.name),
                        ))
                    }
                    _ => c.unit = Some(u),
                }
            }
            continue;
        }
        if rec.len() < cols.len() {
            let missing = &cols[rec.len()].name;
            return Err(FileError::at(
                origin,
                line,
                col_of(&rec, rec.len()),
                format!(
                    "truncated row: {} of {} fields; channel \"{missing}\" has no value",
                    rec.len(),
                    cols.len()
                ),
            ));
        }
        if let Some(extra) = (cols.len()..rec.len()).find(|&k| !rec[k].trim().is_empty()) {
            return Err(FileError::at(
                origin,
                line,
                col_of(&rec, extra),
                format!("row has {} fields, the header names {} channels", rec.len(), cols.len()),
            ));
        }
        for (k, c) in cols.iter_mut().enumerate() {
            let f = &rec[k];
            let at = |msg: String| FileError::at(origin, line, col_of(&rec, k), msg);
            if f.trim().is_empty() {
                return Err(at(format!("channel \"{}\": empty value", c.name)));
            }
            let v = parse_num(f, decimal_comma)
                .ok_or_else(|| at(format!("channel \"{}\": `{}` is not a number", c.name, f.trim())))?;
            if !v.is_finite() {
                return Err(at(format!("channel \"{}\": value {} is not finite", c.name, f.trim())));
            }
            c.values.push(v);
        }
        lines.push(line);
    }
    if lines.is_empty() {
        return Err(FileError::whole(origin, "no data rows (empty file after the header)"));
    }
    // A data row with no newline after it may be a write cut short inside a number
    // (-0.07646873 read as -0.07): refuse it rather than read a shorter number.
    let tail = body.rsplit('\n').next().unwrap_or("").trim();
    if !tail.is_empty() && !tail.starts_with('#') {
        let line = lines.last().copied().unwrap_or(header_line);
        return Err(FileError::at(
            origin,
            line,
            1,
            "the file ends inside this row (no newline after it): a write cut short? \
             If the row is complete, end the file with a newline",
        ));
    }
    let time = cols.remove(tc);
    Ok(RawTable {
        source: origin.to_path_buf(),
        time,
        columns: cols,
        rows: Rows::Lines { lines, header: header_line },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_forms() {
        assert_eq!(split_unit(" C_Kistler_L [N m] "), ("C_Kistler_L".into(), Some("N m".into())));
        assert_eq!(split_unit("Time (s)"), ("Time".into(), Some("s".into())));
        assert_eq!(split_unit("I_XLML 2.2"), ("I_XLML 2.2".into(), None));
        assert_eq!(split_unit("x []"), ("x".into(), None));
        assert_eq!(unit_cell("[rpm]"), Some("rpm".into()));
        assert_eq!(unit_cell(" "), None);
    }

    #[test]
    fn numbers() {
        assert_eq!(parse_num("1,5", true), Some(1.5));
        assert_eq!(parse_num("-2,5e-3", true), Some(-2.5e-3));
        assert_eq!(parse_num("1.5", true), Some(1.5));
        assert_eq!(parse_num("1.000,5", true), None);
        assert_eq!(parse_num("1,5", false), None);
    }

    #[test]
    fn columns_are_counted_in_characters_outside_quotes() {
        assert_eq!(field_col("ab;\"c;d\";e\n", b';', 0), 1);
        assert_eq!(field_col("ab;\"c;d\";e\n", b';', 2), 10);
        assert_eq!(field_col("µ;x", b';', 1), 3);
    }
}
