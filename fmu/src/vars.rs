//! The FMU's variables, derived from the twin's declarations: every output is a
//! [`Channel`] (`Channel::ALL`), every effect parameter an [`EffectDecl`]'s
//! [`ParamDecl`] (`EFFECTS`). `modelDescription.xml` and the C API's getters and
//! setters both read this one table, so they cannot disagree.
//!
//! Value references are grouped with room between the groups, so a channel or an
//! effect added to model-core moves no other group's references: time 0, inputs 1..,
//! choices 100.., outputs 1000 + channel index, effect parameters 2000 + running index.

use model_core::effects::{EffectDecl, ParamDecl, EFFECTS};
use model_core::{Channel, CouplingStiffness, RateSet, SpeedTarget};

/// The independent variable.
pub const VR_TIME: u32 = 0;
const VR_INPUT: u32 = 1;
const VR_CHOICE: u32 = 100;
const VR_OUTPUT: u32 = 1000;
const VR_EFFECT: u32 = 2000;

/// The twin's inputs, in the order of [`Inputs`](crate::instance::Values::inputs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    Throttle,
    LoadL,
    LoadR,
    Supply,
}

impl Input {
    /// Every input.
    pub const ALL: [Input; 4] = [Input::Throttle, Input::LoadL, Input::LoadR, Input::Supply];

    /// Index into the input values.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Variable name.
    pub fn name(self) -> &'static str {
        match self {
            Input::Throttle => "throttle_set_point",
            Input::LoadL => "load_L_set_point",
            Input::LoadR => "load_R_set_point",
            Input::Supply => "supply_voltage",
        }
    }

    /// Unit.
    pub fn unit(self) -> &'static str {
        match self {
            Input::Supply => "V",
            _ => "%",
        }
    }

    /// One line for the description.
    pub fn doc(self) -> &'static str {
        match self {
            Input::Throttle => {
                "throttle set point, signed (negative: reverse); held over each communication step"
            }
            Input::LoadL => "load L set point, + regenerating, - motoring; held over each communication step",
            Input::LoadR => "load R set point, + regenerating, - motoring; held over each communication step",
            Input::Supply => {
                "DPU supply voltage set point (battery emulation); the busbar voltage is an output"
            }
        }
    }
}

/// Set points accepted [%]: the range `model_core::Profile` accepts.
pub const SET_POINT_RANGE: (f64, f64) = (-100.0, 100.0);

/// A parameter that chooses between two model variants (an FMI Enumeration).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Choice {
    RateSet,
    SpeedTarget,
    Coupling,
}

impl Choice {
    /// Every choice.
    pub const ALL: [Choice; 3] = [Choice::RateSet, Choice::SpeedTarget, Choice::Coupling];

    /// Variable name (also the key in the FMU's settings file).
    pub fn name(self) -> &'static str {
        match self {
            Choice::RateSet => "rate_set",
            Choice::SpeedTarget => "speed_target",
            Choice::Coupling => "coupling",
        }
    }

    /// The enumeration type's name.
    pub fn type_name(self) -> &'static str {
        match self {
            Choice::RateSet => "RateSet",
            Choice::SpeedTarget => "SpeedTarget",
            Choice::Coupling => "Coupling",
        }
    }

    /// One line for the description.
    pub fn doc(self) -> &'static str {
        match self {
            Choice::RateSet => "Curtis rate parameters",
            Choice::SpeedTarget => "how the mapped throttle becomes a target speed",
            Choice::Coupling => "flexible coupling stiffness",
        }
    }

    /// The items `(name, description)`; item `k` has the value `k + 1`. The names are
    /// `simrod simulate`'s flag values (`--params`, `--speed-target`, `--coupling`).
    pub fn items(self) -> &'static [(&'static str, &'static str)] {
        match self {
            Choice::RateSet => &[
                ("programmed", "as programmed into the controller (thesis table 5.16)"),
                ("identified", "as identified on the bench (thesis table 5.17)"),
            ],
            Choice::SpeedTarget => &[
                ("map", "identified speed map (thesis fig. 5.7)"),
                ("parameter", "mapped throttle x Max Speed, then the measured limits (thesis fig. 6.3)"),
            ],
            Choice::Coupling => &[
                ("identified", "4369 N m/rad, identified (thesis table 5.10)"),
                ("datasheet", "10310 N m/rad, Flender datasheet (thesis table 5.10)"),
            ],
        }
    }

    /// The value of item `name`.
    pub fn value_of(self, name: &str) -> Option<i64> {
        self.items().iter().position(|(n, _)| *n == name).map(|k| k as i64 + 1)
    }

    /// The name of the item with value `v`.
    pub fn item_name(self, v: i64) -> Option<&'static str> {
        let k = usize::try_from(v.checked_sub(1)?).ok()?;
        self.items().get(k).map(|(n, _)| *n)
    }
}

