//! Reader tests: every malformed case names file, line (CSV) and channel; equivalent
//! files load to equal measurements.

use std::path::{Path, PathBuf};

use super::*;

fn file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn err(path: &Path, opts: &LoadOptions) -> String {
    load_with(path, opts).unwrap_err().to_string()
}

fn strict() -> LoadOptions {
    LoadOptions::default()
}

const GOOD: &str = "\
time [s],C_Kistler_L [N m],SuTMotorEnc [rpm],Accel 1 Z [g]
0.001,1.5,100,0.01
0.002,-2.25,200.5,0.02
0.003,3,300,0.03
";

#[test]
fn reads_a_plain_csv_and_keeps_extra_channels() {
    let d = tempfile::tempdir().unwrap();
    let m = load(&file(d.path(), "a.csv", GOOD), None).unwrap();
    assert_eq!(m.time_s, [0.001, 0.002, 0.003]);
    let c = m.signal("C_Kistler_L").unwrap();
    assert_eq!((c.unit.as_str(), c.values.clone()), ("N m", vec![1.5, -2.25, 3.0]));
    let x = m.signal("Accel 1 Z").unwrap();
    assert_eq!((x.unit.as_str(), x.values[2]), ("g", 0.03));
    assert_eq!(m.gap_mask(), [false; 3]);
}

#[test]
fn decimal_comma_equals_decimal_point() {
    let d = tempfile::tempdir().unwrap();
    let comma = "Time [s];C_Kistler_L [N m];SuTMotorEnc [rpm];Accel 1 Z [g]\r\n\
                 0,001;1,5;100;0,01\r\n0,002;-2,25;200,5;0,02\r\n0,003;3;300;0,03\r\n";
    let a = load(&file(d.path(), "p.csv", GOOD), None).unwrap();
    let b = load(&file(d.path(), "c.csv", comma), None).unwrap();
    assert_eq!(a.time_s, b.time_s);
    assert_eq!(a.signals, b.signals);
    // Tabs with a second header row of units, `Name (unit)` and quotes are equivalent too.
    let tabs = "t\t\"C_Kistler_L\"\tSuTMotorEnc (rpm)\tAccel 1 Z\n[s]\tN m\t\tg\n\
                0,001\t1,5\t100\t0,01\n0,002\t-2,25\t200,5\t0,02\n0,003\t3\t300\t0,03\n";
    let c = load(&file(d.path(), "t.tsv", tabs), None).unwrap();
    assert_eq!(a.signals, c.signals);
}

#[test]
fn latin1_units_and_a_temperature_called_t() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("l.csv");
    // `µs` in Latin-1 (0xB5), as older Windows exports write it.
    std::fs::write(&p, b"zeit [\xb5s];T [\xb0C]\n1000;20,5\n2000;21\n").unwrap();
    let m = load(&p, None).unwrap();
    assert_eq!(m.time_s, [0.001, 0.002]);
    let t = m.signal("T").unwrap();
    assert_eq!((t.unit.as_str(), t.values.clone()), ("°C", vec![20.5, 21.0]));
}

#[test]
fn column_order_does_not_matter() {
    let d = tempfile::tempdir().unwrap();
    let swapped = "\
SuTMotorEnc [rpm],Accel 1 Z [g],C_Kistler_L [N m],time [s]
100,0.01,1.5,0.001
200.5,0.02,-2.25,0.002
300,0.03,3,0.003
";
    let a = load(&file(d.path(), "a.csv", GOOD), None).unwrap();
    let b = load(&file(d.path(), "b.csv", swapped), None).unwrap();
    assert_eq!(a.time_s, b.time_s);
    for s in &a.signals {
        assert_eq!(Some(s), b.signal(&s.name));
    }
}

