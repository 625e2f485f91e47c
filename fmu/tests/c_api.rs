//! The FMU's C API, called as an importer calls it: the packaged binary loaded with
//! `dlopen`, its functions typed from the FMI 3.0 header. Bad calls (unknown value
//! reference, wrong count, wrong state, wrong token, a step that is not a whole
//! multiple of the twin's, NULL pointers) return `fmi3Error` and log why; instances
//! are independent; `fmi3Reset` restores the start values; any communication steps give
//! the same outputs at the instants they share, equal to model-core's own run.

mod support;

use std::ptr::null_mut;
use std::sync::OnceLock;

use model_core::{
    Builtin, Config, CouplingStiffness, Effects, Inputs, Model, Params, Profile, RateSet, N_CHANNELS,
};
use simrod_fmu::vars::{Var, VR_TIME};
use support::capi::{Fmu, Inst, ERROR, OK};

const DT: f64 = 0.001;

fn fmu() -> &'static Fmu {
    static F: OnceLock<Fmu> = OnceLock::new();
    F.get_or_init(|| Fmu::load(support::default_fmu(), &support::scratch("extracted")))
}

/// The value reference of a variable, by name.
fn vr(name: &str) -> u32 {
    Var::all().iter().find(|v| v.name() == name).unwrap_or_else(|| panic!("no variable {name}")).vr()
}

fn outputs_vrs() -> Vec<u32> {
    Var::all().iter().filter(|v| matches!(v, Var::Output(_))).map(Var::vr).collect()
}

fn input_vrs() -> [u32; 4] {
    ["throttle_set_point", "load_L_set_point", "load_R_set_point", "supply_voltage"].map(vr)
}

/// The TP07 set points at the start of each of the first `n` steps, 24 V.
fn tp07_inputs(n: usize) -> Vec<Inputs> {
    let p = Profile::builtin(Builtin::TP07, 1.0, 1.0).unwrap();
    (0..n as u64).map(|k| Inputs { sp: p.at(k * 1000), supply_v: 24.0 }).collect()
}

fn set_inputs(inst: &Inst<'_>, i: &Inputs) {
    let v = [i.sp.throttle_pct, i.sp.load_pct[0], i.sp.load_pct[1], i.supply_v].map(f64::from);
    assert_eq!(inst.set(&input_vrs(), &v), OK, "{}", inst.log());
}

/// Step once per input (h = dt), recording every output after each step.
fn run(inst: &Inst<'_>, inputs: &[Inputs]) -> Vec<Vec<f64>> {
    let outs = outputs_vrs();
    inputs
        .iter()
        .enumerate()
        .map(|(k, i)| {
            set_inputs(inst, i);
            let (s, last) = inst.step(k as f64 * DT, DT);
            assert_eq!(s, OK, "step {k}: {}", inst.log());
            assert!((last - (k + 1) as f64 * DT).abs() < 1e-12, "lastSuccessfulTime {last} after step {k}");
            let (s, v) = inst.get(&outs);
            assert_eq!(s, OK, "{}", inst.log());
            v
        })
        .collect()
}

/// The host model's run on the same inputs: every channel as f64.
fn host(cfg: &Config, inputs: &[Inputs]) -> Vec<Vec<f64>> {
    let mut m = Model::new(cfg).unwrap();
    inputs.iter().map(|i| m.step(i).values.iter().map(|v| f64::from(*v)).collect()).collect()
}

fn bits(rows: &[Vec<f64>]) -> Vec<Vec<u64>> {
    rows.iter().map(|r| r.iter().map(|v| v.to_bits()).collect()).collect()
}

/// `status` is fmi3Error and the last log message names `needle`; then reset.
#[track_caller]
fn refused(inst: &Inst<'_>, status: i32, needle: &str) {
    assert_eq!(status, ERROR, "expected fmi3Error; log:\n{}", inst.log());
    let last = inst.last();
    assert!(
        last.starts_with("[3] logStatusError: ") && last.contains(needle),
        "{last:?} should name {needle:?}"
    );
    assert_eq!(inst.reset(), OK);
}

