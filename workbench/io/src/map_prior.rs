//! The shape of the maps' uncertainty: how the bench's true maps may differ from the
//! identified ones, as a linear combination of smooth fields with unit-normal
//! coefficients. [`crate::map_uncertainty`] says how large the error is; this module
//! says what it looks like. One declaration, two readers: the virtual bench draws the
//! coefficients to perturb its plant (`simrod bench --perturb-maps`), and an estimator
//! of the maps within their uncertainty fits them, so both read one prior.
//!
//! A field is a Fourier series on a map's normalised axis `u ∈ [0, 1]`:
//! `f(u) = Σ_k √w_k (a_k cos πku + b_k sin πku)`, `k = 0..3`, weights [`SPECTRUM`]
//! (variance 1 at every `u`; correlation 0.5 at `Δu ≈ 0.3`, so an error looks like a
//! mis-identified curve — offset, tilt, bow — not noise); a 2-D field is the tensor
//! product of two. A field's change at a map value is `Σ_j g_j weight_j`, the weights
//! holding the size (σ from the uncertainty, relative maps times the value):
//! - friction: absolute, odd in speed where the map is odd, tapered to 0 at standstill
//!   where the map is 0 there (`1 − exp(−(ω/ω_t)²)`), scaled so the expected mean
//!   square over the grid is σ²;
//! - speed and throttle input maps: relative, only the values strictly between the
//!   lowest (zero, deadband) and highest (limit, full) value;
//! - load torque and current maps of a side share one relative field (T = k_t I) on the
//!   torque map's set-point axes, its σ blended between motoring and regenerating
//!   ([`REGION_WIDTH_PCT`]); the load power map takes that field plus its own;
//! - the SuT inverter power map: relative, σ by the sign of the power.
//!
//! [`apply`] takes the fields' change for given coefficients (and the parameter groups'
//! log-normal factors) onto a copy of the data and keeps the constraints that are not
//! linear: friction never changes sign, the monotone maps stay non-decreasing and within
//! their limits.

use crate::datadir::{Map1, Map2, ModelData, ParamLine, FILES_1D, FILES_2D};
use crate::map_uncertainty::{Uncertainty, REGION_WIDTH_PCT};

/// Weights `w_k` of the cosine/sine pairs `k = 0, 1, 2, 3` of a field (sum 1): an
/// offset, a tilt, a bow and a little wiggle across the axis. ASSUMED: a map identified
/// from plateau means errs by its fit's low-order shape, which is what a correlation
/// length of ~0.3 of the axis reproduces.
pub const SPECTRUM: [f64; 4] = [1.0 / 2.75, 1.0 / 2.75, 0.5 / 2.75, 0.25 / 2.75];

/// Coefficients of a 1-D field: `a_k, b_k` for `k = 0..3`, in that (drawing) order.
pub const COEFS_1D: usize = 2 * SPECTRUM.len();

/// Coefficients of a 2-D field: for `k`, then `l`, the four products
/// cos·cos, cos·sin, sin·cos, sin·sin, in that (drawing) order.
pub const COEFS_2D: usize = 4 * SPECTRUM.len() * SPECTRUM.len();

/// Basis function `j < COEFS_1D` of a 1-D field at `u`.
pub fn shape1(j: usize, u: f64) -> f64 {
    let k = j / 2;
    let p = std::f64::consts::PI * k as f64 * u;
    SPECTRUM[k].sqrt() * if j.is_multiple_of(2) { p.cos() } else { p.sin() }
}

/// Basis function `j < COEFS_2D` of a 2-D field at `(u, v)`.
pub fn shape2(j: usize, u: f64, v: f64) -> f64 {
    let (k, l, m) = (j / 16, (j / 4) % 4, j % 4);
    let pi = std::f64::consts::PI;
    let (pu, pv) = (pi * k as f64 * u, pi * l as f64 * v);
    let fu = if m < 2 { pu.cos() } else { pu.sin() };
    let fv = if m.is_multiple_of(2) { pv.cos() } else { pv.sin() };
    (SPECTRUM[k] * SPECTRUM[l]).sqrt() * fu * fv
}

