//! Physical effects the thesis model lacks, each a small block with parameters that
//! default to "off". On the host they are set at run time (`--effects FILE.toml`); on
//! the target the firmware builds a `const Effects` from the same file.
//!
//! Every effect is declared once, in the `effects!` invocation below: its field in
//! [`Effects`] and neutral value, its id and parameter names (the effect-file
//! vocabulary), each parameter's unit, valid range and doc line, what `simrod diagnose`
//! needs to fit it ([`Fit`]) and the hidden-effect case that proves it ([`Proof`]). The
//! struct, [`Effects::NONE`], [`Effects::get`]/[`Effects::set`], [`Effects::validate`],
//! [`EFFECT_PARAMS`], [`LIBRARY`] and the table [`EFFECTS`] are generated from it.
//! Adding an effect: one declaration here, and its few lines at the one place in
//! `model.rs` where it acts (`docs/ADDING_AN_EFFECT.md`).

use core::fmt;

use crate::chain::N_MEASURED;
use crate::params::Params;
use crate::profile::Builtin;

/// Coulomb + viscous friction at the differential case (thesis 7: "missing").
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DifferentialFriction {
    /// [N m] Coulomb torque at the case, axle frame.
    pub coulomb_nm: f32,
    /// [N m s/rad] viscous coefficient at the case, axle frame.
    pub viscous_nm_s: f32,
}

/// Free play in the SuT gearbox: the motor (a share of the SuT inertia) separates from
/// the differential when the transmitted torque reverses, crosses the gap freely and
/// re-engages with an inelastic impact.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GearBacklash {
    /// [deg] total free play, axle frame (at the differential case).
    pub backlash_deg: f32,
}

/// Longest controller delay in steps (1 KiB of state): 0.256 s at 1 ms, 25.6 ms at 100 µs,
/// well beyond the lag the thesis saw (6.1); sized so the firmware fits in 8 KiB of RAM.
pub const DELAY_CAPACITY: usize = 256;

/// The values a parameter accepts: finite and within its bounds. Every twin parameter
/// is bounded on both sides, so that no value makes the model non-physical.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// Lower bound.
    pub min: f32,
    /// Whether `min` itself is allowed.
    pub min_inclusive: bool,
    /// Upper bound.
    pub max: f32,
    /// Whether `max` itself is allowed.
    pub max_inclusive: bool,
}

impl Range {
    /// In `[min, max]`.
    pub const fn closed(min: f32, max: f32) -> Self {
        Self { min, min_inclusive: true, max, max_inclusive: true }
    }
    /// In `[min, max)`.
    pub const fn half_open(min: f32, max: f32) -> Self {
        Self { min, min_inclusive: true, max, max_inclusive: false }
    }

    /// Whether `v` is in range.
    pub fn contains(&self, v: f32) -> bool {
        let lo = v > self.min || (self.min_inclusive && v == self.min);
        let hi = v < self.max || (self.max_inclusive && v == self.max);
        v.is_finite() && lo && hi
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "in {}{}, {}{}",
            if self.min_inclusive { '[' } else { '(' },
            self.min,
            self.max,
            if self.max_inclusive { ']' } else { ')' }
        )
    }
}

/// An amount of a fitted parameter — its finite-difference step, its step bias — in its
/// unit or as a share of a value of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// In the parameter's unit.
    Abs(f64),
    /// A share of the value (the neutral value for a step: overrides of model values
    /// differ in scale).
    Rel(f64),
}

impl Step {
    /// The amount at `value`.
    pub fn at(self, value: f64) -> f64 {
        match self {
            Self::Abs(d) => d,
            Self::Rel(r) => r * value.abs(),
        }
    }
}

/// How the model realises a parameter at its time step: what a fit can resolve of it,
/// and over what span the output is linear in it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InSteps {
    /// Any value, smoothly.
    Continuous,
    /// Whole steps only (the controller delay): a fit resolves it to a step.
    Whole,
    /// Any value, the output linear in it between whole steps (a sensor delay,
    /// interpolated): its slope is the secant over one step.
    Linear,
}

/// What `simrod diagnose` needs to fit a parameter: the step of its sensitivity (the
/// effect's realistic magnitude, also the scale that conditions the fit) and the
/// physical bounds of the search, tighter than [`Range`] (what the model accepts).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fit {
    /// Finite-difference step.
    pub step: Step,
    /// Lower search bound.
    pub lower: f64,
    /// Upper search bound.
    pub upper: f64,
    /// How the model realises the parameter at its time step.
    pub in_steps: InSteps,
    /// `(step, to)`: the fit objective has narrow valleys away from the neutral value
    /// (a free play whose clunks must line up in time: with 3.4° of backlash in the
    /// bench, 2° and 5° both fit worse than none), so a diagnosis scans the parameter
    /// on this grid from `lower` up to `to` instead of trusting its linearisation there.
    pub scan: Option<(f64, f64)>,
    /// How far the twin's 1 ms step moves a fit of the parameter on the bench's data:
    /// the largest error `workbench/examples/step_bias.rs` measures (the physics plant
    /// with the bench's acquisition, every built-in profile), rounded up, in the unit or
    /// as a share of the value, whichever the error scales with; none for a parameter
    /// not measured there. A diagnosis counts it in the parameter's uncertainty.
    pub step_bias: Step,
    /// Which side of the truth `step_bias` puts a fit.
    pub step_bias_side: Side,
}

/// Which side of the truth the twin's step puts a fit of a parameter
/// ([`Fit::step_bias`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// Either side, by up to the bias: an error of unknown sign.
    Either,
    /// Above it, by up to the bias: the error's sign is known (a controller delay the
    /// 1 ms twin fits 0.0–1.4 ms long on the physics plant, never short).
    Above,
}