#[test]
fn every_function_of_the_fmi3_header_is_exported() {
    // The standard's header as FMPy ships it: independent of this crate's list.
    let env = support::py_env();
    let lib = std::fs::read_dir(env.join("lib"))
        .unwrap()
        .flatten()
        .find(|e| e.file_name().to_string_lossy().starts_with("python3"));
    let header = lib.unwrap().path().join("site-packages/fmpy/c-code/fmi3Functions.h");
    let text = std::fs::read_to_string(&header).unwrap_or_else(|e| panic!("{}: {e}", header.display()));
    let names: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("FMI3_Export") && l.contains("TYPE"))
        .filter_map(|l| l.trim_end_matches(';').split_whitespace().last())
        .collect();
    assert_eq!(names.len(), 75, "FMI 3.0 declares 75 functions; {} in {}", names.len(), header.display());
    let missing: Vec<&&str> = names
        .iter()
        .filter(|n| {
            // SAFETY: only looked up, never called.
            unsafe { fmu().api.lib.get::<*const ()>(format!("{n}\0").as_bytes()) }.is_err()
        })
        .collect();
    assert!(missing.is_empty(), "not exported: {missing:?}");
    eprintln!("all {} functions of fmi3Functions.h are exported", names.len());
    // SAFETY: returns a static string.
    let v = unsafe { std::ffi::CStr::from_ptr((fmu().api.get_version)()) };
    assert_eq!(v.to_str(), Ok("3.0"));
}

#[test]
fn instantiation_checks_token_resources_and_interface() {
    let f = fmu();
    let e = f.instantiate("a", "{00000000-0000-0000-0000-000000000000}", Some(&f.resources())).err().unwrap();
    assert!(e.contains("instantiation token {00000000-0000-0000-0000-000000000000} does not match"), "{e}");
    let e = f.instantiate("a", &f.token, None).err().unwrap();
    assert!(e.contains("resourcePath is NULL"), "{e}");
    let e = f.instantiate("a", &f.token, Some("/nonexistent/resources/")).err().unwrap();
    assert!(e.contains("/nonexistent/resources/simrod-fmu.toml: cannot read"), "{e}");
    let inst = f.instance("fine");
    assert!(
        !inst.log().contains("[3]") && inst.log().contains("logEvents: fine: instantiated"),
        "{}",
        inst.log()
    );

    // Model Exchange is refused with the reason, through the importer's callback.
    let log: std::sync::Mutex<Vec<String>> = Default::default();
    let env = (&log as *const std::sync::Mutex<Vec<String>>).cast_mut().cast();
    let c = |s: &str| std::ffi::CString::new(s).unwrap();
    let (n, t, r) = (c("me"), c(&f.token), c(&f.resources()));
    // SAFETY: valid strings; `env` is `log`, alive for the call.
    let p = unsafe {
        (f.api.instantiate_me)(
            n.as_ptr(),
            t.as_ptr(),
            r.as_ptr(),
            false,
            false,
            env,
            Some(support::capi::collect),
        )
    };
    assert!(p.is_null());
    assert!(log.lock().unwrap()[0].contains("Co-Simulation only"), "{:?}", log.lock().unwrap());
}