/// The model variants the choices select.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Choices {
    pub rates: RateSet,
    pub speed_target: SpeedTarget,
    pub coupling: CouplingStiffness,
}

impl Default for Choices {
    /// The model's defaults (`simrod simulate`'s).
    fn default() -> Self {
        Self {
            rates: RateSet::Identified,
            speed_target: SpeedTarget::Map,
            coupling: CouplingStiffness::Identified,
        }
    }
}

impl Choices {
    /// The enumeration value of one choice.
    pub fn get(&self, c: Choice) -> i64 {
        let second = match c {
            Choice::RateSet => self.rates == RateSet::Identified,
            Choice::SpeedTarget => self.speed_target == SpeedTarget::Parameter,
            Choice::Coupling => self.coupling == CouplingStiffness::Datasheet,
        };
        if second {
            2
        } else {
            1
        }
    }

    /// Set one choice by enumeration value; an error names the accepted items.
    pub fn set(&mut self, c: Choice, v: i64) -> Result<(), String> {
        let first = match c.item_name(v) {
            Some(_) => v == 1,
            None => {
                let items: Vec<String> =
                    c.items().iter().enumerate().map(|(k, (n, _))| format!("{} = {n}", k + 1)).collect();
                return Err(format!(
                    "{} = {v} is not an item of {}; expected {}",
                    c.name(),
                    c.type_name(),
                    items.join(", ")
                ));
            }
        };
        match c {
            Choice::RateSet => self.rates = if first { RateSet::Programmed } else { RateSet::Identified },
            Choice::SpeedTarget => {
                self.speed_target = if first { SpeedTarget::Map } else { SpeedTarget::Parameter }
            }
            Choice::Coupling => {
                self.coupling =
                    if first { CouplingStiffness::Identified } else { CouplingStiffness::Datasheet }
            }
        }
        Ok(())
    }

    /// Set one choice by item name (the settings file).
    pub fn set_by_name(&mut self, c: Choice, name: &str) -> Result<(), String> {
        match c.value_of(name) {
            Some(v) => self.set(c, v),
            None => {
                let items: Vec<&str> = c.items().iter().map(|(n, _)| *n).collect();
                Err(format!("{} = \"{name}\": expected one of {}", c.name(), items.join(", ")))
            }
        }
    }
}

/// One effect parameter: its effect and its declaration.
#[derive(Debug, Clone, Copy)]
pub struct EffectParam {
    /// Running index over all effects' parameters.
    pub index: usize,
    pub effect: &'static EffectDecl,
    pub param: &'static ParamDecl,
}

impl EffectParam {
    /// Variable name: `effect.parameter`, the effect file's vocabulary.
    pub fn name(&self) -> String {
        format!("{}.{}", self.effect.id, self.param.name)
    }
}

/// Every effect parameter, in declaration order.
pub fn effect_params() -> impl Iterator<Item = EffectParam> {
    EFFECTS
        .iter()
        .flat_map(|e| e.params.iter().map(move |p| (e, p)))
        .enumerate()
        .map(|(index, (effect, param))| EffectParam { index, effect, param })
}

/// One variable of the FMU.
#[derive(Debug, Clone, Copy)]
pub enum Var {
    Time,
    Input(Input),
    Choice(Choice),
    Output(Channel),
    Effect(EffectParam),
}

/// FMI type of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Type {
    Float64,
    /// Read and written through the Int64 functions.
    Enumeration,
}

impl Type {
    /// The element name in the model description.
    pub fn name(self) -> &'static str {
        match self {
            Type::Float64 => "Float64",
            Type::Enumeration => "Enumeration",
        }
    }
}

impl Var {
    /// The variable of a value reference.
    pub fn from_vr(vr: u32) -> Option<Var> {
        let index = |base: u32| usize::try_from(vr.checked_sub(base)?).ok();
        match vr {
            VR_TIME => Some(Var::Time),
            _ if vr < VR_CHOICE => Input::ALL.get(index(VR_INPUT)?).copied().map(Var::Input),
            _ if vr < VR_OUTPUT => Choice::ALL.get(index(VR_CHOICE)?).copied().map(Var::Choice),
            _ if vr < VR_EFFECT => Channel::ALL.get(index(VR_OUTPUT)?).copied().map(Var::Output),
            _ => effect_params().nth(index(VR_EFFECT)?).map(Var::Effect),
        }
    }

