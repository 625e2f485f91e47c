//! The torque flange between samples: the check's bound, fed every 10th sample (100 µs)
//! of a 10 µs run of the twin, must hold every sample in between. The case rings: a
//! hard load step with 4° of gear backlash, whose impacts excite the 2 kHz flange mode
//! by tens of N m. The dense samples are the twin's own, not the estimator's, so the
//! bound is measured against data it did not make.

use model_core::{Channel, Config, Effects, Profile, ProfileSet, SetMode, Simulation};
use simrod_check::quantity::{Dynamics, Estimator, Quantity};

fn set(duration_s: f32, throttle_pct: f32, load_pct: f32) -> ProfileSet {
    ProfileSet {
        duration_s,
        throttle_pct,
        load_l_pct: load_pct,
        load_r_pct: load_pct,
        throttle_mode: SetMode::Hold,
        load_mode: SetMode::Hold,
    }
}

#[test]
fn bound_holds_the_flange_mode_between_100_us_samples() {
    let mut fx = Effects::NONE;
    fx.set("gear_backlash", "backlash_deg", 4.0).expect("backlash effect");
    let config = Config { dt_us: 10, effects: fx, ..Config::default() };
    let sets = [set(0.5, 0.0, 0.0), set(3.0, 100.0, -100.0), set(1.0, 100.0, 100.0)];
    let profile = Profile::new(&sets, 1.0, 1.0).expect("profile");
    let sim = Simulation::new(&config, profile, 24.0).expect("model");
    let dynamics = Dynamics::of(sim.model().side_params());
    const EVERY: usize = 10;
    for side in [0usize, 1] {
        let c = if side == 0 { Channel::CKistlerL } else { Channel::CKistlerR };
        let mut est = Estimator::new(Quantity::FlangeTorque(side), 1e-5 * EVERY as f64, &dynamics);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let (mut worst_excess, mut widest, mut ringing) = (f64::NEG_INFINITY, 0.0f64, 0.0f64);
        let (mut peak_dense, mut peak_bound) = (0.0f64, 0.0f64);
        let mut last3 = [0.0f64; 3];
        for (k, o) in sim.clone().enumerate() {
            let x = f64::from(o.get(c));
            // The dense run's own ringing: its second difference at 10 µs.
            last3 = [last3[1], last3[2], x];
            if k >= 2 {
                ringing = ringing.max((last3[2] - 2.0 * last3[1] + last3[0]).abs());
            }
            lo = lo.min(x);
            hi = hi.max(x);
            peak_dense = peak_dense.max(x.abs());
            if (k + 1) % EVERY == 0 {
                let (blo, bhi) = est.step(&o);
                peak_bound = peak_bound.max(bhi.abs()).max(blo.abs());
                // In units of the samples' own f32 rounding (one ulp at their size).
                let ulp = hi.abs().max(lo.abs()).max(1.0) * f64::from(f32::EPSILON);
                worst_excess = worst_excess.max((hi - bhi) / ulp).max((blo - lo) / ulp);
                widest = widest.max(bhi - hi).max(lo - blo);
                (lo, hi) = (x, x);
            }
        }
        // Ringing is there: a 2 kHz oscillation of amplitude A has a 10 µs second
        // difference of A (ω dt)² ≈ 0.015 A; 0.15 N m is 10 N m of ringing.
        assert!(ringing > 0.15, "side {side}: no flange-mode ringing to bound ({ringing})");
        // A signal held still jitters by an ulp or two of f32 between the 10 µs samples;
        // nothing beyond that rounding may pass the bound.
        assert!(worst_excess <= 4.0, "side {side}: a dense sample is {worst_excess} ulp beyond the bound");
        // Where it matters, at the run's peak, the bound is tight: within 1 %.
        assert!(
            peak_bound - peak_dense <= 0.01 * peak_dense,
            "side {side}: peak bound {peak_bound} N m, peak of the 10 µs samples {peak_dense} N m"
        );
        println!(
            "side {side}: 10 µs second difference up to {ringing:.3} N m; dense samples at most {worst_excess:.1} ulp beyond the bound, which is at most {widest:.2} N m beyond them (at an impact); run peak {peak_dense:.2} N m, bound {peak_bound:.2} N m"
        );
    }
}
