//! Scalar parameters, with the thesis values (from `data/parameters.toml`) as defaults.

use crate::data as d;
use crate::num::Real;

/// Which Curtis rate parameter set drives the rate logic (thesis tables 5.16 / 5.17).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RateSet {
    /// What is programmed into the controller: what a user starts from.
    Programmed,
    /// What the bench was measured to do.
    Identified,
}

/// How the mapped throttle becomes a target speed (thesis 5.2.1 and 6.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SpeedTarget {
    /// Identified 1-D map (the thesis default, fig. 5.7).
    Map,
    /// Mapped fraction x Max Speed, then the measured limits (fig. 6.3).
    Parameter,
}

/// Which coupling stiffness (thesis table 5.10).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CouplingStiffness {
    /// 4369.434 N m/rad, identified.
    Identified,
    /// 10310 N m/rad, Flender datasheet.
    Datasheet,
}

/// Curtis rate parameters of one direction, in seconds per Typical Max Speed, and the
/// HS/LS thresholds in percent of Typical Max Speed.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DirectionRates<R = f32> {
    pub hs_pct: R,
    pub ls_pct: R,
    pub accel_hs_s: R,
    pub accel_ls_s: R,
    pub low_accel_s: R,
    pub neutral_decel_hs_s: R,
    pub neutral_decel_ls_s: R,
    pub partial_decel_s: R,
}

/// Rate parameters for both directions: `[forward, reverse]`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RateParams<R = f32> {
    pub dir: [DirectionRates<R>; 2],
}

impl RateParams {
    /// Table 5.16.
    pub const PROGRAMMED: Self = Self {
        dir: [
            DirectionRates {
                hs_pct: d::PROG_HS_FWD_PCT,
                ls_pct: d::PROG_LS_FWD_PCT,
                accel_hs_s: d::PROG_ACCEL_HS_FWD_S,
                accel_ls_s: d::PROG_ACCEL_LS_FWD_S,
                low_accel_s: d::PROG_LOW_ACCEL_FWD_S,
                neutral_decel_hs_s: d::PROG_NEUTRAL_DECEL_HS_FWD_S,
                neutral_decel_ls_s: d::PROG_NEUTRAL_DECEL_LS_FWD_S,
                partial_decel_s: d::PROG_PARTIAL_DECEL_FWD_S,
            },
            DirectionRates {
                hs_pct: d::PROG_HS_REV_PCT,
                ls_pct: d::PROG_LS_REV_PCT,
                accel_hs_s: d::PROG_ACCEL_HS_REV_S,
                accel_ls_s: d::PROG_ACCEL_LS_REV_S,
                low_accel_s: d::PROG_LOW_ACCEL_REV_S,
                neutral_decel_hs_s: d::PROG_NEUTRAL_DECEL_HS_REV_S,
                neutral_decel_ls_s: d::PROG_NEUTRAL_DECEL_LS_REV_S,
                partial_decel_s: d::PROG_PARTIAL_DECEL_REV_S,
            },
        ],
    };

    /// Table 5.17.
    pub const IDENTIFIED: Self = Self {
        dir: [
            DirectionRates {
                hs_pct: d::IDENT_HS_FWD_PCT,
                ls_pct: d::IDENT_LS_FWD_PCT,
                accel_hs_s: d::IDENT_ACCEL_HS_FWD_S,
                accel_ls_s: d::IDENT_ACCEL_LS_FWD_S,
                low_accel_s: d::IDENT_LOW_ACCEL_FWD_S,
                neutral_decel_hs_s: d::IDENT_NEUTRAL_DECEL_HS_FWD_S,
                neutral_decel_ls_s: d::IDENT_NEUTRAL_DECEL_LS_FWD_S,
                partial_decel_s: d::IDENT_PARTIAL_DECEL_FWD_S,
            },
            DirectionRates {
                hs_pct: d::IDENT_HS_REV_PCT,
                ls_pct: d::IDENT_LS_REV_PCT,
                accel_hs_s: d::IDENT_ACCEL_HS_REV_S,
                accel_ls_s: d::IDENT_ACCEL_LS_REV_S,
                low_accel_s: d::IDENT_LOW_ACCEL_REV_S,
                neutral_decel_hs_s: d::IDENT_NEUTRAL_DECEL_HS_REV_S,
                neutral_decel_ls_s: d::IDENT_NEUTRAL_DECEL_LS_REV_S,
                partial_decel_s: d::IDENT_PARTIAL_DECEL_REV_S,
            },
        ],
    };

