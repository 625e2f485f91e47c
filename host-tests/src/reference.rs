//! An independent, high-accuracy simulation of the twin's continuous model, to measure
//! how far `model-core`'s fixed-step discretization is from the model it discretizes.
//!
//! Written plainly, in f64, from the model description (`MODEL.md` and the documented
//! semantics of each block), sharing nothing with `model-core` but its data: the scalar
//! parameters ([`Params::thesis`]), the maps ([`Maps::builtin`], interpolated here with
//! our own code) and the profile sets ([`Builtin::sets`]).
//!
//! What "the same continuous model" means here, block by block:
//! - **Set points**: piecewise constant or linear in time, exactly as the profile defines
//!   them; a step at a set boundary applies from that instant on.
//! - **Curtis rate logic**: the speed command is a continuous ramp towards the target at
//!   the rate the switching logic picks; it stops on the target (and then follows it, as
//!   long as the target moves slower than the ramp).
//! - **PID**: continuous; the integrator and the derivative filter are ODE states;
//!   conditional-integration anti-windup freezes the integrator while saturated.
//! - **Mechanics**: the five ODEs per half shaft, with the motor torque, the friction map
//!   and the load torque evaluated continuously (no hold).
//! - **Electrics**: maps of the set points through continuous ramp limiters; the SuT
//!   inverter also draws the mechanical power its map does not cover (accelerating
//!   inertias), through the drive efficiency; then the connector in closed form.
//!
//! Integration: classical RK4 on the ODE states with a fixed step `h` (10 µs resolves
//! the ~2 kHz flange mode with `ω h ≈ 0.12`). The ramps (speed command, powers) are
//! advanced exactly over each step with their rate and target taken at the step; that is
//! first-order in `h` only for the slow HS/LS rate variation with speed and at switching
//! instants, an error of order `rate · h` (~0.01 rpm), far below what is measured.
//! Convergence is checked by halving `h` (see `tests/reference_accuracy.rs`).
//! Only the thesis model is covered (`Effects::NONE`, map speed target).

use std::cell::Cell;

use model_core::table::{Table1, Table2};
use model_core::{Builtin, Channel, CouplingStiffness, Maps, Params, RateSet, SetMode};

const RPM_PER_RAD_S: f64 = 30.0 / std::f64::consts::PI;
const RAD_S_PER_RPM: f64 = std::f64::consts::PI / 30.0;

/// The channels the reference produces, in the order of [`Sample::values`].
pub const CHANNELS: [Channel; 14] = [
    Channel::SuTMotorEnc,
    Channel::CKistlerL,
    Channel::CKistlerR,
    Channel::TKistlerL,
    Channel::TKistlerR,
    Channel::SiemensEnc,
    Channel::PSutInv,
    Channel::PLml,
    Channel::PLmr,
    Channel::PDpu,
    Channel::IDpu27,
    Channel::IDc,
    Channel::VDc,
    Channel::SpeedCmd,
];

/// One output sample.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    /// [µs] sample time.
    pub t_us: u64,
    /// Values of [`CHANNELS`], in the bench's units.
    pub values: [f64; CHANNELS.len()],
}

impl Sample {
    /// Value of a channel, `None` if the reference does not produce it.
    pub fn get(&self, c: Channel) -> Option<f64> {
        let i = CHANNELS.iter().position(|&k| k == c)?;
        self.values.get(i).copied()
    }
}

/// What to simulate: a built-in profile, its scaling, the Curtis rate set and the supply.
#[derive(Debug, Clone, Copy)]
pub struct Case {
    pub profile: Builtin,
    pub throttle_scale: f32,
    pub load_scale: f32,
    pub rates: RateSet,
    /// [V] DPU voltage.
    pub supply_v: f64,
}

// ---------------------------------------------------------------------------------
// Tables: piecewise linear (1-D) and bilinear (2-D) in f64, edges clamped.

/// A strictly increasing grid that remembers the last interval it found: queries move
/// slowly from one evaluation to the next, so the search starts there (a plain binary
/// search per lookup was most of the reference's run time).
struct Grid {
    x: Vec<f64>,
    last: Cell<usize>,
}