#[test]
fn bad_calls_return_errors_that_say_why() {
    let f = fmu();
    let inst = f.instance("bad");
    let thr = vr("throttle_set_point");
    let speed = vr("SuTMotorEnc");

    // Unknown value reference.
    refused(&inst, inst.get(&[99_999]).0, "unknown value reference 99999");
    // Terminated after an error until reset: getters still work, a good set is refused.
    inst.get(&[99_999]);
    assert_eq!(inst.get(&[speed]).0, OK);
    refused(&inst, inst.set(&[thr], &[1.0]), "not allowed in Terminated");
    // Wrong count: two value references, one value.
    let mut one = [0.0];
    // SAFETY: arrays of the lengths passed.
    let s = unsafe { (f.api.get_f64)(inst.ptr, [thr, speed].as_ptr(), 2, one.as_mut_ptr(), 1) };
    refused(&inst, s, "nValues = 1, but 2 scalar value references need 2 values");
    // Wrong type.
    refused(&inst, inst.get_i64(&[speed]).0, "`SuTMotorEnc`");
    let mut i = [0i32];
    // SAFETY: arrays of the lengths passed.
    let s = unsafe { (f.api.get_i32)(inst.ptr, [speed].as_ptr(), 1, i.as_mut_ptr(), 1) };
    refused(&inst, s, "cannot be accessed as Int32");
    // Wrong state.
    refused(&inst, inst.step(0.0, DT).0, "fmi3DoStep: not allowed in Instantiated (allowed in: Step Mode)");
    // SAFETY: a live instance.
    refused(&inst, unsafe { (f.api.exit_init)(inst.ptr) }, "not allowed in Instantiated");
    inst.init();
    refused(&inst, inst.set(&[vr("differential_friction.coulomb_nm")], &[1.0]), "fixed after initialization");
    // SAFETY: a live instance.
    refused(&inst, unsafe { (f.api.terminate)(inst.ptr) }, "fmi3Terminate: not allowed in Instantiated");
    // Communication steps: not a multiple of dt, not at the FMU's time, not positive.
    inst.init();
    refused(
        &inst,
        inst.step(0.0, 0.0015).0,
        "0.0015 s is not a whole multiple of the twin's fixed step 0.001 s",
    );
    inst.init();
    refused(&inst, inst.step(0.0, 0.0).0, "not a whole multiple");
    inst.init();
    refused(&inst, inst.step(0.5, DT).0, "currentCommunicationPoint = 0.5 s, but the FMU is at 0 s");
    // Values out of range, unknown items, variables that cannot be set.
    refused(&inst, inst.set(&[thr], &[150.0]), "throttle_set_point = 150: expected a value in [-100, 100] %");
    refused(&inst, inst.set(&[thr], &[f64::NAN]), "throttle_set_point = NaN");
    refused(&inst, inst.set(&[vr("supply_voltage")], &[40.0]), "[12, 30] V");
    refused(&inst, inst.set(&[vr("controller_delay.delay_s")], &[20.0]), "must be in [0, 10] s");
    refused(&inst, inst.set_i64(&[vr("rate_set")], &[7]), "rate_set = 7 is not an item of RateSet");
    refused(&inst, inst.set(&[speed], &[1.0]), "output `SuTMotorEnc` (Float64, value reference");
    refused(&inst, inst.set(&[VR_TIME], &[1.0]), "cannot be set");
    // A controller delay the model would cap is refused at initialization.
    inst.set(&[vr("controller_delay.delay_s")], &[1.0]);
    // SAFETY: a live instance.
    unsafe { (f.api.enter_init)(inst.ptr, false, 0.0, 0.0, false, 0.0) };
    // SAFETY: a live instance.
    refused(&inst, unsafe { (f.api.exit_init)(inst.ptr) }, "the model holds at most 256 steps");
    // Unsupported capabilities say so.
    let mut state = null_mut();
    // SAFETY: a live instance and a valid output pointer.
    refused(
        &inst,
        unsafe { (f.api.get_fmu_state)(inst.ptr, &mut state) },
        "not supported: canGetAndSetFMUState = false",
    );

    // NULL pointers.
    let mut v = [0.0];
    // SAFETY: NULL with a non-zero length is what is being refused.
    let s = unsafe { (f.api.get_f64)(inst.ptr, std::ptr::null(), 1, v.as_mut_ptr(), 1) };
    refused(&inst, s, "valueReferences is NULL, but its length is 1");
    // SAFETY: as above.
    let s = unsafe { (f.api.get_f64)(inst.ptr, [thr].as_ptr(), 1, null_mut(), 1) };
    refused(&inst, s, "values is NULL, but its length is 1");
    inst.init();
    let (mut a, mut b, mut c) = (false, false, false);
    // SAFETY: as above.
    let s = unsafe { (f.api.do_step)(inst.ptr, 0.0, DT, false, &mut a, &mut b, &mut c, null_mut()) };
    refused(&inst, s, "lastSuccessfulTime is NULL");
    // A NULL or foreign instance pointer: refused, nothing dereferenced.
    // SAFETY: invalid instances are what is being refused.
    unsafe {
        assert_eq!((f.api.reset)(null_mut()), ERROR);
        let mut x = 0u64;
        assert_eq!((f.api.reset)((&mut x as *mut u64).cast()), ERROR);
    }
    // A freed instance: refused too.
    let gone = f.instance("gone");
    let p = gone.ptr;
    drop(gone);
    // SAFETY: `p` was freed; the FMU must refuse it without touching it.
    assert_eq!(unsafe { (f.api.reset)(p) }, ERROR);

    // Zero value references with NULL arrays are fine, and the instance still works.
    // SAFETY: zero-length arrays.
    assert_eq!(unsafe { (f.api.get_f64)(inst.ptr, std::ptr::null(), 0, null_mut(), 0) }, OK);
    inst.init();
    assert_eq!(inst.step(0.0, DT).0, OK, "{}", inst.log());
}

