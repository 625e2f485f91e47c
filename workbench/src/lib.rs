//! The simrod workbench: the host-side tool around the `model-core` twin.
//!
//! Modules are grouped by what they do for the user; `main.rs` only parses arguments
//! and dispatches.

pub mod measure;