#[test]
fn mat_and_csv_of_the_same_data_load_identically() {
    let d = tempfile::tempdir().unwrap();
    let mut x = 0.123_456_789_f64;
    let n = 500;
    let time_s: Vec<f64> = (1..=n).map(|k| k as f64 / 1000.0).collect();
    let mut sig = |name: &str, unit: &str| Signal {
        name: name.into(),
        unit: unit.into(),
        values: (0..n)
            .map(|_| {
                x = (x * 3.9 * (1.0 - x)).abs() % 1.0; // chaotic: all digits used
                (x - 0.5) * 1e3
            })
            .collect(),
    };
    let m = Measurement {
        source: "x".into(),
        time_s,
        signals: vec![
            sig("I_XLML 2.2", "A"),
            sig("SuT Throttle", "%"),
            sig("T_Kistler_R", "rpm"),
            sig("Strain gauge.3", "um/m"),
        ],
    };
    let csv_p = d.path().join("m.csv");
    let mat_p = d.path().join("m.mat");
    write::save(&csv_p, &m).unwrap();
    write::save(&mat_p, &m).unwrap();
    let a = load(&csv_p, None).unwrap();
    let mut b = load(&mat_p, None).unwrap();
    assert_eq!(a.time_s, m.time_s);
    assert_eq!(a.signals[..3], m.signals[..3]);
    // The unknown channel keeps its sanitized MATLAB name.
    assert_eq!(b.signals[3].name, "Strain_gauge_3");
    b.signals[3].name = "Strain gauge.3".into();
    assert_eq!((a.time_s, a.signals), (b.time_s, b.signals));
}

#[test]
fn compressed_mat_reads_the_same() {
    use std::io::Write;
    let d = tempfile::tempdir().unwrap();
    let m = load(&file(d.path(), "a.csv", GOOD), None).unwrap();
    let mut plain = Vec::new();
    mat::write(&mut plain, &m).unwrap();
    // Re-pack every top-level element as miCOMPRESSED, as `save -v7` does.
    let mut packed = plain[..128].to_vec();
    let mut p = 128;
    while p < plain.len() {
        let len = u32::from_le_bytes(plain[p + 4..p + 8].try_into().unwrap()) as usize;
        let mut enc = libflate::zlib::Encoder::new(Vec::new()).unwrap();
        enc.write_all(&plain[p..p + 8 + len]).unwrap();
        let z = enc.finish().into_result().unwrap();
        packed.extend_from_slice(&15u32.to_le_bytes());
        packed.extend_from_slice(&(z.len() as u32).to_le_bytes());
        packed.extend_from_slice(&z);
        p += 8 + len;
    }
    let path = d.path().join("z.mat");
    std::fs::write(&path, packed).unwrap();
    let z = load(&path, None).unwrap();
    assert_eq!(z.time_s, m.time_s);
    assert_eq!(z.signals[..2], m.signals[..2]);
    assert_eq!(z.signals[2].name, "Accel_1_Z");
    assert_eq!(z.signals[2].unit, "g");
}

#[test]
fn missing_required_channels_are_listed() {
    let d = tempfile::tempdir().unwrap();
    let p = file(d.path(), "a.csv", GOOD);
    let opts = LoadOptions {
        required: vec!["C_Kistler_L".into(), "C_Kistler_R".into(), "SiemensEnc".into()],
        ..strict()
    };
    let e = err(&p, &opts);
    assert!(e.starts_with(&format!("{}:1: ", p.display())), "{e}");
    assert!(e.contains("\"C_Kistler_R\", \"SiemensEnc\""), "{e}");
    assert!(!e.contains("\"C_Kistler_L\""), "{e}");
    let m = load(&p, None).unwrap();
    let e = m.require(&["SuTMotorEnc", "I_DC"]).unwrap_err().to_string();
    assert!(e.contains("a.csv") && e.contains("\"I_DC\"") && !e.contains("SuTMotorEnc"), "{e}");
}

#[test]
fn time_must_increase() {
    let d = tempfile::tempdir().unwrap();
    let dup = file(d.path(), "dup.csv", "t,x\n# c\n0.001,1\n0.002,2\n0.002,3\n");
    let e = err(&dup, &strict());
    assert!(e.starts_with(&format!("{}:5: ", dup.display())), "{e}");
    assert!(e.contains("\"t\"") && e.contains("duplicated"), "{e}");
    let back = file(d.path(), "back.csv", "t,x\n0.001,1\n0.003,2\n0.002,3\n");
    let e = err(&back, &strict());
    assert!(e.starts_with(&format!("{}:4: ", back.display())) && e.contains("goes back"), "{e}");
}

