//! Host-side tests.

pub mod reference;
