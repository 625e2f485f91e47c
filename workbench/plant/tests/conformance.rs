//! Conformance of the physics plant and the twin, both ways (issue 11, item 4).
//!
//! 1. With no effects the plant (f64, RK4 at the bench step) and the twin (f32, exact
//!    ZOH at 1 ms) agree within 1e-3 NRMSE on every channel, for every named profile at
//!    both rate sets: the plant is the same bench, so any effect found later is the
//!    effect's, not a difference of the two models.
//! 2. Every library effect at a realistic magnitude (the middle of its proof range)
//!    moves the plant and the twin, each with its own implementation, by the same
//!    amount: the difference of the two contributions (run with minus run without) is
//!    within 2 % of the contribution's RMS on every channel either of them clearly moves
//!    (by at least 1 % of the channel's span), and at least on the channel it moves most. A second
//!    check of every effect block of the twin.
//!
//! NRMSE = RMSE / (max - min of the plant's channel over the run).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::thread;

use model_core::{
    Builtin, Config, CouplingStiffness, Effects, Maps, Outputs, Params, Profile, RateSet, Simulation,
    SpeedTarget,
};
use simrod_plant::plant::BENCH_STEP_NS;
use simrod_plant::{step_for, Plant, PlantEffects, Sample, Setup, CHANNELS};

const SUPPLY_V: f32 = 24.0;
const DT_US: u32 = 1000;
/// The twin's fine step: the effect check is asserted here, where the twin's own
/// discretization no longer hides the effect block's semantics.
const FINE_DT_US: u32 = 100;
/// Plant vs twin with no effects.
const NO_EFFECT_BOUND: f64 = 1e-3;
/// Contribution difference / contribution RMS.
const CONTRIBUTION_BOUND: f64 = 0.02;
/// A channel is "clearly moved" by an effect when its contribution's RMS is at least
/// this share of the channel's span.
const MOVED: f64 = 0.01;

#[derive(Clone, Copy, PartialEq)]
struct Run {
    profile: Builtin,
    scales: (f32, f32),
    rates: RateSet,
}

fn twin(r: Run, fx: Effects, dt_us: u32) -> Vec<Outputs> {
    let cfg = Config {
        dt_us,
        params: Params::thesis(r.rates, CouplingStiffness::Identified),
        speed_target: SpeedTarget::Map,
        effects: fx,
    };
    let profile = Profile::builtin(r.profile, r.scales.0, r.scales.1).unwrap();
    Simulation::new(&cfg, profile, SUPPLY_V).unwrap().collect()
}

fn plant(r: Run, fx: Effects, every_us: u32) -> Vec<Sample> {
    let setup = Setup {
        params: Params::thesis(r.rates, CouplingStiffness::Identified),
        maps: Maps::builtin(),
        speed_target: SpeedTarget::Map,
        sets: r.profile.sets(),
        throttle_scale: f64::from(r.scales.0),
        load_scale: f64::from(r.scales.1),
        supply_v: f64::from(SUPPLY_V),
        library: fx,
        bench: PlantEffects::default(),
    };
    let every = u64::from(every_us);
    Plant::new(&setup, step_for(every, BENCH_STEP_NS)).unwrap().run(every).unwrap()
}

/// Series of every plant channel from the twin's and the plant's runs.
fn series(t: &[Outputs], p: &[Sample]) -> Vec<(Vec<f64>, Vec<f64>)> {
    assert_eq!(t.len(), p.len(), "sample counts differ");
    for (a, b) in t.iter().zip(p) {
        assert_eq!(a.t_us, b.t_us, "sample instants differ");
    }
    CHANNELS
        .iter()
        .map(|&c| {
            (t.iter().map(|o| f64::from(o.get(c))).collect(), p.iter().map(|s| s.get(c).unwrap()).collect())
        })
        .collect()
}

/// `v <= bound`, false for NaN (an undefined error never passes).
fn within(v: f64, bound: f64) -> bool {
    v <= bound
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (mut sq, mut n) = (0.0f64, 0.0f64);
    for x in v {
        sq += x * x;
        n += 1.0;
    }
    (sq / n.max(1.0)).sqrt()
}

