//! The simulation CSV: a `time [s]` column, then every [`Channel`] as `name [unit]`,
//! one row per step.
//!
//! Times are printed exactly from the integer microseconds (`12.345000`), values with
//! Rust's shortest round-trip `Display`, so parsing a value back as `f32` gives the
//! same bits the model produced: a CSV can stand in for a run in bit-exact comparisons
//! (host vs. target, before vs. after a change).

use std::fmt::Write as _;
use std::io::{self, Write};

use model_core::{Channel, Outputs, N_CHANNELS};

/// The header line (with its newline).
pub fn header() -> String {
    header_with(&[])
}

/// The header line with `extra` columns `(name, unit)` after the channels (what a
/// command adds to the twin's channels, e.g. `simrod xil`'s vehicle speed).
pub fn header_with(extra: &[(&str, &str)]) -> String {
    let mut h = String::from("time [s]");
    let columns = Channel::ALL.iter().map(|c| (c.name(), c.unit())).chain(extra.iter().copied());
    for (name, unit) in columns {
        h.push(',');
        h.push_str(name);
        h.push_str(" [");
        h.push_str(unit);
        h.push(']');
    }
    h.push('\n');
    h
}

/// Formats rows into one reused buffer, so writing a row is one `write_all` and no
/// allocation once the buffers have grown. Float formatting is most of the cost of a
/// run and many channels hold their value for long stretches (set points, idle
/// loads), so each column keeps the text of its last value and reuses it while the
/// bits do not change (about 45 % of the values of TP07).
#[derive(Debug)]
pub struct RowWriter {
    line: String,
    last: Vec<LastValue>,
}

#[derive(Debug, Default)]
struct LastValue {
    bits: Option<u32>,
    text: String,
}

impl Default for RowWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl RowWriter {
    pub fn new() -> Self {
        Self {
            line: String::with_capacity(16 * (N_CHANNELS + 1)),
            last: (0..N_CHANNELS).map(|_| LastValue::default()).collect(),
        }
    }

    /// Appends one row for `o` to `w`.
    pub fn write_row(&mut self, w: &mut dyn Write, o: &Outputs) -> io::Result<()> {
        self.write_row_with(w, o, &[])
    }

    /// Appends one row for `o` and the values of [`header_with`]'s extra columns.
    pub fn write_row_with(&mut self, w: &mut dyn Write, o: &Outputs, extra: &[f32]) -> io::Result<()> {
        self.line.clear();
        write_time(&mut self.line, o.t_us);
        for (v, last) in o.values.iter().zip(self.last.iter_mut()) {
            self.line.push(',');
            let bits = v.to_bits();
            if last.bits != Some(bits) {
                last.text.clear();
                // Formatting into a String cannot fail.
                let _ = write!(last.text, "{v}");
                last.bits = Some(bits);
            }
            self.line.push_str(&last.text);
        }
        for v in extra {
            // Formatting into a String cannot fail.
            let _ = write!(self.line, ",{v}");
        }
        self.line.push('\n');
        w.write_all(self.line.as_bytes())
    }
}

/// `t_us` as seconds with exactly six decimals: no float rounding in the time column.
fn write_time(line: &mut String, t_us: u64) {
    let _ = write!(line, "{}.{:06}", t_us / 1_000_000, t_us % 1_000_000);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_names_every_channel_with_unit_and_needs_no_quoting() {
        let h = header();
        let cols: Vec<&str> = h.trim_end().split(',').collect();
        assert_eq!(cols.len(), N_CHANNELS + 1);
        assert_eq!(cols[0], "time [s]");
        for (c, col) in Channel::ALL.iter().zip(&cols[1..]) {
            assert_eq!(*col, format!("{} [{}]", c.name(), c.unit()));
            assert!(!c.name().contains([',', '"', '\n']), "{}", c.name());
        }
    }

    #[test]
    fn time_is_exact() {
        let mut b = String::new();
        for (t, s) in [
            (0u64, "0.000000"),
            (1, "0.000001"),
            (999_999, "0.999999"),
            (1_000_000, "1.000000"),
            (66_000_123, "66.000123"),
        ] {
            b.clear();
            write_time(&mut b, t);
            assert_eq!(b, s);
        }
    }

    #[test]
    fn extra_columns_follow_the_channels() {
        let h = header_with(&[("v_vehicle", "km/h")]);
        assert!(h.ends_with(",v_vehicle [km/h]\n") && h.starts_with(header().trim_end()), "{h}");
        let mut w = RowWriter::new();
        let mut buf = Vec::new();
        let o = Outputs { t_us: 5, ..Outputs::default() };
        w.write_row_with(&mut buf, &o, &[12.5, -0.25]).unwrap();
        let line = String::from_utf8(buf).unwrap();
        assert_eq!(line.trim_end().split(',').count(), N_CHANNELS + 3);
        assert!(line.ends_with(",12.5,-0.25\n"), "{line}");
    }

    /// The per-column cache must never serve a stale value, not even for -0 after 0.
    #[test]
    fn repeated_and_changing_values_are_written_correctly() {
        let mut w = RowWriter::new();
        let mut buf = Vec::new();
        let seq = [0.0f32, 0.0, -0.0, -0.0, 1.5, 1.5, 0.0, f32::NAN, f32::NAN, 2.0];
        for (i, v) in seq.iter().enumerate() {
            let mut o = Outputs { t_us: i as u64, ..Outputs::default() };
            o.values[3] = *v;
            w.write_row(&mut buf, &o).unwrap();
        }
        let text = String::from_utf8(buf).unwrap();
        let col3: Vec<&str> = text.lines().map(|l| l.split(',').nth(4).unwrap()).collect();
        assert_eq!(col3, ["0", "0", "-0", "-0", "1.5", "1.5", "0", "NaN", "NaN", "2"]);
    }

    /// Every value must come back with the same bits, including the awkward ones.
    #[test]
    fn values_round_trip_bit_exactly() {
        let mut specials = vec![
            0.0f32,
            -0.0,
            0.1,
            1.0 / 3.0,
            f32::MIN_POSITIVE,
            f32::MIN_POSITIVE / 3.0, // subnormal
            f32::from_bits(1),       // smallest subnormal
            f32::MAX,
            f32::MIN,
            f32::EPSILON,
            16_777_217.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        // A deterministic sweep over the bit patterns (xorshift), finite values only.
        let mut x = 0x9E37_79B9u32;
        while specials.len() < 200_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let v = f32::from_bits(x);
            if v.is_finite() {
                specials.push(v);
            }
        }
        let mut w = RowWriter::new();
        let mut buf = Vec::new();
        for chunk in specials.chunks(N_CHANNELS) {
            let mut o = Outputs { t_us: 42, ..Outputs::default() };
            o.values[..chunk.len()].copy_from_slice(chunk);
            buf.clear();
            w.write_row(&mut buf, &o).unwrap();
            let line = String::from_utf8(buf.clone()).unwrap();
            let mut cols = line.trim_end().split(',');
            assert_eq!(cols.next(), Some("0.000042"));
            for (want, got) in o.values.iter().zip(cols) {
                let back: f32 = got.parse().unwrap();
                assert_eq!(back.to_bits(), want.to_bits(), "{want:e} printed as {got}");
            }
        }
    }
}
