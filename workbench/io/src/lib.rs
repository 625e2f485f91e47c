//! Everything the workbench reads and writes: measurement files (CSV, MAT) with units,
//! mappings and resampling, model data directories, effect and profile files, simulation
//! CSVs, atomic writes, content hashes, memory and disk budgets, and the errors that name
//! file, line and column.

pub mod atomic;
pub mod budget;
pub mod datadir;
pub mod effects_file;
pub mod error;
pub mod guard;
pub mod map_prior;
pub mod map_uncertainty;
pub mod measure;
pub mod profile_file;
pub mod progress;
pub mod sha256;
pub mod sim_csv;
pub mod toml_util;
pub mod uncertainty_file;
