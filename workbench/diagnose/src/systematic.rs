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
//! item `m`; the items are independent, so the systematic σ is `√(Σ_m Δθ_m²)`, added to
//! the reported σ in quadrature. Significance is judged on it only for an effect new to
//! a model whose data an earlier round corrected ([`super::uncertainty::parameter_std`]);
//! otherwise whether an effect is needed is the residual's question, how well its value
//! is known is this one's.

use std::sync::Arc;

use simrod_io::datadir::{Map1, Map2, ModelData, ParamLine};
use simrod_io::map_uncertainty::{Uncertainty, REGION_WIDTH_PCT};

use super::engine::{Options, Twin};
use super::linalg::{solve_spd, sub_matrix};
use super::preparation::{run_each, Prepared, Weights};
use super::sensitivities::normal_equations_by;

/// The identified data moved by one σ of each uncertain item (maps by shape and region,
/// parameter groups), with the item's name.
fn moved_data(base: &ModelData, u: &Uncertainty) -> Vec<(String, Arc<ModelData>)> {
    let mut out = Vec::new();
    let mut with = |name: String, f: &dyn Fn(&mut ModelData)| {
        let mut d = base.clone();
        f(&mut d);
        out.push((name, Arc::new(d)));
    };
    for (i, side) in ["L", "R"].iter().enumerate() {
        let (sd, taper) = (u.friction_nm[i].value, u.friction_taper_rpm.value);
        with(format!("axle_friction_{side}"), &|d| shift_friction(&mut d.friction[i], sd, taper));
        // The load torque's field is the current's and the power's too (the bench's).
        let regions = [
            ("motoring", u.load_torque_motoring_rel.value, -1.0),
            ("regen", u.load_torque_regen_rel.value, 1.0),
        ];
        for (region, rel, sign) in regions {
            with(format!("load_torque_{side} {region}"), &|d| {
                let share = |sp: f64| 0.5 * (1.0 + sign * (sp / REGION_WIDTH_PCT).tanh());
                for m in [&mut d.load_torque[i], &mut d.load_current[i], &mut d.load_power[i]] {
                    scale2(m, |_, sp, _| rel * share(sp));
                }
            });
        }
        let rel = u.load_power_rel.value;
        with(format!("load_power_{side}"), &|d| scale2(&mut d.load_power[i], |_, _, _| rel));
    }
    let (drive, regen) = (u.sut_power_rel.value, u.sut_power_regen_rel.value);
    with("sut_inverter_power drive".into(), &|d| {
        scale2(&mut d.sut_power, |_, _, z| if z >= 0.0 { drive } else { 0.0 })
    });
    with("sut_inverter_power regen".into(), &|d| {
        scale2(&mut d.sut_power, |_, _, z| if z < 0.0 { regen } else { 0.0 })
    });
    let speed = u.speed_map_rel.value;
    with("speed_map_fwd".into(), &|d| scale_interior(&mut d.speed_fwd, speed));
    with("speed_map_rev".into(), &|d| scale_interior(&mut d.speed_rev, speed));
    for g in &u.params {
        let k = g.sigma_ln.exp();
        with(g.keys.join("+"), &|d| {
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

/// Friction magnitudes raised by `sd` [N m] away from standstill (tapered to 0 there
/// over `taper` rpm, as the map is 0 at rest), keeping each value's sign.
fn shift_friction(m: &mut Map1, sd: f64, taper: f64) {
    for (y, x) in m.y.iter_mut().zip(&m.x) {
        let v = f64::from(*y);
        let t = 1.0 - (-(f64::from(*x) / taper).powi(2)).exp();
        let sign = if v == 0.0 { 0.0 } else { v.signum() };
        *y = (v + sign * sd * t) as f32;
    }
}

/// A 2-D map's values scaled by `1 + rel(x, y, z)` at each grid point.
fn scale2(m: &mut Map2, rel: impl Fn(f64, f64, f64) -> f64) {
    let nx = m.x.len().max(1);
    for (i, z) in m.z.iter_mut().enumerate() {
        let (x, y) = (m.x.get(i % nx).copied().unwrap_or(0.0), m.y.get(i / nx).copied().unwrap_or(0.0));
        let v = f64::from(*z);
        *z = (v * (1.0 + rel(f64::from(x), f64::from(y), v))) as f32;
    }
}

/// A monotone map's values strictly between its first and its largest scaled by
/// `1 + rel` (the zero region and the saturation plateau stay).
fn scale_interior(m: &mut Map1, rel: f64) {
    let lo = m.y.first().copied().unwrap_or(0.0);
    let hi = m.y.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    for y in &mut m.y {
        if *y > lo && *y < hi {
            *y = (f64::from(*y) * (1.0 + rel)).min(f64::from(hi)) as f32;
        }
    }
}

/// Each uncertain item's response to one σ of it, `[item][channel][fit sample]`, on the
/// twin's data and the current model; empty when the twin's data cannot be changed.
pub(super) fn responses(twin: &dyn Twin, p: &Prepared, o: &Options) -> Vec<Vec<Vec<f64>>> {
    let Some(base) = twin.data() else { return Vec::new() };
    let jobs = moved_data(&base, &Uncertainty::thesis());
    let runs = run_each(&jobs, o, |(_, d)| twin.run_data(d, &o.base, p.stride));
    runs.into_iter()
        .filter_map(Result::ok)
        .map(|out| {
            out.iter()
                .zip(&p.base_sim)
                .map(|(a, b)| p.idx.iter().map(|&t| f64::from(a[t]) - f64::from(b[t])).collect())
                .collect()
        })
        .collect()
}

/// The systematic σ of a refit's parameters (Jacobian `jac[parameter][channel][fit
/// sample]`): `√(Σ_m Δθ_m²)` over the items' responses `items`, the fit taken over the
/// parameters `determined` (the others, which the run does not pin down, get 0: their σ
/// is already unbounded); 0 for every parameter when there are no items.
pub(super) fn systematic_std(
    w: &Weights,
    jac: &[Vec<Vec<f64>>],
    determined: &[bool],
    items: &[Vec<Vec<f64>>],
) -> Vec<f64> {
    let ix: Vec<usize> = (0..jac.len()).filter(|&i| determined.get(i).copied().unwrap_or(false)).collect();
    let (g, _) = normal_equations_by(w, jac, |_, _| 0.0, 1, |_, _| 0);
    let g = sub_matrix(&g[0], jac.len(), &ix);
    let mut var = vec![0.0; jac.len()];
    for item in items {
        // J'W j of the determined parameters.
        let b: Vec<f64> = ix
            .iter()
            .map(|&i| {
                let per_channel = jac[i].iter().zip(item).enumerate();
                per_channel
                    .map(|(c, (jc, mc))| {
                        jc.iter().zip(mc).enumerate().map(|(t, (x, y))| w.at(c, t) * x * y).sum::<f64>()
                    })
                    .sum()
            })
            .collect();
        let Some(d) = solve_spd(&g, &b, 1e-12) else { return vec![f64::INFINITY; jac.len()] };
        for (&i, x) in ix.iter().zip(d) {
            var[i] += x * x;
        }
    }
    var.into_iter().map(f64::sqrt).collect()
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
        let sd = |items: &[Vec<Vec<f64>>]| systematic_std(&w, &jac, &[true], items)[0];
        assert!((sd(std::slice::from_ref(&half)) - 0.5).abs() < 1e-9);
        let off = sd(std::slice::from_ref(&flat));
        assert!(off.abs() < 1e-12, "orthogonal: {off}");
        let double = vec![ramp.iter().map(|v| 1.2 * v).collect::<Vec<f64>>()];
        let two = sd(&[half, double]);
        assert!((two - (0.25f64 + 1.44).sqrt()).abs() < 1e-9, "{two}");
        assert_eq!(sd(&[]), 0.0);
    }

    /// Every item moves the built-in data, and only where it should: the friction map
    /// stays 0 at standstill and keeps its sign, the speed map's plateau stays.
    #[test]
    fn each_item_moves_the_data() {
        let base = ModelData::builtin().expect("built-in data");
        let moved = moved_data(&base, &Uncertainty::thesis());
        assert!(moved.len() > 20, "{} items", moved.len());
        for (name, d) in &moved {
            assert!(**d != base, "{name} moved nothing");
        }
        let fl = &moved.iter().find(|(n, _)| n == "axle_friction_L").expect("friction L").1.friction[0];
        for ((y, y0), x) in fl.y.iter().zip(&base.friction[0].y).zip(&fl.x) {
            assert!(y.signum() == y0.signum() || *y0 == 0.0, "sign kept at {x} rpm");
            if *x == 0.0 {
                assert_eq!(y, y0, "0 at standstill");
            }
        }
        let fwd = &moved.iter().find(|(n, _)| n == "speed_map_fwd").expect("speed map").1.speed_fwd;
        let top = base.speed_fwd.y.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        assert_eq!(fwd.y.iter().copied().fold(f32::NEG_INFINITY, f32::max), top, "plateau kept");
    }
}