impl Grid {
    fn new(x: &[f32]) -> Self {
        Self { x: x.iter().map(|&v| f64::from(v)).collect(), last: Cell::new(0) }
    }

    /// Interval `i` and fraction `f` with `q = x[i] + f (x[i+1] - x[i])`, clamped to the
    /// grid.
    fn locate(&self, q: f64) -> (usize, f64) {
        let x = &self.x;
        let n = x.len();
        if q <= x[0] {
            return (0, 0.0);
        }
        if q >= x[n - 1] {
            return (n - 2, 1.0);
        }
        // x[0] < q < x[n-1]: walk from the last interval to the one with x[i] <= q < x[i+1].
        let mut i = self.last.get().min(n - 2);
        while q < x[i] {
            i -= 1;
        }
        while q >= x[i + 1] {
            i += 1;
        }
        self.last.set(i);
        (i, (q - x[i]) / (x[i + 1] - x[i]))
    }
}

struct Lut1 {
    x: Grid,
    y: Vec<f64>,
}

impl Lut1 {
    fn new(t: &Table1<'_>) -> Self {
        Self { x: Grid::new(t.x()), y: t.y().iter().map(|&v| f64::from(v)).collect() }
    }

    fn at(&self, q: f64) -> f64 {
        let (i, f) = self.x.locate(q);
        self.y[i] + f * (self.y[i + 1] - self.y[i])
    }
}

/// `z(x, y)` with x the throttle set point and y the load set point; `z` row-major by y.
struct Lut2 {
    x: Grid,
    y: Grid,
    z: Vec<f64>,
}

impl Lut2 {
    fn new(t: &Table2<'_>) -> Self {
        Self { x: Grid::new(t.x()), y: Grid::new(t.y()), z: t.z().iter().map(|&v| f64::from(v)).collect() }
    }

    fn at(&self, qx: f64, qy: f64) -> f64 {
        let nx = self.x.x.len();
        let (ix, fx) = self.x.locate(qx);
        let (iy, fy) = self.y.locate(qy);
        let z = |r: usize, c: usize| self.z[r * nx + c];
        let lo = z(iy, ix) + fx * (z(iy, ix + 1) - z(iy, ix));
        let hi = z(iy + 1, ix) + fx * (z(iy + 1, ix + 1) - z(iy + 1, ix));
        lo + fy * (hi - lo)
    }
}

// ---------------------------------------------------------------------------------
// Test profile.

struct Segment {
    /// [ns] start and duration: integers, so set boundaries fall exactly on step times.
    start_ns: u64,
    duration_ns: u64,
    throttle: (f64, f64, SetMode),
    load: [(f64, f64, SetMode); 2],
}

/// A profile as functions of time, scaled and clamped like the PLC does.
struct TimeProfile {
    segments: Vec<Segment>,
    throttle_scale: f64,
    load_scale: f64,
}

/// Set points [%] at one instant: throttle (+ forward), loads (+ regenerating).
#[derive(Clone, Copy)]
struct SetPoints {
    throttle: f64,
    load: [f64; 2],
}

impl TimeProfile {
    fn new(case: &Case) -> Self {
        let sets = case.profile.sets();
        let mut segments = Vec::new();
        let mut start_ns = 0;
        for (i, s) in sets.iter().enumerate() {
            // After the last set, interpolation runs to zero.
            let next = sets.get(i + 1);
            let nt = next.map_or(0.0, |n| f64::from(n.throttle_pct));
            let nl = next.map_or(0.0, |n| f64::from(n.load_l_pct));
            let nr = next.map_or(0.0, |n| f64::from(n.load_r_pct));
            let duration_ns = (f64::from(s.duration_s) * 1e9).round() as u64;
            segments.push(Segment {
                start_ns,
                duration_ns,
                throttle: (f64::from(s.throttle_pct), nt, s.throttle_mode),
                load: [
                    (f64::from(s.load_l_pct), nl, s.load_mode),
                    (f64::from(s.load_r_pct), nr, s.load_mode),
                ],
            });
            start_ns += duration_ns;
        }
        Self {
            segments,
            throttle_scale: f64::from(case.throttle_scale),
            load_scale: f64::from(case.load_scale),
        }
    }

