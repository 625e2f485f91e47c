//! The fixed-point twin on an FPU-less Cortex-M3 (issue 15): the firmware built for
//! `thumbv7m-none-eabi` with feature `fixed` runs its trace mode on QEMU's mps2-an385 and
//! streams every channel's I17F15 bits of every step of every named profile with both
//! Curtis rate sets (TP07, TP11, TP14 among them); each must equal the host run of the
//! same fixed-point twin (`Simulation::new_fx`) exactly. Integer arithmetic is exact on
//! every core, so no tolerance.
//!
//! Also keeps golden hashes of the host's fixed-point traces
//! (`host-tests/golden/traces_fx.txt`), so a change of the fixed-point twin's numbers is
//! a deliberate, reviewed change, as for the f32 twin's (`golden/traces.txt`).
//!
//! Needs `rustup target add thumbv7m-none-eabi` and `qemu-system-arm`; fails (does not
//! skip) without them.

mod firmware_support;

use std::fs;
use std::time::{Duration, Instant};

use firmware_support as fw;
use model_core::{Builtin, RateSet, N_CHANNELS};

/// Far above the ~30 s the M3's trace takes: only a hung firmware gets near it.
const QEMU_TIMEOUT: Duration = Duration::from_secs(600);

#[test]
fn m3_fixed_point_trace_matches_host_bit_for_bit() {
    let dir = fw::build_firmware_on(&fw::M3_FIXED, "m3-fixed", None);
    let cwd = dir.join("trace-run");
    let _ = fs::remove_dir_all(&cwd);
    let run = fw::run_qemu_on(&fw::M3_FIXED, &dir.join("simrod-trace"), &cwd, QEMU_TIMEOUT);
    let t = fw::read_trace(&cwd.join(fw::protocol::TRACE_FILE));
    eprintln!("M3 fixed-point trace run {:.1} s", run.wall.as_secs_f64());
    assert!(t.fixed, "the M3 build must trace the fixed-point twin (its trace magic)");
    assert_eq!(t.n_channels, N_CHANNELS, "channel count of the trace");
    assert_eq!(t.dt_us, fw::STEP_US, "step of the trace");
    assert!(t.effects.is_empty(), "no effects compiled in");
    let expected: Vec<(Builtin, RateSet)> =
        fw::RATES.iter().flat_map(|r| Builtin::ALL.iter().map(move |b| (*b, *r))).collect();
    let got: Vec<_> = t.runs.iter().map(|r| (r.profile, r.rates)).collect();
    assert_eq!(got, expected, "runs in the trace");
    for must in [Builtin::TP07, Builtin::TP11, Builtin::TP14] {
        assert!(got.iter().filter(|(b, _)| *b == must).count() == 2, "{} with both rate sets", must.name());
    }
    let mut total = 0;
    for r in &t.runs {
        let t0 = Instant::now();
        let steps = fw::compare_run_fx(&t, r);
        total += steps;
        eprintln!(
            "  {} {:<10} {steps:>6} steps x {N_CHANNELS} channels equal ({:.2} s)",
            r.profile.name(),
            fw::rates_name(r.rates),
            t0.elapsed().as_secs_f64()
        );
    }
    eprintln!("{total} steps, every channel's bits equal");
    assert_eq!(model_core::saturations(), 0, "the host's fixed-point runs saturated");
}

const GOLDEN: &str = "golden/traces_fx.txt";

const GOLDEN_HEADER: &str = "\
# Golden hashes of the host's fixed-point traces (model_core::Fx, I17F15): FNV-1a 64 over
# the little-endian I17F15 bits (4 bytes) of every channel (model_core::Channel::ALL order)
# of every step. Config as golden/traces.txt: dt 1000 us, thesis parameters with the named
# Curtis rate set, identified coupling, speed map, no effects, 24 V supply, profile scales
# 1/1 (what the M3 firmware's trace mode runs). A mismatch means the fixed-point twin's
# numbers changed. If that is deliberate, regenerate with
#   SIMROD_BLESS=1 cargo test -p host-tests --test firmware_fixed golden
# and review and commit this file with the change.
";

#[test]
fn fixed_point_host_traces_match_golden_hashes() {
    fw::check_golden(GOLDEN, GOLDEN_HEADER, "firmware_fixed", fw::host_hash_fx);
}
