//! How far the twin's 1 ms step moves a fitted parameter on the bench's data: each
//! library effect hidden in the physics plant at the ends of its proof range, on every
//! built-in profile (throttle 0.8, loads at +0.65 and -0.65) and the effect's proof
//! profile, recorded with the bench's default acquisition at two noise seeds and
//! diagnosed blind. The bias of a case is the mean error of its two fits (the noise
//! moves each by its own σ; half their difference is printed beside it). The noise
//! matters beyond its scatter: it decides how much each channel weighs in the fit, and
//! the channels disagree on the value the twin's step prefers (exact outputs, weighted
//! by their model error alone, put coupling stiffness 2 % high on TP07 where the noisy
//! bench data put it 5.5 % high). These are the measurements behind each parameter's
//! declared step bias (`model_core::effects::Fit::step_bias`); `tests/hidden_effects.rs`
//! checks the worst cases of the largest. The last column is the error's distance from
//! the declared bias' centre in its half-widths (`Side::split`: a bias of known sign is
//! centred at half its amount): above 1, outside the declaration.
//!
//! `cargo run --release -p workbench --example step_bias -- [EFFECT[.PARAM]] [--exact]`
//! (`--exact`: the plant's exact outputs, one fit per case; `.PARAM`: hide that parameter
//! at the proof parameter's range instead, e.g. `sensor_delay.throttle`: a chain effect's
//! bias differs by channel).
use model_core::effects::InSteps;
use model_core::{Builtin, Effects};
use workbench::diagnose::proof::*;
use workbench::vbench::bench::PlantKind;
use workbench::vbench::bench_effects::BenchEffects;
use workbench::vbench::noise::NoiseModel;