    /// Every variable, in value-reference order.
    pub fn all() -> Vec<Var> {
        let mut v = vec![Var::Time];
        v.extend(Input::ALL.map(Var::Input));
        v.extend(Choice::ALL.map(Var::Choice));
        v.extend(Channel::ALL.iter().copied().map(Var::Output));
        v.extend(effect_params().map(Var::Effect));
        v
    }

    /// Its value reference.
    pub fn vr(&self) -> u32 {
        let at = |base: u32, i: usize| base + i as u32;
        match self {
            Var::Time => VR_TIME,
            Var::Input(i) => at(VR_INPUT, i.index()),
            Var::Choice(c) => at(VR_CHOICE, *c as usize),
            Var::Output(c) => at(VR_OUTPUT, *c as usize),
            Var::Effect(p) => at(VR_EFFECT, p.index),
        }
    }

    /// Its name.
    pub fn name(&self) -> String {
        match self {
            Var::Time => "time".into(),
            Var::Input(i) => i.name().into(),
            Var::Choice(c) => c.name().into(),
            Var::Output(c) => c.name().into(),
            Var::Effect(p) => p.name(),
        }
    }

    /// Its FMI type.
    pub fn ty(&self) -> Type {
        match self {
            Var::Choice(_) => Type::Enumeration,
            _ => Type::Float64,
        }
    }

    /// Its unit as the declarations write it (`-`: dimensionless).
    pub fn unit(&self) -> &'static str {
        match self {
            Var::Time => "s",
            Var::Input(i) => i.unit(),
            Var::Choice(_) => "-",
            Var::Output(c) => c.unit(),
            Var::Effect(p) => p.param.unit,
        }
    }

    /// Whether the importer may set it in the mode where only inputs can be set (Step
    /// Mode): inputs only; parameters are fixed at initialization.
    pub fn is_input(&self) -> bool {
        matches!(self, Var::Input(_))
    }

    /// Whether it can be set at all (before initialization ends).
    pub fn is_settable(&self) -> bool {
        matches!(self, Var::Input(_) | Var::Choice(_) | Var::Effect(_))
    }

    /// What it is, for messages: `output \`SuTMotorEnc\``.
    pub fn describe(&self) -> String {
        let kind = match self {
            Var::Time => "independent variable",
            Var::Input(_) => "input",
            Var::Choice(_) => "parameter",
            Var::Output(_) => "output",
            Var::Effect(_) => "parameter",
        };
        format!("{kind} `{}` ({}, value reference {})", self.name(), self.ty().name(), self.vr())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_references_round_trip_and_are_unique() {
        let all = Var::all();
        let mut vrs: Vec<u32> = all.iter().map(Var::vr).collect();
        for v in &all {
            let back = Var::from_vr(v.vr()).unwrap();
            assert_eq!(back.name(), v.name());
        }
        let n = vrs.len();
        vrs.sort_unstable();
        vrs.dedup();
        assert_eq!(vrs.len(), n, "value references are unique");
        let mut names: Vec<String> = all.iter().map(Var::name).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), n, "names are unique");
        assert_eq!(all.len(), 1 + 4 + 3 + Channel::ALL.len() + effect_params().count());
        for vr in [5, 99, 103, VR_OUTPUT + Channel::ALL.len() as u32, VR_EFFECT + 10_000, u32::MAX] {
            assert!(Var::from_vr(vr).is_none(), "{vr}");
        }
    }

    #[test]
    fn choices_by_value_and_name() {
        let mut c = Choices::default();
        assert_eq!(c.get(Choice::RateSet), Choice::RateSet.value_of("identified").unwrap());
        c.set(Choice::RateSet, 1).unwrap();
        assert_eq!(c.rates, RateSet::Programmed);
        c.set_by_name(Choice::Coupling, "datasheet").unwrap();
        assert_eq!(c.coupling, CouplingStiffness::Datasheet);
        assert_eq!(c.get(Choice::Coupling), 2);
        let e = c.set(Choice::SpeedTarget, 3).unwrap_err();
        assert!(e.contains("1 = map, 2 = parameter"), "{e}");
        assert!(c.set(Choice::SpeedTarget, i64::MIN).is_err());
        assert!(c.set_by_name(Choice::SpeedTarget, "Map").unwrap_err().contains("map, parameter"));
    }
}
