//! The running twin of an instance: the model together with the data it borrows.
//!
//! `Model<'a>` borrows its maps; with a data directory in the resources they live in
//! the instance's [`Spec`], so model and spec are one self-referential pair, built by
//! `self_cell` (the unsafe code that takes is in that crate's macro, none of ours).

use std::sync::Arc;

use model_core::{Effects, Inputs, Model, Outputs};
use self_cell::self_cell;

use crate::spec::Spec;
use crate::vars::Choices;

self_cell!(
    /// A model and the spec whose maps it borrows.
    pub struct Twin {
        owner: Arc<Spec>,
        #[covariant]
        dependent: Model,
    }
    impl {Debug}
);

impl Twin {
    /// A model at rest with the given choices and effects.
    pub fn build(spec: Arc<Spec>, choices: &Choices, effects: Effects) -> Result<Self, String> {
        Twin::try_new(spec, |s| s.model(choices, effects))
    }

    /// One fixed step.
    pub fn step(&mut self, inputs: &Inputs) -> Outputs {
        self.with_dependent_mut(|_, m| m.step(inputs))
    }

    /// [µs] the model's time.
    pub fn t_us(&self) -> u64 {
        self.borrow_dependent().t_us()
    }
}
