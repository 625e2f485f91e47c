//! `simrod`: argument parsing and dispatch only; each command lives in its own library
//! module (`workbench::simulate`, ...).
//!
//! Exit codes: 0 success, 2 usage error (bad argument or input file, reported before
//! any work), 1 runtime error (the work itself failed, e.g. writing the output).

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use workbench::error::CmdError;
use workbench::simulate::{self, SimulateArgs};

#[derive(Debug, Parser)]
#[command(name = "simrod", version, about = "The SimRod e-powertrain twin on the host")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// One variant per command; its arguments and code live in the command's module.
#[derive(Debug, Subcommand)]
enum Command {
    /// Run the twin on a test profile and write every channel to a CSV.
    Simulate(SimulateArgs),
    /// Virtual bench: run the physics plant (or `--plant twin`) with any effects, add the
    /// acquisition's flaws, sensor noise and encoder counting, and write only what the real
    /// bench records (CSV or MAT); `--scenario random` draws a realistic hidden case.
    Bench(workbench::cmd_bench::BenchArgs),
    /// Run the twin on a measured run's inputs and show where they disagree: per
    /// channel, per operating region, worst time spans, residual structure.
    Compare(workbench::cmd_compare::CompareArgs),
    /// Which physical effect does the model lack? Rank the effect library against a
    /// measured run, refit the best, give uncertainties and a verdict; write the effect
    /// file that adds it.
    Diagnose(workbench::cmd_diagnose::DiagnoseArgs),
    /// The error per channel over the iterations of `simrod compare` on a measurement.
    History(workbench::cmd_history::HistoryArgs),
    /// The whole improve-the-model loop in one command: measure a run with a hidden
    /// effect, compare, diagnose, add the effect, compare again.
    Demo(workbench::demo::DemoArgs),
    /// Rebuild the model's maps and parameters from a measured campaign (thesis
    /// chapter 5): writes a complete data directory (for --data-dir or model-core/data),
    /// report.md and charts.
    Identify(workbench::cmd_identify::IdentifyArgs),
    /// Will this test stay inside the bench's limits? Every limit's peak, margin, time and
    /// set; under the model's uncertainty (Monte Carlo) the probability of a violation;
    /// the set point that keeps it inside. Exit 0 approved, 1 not, 2 bad input.
    Check(workbench::cmd_check::CheckArgs),
    /// Close the XiL loop offline: the twin driven by the vehicle-and-road twin (xDT) on
    /// a drive cycle, through the RT platform's delay and sample time; writes every
    /// channel and the vehicle's speed, reports tracking, energy per km, peak flange
    /// torque, stability and (--margin) the delay margin.
    Xil(workbench::cmd_xil::XilArgs),
}

fn dispatch(command: Command) -> Result<(), CmdError> {
    match command {
        Command::Simulate(args) => simulate::execute(&args),
        Command::Bench(args) => workbench::cmd_bench::execute(&args),
        Command::Compare(args) => workbench::cmd_compare::execute(&args),
        Command::Diagnose(args) => workbench::cmd_diagnose::execute(&args),
        Command::History(args) => workbench::cmd_history::execute(&args),
        Command::Demo(args) => workbench::demo::execute(&args),
        Command::Identify(args) => workbench::cmd_identify::execute(&args),
        Command::Check(args) => workbench::cmd_check::execute(&args),
        Command::Xil(args) => workbench::cmd_xil::execute(&args),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse(); // clap reports its own usage errors, with exit code 2
                            // Ctrl-C or a kill during a write leaves no temporary file behind.
    if let Err(e) = workbench::atomic::clean_up_on_signals() {
        eprintln!("warning: cannot watch for signals ({e}); an interrupted write may leave a .tmp file");
    }
    match dispatch(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(1))
        }
    }
}
