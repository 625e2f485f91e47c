//! The MAT reader against files it did not write: scipy's `savemat` (and two MATLAB-style
//! files checked by scipy's `loadmat`), made by `scripts/make-mat-fixtures.py`. The known
//! values are recomputed here: k = 0..100, time = 0.001 k, C_Kistler_L = k - 50 (k for
//! unsigned classes). Also: a file cut at any byte is "truncated", and no bytes panic.

use std::path::{Path, PathBuf};

use simrod_io::measure::{load_with, parse_bytes, LoadOptions, Loaded};

const N: usize = 100;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/mat").join(name)
}

fn load(name: &str) -> Loaded {
    let p = fixture(name);
    load_with(&p, &LoadOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn err(name: &str, opts: &LoadOptions) -> String {
    let p = fixture(name);
    let e = load_with(&p, opts).expect_err(name).to_string();
    assert!(e.starts_with(&format!("{}: ", p.display())), "names the file: {e}");
    e
}

fn k_minus(offset: f64) -> Vec<f64> {
    (0..N).map(|k| k as f64 - offset).collect()
}

fn values(l: &Loaded, name: &str) -> Vec<f64> {
    l.measurement.signal(name).unwrap_or_else(|| panic!("no {name}")).values.clone()
}

const CLASSES: [&str; 10] =
    ["double", "single", "int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64"];

#[test]
fn every_numeric_class_scipy_writes_reads_as_f64() {
    let time: Vec<f64> = (0..N).map(|k| 0.001 * k as f64).collect();
    for class in CLASSES {
        let want = k_minus(if class.starts_with("uint") { 0.0 } else { 50.0 });
        // Plain with column vectors, compressed with row vectors.
        for file in [format!("class_{class}.mat"), format!("class_{class}_z.mat")] {
            let l = load(&file);
            let m = &l.measurement;
            assert_eq!(m.time_s, time, "{file}");
            assert_eq!(l.resampled_dt, None, "{file}");
            // class_double also holds a scalar, a complex scalar and a text: ignored.
            assert_eq!(m.signals.len(), 1, "{file}: {:?}", m.signals);
            let c = &m.signals[0];
            assert_eq!((c.name.as_str(), c.unit.as_str()), ("C_Kistler_L", "N m"), "{file}");
            assert_eq!(c.values, want, "{file}");
        }
    }
}

#[test]
fn logical_reads_as_zero_and_one() {
    let l = load("logical.mat");
    let want: Vec<f64> = (0..N).map(|k| if k % 3 == 0 { 1.0 } else { 0.0 }).collect();
    assert_eq!(values(&l, "brake_on"), want);
}

#[test]
fn matlab_style_smaller_storage_types_read_as_their_values_in_both_byte_orders() {
    for file in ["stored_small_le.mat", "stored_small_be.mat"] {
        let l = load(file);
        let scaled = |f: f64, off: f64| -> Vec<f64> { (0..N).map(|k| (k as f64 - off) * f).collect() };
        assert_eq!(l.measurement.time_s, (0..N).map(|k| 0.001 * k as f64).collect::<Vec<_>>());
        let c = l.measurement.signal("C_Kistler_L").unwrap();
        // The unit is UTF-16 char data in a compressed element, next to plain elements.
        assert_eq!((c.unit.as_str(), &c.values), ("N m", &k_minus(50.0)), "{file}");
        assert_eq!(values(&l, "count_u8"), scaled(1.0, 0.0), "{file}: double as miUINT8");
        assert_eq!(values(&l, "count_u16"), scaled(500.0, 0.0), "{file}: double as miUINT16");
        assert_eq!(values(&l, "big_i32"), scaled(100000.0, 50.0), "{file}: double as miINT32");
        assert_eq!(values(&l, "single_i16"), k_minus(50.0), "{file}: single as miINT16");
        assert_eq!(values(&l, "int32_i16"), k_minus(50.0), "{file}: int32 as miINT16");
    }
}

#[test]
fn wrong_content_is_named_with_what_was_expected() {
    // Required, so that before the fix the char array showed up as a missing channel.
    let opts = LoadOptions { required: vec!["C_Kistler_L".into()], ..LoadOptions::default() };
    let cases = [
        (
            "char_channel.mat",
            "variable `C_Kistler_L` is a 1x3 char array; a numeric vector (channel) was expected",
        ),
        (
            "matrix_channel.mat",
            "variable `C_Kistler_L` is a 100x2 array; a channel must be a vector (1xN or Nx1)",
        ),
        ("complex_channel.mat", "variable `C_Kistler_L` is complex; a channel must be a real numeric vector"),
        ("cell_var.mat", "variable `notes` is a cell array; a numeric vector (channel) was expected"),
        ("struct_var.mat", "variable `meta` is a struct array; a numeric vector (channel) was expected"),
        ("sparse_var.mat", "variable `stiff` is a sparse array; a numeric vector (channel) was expected"),
        (
            "short_channel.mat",
            "channel \"C_Kistler_L\" (variable `C_Kistler_L`) has 99 samples, time has 100",
        ),
        (
            "nan_channel.mat",
            "channel \"I_XLML 2.2\" (variable `I_XLML_2_2`), sample 8: value NaN is not finite",
        ),
    ];
    for (file, want) in cases {
        let e = err(file, &opts);
        assert!(e.contains(want), "{file}: {e}");
    }
}

/// Lengths at which `b` ends right after a whole element (with or without its padding):
/// a valid, shorter MAT file, which no reader can tell from a cut one.
fn element_ends(b: &[u8]) -> Vec<usize> {
    let le = &b[126..128] == b"IM";
    let u32_at = |p: usize| {
        let a: [u8; 4] = b[p..p + 4].try_into().unwrap();
        if le {
            u32::from_le_bytes(a)
        } else {
            u32::from_be_bytes(a)
        }
    };
    let (mut p, mut ends) = (128, vec![128]);
    while p < b.len() {
        let (ty, size) = (u32_at(p), u32_at(p + 4) as usize);
        let end = p + 8 + size;
        let padded = if ty == 15 { end } else { p + 8 + size.div_ceil(8) * 8 };
        ends.extend(end..=padded);
        p = padded;
    }
    ends
}

#[test]
fn a_file_cut_at_any_byte_is_reported_truncated() {
    let cut = Path::new("cut.mat");
    for file in ["class_int32.mat", "class_int32_z.mat", "stored_small_be.mat", "cell_var.mat"] {
        let full = std::fs::read(fixture(file)).unwrap();
        let ends = element_ends(&full);
        let mut checked = 0;
        for len in 1..full.len() {
            let r = parse_bytes(cut, full[..len].to_vec(), &LoadOptions::default());
            if ends.contains(&len) && len > 128 {
                continue; // a valid shorter file: loads, or fails for what it lacks
            }
            let e = r.expect_err(&format!("{file} cut at {len}")).to_string();
            assert!(e.starts_with("cut.mat: "), "{e}");
            assert!(e.contains("truncated"), "{file} cut at {len}: {e}");
            if len < 128 {
                assert!(e.contains("inside the 128-byte header"), "{e}");
            }
            checked += 1;
        }
        assert!(checked > full.len() * 9 / 10, "{file}: {checked} of {}", full.len());
    }
    let e = parse_bytes(cut, Vec::new(), &LoadOptions::default()).unwrap_err().to_string();
    assert_eq!(e, "cut.mat: empty file");
}

/// xorshift64: reproducible pseudo-random bytes without a dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// A cheap stand-in for the fuzzer: damaged fixtures (bytes, sizes, dimensions changed)
/// give errors or tables, never a panic.
#[test]
fn damaged_files_never_panic() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let files = ["class_double.mat", "class_int16_z.mat", "stored_small_le.mat", "cell_var.mat"];
    for file in files {
        let full = std::fs::read(fixture(file)).unwrap();
        for _ in 0..1500 {
            let mut b = full.clone();
            for _ in 0..1 + rng.below(3) {
                let at = 128 + rng.below(b.len() - 128);
                match rng.below(3) {
                    0 => b[at] = rng.next() as u8,
                    1 => b[at] ^= 1 << rng.below(8),
                    _ => {
                        let v = [0u32, 1, 3, 7, 8, 0x7fff_ffff, 0xffff_ffff][rng.below(7)].to_le_bytes();
                        let at = at.min(b.len() - 4);
                        b[at..at + 4].copy_from_slice(&v);
                    }
                }
            }
            let _ = parse_bytes(Path::new("x.mat"), b, &LoadOptions::default());
        }
    }
    for _ in 0..2000 {
        let mut b = std::fs::read(fixture("class_int8.mat")).unwrap()[..128].to_vec();
        b.extend((0..rng.below(200)).map(|_| rng.next() as u8));
        let _ = parse_bytes(Path::new("x.mat"), b, &LoadOptions::default());
    }
}

/// A compressed element whose declared size is too short for its zlib stream: the stream
/// ends early, which is a truncation too.
#[test]
fn a_compressed_stream_that_ends_early_is_truncated() {
    let full = std::fs::read(fixture("class_int32_z.mat")).unwrap();
    let size = u32::from_le_bytes(full[132..136].try_into().unwrap()) as usize;
    for short in [1, 2, 4, 5, 9, size / 2, size - 3] {
        let mut b = full[..128].to_vec();
        b.extend_from_slice(&15u32.to_le_bytes());
        b.extend_from_slice(&((size - short) as u32).to_le_bytes());
        b.extend_from_slice(&full[136..136 + size - short]);
        let e = parse_bytes(Path::new("z.mat"), b, &LoadOptions::default()).unwrap_err().to_string();
        assert!(
            e.contains("compressed element at byte 128 ends early: the file is truncated"),
            "{short}: {e}"
        );
    }
}
