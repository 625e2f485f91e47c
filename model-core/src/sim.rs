//! A model driven by a test profile: what the firmware's basic mode and `simrod
//! simulate` both run.

use crate::model::{Config, ConfigError, Inputs, Model};
use crate::num::Real;
use crate::outputs::Outputs;
use crate::profile::Profile;

/// Model + profile + supply voltage.
#[derive(Debug, Clone)]
pub struct Simulation<'a, R: Real = f32> {
    model: Model<'a, R>,
    profile: Profile,
    supply_v: f32,
}

impl Simulation<'static> {
    /// On the built-in maps.
    pub fn new(cfg: &Config, profile: Profile, supply_v: f32) -> Result<Self, ConfigError> {
        Ok(Self { model: Model::new(cfg)?, profile, supply_v })
    }
}

#[cfg(feature = "fixed")]
impl Simulation<'static, crate::num::Fx> {
    /// The fixed-point twin on the built-in maps ([`Model::new_fx`]).
    pub fn new_fx(cfg: &Config, profile: Profile, supply_v: f32) -> Result<Self, ConfigError> {
        Ok(Self { model: Model::new_fx(cfg)?, profile, supply_v })
    }
}

impl<'a, R: Real> Simulation<'a, R> {
    /// On a model built by the caller (e.g. with run-time maps).
    pub fn from_model(model: Model<'a, R>, profile: Profile, supply_v: f32) -> Self {
        Self { model, profile, supply_v }
    }

    /// Number of steps that cover the profile.
    pub fn total_steps(&self) -> u64 {
        self.profile.duration_us().div_ceil(u64::from(self.model.dt_us()))
    }

    /// The inputs applied at the current time.
    pub fn inputs(&self) -> Inputs {
        Inputs { sp: self.profile.at(self.model.t_us()), supply_v: self.supply_v }
    }

    /// One step; `None` once the profile is over.
    pub fn step(&mut self) -> Option<Outputs<R>> {
        if self.model.t_us() >= self.profile.duration_us() {
            return None;
        }
        let inp = self.inputs();
        Some(self.model.advance(&inp))
    }

    /// The model.
    pub fn model(&self) -> &Model<'a, R> {
        &self.model
    }
}

impl<R: Real> Iterator for Simulation<'_, R> {
    type Item = Outputs<R>;
    fn next(&mut self) -> Option<Outputs<R>> {
        self.step()
    }
}