/// One map value a field changes: `Σ_j g_j weights[j]`, in the map's unit.
#[derive(Debug, Clone, PartialEq)]
pub struct Term {
    /// The map's file ([`FILES_1D`] or [`FILES_2D`]).
    pub file: &'static str,
    /// Index of the value (`y` of a 1-D map, `z` of a 2-D map, row-major).
    pub point: usize,
    /// One weight per coefficient of the field.
    pub weights: Vec<f64>,
}

/// A smooth field of the prior: unit-normal coefficients and the values they change.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// The field's name (also the virtual bench's random stream for it).
    pub name: String,
    /// Number of coefficients ([`COEFS_1D`] or [`COEFS_2D`]).
    pub coefs: usize,
    pub terms: Vec<Term>,
}

impl Field {
    /// Every value's change for coefficients `g` (`g.len() == self.coefs`).
    pub fn changes<'a>(&'a self, g: &'a [f64]) -> impl Iterator<Item = (&'static str, usize, f64)> + 'a {
        self.terms.iter().map(move |t| (t.file, t.point, t.weights.iter().zip(g).map(|(w, c)| w * c).sum()))
    }
}

/// Every field of the prior of `data`'s maps with the sizes of `unc`.
pub fn fields(data: &ModelData, unc: &Uncertainty) -> Vec<Field> {
    let mut out = Vec::new();
    for (i, side) in ["L", "R"].iter().enumerate() {
        let file = FILES_1D[3 + i];
        let terms =
            friction_terms(file, &data.friction[i], unc.friction_nm[i].value, unc.friction_taper_rpm.value);
        out.push(Field { name: format!("axle_friction_{side}"), coefs: COEFS_1D, terms });
    }
    for (file, m, sigma) in [
        (FILES_1D[1], &data.speed_fwd, unc.speed_map_rel.value),
        (FILES_1D[2], &data.speed_rev, unc.speed_map_rel.value),
        (FILES_1D[0], &data.throttle_input, unc.throttle_map_rel.value),
    ] {
        let name = file.trim_end_matches(".csv").to_string();
        out.push(Field { name, coefs: COEFS_1D, terms: monotone_terms(file, m, sigma) });
    }
    for (i, side) in ["L", "R"].iter().enumerate() {
        out.extend(load_fields(data, unc, i, side));
    }
    let m = &data.sut_power;
    let (sd, sr) = (unc.sut_power_rel.value, unc.sut_power_regen_rel.value);
    let terms = relative_terms(FILES_2D[6], m, (&m.x, &m.y), |_, z| if z >= 0.0 { sd } else { sr });
    out.push(Field { name: "sut_inverter_power".into(), coefs: COEFS_2D, terms });
    out
}

/// Normaliser of an axis onto [0, 1] (a one-point axis maps to 0).
pub fn unit_axis(x: &[f32]) -> impl Fn(f64) -> f64 {
    let lo = x.first().map_or(0.0, |v| f64::from(*v));
    let hi = x.last().map_or(0.0, |v| f64::from(*v));
    let span = hi - lo;
    move |v| if span > 0.0 { (v - lo) / span } else { 0.0 }
}

/// Whether a 1-D map is odd: symmetric grid and `y(−x) = −y(x)`, exactly.
pub fn is_odd(m: &Map1) -> bool {
    let n = m.x.len();
    n > 0 && (0..n).all(|i| m.x[i] == -m.x[n - 1 - i] && m.y[i] == -m.y[n - 1 - i])
}

/// Whether a 1-D map is 0 at a grid point at 0.
pub fn zero_at_zero(m: &Map1) -> bool {
    m.x.iter().zip(&m.y).any(|(x, y)| *x == 0.0 && *y == 0.0)
}