#[test]
fn two_instances_are_independent() {
    let f = fmu();
    let inputs = tp07_inputs(3000);
    let alone = {
        let a = f.instance("alone");
        a.init();
        run(&a, &inputs)
    };
    let (a, b) = (f.instance("a"), f.instance("b"));
    // b: other parameters and inputs, stepped in between a's steps.
    assert_eq!(b.set_i64(&[vr("rate_set")], &[1]), OK);
    assert_eq!(b.set(&[vr("differential_friction.coulomb_nm")], &[5.0]), OK);
    a.init();
    b.init();
    let outs = outputs_vrs();
    let mut a_rows = Vec::new();
    for (k, i) in inputs.iter().enumerate() {
        set_inputs(&a, i);
        set_inputs(&b, &Inputs { supply_v: 18.0, ..*i });
        assert_eq!(a.step(k as f64 * DT, DT).0, OK);
        assert_eq!(b.step(k as f64 * DT, DT).0, OK);
        a_rows.push(a.get(&outs).1);
    }
    assert_eq!(bits(&a_rows), bits(&alone), "instance a changed by instance b");
    let b_last = b.get(&outs).1;
    assert_ne!(b_last, a_rows[a_rows.len() - 1], "b ran its own model");
    assert_eq!(alone.len() * N_CHANNELS, 3000 * N_CHANNELS);
}

#[test]
fn reset_restores_the_start_values() {
    let f = fmu();
    let floats: Vec<u32> = Var::all().iter().filter(|v| !matches!(v, Var::Choice(_))).map(Var::vr).collect();
    let enums: Vec<u32> = Var::all().iter().filter(|v| matches!(v, Var::Choice(_))).map(Var::vr).collect();
    let fresh = f.instance("fresh");
    let start = (fresh.get(&floats), fresh.get_i64(&enums));
    assert_eq!((start.0 .0, start.1 .0), (OK, OK));

    let inst = f.instance("reset");
    assert_eq!(inst.set_i64(&enums, &[1, 2, 2]), OK);
    assert_eq!(
        inst.set(&[vr("inertia_scale.sut"), vr("coupling_stiffness.stiffness_nm_per_rad")], &[1.3, 9000.0]),
        OK
    );
    inst.init();
    let inputs = tp07_inputs(500);
    run(&inst, &inputs);
    assert_ne!(inst.get(&floats).1, start.0 .1);
    assert_eq!(inst.reset(), OK);
    let after = (inst.get(&floats), inst.get_i64(&enums));
    let b = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(b(&after.0 .1), b(&start.0 .1), "Float64 values after reset");
    assert_eq!(after.1 .1, start.1 .1, "enumerations after reset");
    // And it runs as a fresh instance does.
    inst.init();
    fresh.init();
    assert_eq!(bits(&run(&inst, &inputs)), bits(&run(&fresh, &inputs)));
}