#[test]
fn irregular_sampling_is_resampled_onto_the_median_interval() {
    let d = tempfile::tempdir().unwrap();
    // Intervals 1, 1.5, 0.5, 1, 1 ms: median 1 ms, beyond the 1 % jitter tolerance.
    let p = file(d.path(), "j.csv", "time [ms],x\n0,0\n1,10\n2.5,25\n3,30\n4,40\n5,50\n");
    let l = load_with(&p, &strict()).unwrap();
    assert_eq!(l.resampled_dt, Some(1e-3));
    assert!(l.notes.iter().any(|n| n.contains("resampled")), "{:?}", l.notes);
    let m = l.measurement;
    assert_eq!(m.time_s.len(), 6);
    let x = &m.signal("x").unwrap().values;
    for (t, v) in m.time_s.iter().zip(x) {
        assert!((v - t * 1e4).abs() < 1e-9, "{t} {v}");
    }
    // Within tolerance: times kept exactly as read.
    let q = file(d.path(), "k.csv", "t,x\n0,0\n0.001,1\n0.002004,2\n0.003,3\n");
    let l = load_with(&q, &strict()).unwrap();
    assert_eq!(l.resampled_dt, None);
    assert_eq!(l.measurement.time_s[2], 0.002004);
}

#[test]
fn gaps_are_errors_unless_allowed() {
    let d = tempfile::tempdir().unwrap();
    let mut text = String::from("time [s];I_DC [A]\n");
    for k in (0..10).chain(30..40) {
        text.push_str(&format!("{};{}\n", k as f64 * 0.01, k));
    }
    let p = file(d.path(), "g.csv", &text);
    let e = err(&p, &strict());
    // Sample 11 (t = 0.3) is on line 12.
    assert!(e.starts_with(&format!("{}:12: ", p.display())), "{e}");
    assert!(e.contains("gap") && e.contains("--allow-gaps") && e.contains("\"time\""), "{e}");
    let l = load_with(&p, &LoadOptions { allow_gaps: true, ..strict() }).unwrap();
    assert_eq!(l.gaps.len(), 1);
    assert!((l.gaps[0].0 - 0.09).abs() < 1e-12 && (l.gaps[0].1 - 0.3).abs() < 1e-12);
    let m = &l.measurement;
    assert_eq!(m.time_s.len(), 40);
    let mask = m.gap_mask();
    assert_eq!(mask.iter().filter(|g| **g).count(), 20); // 0.10 ..= 0.29
    assert!(!mask[9] && mask[10] && mask[29] && !mask[30]);
    assert_eq!(m.signal(GAP_CHANNEL).unwrap().unit, "-");
}

#[test]
fn non_finite_values_are_located() {
    let d = tempfile::tempdir().unwrap();
    let p = file(d.path(), "n.csv", "time [s],C_Kistler_L [N m],V_DC [V]\n0.001,1,24\n0.002,1,NaN\n");
    let e = err(&p, &strict());
    assert_eq!(e, format!("{}:3:9: channel \"V_DC\": value NaN is not finite", p.display()));
    let p = file(d.path(), "i.csv", "time [s];C_Kistler_L [N m]\n0,001;-inf\n");
    let e = err(&p, &strict());
    assert!(e.starts_with(&format!("{}:2:7: ", p.display())) && e.contains("\"C_Kistler_L\""), "{e}");
}

#[test]
fn units_of_known_channels_are_checked_and_converted() {
    let d = tempfile::tempdir().unwrap();
    let p = file(
        d.path(),
        "u.csv",
        "time [ms],SuTMotorEnc [rad/s],C_Kistler_L [kNm],Temp [°C]\n1,10,0.5,20\n2,20,0.25,21\n",
    );
    let m = load(&p, None).unwrap();
    assert_eq!(m.time_s, [0.001, 0.002]);
    let w = m.signal("SuTMotorEnc").unwrap();
    assert_eq!(w.unit, "rpm");
    assert!((w.values[0] - 10.0 * 30.0 / std::f64::consts::PI).abs() < 1e-9);
    assert_eq!(m.signal("C_Kistler_L").unwrap().values, [500.0, 250.0]);
    assert_eq!(m.signal("Temp").unwrap().unit, "°C");

    let bad = file(d.path(), "hz.csv", "time [s],T_Kistler_L [Hz]\n0.001,1\n");
    let e = err(&bad, &strict());
    assert!(e.starts_with(&format!("{}:1: ", bad.display())), "{e}");
    assert!(e.contains("\"T_Kistler_L\"") && e.contains("`Hz`") && e.contains("rpm"), "{e}");

    let none = file(d.path(), "none.csv", "time,I_DC\n0.001,1\n");
    let e = err(&none, &strict());
    assert!(e.contains("\"I_DC\" has no unit; expected A"), "{e}");
}