    fn duration_ns(&self) -> u64 {
        self.segments.last().map_or(0, |s| s.start_ns + s.duration_ns)
    }

    /// Index of the segment that contains `t_ns` (the last one at or beyond the end).
    fn segment_at(&self, t_ns: u64) -> usize {
        let mut k = 0;
        while k + 1 < self.segments.len() && t_ns >= self.segments[k + 1].start_ns {
            k += 1;
        }
        k
    }

    /// Set points at `t_ns` as segment `k` defines them: at the end of the segment this
    /// is the left limit, so an integration step that starts inside `k` never sees the
    /// next set's jump. `t_ns` may be fractional (RK4 stages).
    fn at(&self, k: usize, t_ns: f64) -> SetPoints {
        let s = &self.segments[k];
        let frac = ((t_ns - s.start_ns as f64) / s.duration_ns as f64).clamp(0.0, 1.0);
        let value = |(a, b, mode): (f64, f64, SetMode)| match mode {
            SetMode::Hold => a,
            SetMode::Interpolate => a + frac * (b - a),
        };
        let clamp = |v: f64| v.clamp(-100.0, 100.0);
        SetPoints {
            throttle: clamp(value(s.throttle) * self.throttle_scale),
            load: [clamp(value(s.load[0]) * self.load_scale), clamp(value(s.load[1]) * self.load_scale)],
        }
    }
}

// ---------------------------------------------------------------------------------
// The model.

/// Scalars in f64, axle frame unless named `motor`.
struct Scalars {
    volts_per_pct: f64,
    typical_max_rpm: f64,
    speed_limit_rpm: [f64; 2],
    full_throttle_pct: f64,
    low_throttle_pct: f64,
    /// Per direction [fwd, rev]: hs %, ls %, accel hs/ls s, low accel s,
    /// neutral decel hs/ls s, partial decel s.
    rates: [[f64; 8]; 2],
    kp: f64,
    ki: f64,
    kd: f64,
    d_filter_s: f64,
    torque_max_motor: f64,
    power_max: f64,
    gear: f64,
    j_a: f64,
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
    r_conn: f64,
    sut_efficiency: f64,
    sut_power_rate: f64,
    load_power_rate: f64,
}

impl Scalars {
    fn new(p: &Params) -> Self {
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
        Self {
            volts_per_pct: f(p.throttle_volts_per_pct),
            typical_max_rpm: f(p.typical_max_speed_rpm),
            speed_limit_rpm: [f(p.speed_limit_rpm[0]), f(p.speed_limit_rpm[1])],
            full_throttle_pct: f(p.full_throttle_pct),
            low_throttle_pct: f(p.low_throttle_pct),
            rates: [dir(0), dir(1)],
            kp: f(p.pid_kp),
            ki: f(p.pid_ki),
            kd: f(p.pid_kd),
            d_filter_s: f(p.pid_d_filter_s),
            torque_max_motor: f(p.motor_torque_max_nm),
            power_max: f(p.motor_power_max_w),
            gear: f(p.sut_gear_ratio),
            j_a: 0.5 * f(p.sut_inertia),
            j_f: f(p.flange_inertia),
            j_l: [f(p.load_inertia[0]), f(p.load_inertia[1])],
            k_f: f(p.flange_stiffness),
            c_f: f(p.flange_damping),
            k_c: f(p.coupling_stiffness),
            c_c: f(p.coupling_damping),
            regen_fade_rad_s: f(p.regen_fade_rpm) * RAD_S_PER_RPM,
            load_gear: f(p.load_gear_ratio),
            load_base_rpm: f(p.load_base_rpm),
            load_no_load_rpm: f(p.load_no_load_rpm),
            r_conn: f(p.connector_resistance),
            sut_efficiency: f(p.sut_drive_efficiency),
            sut_power_rate: f(p.sut_power_rate_w_per_s),
            load_power_rate: f(p.load_power_rate_w_per_s),
        }
    }
}

struct Tables {
    throttle_input: Lut1,
    speed: [Lut1; 2],
    friction: [Lut1; 2],
    load_torque: [Lut2; 2],
    load_power: [Lut2; 2],
    sut_power: Lut2,
}

