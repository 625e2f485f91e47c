//! `simrod bench`: a virtual test bench. It runs the twin (with any effects switched
//! on), puts a measurement chain on top and writes what the real bench's data
//! acquisition would export: `time [s]`, the measured channels
//! (`model_core::MEASURED`, bench names and units) and the set points as the PLC logs
//! them (`SuT Throttle [%]`, `Dm Left [%]`, `Dm Right [%]`), as CSV or MAT. The file
//! holds nothing else: no effects, no noise settings, no seed. It is the stand-in for
//! a real measurement when testing the analyses: make a run with a known effect, then
//! see whether `simrod compare` finds it.
//!
//! The chain (numbers and their origin in `workbench/examples/noise.toml`, defaults
//! in [`noise::NoiseModel`]):
//! - torque flanges: Gaussian noise, 0.3 N m, growing to 2.8 N m at the operating
//!   limits (the thesis' "very high" noise there);
//! - speeds: pulse encoders counted in a 0.1 s window centred on each sample: Kistler
//!   60 ppr (T_Kistler_L/R), SuT motor 64 ppr (assumed), Siemens 128 ppr (SiemensEnc),
//!   which with `--miscount` loses up to 20 % of its pulses above 100 rpm (fig. 5.35/5.36);
//! - with `--pulses`, the R shaft's pulse channels as a counter/timer input exports them
//!   (thesis table 5.9): cumulative edge counts `inc:Kistler`, `inc:SiemensEnc` and the
//!   latched time of the last edge `tedge:Kistler`, `tedge:SiemensEnc` [s] (1 µs clock,
//!   0.02° edge jitter; [`chain::pulse_channels`]). Off by default: files stay as they were;
//! - current probes: 0.5 A (Tektronix A622), 1 A (Fluke i1010), 0.1 A (Danisense), more
//!   at the limits; voltages 0.02–0.05 V; throttle voltage 5 mV;
//! - set points: exact (the PLC logs its own numbers).
//!
//! `--noise none` writes the model's values exactly (no noise, no quantisation): read
//! back and rounded to f32 they are the model's bits. Random numbers: xoshiro256**
//! seeded by SplitMix64 from `--seed` ([`crate::stats::Rng`]), one stream per channel,
//! so the same seed gives the same file and `--miscount` changes only SiemensEnc.
//!
//! Rows: one per model step, at the end of the step (`t = dt, 2 dt, ...`), the timing
//! convention `simrod compare` assumes.

pub mod chain;
pub mod encoder;
pub mod noise;

#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use crate::error::CmdError;
use crate::measure::write::{save, Format};
use crate::measure::Measurement;
use crate::simulate::SimulateArgs;
use chain::{measure, ChainOptions, Recorded};
use noise::NoiseModel;

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