/// Friction: absolute, odd if the map is, tapered to 0 at standstill if the map is 0
/// there; the expected mean square over the grid is `sigma²`.
fn friction_terms(file: &'static str, m: &Map1, sigma: f64, taper_rpm: f64) -> Vec<Term> {
    let (odd, zero) = (is_odd(m), zero_at_zero(m));
    let xmax = m.x.iter().fold(0.0_f64, |a, v| a.max(f64::from(v.abs())));
    let unit = unit_axis(&m.x);
    let taper = |x: f64| if zero && taper_rpm > 0.0 { 1.0 - (-(x / taper_rpm).powi(2)).exp() } else { 1.0 };
    // The expected mean square of `taper · shape` over the grid is mean(taper²).
    let ms = m.x.iter().map(|x| taper(f64::from(*x)).powi(2)).sum::<f64>() / m.x.len().max(1) as f64;
    let k = if ms > 0.0 { sigma / ms.sqrt() } else { 0.0 };
    m.x.iter()
        .enumerate()
        .map(|(point, &x)| {
            let x = f64::from(x);
            let weights = (0..COEFS_1D)
                .map(|j| {
                    let shape = match odd {
                        true if x == 0.0 => 0.0,
                        true => x.signum() * shape1(j, if xmax > 0.0 { x.abs() / xmax } else { 0.0 }),
                        false => shape1(j, unit(x)),
                    };
                    k * taper(x) * shape
                })
                .collect();
            Term { file, point, weights }
        })
        .collect()
}

/// Monotone maps: relative, the values strictly between the lowest and highest only.
fn monotone_terms(file: &'static str, m: &Map1, sigma: f64) -> Vec<Term> {
    let unit = unit_axis(&m.x);
    let lo = m.y.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = m.y.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    m.x.iter()
        .zip(&m.y)
        .enumerate()
        .filter(|(_, (_, y))| **y > lo && **y < hi)
        .map(|(point, (&x, &y))| {
            let s = f64::from(y) * sigma;
            Term { file, point, weights: (0..COEFS_1D).map(|j| s * shape1(j, unit(f64::from(x)))).collect() }
        })
        .collect()
}

/// A relative 2-D field on map `m`: value `z` at set point `(x, y)` changes by
/// `z · sigma(y, z) · f(u(x), v(y))`, `(u, v)` normalised on `axes` (which may be
/// another map's, for fields shared between maps).
fn relative_terms(
    file: &'static str,
    m: &Map2,
    axes: (&[f32], &[f32]),
    sigma: impl Fn(f64, f64) -> f64,
) -> Vec<Term> {
    let (ux, uy) = (unit_axis(axes.0), unit_axis(axes.1));
    let nx = m.x.len().max(1);
    m.z.iter()
        .enumerate()
        .map(|(point, &z)| {
            let (x, y, z) = (f64::from(m.x[point % nx]), f64::from(m.y[point / nx]), f64::from(z));
            let s = z * sigma(y, z);
            Term { file, point, weights: (0..COEFS_2D).map(|j| s * shape2(j, ux(x), uy(y))).collect() }
        })
        .collect()
}

/// Blend of the motoring and regenerating sigma at load set point `sp` [%].
pub fn region_sigma(sp: f64, motoring: f64, regen: f64) -> f64 {
    motoring + (regen - motoring) * 0.5 * (1.0 + (sp / REGION_WIDTH_PCT).tanh())
}

/// Side `i`'s two load fields: the torque field (torque, current and power maps, on
/// the torque map's axes) and the power map's own.
fn load_fields(data: &ModelData, unc: &Uncertainty, i: usize, side: &str) -> [Field; 2] {
    let tq = &data.load_torque[i];
    let axes = (tq.x.as_slice(), tq.y.as_slice());
    let (mo, re) = (unc.load_torque_motoring_rel.value, unc.load_torque_regen_rel.value);
    let rel_t = |y: f64, _: f64| region_sigma(y, mo, re);
    let mut torque = relative_terms(FILES_2D[i], tq, axes, rel_t);
    torque.extend(relative_terms(FILES_2D[2 + i], &data.load_current[i], axes, rel_t));
    torque.extend(relative_terms(FILES_2D[4 + i], &data.load_power[i], axes, rel_t));
    let sp = unc.load_power_rel.value;
    let power = relative_terms(FILES_2D[4 + i], &data.load_power[i], axes, |_, _| sp);
    [
        Field { name: format!("load_torque_{side}"), coefs: COEFS_2D, terms: torque },
        Field { name: format!("load_power_{side}"), coefs: COEFS_2D, terms: power },
    ]
}