impl Tables {
    fn new(m: &Maps<'_>) -> Self {
        Self {
            throttle_input: Lut1::new(&m.throttle_input),
            speed: [Lut1::new(&m.speed_fwd), Lut1::new(&m.speed_rev)],
            friction: [Lut1::new(&m.friction[0]), Lut1::new(&m.friction[1])],
            load_torque: [Lut2::new(&m.load_torque[0]), Lut2::new(&m.load_torque[1])],
            load_power: [Lut2::new(&m.load_power[0]), Lut2::new(&m.load_power[1])],
            sut_power: Lut2::new(&m.sut_power),
        }
    }
}

// ODE state layout: per side (L at 0, R at SIDE) ω_a, ω_f, ω_l [rad/s], flange twist,
// coupling twist [rad]; then the PID integrator [N m, motor frame] and the derivative
// filter's output (filtered motor speed [rad/s]).
const W_A: usize = 0;
const W_F: usize = 1;
const W_L: usize = 2;
const PHI_AF: usize = 3;
const PHI_FL: usize = 4;
const SIDE: usize = 5;
const INTEG: usize = 10;
const SPEED_FILT: usize = 11;
const NX: usize = 12;

type X = [f64; NX];

/// The reference simulation.
pub struct Reference {
    s: Scalars,
    tab: Tables,
    profile: TimeProfile,
    supply_v: f64,
    /// Step [ns].
    h_ns: u64,
    steps_done: u64,
    x: X,
    /// [rpm] motor speed command (continuous ramp).
    cmd_rpm: f64,
    /// [W] rate-limited SuT inverter and load powers.
    p_sut: f64,
    /// Absorbed mechanical power, through the SuT power ramp limiter.
    p_mech_ref: f64,
    p_load: [f64; 2],
}

fn ramp_towards(y: f64, target: f64, max_change: f64) -> f64 {
    y + (target - y).clamp(-max_change, max_change)
}

impl Reference {
    /// A reference at rest at t = 0, integrating with step `h_ns` [ns].
    pub fn new(case: &Case, h_ns: u64) -> Self {
        assert!(h_ns > 0, "step must be positive");
        let p = Params::thesis(case.rates, CouplingStiffness::Identified);
        Self {
            s: Scalars::new(&p),
            tab: Tables::new(&Maps::builtin()),
            profile: TimeProfile::new(case),
            supply_v: case.supply_v,
            h_ns,
            steps_done: 0,
            x: [0.0; NX],
            cmd_rpm: 0.0,
            p_sut: 0.0,
            p_mech_ref: 0.0,
            p_load: [0.0; 2],
        }
    }

    /// Profile duration [µs].
    pub fn duration_us(&self) -> u64 {
        self.profile.duration_ns() / 1000
    }

    /// Mapped throttle [%] and signed target motor speed [rpm] for a throttle set point.
    fn throttle_chain(&self, throttle_sp: f64) -> (f64, f64) {
        let volts = (throttle_sp.abs() * self.s.volts_per_pct).clamp(0.0, 5.0);
        let mapped = self.tab.throttle_input.at(volts);
        let reverse = throttle_sp < 0.0;
        let d = usize::from(reverse);
        let mag = self.tab.speed[d].at(mapped).clamp(0.0, self.s.speed_limit_rpm[d]);
        (mapped, if reverse { -mag } else { mag })
    }