impl Side {
    /// A bias of `amount` on this side as `(centre, half-width)`: the truth lies within
    /// the half-width of the fit less the centre. An error of unknown sign is centred on
    /// the fit; one of known sign shifts the truth off it by half the amount and leaves
    /// half of it unknown.
    pub fn split(self, amount: f64) -> (f64, f64) {
        match self {
            Self::Either => (0.0, amount),
            Self::Above => (0.5 * amount, 0.5 * amount),
        }
    }
}

impl Fit {
    /// An absolute step and bounds.
    pub const fn abs(step: f64, lower: f64, upper: f64) -> Self {
        Self {
            step: Step::Abs(step),
            lower,
            upper,
            in_steps: InSteps::Continuous,
            scan: None,
            step_bias: Step::Abs(0.0),
            step_bias_side: Side::Either,
        }
    }
    /// A step relative to the neutral value, and bounds.
    pub const fn rel(step: f64, lower: f64, upper: f64) -> Self {
        Self {
            step: Step::Rel(step),
            lower,
            upper,
            in_steps: InSteps::Continuous,
            scan: None,
            step_bias: Step::Abs(0.0),
            step_bias_side: Side::Either,
        }
    }
    /// Realised in whole time steps.
    pub const fn in_whole_steps(self) -> Self {
        Self { in_steps: InSteps::Whole, ..self }
    }
    /// Realised linearly between whole time steps.
    pub const fn linear_between_steps(self) -> Self {
        Self { in_steps: InSteps::Linear, ..self }
    }
    /// Scanned on a grid of `step` up to `to` ([`Fit::scan`]).
    pub const fn scanned(self, step: f64, to: f64) -> Self {
        Self { scan: Some((step, to)), ..self }
    }
    /// Biased by the twin's step by up to `bias` ([`Fit::step_bias`]).
    pub const fn step_biased(self, bias: Step) -> Self {
        Self { step_bias: bias, ..self }
    }
    /// Biased by the twin's step above the truth, by up to `bias` ([`Side::Above`]).
    pub const fn step_biased_above(self, bias: Step) -> Self {
        Self { step_bias: bias, step_bias_side: Side::Above, ..self }
    }
    /// The step at a neutral value.
    pub fn delta(&self, neutral: f64) -> f64 {
        self.step.at(neutral)
    }
}

/// The hidden-effect proof of a library effect (`workbench::diagnose::proof`): which
/// parameter to hide, the range its value is drawn from, and a profile that excites it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proof {
    /// The hidden parameter.
    pub param: &'static str,
    /// Range of the drawn value.
    pub lo: f32,
    /// Range of the drawn value.
    pub hi: f32,
    /// Profile that excites the effect.
    pub profile: Builtin,
    /// Throttle and load scalings of the profile.
    pub scales: (f32, f32),
}

/// One parameter of an effect, as declared.
#[derive(Debug, Clone, Copy)]
pub struct ParamDecl {
    /// Name in effect files.
    pub name: &'static str,
    /// `effect.parameter`, e.g. `sensor_lag.c_kistler_l`: the cause's name when each
    /// parameter is a cause of its own ([`Cause::PerParameter`]).
    pub path: &'static str,
    /// Unit (`-` for factors).
    pub unit: &'static str,
    /// One line: what it is.
    pub doc: &'static str,
    /// Values the model accepts.
    pub range: Range,
    /// How diagnose fits it; `None` for effects outside the diagnose library.
    pub fit: Option<Fit>,
    /// For an override of a model value: that value (what applies while unset).
    pub model: Option<fn(&Params) -> f32>,
}

impl ParamDecl {
    /// The value that leaves the model as it is: the "off" value, or for an override
    /// the model's own value.
    pub fn neutral(&self, effect: &str, p: &Params) -> f32 {
        match (Effects::NONE.get(effect, self.name), self.model) {
            (Ok(Some(v)), _) => v,
            (_, Some(model)) => model(p),
            _ => 0.0,
        }
    }
}

/// One effect, as declared.
#[derive(Debug, Clone, Copy)]
pub struct EffectDecl {
    /// Id in effect files.
    pub id: &'static str,
    /// What it models.
    pub doc: &'static str,
    /// Its parameters, in file order.
    pub params: &'static [ParamDecl],
    /// Hidden-effect proof case; `Some` exactly for the diagnose library.
    pub proof: Option<Proof>,
    /// Whether its parameters act together or each on its own.
    pub cause: Cause,
}

/// What `simrod diagnose` fits as one candidate cause.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cause {
    /// All parameters together: one physical mechanism (friction's Coulomb and viscous
    /// parts).
    Whole,
    /// Each parameter alone: the measurement chain of one channel, a sensor cause that
    /// moves that channel only (an offset on C_Kistler_L says nothing of I_DC's).
    PerParameter,
}

impl EffectDecl {
    /// Whether `simrod diagnose` may propose it (every parameter has a [`Fit`]).
    pub const fn in_library(&self) -> bool {
        let mut i = 0;
        while i < self.params.len() {
            if self.params[i].fit.is_none() {
                return false;
            }
            i += 1;
        }
        !self.params.is_empty()
    }

    /// A parameter by name.
    pub fn param(&self, name: &str) -> Option<&'static ParamDecl> {
        self.params.iter().find(|p| p.name == name)
    }

    /// What [`Effects::validate`] requires of this effect, for messages.
    pub fn constraint(&'static self) -> Constraint {
        Constraint(self)
    }
}

/// What an effect's parameters must be, displayed `p1 must be ...; p2 must be ...`.
#[derive(Debug, Clone, Copy)]
pub struct Constraint(&'static EffectDecl);

impl fmt::Display for Constraint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, p) in self.0.params.iter().enumerate() {
            write!(f, "{}{} must be {}", if i > 0 { "; " } else { "" }, p.name, p.range)?;
        }
        Ok(())
    }
}

/// The declaration of an effect by id.
pub fn effect(id: &str) -> Option<&'static EffectDecl> {
    EFFECTS.iter().find(|e| e.id == id)
}

