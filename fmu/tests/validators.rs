//! Independent validators accept the packaged FMU: FMPy's `fmpy validate` (the model
//! description against the FMI 3.0 schema, variable names, model structure, start
//! values, causality/variability combinations, units) and the FMU Manipulation
//! Toolbox's `fmutool -check`. Both the default FMU and one with every packaging option
//! (data directory, effect file, 100 µs step, other start values), which must also run
//! what its resources hold.

mod support;

use std::path::Path;

use model_core::{Builtin, Channel, Config, CouplingStiffness, Inputs, Model, Profile, RateSet, SpeedTarget};
use simrod_fmu::package::Options;
use simrod_fmu::spec::Settings;
use simrod_fmu::vars::{Choice, Choices, Var};
use simrod_io::datadir::ModelData;
use simrod_io::effects_file::load_effects;

/// Both validators on one FMU; their reports.
fn validate(fmu: &Path) -> (String, String) {
    let env = support::py_env();
    let fmpy = support::run(&env.join("bin/fmpy"), &[&"validate", &fmu]);
    let fmpy_out = support::text(&fmpy);
    assert!(fmpy.status.success(), "fmpy validate {} failed:\n{fmpy_out}", fmu.display());
    assert!(fmpy_out.contains("No problems found."), "fmpy validate said:\n{fmpy_out}");
    let tool = support::run(&env.join("bin/fmutool"), &[&"-input", &fmu, &"-check"]);
    let tool_out = support::text(&tool);
    assert!(tool.status.success(), "fmutool -check {} failed:\n{tool_out}", fmu.display());
    // fmutool's exit status does not reflect its findings: read its report.
    let flagged = tool_out.lines().any(|l| l.starts_with("ERROR") || l.starts_with("WARNING"));
    assert!(
        !flagged
            && tool_out.contains("This FMU seems to be compliant with FMI-3.0.")
            && tool_out.contains("No semantic error against the FMI-3 standard."),
        "fmutool -check reported:\n{tool_out}"
    );
    (fmpy_out, tool_out)
}

#[test]
fn validators_accept_the_default_fmu() {
    let (fmpy, tool) = validate(support::default_fmu());
    eprintln!("fmpy validate:\n{fmpy}\nfmutool -check:\n{tool}");
}

#[test]
fn an_fmu_with_every_packaging_option_validates_and_runs_its_resources() {
    let dir = support::scratch("options");
    let mut choices = Choices::default();
    choices.set_by_name(Choice::RateSet, "programmed").unwrap();
    choices.set_by_name(Choice::Coupling, "datasheet").unwrap();
    let effects = dir.join("effects.toml");
    std::fs::write(
        &effects,
        "[controller_delay]\ndelay_s = 0.012\n\n[differential_friction]\ncoulomb_nm = 2\n",
    )
    .unwrap();
    let opts = Options {
        out: dir.join("options.fmu"),
        data_dir: Some(support::ws("model-core/data")),
        effects: Some(effects.clone()),
        settings: Settings { dt_us: 100, choices, supply_v: Some(18.0) },
    };
    let fmu = support::package_fmu(opts);
    validate(&fmu);
    let x = support::scratch("options-extracted");
    support::extract(&fmu, &x);
    let xml = std::fs::read_to_string(x.join("modelDescription.xml")).unwrap();
    assert!(xml.contains("fixedInternalStepSize=\"0.0001\""), "the step is declared");
    assert!(x.join("resources/data/parameters.toml").is_file() && x.join("resources/effects.toml").is_file());
    let line =
        |name: &str| xml.lines().find(|l| l.contains(&format!("name=\"{name}\""))).unwrap().to_string();
    assert!(line("supply_voltage").contains("start=\"18\""), "{}", line("supply_voltage"));
    assert!(line("rate_set").contains("start=\"1\""), "{}", line("rate_set"));
    // The effect file's values are the start values (f32 in the twin, exact in f64).
    assert!(line("controller_delay.delay_s").contains(&format!("start=\"{}\"", f64::from(0.012f32))));

    // And the binary runs what the resources hold: the host model with the same data,
    // effects, step and choices gives the same bits.
    let fmu = support::capi::Fmu::load(&fmu, &support::scratch("options-loaded"));
    let inst = fmu.instance("options");
    inst.init();
    let data = ModelData::load(&support::ws("model-core/data")).unwrap();
    let cfg = Config {
        dt_us: 100,
        params: data.params(RateSet::Programmed, CouplingStiffness::Datasheet),
        speed_target: SpeedTarget::Map,
        effects: load_effects(&effects).unwrap(),
    };
    let mut host = Model::with_maps(&cfg, data.maps().unwrap()).unwrap();
    let profile = Profile::builtin(Builtin::TP07, 1.0, 1.0).unwrap();
    let ins: Vec<u32> =
        ["throttle_set_point", "load_L_set_point", "load_R_set_point"].iter().map(|n| vr(n)).collect();
    let outs: Vec<u32> = Channel::ALL.iter().map(|c| vr(c.name())).collect();
    for k in 0..5000u64 {
        let sp = profile.at(k * 100);
        let v = [sp.throttle_pct, sp.load_pct[0], sp.load_pct[1]].map(f64::from);
        assert_eq!(inst.set(&ins, &v), support::capi::OK, "{}", inst.log());
        assert_eq!(inst.step(k as f64 * 1e-4, 1e-4).0, support::capi::OK, "{}", inst.log());
        let want = host.step(&Inputs { sp, supply_v: 18.0 });
        let got = inst.get(&outs).1;
        let same = got.iter().zip(want.values).all(|(g, w)| g.to_bits() == f64::from(w).to_bits());
        assert!(same, "step {k}: FMU {got:?}\nhost {:?}", want.values);
    }
}

fn vr(name: &str) -> u32 {
    Var::all().iter().find(|v| v.name() == name).unwrap().vr()
}

#[test]
fn packaging_refuses_bad_options_before_writing() {
    let dir = support::scratch("refused");
    let out = dir.join("x.fmu");
    let fx = support::ws("firmware/effects/example.toml");
    let try_ = |o: Options| simrod_fmu::package::package(&o).err().unwrap_or_default();
    let e = try_(Options { out: fx.clone(), effects: Some(fx.clone()), ..Options::default() });
    assert!(e.contains("is the input") && e.contains("--effects"), "{e}");
    let e = try_(Options {
        out: out.clone(),
        settings: Settings { dt_us: 5, ..Settings::default() },
        ..Options::default()
    });
    assert!(e.contains("--dt-us 5: expected a step in [10, 10000]"), "{e}");
    let e = try_(Options {
        out: out.clone(),
        settings: Settings { supply_v: Some(40.0), ..Settings::default() },
        ..Options::default()
    });
    assert!(e.contains("--supply-v: 40 V is outside the bench's range [12, 30] V"), "{e}");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[controller_delay]\ndelay = 1\n").unwrap();
    let e = try_(Options { out: out.clone(), effects: Some(bad), ..Options::default() });
    assert!(e.contains("bad.toml:2:1: [controller_delay]: unknown parameter `delay`"), "{e}");
    let e = try_(Options { out: dir.join("no/such/dir/x.fmu"), ..Options::default() });
    assert!(e.contains("does not exist"), "{e}");
    assert!(!out.exists(), "nothing written");
}
