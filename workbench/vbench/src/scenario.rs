//! Realistic random cases (`simrod bench --scenario random --seed N`): a built-in
//! profile with random scales and load sign, 0–3 effects drawn from the union of the
//! twin's library, the plant's bench-only physics and the acquisition's effects, each
//! at a magnitude in its realistic range, maps perturbed or not, the bench's noise. The
//! run is written as any measurement; the truth goes to a separate file that no
//! diagnosis code reads (tests read it to judge).

use serde::Serialize;

use model_core::effects::EFFECTS;
use model_core::{Builtin, Channel, MEASURED};
use simrod_numerics::stats::Rng;
use simrod_plant::PLANT_EFFECTS;

use crate::bench_effects::BenchEffects;
use crate::chain::Recorded;
use crate::daq::{channel_key, DAQ_EFFECTS};

/// Streams of the scenario's random numbers (one per purpose, so each draw is stable).
const S_PROFILE: u64 = 0;
const S_SCALES: u64 = 1;
const S_COUNT: u64 = 2;
const S_PICK: u64 = 3;
const S_PERTURB: u64 = 4;
const S_VALUES: u64 = 100;

/// Most effects hidden in one case.
pub const MAX_EFFECTS: usize = 3;

/// One drawn effect.
#[derive(Debug, Clone, PartialEq)]
pub enum Pick {
    /// A twin effect: its proof parameter, drawn in the proof range.
    Library { id: &'static str, param: &'static str, value: f64 },
    /// Bench-only physics: every parameter drawn in its realistic range.
    Plant { id: &'static str, params: Vec<(&'static str, f64)> },
    /// An acquisition effect on one channel.
    Daq { id: &'static str, channel: Channel, value: f64 },
}

impl Pick {
    /// The effect id.
    pub fn id(&self) -> &'static str {
        match self {
            Self::Library { id, .. } | Self::Plant { id, .. } | Self::Daq { id, .. } => id,
        }
    }

    /// Switch this effect on in `fx`.
    fn apply(&self, fx: &mut BenchEffects) {
        // Values are drawn inside declared ranges, so `set` accepts them.
        match self {
            Self::Library { id, param, value } => {
                let _ = fx.library.set(id, param, *value as f32);
            }
            Self::Plant { id, params } => {
                for (p, v) in params {
                    let _ = fx.plant.set(id, p, *v);
                }
            }
            Self::Daq { id, channel, value } => {
                let _ = fx.daq.set(id, &channel_key(*channel), *value);
            }
        }
    }
}

/// A drawn case.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    pub seed: u64,
    pub profile: Builtin,
    pub throttle_scale: f32,
    pub load_scale: f32,
    pub picks: Vec<Pick>,
    /// Seed of the map perturbation, if the bench's data is perturbed.
    pub perturb_maps: Option<u64>,
}

fn uniform(rng: &mut Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.uniform()
}

/// Index in `0..n` (n > 0).
fn index(rng: &mut Rng, n: usize) -> usize {
    ((rng.uniform() * n as f64) as usize).min(n.saturating_sub(1))
}

/// Every effect id the generator draws from, with how to draw it.
fn pool() -> Vec<&'static str> {
    let lib = EFFECTS.iter().filter(|e| e.proof.is_some()).map(|e| e.id);
    let plant = PLANT_EFFECTS.iter().map(|e| e.id);
    let daq = DAQ_EFFECTS.iter().map(|e| e.id);
    lib.chain(plant).chain(daq).collect()
}

fn draw_pick(id: &'static str, rng: &mut Rng) -> Option<Pick> {
    if let Some(e) = EFFECTS.iter().find(|e| e.id == id) {
        let p = e.proof?;
        let value = uniform(rng, f64::from(p.lo), f64::from(p.hi));
        return Some(Pick::Library { id, param: p.param, value });
    }
    if let Some(e) = PLANT_EFFECTS.iter().find(|e| e.id == id) {
        let params = e.params.iter().map(|p| (p.name, uniform(rng, p.realistic.0, p.realistic.1))).collect();
        return Some(Pick::Plant { id, params });
    }
    let d = DAQ_EFFECTS.iter().find(|d| d.id == id)?;
    let channels = d.channels();
    let channel = *channels.get(index(rng, channels.len()))?;
    let (lo, hi) = (d.realistic)(channel)?;
    Some(Pick::Daq { id, channel, value: uniform(rng, lo, hi) })
}

