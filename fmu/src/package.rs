//! Packaging: build the FMU's binary and zip the standard layout.
//!
//! ```text
//! simrod.fmu
//! ├── modelDescription.xml
//! ├── binaries/x86_64-linux/simrod.so      this crate's cdylib, release build
//! └── resources/
//!     ├── simrod-fmu.toml                   step and start values (spec::Settings)
//!     ├── effects.toml                      the --effects file, if given
//!     └── data/                             the --data-dir directory, if given
//! ```
//!
//! The resources are staged first and read back with [`Spec::load`], the FMU's own
//! loader, and the model description is generated from what it loaded: what the
//! description declares is what the binary runs. `cargo xtask fmu` and the tests both
//! come through [`package`].

use std::io::{Cursor, Write};
use std::path::{Path, PathBuf};
use std::process::Command;

use model_core::model::DT_US_RANGE;
use model_core::Effects;
use simrod_io::atomic::write_atomic;
use simrod_io::datadir::ModelData;
use simrod_io::effects_file::load_effects;
use simrod_io::guard::Inputs;
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, ZipWriter};

use crate::description::{model_description, token, MODEL_IDENTIFIER};
use crate::spec::{Settings, Spec, DATA_DIR, EFFECTS_FILE, SETTINGS_FILE};

/// The binary's platform tuple, as FMI 3.0 names the directory under `binaries/`.
pub const PLATFORM: &str = "x86_64-linux";

/// What to package.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// The `.fmu` file to write (replaced atomically).
    pub out: PathBuf,
    /// A model data directory to run instead of the compiled-in data.
    pub data_dir: Option<PathBuf>,
    /// An effect file whose effects are the effect parameters' start values.
    pub effects: Option<PathBuf>,
    /// Step and start values.
    pub settings: Settings,
}

/// What was written.
#[derive(Debug, Clone)]
pub struct Packaged {
    pub path: PathBuf,
    pub token: String,
    /// Number of variables in the model description.
    pub variables: usize,
    pub bytes: u64,
}

/// The workspace's root (this crate sits in `fmu/`).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// `<target>/fmu-build`: the build directory of the FMU's binary. Separate from the
/// workspace's own, whose lock a running `cargo test` holds (a nested build there would
/// wait forever).
pub fn build_dir() -> PathBuf {
    let target = match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) if Path::new(&d).is_absolute() => PathBuf::from(d),
        Some(d) => workspace_root().join(d),
        None => workspace_root().join("target"),
    };
    target.join("fmu-build")
}

/// Build this crate's cdylib in release into `build_dir`; the library's path.
pub fn build_library(build_dir: &Path) -> Result<PathBuf, String> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(workspace_root())
        .args(["build", "-p", env!("CARGO_PKG_NAME"), "--release", "--lib", "--target-dir"])
        .arg(build_dir)
        // No debug information in the FMU's binary (40 MB with it, 8 MB zipped); the
        // symbols stay, for backtraces in valgrind and debuggers.
        .env("CARGO_PROFILE_RELEASE_DEBUG", "false")
        .env("CARGO_PROFILE_RELEASE_STRIP", "debuginfo")
        .output()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !out.status.success() {
        return Err(format!("building the FMU's library failed:\n{}", String::from_utf8_lossy(&out.stderr)));
    }
    let lib = build_dir.join("release").join(format!("lib{}.so", env!("CARGO_CRATE_NAME")));
    if !lib.is_file() {
        return Err(format!("cargo built, but {} is missing", lib.display()));
    }
    Ok(lib)
}

/// Check the options and stage the resources, build the binary, write the FMU: a bad
/// option is refused before the build.
pub fn package(opts: &Options) -> Result<Packaged, String> {
    let staged = stage(opts)?;
    let lib = build_library(&build_dir())?;
    finish(opts, staged, &lib)
}

/// The step must be one the model accepts; the output a file in an existing directory
/// and none of the inputs.
fn check_paths(opts: &Options) -> Result<(), String> {
    let dt = opts.settings.dt_us;
    if !(DT_US_RANGE.0..=DT_US_RANGE.1).contains(&dt) {
        return Err(format!("--dt-us {dt}: expected a step in [{}, {}] µs", DT_US_RANGE.0, DT_US_RANGE.1));
    }
    let out = &opts.out;
    Inputs::new()
        .file("--effects", opts.effects.as_deref())
        .dir("--data-dir", opts.data_dir.as_deref())
        .check("--out", out)?;
    if out.file_name().is_none() || out.is_dir() {
        return Err(format!("--out {}: expected a file name", out.display()));
    }
    match out.parent() {
        Some(d) if !d.as_os_str().is_empty() && !d.is_dir() => {
            Err(format!("--out {}: directory {} does not exist", out.display(), d.display()))
        }
        _ => Ok(()),
    }
}