    /// Curtis ramp rate [rpm/s] (MODEL.md, signal chain step 4).
    fn curtis_rate(&self, mapped: f64, target: f64, cmd: f64, speed_rpm: f64) -> f64 {
        if target == cmd {
            return 0.0;
        }
        let s = &self.s;
        let moving = if cmd != 0.0 { cmd } else { target };
        let r = &s.rates[usize::from(moving < 0.0)];
        let (hs_pct, ls_pct) = (r[0], r[1]);
        let per_s = |seconds: f64| {
            if seconds > 0.0 {
                s.typical_max_rpm / seconds
            } else {
                0.0
            }
        };
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
            if mapped >= s.full_throttle_pct {
                accel
            } else if mapped <= s.low_throttle_pct {
                low
            } else {
                let f = (mapped - s.low_throttle_pct) / (s.full_throttle_pct - s.low_throttle_pct);
                low + f * (accel - low)
            }
        } else if mapped <= 0.0 {
            blend(r[5], r[6])
        } else {
            per_s(r[7])
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

    fn motor_speed(&self, x: &X) -> f64 {
        self.s.gear * 0.5 * (x[W_A] + x[W_A + SIDE])
    }

    /// PID: motor torque [N m] and whether the integrator is frozen (saturated and the
    /// error pushing further out).
    fn pid(&self, x: &X, cmd_rpm: f64) -> (f64, bool) {
        let s = &self.s;
        let w_m = self.motor_speed(x);
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
            map * (w_l / s.regen_fade_rad_s).clamp(-1.0, 1.0)
        } else {
            let drive_dir = if sp.throttle < 0.0 { -1.0 } else { 1.0 };
            let motor_rpm_along = w_l * drive_dir * s.load_gear * RPM_PER_RAD_S;
            let envelope = ((s.load_no_load_rpm - motor_rpm_along) / (s.load_no_load_rpm - s.load_base_rpm))
                .clamp(0.0, 1.0);
            map * drive_dir * envelope
        }
    }

    /// Mechanical power [W] the mapped friction and load motors absorb at the load-side
    /// speeds.
    fn absorbed_power(&self, sp: &SetPoints) -> f64 {
        let x = &self.x;
        let mut absorbed = 0.0;
        for side in 0..2 {
            let w_l = x[side * SIDE + W_L];
            let friction = self.tab.friction[side].at(w_l * RPM_PER_RAD_S);
            absorbed += (friction + self.load_torque(side, sp, w_l)) * w_l;
        }
        absorbed
    }

    /// Electrical power [W] the SuT inverter draws beyond its map: the mechanical power
    /// the motor delivers minus the absorbed power (followed through the map's ramp
    /// limiter, so map and reference move together), through the drive's efficiency.
    fn unmapped_power(&self, _sp: &SetPoints) -> f64 {
        let x = &self.x;
        let (t_motor, _) = self.pid(x, self.cmd_rpm);
        let p_mech = t_motor * self.motor_speed(x) - self.p_mech_ref;
        if p_mech > 0.0 {
            p_mech / self.s.sut_efficiency
        } else {
            p_mech * self.s.sut_efficiency
        }
    }

    /// Time derivative of the ODE state at `t_ns`, set points from segment `k`.
    fn deriv(&self, k: usize, t_ns: f64, x: &X, cmd_rpm: f64) -> X {
        let s = &self.s;
        let sp = self.profile.at(k, t_ns);
        let mut dx = [0.0; NX];

        let w_m = self.motor_speed(x);
        let (t_motor, frozen) = self.pid(x, cmd_rpm);
        dx[INTEG] = if frozen { 0.0 } else { s.ki * (cmd_rpm * RAD_S_PER_RPM - w_m) };
        dx[SPEED_FILT] = (w_m - x[SPEED_FILT]) / s.d_filter_s;

        // Gearbox, then the open differential splits the torque equally.
        let t_in = 0.5 * s.gear * t_motor;
        for side in 0..2 {
            let o = side * SIDE;
            let (w_a, w_f, w_l) = (x[o + W_A], x[o + W_F], x[o + W_L]);
            let t_flange = s.k_f * x[o + PHI_AF] + s.c_f * (w_a - w_f);
            let t_coupling = s.k_c * x[o + PHI_FL] + s.c_c * (w_f - w_l);
            let friction = self.tab.friction[side].at(w_l * RPM_PER_RAD_S);
            let t_load = self.load_torque(side, &sp, w_l);
            dx[o + W_A] = (t_in - t_flange) / s.j_a;
            dx[o + W_F] = (t_flange - t_coupling) / s.j_f;
            dx[o + W_L] = (t_coupling - friction - t_load) / s.j_l[side];
            dx[o + PHI_AF] = w_a - w_f;
            dx[o + PHI_FL] = w_f - w_l;
        }
        dx
    }