#[test]
fn any_communication_steps_give_the_same_outputs_as_the_host_model() {
    let f = fmu();
    // Inputs held over segments of 1, 3, 7, 2, 10 and 50 steps.
    let lens = [1usize, 3, 7, 2, 10, 50];
    let mut segs = Vec::new();
    let (mut k, mut j) = (0usize, 0usize);
    while k < 4000 {
        let n = lens[j % lens.len()];
        segs.push((k, n));
        k += n;
        j += 1;
    }
    let total = k;
    let profile = tp07_inputs(total);
    let held: Vec<Inputs> = segs.iter().flat_map(|(k, n)| std::iter::repeat_n(profile[*k], *n)).collect();

    let fine = f.instance("fine");
    fine.init();
    let fine_rows = run(&fine, &held);
    assert_eq!(bits(&fine_rows), bits(&host(&Config::default(), &held)), "h = dt vs model-core");

    let coarse = f.instance("coarse");
    coarse.init();
    let outs = outputs_vrs();
    let mut compared = 0;
    for (k, n) in &segs {
        set_inputs(&coarse, &profile[*k]);
        let (s, last) = coarse.step(*k as f64 * DT, *n as f64 * DT);
        assert_eq!(s, OK, "{}", coarse.log());
        let end = k + n;
        assert!((last - end as f64 * DT).abs() < 1e-12);
        let (_, v) = coarse.get(&outs);
        let want: Vec<u64> = fine_rows[end - 1].iter().map(|x| x.to_bits()).collect();
        assert_eq!(v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), want, "at step {end}");
        let (_, t) = coarse.get(&[VR_TIME]);
        assert!((t[0] - end as f64 * DT).abs() < 1e-12, "time {} at step {end}", t[0]);
        compared += 1;
    }
    eprintln!("{compared} communication points ({total} steps) equal bit for bit across step sizes");
}

#[test]
fn parameters_and_choices_reach_the_model() {
    let f = fmu();
    let inst = f.instance("params");
    let stiffness = vr("coupling_stiffness.stiffness_nm_per_rad");
    let model_k = |c| f64::from(Params::thesis(RateSet::Identified, c).coupling_stiffness);
    // An override left unset follows the model's value under the current choice.
    assert_eq!(inst.get(&[stiffness]).1[0], model_k(CouplingStiffness::Identified));
    assert_eq!(inst.set_i64(&[vr("coupling")], &[2]), OK);
    assert_eq!(inst.get(&[stiffness]).1[0], model_k(CouplingStiffness::Datasheet));
    assert_eq!(inst.get_i64(&[vr("coupling")]).1, [2]);

    assert_eq!(inst.set_i64(&[vr("rate_set")], &[1]), OK);
    assert_eq!(
        inst.set(&[vr("differential_friction.coulomb_nm"), vr("controller_delay.delay_s")], &[4.0, 0.012]),
        OK
    );
    // f32 in the twin: read back as the f32 it became.
    assert_eq!(inst.get(&[vr("controller_delay.delay_s")]).1[0], f64::from(0.012f32));
    inst.init();
    let inputs = tp07_inputs(4000);
    let got = run(&inst, &inputs);
    let mut fx = Effects::NONE;
    fx.differential_friction.coulomb_nm = 4.0;
    fx.controller_delay_s = 0.012;
    let cfg = Config {
        params: Params::thesis(RateSet::Programmed, CouplingStiffness::Datasheet),
        effects: fx,
        ..Config::default()
    };
    assert_eq!(bits(&got), bits(&host(&cfg, &inputs)), "FMU with parameters vs model-core with the same");
    assert_ne!(bits(&got), bits(&host(&Config::default(), &inputs)), "the parameters changed the run");
}