#[test]
fn empty_and_truncated_files() {
    let d = tempfile::tempdir().unwrap();
    let p = file(d.path(), "e.csv", "");
    assert_eq!(err(&p, &strict()), format!("{}: empty file: no header line", p.display()));
    let p = file(d.path(), "h.csv", "time [s],I_DC [A]\n\n");
    assert!(err(&p, &strict()).contains("no data rows"));
    let p = file(d.path(), "e.mat", "");
    assert_eq!(err(&p, &strict()), format!("{}: empty file", p.display()));

    let p = file(d.path(), "t.csv", "time [s],I_DC [A],V_DC [V]\n0.001,1,24\n0.002,1,24\n0.003,1\n");
    let e = err(&p, &strict());
    assert!(e.starts_with(&format!("{}:4:", p.display())), "{e}");
    assert!(e.contains("truncated row") && e.contains("\"V_DC\""), "{e}");

    let p = file(d.path(), "x.csv", "time [s],I_DC [A]\n0.001,1,7\n");
    let e = err(&p, &strict());
    assert!(e.starts_with(&format!("{}:2:9: ", p.display())), "{e}");
    // Trailing separators are fine.
    let p = file(d.path(), "ok.csv", "time [s];I_DC [A];\n0,001;1;\n");
    assert_eq!(load(&p, None).unwrap().signals.len(), 1);
}

#[test]
fn bad_fields_and_headers() {
    let d = tempfile::tempdir().unwrap();
    let p = file(d.path(), "b.csv", "time [s],I_DC [A]\n0.001,1\n0.002,\n0.003,x1\n");
    let e = err(&p, &strict());
    assert_eq!(e, format!("{}:3:7: channel \"I_DC\": empty value", p.display()));
    let p = file(d.path(), "c.csv", "time [s];I_DC [A]\n0,001;1.000,5\n");
    let e = err(&p, &strict());
    assert!(e.contains("`1.000,5` is not a number"), "{e}");
    let p = file(d.path(), "n.csv", "I_DC [A],V_DC [V]\n1,2\n");
    assert!(err(&p, &strict()).contains("no time column"));
    let p = file(d.path(), "d.csv", "t,I_DC [A],I_DC [A]\n0,1,2\n");
    let e = err(&p, &strict());
    assert!(e.contains("\"I_DC\" appears twice"), "{e}");
    let p = file(d.path(), "u.csv", "t [s],I_DC [A]\n[s],[mA]\n0,1\n");
    let e = err(&p, &strict());
    assert!(e.starts_with(&format!("{}:2:5: ", p.display())) && e.contains("\"I_DC\""), "{e}");
    let p = file(d.path(), "a.csv", "time [s],I_DC [A]\n0.001x,1\n");
    let e = err(&p, &strict());
    assert!(e.starts_with(&format!("{}:2:1: ", p.display())) && e.contains("`0.001x`"), "{e}");
    let p = file(d.path(), "x.dat", "t\n");
    assert!(err(&p, &strict()).contains("expected a .csv or .mat"));
}

#[test]
fn mapping_renames_scales_and_sets_units() {
    let d = tempfile::tempdir().unwrap();
    let p = file(d.path(), "o.csv", "t,Torque L,Speed L,Other\n0.001,2,10,5\n0.002,4,20,6\n");
    let map = file(
        d.path(),
        "map.toml",
        "[rename]\n\"Torque L\" = \"C_Kistler_L\"\n\"Speed L\" = \"T_Kistler_L\"\nnothing = \"x\"\n\
         [scale]\n\"Torque L\" = -1\n[unit]\n\"Torque L\" = \"N m\"\n\"Speed L\" = \"rpm\"\n",
    );
    let opts = LoadOptions { mapping: Some(Mapping::load(&map).unwrap()), ..strict() };
    let l = load_with(&p, &opts).unwrap();
    let m = &l.measurement;
    assert_eq!(m.signal("C_Kistler_L").unwrap().values, [-2.0, -4.0]);
    assert_eq!(m.signal("T_Kistler_L").unwrap().unit, "rpm");
    assert!(m.signal("Torque L").is_none() && m.signal("Other").is_some());
    assert!(l.notes.iter().any(|n| n.contains("\"nothing\"")), "{:?}", l.notes);
    // Without the mapping, the renamed channel is missing.
    let e = err(&p, &LoadOptions { required: vec!["C_Kistler_L".into()], ..strict() });
    assert!(e.contains("missing required channel(s) \"C_Kistler_L\""), "{e}");
    // A mapping file error is located in the mapping file.
    let bad = file(d.path(), "bad.toml", "[scale]\n\"Torque L\" = \"x\"\n");
    let e = load(&p, Some(&bad)).unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}:2:", bad.display())), "{e}");
}

