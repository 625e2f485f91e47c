//! The plant: the SimRod bench as continuous physics in f64, integrated by classical RK4
//! with a fixed step far below every time constant (10 µs resolves the ~2 kHz flange
//! mode with `ω h ≈ 0.12`).
//!
//! Written from the physical description (`docs/MODEL.md`, the thesis), sharing nothing
//! with `model-core` but its data: the scalar parameters, the maps (interpolated here by
//! [`crate::tables`]) and the profile sets. Every block is continuous:
//! - **Set points**: piecewise constant or linear in time as the profile defines them.
//! - **Curtis rate logic**: the speed command ramps towards the target at the rate the
//!   switching logic picks and stops on it. The ramps (speed command, powers) are
//!   advanced exactly over each step with rate and target taken at the step: first
//!   order in `h` only at switching instants (~0.01 rpm).
//! - **PID**: integrator and derivative filter are ODE states; conditional-integration
//!   anti-windup freezes the integrator while saturated.
//! - **Mechanics**: five ODEs per half shaft; motor torque, friction and loads evaluated
//!   continuously (no hold).
//! - **Electrics**: maps through ramp limiters; the SuT inverter also draws the
//!   mechanical power its map does not cover, through the drive efficiency; the
//!   connector (and busbars) solved in closed form or by a converged root search.
//!
//! The twin's library effects are simulated here with the plant's own code, in
//! continuous time: differential friction as a smooth Coulomb + viscous torque
//! (`tanh`), the backlash as a hybrid system (free flight of the motor, inelastic
//! impact at the step where the gap closes), the controller delay as `sp(t - d)` with
//! the exact delay, the busbar sag by a converged root search. The bench-only effects
//! ([`crate::effects`]) act here as well.

use model_core::{Channel, Effects, Maps, Params, ProfileSet, SpeedTarget, MEASURED};

use crate::effects::{KeyError, PlantEffects};
use crate::electrics::{Electrics, ElectricsOut};
use crate::profile::{SetPoints, TimeProfile};
use crate::sampled::{first_order_lag, fractional_delay};
use crate::tables::Tables;

const RPM_PER_RAD_S: f64 = 30.0 / std::f64::consts::PI;
const RAD_S_PER_RPM: f64 = std::f64::consts::PI / 30.0;

/// Speed [rad/s, axle] over which the differential's Coulomb friction builds up
/// (`tanh(w / w_c)`): smooth, so the ODE stays integrable through zero speed.
const COULOMB_SPEED_RAD_S: f64 = 0.1;
/// Axle speed [rpm] over which Stribeck friction reverses sign through zero.
const STRIBECK_SIGN_RPM: f64 = 0.5;
/// Torque [N m, axle] by which the mesh torque must reverse before the gears part.
const SEPARATION_NM: f64 = 0.05;
/// Lowest friction factor of a fully warmed gearbox.
const WARM_FLOOR: f64 = 0.2;

/// Channels the plant gives beyond the measured ones: the derived powers (thesis table
/// 5.13) and the speed command.
const DERIVED: [Channel; 5] =
    [Channel::PSutInv, Channel::PLml, Channel::PLmr, Channel::PDpu, Channel::SpeedCmd];

/// The channels the plant produces, in the order of [`Sample::values`]: the measured
/// channels (`MEASURED`, in its order), then [`DERIVED`].
pub const CHANNELS: [Channel; MEASURED.len() + DERIVED.len()] = {
    let mut out = [Channel::Throttle; MEASURED.len() + DERIVED.len()];
    let mut i = 0;
    while i < out.len() {
        out[i] = if i < MEASURED.len() { MEASURED[i] } else { DERIVED[i - MEASURED.len()] };
        i += 1;
    }
    out
};

/// One output sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// [µs] sample time.
    pub t_us: u64,
    /// Values of [`CHANNELS`], in the bench's units.
    pub values: [f64; CHANNELS.len()],
}

impl Sample {
    /// Value of a channel, `None` if the plant does not produce it.
    pub fn get(&self, c: Channel) -> Option<f64> {
        let i = CHANNELS.iter().position(|&k| k == c)?;
        self.values.get(i).copied()
    }
}

/// What to simulate.
#[derive(Debug, Clone, Copy)]
pub struct Setup<'a> {
    pub params: Params,
    pub maps: Maps<'a>,
    pub speed_target: SpeedTarget,
    pub sets: &'a [ProfileSet],
    pub throttle_scale: f64,
    pub load_scale: f64,
    /// [V] DPU voltage.
    pub supply_v: f64,
    /// The twin's library effects, simulated by the plant's own code.
    pub library: Effects,
    /// Effects the twin does not have.
    pub bench: PlantEffects,
}