/// Where an effect parameter is stored: a plain value, or an override of a model value
/// (`None` while unset).
trait Slot {
    fn put(&mut self, v: f32);
    fn read(&self) -> Option<f32>;
}

impl Slot for f32 {
    fn put(&mut self, v: f32) {
        *self = v;
    }
    fn read(&self) -> Option<f32> {
        Some(*self)
    }
}

impl Slot for Option<f32> {
    fn put(&mut self, v: f32) {
        *self = Some(v);
    }
    fn read(&self) -> Option<f32> {
        *self
    }
}

/// Declares the effect library. Per effect: its doc, `id => field: Type = neutral`, its
/// proof case (`Some(Proof)` puts it in the diagnose library, whose parameters then all
/// need a `fit`), and per parameter `name(accessor into the field): unit, range, fit,
/// model value it overrides, doc`.
macro_rules! effects {
    ($(
        $(#[doc = $doc:literal])*
        $id:ident => $field:ident : $ty:ty = $neutral:expr, proof $proof:expr, $cause:ident;
        {$(
            $param:ident ($($acc:tt)*) : $unit:literal, $range:expr, fit $fit:expr, model $model:expr,
                $pdoc:literal;
        )+}
    )+) => {
        /// The effect library. `Effects::NONE` is the thesis model.
        #[derive(Debug, Clone, Copy, PartialEq)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        pub struct Effects {
            $(
                #[doc = concat!("`", stringify!($id), "`:", $($doc),*)]
                pub $field: $ty,
            )+
        }

        impl Effects {
            /// Every effect off: the thesis model.
            pub const NONE: Self = Self { $($field: $neutral,)+ };

            /// Set one parameter by effect id and parameter name (the effect-file
            /// vocabulary). Range checks happen in [`Effects::validate`], once every
            /// parameter is set (some ranges depend on a sibling parameter).
            pub fn set(&mut self, effect: &str, param: &str, v: f32) -> Result<(), EffectKeyError> {
                $(
                    if effect == stringify!($id) {
                        $(
                            if param == stringify!($param) {
                                Slot::put(&mut self.$field $($acc)*, v);
                                return Ok(());
                            }
                        )+
                        return Err(EffectKeyError::UnknownParameter(&[$(stringify!($param)),+]));
                    }
                )+
                Err(EffectKeyError::UnknownEffect)
            }

            /// Put one parameter back to its value in [`Effects::NONE`] (an override is
            /// unset, not set to the model's value), so an effect file no longer states it.
            pub fn reset(&mut self, effect: &str, param: &str) -> Result<(), EffectKeyError> {
                $(
                    if effect == stringify!($id) {
                        $(
                            if param == stringify!($param) {
                                self.$field $($acc)* = Self::NONE.$field $($acc)*;
                                return Ok(());
                            }
                        )+
                        return Err(EffectKeyError::UnknownParameter(&[$(stringify!($param)),+]));
                    }
                )+
                Err(EffectKeyError::UnknownEffect)
            }

            /// One parameter's value; `None` for an override that is not set (the
            /// model's own value applies).
            pub fn get(&self, effect: &str, param: &str) -> Result<Option<f32>, EffectKeyError> {
                $(
                    if effect == stringify!($id) {
                        $(
                            if param == stringify!($param) {
                                return Ok(Slot::read(&self.$field $($acc)*));
                            }
                        )+
                        return Err(EffectKeyError::UnknownParameter(&[$(stringify!($param)),+]));
                    }
                )+
                Err(EffectKeyError::UnknownEffect)
            }
        }

        impl Effects {
            /// Every parameter's value in declaration order (`None`: an unset override).
            fn param_values(&self) -> [Option<f32>; N_PARAMS] {
                [$($(Slot::read(&self.$field $($acc)*),)+)+]
            }
        }

        /// Number of declared parameters.
        const N_PARAMS: usize = [$($(stringify!($param),)+)+].len();

        /// Every effect id, in declaration order.
        pub const EFFECT_IDS: &[&str] = &[$(stringify!($id)),+];

        /// Every effect, as declared, in declaration order.
        pub const EFFECTS: &[EffectDecl] = &[$(
            EffectDecl {
                id: stringify!($id),
                doc: concat!($($doc),*),
                params: &[$(
                    ParamDecl {
                        name: stringify!($param),
                        path: concat!(stringify!($id), ".", stringify!($param)),
                        unit: $unit,
                        doc: $pdoc,
                        range: $range,
                        fit: $fit,
                        model: $model,
                    },
                )+],
                proof: $proof,
                cause: Cause::$cause,
            },
        )+];

        /// The parameter names of each effect, as written in effect files.
        pub const EFFECT_PARAMS: &[(&str, &[&str])] = &[$((stringify!($id), &[$(stringify!($param)),+]),)+];
    };
}

use Builtin::{TP07, TP11, TP14};

const fn proof(param: &'static str, lo: f32, hi: f32, profile: Builtin, scales: (f32, f32)) -> Option<Proof> {
    Some(Proof { param, lo, hi, profile, scales })
}

