//! [`RobotArgs`]: `--robot FILE` and `--plant FILE`, shared by `run`,
//! `compare`, `montecarlo`, `device` and `sweep`.

use crate::scenario::Robot;
use clap::Args;
use std::path::{Path, PathBuf};

/// The robot files of a command.
#[derive(Debug, Args, Default, Clone)]
pub struct RobotArgs {
    /// Robot file (book/src/how-to/robot-file.md, examples in robots/): the controller's
    /// model, gains, motor, encoder and limits, and the simulated robot
    /// unless --plant names another [default: the paper's robot].
    #[arg(long, value_name = "FILE.toml")]
    pub robot: Option<PathBuf>,
    /// Robot file of the simulated robot, when it differs from the
    /// controller's (model mismatch in any field of the file).
    #[arg(long, value_name = "FILE.toml")]
    pub plant: Option<PathBuf>,
}

/// Reads and validates a robot file; the error names the file, the field
/// and the reason.
pub fn load_robot(path: &Path) -> Result<Robot, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read robot file {}: {e}", path.display()))?;
    Robot::from_toml_str(&text).map_err(|e| format!("robot file {}: {e}", path.display()))
}

impl RobotArgs {
    /// The robots named: (controller's, plant's), each None when not given.
    pub fn load(&self) -> Result<(Option<Robot>, Option<Robot>), String> {
        let robot = self.robot.as_deref().map(load_robot).transpose()?;
        let plant = self.plant.as_deref().map(load_robot).transpose()?;
        Ok((robot, plant))
    }
}
