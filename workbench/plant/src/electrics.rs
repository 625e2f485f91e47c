//! The bench's electrics after the power maps: DPU supply (its source resistance and
//! current limit), busbars, the busbar-to-inverter connector (its thermal drift) and the
//! SuT inverter's DC link. Everything is solved to convergence each plant step.

use model_core::Effects;

use crate::effects::{ConnectorDrift, DcLink, PlantEffects, SupplyLimit};

/// Electrical outputs at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ElectricsOut {
    /// [V] busbar voltage.
    pub v_b: f64,
    /// [A] current through the connector into the SuT inverter.
    pub i_dc: f64,
    /// [V] inverter DC voltage.
    pub v_dc: f64,
    /// [A] load L, R currents from the busbars.
    pub i_load: [f64; 2],
}

/// Constants and state of the electrics.
pub(crate) struct Electrics {
    v_s: f64,
    r0: f64,
    supply_r: f64,
    limit: SupplyLimit,
    drift: ConnectorDrift,
    link: DcLink,
    /// [K] connector temperature rise.
    t_conn: f64,
    /// [V] DC-link voltage (with a link capacitance).
    v_cap: f64,
    /// [V] busbar voltage of the last step (root search start).
    v_b: f64,
}

/// Current [A] drawn through resistance `r` by a load taking power `p` at the far end,
/// from a source at `v`: `r i² - v i + p = 0`, the smaller root (without cancellation),
/// the draw capped at 95 % of the most the connector can pass (`v²/4r`).
fn connector(p: f64, v: f64, r: f64) -> f64 {
    if v <= 0.0 {
        return 0.0;
    }
    let p = if r > 0.0 { p.min(0.95 * v * v / (4.0 * r)) } else { p };
    2.0 * p / (v + (v * v - 4.0 * r * p).max(0.0).sqrt())
}

impl Electrics {
    pub(crate) fn new(supply_v: f64, r_conn: f64, fx: &Effects, bench: &PlantEffects) -> Self {
        Self {
            v_s: supply_v,
            r0: r_conn,
            supply_r: f64::from(fx.supply_resistance),
            limit: bench.supply_current_limit,
            drift: bench.connector_resistance_drift,
            link: bench.dc_link,
            t_conn: 0.0,
            v_cap: supply_v,
            v_b: supply_v,
        }
    }

    /// Nothing drawn yet.
    pub(crate) fn at_rest(&self) -> ElectricsOut {
        ElectricsOut { v_b: self.v_s, i_dc: 0.0, v_dc: self.v_s, i_load: [0.0; 2] }
    }

    /// Connector resistance at its present temperature.
    fn resistance(&self) -> f64 {
        self.r0 * (1.0 + self.drift.alpha_per_k * self.t_conn)
    }

    /// Supply voltage drop [V] at total current `i`: source resistance, and the droop
    /// beyond the current limit.
    fn sag(&self, i: f64) -> f64 {
        let mut dv = self.supply_r * i;
        if self.limit.limit_a > 0.0 {
            dv += self.limit.droop_ohm * (i - self.limit.limit_a).max(0.0);
        }
        dv
    }

