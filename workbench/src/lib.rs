//! The simrod workbench CLI: the commands around the `model-core` twin, in the order of
//! the user's loop. The work is done by library crates, one job each (re-exported here
//! under their module names so `workbench::compare::...` keeps naming them):
//!
//! - `simrod-io` (I/O: measurement files, data directories, effect/profile files,
//!   atomic writes) and `simrod-numerics` (statistics, one RNG, linear algebra);
//! - `simrod-vbench`, the virtual bench's measurement chain;
//! - `simrod-twin`, the one path that runs the twin on a measurement;
//! - `simrod-compare`, `simrod-diagnose`, `simrod-identify`;
//! - `simrod-report`, tables, JSON, HTML and the one SVG plotter.
//!
//! The modules of this crate are the commands: they turn flags into the libraries'
//! typed options and results into output.

pub use simrod_compare as compare;
pub use simrod_diagnose as diagnose;
pub use simrod_identify as identify;
pub use simrod_io::{
    atomic, datadir, effects_file, error, measure, profile_file, sha256, sim_csv, toml_util,
};
pub use simrod_numerics::{linalg, stats};
pub use simrod_report as report;
pub use simrod_twin as twin;
pub use simrod_vbench as vbench;

pub mod cmd_bench;
pub mod cmd_check;
pub mod cmd_compare;
pub mod cmd_diagnose;
pub mod cmd_history;
pub mod cmd_identify;
pub mod cmd_xil;
pub mod demo;
pub mod history;
pub mod iterate;
pub mod simulate;
pub mod summary;
pub mod xil_run;
