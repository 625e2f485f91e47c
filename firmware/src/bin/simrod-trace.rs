//! Trace mode: the named profiles with both Curtis rate sets, flat out (no tick), every
//! channel's bits of every step written to `simrod-trace.bin` in QEMU's working
//! directory over semihosting (format in `protocol`). The host test compares them bit
//! for bit with the host simulation; this binary only computes and streams.

#![no_std]
#![no_main]

use cortex_m_rt::{entry, exception, ExceptionFrame};
use firmware::hostio::{HostFile, HostOut};
use firmware::protocol::{self, Fnv1a64};
use firmware::step::{simrod_profile_at, simrod_step};
use firmware::{Scalar, VALUE_BYTES};
use model_core::{Builtin, Inputs, Outputs, Profile, RateSet, N_CHANNELS};

/// Profiles traced: all built-in ones.
const PROFILES: [Builtin; 5] = Builtin::ALL;
/// Rate sets traced, in this order.
const RATES: [RateSet; 2] = [RateSet::Programmed, RateSet::Identified];
/// Bytes per step record.
const RECORD: usize = 8 + VALUE_BYTES * N_CHANNELS;
/// Steps buffered per semihosting write: each write is a trap to the host, so fewer,
/// larger writes are what makes the trace fast.
const BATCH: usize = 64;

/// The trace file's writer.
type Out = HostOut<{ RECORD * BATCH }>;

/// Positive control for the ELF check in `host-tests/tests/firmware_elf.rs`: an
/// unchecked index, i.e. a panic path the check must find. Never part of the step.
#[inline(never)]
#[no_mangle]
pub fn simrod_canary_index(values: &[Scalar; N_CHANNELS], i: usize) -> Scalar {
    values[i]
}

fn run(out: &mut Out, which: Builtin, rates: RateSet) -> u32 {
    let cfg = firmware::config(rates);
    let mut model = match firmware::new_model(&cfg) {
        Ok(m) => m,
        Err(e) => defmt::panic!("model config rejected: {}", e),
    };
    let profile = match Profile::builtin(which, 1.0, 1.0) {
        Ok(p) => p,
        Err(e) => defmt::panic!("profile: {}", e),
    };
    let n_steps = profile.duration_us().div_ceil(u64::from(firmware::STEP_US)) as u32;
    let mut name = [0u8; 8];
    for (d, s) in name.iter_mut().zip(which.name().bytes()) {
        *d = s;
    }
    out.put(&protocol::RUN_MAGIC);
    out.put(&name);
    out.put(&[u8::from(rates == RateSet::Identified)]);
    out.put(&n_steps.to_le_bytes());

    let mut hash = Fnv1a64::default();
    let mut o = Outputs::zero();
    let mut rec = [0u8; RECORD];
    let mut steps = 0u32;
    while model.t_us() < profile.duration_us() {
        let inputs = Inputs { sp: simrod_profile_at(&profile, model.t_us()), supply_v: firmware::SUPPLY_V };
        simrod_step(&mut model, &inputs, &mut o);
        rec[..8].copy_from_slice(&o.t_us.to_le_bytes());
        for (dst, v) in rec[8..].chunks_exact_mut(VALUE_BYTES).zip(o.values.iter()) {
            dst.copy_from_slice(&firmware::value_le(*v));
        }
        hash.write(&rec[8..]);
        out.put(&rec);
        steps += 1;
    }
    // Keeps the canary linked; index 0 is always in bounds.
    let _ = simrod_canary_index(&o.values, core::hint::black_box(0));
    out.put(&protocol::END_MAGIC);
    out.put(&hash.0.to_le_bytes());
    defmt::info!("{} {}: {=u32} steps, fnv1a64 {=u64:#018x}", which, rates, steps, hash.0);
    steps
}

#[entry]
fn main() -> ! {
    let Some(file) = HostFile::create(concat!("simrod-trace.bin", "\0")) else {
        defmt::panic!("cannot create {=str} on the host", protocol::TRACE_FILE);
    };
    let mut out = Out::new(file);
    out.put(&firmware::TRACE_MAGIC);
    out.put(&(N_CHANNELS as u16).to_le_bytes());
    out.put(&firmware::STEP_US.to_le_bytes());
    out.put(&(firmware::BUILD_EFFECTS.len() as u16).to_le_bytes());
    for (id, key, v) in firmware::BUILD_EFFECTS {
        out.put(&[id.len() as u8]);
        out.put(id.as_bytes());
        out.put(&[key.len() as u8]);
        out.put(key.as_bytes());
        out.put(&v.to_bits().to_le_bytes());
    }
    let mut runs = 0u32;
    for rates in RATES {
        for which in PROFILES {
            run(&mut out, which, rates);
            runs += 1;
        }
    }
    out.put(&protocol::DONE_MAGIC);
    out.put(&runs.to_le_bytes());
    out.finish();
    firmware::exit(true)
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    defmt::error!("hard fault at pc {=u32:#x}", ef.pc());
    firmware::exit(false)
}
