//! The interface between the simulated robot and what controls it: what the
//! simulated sensors measure ([`Sensed`]), what comes back ([`ControlOutput`]),
//! and the [`ControlSide`] trait implemented by the bare controller with ideal
//! sensing ([`crate::sim::IdealSide`]) and by the firmware runtime behind
//! simulated encoders and an H-bridge ([`crate::hil::RuntimeSide`]).

use controller_core::pacer::PaceReport;
use controller_core::{ControllerKind, Diagnostics, Pose, RefSample};
use sim_robot::{Drive, MotorDrive};

/// What the simulated sensors give the controller side at one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sensed {
    /// Control step index.
    pub step: usize,
    /// Time of the step \[s\].
    pub t_s: f64,
    /// Pose of G with measurement noise (ideal sensing's `pose_noise_m`).
    pub pose: Pose,
    /// True pose of G \[x m, y m, θ rad\] (for the simulated external
    /// pose source).
    pub true_pose: [f64; 3],
    /// True body yaw rate θ̇ \[rad/s\] (for the simulated gyro).
    pub yaw_rate_radps: f64,
    /// True wheel angles φ `[right, left]` \[rad\] (for encoders).
    pub wheel_angle_rad: [f64; 2],
    /// True wheel rates φ̇ `[right, left]` \[rad/s\].
    pub wheel_rate_radps: [f64; 2],
}

/// How the controller side drives the wheels over the next period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Actuation {
    /// Wheel torques `[right, left]` \[N·m\] held over the period.
    Torque([f64; 2]),
    /// The H-bridge's duty held over the period; the motors' torque follows
    /// the wheel speed (back-EMF) within it.
    Motor(MotorDrive),
}

impl Drive for Actuation {
    fn torque_nm(&self, wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        match self {
            Self::Torque(t) => *t,
            Self::Motor(m) => m.torque_nm(wheel_rates_radps),
        }
    }
}

/// What the controller side did in one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControlOutput {
    /// How the wheels are driven over the next period.
    pub actuation: Actuation,
    /// The η = \[v, ω\] the controller used \[m/s, rad/s\].
    pub eta_measured: [f64; 2],
    /// The controller's diagnostics.
    pub diag: Diagnostics,
    /// The reference the controller tracked this step (at the governed time
    /// τ; at the step's time when pacing is off), for the metrics.
    pub reference: RefSample,
    /// Governor and health machine after this step.
    pub pace: PaceReport,
}

/// The controller side of the simulated loop.
pub trait ControlSide {
    /// The controller kind (for the fault-estimate metric).
    fn kind(&self) -> ControllerKind;
    /// One control period.
    fn step(&mut self, sensed: &Sensed) -> ControlOutput;
    /// Steps the controller rejected or the runtime stopped on.
    fn rejected_steps(&self) -> u32;
}

impl<C: ControlSide> ControlSide for &mut C {
    fn kind(&self) -> ControllerKind {
        (**self).kind()
    }
    fn step(&mut self, sensed: &Sensed) -> ControlOutput {
        (**self).step(sensed)
    }
    fn rejected_steps(&self) -> u32 {
        (**self).rejected_steps()
    }
}
