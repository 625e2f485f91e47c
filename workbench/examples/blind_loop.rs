//! Issue 12's proof sweep: the user's loop run blind on realistic cases, judged against
//! the truth the loop never sees.
//!
//! ```text
//! cargo build --release -p workbench --bin simrod
//! cargo run --release -p workbench --example blind_loop -- [--cases N] [--first SEED] [--jobs J] [--check] [--keep DIR] [--sensor-noise default|FILE] [--maps-within-uncertainty]
//! cargo run --release -p workbench --example blind_loop -- --replay DIR [--cases N] [--first SEED]
//! ```
//!
//! Each case is `simrod bench --scenario random` (the physics plant, not the twin; 0–3
//! hidden effects from the twin's library, the plant's bench-only physics and the
//! acquisition's faults; maps perturbed in half the cases; the bench's noise). Two cases
//! in five are campaigns of 2–5 runs: the same hidden bench on other profiles and scales.
//! The loop is the user's, through the `simrod` binary: `diagnose RUN... --write-effects
//! F --write-data D`, then `diagnose --effects F --data-dir D` with what it wrote (an
//! effect file, and an empirically corrected data directory when the library leaves
//! error), up to five rounds, stopping at "nothing missing" or when nothing new is
//! written. With `--maps-within-uncertainty` round 1 also estimates the maps within their
//! stated uncertainty (`--write-estimate`), and the loop goes on from what that wrote (the
//! maps refitted with the credited set, and the set's effect file) in place of round 1's
//! proposal. Then, per run and channel:
//!
//! - the **floor**: the error of the true plant model on the file (the noise-free run of
//!   the same bench, `--noise none`, against the file);
//! - **moved** channels: those the hidden causes move, i.e. on which the noise-free run
//!   of the bench differs from the noise-free run of the same test with nothing hidden
//!   (no effects, maps as identified) by at least 1 % of the channel's span (RMS; the
//!   scenario generator's rule, `scenario::is_moved`), or by enough to show above the
//!   floor (RMS change > 0.663x the floor: without the causes the twin would be above
//!   1.2x it, [`VISIBLE`]);
//! - **honest**: every moved channel ends within 1.2x its floor and no other channel is
//!   made worse than 1.15x; or the loop ends "unexplained"/"partial" located on a moved
//!   channel, having made no channel worse than 1.15x;
//! - **miss**: "nothing missing" while a moved channel is above 1.2x its floor;
//! - **false claim**: a library effect added that is not in the truth, with a moved
//!   channel left above 1.2x its floor. The truth is the hidden effects and, when the
//!   maps are perturbed, the twin effects that model a perturbed parameter or map
//!   exactly (`PERTURBED_TWIN`: a bench whose SuT inertia is 8 % high has
//!   `inertia_scale.sut = 1.08`); the figure counting only the hidden effects is
//!   printed too, and how many false effects were first claimed on top of an empirical
//!   table (in a round whose model already ran on a corrected data directory);
//! - **found**: a hidden library effect that moves a channel of the scenario's run (the
//!   truth file's `moves`, [`excited_ids`]) is in the final file (a measurement-chain
//!   effect on its own channel, [`claim_key`]: a gain on another channel is not it, and
//!   is a claim the truth does not justify); the 95 % interval
//!   stated beside the value that file holds (the last round naming it) holds the truth
//!   (coverage, [`stated_interval`]; the found effects' other parameters, whose truth is
//!   their neutral value, are printed apart and together with them, [`rest_covered`]).
//!   Found and coverage are also printed apart for the
//!   cases with the maps as identified and those with the maps perturbed: beside a wrong
//!   map many effects are ones the maps' stated uncertainty could give, and an interval
//!   holds that uncertainty, which only a perturbed map realises. Beside perturbed maps,
//!   found is split too by how large each effect is against the maps' error on the
//!   channel it shows most on ([`MapsError::ratio`]: both noise-free plant runs): below 1x
//!   the wrong maps outweigh it everywhere it acts.
//!
//! Seeds: the proof uses seeds from 1,000,000 on, never used while developing (tuning
//! used 500,000 on); `--first` moves them. `--check` exits 1 when a target is missed
//! (honest >= 95 %, false claims <= 2 %, found >= 95 % single / 98 % campaigns, nothing
//! hidden claims nothing >= 98 %, coverage 90-99 %). `--keep DIR` keeps each case's
//! files (runs, truth, every round's JSON, effect files and data) in `DIR/SEED`;
//! `--replay DIR` judges those kept rounds again without running a diagnosis (a change
//! of the judge, or of `compare`, seen on the same decisions in minutes). `--jobs J`
//! (default 2) runs J cases at a time: the bench runs and comparisons of a case are
//! single-threaded, so two cases keep both cores busy (the seconds column then counts
//! the time the cases shared).
//!
//! A hidden effect not found is listed on its case's line with why (the round that came
//! closest, [`Unfound`]) and, with `--maps-within-uncertainty`, how much of its signature
//! the first round's estimate says the maps and parameters take and what would tell it
//! from them ([`shared_with_maps`]).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use serde_json::Value;
use workbench::diagnose::library::{cause_of, current_value, library};
use workbench::effects_file::load_effects;
use workbench::measure::{load, Measurement};
use workbench::stats::{rms, Rng};
use workbench::vbench::bench_effects::format_bench_effects;
use workbench::vbench::scenario::{is_moved, Pick, Scenario};

mod common;
use common::sibling;

/// Most rounds of the loop.
const ROUNDS: usize = 5;
/// A moved channel must end within this factor of its floor.
const FLOOR_FACTOR: f64 = 1.2;
/// No channel may end worse than this factor of its starting error.
const WORSE_FACTOR: f64 = 1.15;

/// The acquisition faults and the twin effect that models each.
const DAQ_TWIN: [(&str, &str); 3] =
    [("amplifier_lag", "sensor_lag"), ("daq_skew", "sensor_delay"), ("offset_drift", "sensor_offset")];

struct Case {
    seed: u64,
    scenario: Scenario,
    runs: Vec<PathBuf>,
    /// Noise-free: the same bench, and the same test with nothing hidden.
    exact: Vec<PathBuf>,
    clean: Vec<PathBuf>,
    setup: Setup,
}

/// How every case is run: the flags, parsed once.
#[derive(Clone)]
struct Setup {
    /// Judge the rounds a kept directory holds instead of running them (`--replay`).
    replay: bool,
    /// `--sensor-noise` for every diagnosis (absolute, or `default`).
    sensor_noise: Option<PathBuf>,
    /// Round 1 estimates the maps within their stated uncertainty and the loop goes on
    /// from the estimate (`--maps-within-uncertainty`).
    within: bool,
}