#[test]
fn mat_errors_name_the_variable() {
    let d = tempfile::tempdir().unwrap();
    let m = Measurement {
        source: "x".into(),
        time_s: vec![0.001, 0.002, 0.003],
        signals: vec![Signal { name: "I_DC".into(), unit: "A".into(), values: vec![1.0, f64::NAN, 3.0] }],
    };
    let p = d.path().join("nan.mat");
    write::save(&p, &m).unwrap();
    let e = err(&p, &strict());
    assert_eq!(e, format!("{}: channel \"I_DC\", sample 2: value NaN is not finite", p.display()));
    let mut short = m.clone();
    short.signals[0].values = vec![1.0, 2.0, 3.0];
    short.signals.push(Signal { name: "V_DC".into(), unit: "V".into(), values: vec![24.0, 24.0, 24.0] });
    let mut buf = Vec::new();
    mat::write(&mut buf, &short).unwrap();
    let mut other = short.clone();
    other.time_s.pop();
    other.signals = vec![Signal { name: "SiemensEnc".into(), unit: "rpm".into(), values: vec![1.0, 2.0] }];
    let mut extra = Vec::new();
    mat::write(&mut extra, &other).unwrap();
    // Append the 2-sample SiemensEnc (skip the second file's header, time and time_unit).
    let mut p2 = 128;
    for _ in 0..2 {
        let len = u32::from_le_bytes(extra[p2 + 4..p2 + 8].try_into().unwrap()) as usize;
        p2 += 8 + len;
    }
    buf.extend_from_slice(&extra[p2..]);
    let p = d.path().join("len.mat");
    std::fs::write(&p, &buf).unwrap();
    let e = err(&p, &strict());
    assert!(e.contains("\"SiemensEnc\" (variable `SiemensEnc`) has 2 samples, time has 3"), "{e}");

    let mut v73 = vec![b' '; 128];
    v73[..6].copy_from_slice(b"MATLAB");
    v73[124..126].copy_from_slice(&0x0200u16.to_le_bytes());
    v73[126..128].copy_from_slice(b"IM");
    let p = d.path().join("v73.mat");
    std::fs::write(&p, &v73).unwrap();
    assert!(err(&p, &strict()).contains("v7.3"));
    let p = d.path().join("cut.mat");
    std::fs::write(&p, &buf[..buf.len() - 20]).unwrap();
    let e = err(&p, &strict());
    assert!(e.contains("not a readable MAT v5/v7 file: element runs past the end"), "{e}");
    let mut odd = buf.clone();
    odd[128] = 3; // first element's type: miINT16 at the top level
    std::fs::write(&p, &odd).unwrap();
    let e = err(&p, &strict());
    assert!(e.contains("unexpected element type 3 at byte 128"), "{e}");
    let p = file(d.path(), "garbage.mat", "hello");
    assert!(err(&p, &strict()).contains("not a MAT file"));
}

#[test]
fn a_row_without_its_newline_is_a_cut_write_not_a_shorter_number() {
    let d = tempfile::tempdir().unwrap();
    let cut = GOOD.trim_end_matches('\n');
    let last = cut.lines().count();
    let e = err(&file(d.path(), "cut.csv", cut), &LoadOptions::default());
    assert!(e.contains(&format!("cut.csv:{last}:1:")) && e.contains("ends inside this row"), "{e}");
    // A trailing comment or blank line after the last row is fine.
    assert!(load(&file(d.path(), "c.csv", &format!("{GOOD}# end")), None).is_ok());
}

/// Fuzzer regression (fuzz/regressions/csv/resample-interp-overflow-inf.csv): values near
/// ±f64::MAX on an irregular grid interpolate to finite values, not ±inf.
#[test]
fn resampling_extreme_values_stays_finite() {
    let bytes = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fuzz/regressions/csv/resample-interp-overflow-inf.csv"
    ))
    .unwrap();
    let l = super::parse_bytes(Path::new("r.csv"), bytes, &LoadOptions::default()).unwrap();
    assert!(l.resampled_dt.is_some());
    for s in &l.measurement.signals {
        assert!(s.values.iter().all(|v| v.is_finite()), "{}: {:?}", s.name, s.values);
    }
}