    /// The set named by `which`.
    pub const fn of(which: RateSet) -> Self {
        match which {
            RateSet::Programmed => Self::PROGRAMMED,
            RateSet::Identified => Self::IDENTIFIED,
        }
    }
}

/// Every scalar of the model. Defaults come from `data/parameters.toml`; units in the
/// field docs; mechanical values in the axle frame unless named `motor`. The inertias,
/// stiffnesses and dampings are f32 in every instance: only the construction reads
/// them (the drivetrain's discretization, in f64), never the step.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Params<R: Real = f32> {
    /// [V/%] throttle volts per set-point percent (wide: 0.05 is not a multiple of a
    /// fixed-point signal's resolution to better than 2e-4).
    pub throttle_volts_per_pct: R::Wide,
    /// [rpm] Max Speed Fwd / Rev (parameter approach).
    pub max_speed_rpm: [R; 2],
    /// [rpm] Typical Max Speed: rates are normalised to it.
    pub typical_max_speed_rpm: R,
    /// [rpm] measured speed limits Fwd / Rev.
    pub speed_limit_rpm: [R; 2],
    /// [%] mapped throttle above which acceleration is "full throttle".
    pub full_throttle_pct: R,
    /// [%] mapped throttle below which acceleration is "low".
    pub low_throttle_pct: R,
    /// Curtis rates.
    pub rates: RateParams<R>,
    /// [N m/(rad/s)], [N m/rad], [N m s/rad] PID gains, motor frame.
    pub pid_kp: R,
    pub pid_ki: R,
    pub pid_kd: R,
    /// [s] derivative filter.
    pub pid_d_filter_s: R,
    /// [N m] motor torque limit, motor frame.
    pub motor_torque_max_nm: R,
    /// [W] motor mechanical power limit.
    pub motor_power_max_w: R,
    /// [-] SuT gearbox ratio (motor / axle speed).
    pub sut_gear_ratio: R,
    /// [-] load gearbox ratio (load motor / axle speed), reporting only.
    pub load_gear_ratio: R,
    /// [kg m^2] total SuT-side inertia, split in halves.
    pub sut_inertia: f32,
    /// [-] share of the SuT inertia on the motor side of the gear mesh (backlash only).
    pub sut_motor_inertia_share: f32,
    /// [kg m^2] load inertias L, R.
    pub load_inertia: [f32; 2],
    /// [kg m^2] torque flange inertia.
    pub flange_inertia: f32,
    /// [N m/rad] torque flange stiffness.
    pub flange_stiffness: f32,
    /// [N m s/rad] torque flange damping.
    pub flange_damping: f32,
    /// [N m/rad] flexible coupling stiffness.
    pub coupling_stiffness: f32,
    /// [N m s/rad] flexible coupling damping.
    pub coupling_damping: f32,
    /// [rpm] load motor shaft speed where its motoring torque has faded to zero
    /// (back-EMF reaches the supply): bounds what a motoring load can drive.
    pub load_no_load_rpm: R,
    /// [rpm] load motor shaft speed up to which the motoring torque is as mapped.
    pub load_base_rpm: R,
    /// [rpm] axle speed below which a regenerating load's torque fades out.
    pub regen_fade_rpm: R,
    /// [ohm] busbar-to-SuT-inverter connector resistance.
    pub connector_resistance: R,
    /// [-] SuT motor + inverter efficiency for power the maps do not cover.
    pub sut_drive_efficiency: R,
    /// [W/s] SuT inverter power rate limit.
    pub sut_power_rate_w_per_s: R,
    /// [W/s] load power rate limit.
    pub load_power_rate_w_per_s: R,
}

