//! Accuracy of the twin against an independent reference (`host_tests::reference`): the
//! same continuous model in f64, integrated by RK4 at 10 µs.
//!
//! Every named profile runs through `model-core` at the bench step (1 ms) and at 100 µs,
//! and the reference is sampled at the same instants. The error measure is
//!
//! `NRMSE = RMSE(twin - reference) / (max - min of the reference over the run)`,
//!
//! the RMSE relative to the span the channel covers: unit-free, comparable between
//! channels, and well defined for signals that cross zero (torques, powers), where a
//! normalisation by the mean would blow up.
//!
//! The reference itself is checked by halving its step (`reference_converges`): its own
//! error must be far below the twin's, or the comparison would measure the reference.
//!
//! Both instances of the twin are measured: the f32 twin and the fixed-point twin
//! (`model_core::Fx`, the Cortex-M3 build), against the same reference runs and the same
//! bound; the fixed-point runs must not saturate a single operation.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::thread;

use host_tests::reference::{Case, Reference, Sample, CHANNELS};
use model_core::{
    Builtin, Channel, Config, CouplingStiffness, Outputs, Params, Profile, RateSet, Real, Simulation,
    N_CHANNELS,
};

/// Reference step [ns]: `ω h ≈ 0.12` on the 2 kHz flange mode.
const REF_STEP_NS: u64 = 10_000;
/// Supply voltage [V].
const SUPPLY_V: f32 = 24.0;

/// Speeds, torques and powers: the channels the accuracy bound applies to.
const ASSERTED: [Channel; 11] = [
    Channel::SuTMotorEnc,
    Channel::CKistlerL,
    Channel::CKistlerR,
    Channel::TKistlerL,
    Channel::TKistlerR,
    Channel::SiemensEnc,
    Channel::PSutInv,
    Channel::PLml,
    Channel::PLmr,
    Channel::PDpu,
    Channel::IDpu27,
];

/// Speeds: a finer step must not make them worse (the discretization converges).
const SPEEDS: [Channel; 4] =
    [Channel::SuTMotorEnc, Channel::TKistlerL, Channel::TKistlerR, Channel::SiemensEnc];

/// 1 % of the span: the accuracy the twin must have against the model it discretizes.
const BOUND: f64 = 0.01;

/// Largest NRMSE between the reference at 10 µs and at 5 µs: a hundredth of the twin's
/// smallest 1 ms error on speeds and torques (~1e-4), so the comparison measures the twin.
const REF_SELF_BOUND: f64 = 1e-6;

struct Named {
    name: &'static str,
    case: Case,
}

fn named(
    name: &'static str,
    profile: Builtin,
    throttle_scale: f32,
    load_scale: f32,
    rates: RateSet,
) -> Named {
    Named { name, case: Case { profile, throttle_scale, load_scale, rates, supply_v: f64::from(SUPPLY_V) } }
}

fn cases() -> Vec<Named> {
    use Builtin::*;
    use RateSet::*;
    vec![
        named("TP07 thr 1.0 load 1.0 programmed", TP07, 1.0, 1.0, Programmed),
        named("TP07 thr 1.0 load 1.0 identified", TP07, 1.0, 1.0, Identified),
        named("TP11 thr 0.79 load 0 identified", TP11, 0.79, 0.0, Identified),
        named("TP11 thr 0.79 load 1.0 identified", TP11, 0.79, 1.0, Identified),
        named("TP12 thr 1.0 load 0 identified", TP12, 1.0, 0.0, Identified),
        named("TP13 thr 1.0 load 0 identified", TP13, 1.0, 0.0, Identified),
        named("TP14 thr 1.0 load 0 identified", TP14, 1.0, 0.0, Identified),
    ]
}

/// One step's outputs in f64: the time [µs] and every channel's value, exact for both
/// instances (an f32, and an I17F15's bits over 2^15, convert to f64 exactly).
type Step = (u64, [f64; N_CHANNELS]);

fn f64_of<R: Real>(o: &Outputs<R>, exact: impl Fn(R) -> f64) -> Step {
    (o.t_us, o.values.map(exact))
}

fn setup(c: &Case, dt_us: u32) -> (Config, Profile) {
    let cfg =
        Config { dt_us, params: Params::thesis(c.rates, CouplingStiffness::Identified), ..Config::default() };
    (cfg, Profile::builtin(c.profile, c.throttle_scale, c.load_scale).unwrap())
}

/// The twin: the f32 instance, or the fixed-point one (`fixed`).
fn twin(c: &Case, dt_us: u32, fixed: bool) -> Vec<Step> {
    let (cfg, profile) = setup(c, dt_us);
    if fixed {
        let sim = Simulation::new_fx(&cfg, profile, SUPPLY_V).unwrap();
        sim.map(|o| f64_of(&o, |v| f64::from(v.to_bits()) / 32_768.0)).collect()
    } else {
        Simulation::new(&cfg, profile, SUPPLY_V).unwrap().map(|o| f64_of(&o, f64::from)).collect()
    }
}

/// `v <= bound`, false for NaN (an undefined error never passes).
fn within(v: f64, bound: f64) -> bool {
    v <= bound
}