/// Resources staged and read back, with the model description generated from them.
struct Staged {
    dir: tempfile::TempDir,
    spec: Spec,
    xml: String,
}

/// Check the paths, stage the resources, load them with the FMU's loader and generate
/// the model description.
fn stage(opts: &Options) -> Result<Staged, String> {
    check_paths(opts)?;
    let dir = tempfile::tempdir().map_err(|e| format!("cannot make a staging directory: {e}"))?;
    let resources = dir.path().join("resources");
    stage_resources(opts, &resources)?;
    let spec = Spec::load(&resources).map_err(|e| format!("the staged resources do not load: {e}"))?;
    let xml = model_description(&spec)?;
    Ok(Staged { dir, spec, xml })
}

/// Zip the model description, the library `lib` and the resources; write the FMU
/// atomically.
fn finish(opts: &Options, staged: Staged, lib: &Path) -> Result<Packaged, String> {
    let library = std::fs::read(lib).map_err(|e| format!("{}: cannot read: {e}", lib.display()))?;
    let mut files: Vec<(String, Vec<u8>)> = vec![
        ("modelDescription.xml".into(), staged.xml.into_bytes()),
        (format!("binaries/{PLATFORM}/{MODEL_IDENTIFIER}.so"), library),
    ];
    for path in walk(&staged.dir.path().join("resources"))? {
        let rel = path.strip_prefix(staged.dir.path()).map_err(|e| e.to_string())?;
        let name = rel.to_str().ok_or_else(|| format!("{}: not UTF-8", rel.display()))?.to_string();
        let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        files.push((name, bytes));
    }
    let zipped = zip_files(&files).map_err(|e| format!("zipping the FMU: {e}"))?;
    write_atomic(&opts.out, |w| w.write_all(&zipped))
        .map_err(|e| format!("cannot write {}: {e}", opts.out.display()))?;
    Ok(Packaged {
        path: opts.out.clone(),
        token: token(&staged.spec)?,
        variables: crate::vars::Var::all().len(),
        bytes: zipped.len() as u64,
    })
}

/// Write the settings, and copy the effect file and the data directory (read with the
/// workspace's readers first, so a broken input is named with its flag, file and line).
fn stage_resources(opts: &Options, resources: &Path) -> Result<(), String> {
    std::fs::create_dir_all(resources).map_err(|e| format!("{}: {e}", resources.display()))?;
    let put = |name: &str, bytes: &[u8]| {
        let p = resources.join(name);
        std::fs::write(&p, bytes).map_err(|e| format!("{}: {e}", p.display()))
    };
    put(SETTINGS_FILE, opts.settings.to_toml().as_bytes())?;
    let mut effects = Effects::NONE;
    if let Some(fx) = &opts.effects {
        effects = load_effects(fx).map_err(|e| format!("--effects {e}"))?;
        effects.check_delays(opts.settings.dt_us).map_err(|m| format!("--effects {}: {m}", fx.display()))?;
        let bytes = std::fs::read(fx).map_err(|e| format!("--effects {}: cannot read: {e}", fx.display()))?;
        put(EFFECTS_FILE, &bytes)?;
    }
    let data = match &opts.data_dir {
        Some(dir) => {
            let data = ModelData::load(dir).map_err(|e| format!("--data-dir {e}"))?;
            data.write(&resources.join(DATA_DIR)).map_err(|e| format!("staging --data-dir: {e}"))?;
            Some(data)
        }
        None => None,
    };
    let spec = Spec { settings: opts.settings, effects, data };
    spec.check_supply(spec.supply_start()).map_err(|m| format!("--supply-v: {m}"))
}

/// Every file under `dir`, sorted (a reproducible archive).
fn walk(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut out = Vec::new();
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .map(|e| e.map(|e| e.path()).map_err(|e| e.to_string()))
        .collect::<Result<_, _>>()?;
    entries.sort();
    for p in entries {
        if p.is_dir() {
            out.extend(walk(&p)?);
        } else {
            out.push(p);
        }
    }
    Ok(out)
}

/// The archive: DEFLATE, fixed timestamps (the zip default, 1980-01-01), the binary
/// executable.
fn zip_files(files: &[(String, Vec<u8>)]) -> zip::result::ZipResult<Vec<u8>> {
    let mut z = ZipWriter::new(Cursor::new(Vec::new()));
    for (name, bytes) in files {
        let mode = if name.starts_with("binaries/") { 0o755 } else { 0o644 };
        let o = SimpleFileOptions::default()
            .compression_method(CompressionMethod::Deflated)
            .unix_permissions(mode);
        z.start_file(name.as_str(), o)?;
        z.write_all(bytes)?;
    }
    Ok(z.finish()?.into_inner())
}
