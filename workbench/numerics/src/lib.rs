//! The workbench's numerics, one of each: statistics (median, moving mean, RMS, one
//! random-number generator) and dense linear algebra on nalgebra.

pub mod linalg;
pub mod stats;