/// Why a setup was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum SetupError {
    /// A library effect parameter outside its range.
    Library(String),
    /// A bench-only effect parameter outside its range.
    Bench(KeyError),
    /// Step or output interval not positive, or not a divisor.
    Step(String),
    /// Supply voltage not finite and positive.
    Supply(f64),
}

impl std::fmt::Display for SetupError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Library(m) => write!(f, "{m}"),
            Self::Bench(e) => write!(f, "{e}"),
            Self::Step(m) => write!(f, "{m}"),
            Self::Supply(v) => write!(f, "supply voltage {v} V: expected a finite value > 0"),
        }
    }
}

impl std::error::Error for SetupError {}

/// Scalars in f64, effects applied, axle frame unless named `motor`.
struct Scalars {
    volts_per_pct: f64,
    typical_max_rpm: f64,
    speed_limit_rpm: [f64; 2],
    max_speed_rpm: [f64; 2],
    map_target: bool,
    full_throttle_pct: f64,
    low_throttle_pct: f64,
    /// Per direction [fwd, rev]: hs %, ls %, accel hs/ls s, low accel s,
    /// neutral decel hs/ls s, partial decel s.
    rates: [[f64; 8]; 2],
    /// Per direction: multipliers on the accelerating and decelerating rates.
    rate_scale: [[f64; 2]; 2],
    kp: f64,
    ki: f64,
    kd: f64,
    d_filter_s: f64,
    torque_max_motor: f64,
    power_max: f64,
    gear: f64,
    /// Per side SuT inertia with the gears in mesh, and without the motor's share.
    j_a: f64,
    j_a_free: f64,
    /// Motor share of the SuT inertia (backlash).
    j_m: f64,
    /// [rad, axle] half the gear free play (0: no backlash).
    half_gap: f64,
    j_f: f64,
    j_l: [f64; 2],
    k_f: f64,
    c_f: f64,
    k_c: f64,
    c_c: f64,
    regen_fade_rad_s: f64,
    load_gear: f64,
    load_base_rpm: f64,
    load_no_load_rpm: f64,
    sut_efficiency: f64,
    sut_power_rate: f64,
    load_power_rate: f64,
    diff_coulomb: f64,
    diff_viscous: f64,
    friction_scale: [f64; 2],
    delay_ns: f64,
}

impl Scalars {
    fn new(p: &Params, fx: &Effects, mode: SpeedTarget) -> Self {
        let f = f64::from;
        let dir = |d: usize| {
            let r = &p.rates.dir[d];
            [
                f(r.hs_pct),
                f(r.ls_pct),
                f(r.accel_hs_s),
                f(r.accel_ls_s),
                f(r.low_accel_s),
                f(r.neutral_decel_hs_s),
                f(r.neutral_decel_ls_s),
                f(r.partial_decel_s),
            ]
        };
        let sc = fx.inertia_scale.map(f);
        let j_sut = f(p.sut_inertia) * sc[0];
        let j_m = f(p.sut_motor_inertia_share) * j_sut;
        let rs = fx.inverter_rate_scale;
        Self {
            volts_per_pct: f(p.throttle_volts_per_pct),
            typical_max_rpm: f(p.typical_max_speed_rpm),
            speed_limit_rpm: p.speed_limit_rpm.map(f),
            max_speed_rpm: p.max_speed_rpm.map(f),
            map_target: matches!(mode, SpeedTarget::Map),
            full_throttle_pct: f(p.full_throttle_pct),
            low_throttle_pct: f(p.low_throttle_pct),
            rates: [dir(0), dir(1)],
            rate_scale: [[f(rs[0][0]), f(rs[0][1])], [f(rs[1][0]), f(rs[1][1])]],
            kp: f(p.pid_kp),
            ki: f(p.pid_ki),
            kd: f(p.pid_kd),
            d_filter_s: f(p.pid_d_filter_s),
            torque_max_motor: f(p.motor_torque_max_nm),
            power_max: f(p.motor_power_max_w),
            gear: f(p.sut_gear_ratio),
            j_a: 0.5 * j_sut,
            j_a_free: 0.5 * (j_sut - j_m),
            j_m,
            half_gap: 0.5 * f(fx.gear_backlash.backlash_deg).to_radians(),
            j_f: f(p.flange_inertia),
            j_l: [f(p.load_inertia[0]) * sc[1], f(p.load_inertia[1]) * sc[2]],
            k_f: f(p.flange_stiffness),
            c_f: f(p.flange_damping),
            k_c: f(fx.coupling_stiffness.unwrap_or(p.coupling_stiffness)),
            c_c: f(fx.coupling_damping.unwrap_or(p.coupling_damping)),
            regen_fade_rad_s: f(p.regen_fade_rpm) * RAD_S_PER_RPM,
            load_gear: f(p.load_gear_ratio),
            load_base_rpm: f(p.load_base_rpm),
            load_no_load_rpm: f(p.load_no_load_rpm),
            sut_efficiency: f(p.sut_drive_efficiency),
            sut_power_rate: f(p.sut_power_rate_w_per_s),
            load_power_rate: f(p.load_power_rate_w_per_s),
            diff_coulomb: f(fx.differential_friction.coulomb_nm),
            diff_viscous: f(fx.differential_friction.viscous_nm_s),
            friction_scale: fx.axle_friction_scale.map(f),
            delay_ns: f(fx.controller_delay_s) * 1e9,
        }
    }
}

