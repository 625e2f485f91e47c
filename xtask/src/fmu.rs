//! `cargo xtask fmu --out simrod.fmu [...]`: the twin as an FMI 3.0 Co-Simulation FMU
//! for x86_64-linux (the packaging itself is `simrod_fmu::package`, which the FMU's
//! tests run too).
//!
//! Why an xtask and not a `simrod` subcommand: it drives a cargo build (the FMU's
//! binary is the `simrod-fmu` cdylib, built in release) and needs the workspace's
//! sources; `simrod` is the twin's user tool and must not depend on a toolchain at run
//! time.

use std::path::PathBuf;

use simrod_fmu::package::{self, Options};
use simrod_fmu::vars::Choice;

pub const USAGE: &str =
    "usage: cargo xtask fmu --out FILE.fmu [--data-dir DIR] [--effects FILE.toml] [--dt-us N]
                       [--params programmed|identified] [--speed-target map|parameter]
                       [--coupling identified|datasheet] [--supply-v V]

  --out FILE.fmu       the FMU to write (replaced atomically; never one of the inputs)
  --data-dir DIR       model data directory to run (format of model-core/data; default: built in)
  --effects FILE.toml  effect file: the effect parameters' start values (default: all off)
  --dt-us N            the twin's fixed step [µs], 10..=10000 (default 1000); fmi3DoStep takes
                       whole multiples of it
  --params, --speed-target, --coupling, --supply-v
                       start values of the FMU's parameters rate_set, speed_target, coupling and
                       of the input supply_voltage; same values and defaults as `simrod simulate`";

/// Parse the arguments of `cargo xtask fmu`.
fn parse(args: &[String]) -> Result<Options, String> {
    let mut o = Options::default();
    let mut out = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = || it.next().cloned().ok_or_else(|| format!("{a} needs a value\n{USAGE}"));
        match a.as_str() {
            "--out" => out = Some(PathBuf::from(value()?)),
            "--data-dir" => o.data_dir = Some(value()?.into()),
            "--effects" => o.effects = Some(value()?.into()),
            "--dt-us" => {
                let v = value()?;
                o.settings.dt_us =
                    v.parse().map_err(|_| format!("--dt-us {v}: expected a whole number of µs"))?;
            }
            "--params" => o.settings.choices.set_by_name(Choice::RateSet, &value()?)?,
            "--speed-target" => o.settings.choices.set_by_name(Choice::SpeedTarget, &value()?)?,
            "--coupling" => o.settings.choices.set_by_name(Choice::Coupling, &value()?)?,
            "--supply-v" => {
                let v = value()?;
                o.settings.supply_v =
                    Some(v.parse().map_err(|_| format!("--supply-v {v}: expected a voltage"))?);
            }
            other => return Err(format!("unknown argument `{other}`\n{USAGE}")),
        }
    }
    o.out = out.ok_or_else(|| format!("--out is required\n{USAGE}"))?;
    Ok(o)
}

/// `cargo xtask fmu`.
pub fn run(args: &[String]) -> Result<(), String> {
    let opts = parse(args)?;
    eprintln!("fmu: building the FMU's binary (cargo build --release -p simrod-fmu) ...");
    let p = package::package(&opts)?;
    println!(
        "wrote {} ({:.1} MB): FMI 3.0 Co-Simulation, {} variables, step {} µs, instantiation token {}",
        p.path.display(),
        p.bytes as f64 / 1e6,
        p.variables,
        opts.settings.dt_us,
        p.token
    );
    Ok(())
}
