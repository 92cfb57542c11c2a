//! Hardware-in-the-loop on the host: the firmware's runtime
//! ([`controller_core::runtime::ControlLoop`]) closed through simulated
//! quadrature encoders (integer 16-bit counts at the encoder's resolution,
//! wrapping, mirrored mounting) and a simulated H-bridge (integer duty at the
//! PWM resolution) driving the runtime's own DC-motor model, whose torque
//! depends on the wheel speed through the back-EMF.
//!
//! Only sensors and actuators are simulated: encoder decoding, speed
//! estimation, odometry, the controller, torque-to-duty mapping and the
//! safety supervisor are the code the firmware runs.

use crate::scenario::Scenario;
use crate::sim::{run_loop, Actuation, ControlSide, Sensed, SimOutput};
use controller_core::runtime::{
    ControlLoop, DutyCommand, EncoderParams, MotorDriver, MotorModel, MotorParams, PoseSource,
    RuntimeConfig, SafetyLimits, StopReason, WheelEncoders,
};
use controller_core::{ControllerKind, Diagnostics, Pose};

/// Options of a HIL run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HilOptions {
    /// Encoder resolution, mounting and speed window.
    pub encoder: EncoderParams,
    /// Motor, gearbox, supply and PWM constants.
    pub motor: MotorParams,
    /// Per wheel: the motor is mounted mirrored (direction output flipped).
    pub motor_inverted: [bool; 2],
    /// Feed the (noisy) true pose as an external measurement every tick;
    /// false = wheel odometry only (blind to slip and to the actuator fault).
    pub external_pose: bool,
    /// Safety thresholds.
    pub safety: SafetyLimits,
    /// Fault injection: from this time \[s\] on, the encoder of wheel
    /// `.0` (0 = right, 1 = left) stops counting (broken wire).
    pub dead_encoder: Option<(usize, f64)>,
}

impl Default for HilOptions {
    fn default() -> Self {
        Self {
            encoder: EncoderParams::EXAMPLE,
            motor: MotorParams::EXAMPLE,
            motor_inverted: [false, true],
            external_pose: true,
            safety: SafetyLimits::EXAMPLE,
            dead_encoder: None,
        }
    }
}

/// A duty command applied to the motor model (the plant side of the bridge).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorActuation {
    model: MotorModel,
    duty: [DutyCommand; 2],
    inverted: [bool; 2],
    enabled: bool,
}

impl MotorActuation {
    /// Wheel torques at the given wheel rates (back-EMF at that speed).
    pub fn torque_nm(&self, wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        if !self.enabled {
            return [0.0; 2];
        }
        let mut out = [0.0; 2];
        for i in 0..2 {
            // A mirrored motor turns opposite to its wheel.
            let sign = if self.inverted[i] { -1.0 } else { 1.0 };
            let motor_rate = (sign * wheel_rates_radps[i]) as f32;
            out[i] = sign * self.model.torque_for_duty(self.duty[i], motor_rate) as f64;
        }
        out
    }
}

/// Simulated encoders: the true wheel angles quantised to counts, as u16.
struct SimEncoders {
    counts_per_rad: f64,
    inverted: [bool; 2],
    angle_rad: [f64; 2],
    /// Per wheel: frozen raw count (dead encoder).
    frozen: [Option<u16>; 2],
}

impl WheelEncoders for SimEncoders {
    fn counts(&mut self) -> [u16; 2] {
        std::array::from_fn(|i| {
            let c = (self.angle_rad[i] * self.counts_per_rad).floor() as i64;
            let c = if self.inverted[i] { -c } else { c };
            // Two's complement wrap, like a 16-bit timer; a dead encoder is frozen.
            self.frozen[i].unwrap_or(c as u16)
        })
    }
}

/// Simulated H-bridge: remembers what the runtime wrote.
#[derive(Default)]
struct SimDriver {
    duty: [DutyCommand; 2],
    enabled: bool,
}

