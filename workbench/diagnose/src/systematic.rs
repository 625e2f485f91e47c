//! Stage 1b: how far a fitted value may be off because the identified data it is fitted
//! with may be off. The maps and parameters are identified data with a stated
//! uncertainty ([`Uncertainty::thesis`]: the thesis's figures, or ASSUMED with the
//! reason), and a fitted effect absorbs whatever part of their error looks like it (an
//! axle friction scale fitted beside a friction map 2 N m off is that much off too). The
//! statistical σ of a refit cannot see this: the error is shared by every sample.
//!
//! Each uncertain item is moved by one standard deviation, in the shape it is most
//! uncertain in (a whole map scaled, per operating region where the thesis gives two
//! figures; friction shifted; a parameter scaled), one simulation each. A refit with
//! Jacobian `J` moves by `Δθ_m = G⁻¹ J'W j_m` (`G = J'WJ`) for the response `j_m` of
//! item `m`; the items are independent, so what they *could* move it by is
//! `√(Σ_m Δθ_m²)`. Significance is judged on that only for an effect new to a model whose
//! data an earlier round corrected ([`super::uncertainty::parameter_std`]); otherwise
//! whether an effect is needed is the residual's question, how well its value is known
//! is this one's.
//!
//! The run also says where the items are: fitted jointly with the parameters, each item
//! with its stated σ as prior, the run pins down those it excites (at 0 when the data are
//! as identified, elsewhere when a map is off). The σ reported is the systematic error's
//! second moment given the run, `a' (P + ν̂ν̂') a` ([`item_moment`]), not the prior's
//! `a'a`: with the prior, every interval held the whole stated uncertainty whether or not
//! the run showed it (the proof of d2701db: 56 of 56 intervals held the truth, the
//! largest error 1.22 of its σ, the median 0.03).

use std::sync::Arc;

use model_core::effects::{EffectDecl, EFFECTS};
use model_core::{CouplingStiffness, Params, RateSet};
use simrod_numerics::stats::rms;

use simrod_io::datadir::{Map1, Map2, ModelData, ParamLine};
use simrod_io::map_prior::unit_axis;
use simrod_io::map_uncertainty::{Uncertainty, REGION_WIDTH_PCT};

use super::engine::{Options, Twin};
use super::linalg::{solve_spd, sub_matrix};
use super::preparation::{run_each, Prepared, Weights};
use super::sensitivities::normal_equations_by;

/// One uncertain item's response, `[channel][fit sample]`, at one σ of its shape (inside
/// [`Items`], weighted: `W j`).
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    pub j: Vec<Vec<f64>>,
    /// Whether it is the item's stated shape (counted in the prior σ, [`data_std`]);
    /// a map's other shapes are only for the run to tell apart.
    pub stated: bool,
    /// Its prior variance in the joint fit ([`item_moment`]): a map's three shapes share
    /// its stated variance (⅓ each), a parameter has one shape (1).
    pub var: f64,
    /// The effects whose parameter replaces the item's value (`connector_resistance` the
    /// parameter of that name): beside them the item moves nothing ([`replacing`]).
    pub replaced_by: Vec<&'static str>,
}

/// A shape of an uncertain item.
struct Moved {
    name: String,
    /// The model data with the item moved by one σ in this shape.
    data: Arc<ModelData>,
    /// Whether it is the item's stated shape.
    stated: bool,
    /// The effects that replace the item's value ([`replacing`]; a parameter group's).
    replaced_by: Vec<&'static str>,
}

/// The shapes a map's error is taken in, each at one σ of the map: the stated one (a
/// friction map shifted, the others scaled), a tilt across the map's first axis (the odd
/// Legendre term `√3(2u − 1)`, unit RMS over the axis), and the other of shift and scale
/// (a friction map scaled, the others shifted by their RMS value).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Shape {
    Stated,
    Tilt,
    Other,
}

impl Shape {
    const ALL: [Shape; 3] = [Shape::Stated, Shape::Tilt, Shape::Other];

    /// The suffix of the shape's name after the item's.
    fn suffix(self, other: &str) -> String {
        match self {
            Shape::Stated => String::new(),
            Shape::Tilt => " tilt".into(),
            Shape::Other => format!(" {other}"),
        }
    }

    /// The factor across the axis at `u ∈ [0, 1]`: the tilt's Legendre term, else 1.
    fn across(self, u: f64) -> f64 {
        match self {
            Shape::Tilt => 3f64.sqrt() * (2.0 * u - 1.0),
            _ => 1.0,
        }
    }
}

