//! The xDT: the vehicle on its road, emulated on the bench. Each sample it reads the
//! bench's measured axle speeds (`T_Kistler_L/R`) and flange torques (`C_Kistler_L/R`)
//! and writes the set points: the throttle from the driver, and per load motor the
//! torque the road would put on that wheel.
//!
//! **The road load.** The flange torques are what the half shafts deliver to the wheels.
//! In the vehicle, both wheels drive one body: `J_v α = C_L + C_R − r F_road`, with
//! `J_v = m_eq r²` the vehicle's inertia at the axle (`m_eq` the mass plus the wheels'
//! rotating inertia). On the bench each shaft drives its flange and load inertia
//! `J_b,i` (the SuT's own inertia is in both, so it needs no emulating). The load
//! motor of side `i` therefore applies
//!
//! ```text
//! T_load,i = r F_road / 2  +  (J_v / 2 − J_b,i) α  −  k_f T_fric,i(ω_i)
//! ```
//!
//! the road's share, the vehicle's inertia beyond the bench's (through the vehicle's
//! acceleration `α` computed from the measured torques, not from a differentiated
//! speed: a differentiator of a 20x inertia ratio would make the loop a neutral delay
//! system, unstable at any delay), and the bench's own axle friction (model-core's
//! friction map at the measured speed) cancelled, since the vehicle has no load-motor
//! drag. With this load the bench's shaft accelerates as the vehicle's wheel would.
//! The measured torques pass a first-order low-pass (the DAQ's anti-alias filter):
//! the flange's 2 kHz mode aliases in 1 kHz samples.
//!
//! The vehicle's speed is the bench's: `v = r (ω_L + ω_R) / 2`; its distance (for the
//! grade profile) is integrated from it. Forward driving only.

use model_core::drivetrain::{two_sum, RAD_S_PER_RPM};
use model_core::table::Table1;
use model_core::{Channel, Maps, Outputs, Params, SetPoints};

use crate::cycle::{Route, Slope};
use crate::driver::{DriverConfig, DriverState};
use crate::loadmap::{LoadHint, LoadInverse, NotMonotone};
use crate::num::clamp;
use crate::vehicle::Vehicle;

/// What the xDT computed in a sample, for the outputs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct XdtSignals {
    /// [m/s] vehicle speed (the bench's axle speed at the wheel radius).
    pub v_mps: f32,
    /// [m/s] the target the driver follows: the cycle's, capped at the vehicle's top
    /// speed and the bench's reach.
    pub target_mps: f32,
    /// [m/s] the cycle's own target.
    pub cycle_mps: f32,
    /// [m] distance driven.
    pub distance_m: f32,
    /// The road under the vehicle.
    pub slope: Slope,
    /// [N m] the road's resistance at the axle, both wheels (`r F_road`).
    pub road_torque_nm: f32,
    /// [m/s^2] the vehicle's acceleration from the measured torques.
    pub accel_mps2: f32,
    /// [N m] load torque asked of each load motor, + braking.
    pub load_torque_nm: [f32; 2],
    /// Whether a load torque lay beyond the load map and was clipped, per side.
    pub clipped: [bool; 2],
}

/// Why the xDT cannot be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum XdtError {
    /// A vehicle parameter: its key and what is expected.
    Vehicle(&'static str, &'static str),
    /// A loop parameter: its key and what is expected.
    Loop(&'static str, &'static str),
    /// The load torque map of a side (0 L, 1 R) cannot be inverted.
    LoadMap(usize, NotMonotone),
    /// The cycle's tables are inconsistent.
    Route,
    /// The vehicle is lighter than the bench: its inertia at the axle (`m_eq r^2 / 2`
    /// per side) is below the bench's flange and load inertia, which no load can remove.
    InertiaBelowBench,
}