impl Params {
    /// The thesis values, with the given rate set and coupling stiffness.
    pub const fn thesis(rates: RateSet, coupling: CouplingStiffness) -> Self {
        Self {
            throttle_volts_per_pct: d::THROTTLE_VOLTS_PER_PCT,
            max_speed_rpm: [d::MAX_SPEED_FWD_RPM, d::MAX_SPEED_REV_RPM],
            typical_max_speed_rpm: d::TYPICAL_MAX_SPEED_RPM,
            speed_limit_rpm: [d::SPEED_LIMIT_FWD_RPM, d::SPEED_LIMIT_REV_RPM],
            full_throttle_pct: d::FULL_THROTTLE_PCT,
            low_throttle_pct: d::LOW_THROTTLE_PCT,
            rates: RateParams::of(rates),
            pid_kp: d::PID_KP,
            pid_ki: d::PID_KI,
            pid_kd: d::PID_KD,
            pid_d_filter_s: d::PID_D_FILTER_S,
            motor_torque_max_nm: d::MOTOR_TORQUE_MAX_NM,
            motor_power_max_w: d::MOTOR_POWER_MAX_W,
            sut_gear_ratio: d::SUT_GEAR_RATIO,
            load_gear_ratio: d::LOAD_GEAR_RATIO,
            sut_inertia: d::SUT_INERTIA,
            sut_motor_inertia_share: d::SUT_MOTOR_INERTIA_SHARE,
            load_inertia: [d::LOAD_INERTIA_L, d::LOAD_INERTIA_R],
            flange_inertia: d::FLANGE_INERTIA,
            flange_stiffness: d::FLANGE_STIFFNESS,
            flange_damping: d::FLANGE_DAMPING,
            coupling_stiffness: match coupling {
                CouplingStiffness::Identified => d::COUPLING_STIFFNESS_IDENTIFIED,
                CouplingStiffness::Datasheet => d::COUPLING_STIFFNESS_DATASHEET,
            },
            coupling_damping: d::COUPLING_DAMPING,
            load_no_load_rpm: d::LOAD_NO_LOAD_RPM,
            load_base_rpm: d::LOAD_BASE_RPM,
            regen_fade_rpm: d::REGEN_FADE_RPM,
            connector_resistance: d::CONNECTOR_RESISTANCE,
            sut_drive_efficiency: d::SUT_DRIVE_EFFICIENCY,
            sut_power_rate_w_per_s: d::SUT_POWER_RATE_W_PER_S,
            load_power_rate_w_per_s: d::LOAD_POWER_RATE_W_PER_S,
        }
    }
}