/// The identified data moved by one σ of each uncertain item (maps by shape and region,
/// parameter groups), with the item's name. Each map is moved in three shapes
/// ([`Shape`]), which share its stated variance in the joint fit: a map identified by a
/// fit errs by low-order shapes, and an effect that mimics one the stated shape misses
/// (an axle friction scale is a friction map's scale, a sensor offset a load map's
/// shift) must not be credited with what a run that pins down only the stated shape
/// cannot see.
fn moved_data(base: &ModelData, u: &Uncertainty) -> Vec<Moved> {
    let mut out = Vec::new();
    let mut moved =
        |name: String, shape: Shape, replaced_by: Vec<&'static str>, f: &dyn Fn(&mut ModelData)| {
            let mut d = base.clone();
            f(&mut d);
            out.push(Moved { name, data: Arc::new(d), stated: shape == Shape::Stated, replaced_by });
        };
    // A map's shapes: no effect replaces a map.
    let mut with = |name: String, shape: Shape, f: &dyn Fn(&mut ModelData)| moved(name, shape, Vec::new(), f);
    for (i, side) in ["L", "R"].iter().enumerate() {
        let (sd, taper) = (u.friction_nm[i].value, u.friction_taper_rpm.value);
        for sh in Shape::ALL {
            with(format!("axle_friction_{side}{}", sh.suffix("scale")), sh, &|d| {
                shift_friction(&mut d.friction[i], sd, taper, sh)
            });
        }
        // The load torque's field is the current's and the power's too (the bench's).
        let regions = [
            ("motoring", u.load_torque_motoring_rel.value, -1.0),
            ("regen", u.load_torque_regen_rel.value, 1.0),
        ];
        for (region, rel, sign) in regions {
            for sh in Shape::ALL {
                with(format!("load_torque_{side} {region}{}", sh.suffix("shift")), sh, &|d| {
                    let share = |sp: f64| 0.5 * (1.0 + sign * (sp / REGION_WIDTH_PCT).tanh());
                    for m in [&mut d.load_torque[i], &mut d.load_current[i], &mut d.load_power[i]] {
                        scale2(m, sh, |_, sp, _| rel * share(sp));
                    }
                });
            }
        }
        let rel = u.load_power_rel.value;
        for sh in Shape::ALL {
            with(format!("load_power_{side}{}", sh.suffix("shift")), sh, &|d| {
                scale2(&mut d.load_power[i], sh, |_, _, _| rel)
            });
        }
    }
    let (drive, regen) = (u.sut_power_rel.value, u.sut_power_regen_rel.value);
    let speed = u.speed_map_rel.value;
    for sh in Shape::ALL {
        let name = |item: &str| format!("{item}{}", sh.suffix("shift"));
        with(name("sut_inverter_power drive"), sh, &|d| {
            scale2(&mut d.sut_power, sh, |_, _, z| if z >= 0.0 { drive } else { 0.0 })
        });
        with(name("sut_inverter_power regen"), sh, &|d| {
            scale2(&mut d.sut_power, sh, |_, _, z| if z < 0.0 { regen } else { 0.0 })
        });
        with(name("speed_map_fwd"), sh, &|d| scale_interior(&mut d.speed_fwd, speed, sh));
        with(name("speed_map_rev"), sh, &|d| scale_interior(&mut d.speed_rev, speed, sh));
    }
    for g in &u.params {
        let k = g.sigma_ln.exp();
        moved(g.keys.join("+"), Shape::Stated, replacing(g.keys), &|d| {
            for line in &mut d.params {
                if let ParamLine::Entry { key, value, .. } = line {
                    if g.keys.contains(&key.as_str()) {
                        *value = (f64::from(*value) * k) as f32;
                    }
                }
            }
        });
    }
    out
}

/// The library effects with a parameter that replaces a value one of the
/// `parameters.toml` `keys` sets (under either coupling stiffness: the one not in use
/// moves nothing anyway). A refit of such an effect *is* a new identification of that
/// value, so the value's stated uncertainty is no error of the refit: counting it held a
/// connector resistance found at 0.0279 ± 0.0003 Ω (statistical) to ± 0.005 Ω, the
/// stated σ of the 0.0196 Ω it replaces, and never significant.
fn replacing(keys: &[&str]) -> Vec<&'static str> {
    let moves = |f: fn(&Params) -> f32| {
        [CouplingStiffness::Identified, CouplingStiffness::Datasheet].into_iter().any(|c| {
            let p0 = Params::thesis(RateSet::Identified, c);
            let mut p1 = p0;
            let set = keys.iter().all(|k| p1.set(k, f(&p0) * 2.0 + 1.0, RateSet::Identified, c).is_ok());
            set && f(&p1) != f(&p0)
        })
    };
    let replaces = |e: &EffectDecl| e.params.iter().any(|d| d.model.is_some_and(moves));
    EFFECTS.iter().filter(|e| e.in_library() && replaces(e)).map(|e| e.id).collect()
}

