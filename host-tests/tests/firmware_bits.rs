//! Bit-for-bit agreement of the Cortex-M4F firmware with the host simulation, without
//! a probe: the firmware's trace binary runs every built-in profile with both Curtis
//! rate sets on QEMU (mps2-an386) and streams every channel's f32 bits of every step
//! over semihosting; each must equal the host `Simulation`'s `to_bits()` exactly.
//! No tolerance: the model is written so that both FPUs compute the same bits (f32
//! basic operations, no FMA, no transcendental functions in the step).
//!
//! Also keeps golden hashes of the host traces, so a change of the model's numbers is
//! always a deliberate, reviewed change of `host-tests/golden/traces.txt`.
//!
//! Needs `rustup target add thumbv7em-none-eabihf` and `qemu-system-arm`; fails (does
//! not skip) without them.

mod firmware_support;

use std::fmt::Write as _;
use std::fs;
use std::path::Path;
use std::time::{Duration, Instant};

use firmware_support as fw;
use model_core::{Builtin, Effects, N_CHANNELS};

/// Far above the ~5 s a trace takes: only a hung firmware gets near it.
const QEMU_TIMEOUT: Duration = Duration::from_secs(300);

/// Run the trace binary of a build in a fresh directory; the parsed trace.
fn trace(variant: &str, effects: Option<&Path>) -> fw::Trace {
    let dir = fw::build_firmware(variant, effects);
    let elf = dir.join("simrod-trace");
    let cwd = dir.join("trace-run");
    let _ = fs::remove_dir_all(&cwd);
    let run = fw::run_qemu(&elf, &cwd, QEMU_TIMEOUT);
    let path = cwd.join(fw::protocol::TRACE_FILE);
    let size = fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    eprintln!(
        "{variant}: QEMU trace run {:.2} s, {:.1} MB of trace",
        run.wall.as_secs_f64(),
        size as f64 / 1e6
    );
    let t = fw::read_trace(&path);
    assert_eq!(t.n_channels, N_CHANNELS, "channel count of the trace");
    assert_eq!(t.dt_us, fw::STEP_US, "step of the trace");
    let expected: Vec<(Builtin, model_core::RateSet)> =
        fw::RATES.iter().flat_map(|r| Builtin::ALL.iter().map(move |b| (*b, *r))).collect();
    let got: Vec<_> = t.runs.iter().map(|r| (r.profile, r.rates)).collect();
    assert_eq!(got, expected, "runs in the trace");
    t
}

/// Compare every run; a summary line per run.
fn compare_all(t: &fw::Trace, effects: Effects) -> String {
    let mut summary = String::new();
    for run in &t.runs {
        let t0 = Instant::now();
        let steps = fw::compare_run(t, run, effects);
        writeln!(
            summary,
            "  {} {:<10} {steps:>6} steps x {} channels = {:>9} values equal ({:.2} s)",
            run.profile.name(),
            fw::rates_name(run.rates),
            t.n_channels,
            steps * t.n_channels,
            t0.elapsed().as_secs_f64()
        )
        .ok();
    }
    summary
}

#[test]
fn firmware_trace_matches_host_bit_for_bit() {
    let t0 = Instant::now();
    let t = trace("plain", None);
    assert!(t.effects.is_empty(), "the plain build must have no effects compiled in: {:?}", t.effects);
    let summary = compare_all(&t, Effects::NONE);
    eprintln!("firmware == host, bit for bit ({:.1} s in all):\n{summary}", t0.elapsed().as_secs_f64());
}

/// The effects file the effects build compiles in, parsed here independently of the
/// firmware's build script (decimal -> f64 -> f32, like the workbench).
fn parse_effects_file(path: &Path) -> Vec<(String, String, f32)> {
    let text = fs::read_to_string(path).unwrap();
    let mut section = String::new();
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap().trim();
        if let Some(s) = line.strip_prefix('[') {
            section = s.trim_end_matches(']').trim().to_string();
        } else if let Some((k, v)) = line.split_once('=') {
            let v: f64 = v.trim().parse().unwrap();
            out.push((section.clone(), k.trim().to_string(), v as f32));
        }
    }
    out
}

#[test]
fn firmware_with_build_time_effects_matches_host_bit_for_bit() {
    let file = fw::root().join("firmware/effects/example.toml");
    let t = trace("effects", Some(&file));
    let expected = parse_effects_file(&file);
    assert!(!expected.is_empty());
    let bits = |v: &[(String, String, f32)]| {
        v.iter().map(|(i, k, x)| (i.clone(), k.clone(), x.to_bits())).collect::<Vec<_>>()
    };
    assert_eq!(bits(&t.effects), bits(&expected), "effects compiled into the firmware vs {}", file.display());
    let mut effects = Effects::NONE;
    for (id, key, v) in &t.effects {
        effects.set(id, key, *v).unwrap();
    }
    effects.validate().unwrap();
    assert!(!effects.is_none());
    let summary = compare_all(&t, effects);
    eprintln!("firmware with effects == host, bit for bit:\n{summary}");
}

const GOLDEN: &str = "golden/traces.txt";

const GOLDEN_HEADER: &str = "\
# Golden hashes of the host simulation's traces: FNV-1a 64 over the little-endian bits
# of every channel (model_core::Channel::ALL order) of every step. Config: dt 1000 us,
# thesis parameters with the named Curtis rate set, identified coupling, speed map,
# no effects, 24 V supply, profile scales 1/1 (what the firmware's trace mode runs).
# A mismatch means the model's numbers changed. If that is deliberate, regenerate with
#   SIMROD_BLESS=1 cargo test -p host-tests --test firmware_bits golden
# and review and commit this file with the change.
";

#[test]
fn host_traces_match_golden_hashes() {
    fw::check_golden(GOLDEN, GOLDEN_HEADER, "firmware_bits", fw::host_hash);
}