    /// Advance one step of `h`.
    fn step(&mut self) {
        let h = self.h_ns as f64 * 1e-9;
        let t0_ns = self.steps_done * self.h_ns;
        let (t0, h_ns) = (t0_ns as f64, self.h_ns as f64);
        let k = self.profile.segment_at(t0_ns);
        let sp_end = self.profile.at(k, t0 + h_ns);

        // Speed command: ramp towards the target at the Curtis rate, stopping on it.
        let (mapped, target) = self.throttle_chain(sp_end.throttle);
        let speed_rpm = self.motor_speed(&self.x) * RPM_PER_RAD_S;
        let rate = self.curtis_rate(mapped, target, self.cmd_rpm, speed_rpm);
        let cmd0 = self.cmd_rpm;
        let cmd_at = |frac: f64| ramp_towards(cmd0, target, rate * frac * h);

        // RK4 on the mechanics and the controller states.
        let x0 = self.x;
        let add = |a: &X, b: &X, c: f64| {
            let mut r = *a;
            for (ri, bi) in r.iter_mut().zip(b.iter()) {
                *ri += c * bi;
            }
            r
        };
        let k1 = self.deriv(k, t0, &x0, cmd_at(0.0));
        let k2 = self.deriv(k, t0 + 0.5 * h_ns, &add(&x0, &k1, 0.5 * h), cmd_at(0.5));
        let k3 = self.deriv(k, t0 + 0.5 * h_ns, &add(&x0, &k2, 0.5 * h), cmd_at(0.5));
        let k4 = self.deriv(k, t0 + h_ns, &add(&x0, &k3, h), cmd_at(1.0));
        for i in 0..NX {
            self.x[i] = x0[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        self.cmd_rpm = cmd_at(1.0);

        // Anti-windup: while integrating, the integrator stays within the torque limit.
        let (_, frozen) = self.pid(&self.x, self.cmd_rpm);
        if !frozen {
            let lim = self.torque_limit(self.motor_speed(&self.x));
            self.x[INTEG] = self.x[INTEG].clamp(-lim, lim);
        }

        // Electrics: power maps through ramp limiters (the SuT's unmapped power is added
        // when sampling, it is algebraic).
        let load_mean = 0.5 * (sp_end.load[0] + sp_end.load[1]);
        let sut_target = self.tab.sut_power.at(sp_end.throttle, load_mean);
        self.p_sut = ramp_towards(self.p_sut, sut_target, self.s.sut_power_rate * h);
        let absorbed = self.absorbed_power(&sp_end);
        self.p_mech_ref = ramp_towards(self.p_mech_ref, absorbed, self.s.sut_power_rate * h);
        for side in 0..2 {
            let target = self.tab.load_power[side].at(sp_end.throttle, sp_end.load[side]);
            self.p_load[side] = ramp_towards(self.p_load[side], target, self.s.load_power_rate * h);
        }
        self.steps_done += 1;
    }

    /// Time reached [µs].
    pub fn t_us(&self) -> u64 {
        self.steps_done * self.h_ns / 1000
    }

    /// Outputs at the current time, in the bench's channels.
    pub fn sample(&self) -> Sample {
        let s = &self.s;
        let x = &self.x;
        let t_us = self.t_us();
        let flange = |o: usize| s.k_f * x[o + PHI_AF] + s.c_f * (x[o + W_A] - x[o + W_F]);

        // Connector: the inverter draws P through R from the busbars at V_b:
        // R i^2 - V_b i + P = 0, smaller root (written without cancellation), the draw
        // capped at 95 % of the most the connector can pass.
        let t_ns = self.steps_done * self.h_ns;
        let sp = self.profile.at(self.profile.segment_at(t_ns.saturating_sub(1)), t_ns as f64);
        let p_sut = self.p_sut + self.unmapped_power(&sp);
        let v_b = self.supply_v;
        let r = s.r_conn;
        let p = p_sut.min(0.95 * v_b * v_b / (4.0 * r));
        let i_dc = 2.0 * p / (v_b + (v_b * v_b - 4.0 * r * p).sqrt());
        let v_dc = v_b - r * i_dc;
        let i_load = [self.p_load[0] / v_b, self.p_load[1] / v_b];
        let i_dpu = i_dc + i_load[0] + i_load[1];

        let values = CHANNELS.map(|c| match c {
            Channel::SuTMotorEnc => self.motor_speed(x) * RPM_PER_RAD_S,
            Channel::CKistlerL => flange(0),
            Channel::CKistlerR => flange(SIDE),
            Channel::TKistlerL => x[W_F] * RPM_PER_RAD_S,
            Channel::TKistlerR => x[SIDE + W_F] * RPM_PER_RAD_S,
            Channel::SiemensEnc => x[SIDE + W_L] * RPM_PER_RAD_S,
            Channel::PSutInv => v_dc * i_dc,
            Channel::PLml => i_load[0] * v_b,
            Channel::PLmr => i_load[1] * v_b,
            Channel::PDpu => v_b * i_dpu,
            Channel::IDpu27 => i_dpu,
            Channel::IDc => i_dc,
            Channel::VDc => v_dc,
            Channel::SpeedCmd => self.cmd_rpm,
            _ => f64::NAN,
        });
        Sample { t_us, values }
    }

    /// Advance by `us` [µs] (a multiple of the step).
    pub fn advance_us(&mut self, us: u64) {
        let ns = us * 1000;
        assert_eq!(ns % self.h_ns, 0, "advance by a multiple of the step");
        for _ in 0..ns / self.h_ns {
            self.step();
        }
    }

    /// Run to the end of the profile; a sample every `every_us` [µs] (a multiple of the
    /// step), the first at `every_us`, as the twin emits its outputs at the end of each
    /// step.
    pub fn run(mut self, every_us: u64) -> Vec<Sample> {
        let end_us = self.duration_us();
        let mut out = Vec::with_capacity((end_us / every_us) as usize);
        while self.t_us() + every_us <= end_us {
            self.advance_us(every_us);
            out.push(self.sample());
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_interpolate_and_clamp() {
        let t = Lut1 { x: Grid::new(&[0.0, 1.0, 3.0]), y: vec![0.0, 10.0, 30.0] };
        assert_eq!(t.at(-1.0), 0.0);
        assert_eq!(t.at(2.0), 20.0);
        assert_eq!(t.at(0.5), 5.0); // searching down from the last interval
        assert_eq!(t.at(1.0), 10.0);
        assert_eq!(t.at(9.0), 30.0);
        // z = 2x + 3y is reproduced by bilinear interpolation.
        let t2 = Lut2 {
            x: Grid::new(&[0.0, 1.0, 4.0]),
            y: Grid::new(&[-1.0, 2.0]),
            z: vec![-3.0, -1.0, 5.0, 6.0, 8.0, 14.0],
        };
        assert!((t2.at(2.0, 0.5) - 5.5).abs() < 1e-12);
    }

    #[test]
    fn steady_state_balances_the_shaft_torques() {
        // End of TP12's 100 % plateau (t = 16 s): the command is at the 2100 rpm limit,
        // and on each side the flange carries what the load node takes: the friction map
        // at the side's own speed (the open differential lets them differ) plus the load
        // map's torque at load set point 0 (2 N m regenerating at full throttle).
        let case = Case {
            profile: Builtin::TP12,
            throttle_scale: 1.0,
            load_scale: 0.0,
            rates: RateSet::Identified,
            supply_v: 24.0,
        };
        let out = Reference::new(&case, 20_000).run(100_000);
        let s = out.iter().find(|s| s.t_us == 16_000_000).unwrap();
        let speed = s.get(Channel::SuTMotorEnc).unwrap();
        assert!((speed - 2100.0).abs() < 0.01, "{speed}");
        let tab = Tables::new(&Maps::builtin());
        let sides =
            [(0, Channel::TKistlerL, Channel::CKistlerL), (1, Channel::TKistlerR, Channel::CKistlerR)];
        for (i, w, c) in sides {
            let want = tab.friction[i].at(s.get(w).unwrap()) + tab.load_torque[i].at(100.0, 0.0);
            let torque = s.get(c).unwrap();
            assert!((torque - want).abs() < 0.01, "side {i}: {torque} vs {want}");
        }
        // The open differential balances torque, not speed: L, with less friction at a
        // given speed, runs faster than R.
        let (l, r) = (s.get(Channel::TKistlerL).unwrap(), s.get(Channel::TKistlerR).unwrap());
        assert!(l > r + 1.0, "L {l} rpm, R {r} rpm");
    }
}
