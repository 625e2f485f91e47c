//! Drivetrain mechanics (appendix A), integrated exactly for its linear part.
//!
//! Per half shaft (axle frame), five states, every compliance kept:
//!
//! ```text
//!  T_in ─► [J_a: half the SuT inertia] ─k_f,c_f─ [J_f: flange] ─k_c,c_c─ [J_l: load] ◄─ T_ext
//!           ω_a                 φ_af (flange twist)  ω_f   φ_fl (coupling twist)  ω_l
//! ```
//!
//! `T_in` is the side's share of the motor torque through gearbox and open
//! differential; `T_ext` is the axle friction plus the load motor torque.
//!
//! **The ~2 kHz flange mode.** `J_f = 0.0023 kg m²` on `k_f = 349 kN m/rad` rings near
//! 1.96 kHz, above the 1 kHz bench rate: explicit schemes diverge and implicit ones
//! distort or damp it. The chain between the torques is linear, so we discretize it
//! *exactly* under a zero-order hold: `x[k+1] = Φ x[k] + Γ u[k]`, with
//! `[[Φ, Γ], [0, I]] = exp([[A, B], [0, 0]] dt)` computed once at construction (f64,
//! scaling and squaring, see `expm`). The flange mode is then neither amplified nor
//! artificially damped at any step; it only aliases in the 1 kHz samples exactly as it
//! would for a data-acquisition system without anti-alias filter. The nonlinear torques
//! (friction map, regenerating fade, controller) are evaluated at the start of each step
//! and held; their time constants (J/b ≥ 0.3 s) are far slower than the step.
//! States are balanced (twists scaled by `sqrt(k/J)`) before the exponential so it stays
//! well-conditioned.
//!
//! **Round-off.** Each step changes a state by far less than the state itself (at 100 µs
//! a 20 rad/s shaft moves by ~1e-4 rad/s), so plain f32 updates lose the change's low
//! bits with a bias that a slow mode (the open differential's L−R speed, restored only
//! by the friction slope) integrates into a visible drift. The state is therefore kept
//! as an f32 pair `hi + lo`: the increment `(Φ − I) hi + Φ lo + Γ u` is small and
//! accurate, and is added to `hi` with an exact two-term sum. Basic operations only.

use crate::expm::expm;
use crate::num::Real;

/// Number of states per side.
pub const NS: usize = 5;
/// Index of each state in a side's state vector.
pub const W_A: usize = 0;
pub const W_F: usize = 1;
pub const W_L: usize = 2;
pub const PHI_AF: usize = 3;
pub const PHI_FL: usize = 4;

/// Physical parameters of one side, axle frame.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SideParams {
    pub j_a: f32,
    pub j_f: f32,
    pub j_l: f32,
    pub k_f: f32,
    pub c_f: f32,
    pub k_c: f32,
    pub c_c: f32,
}

impl SideParams {
    /// Continuous-time `A` (states as in the module docs) and `B` (inputs `[T_in, T_ext]`).
    pub fn continuous(&self) -> ([[f64; NS]; NS], [[f64; 2]; NS]) {
        let (ja, jf, jl) = (f64::from(self.j_a), f64::from(self.j_f), f64::from(self.j_l));
        let (kf, cf, kc, cc) =
            (f64::from(self.k_f), f64::from(self.c_f), f64::from(self.k_c), f64::from(self.c_c));
        let a = [
            [-cf / ja, cf / ja, 0.0, -kf / ja, 0.0],
            [cf / jf, -(cf + cc) / jf, cc / jf, kf / jf, -kc / jf],
            [0.0, cc / jl, -cc / jl, 0.0, kc / jl],
            [1.0, -1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, -1.0, 0.0, 0.0],
        ];
        let b = [[1.0 / ja, 0.0], [0.0, 0.0], [0.0, -1.0 / jl], [0.0, 0.0], [0.0, 0.0]];
        (a, b)
    }
}

/// Exact zero-order-hold discretization of one side.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SideDisc<R = f32> {
    pub phi: [[R; NS]; NS],
    /// `Φ − I`, rounded from f64 (the small increments keep their precision).
    pub dphi: [[R; NS]; NS],
    pub gam: [[R; 2]; NS],
}

/// `a + b = s + e` exactly (Knuth's TwoSum; no FMA, so the same bits everywhere).
#[inline]
pub fn two_sum<R: Real>(a: R, b: R) -> (R, R) {
    R::two_sum(a, b)
}

fn min(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

/// Square root by Newton's method, basic operations only (bit-identical everywhere).
fn sqrt_f64(x: f64) -> f64 {
    // Not `x <= 0.0`: NaN must take this branch too.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    if !(x > 0.0) {
        return 0.0;
    }
    let mut r = if x > 1.0 { x } else { 1.0 };
    for _ in 0..200 {
        let n = 0.5 * (r + x / r);
        if n >= r {
            break;
        }
        r = n;
    }
    r
}

