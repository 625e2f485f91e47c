//! `simrod bench`: a virtual test bench. It runs a plant — the independent physics plant
//! (`simrod-plant`, the default) or the twin — with any effects switched on
//! ([`bench_effects`]: the twin's, bench-only physics, the acquisition's [`daq`]), on
//! the identified or a perturbed data set ([`perturb`]), puts a measurement chain on top
//! ([`bench`] is the one path) and writes what the real bench's data
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
//! seeded by SplitMix64 from `--seed` ([`simrod_numerics::stats::Rng`]), one stream per channel,
//! so the same seed gives the same file and `--miscount` changes only SiemensEnc.
//!
//! Rows: one per model step, at the end of the step (`t = dt, 2 dt, ...`), the timing
//! convention `simrod compare` assumes.

pub mod bench;
pub mod bench_effects;
pub mod chain;
pub mod daq;
pub mod encoder;
pub mod noise;
pub mod perturb;
pub mod scenario;
