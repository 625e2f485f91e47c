//! Perturbed model data for the virtual bench (`simrod bench --perturb-maps SEED`).
//!
//! A real bench's physics is never exactly the identified data. [`perturb`] returns a
//! copy of a [`ModelData`] whose maps and uncertain scalar parameters are smooth random
//! perturbations of the originals, each within the uncertainty the thesis reports
//! ([`Uncertainty::thesis`], every number with its origin or marked ASSUMED). The bench
//! runs its plant on the perturbed copy while the twin keeps the identified data, so the
//! diagnosis tools are tested against "base data that is not the identified data".
//! [`summary`] says what was changed, for the truth file of a generated case.
//!
//! How a perturbation is built:
//! - grids are never touched, only values; every value stays finite, so the model-core
//!   table constructors accept the result ([`ModelData::maps`] is `Ok`);
//! - the maps change by the smooth fields of [`simrod_io::map_prior`] (the prior an
//!   estimator of the maps within their uncertainty fits too): random Fourier series on
//!   the normalised axes, a perturbation looks like a mis-identified curve (offset, tilt,
//!   a bow), not like noise; their unit-normal coefficients are drawn here;
//! - each field and each parameter group draws from its own [`Rng`] stream, named by a
//!   hash of its name, so adding an item later leaves the others' draws unchanged and the
//!   same `(data, seed, unc)` always gives the same result;
//! - magnitudes: the expected mean square of the change over the map's grid points is
//!   the target sigma squared (absolute for friction, relative to the value for the
//!   other maps); each draw's RMS scatters around it (it is a random draw, not a
//!   normalised one).
//!
//! Constraints kept (only where the base data has them):
//! - friction: odd in speed (`f(−ω) = −f(ω)`, exactly, when the base map is), zero at
//!   zero speed (a taper `1 − exp(−(ω/ω_t)²)` takes the change to 0 there) and no sign
//!   change (friction opposes motion);
//! - speed maps and the throttle input map: non-decreasing, the zero region (deadband,
//!   0 % → 0 rpm) stays 0 and the saturation plateau (2100 / 500 rpm, 100 %) stays at
//!   its value; only the values strictly between are scaled;
//! - scalar parameters: log-normal factors (`v · exp(σ g)`, median = identified value),
//!   so they stay positive.

use simrod_io::datadir::{ModelData, ParamLine, FILES_1D, FILES_2D};
use simrod_io::map_prior::{apply, fields};
use simrod_numerics::stats::Rng;

pub use simrod_io::map_prior::SPECTRUM;
pub use simrod_io::map_uncertainty::{ParamSigma, Sigma, Uncertainty, REGION_WIDTH_PCT};