// Ranges keep the twin physical and its step stable: a parameter may move a value by
// about an order of magnitude from the thesis's, not to 1e30 or 1e-12 (issue 13: such
// values gave non-physical output with exit 0). The diagnose search bounds (`Fit`) lie
// inside them.
/// A multiplier on an identified value.
const SCALE: Range = Range::closed(0.1, 10.0);
/// A multiplier on a sensor's reading.
const GAIN: Range = Range::closed(0.1, 10.0);
const FACTOR: Option<Fit> = Some(Fit::abs(0.05, 0.1, 5.0).step_biased(Step::Rel(2.4e-4)));
const SENSOR_GAIN: Option<Fit> = Some(Fit::abs(0.02, 0.5, 2.0).step_biased(Step::Rel(7.4e-4)));
const SPEED_GAIN: Option<Fit> = Some(Fit::abs(0.01, 0.5, 2.0));
// A sensor offset may be about a tenth of the channel's span; the search a third of that.
const OFFSET_V: Range = Range::closed(-30.0, 30.0);
const OFFSET_RPM: Range = Range::closed(-5000.0, 5000.0);
const OFFSET_NM: Range = Range::closed(-200.0, 200.0);
const OFFSET_A: Range = Range::closed(-200.0, 200.0);
const OFFSET_V_FIT: Option<Fit> = Some(Fit::abs(0.1, -5.0, 5.0));
const OFFSET_RPM_FIT: Option<Fit> = Some(Fit::abs(10.0, -500.0, 500.0));
const OFFSET_NM_FIT: Option<Fit> = Some(Fit::abs(1.0, -60.0, 60.0).step_biased(Step::Abs(0.012)));
const OFFSET_A_FIT: Option<Fit> = Some(Fit::abs(0.5, -30.0, 30.0));
/// A sensor's lag or delay [s]: up to a second (far beyond a real chain's 1-100 ms).
const SENSOR_TIME: Range = Range::closed(0.0, 1.0);
const LAG_FIT: Option<Fit> = Some(Fit::abs(0.01, 0.0, 0.2).step_biased(Step::Rel(0.03)));
/// A sensor delay's fit, `bias` [s] its channel's step bias: `examples/step_bias.rs
/// sensor_delay.CHANNEL` measures each channel, and the twin's step moves a delay fit by
/// channel, from 0.8 ms on I_DC and V_DC to 3.4 ms on T_Kistler_L (Throttle's 5.0 ms is
/// a fit left at a coarse grid point on TP14, where the throttle hardly steps).
const fn delay_fit(bias: f64) -> Option<Fit> {
    Some(Fit::abs(0.02, 0.0, 0.1).linear_between_steps().step_biased(Step::Abs(bias)))
}