    /// Busbar voltage where the supply's sag matches the current drawn at it. `g(v) = v -
    /// V_s + sag(I(v))` rises with `v` on both sides of the connector's cap (slopes 1 -
    /// R I/v and 1 + 0.39 R/r), but has a kink there that can make Newton cycle: Newton
    /// from the last step's voltage (the root moves little per step), then bisection on
    /// a bracket if it has not converged.
    /// `None` when there is no root: the draw exceeds what the supply can deliver.
    fn busbars(&self, current_at: &dyn Fn(f64) -> f64) -> Option<f64> {
        if self.supply_r == 0.0 && self.limit.limit_a <= 0.0 {
            return Some(self.v_s);
        }
        let g = |v: f64| v - self.v_s + self.sag(current_at(v));
        let tol = 1e-12 * self.v_s;
        let (lo_v, hi_v) = (0.01 * self.v_s, 10.0 * self.v_s);
        let mut v = self.v_b;
        for _ in 0..20 {
            let gv = g(v);
            let dv = 1e-7 * self.v_s;
            let slope = (g(v + dv) - gv) / dv;
            if !(slope.is_finite() && slope > 0.0) {
                break;
            }
            let next = (v - gv / slope).clamp(lo_v, hi_v);
            if (next - v).abs() <= tol {
                return Some(next);
            }
            v = next;
        }
        // Bisection: widen a bracket around the last iterate, then halve it.
        let (mut lo, mut hi) = (v, v);
        let mut step = 0.01 * self.v_s;
        while g(lo) > 0.0 && lo > lo_v {
            lo = (lo - step).max(lo_v);
            step *= 2.0;
        }
        step = 0.01 * self.v_s;
        while g(hi) < 0.0 && hi < hi_v {
            hi = (hi + step).min(hi_v);
            step *= 2.0;
        }
        if !(g(lo) <= 0.0 && g(hi) >= 0.0) {
            return None;
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if hi - lo <= tol {
                break;
            }
            if g(mid) > 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        Some(0.5 * (lo + hi))
    }

    /// Advance over a step of `h` [s] with the SuT inverter drawing `p_sut` and the loads
    /// `p_load` [W] (+ drawn); `theta` [rad] is the motor angle (inverter ripple).
    /// `None` when the supply collapses: no busbar voltage carries the draw, or the link
    /// capacitor has fallen below half the busbar voltage, where a constant-power draw
    /// through the connector has no stable state left (`v² - v_b v + r p = 0` has its
    /// stable root above `v_b / 2`) and only runs away (a connector heating up under a
    /// steady 4 kW draw fell from 15.5 V to -1.7e8 V in 1.4 s: random scenario
    /// 1,009,320).
    pub(crate) fn step(&mut self, p_sut: f64, p_load: [f64; 2], theta: f64, h: f64) -> Option<ElectricsOut> {
        let r = self.resistance();
        let link = self.link;
        let with_link = link.capacitance_f > 0.0 && r > 0.0;
        if with_link {
            // The link capacitor charges through the connector from the busbars while the
            // inverter draws from it: exact over the step with the draw held.
            let i_inv = p_sut / self.v_cap.max(0.01 * self.v_s)
                + link.ripple_a * (link.periods_per_rev * theta).sin();
            let v_inf = self.v_b - r * i_inv;
            self.v_cap = v_inf + (self.v_cap - v_inf) * (-h / (r * link.capacitance_f)).exp();
            if self.v_cap < 0.5 * self.v_b {
                return None;
            }
        }
        let v_cap = self.v_cap;
        let i_sut = |v: f64| if with_link { (v - v_cap) / r } else { connector(p_sut, v, r) };
        let current_at = |v: f64| {
            let i_ld = if v > 0.0 { (p_load[0] + p_load[1]) / v } else { 0.0 };
            i_sut(v) + i_ld
        };
        let v_b = self.busbars(&current_at)?;
        self.v_b = v_b;
        let i_dc = i_sut(v_b);
        let i_load = if v_b > 0.0 { [p_load[0] / v_b, p_load[1] / v_b] } else { [0.0; 2] };
        let v_dc = if with_link { v_cap } else { v_b - r * i_dc };
        let d = &self.drift;
        if d.k_per_w > 0.0 {
            let heat = d.k_per_w * i_dc * i_dc * r;
            self.t_conn += (1.0 - (-h / d.time_constant_s).exp()) * (heat - self.t_conn);
        }
        Some(ElectricsOut { v_b, i_dc, v_dc, i_load })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn connector_solves_the_quadratic() {
        let (p, v, r) = (2000.0, 24.0, 0.02);
        let i = connector(p, v, r);
        assert!((r * i * i - v * i + p).abs() < 1e-9);
        assert!((connector(p, v, 0.0) - p / v).abs() < 1e-12);
    }

    #[test]
    fn busbars_sag_with_current_and_droop_beyond_the_limit() {
        let mut fx = Effects::NONE;
        fx.supply_resistance = 0.01;
        let bench = PlantEffects {
            supply_current_limit: SupplyLimit { limit_a: 60.0, droop_ohm: 0.05 },
            ..PlantEffects::default()
        };
        let mut e = Electrics::new(24.0, 0.02, &fx, &bench);
        let out = e.step(2000.0, [0.0; 2], 0.0, 1e-5).unwrap();
        let i = out.i_dc;
        let want = 24.0 - f64::from(fx.supply_resistance) * i - 0.05 * (i - 60.0);
        assert!(i > 60.0 && (out.v_b - want).abs() < 1e-9, "{out:?}");
        // The stable (high-voltage) root: above the collapse point of the draw.
        assert!(out.v_b > 19.0 && (out.v_dc * i - 2000.0).abs() < 1e-6, "{out:?}");
    }

    /// Behind a link capacitor a draw the connector can carry settles at the stable root
    /// of `v² - v_b v + r p = 0`; one beyond `v_b² / 4r` (7.2 kW at 24 V and 0.02 Ω)
    /// collapses, and is reported so before the link voltage leaves the stable half.
    #[test]
    fn a_link_settles_under_a_draw_it_can_carry_and_collapses_beyond() {
        let bench = PlantEffects {
            dc_link: DcLink { capacitance_f: 0.005, ripple_a: 0.0, periods_per_rev: 0.0 },
            ..PlantEffects::default()
        };
        let (r, v_b) = (0.02, 24.0);
        let settle = |p: f64| {
            let mut e = Electrics::new(v_b, r, &Effects::NONE, &bench);
            let mut last = None;
            for _ in 0..20_000 {
                last = e.step(p, [0.0; 2], 0.0, 1e-4);
                if last.is_none() {
                    break;
                }
            }
            (last, e.v_cap)
        };
        let (out, v) = settle(5000.0);
        let stable = 0.5 * (v_b + (v_b * v_b - 4.0 * r * 5000.0).sqrt());
        assert!(out.is_some() && (v - stable).abs() < 1e-6, "{v} for {stable}");
        let (out, v) = settle(8000.0);
        assert!(out.is_none() && v < 0.5 * v_b && v > 0.4 * v_b, "{out:?} at {v} V");
    }
}