/// Where in the proof range the hidden values are set: its ends.
const AT: [f32; 2] = [0.0, 1.0];
/// And between them, for a parameter the twin realises in whole steps: where the truth
/// falls between two steps moves the fit (the controller delay's proof range, 50–150 ms,
/// has whole steps at its ends; at 73.45, 106.78 and 131.23 ms the fit is 0.7, 1.3 and
/// 0.7 ms long on TP14).
const BETWEEN_STEPS: [f32; 3] = [0.2345, 0.5678, 0.8123];
/// The noise seeds of each case.
const SEEDS: [u64; 2] = [1, 2];

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let exact = args.iter().any(|a| a == "--exact");
    let only = args.iter().find(|a| !a.starts_with("--"));
    let seeds: &[u64] = if exact { &SEEDS[..1] } else { &SEEDS };
    println!(
        "{:22} {:12} {:22} {:>11} {:>11} {:>11} {:>9} {:>11} {:>9}",
        "effect", "profile", "param", "truth", "fit", "error", "rel", "noise ±", "/declared"
    );
    let (only, other) = match only.map(|o| o.split_once('.').unwrap_or((o.as_str(), ""))) {
        Some((id, "")) => (Some(id), None),
        Some((id, param)) => match model_core::effects::effect(id).and_then(|e| e.param(param)) {
            Some(p) => (Some(id), Some(p)),
            None => {
                eprintln!("step_bias: {id} has no parameter '{param}'");
                std::process::exit(2);
            }
        },
        None => (None, None),
    };
    for case in library_cases() {
        let (id, proof_param, lo, hi) = case.params[0];
        if only.is_some_and(|o| o != id) {
            continue;
        }
        let hidden = other.map_or(proof_param, |p| p.name);
        let mut profiles = vec![case.profile];
        for b in Builtin::ALL {
            profiles.extend([(b, 0.8, 0.65), (b, 0.8, -0.65)]);
        }
        // Per parameter: the worst absolute error, relative error, and distance from the
        // declared bias' centre in its half-widths.
        let mut worst: Vec<(&str, [f64; 3])> = Vec::new();
        let decl = model_core::effects::effect(id).and_then(|e| e.param(hidden));
        let whole = decl.and_then(|p| p.fit).is_some_and(|f| f.in_steps == InSteps::Whole);
        let between = if whole { &BETWEEN_STEPS[..] } else { &[] };
        for profile in profiles {
            for &at in AT.iter().chain(between) {
                let mut truth = Effects::NONE;
                truth.set(id, hidden, lo + (hi - lo) * at).expect("a library parameter");
                let fx = BenchEffects { library: truth, ..BenchEffects::none() };
                let noise = (!exact).then(NoiseModel::default);
                let fits: Vec<_> = seeds
                    .iter()
                    .map(|&seed| {
                        fitted(&plant_run(&fx, PlantKind::Physics, profile, noise, seed), &truth, id, hidden)
                    })
                    .collect();
                let label = format!("{:?} {:+.2}", profile.0, profile.2);
                for (k, &(param, t, _)) in fits[0].iter().enumerate() {
                    let vs: Result<Vec<f64>, &str> =
                        fits.iter().map(|f| f.get(k).map_or(Err("not ranked"), |x| x.2.value())).collect();
                    let vs = match vs {
                        Ok(vs) => vs,
                        Err(why) => {
                            println!("{id:22} {label:12} {param:22} {t:>11.5} {:>11} ({why})", "-");
                            continue;
                        }
                    };
                    let v = vs.iter().sum::<f64>() / vs.len() as f64;
                    let spread = 0.5
                        * (vs.iter().copied().fold(f64::MIN, f64::max)
                            - vs.iter().copied().fold(f64::MAX, f64::min));
                    let (centre, half) = declared_step_bias(id, param, t).unwrap_or((0.0, 0.0));
                    let e = [(v - t).abs(), ((v - t) / t).abs(), (v - centre - t).abs() / half];
                    println!(
                        "{id:22} {label:12} {param:22} {t:>11.5} {v:>11.5} {:>11.3e} {:>8.3}% {spread:>11.3e} {:>9.2}",
                        v - t,
                        100.0 * (v - t) / t,
                        e[2]
                    );
                    match worst.iter_mut().find(|w| w.0 == param) {
                        Some(w) => (0..3).for_each(|k| w.1[k] = w.1[k].max(e[k])),
                        None => worst.push((param, e)),
                    }
                }
            }
        }
        for (param, [a, r, d]) in worst {
            println!(
                "  worst {id}.{param}: {a:.3e} ({:.3} %), {d:.2} of the declared half-width from its centre",
                100.0 * r
            );
        }
    }
}

/// A parameter's fit, or why there is none to measure a bias on.
enum Fitted {
    Value(f64),
    Not(&'static str),
}

impl Fitted {
    fn value(&self) -> Result<f64, &'static str> {
        match self {
            Self::Value(v) => Ok(*v),
            Self::Not(why) => Err(why),
        }
    }
}

/// Each parameter of `id` with its truth and the fit of `id`'s candidate. A candidate
/// the diagnosis did not refit, an undetermined parameter and a hidden one the fit left
/// where it started (not found: no bias to measure) give no value.
fn fitted(run: &Run, truth: &Effects, id: &str, hidden: &str) -> Vec<(&'static str, f64, Fitted)> {
    let d = diagnose_run(run, &Effects::NONE).expect("a diagnosis");
    let cause = workbench::diagnose::library::cause_of(id, hidden).unwrap_or(id);
    let Some(c) = d.ranking.iter().find(|c| c.effect == cause) else { return Vec::new() };
    c.params
        .iter()
        .map(|fp| {
            let t = f64::from(truth.get(id, fp.name).ok().flatten().unwrap_or(fp.start as f32));
            let fit = if c.confirmed_reduction.is_none() {
                Fitted::Not("not refitted")
            } else if !fp.std.is_finite() {
                Fitted::Not("undetermined")
            } else if fp.name == hidden && fp.value == fp.start {
                Fitted::Not("not found: the fit stayed at its start")
            } else {
                Fitted::Value(fp.value)
            };
            (fp.name, t, fit)
        })
        .collect()
}