// ODE state layout: per side (L at 0, R at SIDE) ω_a, ω_f, ω_l [rad/s], flange twist,
// coupling twist [rad]; the PID integrator [N m, motor frame] and the derivative
// filter's output [rad/s, motor]; the free motor's speed [rad/s, axle] and the gear gap
// [rad, axle] (backlash); the motor angle [rad, motor] (mesh and inverter ripple); the
// gearbox temperature rise [K] (warm-up).
const W_A: usize = 0;
const W_F: usize = 1;
const W_L: usize = 2;
const PHI_AF: usize = 3;
const PHI_FL: usize = 4;
const SIDE: usize = 5;
const INTEG: usize = 10;
const SPEED_FILT: usize = 11;
const W_M: usize = 12;
const GAP: usize = 13;
const THETA: usize = 14;
const T_GEAR: usize = 15;
const NX: usize = 16;

type X = [f64; NX];

/// Where the step is in the profile: the segment of the set points and of the delayed
/// throttle, and whether the gears are apart.
#[derive(Clone, Copy)]
struct Ctx {
    seg: Option<usize>,
    seg_delayed: Option<usize>,
    free: bool,
}

/// The plant.
pub struct Plant {
    s: Scalars,
    fx: Effects,
    bench: PlantEffects,
    tab: Tables,
    profile: TimeProfile,
    /// Step [ns].
    h_ns: u64,
    steps_done: u64,
    x: X,
    /// [rpm] motor speed command (continuous ramp).
    cmd_rpm: f64,
    /// Gears apart (backlash), and the flank last engaged (+1, -1).
    free: bool,
    flank: f64,
    /// [W] rate-limited SuT inverter map power and absorbed mechanical power.
    p_sut: f64,
    p_mech_ref: f64,
    p_load: [f64; 2],
    elec: Electrics,
    out: ElectricsOut,
    /// [µs] when the supply collapsed (no busbar or DC-link voltage carries the draw).
    collapsed_at_us: Option<u64>,
}

fn ramp_towards(y: f64, target: f64, max_change: f64) -> f64 {
    y + (target - y).clamp(-max_change, max_change)
}

impl Plant {
    /// A plant at rest at t = 0, integrating with step `h_ns` [ns].
    pub fn new(setup: &Setup<'_>, h_ns: u64) -> Result<Self, SetupError> {
        if h_ns == 0 {
            return Err(SetupError::Step("the plant's step must be positive".into()));
        }
        setup.library.check().map_err(|e| SetupError::Library(e.to_string()))?;
        setup.bench.check().map_err(SetupError::Bench)?;
        if !(setup.supply_v.is_finite() && setup.supply_v > 0.0) {
            return Err(SetupError::Supply(setup.supply_v));
        }
        let p = &setup.params;
        let fx = setup.library;
        let r_conn = f64::from(fx.connector_resistance.unwrap_or(p.connector_resistance));
        let elec = Electrics::new(setup.supply_v, r_conn, &fx, &setup.bench);
        let mut plant = Self {
            s: Scalars::new(p, &fx, setup.speed_target),
            fx,
            bench: setup.bench,
            tab: Tables::new(&setup.maps),
            profile: TimeProfile::new(setup.sets, setup.throttle_scale, setup.load_scale),
            h_ns,
            steps_done: 0,
            x: [0.0; NX],
            cmd_rpm: 0.0,
            // The gears start in the middle of the gap, apart if there is one.
            free: false,
            flank: 1.0,
            p_sut: 0.0,
            p_mech_ref: 0.0,
            p_load: [0.0; 2],
            out: elec.at_rest(),
            elec,
            collapsed_at_us: None,
        };
        plant.free = plant.s.half_gap > 0.0;
        Ok(plant)
    }

    /// Profile duration [µs].
    pub fn duration_us(&self) -> u64 {
        self.profile.duration_ns() / 1000
    }

    /// Time reached [µs].
    pub fn t_us(&self) -> u64 {
        self.steps_done * self.h_ns / 1000
    }

    fn t_ns(&self) -> u64 {
        self.steps_done * self.h_ns
    }

