//! `hil-sim sweep`: the mismatch sweep of issue 18 for one robot
//! ([`crate::sweep`]).

use super::robot_arg::RobotArgs;
use crate::scenario::Robot;
use crate::sweep::{run_sweep, sweep_text};
use clap::Args;
use std::io::Write;

/// `sweep` options.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// The robot files (`--robot`: the controller's robot and the plant's
    /// base; `--plant`: another base for the plant).
    #[command(flatten)]
    pub robots: RobotArgs,
    /// Seeds (measurement noise) per case and controller: 1..=N.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=100))]
    pub seeds: u64,
    /// Run length [s].
    #[arg(long, value_name = "s", default_value_t = 40.0)]
    pub duration: f64,
    /// Print the rows as JSON.
    #[arg(long)]
    pub json: bool,
}

/// `sweep`: every case with the three controllers; the table or JSON.
pub fn sweep(a: &SweepArgs, out: &mut dyn Write) -> Result<(), String> {
    let (robot, plant) = a.robots.load()?;
    let robot = robot.unwrap_or_else(Robot::paper);
    let seeds: Vec<u64> = (1..=a.seeds).collect();
    let rows = run_sweep(&robot, plant.as_ref(), &seeds, a.duration)?;
    let text = if a.json {
        serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())? + "\n"
    } else {
        sweep_text(&robot, &rows)
    };
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())
}
