//! `simrod diagnose`: which physical effect does the model lack? (See `engine`.)

pub mod empirical;
pub mod engine;
pub mod library;
pub mod linalg;
/// The hidden-effect proof harness (tests and sweeps only, not the public library).
#[cfg(feature = "proof")]
pub mod proof;
pub mod twin;
pub mod within_uncertainty;

// The stages of `engine::diagnose`, in order.
mod alias;
mod confounding;
mod constancy;
mod dynamics;
mod locate;
mod normal;
mod preparation;
mod refit;
mod scan;
mod selection;
mod sensitivities;
mod systematic;
mod uncertainty;
mod unread;
mod verdict;

pub use engine::{diagnose, Diagnosis, Options, ProbeRate, ProfileProbe, Twin, Unnamed, VerdictKind};
pub use within_uncertainty::{estimate_within_uncertainty, Estimate};