// The order is the diagnose library's order (its ranking breaks ties by it) and the
// order of sections in written effect files.
effects! {
    /// Torque lost at the differential case (thesis 7: "missing").
    differential_friction => differential_friction: DifferentialFriction =
        DifferentialFriction { coulomb_nm: 0.0, viscous_nm_s: 0.0 },
        proof proof("coulomb_nm", 2.0, 6.0, TP07, (1.0, 1.0)), Whole;
    {
        coulomb_nm(.coulomb_nm): "N m", Range::closed(0.0, 200.0), fit Some(Fit::abs(1.0, 0.0, 60.0).step_biased(Step::Abs(0.037))), model None,
            "Coulomb friction torque at the case, axle frame (0 = off)";
        viscous_nm_s_per_rad(.viscous_nm_s): "N m s/rad", Range::closed(0.0, 100.0), fit Some(Fit::abs(0.2, 0.0, 20.0).step_biased(Step::Abs(2.1e-3))),
            model None, "viscous coefficient at the case, axle frame (0 = off)";
    }
    /// Multipliers on the L, R friction maps (1 = off).
    axle_friction_scale => axle_friction_scale: [f32; 2] = [1.0, 1.0],
        proof proof("left", 1.15, 1.4, TP11, (0.79, 0.0)), Whole;
    {
        left([0]): "-", Range::closed(0.0, 10.0), fit FACTOR, model None, "multiplies the L friction map (1 = off)";
        right([1]): "-", Range::closed(0.0, 10.0), fit FACTOR, model None, "multiplies the R friction map (1 = off)";
    }
    /// Free play in the SuT gearbox.
    gear_backlash => gear_backlash: GearBacklash = GearBacklash { backlash_deg: 0.0 },
        proof proof("backlash_deg", 1.0, 4.0, TP07, (1.0, 1.0)), Whole;
    {
        backlash_deg(.backlash_deg): "deg", Range::closed(0.0, 30.0), fit Some(Fit::abs(0.5, 0.0, 20.0).scanned(0.25, 10.0).step_biased(Step::Abs(0.054))),
            model None, "total free play at the differential case (0 = off)";
    }
    /// [s] pure delay between the throttle and the speed controller (thesis 6.1).
    /// Capped at `DELAY_CAPACITY` steps.
    controller_delay => controller_delay_s: f32 = 0.0,
        proof proof("delay_s", 0.05, 0.15, TP14, (1.0, 0.0)), Whole;
    {
        delay_s(): "s", Range::closed(0.0, 10.0), fit Some(Fit::abs(0.02, 0.0, 0.25).in_whole_steps().step_biased_above(Step::Abs(1.4e-3))), model None,
            "throttle-to-controller delay, at most 256 steps (0 = off)";
    }
    /// Multipliers on the Curtis ramp rates `[accel, decel]` for `[forward, reverse]`
    /// (1 = off).
    inverter_rate_scale => inverter_rate_scale: [[f32; 2]; 2] = [[1.0, 1.0], [1.0, 1.0]],
        proof proof("decel_fwd", 0.7, 0.9, TP14, (1.0, 0.0)), Whole;
    {
        accel_fwd([0][0]): "-", SCALE, fit Some(Fit::abs(0.05, 0.2, 5.0).step_biased(Step::Rel(8.2e-4))), model None,
            "multiplies the forward acceleration rates (1 = off)";
        decel_fwd([0][1]): "-", SCALE, fit Some(Fit::abs(0.05, 0.2, 5.0).step_biased(Step::Rel(4.8e-3))), model None,
            "multiplies the forward deceleration rates (1 = off)";
        accel_rev([1][0]): "-", SCALE, fit Some(Fit::abs(0.05, 0.2, 5.0)), model None,
            "multiplies the reverse acceleration rates (1 = off)";
        decel_rev([1][1]): "-", SCALE, fit Some(Fit::abs(0.05, 0.2, 5.0)), model None,
            "multiplies the reverse deceleration rates (1 = off)";
    }
    /// [N m/rad] replaces the coupling stiffness when set.
    coupling_stiffness => coupling_stiffness: Option<f32> = None,
        proof proof("stiffness_nm_per_rad", 6000.0, 12000.0, TP07, (1.0, 1.0)), Whole;
    {
        stiffness_nm_per_rad(): "N m/rad", Range::closed(100.0, 1.0e6), fit Some(Fit::rel(0.2, 300.0, 60_000.0).step_biased(Step::Rel(0.11))),
            model Some(|p| p.coupling_stiffness), "replaces the flexible coupling stiffness";
    }
    /// [N m s/rad] replaces the coupling damping when set.
    coupling_damping => coupling_damping: Option<f32> = None,
        proof proof("damping_nm_s_per_rad", 10.0, 30.0, TP07, (1.0, 1.0)), Whole;
    {
        damping_nm_s_per_rad(): "N m s/rad", Range::closed(0.0, 1000.0), fit Some(Fit::abs(2.0, 0.0, 300.0).step_biased(Step::Rel(0.22))),
            model Some(|p| p.coupling_damping), "replaces the flexible coupling damping";
    }
    /// Multipliers on the SuT, load L, load R inertias (1 = off).
    inertia_scale => inertia_scale: [f32; 3] = [1.0, 1.0, 1.0],
        proof proof("sut", 1.2, 1.5, TP14, (1.0, 0.0)), Whole;
    {
        sut([0]): "-", SCALE, fit Some(Fit::abs(0.05, 0.1, 5.0).step_biased(Step::Abs(0.067))), model None, "multiplies the SuT-side inertia (1 = off)";
        load_l([1]): "-", SCALE, fit Some(Fit::abs(0.05, 0.1, 5.0).step_biased(Step::Abs(0.065))), model None, "multiplies the load L inertia (1 = off)";
        load_r([2]): "-", SCALE, fit Some(Fit::abs(0.05, 0.1, 5.0).step_biased(Step::Abs(0.044))), model None, "multiplies the load R inertia (1 = off)";
    }
    /// [ohm] replaces the connector resistance when set.
    connector_resistance => connector_resistance: Option<f32> = None,
        proof proof("resistance_ohm", 0.025, 0.04, TP11, (0.79, 1.0)), Whole;
    {
        resistance_ohm(): "ohm", Range::closed(0.0, 1.0), fit Some(Fit::abs(0.005, 0.0, 0.3).step_biased(Step::Rel(1.3e-3))),
            model Some(|p| p.connector_resistance), "replaces the busbar-to-inverter connector resistance";
    }
    /// [ohm] DPU source resistance: the busbars sag with current.
    supply_resistance => supply_resistance: f32 = 0.0,
        proof proof("resistance_ohm", 0.005, 0.02, TP11, (0.79, 1.0)), Whole;
    {
        resistance_ohm(): "ohm", Range::half_open(0.0, 1.0), fit Some(Fit::abs(0.005, 0.0, 0.5).step_biased(Step::Rel(3.3e-3))),
            model None, "DPU source resistance (0 = off)";
    }
    /// [-] fraction of regenerated power additionally lost (0 = off).
    regen_efficiency => regen_loss: f32 = 0.0,
        proof proof("extra_loss", 0.1, 0.3, TP07, (1.0, 1.0)), Whole;
    {
        extra_loss(): "-", Range::half_open(0.0, 1.0), fit Some(Fit::abs(0.05, 0.0, 0.9).step_biased(Step::Abs(1.4e-3))), model None,
            "fraction of regenerated power additionally lost (0 = off)";
    }
    /// [-] multiplies each measured channel at its sensor (1 = off).
    sensor_gain => sensor_gain: [f32; N_MEASURED] = [1.0; N_MEASURED],
        proof proof("c_kistler_r", 1.02, 1.06, TP07, (1.0, 1.0)), PerParameter;
    {
        throttle([0]): "-", GAIN, fit SPEED_GAIN, model None, "multiplies Throttle (1 = off)";
        sutmotorenc([1]): "-", GAIN, fit SPEED_GAIN, model None, "multiplies SuTMotorEnc (1 = off)";
        c_kistler_l([2]): "-", GAIN, fit SENSOR_GAIN, model None, "multiplies C_Kistler_L (1 = off)";
        c_kistler_r([3]): "-", GAIN, fit SENSOR_GAIN, model None, "multiplies C_Kistler_R (1 = off)";
        t_kistler_l([4]): "-", GAIN, fit SPEED_GAIN, model None, "multiplies T_Kistler_L (1 = off)";
        t_kistler_r([5]): "-", GAIN, fit SPEED_GAIN, model None, "multiplies T_Kistler_R (1 = off)";
        siemensenc([6]): "-", GAIN, fit SPEED_GAIN, model None, "multiplies SiemensEnc (1 = off)";
        i_xlml_2_2([7]): "-", GAIN, fit SENSOR_GAIN, model None, "multiplies I_XLML 2.2 (1 = off)";
        i_xlml_bu1([8]): "-", GAIN, fit SENSOR_GAIN, model None, "multiplies I_XLML BU1 (1 = off)";
        i_xlmr_2_3([9]): "-", GAIN, fit SENSOR_GAIN, model None, "multiplies I_XLMR 2.3 (1 = off)";
        i_dpu_2_7([10]): "-", GAIN, fit SENSOR_GAIN, model None, "multiplies I_DPU 2.7 (1 = off)";
        v_dc_busbars([11]): "-", GAIN, fit SPEED_GAIN, model None, "multiplies V_DC_busbars (1 = off)";
        i_dc([12]): "-", GAIN, fit SENSOR_GAIN, model None, "multiplies I_DC (1 = off)";
        v_dc([13]): "-", GAIN, fit SPEED_GAIN, model None, "multiplies V_DC (1 = off)";
    }
    /// Added to each measured channel at its sensor, in the channel's unit (0 = off).
    sensor_offset => sensor_offset: [f32; N_MEASURED] = [0.0; N_MEASURED],
        proof proof("c_kistler_l", 0.5, 2.0, TP11, (0.79, 0.0)), PerParameter;
    {
        throttle([0]): "V", OFFSET_V, fit OFFSET_V_FIT, model None, "added to Throttle (0 = off)";
        sutmotorenc([1]): "rpm", OFFSET_RPM, fit OFFSET_RPM_FIT, model None, "added to SuTMotorEnc (0 = off)";
        c_kistler_l([2]): "N m", OFFSET_NM, fit OFFSET_NM_FIT, model None, "added to C_Kistler_L (0 = off)";
        c_kistler_r([3]): "N m", OFFSET_NM, fit OFFSET_NM_FIT, model None, "added to C_Kistler_R (0 = off)";
        t_kistler_l([4]): "rpm", OFFSET_RPM, fit OFFSET_RPM_FIT, model None, "added to T_Kistler_L (0 = off)";
        t_kistler_r([5]): "rpm", OFFSET_RPM, fit OFFSET_RPM_FIT, model None, "added to T_Kistler_R (0 = off)";
        siemensenc([6]): "rpm", OFFSET_RPM, fit OFFSET_RPM_FIT, model None, "added to SiemensEnc (0 = off)";
        i_xlml_2_2([7]): "A", OFFSET_A, fit OFFSET_A_FIT, model None, "added to I_XLML 2.2 (0 = off)";
        i_xlml_bu1([8]): "A", OFFSET_A, fit OFFSET_A_FIT, model None, "added to I_XLML BU1 (0 = off)";
        i_xlmr_2_3([9]): "A", OFFSET_A, fit OFFSET_A_FIT, model None, "added to I_XLMR 2.3 (0 = off)";
        i_dpu_2_7([10]): "A", OFFSET_A, fit OFFSET_A_FIT, model None, "added to I_DPU 2.7 (0 = off)";
        v_dc_busbars([11]): "V", OFFSET_V, fit OFFSET_V_FIT, model None, "added to V_DC_busbars (0 = off)";
        i_dc([12]): "A", OFFSET_A, fit OFFSET_A_FIT, model None, "added to I_DC (0 = off)";
        v_dc([13]): "V", OFFSET_V, fit OFFSET_V_FIT, model None, "added to V_DC (0 = off)";
    }
    /// [s] time constant of each measured channel's amplifier or filter, a first-order
    /// lag (0 = off).
    sensor_lag => sensor_lag_s: [f32; N_MEASURED] = [0.0; N_MEASURED],
        proof proof("c_kistler_l", 0.02, 0.06, TP07, (1.0, 1.0)), PerParameter;
    {
        throttle([0]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of Throttle (0 = off)";
        sutmotorenc([1]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of SuTMotorEnc (0 = off)";
        c_kistler_l([2]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of C_Kistler_L (0 = off)";
        c_kistler_r([3]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of C_Kistler_R (0 = off)";
        t_kistler_l([4]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of T_Kistler_L (0 = off)";
        t_kistler_r([5]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of T_Kistler_R (0 = off)";
        siemensenc([6]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of SiemensEnc (0 = off)";
        i_xlml_2_2([7]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of I_XLML 2.2 (0 = off)";
        i_xlml_bu1([8]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of I_XLML BU1 (0 = off)";
        i_xlmr_2_3([9]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of I_XLMR 2.3 (0 = off)";
        i_dpu_2_7([10]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of I_DPU 2.7 (0 = off)";
        v_dc_busbars([11]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of V_DC_busbars (0 = off)";
        i_dc([12]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of I_DC (0 = off)";
        v_dc([13]): "s", SENSOR_TIME, fit LAG_FIT, model None, "lag of V_DC (0 = off)";
    }
    /// [s] each measured channel recorded late, between steps by linear interpolation;
    /// all channels together take at most `SENSOR_DELAY_CAPACITY` slots, one per started
    /// step (0 = off).
    sensor_delay => sensor_delay_s: [f32; N_MEASURED] = [0.0; N_MEASURED],
        proof proof("sutmotorenc", 0.03, 0.08, TP14, (1.0, 0.0)), PerParameter;
    {
        throttle([0]): "s", SENSOR_TIME, fit delay_fit(5.0e-3), model None, "Throttle recorded late by (0 = off)";
        sutmotorenc([1]): "s", SENSOR_TIME, fit delay_fit(1.2e-3), model None, "SuTMotorEnc recorded late by (0 = off)";
        c_kistler_l([2]): "s", SENSOR_TIME, fit delay_fit(2.1e-3), model None, "C_Kistler_L recorded late by (0 = off)";
        c_kistler_r([3]): "s", SENSOR_TIME, fit delay_fit(1.7e-3), model None, "C_Kistler_R recorded late by (0 = off)";
        t_kistler_l([4]): "s", SENSOR_TIME, fit delay_fit(3.4e-3), model None, "T_Kistler_L recorded late by (0 = off)";
        t_kistler_r([5]): "s", SENSOR_TIME, fit delay_fit(2.5e-3), model None, "T_Kistler_R recorded late by (0 = off)";
        siemensenc([6]): "s", SENSOR_TIME, fit delay_fit(1.4e-3), model None, "SiemensEnc recorded late by (0 = off)";
        i_xlml_2_2([7]): "s", SENSOR_TIME, fit delay_fit(1.0e-3), model None, "I_XLML 2.2 recorded late by (0 = off)";
        i_xlml_bu1([8]): "s", SENSOR_TIME, fit delay_fit(0.9e-3), model None, "I_XLML BU1 recorded late by (0 = off)";
        i_xlmr_2_3([9]): "s", SENSOR_TIME, fit delay_fit(1.0e-3), model None, "I_XLMR 2.3 recorded late by (0 = off)";
        i_dpu_2_7([10]): "s", SENSOR_TIME, fit delay_fit(1.0e-3), model None, "I_DPU 2.7 recorded late by (0 = off)";
        v_dc_busbars([11]): "s", SENSOR_TIME, fit delay_fit(0.8e-3), model None, "V_DC_busbars recorded late by (0 = off)";
        i_dc([12]): "s", SENSOR_TIME, fit delay_fit(0.8e-3), model None, "I_DC recorded late by (0 = off)";
        v_dc([13]): "s", SENSOR_TIME, fit delay_fit(0.8e-3), model None, "V_DC recorded late by (0 = off)";
    }
}

/// Each parameter's range, in declaration order: all the target's check reads
/// (computed at compile time from the declarations, which stay out of flash).
const RANGES: [Range; N_PARAMS] = {
    let mut out = [Range::closed(0.0, 0.0); N_PARAMS];
    let (mut i, mut e) = (0, 0);
    while e < EFFECTS.len() {
        let mut p = 0;
        while p < EFFECTS[e].params.len() {
            out[i] = EFFECTS[e].params[p].range;
            (i, p) = (i + 1, p + 1);
        }
        e += 1;
    }
    out
};

/// Each parameter's (effect index, index within the effect), in declaration order.
const OWNERS: [(u8, u8); N_PARAMS] = {
    let mut out = [(0, 0); N_PARAMS];
    let (mut i, mut e) = (0, 0);
    while e < EFFECTS.len() {
        let mut p = 0;
        while p < EFFECTS[e].params.len() {
            out[i] = (e as u8, p as u8);
            (i, p) = (i + 1, p + 1);
        }
        e += 1;
    }
    out
};

impl Effects {
    /// The first parameter outside its declared range: (effect index, parameter index,
    /// value).
    fn first_invalid(&self) -> Option<(usize, usize, f32)> {
        let values = self.param_values();
        let checks = values.iter().zip(RANGES.iter()).zip(OWNERS.iter());
        for ((v, range), (e, p)) in checks {
            if let Some(v) = *v {
                if !range.contains(v) {
                    return Some((usize::from(*e), usize::from(*p), v));
                }
            }
        }
        None
    }
}

const LIBRARY_LEN: usize = {
    let mut n = 0;
    let mut i = 0;
    while i < EFFECTS.len() {
        if EFFECTS[i].in_library() {
            n += 1;
        }
        i += 1;
    }
    n
};

const LIBRARY_IDS: [&str; LIBRARY_LEN] = {
    let mut out = [""; LIBRARY_LEN];
    let (mut n, mut i) = (0, 0);
    while i < EFFECTS.len() {
        if EFFECTS[i].in_library() {
            out[n] = EFFECTS[i].id;
            n += 1;
        }
        i += 1;
    }
    out
};

/// The effects `simrod diagnose` may propose: those declared with a proof case and a
/// fit for every parameter. Physics the twin lacks on purpose (Stribeck friction, a
/// drifting connector, ...) lives in the physics plant (`simrod-plant`), which the
/// virtual bench uses to prove that diagnose reports what its library cannot explain.
pub const LIBRARY: &[&str] = &LIBRARY_IDS;

/// Why an effect's parameters are refused: the first parameter out of its range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Invalid {
    /// The effect's declaration.
    pub effect: &'static EffectDecl,
    /// The parameter out of range.
    pub param: &'static ParamDecl,
    /// Its value.
    pub value: f32,
}

impl PartialEq for EffectDecl {
    fn eq(&self, other: &Self) -> bool {
        self.id == other.id
    }
}

impl PartialEq for ParamDecl {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name && self.unit == other.unit
    }
}

impl fmt::Display for Invalid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (id, p) = (self.effect.id, self.param.name);
        write!(f, "[{id}]: {p} = {} is invalid: {p} must be {}", self.value, self.param.range)
    }
}

impl Effects {
    /// True when every effect is off.
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// Check every parameter against its declared range; the first one refused. (An
    /// unset override keeps the model's value, checked with the model.)
    pub fn check(&self) -> Result<(), Invalid> {
        let Some((e, p, value)) = self.first_invalid() else { return Ok(()) };
        match EFFECTS.get(e).and_then(|d| Some((d, d.params.get(p)?))) {
            Some((effect, param)) => Err(Invalid { effect, param, value }),
            None => Ok(()),
        }
    }

    /// Check ranges; returns the id of the first effect with an invalid parameter.
    pub fn validate(&self) -> Result<(), &'static str> {
        match self.first_invalid() {
            Some((e, ..)) => Err(EFFECT_IDS.get(e).copied().unwrap_or("effects")),
            None => Ok(()),
        }
    }
}

/// A delay longer than the model's delay line holds at a time step: the model would cut
/// it, so the commands refuse it instead ([`Effects::check_delays`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DelayTooLong {
    /// What is delayed: `controller_delay.delay_s`, or all channels' `sensor_delay`.
    pub what: &'static str,
    /// [s] the delay asked for (for `sensor_delay`: all channels together).
    pub seconds: f64,
    /// The steps it takes at `dt_us`.
    pub steps: u64,
    /// The steps the line holds.
    pub capacity: usize,
    /// [µs] the time step.
    pub dt_us: u32,
}

impl fmt::Display for DelayTooLong {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let cap_s = self.capacity as f64 * f64::from(self.dt_us) * 1e-6;
        write!(
            f,
            "{} = {} s is {} steps at a {} µs step; the model holds at most {} steps ({} s at this step)",
            self.what, self.seconds, self.steps, self.dt_us, self.capacity, cap_s
        )
    }
}

/// Whole steps of `seconds` at `dt_s`, as the model rounds the controller delay (the
/// sensor delays also realise a fraction: [`crate::chain::delay_split`]).
pub fn delay_steps(seconds: f32, dt_s: f64) -> u64 {
    (f64::from(seconds) / dt_s + 0.5) as u64
}

impl Effects {
    /// Whether every delay fits its line at step `dt_us`: the controller delay
    /// ([`DELAY_CAPACITY`]) and the sensor delays of all channels together
    /// ([`crate::chain::SENSOR_DELAY_CAPACITY`]).
    pub fn check_delays(&self, dt_us: u32) -> Result<(), DelayTooLong> {
        let dt_s = f64::from(dt_us) * 1e-6;
        let steps = delay_steps(self.controller_delay_s, dt_s);
        if steps > DELAY_CAPACITY as u64 {
            let seconds = f64::from(self.controller_delay_s);
            let what = "controller_delay.delay_s";
            return Err(DelayTooLong { what, seconds, steps, capacity: DELAY_CAPACITY, dt_us });
        }
        let steps: u64 = self.sensor_delay_s.iter().map(|d| crate::chain::delay_slots(*d, dt_s)).sum();
        let capacity = crate::chain::SENSOR_DELAY_CAPACITY;
        if steps > capacity as u64 {
            let seconds = self.sensor_delay_s.iter().map(|d| f64::from(*d)).sum();
            let what = "sensor_delay (all channels together)";
            return Err(DelayTooLong { what, seconds, steps, capacity, dt_us });
        }
        Ok(())
    }
}

impl Default for Effects {
    fn default() -> Self {
        Self::NONE
    }
}

/// Why `Effects::set` refused a parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EffectKeyError {
    /// No effect with this id.
    UnknownEffect,
    /// The effect has no parameter with this name; the names it accepts.
    UnknownParameter(&'static [&'static str]),
}

impl EffectKeyError {
    /// The message for this error on `effect`.`param`, naming the accepted vocabulary.
    pub fn describe<'a>(self, effect: &'a str, param: &'a str) -> KeyErrorText<'a> {
        KeyErrorText { error: self, effect, param }
    }
}

/// [`EffectKeyError`] with the names it was given, for messages.
#[derive(Debug, Clone, Copy)]
pub struct KeyErrorText<'a> {
    error: EffectKeyError,
    effect: &'a str,
    param: &'a str,
}

/// `a`, `b`: back-quoted names.
fn write_list<'a>(f: &mut fmt::Formatter<'_>, names: impl Iterator<Item = &'a str>) -> fmt::Result {
    for (i, n) in names.enumerate() {
        write!(f, "{}`{n}`", if i > 0 { ", " } else { "" })?;
    }
    Ok(())
}

impl fmt::Display for KeyErrorText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.error {
            EffectKeyError::UnknownEffect => {
                write!(f, "unknown effect `{}`; known effects: ", self.effect)?;
                write_list(f, effect_ids())
            }
            EffectKeyError::UnknownParameter(names) => {
                write!(f, "[{}]: unknown parameter `{}`; accepted: ", self.effect, self.param)?;
                write_list(f, names.iter().copied())
            }
        }
    }
}