impl Params {
    /// The same parameters in the scalar `R` (each value the step reads [`Real::lit`]; for
    /// f32 itself).
    pub fn to<R: Real>(&self) -> Params<R> {
        Params {
            throttle_volts_per_pct: R::Wide::lit(self.throttle_volts_per_pct),
            max_speed_rpm: [R::lit(self.max_speed_rpm[0]), R::lit(self.max_speed_rpm[1])],
            typical_max_speed_rpm: R::lit(self.typical_max_speed_rpm),
            speed_limit_rpm: [R::lit(self.speed_limit_rpm[0]), R::lit(self.speed_limit_rpm[1])],
            full_throttle_pct: R::lit(self.full_throttle_pct),
            low_throttle_pct: R::lit(self.low_throttle_pct),
            rates: RateParams { dir: [self.rates.dir[0].to(), self.rates.dir[1].to()] },
            pid_kp: R::lit(self.pid_kp),
            pid_ki: R::lit(self.pid_ki),
            pid_kd: R::lit(self.pid_kd),
            pid_d_filter_s: R::lit(self.pid_d_filter_s),
            motor_torque_max_nm: R::lit(self.motor_torque_max_nm),
            motor_power_max_w: R::lit(self.motor_power_max_w),
            sut_gear_ratio: R::lit(self.sut_gear_ratio),
            load_gear_ratio: R::lit(self.load_gear_ratio),
            sut_inertia: self.sut_inertia,
            sut_motor_inertia_share: self.sut_motor_inertia_share,
            load_inertia: self.load_inertia,
            flange_inertia: self.flange_inertia,
            flange_stiffness: self.flange_stiffness,
            flange_damping: self.flange_damping,
            coupling_stiffness: self.coupling_stiffness,
            coupling_damping: self.coupling_damping,
            load_no_load_rpm: R::lit(self.load_no_load_rpm),
            load_base_rpm: R::lit(self.load_base_rpm),
            regen_fade_rpm: R::lit(self.regen_fade_rpm),
            connector_resistance: R::lit(self.connector_resistance),
            sut_drive_efficiency: R::lit(self.sut_drive_efficiency),
            sut_power_rate_w_per_s: R::lit(self.sut_power_rate_w_per_s),
            load_power_rate_w_per_s: R::lit(self.load_power_rate_w_per_s),
        }
    }
}

impl DirectionRates {
    /// The same rates in the scalar `R`.
    pub fn to<R: Real>(&self) -> DirectionRates<R> {
        DirectionRates {
            hs_pct: R::lit(self.hs_pct),
            ls_pct: R::lit(self.ls_pct),
            accel_hs_s: R::lit(self.accel_hs_s),
            accel_ls_s: R::lit(self.accel_ls_s),
            low_accel_s: R::lit(self.low_accel_s),
            neutral_decel_hs_s: R::lit(self.neutral_decel_hs_s),
            neutral_decel_ls_s: R::lit(self.neutral_decel_ls_s),
            partial_decel_s: R::lit(self.partial_decel_s),
        }
    }
}

impl Default for Params {
    fn default() -> Self {
        Self::thesis(RateSet::Identified, CouplingStiffness::Identified)
    }
}

/// Why `Params::set` refused a key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamKeyError {
    /// Not a key of `parameters.toml`.
    Unknown,
}