impl<R: Real> SideDisc<R> {
    /// Discretize for step `dt` [s]: the exponential in f64, each coefficient then
    /// rounded once to `R` ([`Real::from_f64`]).
    pub fn new(sp: &SideParams, dt: f64) -> Self {
        let (a, b) = sp.continuous();
        // Balancing: twist states scaled by the stiffest natural frequency they feed.
        let mut d = [1.0f64; NS];
        d[PHI_AF] = sqrt_f64(f64::from(sp.k_f) / min(f64::from(sp.j_a), f64::from(sp.j_f)));
        d[PHI_FL] = sqrt_f64(f64::from(sp.k_c) / min(f64::from(sp.j_f), f64::from(sp.j_l)));
        const M: usize = NS + 2;
        let mut m = [[0.0f64; M]; M];
        for i in 0..NS {
            for j in 0..NS {
                m[i][j] = d[i] * a[i][j] / d[j] * dt;
            }
            for k in 0..2 {
                m[i][NS + k] = d[i] * b[i][k] * dt;
            }
        }
        let e = expm(&m);
        let mut phi = [[R::ZERO; NS]; NS];
        let mut dphi = [[R::ZERO; NS]; NS];
        let mut gam = [[R::ZERO; 2]; NS];
        for i in 0..NS {
            for j in 0..NS {
                let v = e[i][j] * d[j] / d[i];
                phi[i][j] = R::from_f64(v);
                dphi[i][j] = R::from_f64(if i == j { v - 1.0 } else { v });
            }
            for k in 0..2 {
                gam[i][k] = R::from_f64(e[i][NS + k] / d[i]);
            }
        }
        Self { phi, dphi, gam }
    }

    /// One compensated step: `hi + lo <- Φ (hi + lo) + Γ u`, summed in a fixed order.
    /// The state and coefficients are in `R`, the inputs `u` signals whose wide format
    /// is `R` ([`Real::wide_mul`]: for f32 the plain product).
    #[inline]
    pub fn step_compensated<N: Real<Wide = R>>(&self, hi: &mut [R; NS], lo: &mut [R; NS], u: [N; 2]) {
        let (h0, l0) = (*hi, *lo);
        for (((h, l), (drow, prow)), grow) in
            hi.iter_mut().zip(lo.iter_mut()).zip(self.dphi.iter().zip(self.phi.iter())).zip(self.gam.iter())
        {
            let mut inc = R::ZERO;
            for (dij, xj) in drow.iter().zip(h0.iter()) {
                inc += *dij * *xj;
            }
            // With exact sums the low parts are 0 (`Real::EXACT_SUM`): Φ lo adds nothing.
            if !R::EXACT_SUM {
                for (pij, lj) in prow.iter().zip(l0.iter()) {
                    inc += *pij * *lj;
                }
            }
            inc += N::wide_mul(grow[0], u[0]);
            inc += N::wide_mul(grow[1], u[1]);
            let (s, e) = R::two_sum(*h, inc);
            *h = s;
            *l = e;
        }
    }

    /// One step: `x <- Φ x + Γ u`, summed in a fixed order.
    #[inline]
    pub fn step(&self, x: &[R; NS], u: [R; 2]) -> [R; NS] {
        let mut out = [R::ZERO; NS];
        for ((o, prow), grow) in out.iter_mut().zip(self.phi.iter()).zip(self.gam.iter()) {
            let mut s = R::ZERO;
            for (pij, xj) in prow.iter().zip(x.iter()) {
                s += *pij * *xj;
            }
            s += grow[0] * u[0];
            s += grow[1] * u[1];
            *o = s;
        }
        out
    }
}

/// Angular speed conversions.
pub const RPM_PER_RAD_S: f32 = 30.0 / core::f32::consts::PI;
/// Inverse of [`RPM_PER_RAD_S`].
pub const RAD_S_PER_RPM: f32 = core::f32::consts::PI / 30.0;

#[cfg(test)]
mod tests {
    use super::*;

    fn thesis_side() -> SideParams {
        SideParams {
            j_a: 0.31355,
            j_f: 0.0023,
            j_l: 0.4543,
            k_f: 349_000.0,
            c_f: 1.13,
            k_c: 4369.434,
            c_c: 3.65,
        }
    }

    #[test]
    fn discrete_is_stable_at_bench_and_fine_steps() {
        // Every state decays or stays bounded when unforced: |x| after 10 s is bounded
        // by its start (the rigid-body mode conserves, every other mode decays).
        for dt in [1e-3, 1e-4] {
            let disc = SideDisc::<f32>::new(&thesis_side(), dt);
            let mut x = [0.0, 0.0, 0.0, 1e-4, 1e-3];
            let steps = (10.0 / dt) as usize;
            for _ in 0..steps {
                x = disc.step(&x, [0.0, 0.0]);
            }
            assert!(x.iter().all(|v| v.is_finite()));
            assert!(x[PHI_AF].abs() < 1e-6 && x[PHI_FL].abs() < 1e-5, "{x:?}");
        }
    }

    #[test]
    fn steady_torque_through_springs() {
        // Constant drive torque T in at the SuT side, T out at the load side: after the
        // transients decay the flange and coupling each carry T.
        let sp = thesis_side();
        let disc = SideDisc::<f32>::new(&sp, 1e-3);
        let mut x = [0.0; NS];
        for _ in 0..20_000 {
            x = disc.step(&x, [50.0, 50.0]);
        }
        let t_flange = sp.k_f * x[PHI_AF] + sp.c_f * (x[W_A] - x[W_F]);
        let t_coupling = sp.k_c * x[PHI_FL] + sp.c_c * (x[W_F] - x[W_L]);
        assert!((t_flange - 50.0).abs() < 0.05, "{t_flange}");
        assert!((t_coupling - 50.0).abs() < 0.05, "{t_coupling}");
    }

    #[test]
    fn sqrt_is_exact_on_squares() {
        assert_eq!(sqrt_f64(16.0), 4.0);
        assert_eq!(sqrt_f64(0.25), 0.5);
        assert!((sqrt_f64(2.0) - core::f64::consts::SQRT_2).abs() < 1e-15);
    }
}