/// What happened to one case.
#[derive(Default)]
struct Outcome {
    class: String,
    campaign: bool,
    /// The bench's maps are perturbed (a wrong map beside the hidden effects).
    maps: bool,
    nothing_hidden: bool,
    honest: bool,
    miss: bool,
    false_claim: Vec<String>,
    /// Of `false_claim`, the effects first written in a round whose model already ran on
    /// an empirically corrected data directory (a table fitted in an earlier round).
    false_on_table: Vec<String>,
    /// The same counting only the hidden effects as the truth (not the perturbation).
    false_claim_strict: Vec<String>,
    /// Hidden library effects that move a channel of the run ([`excited_ids`]).
    library: Vec<Library>,
    /// Coverage of the truth by the 95 % interval: (inside, total).
    coverage: (usize, usize),
    /// The same for the found effects' other parameters ([`rest_covered`]).
    coverage_rest: (usize, usize),
    /// Effects found with no interval stated for them (not in [`Outcome::coverage`]).
    unstated: usize,
    rounds: usize,
    /// The loop ended with an empirically corrected data directory.
    empirical: bool,
    last: String,
    seconds: f64,
    /// Why a case is not honest, or what a false claim left: moved channels above their
    /// floor, channels made worse.
    why: Vec<String>,
    /// Hidden library effects not found, and stated intervals that miss the truth.
    missed: Vec<String>,
}

/// A hidden library effect that moves a channel of the scenario's run.
struct Library {
    found: bool,
    /// Beside perturbed maps: its signal against theirs ([`MapsError::ratio`]).
    against_maps: Option<f64>,
    /// Why it is not in the final file, when it is not ([`Unfound::of`]).
    why: Option<Why>,
    /// What it removes of the error at that closest round (none when it was named, or
    /// when no round ranked it).
    removes: Option<f64>,
}

/// What kept a hidden effect out of the final file, in the round that came closest to
/// naming it: the sweep's failures explained by the verdicts' own reasons.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Why {
    /// No round's ranking held it.
    NeverRanked,
    /// Ranked, never significant.
    NotSignificant,
    /// Refused: it makes a channel worse (beside a wrong map, most often).
    MadeWorse,
    /// Refused: its value changes over the run, with speed or with the load.
    NotConstant,
    /// Refused: a change of a map removes as much (a wrong map looks alike).
    MapAlike,
    /// Refused: it leaves its channel above the noise (absorbs only part).
    AbsorbsPart,
    /// Refused for another reason.
    OtherRefusal,
    /// Significant, not refused, leading its round's ranking, which ended unexplained:
    /// it removes too little of the error to be named.
    TooLittle,
    /// Significant and not refused, but another candidate or a table was preferred.
    NotChosen,
    /// Named in a round, not in the final file (taken out later).
    Dropped,
}

impl Why {
    const ALL: [Why; 10] = [
        Why::NeverRanked,
        Why::NotSignificant,
        Why::MadeWorse,
        Why::NotConstant,
        Why::MapAlike,
        Why::AbsorbsPart,
        Why::OtherRefusal,
        Why::TooLittle,
        Why::NotChosen,
        Why::Dropped,
    ];

    fn label(self) -> &'static str {
        match self {
            Why::NeverRanked => "never ranked",
            Why::NotSignificant => "never significant",
            Why::MadeWorse => "refused, makes a channel worse",
            Why::NotConstant => "refused, not a constant",
            Why::MapAlike => "refused, a map change does as well",
            Why::AbsorbsPart => "refused, absorbs only part",
            Why::OtherRefusal => "refused otherwise",
            Why::TooLittle => "leads, removes too little to name",
            Why::NotChosen => "another candidate or a table chosen",
            Why::Dropped => "named, later taken out",
        }
    }

    /// The kind of a verdict's refusal text.
    fn of_refusal(text: &str) -> Why {
        if text.contains("worse") {
            Why::MadeWorse
        } else if text.contains("changes with") || text.contains("drifts over") {
            Why::NotConstant
        } else if text.contains("look alike") || text.contains("as much") {
            Why::MapAlike
        } else if text.contains("above the noise") {
            Why::AbsorbsPart
        } else {
            Why::OtherRefusal
        }
    }
}

/// A hidden effect not found: why, and the round that came closest, for the case's line.
struct Unfound {
    why: Why,
    detail: String,
    /// Its share of the error removed there ([`Library::removes`]).
    removes: Option<f64>,
}

impl Unfound {
    /// From the rounds' JSON: a round that named `id` (then [`Why::Dropped`]); else the
    /// ranking entry of `id` with the largest reduction, significant ones first, and its
    /// refusal. `id` is the claim ([`claim_key`]), which the JSON's labels are (effects are
    /// ranked by cause): a C_Kistler_L offset missed is not explained by how close a V_DC
    /// offset came.
    fn of(rounds: &[Value], id: &str) -> Unfound {
        let named = rounds
            .iter()
            .position(|j| j["stated"].as_array().is_some_and(|st| st.iter().any(|x| x["effect"] == id)));
        if let Some(k) = named {
            return Unfound { why: Why::Dropped, detail: format!("named in round {}", k + 1), removes: None };
        }
        let entries = rounds.iter().enumerate().flat_map(|(k, j)| {
            let ranking = j["ranking"].as_array().map(Vec::as_slice).unwrap_or_default();
            ranking.iter().enumerate().filter(move |(_, c)| c["effect"] == id).map(move |(r, c)| (k, r, c))
        });
        let reduction =
            |c: &Value| c["confirmed_reduction"].as_f64().or(c["error_reduction"].as_f64()).unwrap_or(0.0);
        let key = |c: &Value| (c["significant"].as_bool().unwrap_or(false), reduction(c));
        let best = entries.max_by(|a, b| {
            let (ka, kb) = (key(a.2), key(b.2));
            ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
        });
        let Some((k, r, c)) = best else {
            return Unfound { why: Why::NeverRanked, detail: String::new(), removes: None };
        };
        let refused = c["refused"].as_str().filter(|t| !t.is_empty());
        let why = match (c["significant"].as_bool().unwrap_or(false), refused) {
            (false, _) => Why::NotSignificant,
            (true, Some(t)) => Why::of_refusal(t),
            (true, None) if r == 0 && rounds[k]["kind"].as_str() == Some("unexplained") => Why::TooLittle,
            (true, None) => Why::NotChosen,
        };
        let head = format!("round {} #{} removes {:.0} %", k + 1, r + 1, 100.0 * reduction(c));
        let detail = match refused {
            Some(t) if why != Why::NotSignificant => {
                format!("{head}: {}", t.chars().take(70).collect::<String>())
            }
            _ => head,
        };
        Unfound { why, detail, removes: Some(reduction(c)) }
    }
}