    /// Mapped throttle [%] and signed target motor speed [rpm] for a throttle set point.
    fn throttle_chain(&self, throttle_sp: f64) -> (f64, f64) {
        let s = &self.s;
        let volts = (throttle_sp.abs() * s.volts_per_pct).clamp(0.0, 5.0);
        let mapped = self.tab.throttle_input.at(volts);
        let d = usize::from(throttle_sp < 0.0);
        let mag =
            if s.map_target { self.tab.speed[d].at(mapped) } else { mapped * 0.01 * s.max_speed_rpm[d] };
        let mag = mag.clamp(0.0, s.speed_limit_rpm[d]);
        (mapped, if d == 1 { -mag } else { mag })
    }

    /// Curtis ramp rate [rpm/s] (MODEL.md, Curtis rate logic).
    fn curtis_rate(&self, mapped: f64, target: f64, cmd: f64, speed_rpm: f64) -> f64 {
        if target == cmd {
            return 0.0;
        }
        let s = &self.s;
        let moving = if cmd != 0.0 { cmd } else { target };
        let d = usize::from(moving < 0.0);
        let (r, [accel_scale, decel_scale]) = (&s.rates[d], s.rate_scale[d]);
        let (hs_pct, ls_pct) = (r[0], r[1]);
        let per_s = |seconds: f64| if seconds > 0.0 { s.typical_max_rpm / seconds } else { 0.0 };
        // LS rate below LS % of Typical Max Speed, HS above HS %, linear blend between.
        let speed_pct = speed_rpm.abs() / s.typical_max_rpm * 100.0;
        let hs_weight = if hs_pct > ls_pct {
            ((speed_pct - ls_pct) / (hs_pct - ls_pct)).clamp(0.0, 1.0)
        } else if speed_pct >= ls_pct {
            1.0
        } else {
            0.0
        };
        let blend = |hs_s: f64, ls_s: f64| per_s(ls_s) + hs_weight * (per_s(hs_s) - per_s(ls_s));
        let same_side = (target >= 0.0) == (cmd >= 0.0) || cmd == 0.0;
        if same_side && target.abs() > cmd.abs() {
            let accel = blend(r[2], r[3]);
            let low = per_s(r[4]);
            let rate = if mapped >= s.full_throttle_pct {
                accel
            } else if mapped <= s.low_throttle_pct {
                low
            } else {
                let f = (mapped - s.low_throttle_pct) / (s.full_throttle_pct - s.low_throttle_pct);
                low + f * (accel - low)
            };
            rate * accel_scale
        } else if mapped <= 0.0 {
            blend(r[5], r[6]) * decel_scale
        } else {
            per_s(r[7]) * decel_scale
        }
    }

    /// Motor torque limit [N m] at motor speed `w` [rad/s]: torque, then power.
    fn torque_limit(&self, w: f64) -> f64 {
        let w = w.abs();
        if w > 0.0 {
            self.s.torque_max_motor.min(self.s.power_max / w)
        } else {
            self.s.torque_max_motor
        }
    }

    /// Differential case speed [rad/s, axle].
    fn case_speed(x: &X) -> f64 {
        0.5 * (x[W_A] + x[W_A + SIDE])
    }

    /// Motor speed [rad/s, motor frame]: the case's, or its own while the gears are apart.
    fn motor_speed(&self, x: &X, free: bool) -> f64 {
        self.s.gear * if free { x[W_M] } else { Self::case_speed(x) }
    }

    /// PID: motor torque [N m] and whether the integrator is frozen (saturated and the
    /// error pushing further out).
    fn pid(&self, x: &X, cmd_rpm: f64, free: bool) -> (f64, bool) {
        let s = &self.s;
        let w_m = self.motor_speed(x, free);
        let e = cmd_rpm * RAD_S_PER_RPM - w_m;
        let derivative = (w_m - x[SPEED_FILT]) / s.d_filter_s;
        let unsat = s.kp * e + x[INTEG] - s.kd * derivative;
        let lim = self.torque_limit(w_m);
        let frozen = (unsat > lim && e > 0.0) || (unsat < -lim && e < 0.0);
        (unsat.clamp(-lim, lim), frozen)
    }

    /// Load motor torque on side `side` [N m, axle frame, + braking forward motion].
    /// Regenerating (map >= 0) brakes and fades out near standstill; motoring drives in
    /// the run direction, as mapped up to the load motor's base speed, then fading
    /// linearly to zero at its no-load speed (back-EMF).
    fn load_torque(&self, side: usize, sp: &SetPoints, w_l: f64) -> f64 {
        let s = &self.s;
        let map = self.tab.load_torque[side].at(sp.throttle, sp.load[side]);
        if map >= 0.0 {
            if s.regen_fade_rad_s > 0.0 {
                map * (w_l / s.regen_fade_rad_s).clamp(-1.0, 1.0)
            } else {
                0.0
            }
        } else {
            let drive_dir = if sp.throttle < 0.0 { -1.0 } else { 1.0 };
            let motor_rpm_along = w_l * drive_dir * s.load_gear * RPM_PER_RAD_S;
            let envelope = ((s.load_no_load_rpm - motor_rpm_along) / (s.load_no_load_rpm - s.load_base_rpm))
                .clamp(0.0, 1.0);
            map * drive_dir * envelope
        }
    }