/// Friction magnitudes raised by `sd` [N m] away from standstill (tapered to 0 there
/// over `taper` rpm, as the map is 0 at rest), keeping each value's sign; as a tilt, by
/// `sd` times the tilt across `|x|`; as a scale, by `sd` times the magnitude over its
/// RMS (a magnitude never crosses 0: friction opposes motion).
fn shift_friction(m: &mut Map1, sd: f64, taper: f64, shape: Shape) {
    let top = m.x.iter().fold(0.0f64, |a, x| a.max(f64::from(x.abs())));
    let size = rms(&m.y.iter().map(|y| f64::from(*y)).collect::<Vec<f64>>());
    for (y, x) in m.y.iter_mut().zip(&m.x) {
        let v = f64::from(*y);
        let x = f64::from(*x);
        let u = if top > 0.0 { x.abs() / top } else { 0.0 };
        let change = match shape {
            Shape::Other if size > 0.0 => sd * v.abs() / size,
            Shape::Other => 0.0,
            _ => sd * (1.0 - (-(x / taper).powi(2)).exp()) * shape.across(u),
        };
        let sign = if v == 0.0 { 0.0 } else { v.signum() };
        *y = (sign * (v.abs() + change).max(0.0)) as f32;
    }
}

/// A 2-D map's values scaled by `1 + rel(x, y, z)` at each grid point (as a tilt, times
/// the tilt across its first axis); as a shift, raised by `rel` times the map's RMS.
fn scale2(m: &mut Map2, shape: Shape, rel: impl Fn(f64, f64, f64) -> f64) {
    let nx = m.x.len().max(1);
    let size = rms(&m.z.iter().map(|z| f64::from(*z)).collect::<Vec<f64>>());
    let unit = unit_axis(&m.x);
    for (i, z) in m.z.iter_mut().enumerate() {
        let (x, y) = (m.x.get(i % nx).copied().unwrap_or(0.0), m.y.get(i / nx).copied().unwrap_or(0.0));
        let v = f64::from(*z);
        let r = rel(f64::from(x), f64::from(y), v);
        *z = match shape {
            Shape::Other => v + r * size,
            _ => v * (1.0 + shape.across(unit(f64::from(x))) * r),
        } as f32;
    }
}

/// A monotone map's values strictly between its first and its largest scaled by
/// `1 + rel` (as a tilt, times the tilt across the axis; as a shift, raised by `rel`
/// times their RMS); the zero region and the saturation plateau stay, the map stays
/// non-decreasing.
fn scale_interior(m: &mut Map1, rel: f64, shape: Shape) {
    let lo = m.y.first().copied().unwrap_or(0.0);
    let hi = m.y.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let inside = |y: f32| y > lo && y < hi;
    let size = rms(&m.y.iter().filter(|y| inside(**y)).map(|y| f64::from(*y)).collect::<Vec<f64>>());
    let unit = unit_axis(&m.x);
    let mut prev = f32::NEG_INFINITY;
    for (y, x) in m.y.iter_mut().zip(&m.x) {
        if inside(*y) {
            let v = f64::from(*y);
            let moved = match shape {
                Shape::Other => v + rel * size,
                _ => v * (1.0 + shape.across(unit(f64::from(*x))) * rel),
            };
            *y = moved.clamp(f64::from(lo), f64::from(hi)) as f32;
        }
        *y = y.max(prev);
        prev = *y;
    }
}

/// Each uncertain item's response to one σ of each of its shapes ([`Item`]), on the
/// twin's data and the current model; none when the twin's data cannot be changed.
pub(super) fn responses(twin: &dyn Twin, p: &Prepared, o: &Options) -> Items {
    let Some(base) = twin.data() else { return Items::default() };
    let (stated, others): (Vec<Moved>, Vec<Moved>) =
        moved_data(&base, &Uncertainty::thesis()).into_iter().partition(|m| m.stated);
    let stem = |name: &str| {
        [" tilt", " shift", " scale"].iter().find_map(|x| name.strip_suffix(x)).unwrap_or(name).to_owned()
    };
    // A map's shapes share its variance; a parameter group has one.
    let maps: Vec<String> = others.iter().map(|m| stem(&m.name)).collect();
    let var = |name: &str| if maps.iter().any(|m| m == name) { 1.0 / 3.0 } else { 1.0 };
    let respond = |jobs: &[Moved]| -> Vec<Option<Vec<Vec<f64>>>> {
        let runs = run_each(jobs, o, |m| match p.unread.only_unread_differ(&base, &m.data) {
            true => Ok(p.base_sim.clone()),
            false => twin.run_data(&m.data, &o.base, p.stride),
        });
        let diff = |out: Vec<Vec<f32>>| -> Vec<Vec<f64>> {
            let per_channel = out.iter().zip(&p.base_sim);
            per_channel
                .map(|(a, b)| p.idx.iter().map(|&t| f64::from(a[t]) - f64::from(b[t])).collect())
                .collect()
        };
        runs.into_iter().map(|r| r.ok().map(diff)).collect()
    };
    let first = respond(&stated);
    // A map the run does not reach in its stated shape (a reverse speed map on a
    // forward run, a regenerating region never entered) is not reached in the others
    // either: those simulations are skipped.
    let reached: Vec<&str> = stated
        .iter()
        .zip(&first)
        .filter(|(_, j)| j.as_ref().is_some_and(|j| j.iter().flatten().any(|v| *v != 0.0)))
        .map(|(m, _)| m.name.as_str())
        .collect();
    let others: Vec<Moved> =
        others.into_iter().filter(|m| reached.contains(&stem(&m.name).as_str())).collect();
    let second = respond(&others);
    let items = stated
        .iter()
        .zip(first)
        .chain(others.iter().zip(second))
        .filter_map(|(m, j)| {
            Some(Item {
                j: j?,
                stated: m.stated,
                var: var(&stem(&m.name)),
                replaced_by: m.replaced_by.clone(),
            })
        })
        .collect();
    Items::new(&p.weights, items)
}