/// FNV-1a of a name: the RNG stream of one map or parameter group.
fn stream_of(name: &str) -> u64 {
    name.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

fn rng_for(seed: u64, name: &str) -> Rng {
    Rng::new(seed, stream_of(name))
}

/// `n` unit-normal coefficients of one field, from its own stream.
fn draw(seed: u64, name: &str, n: usize) -> Vec<f64> {
    let mut rng = rng_for(seed, name);
    (0..n).map(|_| rng.gauss()).collect()
}

/// A copy of `data` with every map and the uncertain scalar parameters perturbed: same
/// grids, smooth (the fields of [`simrod_io::map_prior`], each field's coefficients and
/// each parameter group's factor drawn from its own stream, so adding an item leaves the
/// others' draws unchanged), seeded. The same `(data, seed, unc)` always gives the same
/// result.
pub fn perturb(data: &ModelData, seed: u64, unc: &Uncertainty) -> ModelData {
    let fields = fields(data, unc);
    let coefs: Vec<Vec<f64>> = fields.iter().map(|f| draw(seed, &f.name, f.coefs)).collect();
    let z: Vec<f64> = unc
        .params
        .iter()
        .map(|p| p.keys.first().map_or(0.0, |first| rng_for(seed, &format!("param:{first}")).gauss()))
        .collect();
    let mut out = apply(data, unc, &fields, &coefs, &z);
    let note = format!(
        "# PERTURBED (simrod-vbench perturb, seed {seed}): a virtual bench's true data, not the identified data"
    );
    let (ones, twos) = out.maps_mut();
    let comments = ones.into_iter().map(|m| &mut m.comments).chain(twos.into_iter().map(|m| &mut m.comments));
    for c in comments {
        c.push(note.clone());
    }
    for line in &mut out.params {
        if let ParamLine::Entry { key, value, comment } = line {
            let moved = unc.params.iter().any(|p| p.keys.contains(&key.as_str()));
            if moved && Some(*value) != data.param(key) && !comment.contains("PERTURBED") {
                comment.push_str(" PERTURBED");
            }
        }
    }
    out
}

/// One changed map or parameter: RMS and max |change| in its unit.
#[derive(Debug, Clone, PartialEq)]
pub struct PerturbItem {
    /// Map file name without `.csv`, or the parameter key.
    pub name: String,
    pub unit: &'static str,
    /// RMS of the change over the map's grid points (a parameter: |change|).
    pub rms: f64,
    /// Largest |change|.
    pub max_abs: f64,
}

/// What was changed, for the truth file of a generated case.
#[derive(Debug, Clone, PartialEq)]
pub struct PerturbSummary {
    pub items: Vec<PerturbItem>,
}

impl PerturbSummary {
    /// The item called `name`.
    pub fn item(&self, name: &str) -> Option<&PerturbItem> {
        self.items.iter().find(|i| i.name == name)
    }
}

/// Units of the maps, in `FILES_1D` then `FILES_2D` order.
const MAP_UNITS: [&str; 12] = ["%", "rpm", "rpm", "N m", "N m", "N m", "N m", "A", "A", "W", "W", "W"];

/// The unit of a parameter key, from the thesis list (others: "").
fn param_unit(key: &str) -> &'static str {
    Uncertainty::thesis().params.iter().find(|p| p.keys.contains(&key)).map_or("", |p| p.unit)
}

fn change_stats(a: &[f32], b: &[f32]) -> (f64, f64) {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| f64::from(*y) - f64::from(*x)).collect();
    let rms = if d.is_empty() { 0.0 } else { (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt() };
    (rms, d.iter().fold(0.0, |m, v| m.max(v.abs())))
}

/// What was changed: every map (by file name without `.csv`, even if unchanged) and
/// every parameter whose value differs, with the RMS and max |change| in its unit.
pub fn summary(base: &ModelData, perturbed: &ModelData) -> PerturbSummary {
    let mut items = Vec::new();
    let names = FILES_1D.iter().chain(FILES_2D.iter()).map(|f| f.trim_end_matches(".csv"));
    let values: Vec<(&[f32], &[f32])> = base
        .maps_1d()
        .iter()
        .zip(perturbed.maps_1d().iter())
        .map(|((_, a), (_, b))| (a.y.as_slice(), b.y.as_slice()))
        .chain(
            base.maps_2d()
                .iter()
                .zip(perturbed.maps_2d().iter())
                .map(|((_, a), (_, b))| (a.z.as_slice(), b.z.as_slice())),
        )
        .collect();
    for ((name, (a, b)), unit) in names.zip(values).zip(MAP_UNITS) {
        let (rms, max_abs) = change_stats(a, b);
        items.push(PerturbItem { name: name.to_string(), unit, rms, max_abs });
    }
    for line in &base.params {
        if let ParamLine::Entry { key, value, .. } = line {
            if let Some(v) = perturbed.param(key) {
                if v != *value {
                    let d = (f64::from(v) - f64::from(*value)).abs();
                    items.push(PerturbItem { name: key.clone(), unit: param_unit(key), rms: d, max_abs: d });
                }
            }
        }
    }
    PerturbSummary { items }
}

#[cfg(test)]
mod tests {
    use super::*;
    use simrod_io::datadir::{Map1, Map2};
    use simrod_io::map_prior::{is_odd, non_decreasing, shape1, shape2, zero_at_zero, COEFS_1D, COEFS_2D};

    fn base() -> ModelData {
        ModelData::builtin().expect("built-in data")
    }

