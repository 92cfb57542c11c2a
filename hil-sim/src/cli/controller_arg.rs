//! [`ControllerArg`]: the `--controller` value of every subcommand that runs one.

use clap::ValueEnum;
use controller_core::ControllerKind;

/// The controller to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ControllerArg {
    /// SMC without observer (fixed switching gain).
    Smc,
    /// Adaptive SMC without observer.
    Asmc,
    /// Fault observer + fal-ESO + adaptive SMC (the paper's).
    Proposed,
}

impl From<ControllerArg> for ControllerKind {
    fn from(c: ControllerArg) -> Self {
        match c {
            ControllerArg::Smc => ControllerKind::Smc,
            ControllerArg::Asmc => ControllerKind::Asmc,
            ControllerArg::Proposed => ControllerKind::Proposed,
        }
    }
}
