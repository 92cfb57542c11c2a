//! The `hil-sim` command line (clap derive): one file per subcommand
//! (`compare`, `run`, `montecarlo`, `merge`, `bench`, `device`, `report`), the
//! shared arguments in files of their own ([`ScenarioArgs`], [`ControllerArg`]),
//! the text of every subcommand in [`crate::report`]. The binary is a thin
//! wrapper around [`main_entry`]; everything here is library code so tests can
//! drive it. The subcommand files use only the argument files and the modules
//! below the CLI; nothing below imports from here.

pub mod bench;
pub mod compare;
pub mod controller_arg;
pub mod device;
pub mod live;
pub mod merge;
pub mod montecarlo;
pub mod report;
pub mod robot_arg;
pub mod run;
pub mod scenario_args;
pub mod sweep;
#[cfg(test)]
mod tests;
pub mod tune;

pub use controller_arg::ControllerArg;
pub use robot_arg::RobotArgs;
pub use scenario_args::ScenarioArgs;

use clap::{Parser, Subcommand};
use std::io::Write;

/// Host simulator: the controller-core controllers against the paper's
/// differential-drive robot with slip, skid, disturbance and actuator fault.
#[derive(Debug, Parser)]
#[command(name = "hil-sim", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Both paper cases x the three controllers: metrics table, plots, metrics.json.
    Compare(compare::CompareArgs),
    /// One scenario with one controller.
    Run(Box<run::RunArgs>),
    /// N random paper scenarios per controller, in parallel: mean/p95/max of every metric
    /// (or, with --shard, one slice of the runs written to a file for `merge`).
    Montecarlo(montecarlo::McArgs),
    /// Combines shard files of `montecarlo --shard` into the statistics of one run.
    Merge(merge::MergeArgs),
    /// Time per 40 s paper scenario and Monte-Carlo throughput on this machine.
    Bench(bench::BenchArgs),
    /// The simulated robot behind the host link: prints a pseudo-terminal's path
    /// (first stdout line) for `wmr --port PATH ...`.
    Device(Box<device::DeviceArgs>),
    /// Metrics and plots of a trace CSV (`hil-sim run --csv` or `wmr record`).
    Report(report::ReportArgs),
    /// Model-mismatch sweep of one robot (issue 18): wheel radius, track,
    /// friction, motor constant, actuation delay; the three controllers.
    Sweep(sweep::SweepArgs),
    /// Tunes the gains of the three controllers for a robot file over a
    /// Monte-Carlo set drawn around it (book/src/how-to/tuning.md); writes FILE.tuned.toml.
    Tune(Box<tune::TuneArgs>),
    /// Combines shard files of `tune --shard` into the tuned robot file.
    TuneMerge(tune::TuneMergeArgs),
}

/// Executes a parsed command line, writing results to `out`.
pub fn execute(cli: &Cli, out: &mut dyn Write) -> Result<(), String> {
    execute_status(cli, out).map(|_| ())
}

/// [`execute`], returning the exit status of a command that finished
/// without an error: 0, or `tune`'s [`tune::EXIT_KEPT_START`].
pub fn execute_status(cli: &Cli, out: &mut dyn Write) -> Result<i32, String> {
    match &cli.command {
        Command::Tune(a) => return tune::tune_status(a, out),
        Command::TuneMerge(a) => return tune::tune_merge_status(a, out),
        _ => {}
    }
    match &cli.command {
        Command::Compare(a) => compare::compare(a, out),
        Command::Run(a) => run::run(a, out),
        Command::Montecarlo(a) => montecarlo::montecarlo(a, out),
        Command::Merge(a) => merge::merge(a, out),
        Command::Bench(a) => bench::bench(a, out),
        Command::Device(a) => device::device(a, out),
        Command::Report(a) => report::report(a, out),
        Command::Sweep(a) => sweep::sweep(a, out),
        Command::Tune(a) => tune::tune(a, out),
        Command::TuneMerge(a) => tune::tune_merge(a, out),
    }
    .map(|_| 0)
}

/// Exit status of a command that failed (the line after `error: ` on
/// stderr says why).
pub const EXIT_ERROR: i32 = 1;

/// Every exit status of `hil-sim` but clap's usage error (the book's
/// reference, errors.md, adds it from clap).
pub const EXIT_CODES: [(i32, &str); 3] = [
    (0, "the command succeeded"),
    (
        EXIT_ERROR,
        "the command failed: the line after `error:` on stderr says why",
    ),
    (
        tune::EXIT_KEPT_START,
        "`tune`, `tune-merge`: no tuned gains validated better than the robot file's own; the file is written with them and says why",
    ),
];

/// The binary: parse (clap prints usage errors and exits 2), execute, print
/// any error to stderr and return the exit code (0, 1 on an error, or
/// `tune`'s [`tune::EXIT_KEPT_START`]).
pub fn main_entry() -> i32 {
    let cli = Cli::parse();
    let stdout = std::io::stdout();
    let mut lock = stdout.lock();
    match execute_status(&cli, &mut lock) {
        Ok(code) => code,
        Err(e) => {
            let _ = lock.flush();
            eprintln!("error: {e}");
            EXIT_ERROR
        }
    }
}
