//! Hardware-in-the-loop runs on the host: the firmware runtime
//! ([`RuntimeSide`]) closed through the scenario's simulated hardware
//! ([`crate::closed_loop::world::hardware_world`]).
//!
//! Only sensors and actuators are simulated: encoder decoding, speed
//! estimation, the pose estimator, the controller, torque-to-duty mapping
//! and the safety supervisor are the code the firmware runs.

use crate::closed_loop::{run_loop_ending, trace_every, SimOutput};
use crate::scenario::{Scenario, Sensing};
use controller_core::{ControllerConfig, ControllerKind};

pub use crate::closed_loop::SensingReport;
pub use crate::sides::runtime::{HilOptions, RuntimeSide};

/// Result of a HIL run.
#[derive(Clone, Debug)]
pub struct HilOutput {
    /// Trace and metrics, as for [`crate::run`].
    pub sim: SimOutput,
    /// The estimator's status and the pose source's counters at the end.
    pub sensing: SensingReport,
}

/// Runs `scn` (a firmware sensing preset) with `controller` through the firmware
/// runtime; a trace every `trace_every` steps (0 = none).
pub fn run_runtime(
    scn: &Scenario,
    controller: ControllerConfig,
    opts: HilOptions,
    trace_every: usize,
) -> Result<HilOutput, String> {
    scn.validate()?;
    if scn.sensing.preset == Sensing::Ideal {
        return Err("the firmware runtime needs a firmware sensing preset, not ideal".into());
    }
    let cfg = scn.runtime_config(controller, opts.safety.unwrap_or(scn.safety_limits()));
    let est = opts
        .estimator
        .unwrap_or_else(|| scn.derive(controller.kind).estimator);
    let mut side = RuntimeSide::new(cfg, est)?;
    let mut world = crate::closed_loop::world::hardware_world(scn, &cfg, opts.dead_encoder)?;
    let mut sim = run_loop_ending(scn, &mut world, &mut side, trace_every, opts.end_at_stop)?;
    let sensing = SensingReport {
        estimator: side.estimator_status(),
        pose_source: world.pose_stats(),
    };
    sim.sensing = Some(sensing);
    Ok(HilOutput { sim, sensing })
}

/// Runs `scn` (a firmware sensing preset) with `kind` at the scenario's gains through
/// the firmware runtime; trace every [`crate::closed_loop::TRACE_PERIOD_S`].
pub fn run_hil(
    scn: &Scenario,
    kind: ControllerKind,
    opts: HilOptions,
) -> Result<HilOutput, String> {
    let controller = scn.controller_config(kind);
    run_runtime(scn, controller, opts, trace_every(scn))
}