/// How much of effect `id`'s signature the first round's estimate within the maps'
/// uncertainty says the maps and parameters take (`shared`), and the field or group
/// that, known exactly, leaves the most of it its own (`separator`), for a line of a
/// case's failures: `None` without that estimate or that cause in it.
fn shared_with_maps(rounds: &[Value], id: &str) -> Option<String> {
    let credits = rounds.first()?["within_uncertainty"]["credits"].as_array()?;
    let c = credits.iter().find(|c| c["cause"] == id)?;
    let shared = c["shared"].as_f64()?;
    let by = match (c["separator"]["unit"].as_str(), c["separator"]["shared_then"].as_f64()) {
        (Some(unit), Some(then)) => format!(", {:.0} % with {unit} exact", 100.0 * then),
        _ => String::new(),
    };
    Some(format!("; the maps take {:.0} %{by}", 100.0 * shared))
}

/// The sweep's flags, parsed once (an unknown flag or a bad value is an error, not a
/// default: a typo must not start a 90-minute sweep on the wrong seeds).
#[derive(clap::Parser)]
#[command(about = "Issue 12's proof sweep: the user's loop run blind on the physics plant")]
struct Options {
    /// Cases to run (or judge again with --replay).
    #[arg(long, default_value_t = 200)]
    cases: u64,
    /// First seed (proof seeds from 1,000,000; tuning used 500,000 on).
    #[arg(long, default_value_t = 1_000_000)]
    first: u64,
    /// Cases run at a time.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(1..))]
    jobs: u64,
    /// Exit 1 when a target is missed.
    #[arg(long)]
    check: bool,
    /// Keep each case's files in DIR/SEED.
    #[arg(long, value_name = "DIR", conflicts_with = "replay")]
    keep: Option<PathBuf>,
    /// Judge the rounds kept in DIR again without running a diagnosis.
    #[arg(long, value_name = "DIR")]
    replay: Option<PathBuf>,
    /// The user states the sensors' noise to diagnose (`--sensor-noise`): `default`, the
    /// bench's (the noise its runs have), or a noise file.
    #[arg(long, value_name = "default|FILE")]
    sensor_noise: Option<PathBuf>,
    /// Round 1 also estimates the maps within their stated uncertainty
    /// (`diagnose --maps-within-uncertainty --write-estimate`); the loop goes on from the
    /// estimate refitted with its credited set (its data directory and effect file).
    #[arg(long)]
    maps_within_uncertainty: bool,
}