/// The xDT's tuning: what `data/xil.toml` gives besides the loop's timing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct XdtTuning {
    /// [%/(km/h)], [%/(km/h s)] driver PI gains.
    pub kp: f32,
    pub ki: f32,
    /// [s] the feed-forward's preview.
    pub preview_s: f32,
    /// [m/s] a target at or below this is a stop.
    pub stop_mps: f32,
    /// [Hz] low-pass on the measured torques (0: none).
    pub torque_filter_hz: f32,
    /// [-] share of the bench's top axle speed a target is capped at.
    pub bench_speed_margin: f32,
    /// [-] share of the bench's axle friction the loads cancel.
    pub friction_compensation: f32,
}

/// Everything fixed at construction.
#[derive(Debug, Clone, Copy)]
pub struct XdtConfig<'a> {
    vehicle: Vehicle,
    route: Route<'a>,
    driver: DriverConfig<'a>,
    load: [LoadInverse<'a>; 2],
    friction: [Table1<'a>; 2],
    /// [s] sample time.
    dt: f32,
    /// [m] wheel radius.
    r: f32,
    /// [1/(kg m^2)] inverse of the vehicle's inertia at the axle, both wheels.
    inv_j_vehicle: f32,
    /// [kg m^2] per side: the vehicle's inertia beyond the bench's.
    j_extra: [f32; 2],
    /// Weight of the torque filter, `w dt / (1 + w dt)` (backward Euler; 1: none).
    filter: f32,
    /// [m/s] highest target.
    cap_mps: f32,
    /// [s] feed-forward preview.
    preview_s: f32,
    friction_compensation: f32,
}

/// What a sample changes.
#[derive(Debug, Clone, Copy, Default)]
pub struct XdtState {
    driver: DriverState,
    /// [N m] filtered flange torques.
    c_filt: [f32; 2],
    /// [m] distance, compensated sum `hi + lo` (a 5 mm step on a kilometre).
    dist: (f32, f32),
    hint_t: usize,
    hint_ahead: usize,
    hint_x: usize,
    hint_fric: [usize; 2],
    hint_load: [LoadHint; 2],
}

impl<'a> XdtConfig<'a> {
    /// The xDT for `vehicle` on `route`, sampled every `dt` [s], around the bench with
    /// `maps` and `params` (the twin's).
    pub fn new(
        vehicle: &Vehicle,
        tuning: &XdtTuning,
        route: Route<'a>,
        maps: &Maps<'a>,
        params: &Params,
        dt: f32,
    ) -> Result<Self, XdtError> {
        vehicle.validate().map_err(|(k, why)| XdtError::Vehicle(k, why))?;
        if !route.is_consistent() {
            return Err(XdtError::Route);
        }
        let load = [
            LoadInverse::new(maps.load_torque[0]).map_err(|e| XdtError::LoadMap(0, e))?,
            LoadInverse::new(maps.load_torque[1]).map_err(|e| XdtError::LoadMap(1, e))?,
        ];
        let r = vehicle.wheel_radius_m;
        let j_vehicle = vehicle.equivalent_mass() * r * r;
        let j_bench =
            [params.flange_inertia + params.load_inertia[0], params.flange_inertia + params.load_inertia[1]];
        let j_extra = [0.5 * j_vehicle - j_bench[0], 0.5 * j_vehicle - j_bench[1]];
        if j_extra.iter().any(|j| j.is_nan() || *j < 0.0) {
            return Err(XdtError::InertiaBelowBench);
        }
        let w_dt = 2.0 * core::f32::consts::PI * tuning.torque_filter_hz * dt;
        let bench_top = params.speed_limit_rpm[0] / params.sut_gear_ratio * RAD_S_PER_RPM * r;
        let cap = tuning.bench_speed_margin * bench_top;
        let top = vehicle.top_speed_kmh / 3.6;
        Ok(Self {
            vehicle: *vehicle,
            route,
            driver: DriverConfig::new(maps, params, r, (tuning.kp, tuning.ki), dt, tuning.stop_mps),
            load,
            friction: maps.friction,
            dt,
            r,
            inv_j_vehicle: 1.0 / j_vehicle,
            j_extra,
            filter: if tuning.torque_filter_hz > 0.0 { w_dt / (1.0 + w_dt) } else { 1.0 },
            cap_mps: if cap < top { cap } else { top },
            preview_s: tuning.preview_s,
            friction_compensation: tuning.friction_compensation,
        })
    }

    /// [m/s] the highest target the driver is given (vehicle top speed, bench reach).
    pub fn cap_mps(&self) -> f32 {
        self.cap_mps
    }

    /// The route driven.
    pub fn route(&self) -> &Route<'a> {
        &self.route
    }

    /// The vehicle.
    pub fn vehicle(&self) -> &Vehicle {
        &self.vehicle
    }

    /// [kg m^2] per side, the vehicle's inertia beyond the bench's.
    pub fn extra_inertia(&self) -> [f32; 2] {
        self.j_extra
    }
}