/// The items' responses weighted by `W` (`W j_m`, so that every product with them is a
/// plain dot product: the weights are looked up once, not per refit), with their Gram
/// matrix `K'WK` (`[item][item]` row-major), which every refit's joint fit
/// ([`item_moment`]) shares.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Items {
    pub shapes: Vec<Item>,
    gram: Vec<f64>,
}

impl Items {
    /// `shapes` with their Gram matrix under the weights `w`; each shape's `j` is kept
    /// weighted (`W j`).
    /// The products are independent sums: taken side by side (fifty items make 1,275).
    pub fn new(w: &Weights, mut shapes: Vec<Item>) -> Self {
        use rayon::prelude::*;
        let m = shapes.len();
        let weighted: Vec<Vec<Vec<f64>>> = shapes.par_iter().map(|it| weigh(w, &it.j)).collect();
        let pairs: Vec<(usize, usize)> = (0..m).flat_map(|p| (0..=p).map(move |q| (p, q))).collect();
        let dots: Vec<f64> = pairs.par_iter().map(|&(p, q)| dot3(&weighted[p], &shapes[q].j)).collect();
        let mut gram = vec![0.0; m * m];
        for (&(p, q), v) in pairs.iter().zip(dots) {
            gram[p * m + q] = v;
            gram[q * m + p] = v;
        }
        for (it, wj) in shapes.iter_mut().zip(weighted) {
            it.j = wj;
        }
        Self { shapes, gram }
    }
}

/// `W x` (`[channel][fit sample]`).
fn weigh(w: &Weights, x: &[Vec<f64>]) -> Vec<Vec<f64>> {
    x.iter().enumerate().map(|(c, xc)| xc.iter().enumerate().map(|(t, v)| w.at(c, t) * v).collect()).collect()
}

/// `Σ_c Σ_t x_ct y_ct`.
fn dot3(x: &[Vec<f64>], y: &[Vec<f64>]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>()).sum()
}

/// The systematic σ of a refit's parameters (Jacobian `jac[parameter][channel][fit
/// sample]`, residual `resid[channel][fit sample]`) from the items' responses, the fit
/// taken over the parameters `determined` (the others, which the run does not pin down,
/// get 0: their σ is already unbounded); 0 for every parameter when there are no items.
/// `sandwich` is the parameters' sandwich σ, whose ratio to the white-noise σ says how
/// much the noise's correlation inflates what the run tells ([`item_moment`]). Items a
/// fitted effect (of `effects`) replaces are left out ([`Item::replaced_by`]).
/// As the run leaves the items: [`data_std`]'s posterior.
pub(super) fn systematic_std(
    w: &Weights,
    jr: (&[Vec<Vec<f64>>], &[Vec<f64>]),
    de: (&[bool], &[&str]),
    items: &Items,
    sandwich: &[f64],
) -> Vec<f64> {
    data_std(w, jr, de, items, sandwich).1
}

