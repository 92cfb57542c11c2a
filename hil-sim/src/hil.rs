//! Hardware-in-the-loop on the host: the firmware's runtime
//! ([`controller_core::runtime::ControlLoop`]) closed through the simulated
//! robot's hardware ([`sim_robot::hardware`]): 16-bit quadrature counters at
//! the scenario's resolution (wrapping, mirrored mounting) and an H-bridge
//! taking integer duty at the scenario's PWM resolution into the runtime's own
//! DC-motor model, whose torque depends on the wheel speed (back-EMF).
//!
//! Only sensors and actuators are simulated: encoder decoding, speed
//! estimation, odometry, the controller, torque-to-duty mapping and the
//! safety supervisor are the code the firmware runs.

use crate::control_side::{Actuation, ControlOutput, ControlSide, Sensed};
use crate::scenario::{Scenario, Sensing};
use crate::sim::{run_loop, trace_every, SimOutput};
use controller_core::runtime::{
    ControlLoop, LoopTimer, PoseSource, RuntimeConfig, SafetyLimits, StopReason, MIRRORED_LEFT,
};
use controller_core::{ControllerConfig, ControllerKind, Pose};
use sim_robot::{MotorDrive, SimDriver, SimEncoders};

/// Options of a HIL run beyond the scenario: safety thresholds and fault
/// injection. Resolution, sensing and motors come from the [`Scenario`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HilOptions {
    /// Safety thresholds.
    pub safety: SafetyLimits,
    /// Fault injection: from this time \[s\] on, the encoder of wheel
    /// `.0` (0 = right, 1 = left) stops counting (broken wire).
    pub dead_encoder: Option<(usize, f64)>,
}

impl Default for HilOptions {
    fn default() -> Self {
        Self {
            safety: SafetyLimits::EXAMPLE,
            dead_encoder: None,
        }
    }
}

/// The pose measurement of one tick, taken once.
struct ExternalPose(Option<Pose>);

impl PoseSource for ExternalPose {
    fn pose(&mut self) -> Option<Pose> {
        self.0.take()
    }
}

/// The runtime as the controller side of [`run_loop`].
pub struct RuntimeSide {
    control: ControlLoop,
    /// Measures each tick against the schedule, as in the firmware; the
    /// simulated clock advances exactly one period per step.
    timer: LoopTimer,
    encoders: SimEncoders,
    bridge: SimDriver,
    external_pose: bool,
    opts: HilOptions,
    /// First safe stop latched, with the step it happened at.
    pub stop: Option<(usize, StopReason)>,
}

impl RuntimeSide {
    /// The runtime for `scn` (firmware sensing) with `controller`, armed.
    pub fn new(
        scn: &Scenario,
        controller: ControllerConfig,
        opts: HilOptions,
    ) -> Result<Self, String> {
        let external_pose = match scn.sensing {
            Sensing::Ideal => {
                return Err("the firmware runtime needs sensing = odometry or external-pose".into())
            }
            Sensing::Odometry => false,
            Sensing::ExternalPose => true,
        };
        let p0 = scn.initial_pose;
        let cfg = RuntimeConfig {
            controller,
            reference: scn.trajectory.reference(),
            initial_pose: Pose::new(p0[0] as f32, p0[1] as f32, p0[2] as f32),
            encoder: scn.encoder(),
            motor: scn.motor(),
            motor_inverted: MIRRORED_LEFT,
            safety: opts.safety,
            pacing: scn.pacing(),
        };
        let mut control = ControlLoop::new(cfg).map_err(|e| format!("runtime config: {e}"))?;
        let timer = LoopTimer::from_config(&cfg).map_err(|e| format!("loop timer: {e}"))?;
        control.arm().map_err(|e| format!("arm: {e:?}"))?;
        Ok(Self {
            control,
            timer,
            encoders: SimEncoders::new(&cfg.encoder),
            bridge: SimDriver::default(),
            external_pose,
            opts,
            stop: None,
        })
    }
}

impl ControlSide for RuntimeSide {
    fn kind(&self) -> ControllerKind {
        self.control.config().controller.kind
    }

    fn step(&mut self, sensed: &Sensed) -> ControlOutput {
        self.encoders.set_angles(sensed.wheel_angle_rad);
        if let Some((wheel, t_dead)) = self.opts.dead_encoder {
            if sensed.t_s >= t_dead {
                self.encoders.kill(wheel);
            }
        }
        let mut pose = ExternalPose(self.external_pose.then_some(sensed.pose));
        // A µs counter that wraps, like the firmware's.
        let now_us = (sensed.step as u64 * self.timer.period_us() as u64) as u32;
        let timing = self.timer.tick(now_us);
        let rep = self
            .control
            .tick(&mut self.encoders, &mut self.bridge, &mut pose, timing);
        if let (Some(reason), None) = (rep.stopped, self.stop) {
            self.stop = Some((sensed.step, reason));
        }
        let cfg = self.control.config();
        ControlOutput {
            actuation: Actuation::Motor(MotorDrive {
                model: *self.control.motor_model(),
                bridge: self.bridge,
                inverted: cfg.motor_inverted,
            }),
            eta_measured: [rep.eta.v_mps as f64, rep.eta.omega_radps as f64],
            diag: rep.diag,
            reference: rep.reference,
            pace: rep.pace,
        }
    }

    fn rejected_steps(&self) -> u32 {
        self.control.status().input_faults + self.control.status().stops
    }
}

/// Result of a HIL run.
#[derive(Clone, Debug)]
pub struct HilOutput {
    /// Trace and metrics, as for [`crate::run`].
    pub sim: SimOutput,
    /// The first safe stop the runtime latched, if any: (step, reason).
    pub stop: Option<(usize, StopReason)>,
}

/// Runs `scn` (firmware sensing) with `controller` through the firmware
/// runtime; a trace every `trace_every` steps (0 = none).
pub fn run_runtime(
    scn: &Scenario,
    controller: ControllerConfig,
    opts: HilOptions,
    trace_every: usize,
) -> Result<HilOutput, String> {
    scn.validate()?;
    let mut side = RuntimeSide::new(scn, controller, opts)?;
    let sim = run_loop(scn, &controller.robot, &mut side, trace_every)?;
    Ok(HilOutput {
        sim,
        stop: side.stop,
    })
}

/// Runs `scn` (firmware sensing) with `kind` at the scenario's gains through
/// the firmware runtime; trace every [`crate::sim::TRACE_PERIOD_S`].
pub fn run_hil(
    scn: &Scenario,
    kind: ControllerKind,
    opts: HilOptions,
) -> Result<HilOutput, String> {
    let controller = crate::sim::controller_config(scn, kind);
    run_runtime(scn, controller, opts, trace_every(scn))
}