    /// Friction factor of the warming gearbox at temperature rise `t_k`.
    fn warm_factor(&self, t_k: f64) -> f64 {
        let w = &self.bench.gearbox_warmup;
        if w.drop_per_k > 0.0 {
            (1.0 - w.drop_per_k * t_k).max(WARM_FLOOR)
        } else {
            1.0
        }
    }

    /// Axle friction on side `side` at load-side speed `w_l` [N m, against the motion]:
    /// the map, its scale, warm-up and Stribeck.
    fn friction(&self, side: usize, w_l: f64, t_gear: f64) -> f64 {
        let w_rpm = w_l * RPM_PER_RAD_S;
        let mut fric =
            self.tab.friction[side].at(w_rpm) * self.s.friction_scale[side] * self.warm_factor(t_gear);
        let st = &self.bench.stribeck_friction;
        if st.peak_nm > 0.0 {
            let r = w_rpm / st.speed_rpm;
            fric += st.peak_nm * (-(r * r)).exp() * (w_rpm / STRIBECK_SIGN_RPM).tanh();
        }
        fric
    }

    /// Coupling torque [N m] at twist `phi` and twist rate `dphi` (progressive when on).
    fn coupling(&self, phi: f64, dphi: f64) -> f64 {
        let pc = &self.bench.progressive_coupling;
        let k = if pc.doubling_twist_deg > 0.0 {
            let r = phi / pc.doubling_twist_deg.to_radians();
            self.s.k_c * (1.0 + r * r)
        } else {
            self.s.k_c
        };
        k * phi + self.s.c_c * dphi
    }

    /// Bearing drag [N m] on a SuT output shaft turning at `w_a`.
    fn bearing_drag(&self, w_a: f64) -> f64 {
        let t200 = self.bench.bearing_drag.at_200rpm_nm;
        if t200 > 0.0 {
            let r = w_a * RPM_PER_RAD_S / 200.0;
            t200 * r * r.abs()
        } else {
            0.0
        }
    }

    /// Mesh ripple [N m, axle] at the case for motor angle `theta` and case torque.
    fn mesh_ripple(&self, theta: f64, t_case: f64) -> f64 {
        let m = &self.bench.gear_mesh_ripple;
        if m.amplitude_nm > 0.0 {
            (m.amplitude_nm + m.relative * t_case.abs()) * (m.periods_per_rev * theta).sin()
        } else {
            0.0
        }
    }

    /// Time derivative of the ODE state at `t_ns`.
    fn deriv(&self, c: Ctx, t_ns: f64, x: &X, cmd_rpm: f64) -> X {
        let s = &self.s;
        let sp = self.profile.at(c.seg, t_ns);
        let mut dx = [0.0; NX];

        let w_case = Self::case_speed(x);
        let w_m = self.motor_speed(x, c.free);
        let (t_motor, frozen) = self.pid(x, cmd_rpm, c.free);
        dx[INTEG] = if frozen { 0.0 } else { s.ki * (cmd_rpm * RAD_S_PER_RPM - w_m) };
        dx[SPEED_FILT] = (w_m - x[SPEED_FILT]) / s.d_filter_s;
        dx[THETA] = w_m;

        // Gearbox (or the free motor), differential friction, then the open differential
        // splits the case torque equally.
        let t_axle = s.gear * t_motor;
        let (t_case, j_a) = if c.free {
            dx[W_M] = t_axle / s.j_m;
            dx[GAP] = x[W_M] - w_case;
            (0.0, s.j_a_free)
        } else {
            (t_axle + self.mesh_ripple(x[THETA], t_axle), s.j_a)
        };
        let coulomb =
            if s.diff_coulomb > 0.0 { s.diff_coulomb * (w_case / COULOMB_SPEED_RAD_S).tanh() } else { 0.0 };
        let t_diff = coulomb + s.diff_viscous * w_case;
        let t_in = 0.5 * (t_case - t_diff);
        let mut p_friction = 0.0;
        for side in 0..2 {
            let o = side * SIDE;
            let (w_a, w_f, w_l) = (x[o + W_A], x[o + W_F], x[o + W_L]);
            let t_flange = s.k_f * x[o + PHI_AF] + s.c_f * (w_a - w_f);
            let t_coupling = self.coupling(x[o + PHI_FL], w_f - w_l);
            let friction = self.friction(side, w_l, x[T_GEAR]);
            p_friction += (friction * w_l).abs();
            let t_load = self.load_torque(side, &sp, w_l);
            dx[o + W_A] = (t_in - t_flange - self.bearing_drag(w_a)) / j_a;
            dx[o + W_F] = (t_flange - t_coupling) / s.j_f;
            dx[o + W_L] = (t_coupling - friction - t_load) / s.j_l[side];
            dx[o + PHI_AF] = w_a - w_f;
            dx[o + PHI_FL] = w_f - w_l;
        }
        let warm = &self.bench.gearbox_warmup;
        if warm.drop_per_k > 0.0 {
            dx[T_GEAR] = (warm.k_per_w * p_friction - x[T_GEAR]) / warm.time_constant_s;
        }
        dx
    }