/// [`systematic_std`] as `(prior, posterior)`. Prior: each item anywhere within its stated
/// σ, in its stated shape (`Σ_m Δθ_m²`), what the data's uncertainty *could* move the
/// value by. Posterior: with the items' second moments after the run (`a' M a`,
/// [`item_moment`], every shape), how far the value is off given what the run says.
fn data_std(
    w: &Weights,
    (jac, resid): (&[Vec<Vec<f64>>], &[Vec<f64>]),
    (determined, effects): (&[bool], &[&str]),
    items: &Items,
    sandwich: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let n = jac.len();
    let ix: Vec<usize> = (0..n).filter(|&i| determined.get(i).copied().unwrap_or(false)).collect();
    let live: Vec<usize> = (0..items.shapes.len())
        .filter(|&q| !items.shapes[q].replaced_by.iter().any(|e| effects.contains(e)))
        .collect();
    if live.is_empty() || ix.is_empty() {
        return (vec![0.0; n], vec![0.0; n]);
    }
    let Some(joint) = Joint::new(w, (jac, resid), &ix, items, live) else {
        return (vec![f64::INFINITY; n], vec![f64::INFINITY; n]);
    };
    let m = joint.live.len();
    let spread = |cov: &dyn Fn(usize, usize) -> f64| -> Vec<f64> {
        let mut sd = vec![0.0; n];
        for (row, &i) in joint.a.iter().zip(&ix) {
            let var: f64 = (0..m)
                .flat_map(|p| (0..m).map(move |q| (p, q)))
                .map(|(p, q)| row[p] * cov(p, q) * row[q])
                .sum();
            sd[i] = var.max(0.0).sqrt();
        }
        sd
    };
    let prior = spread(&|p, q| if p == q && joint.item(items, p).stated { 1.0 } else { 0.0 });
    let inflation = joint.inflation(&ix, sandwich);
    let posterior = match item_moment(&joint, items, inflation) {
        Some(mm) => spread(&|p, q| mm[p * m + q]),
        None => prior.clone(),
    };
    (prior, posterior)
}

/// Share of an item's response (weighted energy) in the parameters' own response above
/// which the joint fit leaves the item at its prior ([`item_moment`]). The items'
/// responses are taken around the current model, the parameters' around the fit: two
/// shapes that are one (an axle friction scale and the friction map's scale) differ
/// there by the model's curvature, and a run whose noise is small tells that
/// difference apart — pinning the map's scale, and the effect's σ, at nothing (the
/// friction scale of `diagnose_cli::hidden_axle_friction_is_named_and_its_effect_file_closes_the_gap`
/// is 99 % its map's scale and read σ 0.0015 without this). ASSUMED: 0.9.
pub(super) const ALIASED: f64 = 0.9;

/// The weighted normal equations of the determined parameters `ix` and the `live` items
/// together (without the items' prior): the parameters' block `g` (`k x k`), the
/// cross block `c` (`[parameter][live item]`, `J'W j_m`), the right-hand sides of the
/// residual, and `a = g⁻¹ c`, each item's move of the refit (`Δθ_m`, `[parameter][live
/// item]`).
struct Joint {
    g: Vec<f64>,
    c: Vec<Vec<f64>>,
    b: Vec<f64>,
    a: Vec<Vec<f64>>,
    live: Vec<usize>,
}

impl Joint {
    fn new(
        w: &Weights,
        (jac, resid): (&[Vec<Vec<f64>>], &[Vec<f64>]),
        ix: &[usize],
        items: &Items,
        live: Vec<usize>,
    ) -> Option<Self> {
        let (g, _) = normal_equations_by(w, jac, |_, _| 0.0, 1, |_, _| 0);
        let g = sub_matrix(&g[0], jac.len(), ix);
        let shapes = || live.iter().map(|&q| &items.shapes[q]);
        let c: Vec<Vec<f64>> =
            ix.iter().map(|&i| shapes().map(|it| dot3(&jac[i], &it.j)).collect()).collect();
        let b: Vec<f64> = ix
            .iter()
            .map(|&i| weighted_dot(w, &jac[i], resid))
            .chain(shapes().map(|it| dot3(&it.j, resid)))
            .collect();
        let m = live.len();
        let mut a = vec![vec![0.0; m]; ix.len()];
        for q in 0..m {
            let col: Vec<f64> = c.iter().map(|row| row[q]).collect();
            for (row, x) in a.iter_mut().zip(solve_spd(&g, &col, 1e-12)?) {
                row[q] = x;
            }
        }
        Some(Self { g, c, b, a, live })
    }

    /// The `p`-th live item.
    fn item<'a>(&self, items: &'a Items, p: usize) -> &'a Item {
        &items.shapes[self.live[p]]
    }

    /// The Gram matrix's entry of the `p`-th and `q`-th live items.
    fn gram(&self, items: &Items, p: usize, q: usize) -> f64 {
        items.gram[self.live[p] * items.shapes.len() + self.live[q]]
    }

    /// Per live item, whether its response is at least [`ALIASED`] (in weighted energy) in
    /// the parameters' own: `c_m' g⁻¹ c_m ≥ ALIASED · j_m'Wj_m`.
    fn aliased(&self, items: &Items) -> Option<Vec<bool>> {
        (0..self.live.len())
            .map(|q| {
                let col: Vec<f64> = self.c.iter().map(|row| row[q]).collect();
                let x = solve_spd(&self.g, &col, 1e-12)?;
                let along: f64 = x.iter().zip(&col).map(|(a, b)| a * b).sum();
                Some(along >= ALIASED * self.gram(items, q, q))
            })
            .collect()
    }

    /// How much the noise's correlation and local level inflate the variance the run's
    /// white-noise weights give: the parameters' sandwich variance over their
    /// white-noise variance `(g⁻¹)ᵢᵢ`, averaged; 1 when neither is usable.
    fn inflation(&self, ix: &[usize], sandwich: &[f64]) -> f64 {
        let k = ix.len();
        let ratios: Vec<f64> = (0..k)
            .filter_map(|r| {
                let mut e = vec![0.0; k];
                e[r] = 1.0;
                let white = solve_spd(&self.g, &e, 1e-12)?[r];
                let sd = sandwich.get(ix[r]).copied()?;
                let ratio = sd * sd / white;
                (ratio.is_finite() && ratio > 0.0).then_some(ratio)
            })
            .collect();
        if ratios.is_empty() {
            1.0
        } else {
            ratios.iter().sum::<f64>() / ratios.len() as f64
        }
    }
}