impl Scenario {
    /// The case of `seed`: the same seed always gives the same case.
    pub fn draw(seed: u64) -> Self {
        let mut r = Rng::new(seed, S_PROFILE);
        let profile = Builtin::ALL[index(&mut r, Builtin::ALL.len())];
        let mut r = Rng::new(seed, S_SCALES);
        let throttle_scale = uniform(&mut r, 0.6, 1.0) as f32;
        let sign = if r.uniform() < 0.5 { -1.0 } else { 1.0 };
        let load_scale = (sign * uniform(&mut r, 0.3, 1.0)) as f32;
        let n = index(&mut Rng::new(seed, S_COUNT), MAX_EFFECTS + 1);
        let mut ids = pool();
        let mut r = Rng::new(seed, S_PICK);
        let mut picks = Vec::with_capacity(n);
        for k in 0..n {
            let id = ids.remove(index(&mut r, ids.len()));
            if let Some(p) = draw_pick(id, &mut Rng::new(seed, S_VALUES + k as u64)) {
                picks.push(p);
            }
        }
        let mut r = Rng::new(seed, S_PERTURB);
        // A seed a user can type back (`--perturb-maps`), within TOML's integers.
        let perturb_maps = (r.uniform() < 0.5).then(|| r.next_u64() >> 33);
        Self { seed, profile, throttle_scale, load_scale, picks, perturb_maps }
    }

    /// All drawn effects switched on.
    pub fn effects(&self) -> BenchEffects {
        let mut fx = BenchEffects::none();
        for p in &self.picks {
            p.apply(&mut fx);
        }
        fx
    }

    /// The `i`-th drawn effect alone (for its own signal, against that of the maps'
    /// perturbation).
    pub fn effect_alone(&self, i: usize) -> BenchEffects {
        let mut fx = BenchEffects::none();
        if let Some(p) = self.picks.get(i) {
            p.apply(&mut fx);
        }
        fx
    }

    /// All drawn effects but the `i`-th (for what that one moves).
    pub fn effects_without(&self, i: usize) -> BenchEffects {
        let mut fx = BenchEffects::none();
        for (_, p) in self.picks.iter().enumerate().filter(|(k, _)| *k != i) {
            p.apply(&mut fx);
        }
        fx
    }
}

/// A channel is moved by an effect when the effect's contribution's RMS is at least
/// this share of the channel's span over the run.
pub const MOVED_SHARE: f64 = 0.01;

/// The measured channels on which `with` differs from `without` by at least
/// [`MOVED_SHARE`] of the channel's span (RMS).
pub fn moved_channels(with: &Recorded, without: &Recorded) -> Vec<String> {
    MEASURED
        .iter()
        .zip(with.measured.iter().zip(&without.measured))
        .filter(|(_, (a, b))| is_moved(a, b))
        .map(|(c, _)| c.name().to_owned())
        .collect()
}

/// Whether series `with` differs from `without` by at least [`MOVED_SHARE`] of their
/// joint span (RMS over their common length).
pub fn is_moved<T: Copy + Into<f64>>(with: &[T], without: &[T]) -> bool {
    let n = with.len().min(without.len());
    if n == 0 {
        return false;
    }
    let (mut lo, mut hi, mut sq) = (f64::INFINITY, f64::NEG_INFINITY, 0.0);
    for (a, b) in with.iter().zip(without) {
        let (x, y): (f64, f64) = ((*a).into(), (*b).into());
        lo = lo.min(x).min(y);
        hi = hi.max(x).max(y);
        sq += (x - y) * (x - y);
    }
    let rms = (sq / n as f64).sqrt();
    rms > 0.0 && rms >= MOVED_SHARE * (hi - lo)
}

/// The truth file of a case (TOML).
#[derive(Debug, Clone, Serialize)]
pub struct Truth {
    /// Why this file exists and who may read it.
    pub note: &'static str,
    pub seed: Seed,
    pub profile: String,
    pub throttle_scale: f32,
    pub load_scale: f32,
    /// Seed of the map perturbation (absent: the identified data).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub perturb_maps: Option<Seed>,
    /// Per perturbed map or parameter: RMS and largest change, in its unit.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub perturbation: Vec<TruthChange>,
    #[serde(rename = "effect", skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<TruthEffect>,
}

/// A seed as TOML can hold it: an integer up to `i64::MAX`, beyond that its decimal
/// text (TOML integers are 64-bit signed).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Seed {
    Int(i64),
    Text(String),
}

impl From<u64> for Seed {
    fn from(v: u64) -> Self {
        i64::try_from(v).map_or_else(|_| Self::Text(v.to_string()), Self::Int)
    }
}

/// One perturbed item.
#[derive(Debug, Clone, Serialize)]
pub struct TruthChange {
    pub name: String,
    pub unit: String,
    pub rms: f64,
    pub max_abs: f64,
}

/// One hidden effect.
#[derive(Debug, Clone, Serialize)]
pub struct TruthEffect {
    pub id: String,
    /// `twin library`, `bench-only physics` or `acquisition`.
    pub kind: &'static str,
    /// Parameter name → value (for an acquisition effect, the channel key).
    pub params: std::collections::BTreeMap<String, f64>,
    /// The measured channels it moves (see [`MOVED_SHARE`]).
    pub moves: Vec<String>,
}

