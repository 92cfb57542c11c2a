//! Hardware-in-the-loop on the host: the firmware's runtime
//! ([`controller_core::runtime::ControlLoop`]) closed through the simulated
//! world's hardware ([`sim_robot::World`]): 16-bit quadrature counters at
//! the scenario's resolution (wrapping, mirrored mounting) and an H-bridge
//! taking integer duty at the scenario's PWM resolution into the runtime's own
//! DC-motor model, whose torque depends on the wheel speed (back-EMF).
//!
//! With the `imu`, `mocap` and `uwb` presets the runtime also gets the
//! simulated gyro and external pose source of [`sim_robot::sensors`]
//! ([`crate::sensing`] sets them up).
//!
//! Only sensors and actuators are simulated: encoder decoding, speed
//! estimation, the pose estimator, the controller, torque-to-duty mapping
//! and the safety supervisor are the code the firmware runs.

use crate::closed_loop::{ControlOutput, ControlSide};
use controller_core::estimator::{EstimatorConfig, EstimatorStatus};
use controller_core::runtime::{ControlLoop, LoopTimer, RuntimeConfig, SafetyLimits, StopReason};
use controller_core::ControllerKind;
use sim_robot::world::{Actuation, Reading};
use sim_robot::World;

/// Options of a HIL run beyond the scenario: safety thresholds and fault
/// injection. Resolution, sensing and motors come from the [`Scenario`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HilOptions {
    /// Safety thresholds (None = the robot's, `Scenario::safety_limits`).
    pub safety: Option<SafetyLimits>,
    /// Fault injection: from this time \[s\] on, the encoder of wheel
    /// `.0` (0 = right, 1 = left) stops counting (broken wire).
    pub dead_encoder: Option<(usize, f64)>,
    /// Estimator tuning (None = the derivation's, `Scenario::derive`); its initial
    /// pose and centre-of-mass offset are taken from the scenario.
    pub estimator: Option<EstimatorConfig>,
    /// End the run at the first stop the runtime latches (tuning: a
    /// stopped run's score is the stop; `closed_loop::run_loop_ending`).
    pub end_at_stop: bool,
}

/// The runtime as the controller side of the closed loop, reading and
/// writing the world's simulated hardware ([`sim_robot::World::io`]).
pub struct RuntimeSide {
    control: ControlLoop,
    /// Measures each tick against the schedule, as in the firmware; the
    /// simulated clock advances exactly one period per step.
    timer: LoopTimer,
    /// First safe stop latched, with the step it happened at.
    stop: Option<(usize, StopReason)>,
}

impl RuntimeSide {
    /// The runtime of `cfg` with the estimator `est` (its initial pose and
    /// centre-of-mass offset taken from `cfg`), armed.
    pub fn new(cfg: RuntimeConfig, est: EstimatorConfig) -> Result<Self, String> {
        let mut control =
            ControlLoop::with_estimator(cfg, est).map_err(|e| format!("runtime config: {e}"))?;
        let timer = LoopTimer::from_config(&cfg).map_err(|e| format!("loop timer: {e}"))?;
        control.arm().map_err(|e| format!("arm: {e:?}"))?;
        Ok(Self {
            control,
            timer,
            stop: None,
        })
    }

    /// The estimator's status now.
    pub fn estimator_status(&self) -> EstimatorStatus {
        self.control.estimator_status()
    }
}

impl ControlSide for RuntimeSide {
    fn kind(&self) -> ControllerKind {
        self.control.config().controller.kind
    }

    fn step(&mut self, step: usize, _reading: &Reading, world: &mut World) -> ControlOutput {
        // A µs counter that wraps, like the firmware's (the sensors stamp
        // their samples in the same clock).
        let now_us = (step as u64 * self.timer.period_us() as u64) as u32;
        let timing = self.timer.tick(now_us);
        let io = world.io();
        let rep = self
            .control
            .tick(io.encoders, io.motors, io.gyro, io.pose_source, timing);
        if let (Some(reason), None) = (rep.stopped, self.stop) {
            self.stop = Some((step, reason));
        }
        ControlOutput {
            actuation: Actuation::Bridge(world.bridge()),
            eta_measured: [rep.eta.v_mps as f64, rep.eta.omega_radps as f64],
            diag: rep.diag,
            reference: rep.reference,
            pace: rep.pace,
            pose_used: rep.pose,
        }
    }

    fn rejected_steps(&self) -> u32 {
        self.control.status().input_faults + self.control.status().stops
    }

    fn stop(&self) -> Option<(usize, StopReason)> {
        self.stop
    }
}