impl XdtState {
    /// One sample at time `t_s` [s] on the bench's measured outputs `m`: the set points
    /// and what was computed.
    #[inline]
    pub fn step(&mut self, c: &XdtConfig<'_>, t_s: f32, m: &Outputs) -> (SetPoints, XdtSignals) {
        let w = [m.get(Channel::TKistlerL) * RAD_S_PER_RPM, m.get(Channel::TKistlerR) * RAD_S_PER_RPM];
        let v = c.r * 0.5 * (w[0] + w[1]);
        let torque = [m.get(Channel::CKistlerL), m.get(Channel::CKistlerR)];
        for (f, t) in self.c_filt.iter_mut().zip(torque) {
            *f += c.filter * (t - *f);
        }
        self.dist = two_sum(self.dist.0, v * c.dt + self.dist.1);
        let slope = c.route.slope(self.dist.0, &mut self.hint_x);
        let road = c.vehicle.road_force(v, slope.sin, slope.cos) * c.r;
        let alpha = (self.c_filt[0] + self.c_filt[1] - road) * c.inv_j_vehicle;

        let cycle = c.route.target(t_s, &mut self.hint_t);
        let cycle_ahead = c.route.target(t_s + c.preview_s, &mut self.hint_ahead);
        let target = if cycle < c.cap_mps { cycle } else { c.cap_mps };
        let ahead = if cycle_ahead < c.cap_mps { cycle_ahead } else { c.cap_mps };
        let thr = self.driver.update(&c.driver, target, ahead, v);

        let mut load_torque = [0.0f32; 2];
        let mut load_sp = [0.0f32; 2];
        let mut clipped = [false; 2];
        for i in 0..2 {
            let (Some(j), Some(fr), Some(h), Some(inv), Some(wi), Some(hl)) = (
                c.j_extra.get(i),
                c.friction.get(i),
                self.hint_fric.get_mut(i),
                c.load.get(i),
                w.get(i),
                self.hint_load.get_mut(i),
            ) else {
                continue;
            };
            let fric = fr.eval_hinted(*wi * model_core::drivetrain::RPM_PER_RAD_S, h);
            let t = 0.5 * road + *j * alpha - c.friction_compensation * fric;
            let (sp, clip) = inv.set_point_hinted(thr, t, hl);
            if let (Some(lt), Some(ls), Some(cl)) =
                (load_torque.get_mut(i), load_sp.get_mut(i), clipped.get_mut(i))
            {
                (*lt, *ls, *cl) = (t, clamp(sp, -100.0, 100.0), clip);
            }
        }
        let sp = SetPoints { throttle_pct: thr, load_pct: load_sp };
        let sig = XdtSignals {
            v_mps: v,
            target_mps: target,
            cycle_mps: cycle,
            distance_m: self.dist.0,
            slope,
            road_torque_nm: road,
            accel_mps2: alpha * c.r,
            load_torque_nm: load_torque,
            clipped,
        };
        (sp, sig)
    }
}