fn simrod(dir: &Path, args: &[String]) -> Result<String, String> {
    let out =
        Command::new(sibling("simrod")).current_dir(dir).args(args).output().map_err(|e| e.to_string())?;
    if out.status.success() {
        Ok(String::from_utf8_lossy(&out.stdout).into_owned())
    } else {
        Err(format!("simrod {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim()))
    }
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// The runs of case `seed`: the scenario's own, then for a campaign 1–4 more of the
/// same bench on other profiles and scales; each with its noise-free twin.
fn make_case(dir: &Path, seed: u64, setup: &Setup) -> Result<Case, String> {
    let scenario = Scenario::draw(seed);
    let mut r = Rng::new(seed, 7);
    let extra = if r.uniform() < 0.4 { 1 + r.index(4) } else { 0 };
    let fx = format_bench_effects(&scenario.effects())?;
    std::fs::write(dir.join("hidden.toml"), fx).map_err(|e| e.to_string())?;
    let (mut runs, mut exact, mut clean) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..=extra {
        let (run, ex, cl) = (format!("run{k}.csv"), format!("exact{k}.csv"), format!("clean{k}.csv"));
        let test = if k == 0 {
            scenario.clone()
        } else {
            Scenario::draw(seed.wrapping_mul(7919).wrapping_add(k as u64))
        };
        let mut nothing = noise_free(&test);
        nothing.extend(strings(&["--out", &cl]));
        let mut a = if k == 0 {
            strings(&["bench", "--scenario", "random", "--seed", &seed.to_string()])
        } else {
            let other = &test;
            let mut a = strings(&["bench", "--profile", other.profile.name(), "--effects", "hidden.toml"]);
            a.extend(strings(&["--throttle-scale", &other.throttle_scale.to_string()]));
            a.extend(strings(&["--load-scale", &other.load_scale.to_string()]));
            if let Some(p) = scenario.perturb_maps {
                a.extend(strings(&["--perturb-maps", &p.to_string()]));
            }
            a.extend(strings(&["--seed", &(seed + k as u64).to_string()]));
            a
        };
        a.push("-q".into());
        let mut quiet = a.clone();
        a.extend(strings(&["--out", &run]));
        quiet.extend(strings(&["--noise", "none", "--out", &ex]));
        if k == 0 {
            quiet.extend(strings(&["--truth", "exact0.truth.toml"]));
        }
        if setup.replay {
            if let Some(f) = [&run, &ex, &cl].into_iter().find(|f| !dir.join(f).is_file()) {
                return Err(format!("--replay: {} has no {f}", dir.display()));
            }
        } else {
            simrod(dir, &a)?;
            simrod(dir, &quiet)?;
            simrod(dir, &nothing)?;
        }
        runs.push(dir.join(run));
        exact.push(dir.join(ex));
        clean.push(dir.join(cl));
    }
    Ok(Case { seed, scenario, runs, exact, clean, setup: setup.clone() })
}

/// `simrod bench` of `s`'s test (profile and scales), noise-free, nothing hidden yet.
fn noise_free(s: &Scenario) -> Vec<String> {
    let mut a = strings(&["bench", "--profile", s.profile.name(), "--noise", "none", "-q"]);
    a.extend(strings(&["--throttle-scale", &s.throttle_scale.to_string()]));
    a.extend(strings(&["--load-scale", &s.load_scale.to_string()]));
    a
}

/// Beside perturbed maps: the noise-free plant runs of the scenario's test with nothing
/// hidden (`clean0.csv`) and with the maps' perturbation alone (`maps0.csv`, run once per
/// case), against which each hidden effect's own signal is measured ([`Self::ratio`]).
struct MapsError {
    clean: Measurement,
    maps: Measurement,
}

/// A plant run of `s`'s test, noise-free, with `extra` flags, into `dir/name` (kept: run
/// only when missing, as in `--replay`).
fn plant_run(dir: &Path, s: &Scenario, name: &str, extra: &[String]) -> Result<Measurement, String> {
    if !dir.join(name).is_file() {
        let mut a = noise_free(s);
        a.extend_from_slice(extra);
        a.extend(strings(&["--out", name]));
        simrod(dir, &a)?;
    }
    load(&dir.join(name), None).map_err(|e| e.to_string())
}

impl MapsError {
    /// `None` when the case's maps are as identified.
    fn of(dir: &Path, c: &Case) -> Result<Option<Self>, String> {
        let Some(seed) = c.scenario.perturb_maps else { return Ok(None) };
        let maps =
            plant_run(dir, &c.scenario, "maps0.csv", &strings(&["--perturb-maps", &seed.to_string()]))?;
        let clean = load(c.clean.first().ok_or("no clean run")?, None).map_err(|e| e.to_string())?;
        Ok(Some(Self { clean, maps }))
    }

    /// How large the scenario's `i`-th effect is against the maps' error, on the channel
    /// of `moves` where the ratio is largest: the RMS change of the effect alone
    /// (`alone0_ID.csv`) over the RMS change of the maps' perturbation alone, each
    /// against the nothing-hidden run. Below 1, the wrong maps' error outweighs the
    /// effect on every channel it moves: a split of the found figure by it says how much
    /// of what is not found is that. Infinite where the maps move the channel not at all
    /// and the effect does; 0 where the effect moves none of them.
    fn ratio(&self, dir: &Path, s: &Scenario, i: usize, moves: &[String]) -> Result<f64, String> {
        let id = s.picks.get(i).map(Pick::id).ok_or("no such pick")?;
        let (fx, out) = (format!("alone0_{id}.toml"), format!("alone0_{id}.csv"));
        if !dir.join(&out).is_file() {
            std::fs::write(dir.join(&fx), format_bench_effects(&s.effect_alone(i))?)
                .map_err(|e| e.to_string())?;
        }
        let alone = plant_run(dir, s, &out, &strings(&["--effects", &fx]))?;
        let ratio = |ch: &String| -> Option<f64> {
            let z = &self.clean.signal(ch)?.values;
            let e = rms_diff(&alone.signal(ch)?.values, z);
            let m = rms_diff(&self.maps.signal(ch)?.values, z);
            // A channel neither moves (V_DC_busbars without a supply resistance) says nothing.
            (e > 0.0).then(|| if m > 0.0 { e / m } else { f64::INFINITY })
        };
        Ok(moves.iter().filter_map(ratio).fold(0.0, f64::max))
    }
}

/// The channels the truth file says effect `id` moves.
fn moves_of(truth: &toml::Value, id: &str) -> Vec<String> {
    let effects = truth.get("effect").and_then(|e| e.as_array()).map_or(&[][..], |a| a.as_slice());
    let e = effects.iter().find(|e| e.get("id").and_then(|i| i.as_str()) == Some(id));
    let moves = e.and_then(|e| e.get("moves")?.as_array().cloned()).unwrap_or_default();
    moves.iter().filter_map(|m| m.as_str().map(str::to_owned)).collect()
}

/// What the loop has added so far: the last effect file and the last model data
/// directory the diagnosis wrote.
#[derive(Debug, Clone, Default, PartialEq)]
struct Added {
    effects: Option<String>,
    data: Option<String>,
    /// `data` is the estimate within the stated uncertainty, not an empirical table.
    estimated: bool,
}

impl Added {
    /// The model flags that run the twin with what was added.
    fn flags(&self) -> Vec<String> {
        let mut a = Vec::new();
        if let Some(fx) = &self.effects {
            a.extend(strings(&["--effects", fx]));
        }
        if let Some(d) = &self.data {
            a.extend(strings(&["--data-dir", d]));
        }
        a
    }
}

/// Per run, per channel name: the twin's RMSE with what the loop `added`.
fn twin_errors(dir: &Path, c: &Case, added: &Added) -> Result<Vec<Vec<(String, f64)>>, String> {
    c.runs
        .iter()
        .map(|run| {
            let mut a = strings(&["compare", &run.display().to_string(), "--json", "--no-history"]);
            a.extend(added.flags());
            let j: Value = serde_json::from_str(&simrod(dir, &a)?).map_err(|e| e.to_string())?;
            let chans = j["channels"].as_object().ok_or("compare JSON has no channels")?;
            Ok(chans.iter().filter_map(|(k, v)| Some((k.clone(), v["rmse"].as_f64()?))).collect())
        })
        .collect()
}

/// A hidden cause that changes a channel by more than this share of its floor (RMS)
/// takes a twin without it above [`FLOOR_FACTOR`] times the floor (√(1.2² − 1)): the
/// channel is moved, however small the change is against the channel's span.
const VISIBLE: f64 = 0.663;

/// RMS difference of two series over their common length.
fn rms_diff(a: &[f64], b: &[f64]) -> f64 {
    rms(&a.iter().zip(b).map(|(x, y)| x - y).collect::<Vec<f64>>())
}

/// Per run and channel (in `names`' order): the RMS difference between the file and the
/// noise-free run, the error of the true plant model; and whether the hidden causes move
/// the channel (noise-free bench against noise-free nothing-hidden run: by 1 % of its
/// span, or by enough to show above its floor, [`VISIBLE`]). Both runs are the plant's,
/// so the twin's own differences from the plant never make a channel moved.
fn floors(c: &Case, names: &[Vec<(String, f64)>]) -> Result<Vec<Vec<(f64, bool)>>, String> {
    let read = |p: &PathBuf| -> Result<Measurement, String> { load(p, None).map_err(|e| e.to_string()) };
    c.runs
        .iter()
        .zip(c.exact.iter().zip(&c.clean))
        .zip(names)
        .map(|((run, (ex, cl)), chans)| {
            let (m, e, q) = (read(run)?, read(ex)?, read(cl)?);
            Ok(chans
                .iter()
                .map(|(name, _)| match (m.signal(name), e.signal(name), q.signal(name)) {
                    (Some(a), Some(b), Some(z)) => {
                        let floor = rms_diff(&a.values, &b.values);
                        let visible = rms_diff(&b.values, &z.values) > VISIBLE * floor;
                        (floor, is_moved(&b.values, &z.values) || visible)
                    }
                    _ => (f64::NAN, false),
                })
                .collect())
        })
        .collect()
}

/// What the loop did: every round's JSON, what each round ran with, what was added in
/// the end.
struct Rounds {
    json: Vec<Value>,
    /// Per round: whether its model ran on an empirically corrected data directory.
    on_table: Vec<bool>,
    added: Added,
    /// The first round whose proposal the loop could use: 1 when round 1's estimate
    /// replaced its proposal (`--maps-within-uncertainty`), else 0.
    proposals_from: usize,
}

/// The loop: diagnose, add what it wrote (an effect file, an empirically corrected data
/// directory), again.
fn blind_loop(dir: &Path, c: &Case) -> Result<Rounds, String> {
    let runs: Vec<String> = c.runs.iter().map(|p| p.display().to_string()).collect();
    let (mut rounds, mut added): (Vec<Value>, Added) = (Vec::new(), Added::default());
    let (mut on_table, mut proposals_from) = (Vec::new(), 0);
    for k in 1..=ROUNDS {
        on_table.push(added.data.is_some() && !added.estimated);
        let (out, data, est) = (format!("r{k}.toml"), format!("d{k}"), format!("e{k}"));
        let mut a = strings(&["diagnose"]);
        a.extend(runs.iter().cloned());
        a.extend(strings(&["--json", "--write-effects", &out, "--write-data", &data]));
        let within = c.setup.within && k == 1;
        if within {
            a.extend(strings(&["--maps-within-uncertainty", "--write-estimate", &est]));
        }
        a.extend(added.flags());
        if let Some(f) = &c.setup.sensor_noise {
            a.extend(["--sensor-noise".to_string(), f.display().to_string()]);
        }
        let kept = dir.join(format!("r{k}.json"));
        let text = if c.setup.replay {
            std::fs::read_to_string(&kept).map_err(|e| format!("--replay: {}: {e}", kept.display()))?
        } else {
            simrod(dir, &a)?
        };
        let j: Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
        let kind = j["kind"].as_str().unwrap_or("").to_owned();
        let wrote_fx = j.get("effects_written").is_some();
        let wrote_data = j.get("data_written").is_some();
        // Kept for inspection with --keep (in a temporary directory otherwise).
        if !c.setup.replay {
            let _ = std::fs::write(&kept, j.to_string());
        }
        let estimated = j.get("estimate_written").is_some();
        rounds.push(j);
        if within && estimated {
            // The verdict read the identified maps; the loop goes on from the estimate.
            added = Added { effects: Some(format!("{est}/effects.toml")), data: Some(est), estimated: true };
            proposals_from = 1;
            continue;
        }
        if kind == "nothing_missing" || !(wrote_fx || wrote_data) {
            break;
        }
        let same_fx = !wrote_fx
            || added.effects.as_ref().is_some_and(|prev| {
                std::fs::read_to_string(dir.join(prev)).ok() == std::fs::read_to_string(dir.join(&out)).ok()
            });
        if same_fx && !wrote_data {
            break;
        }
        if wrote_fx {
            added.effects = Some(out);
        }
        if wrote_data {
            added.data = Some(data);
            added.estimated = false;
        }
    }
    Ok(Rounds { json: rounds, on_table, added, proposals_from })
}

/// The effects of `claims` first written in a round that ran on an empirically
/// corrected data directory: a library effect claimed on top of a fitted table.
fn claimed_on_table(dir: &Path, r: &Rounds, claims: &[String]) -> Vec<String> {
    let (mut seen, mut first_on_table) = (BTreeSet::new(), BTreeSet::new());
    for (j, &table) in r.json.iter().zip(&r.on_table) {
        for id in ids_in(dir, j["effects_written"].as_str()) {
            if seen.insert(id.clone()) && table {
                first_on_table.insert(id);
            }
        }
    }
    claims.iter().filter(|e| first_on_table.contains(*e)).cloned().collect()
}

/// The twin effect that models each data item a map perturbation changes (the truth
/// file's `perturbation` names): the effect changes exactly that quantity in the model,
/// so claiming it describes part of the truth (a bench whose SuT inertia is 8 % above
/// the identified value *has* `inertia_scale.sut = 1.08`).
const PERTURBED_TWIN: [(&str, &str); 9] = [
    ("axle_friction_L", "axle_friction_scale"),
    ("axle_friction_R", "axle_friction_scale"),
    ("sut_inertia", "inertia_scale"),
    ("load_inertia_l", "inertia_scale"),
    ("load_inertia_r", "inertia_scale"),
    ("connector_resistance", "connector_resistance"),
    ("coupling_stiffness_identified", "coupling_stiffness"),
    ("coupling_damping", "coupling_damping"),
    ("ident.", "inverter_rate_scale"),
];

/// The scenario run's truth file (`exact0.truth.toml`, written by `bench --truth`);
/// an empty table when it is missing or unreadable (nothing perturbed, nothing excited).
fn truth_file(dir: &Path) -> toml::Value {
    let text = std::fs::read_to_string(dir.join("exact0.truth.toml")).unwrap_or_default();
    toml::from_str(&text).unwrap_or(toml::Value::Table(Default::default()))
}

/// The twin effects the truth file's perturbation justifies ([`PERTURBED_TWIN`]).
fn perturbed_ids(truth: &toml::Value) -> BTreeSet<String> {
    let names: Vec<String> = truth
        .get("perturbation")
        .and_then(|p| p.as_array())
        .map(|a| a.iter().filter_map(|i| i.get("name")?.as_str().map(str::to_owned)).collect())
        .unwrap_or_default();
    PERTURBED_TWIN
        .iter()
        .filter(|(item, _)| names.iter().any(|n| n.starts_with(item)))
        .map(|(_, fx)| fx.to_string())
        .collect()
}

/// The hidden effects the truth file says move a channel of the scenario's own run (the
/// generator's 1 %-of-span rule, `moves`): the issue counts effects "present and
/// excited"; one that moves nothing there (a backlash the run never crosses) is not
/// counted as found or missed. A campaign's other runs have no truth file: an effect
/// excited only there is not counted either.
fn excited_ids(truth: &toml::Value) -> BTreeSet<String> {
    truth
        .get("effect")
        .and_then(|e| e.as_array())
        .map(|a| {
            a.iter()
                .filter(|e| e.get("moves").and_then(|m| m.as_array()).is_some_and(|m| !m.is_empty()))
                .filter_map(|e| e.get("id")?.as_str().map(str::to_owned))
                .collect()
        })
        .unwrap_or_default()
}

/// The claim an effect's parameter makes: the effect id, or for the measurement chain
/// (one cause per channel) `effect.channel` — a C_Kistler_L gain is not a C_Kistler_R
/// gain, neither found for it nor justified by it.
fn claim_key(effect: &str, param: &str) -> String {
    cause_of(effect, param).unwrap_or(effect).to_owned()
}

/// The claims of an effect file ([`claim_key`]): every library parameter it holds off its
/// neutral value, as the cause it belongs to (read by the project's effect-file reader;
/// the file lists every channel of a chain effect, most at their neutral values).
fn ids_in(dir: &Path, file: Option<&str>) -> BTreeSet<String> {
    let Some(fx) = file.and_then(|f| load_effects(&dir.join(f)).ok()) else { return BTreeSet::new() };
    library(&model_core::Params::default())
        .iter()
        .filter(|sp| sp.off_neutral(current_value(&fx, sp)))
        .map(|sp| sp.cause.to_owned())
        .collect()
}

/// The claims the truth justifies ([`claim_key`]): its library effects, and the chain
/// effect that models each acquisition fault, on its channel.
fn truth_ids(s: &Scenario) -> BTreeSet<String> {
    s.picks
        .iter()
        .filter_map(|p| match p {
            Pick::Library { id, param, .. } => Some(claim_key(id, param)),
            Pick::Daq { id, channel, .. } => {
                DAQ_TWIN.iter().find(|(d, _)| d == id).map(|(_, t)| claim_key(t, channel.key()))
            }
            Pick::Plant { .. } => None,
        })
        .collect()
}

fn class_of(c: &Case) -> String {
    let s = &c.scenario;
    let kinds: BTreeSet<&str> = s
        .picks
        .iter()
        .map(|p| match p {
            Pick::Library { .. } => "lib",
            Pick::Plant { .. } => "plant",
            Pick::Daq { .. } => "daq",
        })
        .collect();
    let kinds: Vec<&str> = kinds.into_iter().collect();
    format!(
        "{} eff{}{}",
        s.picks.len(),
        if kinds.is_empty() { String::new() } else { format!(" {}", kinds.join("+")) },
        if s.perturb_maps.is_some() { " maps" } else { "" }
    )
}

/// Judge case `c` after its loop.
fn judge(dir: &Path, c: &Case) -> Result<Outcome, String> {
    let t0 = Instant::now();
    let before = twin_errors(dir, c, &Added::default())?;
    let floor = floors(c, &before)?;
    let loop_ = blind_loop(dir, c)?;
    let (rounds, added) = (&loop_.json, &loop_.added);
    let after = if *added == Added::default() { before.clone() } else { twin_errors(dir, c, added)? };
    let last_j = rounds.last().cloned().unwrap_or(Value::Null);
    let kind = last_j["kind"].as_str().unwrap_or("").to_owned();
    let located = last_j["unexplained"]["channel"].as_str().map(str::to_owned);
    let (mut moved_ok, mut worse, mut any_moved_high) = (true, false, false);
    let mut moved = BTreeSet::new();
    let mut why = Vec::new();
    for (run, ((b, a), f)) in before.iter().zip(&after).zip(&floor).enumerate() {
        for (((name, e0), (_, e1)), (fl, is_moved)) in b.iter().zip(a).zip(f) {
            if *is_moved {
                moved.insert(name.clone());
                if *e1 > FLOOR_FACTOR * fl {
                    moved_ok = false;
                    any_moved_high = true;
                    why.push(format!("run{run} {name} {:.2}x floor", e1 / fl));
                }
            } else if *e1 > WORSE_FACTOR * e0.max(*fl) {
                worse = true;
                why.push(format!("run{run} {name} worse {:.2}x", e1 / e0.max(*fl)));
            }
            if *is_moved && *e1 > WORSE_FACTOR * e0 {
                worse = true;
                why.push(format!("run{run} {name} worse {:.2}x", e1 / e0));
            }
        }
    }
    let located_on_moved = located.as_ref().is_some_and(|ch| moved.contains(ch));
    let honest = (moved_ok && !worse)
        || (matches!(kind.as_str(), "unexplained" | "partial") && located_on_moved && !worse);
    let hidden = truth_ids(&c.scenario);
    let mut truth = hidden.clone();
    let truth_toml = truth_file(dir);
    truth.extend(perturbed_ids(&truth_toml));
    let claimed = ids_in(dir, added.effects.as_deref());
    let unjustified = |t: &BTreeSet<String>| -> Vec<String> {
        if any_moved_high {
            claimed.difference(t).cloned().collect()
        } else {
            Vec::new()
        }
    };
    let (false_claim, false_claim_strict) = (unjustified(&truth), unjustified(&hidden));
    let (mut coverage, mut unstated) = ((0, 0), 0);
    let mut missed = Vec::new();
    let excited = excited_ids(&truth_toml);
    let maps_error = MapsError::of(dir, c)?;
    let mut library = Vec::new();
    for (i, p) in c.scenario.picks.iter().enumerate() {
        let Pick::Library { id, param, value } = p else { continue };
        if !excited.contains(*id) {
            continue;
        }
        let key = claim_key(id, param);
        let found = claimed.contains(&key);
        let beside = match &maps_error {
            Some(m) => Some(m.ratio(dir, &c.scenario, i, &moves_of(&truth_toml, id))?),
            None => None,
        };
        let unfound = (!found).then(|| Unfound::of(rounds, &key));
        if let Some(u) = &unfound {
            let against = beside.map(|r| format!("{r:.2}x the maps' error; ")).unwrap_or_default();
            let shared = shared_with_maps(rounds, &key).unwrap_or_default();
            missed.push(format!("{id} not found ({against}{}: {}{shared})", u.why.label(), u.detail));
        } else if let Some((lo, hi)) = stated_interval(&rounds[loop_.proposals_from..], &key, param)
            .or_else(|| estimate_interval(&rounds[..loop_.proposals_from], &key, param))
        {
            let inside = lo <= *value && *value <= hi;
            coverage.0 += usize::from(inside);
            coverage.1 += 1;
            if !inside {
                missed.push(format!("{id}.{param} = {value:.4} outside [{lo:.4}, {hi:.4}]"));
            }
        } else {
            unstated += 1;
            missed.push(format!("{id}.{param} found with no interval stated"));
        }
        let (why, removes) = unfound.map_or((None, None), |u| (Some(u.why), u.removes));
        library.push(Library { found, against_maps: beside, why, removes });
    }
    let why = if honest && false_claim.is_empty() { Vec::new() } else { why };
    Ok(Outcome {
        class: class_of(c),
        maps: c.scenario.perturb_maps.is_some(),
        campaign: c.runs.len() > 1,
        nothing_hidden: c.scenario.picks.is_empty() && c.scenario.perturb_maps.is_none(),
        honest,
        miss: kind == "nothing_missing" && any_moved_high,
        false_on_table: claimed_on_table(dir, &loop_, &false_claim),
        false_claim,
        false_claim_strict,
        library,
        coverage,
        coverage_rest: rest_covered(rounds, loop_.proposals_from, &c.scenario, &claimed),
        unstated,
        rounds: rounds.len(),
        empirical: added.data.is_some() && !added.estimated,
        last: last_j["verdict"].as_str().unwrap_or("").chars().take(160).collect(),
        seconds: t0.elapsed().as_secs_f64(),
        why,
        missed,
    })
}

/// The 95 % interval stated for claim `id` ([`claim_key`], the JSON's label), parameter
/// `param` (to test whether it holds the truth): the interval the verdict stated beside
/// the value the final effect file holds, i.e. in the last round
/// whose verdict names the effect (`stated`: a set's joint refit, not a member's own refit
/// in the ranking; that round's proposal wrote the value, and a later round keeps it).
/// Rounds kept before the JSON had `stated`: the first round naming it, its ranking entry.
fn stated_interval(rounds: &[Value], id: &str, param: &str) -> Option<(f64, f64)> {
    let inside =
        |ci: &Value| -> Option<(f64, f64)> { Some((ci[param][0].as_f64()?, ci[param][1].as_f64()?)) };
    if rounds.iter().any(|j| j.get("stated").is_some()) {
        return rounds.iter().rev().find_map(|j| {
            let st = j["stated"].as_array()?.iter().find(|x| x["effect"] == id)?;
            inside(&st["ci95"])
        });
    }
    for j in rounds {
        let named = j["selected"].as_array().is_some_and(|s| s.iter().any(|x| x["effect"] == id));
        let lead = j["ranking"].as_array().and_then(|r| r.iter().find(|x| x["effect"] == id));
        if let (true, Some(l)) = (named || j["kind"] == "missing", lead) {
            if let Some(ok) = inside(&l["ci95"]) {
                return Some(ok);
            }
        }
    }
    None
}

/// Coverage (inside, total) of the parameters of the found hidden causes (`claimed`)
/// that no pick sets: an inverter rate scale hidden on `decel_fwd` is stated with its
/// `accel_fwd` too, whose truth is the neutral value. Where the stated interval is the
/// parameter's whole range the run does not excite it: not counted.
fn rest_covered(rounds: &[Value], from: usize, s: &Scenario, claimed: &BTreeSet<String>) -> (usize, usize) {
    let picked: Vec<(&str, &str)> = s
        .picks
        .iter()
        .filter_map(|p| match p {
            Pick::Library { id, param, .. } => Some((*id, *param)),
            _ => None,
        })
        .collect();
    let found = |sp: &&workbench::diagnose::library::ParamSpec| {
        picked.iter().any(|(id, param)| claim_key(id, param) == sp.cause && claimed.contains(sp.cause))
            && !picked.contains(&(sp.effect, sp.param))
    };
    let mut n = (0, 0);
    for sp in library(&model_core::Params::default()).iter().filter(found) {
        let stated = stated_interval(&rounds[from..], sp.cause, sp.param)
            .or_else(|| estimate_interval(&rounds[..from], sp.cause, sp.param));
        let Some((lo, hi)) = stated.filter(|&(lo, hi)| lo > sp.lower || hi < sp.upper) else { continue };
        n.0 += usize::from(lo <= sp.neutral && sp.neutral <= hi);
        n.1 += 1;
    }
    n
}

/// Counts (inside, total) summed over cases.
fn summed(counts: impl Iterator<Item = (usize, usize)>) -> (usize, usize) {
    counts.fold((0, 0), |a, x| (a.0 + x.0, a.1 + x.1))
}

/// The 95 % interval the estimate of round 1 stated for `param` of the set member `id`,
/// when the loop went on from that estimate (`rounds` is then round 1 alone) and no later
/// round refitted it: the value the final file holds is the set's.
fn estimate_interval(rounds: &[Value], id: &str, param: &str) -> Option<(f64, f64)> {
    let set = rounds.first()?["within_uncertainty"]["set"].as_array()?;
    let member = set.iter().find(|c| c["cause"] == id)?;
    let k = member["params"].as_array()?.iter().position(|p| p[0] == param)?;
    let ci = &member["ci95"][k];
    Some((ci[0].as_f64()?, ci[1].as_f64()?))
}

/// The effects not found, counted by what they remove of the error at the round that
/// came closest: one that removes little there is buried in what else is wrong (beside
/// perturbed maps, most often), not turned down.
fn by_removal(o: &[Outcome]) -> String {
    let bins = [("under 10 %", 0.0, 0.1), ("10-50 %", 0.1, 0.5), ("50 % and more", 0.5, f64::INFINITY)];
    let unfound: Vec<(f64, bool)> =
        o.iter().flat_map(|x| x.library.iter().filter_map(move |l| Some((l.removes?, x.maps)))).collect();
    let rows: Vec<String> = bins
        .iter()
        .map(|&(label, lo, hi)| {
            let inside: Vec<bool> =
                unfound.iter().filter(|(r, _)| (lo..hi).contains(r)).map(|(_, maps)| *maps).collect();
            let beside = inside.iter().filter(|m| **m).count();
            format!("{label} {} ({beside} beside perturbed maps)", inside.len())
        })
        .collect();
    rows.join("; ")
}

fn pct(a: usize, b: usize) -> String {
    if b == 0 {
        "-".into()
    } else {
        format!("{:.1} % ({a}/{b})", 100.0 * a as f64 / b as f64)
    }
}

fn main() {
    let o = <Options as clap::Parser>::parse();
    let (n, first, jobs, check) = (o.cases, o.first, o.jobs as usize, o.check);
    // The diagnoses run in each case's directory: the kept directory and a file named
    // relative to here are made absolute (a relative --keep failed every case).
    let absolute = |p: PathBuf| std::path::absolute(&p).unwrap_or(p);
    let keep = o.replay.clone().or(o.keep).map(absolute);
    let sensor_noise = o.sensor_noise.map(|f| if f == Path::new("default") { f } else { absolute(f) });
    let setup = Setup { replay: o.replay.is_some(), sensor_noise, within: o.maps_within_uncertainty };
    println!(
        "{:>9} {:<22} {:>4} {:>6} {:>6} {:>7}  last verdict",
        "seed", "class", "runs", "honest", "rounds", "s"
    );
    // Cases are independent: `jobs` at a time, printed in seed order as they finish.
    let next = std::sync::atomic::AtomicU64::new(first);
    let (tx, rx) = std::sync::mpsc::channel::<(u64, String, Option<Outcome>)>();
    let mut outcomes = Vec::new();
    std::thread::scope(|scope| {
        for _ in 0..jobs {
            let (tx, next, keep, setup) = (tx.clone(), &next, keep.as_deref(), &setup);
            scope.spawn(move || loop {
                let seed = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if seed >= first + n {
                    break;
                }
                let (text, o) = one_case(seed, keep, setup);
                if tx.send((seed, text, o)).is_err() {
                    break;
                }
            });
        }
        drop(tx);
        let mut done = std::collections::BTreeMap::new();
        let mut print_next = first;
        for (seed, text, o) in rx {
            done.insert(seed, (text, o));
            while let Some((text, o)) = done.remove(&print_next) {
                print!("{text}");
                outcomes.extend(o);
                print_next += 1;
            }
        }
    });
    std::process::exit(i32::from(!summary(&outcomes) && check));
}

/// Make, run and judge the case of `seed`: its lines of the table, and its outcome.
fn one_case(seed: u64, keep: Option<&Path>, setup: &Setup) -> (String, Option<Outcome>) {
    let dir = match keep {
        Some(k) => {
            let d = k.join(seed.to_string());
            if let Err(e) = std::fs::create_dir_all(&d) {
                return (format!("{seed:>9} cannot make {}: {e}\n", d.display()), None);
            }
            Kept::At(d)
        }
        None => match tempfile::tempdir() {
            Ok(t) => Kept::Temp(t),
            Err(e) => return (format!("{seed:>9} no temporary directory: {e}\n"), None),
        },
    };
    let case = match make_case(dir.path(), seed, setup) {
        Ok(c) => c,
        Err(e) => return (format!("{seed:>9} the bench refused the case: {e}\n"), None),
    };
    match judge(dir.path(), &case) {
        Ok(o) => {
            let mut text = format!(
                "{:>9} {:<22} {:>4} {:>6} {:>6} {:>7.1}  {}{}{}\n",
                case.seed,
                o.class,
                case.runs.len(),
                if o.honest { "yes" } else { "NO" },
                format!("{}{}", o.rounds, if o.empirical { "E" } else { "" }),
                o.seconds,
                if o.miss { "[MISS] " } else { "" },
                match (o.false_claim.is_empty(), o.false_on_table.is_empty()) {
                    (true, _) => String::new(),
                    (false, true) => format!("[FALSE {:?}] ", o.false_claim),
                    (false, false) =>
                        format!("[FALSE {:?}, on a table {:?}] ", o.false_claim, o.false_on_table),
                },
                o.last
            );
            if !o.why.is_empty() {
                let what = if o.honest { "left by the false claim" } else { "not honest" };
                text.push_str(&format!("{:>9}   {what}: {}\n", "", o.why.join(", ")));
            }
            if !o.missed.is_empty() {
                text.push_str(&format!("{:>9}   library: {}\n", "", o.missed.join(", ")));
            }
            (text, Some(o))
        }
        Err(e) => (format!("{seed:>9} failed: {e}\n"), None),
    }
}

/// A case's directory: temporary, or kept for inspection (`--keep DIR`).
enum Kept {
    Temp(tempfile::TempDir),
    At(PathBuf),
}

impl Kept {
    fn path(&self) -> &Path {
        match self {
            Kept::Temp(t) => t.path(),
            Kept::At(p) => p,
        }
    }
}

/// Print the figures by class and overall; whether every target is met.
fn summary(o: &[Outcome]) -> bool {
    let count = |f: &dyn Fn(&Outcome) -> bool| o.iter().filter(|x| f(x)).count();
    let classes: BTreeSet<&str> = o.iter().map(|x| x.class.as_str()).collect();
    println!("\n{:<24} {:>5} {:>18} {:>6} {:>12}", "class", "cases", "honest", "misses", "false claims");
    for cl in classes {
        let of = |x: &Outcome| x.class == cl;
        println!(
            "{:<24} {:>5} {:>18} {:>6} {:>12}",
            cl,
            count(&of),
            pct(count(&|x| of(x) && x.honest), count(&of)),
            count(&|x| of(x) && x.miss),
            count(&|x| of(x) && !x.false_claim.is_empty())
        );
    }
    let total = o.len();
    let honest = count(&|x| x.honest);
    let false_claims = count(&|x| !x.false_claim.is_empty());
    let lib_where = |camp: bool, maps: &dyn Fn(bool) -> bool| {
        let all: Vec<&Library> =
            o.iter().filter(|x| x.campaign == camp && maps(x.maps)).flat_map(|x| &x.library).collect();
        (all.iter().filter(|l| l.found).count(), all.len())
    };
    let lib = |camp: bool| lib_where(camp, &|_| true);
    let (fs, ns) = lib(false);
    let (fc, nc) = lib(true);
    let quiet = count(&|x| x.nothing_hidden && x.library.is_empty() && x.false_claim.is_empty() && x.honest);
    let hidden_none = count(&|x| x.nothing_hidden);
    let (cin, ctot) = summed(o.iter().map(|x| x.coverage));
    println!("\nhonest: {}  (target >= 95 %)", pct(honest, total));
    println!("false claims: {}  (target <= 2 %)", pct(false_claims, total));
    println!(
        "  counting a perturbed parameter's own effect as false too: {}",
        pct(count(&|x| !x.false_claim_strict.is_empty()), total)
    );
    let on_table: usize = o.iter().map(|x| x.false_on_table.len()).sum();
    let claims: usize = o.iter().map(|x| x.false_claim.len()).sum();
    println!(
        "  false effects first claimed on top of an empirical table: {} of the {claims} false effects, in {} of the {false_claims} cases",
        on_table,
        count(&|x| !x.false_on_table.is_empty())
    );
    println!("misses: {}", count(&|x| x.miss));
    println!("library effects found, single runs: {}  (target >= 95 %)", pct(fs, ns));
    println!("library effects found, campaigns: {}  (target >= 98 %)", pct(fc, nc));
    for (what, camp) in [("single runs", false), ("campaigns", true)] {
        let (fi, ni) = lib_where(camp, &|m| !m);
        let (fp, np) = lib_where(camp, &|m| m);
        println!("  {what}: maps as identified {}, maps perturbed {}", pct(fi, ni), pct(fp, np));
    }
    let by_ratio = |bin: &dyn Fn(f64) -> bool| {
        let all: Vec<&Library> =
            o.iter().flat_map(|x| &x.library).filter(|l| l.against_maps.is_some_and(bin)).collect();
        pct(all.iter().filter(|l| l.found).count(), all.len())
    };
    println!(
        "  beside perturbed maps, by the effect's own signal against the maps' error on its best channel: below 1x {}, 1-3x {}, 3x and more {}",
        by_ratio(&|r| r < 1.0),
        by_ratio(&|r| (1.0..3.0).contains(&r)),
        by_ratio(&|r| r >= 3.0)
    );
    let unfound: Vec<(Why, bool)> =
        o.iter().flat_map(|x| x.library.iter().filter_map(move |l| Some((l.why?, x.maps)))).collect();
    if !unfound.is_empty() {
        let n = |w: Why, beside: &dyn Fn(bool) -> bool| {
            unfound.iter().filter(|u| u.0 == w && beside(u.1)).count()
        };
        let rows: Vec<String> = Why::ALL
            .iter()
            .map(|&w| (w, n(w, &|_| true), n(w, &|m| m)))
            .filter(|(_, all, _)| *all > 0)
            .map(|(w, all, maps)| format!("{} {all} ({maps} beside perturbed maps)", w.label()))
            .collect();
        println!("  not found, why (the round that came closest): {}", rows.join("; "));
        println!("  not found, by what they remove at that round: {}", by_removal(o));
    }
    println!("nothing hidden, nothing claimed: {}  (target >= 98 %)", pct(quiet, hidden_none));
    println!("95 % intervals covering the truth: {}  (target 90-99 %)", pct(cin, ctot));
    // An interval holds the data's stated uncertainty, which only a perturbed map
    // realises: apart, the maps as identified show how much of the width that is.
    let cov_where = |maps: bool| summed(o.iter().filter(|x| x.maps == maps).map(|x| x.coverage));
    let ((ii, it), (pi, pt)) = (cov_where(false), cov_where(true));
    println!("  maps as identified {}, maps perturbed {}", pct(ii, it), pct(pi, pt));
    println!("  found with no interval stated: {}", o.iter().map(|x| x.unstated).sum::<usize>());
    let (ri, rt) = summed(o.iter().map(|x| x.coverage_rest));
    println!(
        "  the found effects' other stated parameters (truth: neutral): {}; all together {}",
        pct(ri, rt),
        pct(cin + ri, ctot + rt)
    );
    let rate = |a: usize, b: usize| if b == 0 { 1.0 } else { a as f64 / b as f64 };
    let cov = rate(cin, ctot);
    rate(honest, total) >= 0.95
        && rate(false_claims, total) <= 0.02
        && rate(fs, ns) >= 0.95
        && rate(fc, nc) >= 0.98
        && rate(quiet, hidden_none) >= 0.98
        && (ctot == 0 || (0.90..=0.99).contains(&cov))
}