impl MotorDriver for SimDriver {
    fn set(&mut self, cmd: [DutyCommand; 2]) {
        self.duty = cmd;
        self.enabled = true;
    }
    fn disable(&mut self) {
        self.duty = [DutyCommand::ZERO; 2];
        self.enabled = false;
    }
}

struct ExternalPose(Option<Pose>);

impl PoseSource for ExternalPose {
    fn pose(&mut self) -> Option<Pose> {
        self.0.take()
    }
}

/// The runtime as the controller side of [`run_loop`].
pub struct RuntimeSide {
    lp: ControlLoop,
    enc: SimEncoders,
    drv: SimDriver,
    opts: HilOptions,
    /// First safe stop latched, with the step it happened at.
    pub stop: Option<(usize, StopReason)>,
}

impl ControlSide for RuntimeSide {
    fn kind(&self) -> ControllerKind {
        self.lp.config().controller.kind
    }

    fn step(&mut self, k: usize, t_s: f64, sensed: &Sensed) -> (Actuation, [f64; 2], Diagnostics) {
        self.enc.angle_rad = sensed.wheel_angle_rad;
        if let Some((wheel, t_dead)) = self.opts.dead_encoder {
            if t_s >= t_dead && self.enc.frozen[wheel].is_none() {
                self.enc.frozen[wheel] = Some(self.enc.counts()[wheel]);
            }
        }
        let mut pose = ExternalPose(self.opts.external_pose.then_some(sensed.pose));
        let period_us = (self.lp.config().controller.period_s * 1e6) as u32;
        let rep = self
            .lp
            .tick(&mut self.enc, &mut self.drv, &mut pose, period_us);
        if let (Some(reason), None) = (rep.stopped, self.stop) {
            self.stop = Some((k, reason));
        }
        let act = Actuation::Motor(MotorActuation {
            model: *self.lp.motor_model(),
            duty: self.drv.duty,
            inverted: self.opts.motor_inverted,
            enabled: self.drv.enabled,
        });
        let eta = [rep.eta.v_mps as f64, rep.eta.omega_radps as f64];
        (act, eta, rep.diag)
    }

    fn rejected_steps(&self) -> u32 {
        self.lp.status().input_faults + self.lp.status().stops
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

/// Runs `scn` with `kind` through the firmware runtime with simulated
/// encoders and PWM. The scenario's torque limit and k_y apply; its
/// `encoder_cpr`/`pwm_levels` are replaced by `opts`.
pub fn run_hil(
    scn: &Scenario,
    kind: ControllerKind,
    opts: HilOptions,
) -> Result<HilOutput, String> {
    scn.validate()?;
    let controller = crate::sim::controller_config(scn, kind);
    let p0 = scn.initial_pose;
    let cfg = RuntimeConfig {
        controller,
        reference: scn.trajectory.reference(),
        initial_pose: Pose::new(p0[0] as f32, p0[1] as f32, p0[2] as f32),
        encoder: opts.encoder,
        motor: opts.motor,
        motor_inverted: opts.motor_inverted,
        safety: opts.safety,
    };
    let mut lp = ControlLoop::new(cfg).map_err(|e| format!("runtime config: {e}"))?;
    lp.arm().map_err(|e| format!("arm: {e:?}"))?;
    let mut side = RuntimeSide {
        lp,
        enc: SimEncoders {
            counts_per_rad: opts.encoder.counts_per_wheel_rev as f64 / (2.0 * std::f64::consts::PI),
            inverted: opts.encoder.inverted,
            angle_rad: [0.0; 2],
            frozen: [None; 2],
        },
        drv: SimDriver::default(),
        opts,
        stop: None,
    };
    let every = ((0.01 / scn.control_period_s).round() as usize).max(1);
    let sim = run_loop(scn, &controller.robot, &mut side, every)?;
    Ok(HilOutput {
        sim,
        stop: side.stop,
    })
}