/// Span of the reference and NRMSE of the values paired with its samples (equal times).
fn nrmse<'a>(pairs: impl Iterator<Item = (f64, &'a Sample)>, ch: Channel) -> (f64, f64) {
    let (mut sq, mut n) = (0.0, 0.0);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (v, r) in pairs {
        let rv = r.get(ch).unwrap();
        sq += (v - rv).powi(2);
        n += 1.0;
        lo = lo.min(rv);
        hi = hi.max(rv);
    }
    (hi - lo, (sq / n).sqrt() / (hi - lo))
}

/// The reference sample at each twin output's time (reference sampled every 100 µs).
fn at_twin_times<'a>(
    twin: &'a [Step],
    reference: &'a [Sample],
    ch: Channel,
) -> impl Iterator<Item = (f64, &'a Sample)> {
    twin.iter().map(move |(t_us, v)| {
        let r = &reference[(t_us / 100 - 1) as usize];
        assert_eq!(r.t_us, *t_us, "sample instants differ");
        (v[ch as usize], r)
    })
}

/// NRMSE of one channel at both twin steps, f32 and fixed-point, and the reference's span.
struct Row {
    channel: Channel,
    span: f64,
    ms1: f64,
    us100: f64,
    fx_ms1: f64,
    fx_us100: f64,
}

fn compare(c: &Case) -> Vec<Row> {
    let reference = Reference::new(c, REF_STEP_NS).run(100);
    let [coarse, fine, fx_coarse, fx_fine] =
        [(1000, false), (100, false), (1000, true), (100, true)].map(|(dt, fx)| twin(c, dt, fx));
    assert_eq!(coarse.len() * 10, reference.len());
    assert_eq!(fine.len(), reference.len());
    assert_eq!(fx_coarse.len(), coarse.len());
    assert_eq!(fx_fine.len(), fine.len());
    CHANNELS
        .into_iter()
        .map(|channel| {
            let e = |run: &[Step]| nrmse(at_twin_times(run, &reference, channel), channel);
            let (span, ms1) = e(&coarse);
            Row { channel, span, ms1, us100: e(&fine).1, fx_ms1: e(&fx_coarse).1, fx_us100: e(&fx_fine).1 }
        })
        .collect()
}

/// `compare` for every case on two threads (the reference runs dominate the runtime).
fn compare_all(cases: &[Named]) -> Vec<Vec<Row>> {
    let next = AtomicUsize::new(0);
    let mut done: Vec<(usize, Vec<Row>)> = thread::scope(|s| {
        let worker = || {
            let mut out = Vec::new();
            loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(n) = cases.get(i) else { break };
                out.push((i, compare(&n.case)));
            }
            out
        };
        let a = s.spawn(worker);
        let b = s.spawn(worker);
        [a, b].into_iter().flat_map(|h| h.join().unwrap()).collect()
    });
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, rows)| rows).collect()
}

#[test]
fn twin_matches_reference() {
    let cases = cases();
    let mut failures = Vec::new();
    for (n, rows) in cases.iter().zip(compare_all(&cases)) {
        println!("\n{}", n.name);
        println!(
            "{:<13} {:>5} {:>10} {:>11} {:>12} {:>14} {:>15}",
            "channel", "unit", "span", "NRMSE 1 ms", "NRMSE 100 µs", "fixed: 1 ms", "fixed: 100 µs"
        );
        for Row { channel: ch, span, ms1, us100, fx_ms1, fx_us100 } in rows {
            let asserted = ASSERTED.contains(&ch);
            let info = if asserted { "" } else { "   (info)" };
            println!(
                "{:<13} {:>5} {span:>10.4} {ms1:>11.3e} {us100:>12.3e} {fx_ms1:>14.3e} {fx_us100:>15.3e}{info}",
                ch.name(),
                ch.unit()
            );
            for (what, a, b) in [("f32", ms1, us100), ("fixed-point", fx_ms1, fx_us100)] {
                if asserted && !(within(a, BOUND) && within(b, BOUND)) {
                    failures.push(format!(
                        "{}: {what} {} NRMSE {a:.3e} (1 ms) / {b:.3e} (100 µs) above 1 %",
                        n.name,
                        ch.name()
                    ));
                }
            }
            if SPEEDS.contains(&ch) && !within(us100, ms1) {
                failures.push(format!(
                    "{}: {} worse at 100 µs ({us100:.3e}) than at 1 ms ({ms1:.3e})",
                    n.name,
                    ch.name()
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    // Every fixed-point operation of these runs stayed in range (nothing clipped).
    assert_eq!(model_core::saturations(), 0, "fixed-point operations saturated");
}

#[test]
fn reference_converges() {
    // TP07 exercises every regime the profiles have: load steps, motoring and
    // regenerating loads, the motoring envelope, partial and neutral deceleration.
    let n = &cases()[0];
    let h = Reference::new(&n.case, REF_STEP_NS).run(1000);
    let h2 = Reference::new(&n.case, REF_STEP_NS / 2).run(1000);
    assert_eq!(h.len(), h2.len());
    for ch in CHANNELS {
        let values = h.iter().map(|s| s.get(ch).unwrap());
        let (span, e) = nrmse(values.zip(h2.iter()), ch);
        if span == 0.0 {
            // Constant (the busbars without a supply effect): equal if both are.
            assert!(h.iter().zip(&h2).all(|(a, b)| a.get(ch) == b.get(ch)), "{}", ch.name());
            continue;
        }
        println!("reference 10 µs vs 5 µs, {}: NRMSE {e:.2e}", ch.name());
        assert!(within(e, REF_SELF_BOUND), "{}: {e:.2e}", ch.name());
    }
}
