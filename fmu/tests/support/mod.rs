//! What the FMU's tests share: the packaged FMU (through `simrod_fmu::package`, the
//! code `cargo xtask fmu` runs), the validators' Python environment, extraction.
#![allow(dead_code)] // each test binary uses part of it

pub mod capi;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use simrod_fmu::package::{self, workspace_root, Options};

/// `<target>/fmu-tests/<sub>`: this binary's scratch directory (fresh per call).
pub fn scratch(sub: &str) -> PathBuf {
    let target =
        package::build_dir().parent().map_or_else(|| workspace_root().join("target"), Path::to_path_buf);
    let dir = target.join("fmu-tests").join(env!("CARGO_CRATE_NAME")).join(sub);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    dir
}

/// Package an FMU with `opts` (its `out` inside this binary's scratch area).
pub fn package_fmu(opts: Options) -> PathBuf {
    let t0 = std::time::Instant::now();
    let p = package::package(&opts).unwrap_or_else(|e| panic!("packaging the FMU failed: {e}"));
    eprintln!(
        "packaged {} ({:.1} MB, {} variables) in {:.1} s",
        p.path.display(),
        p.bytes as f64 / 1e6,
        p.variables,
        t0.elapsed().as_secs_f64()
    );
    p.path
}

/// The FMU with every default (built-in data, no effects, 1 ms), packaged once per
/// test binary.
pub fn default_fmu() -> &'static Path {
    static FMU: OnceLock<PathBuf> = OnceLock::new();
    FMU.get_or_init(|| {
        let dir = scratch("default");
        package_fmu(Options { out: dir.join("simrod.fmu"), ..Options::default() })
    })
}

/// The validators' virtual environment: `$SIMROD_PY_ENV`, else `target/py-env`. Fails
/// (never skips) when it is missing.
pub fn py_env() -> PathBuf {
    let env = std::env::var_os("SIMROD_PY_ENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join("target/py-env"));
    assert!(
        env.join("bin/python").is_file()
            && env.join("bin/fmpy").is_file()
            && env.join("bin/fmutool").is_file(),
        "the FMU validators' Python environment is missing at {}: create it with scripts/py-env.sh \
         (FMPy and fmu-manipulation-toolbox at pinned versions; scripts/test-all.sh does this)",
        env.display()
    );
    env
}

/// Run a program; its output (stdout and stderr), whatever its exit status.
pub fn run(program: &Path, args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    let mut cmd = Command::new(program);
    for a in args {
        cmd.arg(a);
    }
    cmd.output().unwrap_or_else(|e| panic!("cannot run {}: {e}", program.display()))
}

/// stdout and stderr as one text, for messages.
pub fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// Unzip `fmu` into `dir` (the layout an importer extracts).
pub fn extract(fmu: &Path, dir: &Path) {
    let file = std::fs::File::open(fmu).unwrap_or_else(|e| panic!("{}: {e}", fmu.display()));
    let mut z = zip::ZipArchive::new(file).unwrap_or_else(|e| panic!("{}: not a zip: {e}", fmu.display()));
    z.extract(dir).unwrap_or_else(|e| panic!("extracting {}: {e}", fmu.display()));
}

/// The instantiation token a model description declares.
pub fn token_of(xml: &str) -> String {
    let key = "instantiationToken=\"";
    let start = xml.find(key).expect("instantiationToken in the model description") + key.len();
    let len = xml[start..].find('"').expect("closing quote");
    xml[start..start + len].to_string()
}

/// The workspace's `path`.
pub fn ws(path: &str) -> PathBuf {
    workspace_root().join(path)
}
