//! Runs of a scenario: the controller side its sensing names (the bare
//! controller with ideal sensing, or the firmware runtime through
//! [`crate::hil`]) against its simulated world, through the closed loop
//! ([`crate::closed_loop`]). The loop's types are re-exported here.

use crate::scenario::{Scenario, Sensing};
use controller_core::{ControllerConfig, ControllerKind};

pub use crate::closed_loop::{
    run_loop, trace_every, SensingReport, SimOutput, TraceSample, TRACE_PERIOD_S,
};
pub use crate::sides::ideal::IdealSide;

/// Controller configuration for a scenario ([`Scenario::controller_config`]).
pub fn controller_config(scn: &Scenario, kind: ControllerKind) -> ControllerConfig {
    scn.controller_config(kind)
}

/// Runs `scn` with the given controller configuration, on the controller
/// side its [`Sensing`] names; logs every `trace_every`-th step (0 = no trace).
pub fn run_with(
    scn: &Scenario,
    cfg: ControllerConfig,
    trace_every: usize,
) -> Result<SimOutput, String> {
    scn.validate()?;
    match scn.sensing.preset {
        Sensing::Ideal => {
            let side = IdealSide::new(cfg, scn.pacing(), scn.trajectory.reference())?;
            let mut world = crate::closed_loop::world::ideal_world(scn, &cfg)?;
            run_loop(scn, &mut world, side, trace_every)
        }
        Sensing::Odometry | Sensing::Imu | Sensing::Mocap | Sensing::Uwb => {
            let opts = crate::hil::HilOptions::default();
            crate::hil::run_runtime(scn, cfg, opts, trace_every).map(|o| o.sim)
        }
    }
}

/// Runs `scn` with `kind` at the paper's gains; trace every [`TRACE_PERIOD_S`].
pub fn run(scn: &Scenario, kind: ControllerKind) -> Result<SimOutput, String> {
    run_with(scn, controller_config(scn, kind), trace_every(scn))
}