impl Params {
    /// Set a parameter by its `parameters.toml` key, so a parameter file (identified or
    /// altered) can be applied at run time exactly as `build.rs` applies it at build time.
    /// `prog.*`/`ident.*` keys apply when they belong to the rate set in use, and
    /// `coupling_stiffness_identified`/`_datasheet` when they are the stiffness in use;
    /// the others are accepted and ignored. `supply_voltage_*` are bench limits, not model
    /// parameters: accepted and ignored.
    pub fn set(
        &mut self,
        key: &str,
        v: f32,
        rates: RateSet,
        coupling: CouplingStiffness,
    ) -> Result<(), ParamKeyError> {
        let rate_field = |r: &mut DirectionRates, name: &str| -> Option<()> {
            let field = match name {
                "hs" => &mut r.hs_pct,
                "ls" => &mut r.ls_pct,
                "accel_hs" => &mut r.accel_hs_s,
                "accel_ls" => &mut r.accel_ls_s,
                "low_accel" => &mut r.low_accel_s,
                "neutral_decel_hs" => &mut r.neutral_decel_hs_s,
                "neutral_decel_ls" => &mut r.neutral_decel_ls_s,
                "partial_decel" => &mut r.partial_decel_s,
                _ => return None,
            };
            *field = v;
            Some(())
        };
        if let Some((set, rest)) = key.split_once('.') {
            let which = match set {
                "prog" => RateSet::Programmed,
                "ident" => RateSet::Identified,
                _ => return Err(ParamKeyError::Unknown),
            };
            // rest = <name>_<fwd|rev>_<unit>, e.g. accel_hs_fwd_s, ls_rev_pct.
            let (stem, unit) = rest.rsplit_once('_').ok_or(ParamKeyError::Unknown)?;
            let (name, dir) = stem.rsplit_once('_').ok_or(ParamKeyError::Unknown)?;
            let d = match dir {
                "fwd" => 0,
                "rev" => 1,
                _ => return Err(ParamKeyError::Unknown),
            };
            let unit_ok =
                matches!((name, unit), ("hs" | "ls", "pct")) || (unit == "s" && !matches!(name, "hs" | "ls"));
            if !unit_ok {
                return Err(ParamKeyError::Unknown);
            }
            let mut scratch = self.rates;
            let target = if which == rates { &mut self.rates } else { &mut scratch };
            let r = target.dir.get_mut(d).ok_or(ParamKeyError::Unknown)?;
            return rate_field(r, name).ok_or(ParamKeyError::Unknown);
        }
        let f: &mut f32 = match key {
            "throttle_volts_per_pct" => &mut self.throttle_volts_per_pct,
            "max_speed_fwd_rpm" => &mut self.max_speed_rpm[0],
            "max_speed_rev_rpm" => &mut self.max_speed_rpm[1],
            "typical_max_speed_rpm" => &mut self.typical_max_speed_rpm,
            "speed_limit_fwd_rpm" => &mut self.speed_limit_rpm[0],
            "speed_limit_rev_rpm" => &mut self.speed_limit_rpm[1],
            "full_throttle_pct" => &mut self.full_throttle_pct,
            "low_throttle_pct" => &mut self.low_throttle_pct,
            "pid_kp" => &mut self.pid_kp,
            "pid_ki" => &mut self.pid_ki,
            "pid_kd" => &mut self.pid_kd,
            "pid_d_filter_s" => &mut self.pid_d_filter_s,
            "motor_torque_max_nm" => &mut self.motor_torque_max_nm,
            "motor_power_max_w" => &mut self.motor_power_max_w,
            "sut_gear_ratio" => &mut self.sut_gear_ratio,
            "load_gear_ratio" => &mut self.load_gear_ratio,
            "sut_inertia" => &mut self.sut_inertia,
            "sut_motor_inertia_share" => &mut self.sut_motor_inertia_share,
            "load_inertia_l" => &mut self.load_inertia[0],
            "load_inertia_r" => &mut self.load_inertia[1],
            "flange_inertia" => &mut self.flange_inertia,
            "flange_stiffness" => &mut self.flange_stiffness,
            "flange_damping" => &mut self.flange_damping,
            "coupling_stiffness_identified" | "coupling_stiffness_datasheet" => {
                let mine = matches!(
                    (key, coupling),
                    ("coupling_stiffness_identified", CouplingStiffness::Identified)
                        | ("coupling_stiffness_datasheet", CouplingStiffness::Datasheet)
                );
                if mine {
                    self.coupling_stiffness = v;
                }
                return Ok(());
            }
            "coupling_damping" => &mut self.coupling_damping,
            "load_base_rpm" => &mut self.load_base_rpm,
            "load_no_load_rpm" => &mut self.load_no_load_rpm,
            "regen_fade_rpm" => &mut self.regen_fade_rpm,
            "connector_resistance" => &mut self.connector_resistance,
            "sut_drive_efficiency" => &mut self.sut_drive_efficiency,
            "sut_power_rate_w_per_s" => &mut self.sut_power_rate_w_per_s,
            "load_power_rate_w_per_s" => &mut self.load_power_rate_w_per_s,
            "supply_voltage_v" | "supply_voltage_min_v" | "supply_voltage_max_v" => return Ok(()),
            _ => return Err(ParamKeyError::Unknown),
        };
        *f = v;
        Ok(())
    }
}