/// A copy of `data` with the change of every field (`coefs[f]` the coefficients of
/// `fields[f]`) and every parameter group of `unc` scaled by `exp(σ_ln z[g])` (a factor
/// that would not be finite leaves the value), the constraints kept: friction keeps its
/// sign, a monotone map's changed values stay within its range and non-decreasing.
/// Comments are left as they are (the caller says what the copy is).
pub fn apply(
    data: &ModelData,
    unc: &Uncertainty,
    fields: &[Field],
    coefs: &[Vec<f64>],
    z: &[f64],
) -> ModelData {
    let files: Vec<&str> = FILES_1D.iter().chain(FILES_2D.iter()).copied().collect();
    let base = data.map_values();
    let mut delta: Vec<Vec<f64>> = base.iter().map(|v| vec![0.0; v.len()]).collect();
    let mut changed: Vec<Vec<bool>> = base.iter().map(|v| vec![false; v.len()]).collect();
    for (f, g) in fields.iter().zip(coefs) {
        for (file, point, d) in f.changes(g) {
            let m = files.iter().position(|x| *x == file);
            if let Some((dv, cv)) = m.and_then(|m| delta[m].get_mut(point).zip(changed[m].get_mut(point))) {
                *dv += d;
                *cv = true;
            }
        }
    }
    let value = |m: usize, i: usize| f64::from(base[m][i]) + delta[m][i];
    let mut out = data.clone();
    let (ones, twos) = out.maps_mut();
    // FILES_1D order: the monotone maps, then friction.
    for (m, map) in ones.into_iter().enumerate() {
        for (i, y) in map.y.iter_mut().enumerate() {
            let v = value(m, i);
            *y = if m >= 3 { keep_sign(map.x[i], f64::from(base[m][i]), v) } else { v } as f32;
        }
        if m < 3 {
            keep_monotone(base[m], map, &changed[m]);
        }
    }
    // FILES_2D order, after the five 1-D maps.
    for (k, map) in twos.into_iter().enumerate() {
        for (i, z) in map.z.iter_mut().enumerate() {
            *z = value(5 + k, i) as f32;
        }
    }
    for (p, zg) in unc.params.iter().zip(z) {
        let factor = (p.sigma_ln * zg).exp();
        for line in &mut out.params {
            if let ParamLine::Entry { key, value, .. } = line {
                let v = (f64::from(*value) * factor) as f32;
                if p.keys.contains(&key.as_str()) && v.is_finite() {
                    *value = v;
                }
            }
        }
    }
    out
}

/// Friction keeps the base's sign (it opposes motion).
fn keep_sign(x: f32, base: f64, v: f64) -> f64 {
    match () {
        _ if x > 0.0 && base >= 0.0 => v.max(0.0),
        _ if x < 0.0 && base <= 0.0 => v.min(0.0),
        _ => v,
    }
}

/// Monotone maps: every changed value within the base's range, and non-decreasing if
/// the base is.
fn keep_monotone(base: &[f32], out: &mut Map1, changed: &[bool]) {
    let lo = base.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = base.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let mono = non_decreasing(base);
    let mut prev = f32::NEG_INFINITY;
    for (y, c) in out.y.iter_mut().zip(changed) {
        if *c {
            *y = y.clamp(lo, hi);
        }
        if mono {
            *y = y.max(prev);
            prev = *y;
        }
    }
}