fn span(v: &[f64]) -> f64 {
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    hi - lo
}

/// `f` over `items` on two threads, results in order.
fn parallel<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let next = AtomicUsize::new(0);
    let mut done: Vec<(usize, R)> = thread::scope(|s| {
        let worker = || {
            let mut out = Vec::new();
            loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(i) else { break };
                out.push((i, f(item)));
            }
            out
        };
        let (a, b) = (s.spawn(worker), s.spawn(worker));
        [a, b].into_iter().flat_map(|h| h.join().unwrap()).collect()
    });
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, r)| r).collect()
}

#[test]
fn with_no_effects_plant_and_twin_agree_on_every_channel() {
    use Builtin::*;
    let mut runs = Vec::new();
    for rates in [RateSet::Programmed, RateSet::Identified] {
        for (profile, scales) in [
            (TP07, (1.0, 1.0)),
            (TP11, (0.79, 1.0)),
            (TP12, (1.0, 0.0)),
            (TP13, (1.0, 0.0)),
            (TP14, (1.0, 0.0)),
        ] {
            runs.push(Run { profile, scales, rates });
        }
    }
    let rows = parallel(&runs, |r| {
        let s = series(&twin(*r, Effects::NONE, DT_US), &plant(*r, Effects::NONE, DT_US));
        s.iter()
            .map(|(t, p)| {
                let sp = span(p);
                let e = rms(t.iter().zip(p).map(|(a, b)| a - b));
                if sp > 0.0 {
                    e / sp
                } else {
                    e / p[0].abs().max(1.0)
                }
            })
            .collect::<Vec<f64>>()
    });
    let mut failures = Vec::new();
    println!(
        "{:<13} {}",
        "NRMSE",
        runs.iter().map(|r| format!("{} {:?}", r.profile.name(), r.rates)).collect::<Vec<_>>().join(" | ")
    );
    for (ci, c) in CHANNELS.iter().enumerate() {
        let line: Vec<String> = rows.iter().map(|r| format!("{:>9.2e}", r[ci])).collect();
        println!("{:<13} {}", c.name(), line.join(" "));
        for (r, row) in runs.iter().zip(&rows) {
            if !within(row[ci], NO_EFFECT_BOUND) {
                failures.push(format!("{} {:?} {}: {:.2e}", r.profile.name(), r.rates, c.name(), row[ci]));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// One library effect at the middle of its proof range, on its proof case.
struct EffectCase {
    id: &'static str,
    param: &'static str,
    value: f32,
    run: Run,
    fx: Effects,
}

/// The twin holds at most `DELAY_CAPACITY` steps of controller delay (25.6 ms at 100 µs)
/// and `SENSOR_DELAY_CAPACITY` of sensor delay (12.8 ms). The fine-step checks of
/// `controller_delay` and `sensor_delay` use this realistic 10 ms (the thesis saw lags
/// of this order, 6.1); the 1 ms table keeps the proof range's middle.
const FINE_DELAY_S: f32 = 0.01;

/// Effects whose contribution is printed but not asserted, with the reason (reported
/// in the conformance table; see `docs/MODEL.md`, Effects).
const KNOWN_DEVIATIONS: &[(&str, &str)] = &[(
    "gear_backlash",
    "hybrid event: at 100 µs half of the P_SuT_inv difference is one sample at an impact (the twin's power dips by 2.5 kW for one step, the plant's does not); the torques converge to the plant's only as the step shrinks (6 % at 1 ms, 2.0 % at 100 µs)",
)];

fn effect_cases(dt_us: u32) -> Vec<EffectCase> {
    model_core::effects::EFFECTS
        .iter()
        .filter_map(|e| {
            let p = e.proof?;
            let mut value = 0.5 * (p.lo + p.hi);
            if matches!(e.id, "controller_delay" | "sensor_delay") && dt_us == FINE_DT_US {
                value = FINE_DELAY_S;
            }
            let mut fx = Effects::NONE;
            fx.set(e.id, p.param, value).ok()?;
            let run = Run { profile: p.profile, scales: p.scales, rates: RateSet::Identified };
            Some(EffectCase { id: e.id, param: p.param, value, run, fx })
        })
        .collect()
}

/// Per channel: the larger contribution's RMS (plant's or twin's) over the channel's
/// span, and the RMS of the two contributions' difference over that RMS. `base`: the
/// series of `c.run` without effects.
fn contributions(c: &EffectCase, base: &[(Vec<f64>, Vec<f64>)], dt_us: u32) -> Vec<(f64, f64)> {
    let with = series(&twin(c.run, c.fx, dt_us), &plant(c.run, c.fx, dt_us));
    base.iter()
        .zip(&with)
        .map(|((t0, p0), (t1, p1))| {
            let ct: Vec<f64> = t1.iter().zip(t0).map(|(a, b)| a - b).collect();
            let cp: Vec<f64> = p1.iter().zip(p0).map(|(a, b)| a - b).collect();
            // The larger of the two contributions: a channel the twin moves and the plant
            // does not is as much a difference as the other way round.
            let size = rms(cp.iter().copied()).max(rms(ct.iter().copied()));
            let diff = rms(ct.iter().zip(&cp).map(|(a, b)| a - b));
            let sp = span(p0).max(span(p1));
            (if sp > 0.0 { size / sp } else { 0.0 }, if size > 0.0 { diff / size } else { 0.0 })
        })
        .collect()
}

/// Print the table of one twin step; the failures of effects that are asserted.
fn table(dt_us: u32) -> Vec<String> {
    let cases = effect_cases(dt_us);
    assert!(cases.len() >= 13, "every library effect has a proof case");
    // The runs without effects, once per distinct run: several effects share a proof run.
    let mut runs: Vec<Run> = Vec::new();
    for c in &cases {
        if !runs.contains(&c.run) {
            runs.push(c.run);
        }
    }
    let bases =
        parallel(&runs, |r| series(&twin(*r, Effects::NONE, dt_us), &plant(*r, Effects::NONE, dt_us)));
    let rows = parallel(&cases, |c| {
        let k = runs.iter().position(|r| *r == c.run).expect("every case's run is in `runs`");
        contributions(c, &bases[k], dt_us)
    });
    let mut failures = Vec::new();
    println!("\ntwin at {dt_us} µs, plant at its bench step");
    println!("{:<44} {:<13} {:>12} {:>12}", "effect = value", "channel", "contrib/span", "diff/contrib");
    for (c, row) in cases.iter().zip(&rows) {
        let label = format!("{}.{} = {}", c.id, c.param, c.value);
        let known = KNOWN_DEVIATIONS.iter().find(|(id, _)| *id == c.id);
        // The channels the effect clearly moves; at least the one it moves most (an
        // effect whose every contribution is below 1 % of span is still checked there).
        let most = row.iter().map(|(size, _)| *size).fold(0.0, f64::max);
        assert!(most > 0.0, "{label} moves no channel");
        for (ch, (size, share)) in CHANNELS.iter().zip(row) {
            if *size < MOVED && *size < most {
                continue;
            }
            let ok = within(*share, CONTRIBUTION_BOUND);
            let mark = match (ok, known) {
                (true, _) => "",
                (false, Some(_)) => "  (known deviation)",
                (false, None) => "  <-- above 2 %",
            };
            println!("{label:<44} {:<13} {size:>12.3e} {share:>12.3e}{mark}", ch.name());
            if !ok && known.is_none() {
                failures.push(format!("{label} {}: {:.1} % of the contribution", ch.name(), share * 100.0));
            }
        }
        if let Some((_, why)) = known {
            println!("{:<44} not asserted: {why}", c.id);
        }
    }
    failures
}

/// Set to print the same table with the twin at the bench rate (1 ms) first, for
/// information: the twin's discretization of sharp transients is part of the difference
/// there (`docs/MODEL.md`, Conformance). Nothing is asserted on it, so it is not run by
/// default (it costs as much as the asserted table).
const AT_BENCH_RATE: &str = "SIMROD_CONFORMANCE_1MS";

#[test]
fn every_library_effect_moves_plant_and_twin_alike() {
    if std::env::var_os(AT_BENCH_RATE).is_some() {
        let _ = table(DT_US);
    }
    let failures = table(FINE_DT_US);
    assert!(failures.is_empty(), "{failures:#?}");
}