impl Truth {
    /// The truth of `s`, with what each pick moves (same order as `s.picks`).
    pub fn new(s: &Scenario, moves: Vec<Vec<String>>, perturbation: Vec<TruthChange>) -> Self {
        let effects = s
            .picks
            .iter()
            .zip(moves)
            .map(|(p, moves)| {
                let (kind, params) = match p {
                    Pick::Library { param, value, .. } => ("twin library", vec![(param.to_string(), *value)]),
                    Pick::Plant { params, .. } => {
                        ("bench-only physics", params.iter().map(|(n, v)| (n.to_string(), *v)).collect())
                    }
                    Pick::Daq { channel, value, .. } => {
                        ("acquisition", vec![(channel_key(*channel), *value)])
                    }
                };
                TruthEffect { id: p.id().to_owned(), kind, params: params.into_iter().collect(), moves }
            })
            .collect();
        Self {
            note: "simrod bench --scenario random: what is hidden in the run. No diagnosis reads this file.",
            seed: s.seed.into(),
            profile: s.profile.name().to_owned(),
            throttle_scale: s.throttle_scale,
            load_scale: s.load_scale,
            perturb_maps: s.perturb_maps.map(Seed::from),
            perturbation,
            effects,
        }
    }

    /// The TOML text.
    pub fn to_toml(&self) -> Result<String, String> {
        toml::to_string(self).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases_are_reproducible_varied_and_valid() {
        let mut counts = [0usize; MAX_EFFECTS + 1];
        let (mut kinds, mut perturbed, mut negative) = ([0usize; 3], 0, 0);
        for seed in 0..200 {
            let s = Scenario::draw(seed);
            assert_eq!(s, Scenario::draw(seed), "seed {seed}");
            counts[s.picks.len()] += 1;
            perturbed += usize::from(s.perturb_maps.is_some());
            negative += usize::from(s.load_scale < 0.0);
            assert!((0.6..=1.0).contains(&s.throttle_scale) && (0.3..=1.0).contains(&s.load_scale.abs()));
            let fx = s.effects();
            fx.library.check().unwrap();
            fx.plant.check().unwrap();
            let mut ids: Vec<_> = s.picks.iter().map(Pick::id).collect();
            ids.dedup();
            assert_eq!(ids.len(), s.picks.len(), "distinct effects");
            for p in &s.picks {
                kinds[match p {
                    Pick::Library { .. } => 0,
                    Pick::Plant { .. } => 1,
                    Pick::Daq { .. } => 2,
                }] += 1;
            }
        }
        assert!(counts.iter().all(|c| *c > 30), "0..=3 effects each drawn: {counts:?}");
        assert!(kinds.iter().all(|k| *k > 20), "every kind drawn: {kinds:?}");
        assert!((60..140).contains(&perturbed) && (60..140).contains(&negative), "{perturbed} {negative}");
        assert_ne!(Scenario::draw(1), Scenario::draw(2));
    }

    #[test]
    fn every_truth_serializes_even_with_the_largest_seed() {
        for seed in (0..60).chain([u64::MAX]) {
            let s = Scenario::draw(seed);
            let moves = vec![Vec::new(); s.picks.len()];
            let text = Truth::new(&s, moves, Vec::new()).to_toml().unwrap();
            let want = if seed == u64::MAX { format!("seed = \"{seed}\"") } else { format!("seed = {seed}") };
            assert!(text.contains(&want), "{text}");
            if let Some(p) = s.perturb_maps {
                assert!(text.contains(&format!("perturb_maps = {p}")), "{text}");
            }
        }
    }

    /// Each pick alone is one part of the whole: alone it differs from no effect, and
    /// with every other pick's part it makes up `effects()` (each pick sets its own
    /// parameters only).
    #[test]
    fn a_pick_alone_is_its_part_of_the_whole() {
        let s = (0..50).map(Scenario::draw).find(|s| s.picks.len() == 3).unwrap();
        for i in 0..3 {
            let alone = s.effect_alone(i);
            assert_ne!(alone, BenchEffects::none(), "pick {i} alone sets something");
            assert_ne!(alone, s.effects(), "pick {i} alone is not all three");
            let mut all = s.effects_without(i);
            s.picks[i].apply(&mut all);
            assert_eq!(all, s.effects(), "pick {i} and the others make the whole");
        }
        assert_eq!(s.effect_alone(3), BenchEffects::none(), "no fourth pick");
    }

    #[test]
    fn truth_names_every_pick() {
        let s = (0..50).map(Scenario::draw).find(|s| s.picks.len() == 3).unwrap();
        let moves = vec![vec!["C_Kistler_L".to_owned()]; 3];
        let text = Truth::new(&s, moves, Vec::new()).to_toml().unwrap();
        for p in &s.picks {
            assert!(text.contains(&format!("id = \"{}\"", p.id())), "{text}");
        }
        assert!(text.contains("No diagnosis reads this file"));
    }
}