/// `Σ_c Σ_t w_ct x_ct y_ct` over channels and fit samples.
fn weighted_dot(w: &Weights, x: &[Vec<f64>], y: &[Vec<f64>]) -> f64 {
    let per_channel = x.iter().zip(y).enumerate();
    per_channel
        .map(|(c, (xc, yc))| xc.iter().zip(yc).enumerate().map(|(t, (a, b))| w.at(c, t) * a * b).sum::<f64>())
        .sum()
}

/// The items' second moments after the run, `M = P + ν̂ν̂'` (`[item][item]` row-major):
/// the items `ν` (in σ, prior `N(0, diag(var))`) fitted to the refit's residual jointly
/// with the determined parameters — bread `B = X'WX + diag(0, 1/var)`, right-hand side
/// `X'Wr`, covariance `B⁻¹(κ X'WX + diag(0, 1/var))B⁻¹`, the data's part of the meat
/// taken as its white-noise part inflated by the parameters' own sandwich ratio `κ`
/// (the noise model's meat over every item would cost more than the rest of a
/// diagnosis) — and `P` that covariance's item block. An item the run does not see
/// keeps its prior (`M_mm = var`); one the run pins down at 0 (the data as identified)
/// has `M_mm ≪ var`, one it finds off keeps `ν̂²`. `None` when the system cannot be
/// solved.
fn item_moment(joint: &Joint, items: &Items, kappa: f64) -> Option<Vec<f64>> {
    let (k, m) = (joint.c.len(), joint.live.len());
    let n = k + m;
    let aliased = joint.aliased(items)?;
    // An aliased item sees only its prior: its data rows and columns are left out.
    let seen = |i: usize| i < k || !aliased[i - k];
    let mut data = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            if !seen(i) || !seen(j) {
                continue;
            }
            data[i * n + j] = match (i < k, j < k) {
                (true, true) => joint.g[i * k + j],
                (true, false) => joint.c[i][j - k],
                (false, true) => joint.c[j][i - k],
                (false, false) => joint.gram(items, i - k, j - k),
            };
        }
    }
    let prior = |i: usize| if i >= k { 1.0 / joint.item(items, i - k).var } else { 0.0 };
    let bread: Vec<f64> =
        (0..n * n).map(|ij| data[ij] + if ij / n == ij % n { prior(ij / n) } else { 0.0 }).collect();
    let meat: Vec<f64> =
        (0..n * n).map(|ij| kappa * data[ij] + if ij / n == ij % n { prior(ij / n) } else { 0.0 }).collect();
    // Jacobi scaling: parameters and items differ by many orders of magnitude.
    let d: Vec<f64> = (0..n).map(|i| 1.0 / bread[i * n + i].max(1e-300).sqrt()).collect();
    let scaled = |x: &[f64]| -> Vec<f64> { (0..n * n).map(|ij| x[ij] * d[ij / n] * d[ij % n]).collect() };
    let (g, s) = (scaled(&bread), scaled(&meat));
    let b: Vec<f64> =
        joint.b.iter().zip(&d).enumerate().map(|(i, (b, d))| if seen(i) { b * d } else { 0.0 }).collect();
    let nu: Vec<f64> = solve_spd(&g, &b, 1e-12)?.iter().zip(&d).skip(k).map(|(x, d)| x * d).collect();
    // Columns of B⁻¹ for the items (scaled), then P = C'SC on them, scaled back.
    let cinv: Vec<Vec<f64>> = (k..n)
        .map(|q| {
            let mut e = vec![0.0; n];
            e[q] = 1.0;
            solve_spd(&g, &e, 1e-12)
        })
        .collect::<Option<_>>()?;
    let mut out = vec![0.0; m * m];
    for p in 0..m {
        for q in 0..m {
            let cov = bilinear(&s, &cinv[p], &cinv[q]) * d[k + p] * d[k + q];
            out[p * m + q] = cov + nu[p] * nu[q];
        }
    }
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// `x' S y` for row-major `S`.
fn bilinear(s: &[f64], x: &[f64], y: &[f64]) -> f64 {
    let n = x.len();
    (0..n).map(|i| x[i] * (0..n).map(|j| s[i * n + j] * y[j]).sum::<f64>()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One parameter whose response is a channel's ramp: an item whose response is half
    /// the ramp moves the fit by 0.5, one orthogonal to it not at all, two together add
    /// in quadrature; with no items nothing is added.
    #[test]
    fn an_item_moves_the_fit_by_its_projection() {
        let w = Weights::uniform(vec![1.0]);
        let ramp: Vec<f64> = (0..20).map(|t| t as f64 - 9.5).collect();
        let jac = vec![vec![ramp.clone()]];
        let half = vec![ramp.iter().map(|v| 0.5 * v).collect::<Vec<f64>>()];
        let flat = vec![vec![1.0; 20]];
        let resid = vec![vec![0.0; 20]];
        let as_items = |js: &[Vec<Vec<f64>>]| -> Items {
            Items::new(
                &w,
                js.iter()
                    .map(|j| Item { j: j.clone(), stated: true, var: 1.0, replaced_by: Vec::new() })
                    .collect(),
            )
        };
        let sd = |items: &[Vec<Vec<f64>>]| {
            data_std(&w, (&jac, &resid), (&[true], &[]), &as_items(items), &[1.0]).0[0]
        };
        assert!((sd(std::slice::from_ref(&half)) - 0.5).abs() < 1e-9);
        let off = sd(std::slice::from_ref(&flat));
        assert!(off.abs() < 1e-12, "orthogonal: {off}");
        let double = vec![ramp.iter().map(|v| 1.2 * v).collect::<Vec<f64>>()];
        let two = sd(&[half, double]);
        assert!((two - (0.25f64 + 1.44).sqrt()).abs() < 1e-9, "{two}");
        assert_eq!(sd(&[]), 0.0);
    }

    /// An item whose value a fitted effect replaces moves nothing beside it: the connector
    /// resistance's stated σ is no error of a refitted `connector_resistance`, but is of
    /// any other effect's. The link comes from the declarations: only the override effects
    /// replace a parameter, and a scaled inertia is not replaced by a scale.
    #[test]
    fn an_item_an_effect_replaces_moves_nothing_beside_it() {
        assert_eq!(replacing(&["connector_resistance"]), ["connector_resistance"]);
        assert_eq!(replacing(&["coupling_damping"]), ["coupling_damping"]);
        assert_eq!(replacing(&["coupling_stiffness_identified"]), ["coupling_stiffness"]);
        assert_eq!(replacing(&["coupling_stiffness_datasheet"]), ["coupling_stiffness"]);
        for key in ["sut_inertia", "load_inertia_l", "throttle_volts_per_pct"] {
            assert!(replacing(&[key]).is_empty(), "{key}: {:?}", replacing(&[key]));
        }
        let w = Weights::uniform(vec![1.0]);
        let ramp: Vec<f64> = (0..20).map(|t| t as f64 - 9.5).collect();
        let jac = vec![vec![ramp.clone()]];
        let resid = vec![vec![0.0; 20]];
        let half = vec![ramp.iter().map(|v| 0.5 * v).collect::<Vec<f64>>()];
        let item = Item { j: half, stated: true, var: 1.0, replaced_by: vec!["connector_resistance"] };
        let items = Items::new(&w, vec![item]);
        let sd = |fx: &[&str]| data_std(&w, (&jac, &resid), (&[true], fx), &items, &[1.0]);
        assert!((sd(&["supply_resistance"]).0[0] - 0.5).abs() < 1e-9);
        let (prior, posterior) = sd(&["connector_resistance"]);
        assert_eq!((prior[0], posterior[0]), (0.0, 0.0));
    }

    /// The run tells the items apart from the parameter where their responses differ.
    /// Parameter: a ramp; item: half the ramp plus a slow cosine the ramp cannot make
    /// (its prior move is 0.5). Measured: the parameter's truth, the item at `ν`, white
    /// noise of σ 0.05; the parameter alone is fitted by least squares. With the item at
    /// 0 (data as identified) the run pins it there: the posterior σ is a tenth of the
    /// prior; noise that tells less (its sandwich σ 3x the white one) widens it (the
    /// covariance part 9x; the estimate's own square, here 7x the white covariance, not). With the item at 1.5 the fitted value is 0.75 off and the posterior σ
    /// says so (within 10 %). An item whose response is the ramp's own shape cannot be
    /// told from the parameter: its posterior is its prior.
    #[test]
    fn the_run_narrows_what_it_can_tell_apart() {
        let m = 2000;
        let ramp: Vec<f64> = (0..m).map(|t| t as f64 / m as f64 - 0.5).collect();
        let wave: Vec<f64> =
            (0..m).map(|t| (6.0 * std::f64::consts::PI * t as f64 / m as f64).cos()).collect();
        let item: Vec<f64> = ramp.iter().zip(&wave).map(|(r, c)| 0.5 * r + 0.3 * c).collect();
        let noise = crate::preparation::tests::gaussian(7, m);
        let sigma = 0.05;
        let w = Weights::uniform(vec![1.0 / (sigma * sigma)]);
        let jac = vec![vec![ramp.clone()]];
        let white = sigma / ramp.iter().map(|v| v * v).sum::<f64>().sqrt();
        let fit = |nu: f64, item: &[f64], sandwich: f64| -> (f64, (Vec<f64>, Vec<f64>)) {
            let y: Vec<f64> = (0..m).map(|t| 2.0 * ramp[t] + nu * item[t] + sigma * noise[t]).collect();
            let theta = y.iter().zip(&ramp).map(|(a, b)| a * b).sum::<f64>()
                / ramp.iter().map(|v| v * v).sum::<f64>();
            let resid = vec![y.iter().zip(&ramp).map(|(a, b)| a - theta * b).collect::<Vec<f64>>()];
            let items = Items::new(
                &w,
                vec![Item { j: vec![item.to_vec()], stated: true, var: 1.0, replaced_by: Vec::new() }],
            );
            (theta - 2.0, data_std(&w, (&jac, &resid), (&[true], &[]), &items, &[sandwich]))
        };
        let (err, at0) = fit(0.0, &item, white);
        assert!((at0.0[0] - 0.5).abs() < 0.005, "prior {}", at0.0[0]);
        assert!(at0.1[0] < 0.05, "pinned at 0: {} (error {err})", at0.1[0]);
        let (err, off) = fit(1.5, &item, white);
        assert!((err - 0.75).abs() < 0.01, "the fit absorbs the item: {err}");
        assert!((off.1[0] / err - 1.0).abs() < 0.1, "posterior {} vs error {err}", off.1[0]);
        // Noise whose correlation makes the sandwich σ 3x the white one tells less.
        let (_, correlated) = fit(0.0, &item, 3.0 * white);
        assert!(correlated.1[0] > 1.3 * at0.1[0], "{} vs {}", correlated.1[0], at0.1[0]);
        let half: Vec<f64> = ramp.iter().map(|r| 0.5 * r).collect();
        let (_, same) = fit(0.0, &half, white);
        assert!((same.1[0] / same.0[0] - 1.0).abs() < 0.01, "{} vs {}", same.1[0], same.0[0]);
    }

    /// Every item moves the built-in data, and only where it should: the friction map
    /// stays 0 at standstill and keeps its sign, the speed map's plateau stays.
    #[test]
    fn each_item_moves_the_data() {
        let base = ModelData::builtin().expect("built-in data");
        let moved = moved_data(&base, &Uncertainty::thesis());
        assert!(moved.len() > 20, "{} items", moved.len());
        for m in &moved {
            assert!(*m.data != base, "{} moved nothing", m.name);
        }
        let get = |n: &str| moved.iter().find(|m| m.name == n).map(|m| m.data.clone()).expect(n);
        for name in ["axle_friction_L", "axle_friction_L tilt", "axle_friction_L scale"] {
            let fl = &get(name).friction[0];
            for ((y, y0), x) in fl.y.iter().zip(&base.friction[0].y).zip(&fl.x) {
                assert!(y.signum() == y0.signum() || *y0 == 0.0 || *y == 0.0, "{name}: sign kept at {x} rpm");
                if *x == 0.0 {
                    assert_eq!(y, y0, "{name}: 0 at standstill");
                }
            }
        }
        let top = base.speed_fwd.y.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        for name in ["speed_map_fwd", "speed_map_fwd tilt", "speed_map_fwd shift"] {
            let fwd = &get(name).speed_fwd;
            assert_eq!(fwd.y.iter().copied().fold(f32::NEG_INFINITY, f32::max), top, "{name}: plateau kept");
            assert!(fwd.y.windows(2).all(|w| w[1] >= w[0]), "{name}: non-decreasing");
        }
        // Every map's stated shape has its tilt and its other shape, each a different
        // change; parameters have none.
        let stated: Vec<&str> = moved.iter().filter(|m| m.stated).map(|m| m.name.as_str()).collect();
        let others: Vec<&Moved> = moved.iter().filter(|m| !m.stated).collect();
        assert_eq!(others.len(), 24, "{stated:?}");
        for Moved { name, data: d, .. } in others {
            let stem = [" tilt", " shift", " scale"].iter().find_map(|x| name.strip_suffix(x));
            let stem = stem.expect("a shape is named so");
            assert!(stated.contains(&stem), "{name} without its stated shape");
            assert!(**d != *get(stem), "{name} is its stated shape");
        }
    }
}