    fn rms(v: &[f64]) -> f64 {
        (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
    }

    fn diff1(a: &Map1, b: &Map1) -> Vec<f64> {
        a.y.iter().zip(&b.y).map(|(x, y)| f64::from(*y) - f64::from(*x)).collect()
    }

    #[test]
    fn reproducible_and_seed_dependent() {
        let d = base();
        let u = Uncertainty::thesis();
        for seed in [0, 1, 42, u64::MAX] {
            let a = perturb(&d, seed, &u);
            let b = perturb(&d, seed, &u);
            assert_eq!(a, b, "seed {seed}");
            assert_ne!(a, d, "seed {seed} changes something");
        }
        let (a, b) = (perturb(&d, 1, &u), perturb(&d, 2, &u));
        for (x, y) in a.maps_2d().iter().zip(b.maps_2d().iter()) {
            assert_ne!(x.1.z, y.1.z, "{}", x.0);
        }
        for (x, y) in a.maps_1d().iter().zip(b.maps_1d().iter()).skip(1) {
            assert_ne!(x.1.y, y.1.y, "{}", x.0);
        }
        assert_ne!(a.param("coupling_stiffness_identified"), b.param("coupling_stiffness_identified"));
    }

    #[test]
    fn valid_tables_finite_and_grids_untouched() {
        let d = base();
        let u = Uncertainty::thesis().scaled(3.0);
        for seed in 0..30 {
            let p = perturb(&d, seed, &u);
            assert!(p.maps().is_ok(), "seed {seed}");
            for ((_, a), (_, b)) in d.maps_1d().iter().zip(p.maps_1d().iter()) {
                assert_eq!(a.x, b.x);
                assert!(b.y.iter().all(|v| v.is_finite()));
            }
            for ((_, a), (_, b)) in d.maps_2d().iter().zip(p.maps_2d().iter()) {
                assert_eq!((&a.x, &a.y), (&b.x, &b.y));
                assert!(b.z.iter().all(|v| v.is_finite()));
            }
            for l in &p.params {
                if let ParamLine::Entry { key, value, .. } = l {
                    assert!(
                        value.is_finite() && (*value > 0.0) == (d.param(key).unwrap_or(0.0) > 0.0),
                        "{key}"
                    );
                }
            }
            // The perturbed data still builds model parameters and a model data dir text.
            let mut buf = Vec::new();
            simrod_io::datadir::write_map1(&mut buf, &p.friction[0]).unwrap();
            simrod_io::datadir::parse_map1(std::path::Path::new("x.csv"), std::str::from_utf8(&buf).unwrap())
                .unwrap();
        }
    }

    #[test]
    fn friction_rms_matches_thesis_rmse() {
        let d = base();
        let u = Uncertainty::thesis();
        for side in 0..2 {
            let target = u.friction_nm[side].value;
            let ms: f64 = (0..20)
                .map(|s| rms(&diff1(&d.friction[side], &perturb(&d, s, &u).friction[side])).powi(2))
                .sum::<f64>()
                / 20.0;
            let r = ms.sqrt();
            assert!((r / target - 1.0).abs() < 0.5, "side {side}: rms {r} vs {target}");
        }
        // Table 5.7: L is 1.7583, R is 2.2156.
        assert!(u.friction_nm[0].value < u.friction_nm[1].value);
    }

    #[test]
    fn friction_stays_odd_zero_at_zero_and_signed() {
        let d = base();
        assert!(is_odd(&d.friction[0]) && is_odd(&d.friction[1]));
        let u = Uncertainty::thesis().scaled(2.0);
        for seed in 0..20 {
            let p = perturb(&d, seed, &u);
            for m in &p.friction {
                assert!(is_odd(m), "seed {seed}");
                assert!(zero_at_zero(m));
                for (x, y) in m.x.iter().zip(&m.y) {
                    assert!(x * y >= 0.0, "seed {seed}: friction {y} at {x} rpm");
                }
            }
        }
    }

    fn rel_changes(a: &Map2, b: &Map2, rows: impl Fn(f32) -> bool) -> Vec<f64> {
        let nx = a.x.len();
        a.z.iter()
            .zip(&b.z)
            .enumerate()
            .filter(|(i, (z, _))| rows(a.y[i / nx]) && z.abs() > 1.0)
            .map(|(_, (z, w))| (f64::from(*w) - f64::from(*z)) / f64::from(*z))
            .collect()
    }

    fn mean_rms(n: u64, f: impl Fn(u64) -> Vec<f64>) -> f64 {
        ((0..n).map(|s| rms(&f(s)).powi(2)).sum::<f64>() / n as f64).sqrt()
    }

    #[test]
    fn relative_map_rms_match_targets() {
        let d = base();
        let u = Uncertainty::thesis();
        let check = |name: &str, got: f64, target: f64| {
            assert!((got / target - 1.0).abs() < 0.5, "{name}: rms {got} vs target {target}");
        };
        for side in 0..2 {
            let mot = mean_rms(20, |s| {
                rel_changes(&d.load_torque[side], &perturb(&d, s, &u).load_torque[side], |y| y < 0.0)
            });
            check("load torque motoring", mot, u.load_torque_motoring_rel.value);
            let reg = mean_rms(20, |s| {
                rel_changes(&d.load_torque[side], &perturb(&d, s, &u).load_torque[side], |y| y > 0.0)
            });
            check("load torque regen", reg, u.load_torque_regen_rel.value);
            assert!(reg > 2.0 * mot, "regen {reg} should be well above motoring {mot}");
            let cur = mean_rms(20, |s| {
                rel_changes(&d.load_current[side], &perturb(&d, s, &u).load_current[side], |y| y < 0.0)
            });
            check("load current motoring", cur, u.load_torque_motoring_rel.value);
            let pw = mean_rms(20, |s| {
                rel_changes(&d.load_power[side], &perturb(&d, s, &u).load_power[side], |y| y < 0.0)
            });
            let t = (u.load_torque_motoring_rel.value.powi(2) + u.load_power_rel.value.powi(2)).sqrt();
            check("load power motoring", pw, t);
        }
        let sut_pos = mean_rms(20, |s| {
            let p = perturb(&d, s, &u);
            d.sut_power
                .z
                .iter()
                .zip(&p.sut_power.z)
                .filter(|(z, _)| **z > 1.0)
                .map(|(z, w)| f64::from(w - z) / f64::from(*z))
                .collect()
        });
        check("sut power", sut_pos, u.sut_power_rel.value);
        let sut_neg = mean_rms(20, |s| {
            let p = perturb(&d, s, &u);
            d.sut_power
                .z
                .iter()
                .zip(&p.sut_power.z)
                .filter(|(z, _)| **z < -1.0)
                .map(|(z, w)| f64::from(w - z) / f64::from(*z))
                .collect()
        });
        check("sut power regen", sut_neg, u.sut_power_regen_rel.value);
        for (name, get) in [
            ("speed fwd", (|m: &ModelData| m.speed_fwd.clone()) as fn(&ModelData) -> Map1),
            ("speed rev", |m: &ModelData| m.speed_rev.clone()),
        ] {
            let b = get(&d);
            let hi = b.y.iter().copied().fold(0.0, f32::max);
            let r = mean_rms(20, |s| {
                let p = get(&perturb(&d, s, &u));
                b.y.iter()
                    .zip(&p.y)
                    .filter(|(y, _)| **y > 0.0 && **y < 0.9 * hi)
                    .map(|(y, w)| f64::from(w - y) / f64::from(*y))
                    .collect()
            });
            check(name, r, u.speed_map_rel.value);
        }
    }

    #[test]
    fn scalar_params_match_targets_and_controller_settings_untouched() {
        let d = base();
        let u = Uncertainty::thesis();
        for p in &u.params {
            for key in p.keys {
                assert!(d.param(key).is_some(), "{key} is a parameters.toml key");
            }
            let k = p.keys[0];
            let v0 = f64::from(d.param(k).unwrap());
            let logs: Vec<f64> =
                (0..40).map(|s| (f64::from(perturb(&d, s, &u).param(k).unwrap()) / v0).ln()).collect();
            let r = rms(&logs);
            assert!((r / p.sigma_ln - 1.0).abs() < 0.5, "{k}: {r} vs {}", p.sigma_ln);
            // Keys of one group share one factor.
            let pd = perturb(&d, 7, &u);
            let f0 = f64::from(pd.param(k).unwrap()) / v0;
            for key in p.keys {
                let f = f64::from(pd.param(key).unwrap()) / f64::from(d.param(key).unwrap());
                assert!((f / f0 - 1.0).abs() < 1e-6, "{key}");
            }
        }
        let p = perturb(&d, 3, &u);
        for key in [
            "pid_kp",
            "pid_ki",
            "prog.accel_hs_fwd_s",
            "speed_limit_fwd_rpm",
            "speed_limit_rev_rpm",
            "max_speed_fwd_rpm",
            "supply_voltage_v",
            "flange_stiffness",
            "ident.ls_fwd_pct",
            "sut_gear_ratio",
        ] {
            assert_eq!(p.param(key), d.param(key), "{key} must not be perturbed");
        }
        // Coupling stiffness stays positive and is perturbed by tens of percent.
        let ks: Vec<f64> = (0..20)
            .map(|s| f64::from(perturb(&d, s, &u).param("coupling_stiffness_identified").unwrap()))
            .collect();
        assert!(ks.iter().all(|k| *k > 0.0));
        assert!(ks.iter().any(|k| (k / 4369.434 - 1.0).abs() > 0.15));
    }

    #[test]
    fn monotone_maps_keep_shape_deadband_and_limits() {
        let d = base();
        let u = Uncertainty::thesis().scaled(3.0);
        for seed in 0..30 {
            let p = perturb(&d, seed, &u);
            for (b, m, limit) in [
                (&d.speed_fwd, &p.speed_fwd, 2100.0),
                (&d.speed_rev, &p.speed_rev, 500.0),
                (&d.throttle_input, &p.throttle_input, 100.0),
            ] {
                assert!(non_decreasing(&m.y), "seed {seed}: {:?}", m.y);
                for (y0, y) in b.y.iter().zip(&m.y) {
                    if *y0 == 0.0 {
                        assert_eq!(*y, 0.0, "zero region kept");
                    }
                    if *y0 == limit {
                        assert_eq!(*y, limit, "limit kept");
                    }
                    assert!(*y <= limit && *y >= 0.0);
                }
            }
            // The built-in throttle map is all deadband/full: nothing to change.
            assert_eq!(p.throttle_input.y, d.throttle_input.y);
        }
        // A throttle map with interior points does change, monotonically.
        let mut t = d.clone();
        t.throttle_input.x = vec![0.0, 1.5, 2.5, 3.5, 4.5, 5.0];
        t.throttle_input.y = vec![0.0, 0.0, 33.3, 66.7, 100.0, 100.0];
        let tp = perturb(&t, 9, &Uncertainty::thesis().scaled(3.0)).throttle_input;
        assert_ne!(tp.y, t.throttle_input.y);
        assert!(non_decreasing(&tp.y));
        assert_eq!((tp.y[1], tp.y[4]), (0.0, 100.0));
    }

    #[test]
    fn shapes_are_smooth() {
        // On a dense axis, the second difference of a shape is far below its value.
        let u: Vec<f64> = (0..=100).map(|i| f64::from(i) / 100.0).collect();
        for seed in 0..20 {
            let f = draw(seed, "smooth", COEFS_1D);
            let v: Vec<f64> = u.iter().map(|x| (0..COEFS_1D).map(|j| f[j] * shape1(j, *x)).sum()).collect();
            let d2: Vec<f64> = v.windows(3).map(|w| w[0] - 2.0 * w[1] + w[2]).collect();
            assert!(rms(&d2) < 0.01 * rms(&v), "seed {seed}");
            let g = draw(seed, "smooth2", COEFS_2D);
            let row: Vec<f64> =
                u.iter().map(|x| (0..COEFS_2D).map(|j| g[j] * shape2(j, *x, 0.3)).sum()).collect();
            let d2: Vec<f64> = row.windows(3).map(|w| w[0] - 2.0 * w[1] + w[2]).collect();
            assert!(rms(&d2) < 0.01 * rms(&row), "seed {seed}");
        }
        // On the maps' own grids: neighbouring changes are strongly correlated (white
        // noise would give a lag-1 correlation near 0 and a second difference ~2.4 times
        // its RMS).
        let d = base();
        let un = Uncertainty::thesis();
        let (mut num, mut den, mut d2s, mut vs) = (0.0, 0.0, 0.0, 0.0);
        for seed in 0..20 {
            let p = perturb(&d, seed, &un);
            let a = &d.load_torque[0];
            let nx = a.x.len();
            for iy in 0..a.y.len() {
                let r: Vec<f64> = (0..nx)
                    .map(|ix| {
                        let (z, w) = (a.z[iy * nx + ix], p.load_torque[0].z[iy * nx + ix]);
                        if z.abs() > 1.0 {
                            f64::from(w - z) / f64::from(z)
                        } else {
                            0.0
                        }
                    })
                    .collect();
                if r.contains(&0.0) {
                    continue;
                }
                num += r.windows(2).map(|w| w[0] * w[1]).sum::<f64>();
                den += r.windows(2).map(|w| w[0] * w[0]).sum::<f64>();
                d2s += r.windows(3).map(|w| (w[0] - 2.0 * w[1] + w[2]).powi(2)).sum::<f64>();
                vs += r.iter().map(|v| v * v).sum::<f64>() * (nx - 2) as f64 / nx as f64;
            }
        }
        assert!(num / den > 0.8, "lag-1 correlation {}", num / den);
        assert!((d2s / vs).sqrt() < 0.5, "second difference ratio {}", (d2s / vs).sqrt());
    }

    #[test]
    fn summary_names_every_item() {
        let d = base();
        let u = Uncertainty::thesis();
        let p = perturb(&d, 0, &u);
        let s = summary(&d, &p);
        for f in FILES_1D.iter().chain(FILES_2D.iter()) {
            let it = s.item(f.trim_end_matches(".csv")).unwrap_or_else(|| panic!("{f}"));
            assert!(it.rms.is_finite() && it.max_abs >= it.rms);
        }
        for name in ["axle_friction_L", "load_torque_R", "sut_inverter_power", "speed_map_fwd"] {
            assert!(s.item(name).unwrap().rms > 0.0, "{name}");
        }
        assert_eq!(s.item("axle_friction_L").unwrap().unit, "N m");
        assert_eq!(s.item("load_current_L").unwrap().unit, "A");
        for ps in &u.params {
            for key in ps.keys {
                let it = s.item(key).unwrap_or_else(|| panic!("{key}"));
                assert_eq!(it.unit, ps.unit);
                assert!(it.rms > 0.0);
            }
        }
        // Nothing else: unchanged parameters are not listed.
        let n_params: usize = u.params.iter().map(|p| p.keys.len()).sum();
        assert_eq!(s.items.len(), 12 + n_params);
        // No perturbation: every map at 0, no parameters.
        let z = summary(&d, &perturb(&d, 5, &Uncertainty::none()));
        assert_eq!(z.items.len(), 12);
        assert!(z.items.iter().all(|i| i.rms == 0.0 && i.max_abs == 0.0));
    }

    #[test]
    fn every_sigma_has_an_origin() {
        let u = Uncertainty::thesis();
        let sig = [
            u.friction_nm[0],
            u.friction_nm[1],
            u.friction_taper_rpm,
            u.load_torque_motoring_rel,
            u.load_torque_regen_rel,
            u.load_power_rel,
            u.sut_power_rel,
            u.sut_power_regen_rel,
            u.speed_map_rel,
            u.throttle_map_rel,
        ];
        for s in sig {
            assert!(s.value > 0.0 && !s.origin.is_empty());
            assert!(s.origin.starts_with("ASSUMED") || s.origin.starts_with("table"), "{}", s.origin);
        }
        for p in &u.params {
            assert!(p.sigma_ln > 0.0 && !p.origin.is_empty() && !p.unit.is_empty());
        }
    }

    #[test]
    fn perturbed_plant_runs_and_differs_from_the_twin() {
        use model_core::{Config, CouplingStiffness, Inputs, Model, RateSet, SetPoints};
        let d = base();
        let p = perturb(&d, 11, &Uncertainty::thesis());
        let run = |m: &ModelData| -> Vec<f32> {
            let cfg = Config {
                params: m.params(RateSet::Identified, CouplingStiffness::Identified),
                ..Config::default()
            };
            let mut model = Model::with_maps(&cfg, m.maps().expect("maps")).expect("model");
            let mut last = Vec::new();
            for k in 0..6000 {
                let sp = if k < 3000 {
                    SetPoints { throttle_pct: 50.0, load_pct: [-40.0, -40.0] }
                } else {
                    SetPoints { throttle_pct: 50.0, load_pct: [40.0, 40.0] }
                };
                let o = model.step(&Inputs { sp, supply_v: 24.0 });
                assert!(o.values.iter().all(|v| v.is_finite()), "step {k}");
                last = o.values.to_vec();
            }
            last
        };
        let (a, b) = (run(&d), run(&p));
        assert!(a.iter().zip(&b).any(|(x, y)| (x - y).abs() > 1e-3 * x.abs().max(1.0)));
    }
}