/// Whether values never fall.
pub fn non_decreasing(v: &[f32]) -> bool {
    v.windows(2).all(|w| w[1] >= w[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn thesis() -> (ModelData, Uncertainty) {
        (ModelData::builtin().expect("built-in data"), Uncertainty::thesis())
    }

    /// The declared sizes: a field's variance at a value is `Σ_j weight_j²`. It is
    /// `(σ z)²` on relative maps (the spectrum sums to 1 and cos² + sin² = 1, so a
    /// field's variance is 1 at every point) and the friction's mean over the grid is
    /// `σ²`.
    #[test]
    fn variances_match_the_stated_sigma() {
        let (d, u) = thesis();
        let var = |t: &Term| t.weights.iter().map(|w| w * w).sum::<f64>();
        let f = fields(&d, &u);
        let sut = f.iter().find(|f| f.name == "sut_inverter_power").unwrap();
        for t in &sut.terms {
            let z = f64::from(d.sut_power.z[t.point]);
            let s = if z >= 0.0 { u.sut_power_rel.value } else { u.sut_power_regen_rel.value };
            assert!((var(t) - (s * z).powi(2)).abs() <= 1e-9 * (s * z).powi(2).max(1e-12), "{}", t.point);
        }
        for (side, fr) in f.iter().take(2).enumerate() {
            let mean = fr.terms.iter().map(var).sum::<f64>() / fr.terms.len() as f64;
            let s2 = u.friction_nm[side].value.powi(2);
            assert!((mean / s2 - 1.0).abs() < 1e-9, "side {side}: {mean} vs {s2}");
        }
    }

    /// Friction fields keep the map odd and 0 at standstill for every coefficient; the
    /// torque field is shared by torque, current and power maps of its side only.
    #[test]
    fn constraints_and_sharing() {
        let (d, u) = thesis();
        let f = fields(&d, &u);
        for (side, m) in d.friction.iter().enumerate() {
            assert!(is_odd(m) && zero_at_zero(m));
            let n = m.x.len();
            for t in &f[side].terms {
                let mirror = &f[side].terms[n - 1 - t.point];
                assert!(t.weights.iter().zip(&mirror.weights).all(|(a, b)| a == &-b));
                if m.x[t.point] == 0.0 {
                    assert!(t.weights.iter().all(|w| *w == 0.0));
                }
            }
        }
        let lt = f.iter().find(|f| f.name == "load_torque_L").unwrap();
        let files: std::collections::BTreeSet<_> = lt.terms.iter().map(|t| t.file).collect();
        assert_eq!(
            files.into_iter().collect::<Vec<_>>(),
            ["load_current_L.csv", "load_power_L.csv", "load_torque_L.csv"]
        );
        // The built-in throttle map is all deadband/full: nothing to change.
        assert!(f.iter().find(|f| f.name == "throttle_input_map").unwrap().terms.is_empty());
        assert_eq!(f.len(), 10);
    }

    /// The 2-D basis is the tensor product of the 1-D one, in the drawing order.
    #[test]
    fn basis_is_the_tensor_product() {
        for j in 0..COEFS_2D {
            let (k, l, m) = (j / 16, (j / 4) % 4, j % 4);
            let (a, b) = (2 * k + usize::from(m >= 2), 2 * l + m % 2);
            for (u, v) in [(0.1, 0.7), (0.5, 0.5), (0.93, 0.2)] {
                assert!((shape2(j, u, v) - shape1(a, u) * shape1(b, v)).abs() < 1e-12, "{j}");
            }
        }
    }

    /// `apply` adds exactly a field's change where no constraint binds, moves nothing
    /// else, clamps friction at 0 rather than flipping its sign, and scales a parameter
    /// group by `exp(σ_ln z)`.
    #[test]
    fn apply_adds_the_change_and_keeps_the_constraints() {
        let (d, u) = thesis();
        let f = fields(&d, &u);
        let zero: Vec<Vec<f64>> = f.iter().map(|x| vec![0.0; x.coefs]).collect();
        let z0 = vec![0.0; u.params.len()];
        assert_eq!(apply(&d, &u, &f, &zero, &z0), d);
        let k = f.iter().position(|x| x.name == "sut_inverter_power").unwrap();
        let mut c = zero.clone();
        c[k][0] = 1.0;
        let a = apply(&d, &u, &f, &c, &z0);
        for t in &f[k].terms {
            let want = f64::from(d.sut_power.z[t.point]) + t.weights[0];
            assert!(
                (f64::from(a.sut_power.z[t.point]) - want).abs() <= 1e-6 * want.abs().max(1.0),
                "{}",
                t.point
            );
        }
        assert_eq!((&a.load_torque, &a.friction, &a.params), (&d.load_torque, &d.friction, &d.params));
        let mut c = zero.clone();
        c[0][0] = -50.0;
        let a = apply(&d, &u, &f, &c, &z0);
        let m = &a.friction[0];
        assert!(m.x.iter().zip(&m.y).all(|(x, y)| x * y >= 0.0));
        assert!(m.x.iter().zip(&m.y).any(|(x, y)| *x > 0.0 && *y == 0.0), "{:?}", m.y);
        let mut z = z0.clone();
        z[0] = 1.0;
        let a = apply(&d, &u, &f, &zero, &z);
        let key = u.params[0].keys[0];
        let ratio = f64::from(a.param(key).unwrap()) / f64::from(d.param(key).unwrap());
        assert!((ratio / u.params[0].sigma_ln.exp() - 1.0).abs() < 1e-6, "{key}: {ratio}");
    }
}
