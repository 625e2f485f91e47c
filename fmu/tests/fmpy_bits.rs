//! FMPy (an independent importer, written in Python) simulates the packaged FMU
//! headless on TP07's set points, given as an input table, and every output at every
//! step equals the host simulation (`model_core::Simulation`, what `simrod simulate`
//! runs and writes) bit for bit: the FMU's f32 values are carried exactly in float64.
//!
//! Why the set points reach the FMU exactly: `simrod simulate` applies the profile's
//! value at each step's start (`Simulation::inputs`); the table has one row per step at
//! t = k x 0.001 s, which is the communication point FMPy computes (start + k x
//! interval, the same float64 product), so FMPy's linear interpolation lands on the row
//! itself (weights 0 and 1) and passes the row's float64 value, the f32 set point
//! exactly.

mod support;

use std::fmt::Write as _;

use model_core::{Builtin, Channel, Config, Profile, Simulation};

#[test]
fn fmpy_on_tp07_equals_the_host_simulation_bit_for_bit() {
    let dir = support::scratch("tp07");
    let fmu = support::default_fmu();
    let env = support::py_env();

    // The reference: the host simulation, and the set points it applied at each step.
    let profile = Profile::builtin(Builtin::TP07, 1.0, 1.0).unwrap();
    let mut sim = Simulation::new(&Config::default(), profile, 24.0).unwrap();
    let mut table =
        String::from("time,throttle_set_point,load_L_set_point,load_R_set_point,supply_voltage\n");
    let mut reference = Vec::new();
    loop {
        let inp = sim.inputs();
        let Some(out) = sim.step() else { break };
        let t = reference.len() as f64 * 0.001;
        let sp = inp.sp;
        let _ =
            writeln!(table, "{t},{},{},{},{}", sp.throttle_pct, sp.load_pct[0], sp.load_pct[1], inp.supply_v);
        reference.push(out);
    }
    let n = reference.len();
    assert_eq!(n, 60_000, "TP07 is 60 s of 1 ms steps");
    let input = dir.join("tp07_inputs.csv");
    std::fs::write(&input, table).unwrap();

    let t0 = std::time::Instant::now();
    let prefix = dir.join("fmpy");
    let stop = format!("{}", n as f64 * 0.001);
    let script = support::ws("fmu/tests/py/fmpy_run.py");
    let o = support::run(&env.join("bin/python"), &[&script, &fmu, &input, &stop, &"0.001", &prefix]);
    assert!(o.status.success(), "FMPy failed:\n{}", support::text(&o));
    eprintln!("FMPy simulated TP07 in {:.1} s: {}", t0.elapsed().as_secs_f64(), support::text(&o).trim());

    let names: Vec<String> = std::fs::read_to_string(prefix.with_extension("names"))
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect();
    let raw = std::fs::read(prefix.with_extension("f64")).unwrap();
    let values: Vec<f64> =
        raw.chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes"))).collect();
    let cols = names.len();
    assert_eq!(names[0], "time");
    let channels: Vec<Channel> = names[1..]
        .iter()
        .map(|n| Channel::from_name(n).unwrap_or_else(|| panic!("unknown output {n}")))
        .collect();
    assert_eq!(channels, Channel::ALL, "every channel is an output, in order");
    assert_eq!(values.len(), cols * (n + 1), "one row at t = 0, then one per step");

    let mut compared = 0usize;
    let mut mismatches = Vec::new();
    for (k, want) in reference.iter().enumerate() {
        let row = &values[(k + 1) * cols..(k + 2) * cols];
        assert!((row[0] - (k + 1) as f64 * 0.001).abs() < 1e-9, "row {} at t = {}", k + 1, row[0]);
        for (c, v) in channels.iter().zip(&row[1..]) {
            let exact = (*v as f32) as f64 == *v || v.is_nan();
            if !exact || (*v as f32).to_bits() != want.get(*c).to_bits() {
                mismatches.push(format!(
                    "t = {} s {}: FMPy {v:e}, host {:e}",
                    want.t_s(),
                    c.name(),
                    want.get(*c)
                ));
            }
            compared += 1;
        }
    }
    assert!(
        mismatches.is_empty(),
        "{} of {compared} values differ; first: {:?}",
        mismatches.len(),
        &mismatches[..mismatches.len().min(5)]
    );
    eprintln!("{n} steps x {} channels = {compared} values equal bit for bit", channels.len());
}