/// Every effect id, as used in effect files.
pub fn effect_ids() -> impl Iterator<Item = &'static str> + Clone {
    EFFECTS.iter().map(|e| e.id)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delays_beyond_their_lines_are_refused_with_the_numbers() {
        let mut fx = Effects::NONE;
        fx.controller_delay_s = 0.256;
        assert!(fx.check_delays(1000).is_ok());
        let e = fx.check_delays(100).unwrap_err();
        assert_eq!((e.steps, e.capacity), (2560, DELAY_CAPACITY));
        fx.controller_delay_s = 0.0;
        (fx.sensor_delay_s[1], fx.sensor_delay_s[2]) = (0.1, 0.028);
        assert!(fx.check_delays(1000).is_ok());
        fx.sensor_delay_s[3] = 0.001;
        let e = fx.check_delays(1000).unwrap_err();
        assert_eq!((e.what, e.steps), ("sensor_delay (all channels together)", 129));
        let text = std::format!("{e}");
        assert!(text.contains("129 steps at a 1000 µs step") && text.contains("at most 128 steps"), "{text}");
    }

    /// The generated range check refuses exactly the parameter whose declared range a
    /// value leaves, and names it; the range's ends, where inclusive, pass.
    #[test]
    fn every_parameter_is_checked_against_its_own_range() {
        for e in EFFECTS {
            for p in e.params {
                let mut fx = Effects::NONE;
                let above = p.range.max + 0.5 * p.range.max.abs() + 1.0;
                assert_eq!(fx.set(e.id, p.name, above), Ok(()));
                let bad = fx.check().unwrap_err();
                assert_eq!((bad.effect.id, bad.param.name, bad.value), (e.id, p.name, above));
                assert_eq!(fx.validate(), Err(e.id));
                for (end, inclusive) in
                    [(p.range.min, p.range.min_inclusive), (p.range.max, p.range.max_inclusive)]
                {
                    assert_eq!(fx.set(e.id, p.name, end), Ok(()));
                    assert_eq!(fx.check().is_ok(), inclusive, "{}.{} = {end}", e.id, p.name);
                }
            }
        }
    }

    /// A reset puts back exactly the one parameter it names, overrides included (unset,
    /// not set to the model's value), and refuses names the library does not have.
    #[test]
    fn a_reset_undoes_one_parameter_and_only_it() {
        for e in EFFECTS {
            for p in e.params {
                let mut fx = Effects::NONE;
                for q in e.params {
                    assert_eq!(fx.set(e.id, q.name, q.range.max), Ok(()));
                }
                assert_eq!(fx.reset(e.id, p.name), Ok(()));
                assert_eq!(fx.get(e.id, p.name), Effects::NONE.get(e.id, p.name), "{}.{}", e.id, p.name);
                for q in e.params.iter().filter(|q| q.name != p.name) {
                    assert_eq!(fx.get(e.id, q.name), Ok(Some(q.range.max)), "{}.{} kept", e.id, q.name);
                }
            }
        }
        let mut fx = Effects::NONE;
        assert_eq!(fx.reset("no_such_effect", "x"), Err(EffectKeyError::UnknownEffect));
        assert!(matches!(fx.reset("coupling_damping", "x"), Err(EffectKeyError::UnknownParameter(_))));
    }
}
