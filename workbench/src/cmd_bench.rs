//! `simrod bench`: the command around the virtual bench ([`crate::vbench`]): the
//! arguments of `simrod simulate` plus the measurement chain, and the file it writes.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use crate::error::CmdError;
use crate::measure::write::{save, Format};
use crate::measure::Measurement;
use crate::simulate::SimulateArgs;
use crate::vbench::chain::{self, measure, ChainOptions, Recorded};
use crate::vbench::noise::NoiseModel;

/// `--noise`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NoiseArg {
    /// The documented defaults.
    Default,
    /// Exact model values.
    None,
    /// A noise TOML file.
    File(PathBuf),
}

fn parse_noise(s: &str) -> Result<NoiseArg, String> {
    Ok(match s {
        "default" => NoiseArg::Default,
        "none" => NoiseArg::None,
        "" => return Err("expected default, none or a noise TOML file".into()),
        f => NoiseArg::File(PathBuf::from(f)),
    })
}

/// Arguments of `simrod bench`: those of `simrod simulate` (profile, scales, `--params`,
/// `--effects`, `--dt-us`, `--out`, ...) plus the measurement chain.
#[derive(Debug, Clone, Args)]
#[command(mut_arg("out", |a| a
    .value_name("FILE.csv|FILE.mat")
    .help("Output file, CSV or MAT by its extension; replaced atomically")))]
pub struct BenchArgs {
    #[command(flatten)]
    pub run: SimulateArgs,

    /// Measurement noise: `default`, `none` (exact model values) or a TOML file
    /// (format: workbench/examples/noise.toml).
    #[arg(long, value_name = "default|none|FILE.toml", default_value = "default", value_parser = parse_noise)]
    pub noise: NoiseArg,

    /// Seed of the noise; the same seed gives the same file.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,

    /// The Siemens encoder loses pulses at high speed (thesis fig. 5.35/5.36).
    #[arg(long)]
    pub miscount: bool,

    /// Also export the R shaft's pulse channels (thesis table 5.9): `inc:Kistler`,
    /// `inc:SiemensEnc` (cumulative edge counts) and `tedge:Kistler`, `tedge:SiemensEnc`
    /// (time of the last edge) — what `simrod identify stiffness` needs.
    #[arg(long)]
    pub pulses: bool,
}

impl BenchArgs {
    /// The chain the arguments ask for (loads the noise file).
    pub fn chain(&self) -> Result<ChainOptions, CmdError> {
        let noise = match &self.noise {
            NoiseArg::Default => Some(NoiseModel::default()),
            NoiseArg::None => None,
            NoiseArg::File(p) => Some(NoiseModel::load(p)?),
        };
        Ok(ChainOptions { noise, seed: self.seed, miscount: self.miscount })
    }
}

/// Run the twin described by `args` and apply the chain; nothing is written.
pub fn bench(args: &BenchArgs) -> Result<Measurement, CmdError> {
    if Format::of(&args.run.out).is_none() {
        return Err(CmdError::Usage(format!(
            "--out {}: the file name must end in .csv or .mat",
            args.run.out.display()
        )));
    }
    let spec = args.run.spec()?;
    let chain = args.chain()?;
    let rec = Recorded::run(spec.simulation()?);
    let mut m = measure(&rec, &chain, &args.run.out);
    if args.pulses {
        m.signals.extend(chain::pulse_channels(&rec, &chain));
    }
    Ok(m)
}

/// `simrod bench`.
pub fn execute(args: &BenchArgs) -> Result<(), CmdError> {
    let start = Instant::now();
    let m = bench(args)?;
    let out: &Path = &args.run.out;
    save(out, &m).map_err(|e| CmdError::Runtime(format!("{}: cannot write: {e}", out.display())))?;
    if !args.run.quiet {
        println!(
            "wrote {}: {} samples of {} channels, {:.3} s of bench time, in {:.2} s",
            out.display(),
            m.time_s.len(),
            m.signals.len(),
            m.time_s.last().copied().unwrap_or(0.0),
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

#[cfg(test)]
#[path = "cmd_bench_tests.rs"]
mod tests;