    /// Advance one step of `h`.
    fn step(&mut self) {
        let h = self.h_ns as f64 * 1e-9;
        let t0_ns = self.t_ns();
        let (t0, h_ns) = (t0_ns as f64, self.h_ns as f64);
        let delay = self.s.delay_ns;
        let c = Ctx {
            seg: self.profile.segment_at(i128::from(t0_ns)),
            seg_delayed: self.profile.segment_at((t0 - delay).floor() as i128),
            free: self.free,
        };
        let sp_end = self.profile.at(c.seg, t0 + h_ns);
        let throttle_ctl = self.profile.at(c.seg_delayed, t0 + h_ns - delay).throttle;

        // Speed command: ramp towards the target at the Curtis rate, stopping on it.
        let (mapped, target) = self.throttle_chain(throttle_ctl);
        let speed_rpm = self.motor_speed(&self.x, self.free) * RPM_PER_RAD_S;
        let rate = self.curtis_rate(mapped, target, self.cmd_rpm, speed_rpm);
        let cmd0 = self.cmd_rpm;
        let cmd_at = |frac: f64| ramp_towards(cmd0, target, rate * frac * h);

        // RK4 on the mechanics and the controller states.
        let x0 = self.x;
        let add = |a: &X, b: &X, f: f64| {
            let mut r = *a;
            for (ri, bi) in r.iter_mut().zip(b.iter()) {
                *ri += f * bi;
            }
            r
        };
        let k1 = self.deriv(c, t0, &x0, cmd_at(0.0));
        let k2 = self.deriv(c, t0 + 0.5 * h_ns, &add(&x0, &k1, 0.5 * h), cmd_at(0.5));
        let k3 = self.deriv(c, t0 + 0.5 * h_ns, &add(&x0, &k2, 0.5 * h), cmd_at(0.5));
        let k4 = self.deriv(c, t0 + h_ns, &add(&x0, &k3, h), cmd_at(1.0));
        for i in 0..NX {
            self.x[i] = x0[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        self.cmd_rpm = cmd_at(1.0);
        self.steps_done += 1;

        // Anti-windup: while integrating, the integrator stays within the torque limit.
        let (_, frozen) = self.pid(&self.x, self.cmd_rpm, self.free);
        if !frozen {
            let lim = self.torque_limit(self.motor_speed(&self.x, self.free));
            self.x[INTEG] = self.x[INTEG].clamp(-lim, lim);
        }
        if self.s.half_gap > 0.0 {
            self.backlash(Ctx { free: self.free, ..c }, t0 + h_ns);
        }
        self.electrics(&sp_end, h);
    }

    /// Backlash events at the end of a step: re-engage with an inelastic impact when the
    /// gap has closed, part when the mesh torque pulls against the engaged flank.
    fn backlash(&mut self, c: Ctx, t_ns: f64) {
        let s = &self.s;
        let x = &mut self.x;
        let w_case = Self::case_speed(x);
        if self.free {
            if x[GAP].abs() >= s.half_gap {
                self.flank = x[GAP].signum();
                x[GAP] = self.flank * s.half_gap;
                // Momentum conserved: the motor's and the two half shafts' (impulse split
                // equally, as the open differential splits torque).
                let impulse = (x[W_M] - w_case) / (1.0 / s.j_m + 1.0 / (2.0 * s.j_a_free));
                x[W_A] += impulse / (2.0 * s.j_a_free);
                x[W_A + SIDE] += impulse / (2.0 * s.j_a_free);
                x[W_M] = Self::case_speed(x);
                self.free = false;
            }
        } else {
            let x_now = *x;
            let dx = self.deriv(c, t_ns, &x_now, self.cmd_rpm);
            let accel = 0.5 * (dx[W_A] + dx[W_A + SIDE]);
            let (t_motor, _) = self.pid(&x_now, self.cmd_rpm, false);
            let mesh = s.gear * t_motor - s.j_m * accel;
            if self.flank * mesh < -SEPARATION_NM {
                self.free = true;
                self.x[W_M] = w_case;
                self.x[GAP] = self.flank * s.half_gap;
            }
        }
    }

    /// Mechanical power [W] the mapped friction and load motors absorb at the load-side
    /// speeds (nominal maps: what the SuT power map was identified with).
    fn absorbed_power(&self, sp: &SetPoints) -> f64 {
        let mut absorbed = 0.0;
        for side in 0..2 {
            let w_l = self.x[side * SIDE + W_L];
            let friction = self.tab.friction[side].at(w_l * RPM_PER_RAD_S);
            absorbed += (friction + self.load_torque(side, sp, w_l)) * w_l;
        }
        absorbed
    }

    /// Electrics at the end of a step: the power maps through their ramp limiters, the
    /// SuT's unmapped power, then supply, connector and DC link.
    fn electrics(&mut self, sp: &SetPoints, h: f64) {
        let s = &self.s;
        let load_mean = 0.5 * (sp.load[0] + sp.load[1]);
        let sut_target = self.tab.sut_power.at(sp.throttle, load_mean);
        self.p_sut = ramp_towards(self.p_sut, sut_target, s.sut_power_rate * h);
        let absorbed = self.absorbed_power(sp);
        self.p_mech_ref = ramp_towards(self.p_mech_ref, absorbed, s.sut_power_rate * h);
        for side in 0..2 {
            let target = self.tab.load_power[side].at(sp.throttle, sp.load[side]);
            self.p_load[side] = ramp_towards(self.p_load[side], target, s.load_power_rate * h);
        }
        // Power the maps do not cover, through the drive's efficiency.
        let (t_motor, _) = self.pid(&self.x, self.cmd_rpm, self.free);
        let p_mech = t_motor * self.motor_speed(&self.x, self.free) - self.p_mech_ref;
        let p_unmapped = if p_mech > 0.0 { p_mech / s.sut_efficiency } else { p_mech * s.sut_efficiency };
        let regen = |p: f64| if p < 0.0 { p * (1.0 - f64::from(self.fx.regen_loss)) } else { p };
        let p_sut = regen(self.p_sut + p_unmapped);
        let p_load = [regen(self.p_load[0]), regen(self.p_load[1])];
        match self.elec.step(p_sut, p_load, self.x[THETA], h) {
            Some(out) => self.out = out,
            None => self.collapsed_at_us = self.collapsed_at_us.or(Some(self.t_us())),
        }
    }

    /// Outputs at the current time, in the bench's channels, with each sensor's gain and
    /// offset (`sensor_gain`, `sensor_offset`); the lag and delay of the chain act on the
    /// series ([`Plant::run_logged`]).
    pub fn sample(&self) -> Sample {
        let s = &self.s;
        let x = &self.x;
        let flange = |o: usize| s.k_f * x[o + PHI_AF] + s.c_f * (x[o + W_A] - x[o + W_F]);
        let e = &self.out;
        // The set point held over the interval that ends now (left limit).
        let t_ns = self.t_ns();
        let seg = self.profile.segment_at(i128::from(t_ns) - 1);
        let throttle = self.profile.at(seg, t_ns as f64).throttle;
        let mut values = CHANNELS.map(|c| match c {
            Channel::Throttle => (throttle.abs() * s.volts_per_pct).clamp(0.0, 5.0),
            Channel::SuTMotorEnc => self.motor_speed(x, self.free) * RPM_PER_RAD_S,
            Channel::CKistlerL => flange(0),
            Channel::CKistlerR => flange(SIDE),
            Channel::TKistlerL => x[W_F] * RPM_PER_RAD_S,
            Channel::TKistlerR => x[SIDE + W_F] * RPM_PER_RAD_S,
            Channel::SiemensEnc => x[SIDE + W_L] * RPM_PER_RAD_S,
            Channel::IXlml22 | Channel::IXlmlBu1 => 0.5 * e.i_load[0],
            Channel::IXlmr23 => 0.5 * e.i_load[1],
            Channel::IDpu27 => e.i_dc + e.i_load[0] + e.i_load[1],
            Channel::VDcBusbars => e.v_b,
            Channel::IDc => e.i_dc,
            Channel::VDc => e.v_dc,
            Channel::SpeedCmd => self.cmd_rpm,
            _ => f64::NAN,
        });
        let fx = &self.fx;
        for (i, v) in values.iter_mut().take(MEASURED.len()).enumerate() {
            *v = *v * f64::from(fx.sensor_gain[i]) + f64::from(fx.sensor_offset[i]);
        }
        derive(&mut values);
        Sample { t_us: self.t_us(), values }
    }

    /// Set points [%] as the PLC logs them for the interval `(t - every, t]`: the value
    /// it held from the interval's start.
    fn logged_setpoints(&self, every_us: u64) -> SetPoints {
        let t_ns = i128::from(self.t_ns()) - i128::from(every_us) * 1000;
        self.profile.value(t_ns)
    }

    /// Advance by `us` [µs] (a multiple of the step).
    pub fn advance_us(&mut self, us: u64) -> Result<(), SetupError> {
        let ns = us * 1000;
        if !ns.is_multiple_of(self.h_ns) {
            return Err(SetupError::Step(format!("{us} µs is not a multiple of the plant's step")));
        }
        for _ in 0..ns / self.h_ns {
            self.step();
        }
        Ok(())
    }

    /// Run to the end of the profile; a sample every `every_us` [µs] (a multiple of the
    /// step), the first at `every_us`, with the set points the PLC held over each
    /// interval. Non-finite values are an error naming the time and channel.
    pub fn run_logged(mut self, every_us: u64) -> Result<(Vec<Sample>, Vec<SetPoints>), SetupError> {
        if every_us == 0 || !(every_us * 1000).is_multiple_of(self.h_ns) {
            return Err(SetupError::Step(format!(
                "output interval {every_us} µs is not a positive multiple of the plant's step"
            )));
        }
        let end_us = self.duration_us();
        let n = (end_us / every_us) as usize;
        let (mut out, mut sps) = (Vec::with_capacity(n), Vec::with_capacity(n));
        while self.t_us() + every_us <= end_us {
            self.advance_us(every_us)?;
            if let Some(t) = self.collapsed_at_us {
                return Err(SetupError::Step(format!(
                    "the supply collapsed at t = {:.6} s: no busbar or DC-link voltage carries the \
                     draw (supply_resistance, supply_current_limit, or the connector's resistance \
                     and its drift behind dc_link, too large for this test)",
                    t as f64 * 1e-6
                )));
            }
            let sample = self.sample();
            if let Some(i) = sample.values.iter().position(|v| !v.is_finite()) {
                return Err(SetupError::Step(format!(
                    "the plant diverged: {} is {} at t = {:.6} s",
                    CHANNELS[i].name(),
                    sample.values[i],
                    sample.t_us as f64 * 1e-6
                )));
            }
            out.push(sample);
            sps.push(self.logged_setpoints(every_us));
        }
        lag_and_delay(&mut out, &self.fx, every_us as f64 * 1e-6);
        Ok((out, sps))
    }

    /// [`Plant::run_logged`] without the set points.
    pub fn run(self, every_us: u64) -> Result<Vec<Sample>, SetupError> {
        self.run_logged(every_us).map(|(s, _)| s)
    }
}

/// The derived channels from the measured ones, as the thesis computes them from the
/// recorded channels (5.13).
fn derive(values: &mut [f64; CHANNELS.len()]) {
    let m = |c: Channel| CHANNELS.iter().position(|&k| k == c).map_or(f64::NAN, |i| values[i]);
    let v_b = m(Channel::VDcBusbars);
    let powers = [
        (Channel::PSutInv, m(Channel::VDc) * m(Channel::IDc)),
        (Channel::PLml, (m(Channel::IXlml22) + m(Channel::IXlmlBu1)) * v_b),
        (Channel::PLmr, 2.0 * m(Channel::IXlmr23) * v_b),
        (Channel::PDpu, v_b * m(Channel::IDpu27)),
    ];
    for (c, v) in powers {
        if let Some(i) = CHANNELS.iter().position(|&k| k == c) {
            values[i] = v;
        }
    }
}

/// The chain's lag and delay (`sensor_lag`, `sensor_delay`) on each measured channel's
/// series sampled every `dt` [s], from rest at its first value, then the derived channels
/// again.
fn lag_and_delay(out: &mut [Sample], fx: &Effects, dt: f64) {
    let mut changed = false;
    for (i, (tau, d)) in fx.sensor_lag_s.iter().zip(fx.sensor_delay_s).enumerate() {
        if *tau == 0.0 && d == 0.0 {
            continue;
        }
        changed = true;
        let mut x: Vec<f64> = out.iter().map(|s| s.values[i]).collect();
        first_order_lag(&mut x, dt, f64::from(*tau));
        if d > 0.0 {
            x = fractional_delay(&x, f64::from(d) / dt);
        }
        for (s, v) in out.iter_mut().zip(x) {
            s.values[i] = v;
        }
    }
    if changed {
        out.iter_mut().for_each(|s| derive(&mut s.values));
    }
}

/// [ns] the step `simrod bench` runs the plant at (at most): `ω h = 0.25` on the
/// 2 kHz flange mode, where RK4's error is still ~1e-7 of the span, a thousandth of
/// the twin's at 1 ms (`host-tests/tests/reference_accuracy.rs` checks 10 µs vs 5 µs).
pub const BENCH_STEP_NS: u64 = 20_000;

/// The largest plant step [ns] at most `max_ns` that divides `every_us` [µs] evenly.
pub fn step_for(every_us: u64, max_ns: u64) -> u64 {
    let every_ns = every_us.max(1) * 1000;
    let parts = every_ns.div_ceil(max_ns.max(1));
    (parts..=every_ns).find(|p| every_ns.is_multiple_of(*p)).map_or(every_ns, |p| every_ns / p)
}
