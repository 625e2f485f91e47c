//! `simrod diagnose`: which physical effect does the model lack? (See `engine`.)

pub mod engine;
pub mod library;
pub mod linalg;
pub mod proof;
pub mod twin;

pub use engine::{diagnose, Diagnosis, Options, ProfileProbe, Twin, VerdictKind};
