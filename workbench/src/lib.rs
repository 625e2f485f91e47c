//! The simrod workbench: the host-side tool around the `model-core` twin.
//!
//! Modules are grouped by what they do for the user; `main.rs` only parses arguments
//! and dispatches.

pub mod atomic;
pub mod cmd_compare;
pub mod cmd_diagnose;
pub mod cmd_history;
pub mod cmd_identify;
pub mod compare;
pub mod datadir;
pub mod demo;
pub mod diagnose;
pub mod effects_file;
pub mod error;
pub mod history;
pub mod identify;
pub mod iterate;
pub mod linalg;
pub mod measure;
pub mod profile_file;
pub mod report;
pub mod sha256;
pub mod sim_csv;
pub mod simulate;
pub mod stats;
pub mod summary;
pub mod toml_util;
pub mod twin;
pub mod vbench;
