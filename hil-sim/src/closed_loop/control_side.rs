//! The interface between the simulated world ([`sim_robot::World`]) and
//! what controls it: what comes back from one control step
//! ([`ControlOutput`]) and the [`ControlSide`] trait implemented by the
//! bare controller with ideal sensing ([`crate::sim::IdealSide`]) and by the
//! firmware runtime behind the world's simulated hardware
//! ([`crate::hil::RuntimeSide`]).

use controller_core::pacer::PaceReport;
use controller_core::runtime::StopReason;
use controller_core::{ControllerKind, Diagnostics, Pose, RefSample};
use sim_robot::world::{Actuation, Reading};
use sim_robot::World;

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
    /// The pose of G the controller was given this step (the estimator's
    /// fused pose; the exact one with ideal sensing), for the sensing-error
    /// metric.
    pub pose_used: Pose,
}

/// The controller side of the simulated loop.
pub trait ControlSide {
    /// The controller kind (for the fault-estimate metric).
    fn kind(&self) -> ControllerKind;
    /// One control period: step `step` with the world's `reading` (ideal
    /// sensing's exact measurements) and its hardware ([`World::io`]).
    fn step(&mut self, step: usize, reading: &Reading, world: &mut World) -> ControlOutput;
    /// Steps the controller rejected or the runtime stopped on.
    fn rejected_steps(&self) -> u32;
    /// The first stop the runtime latched: (step, reason). None for a
    /// side without a runtime (the ideal side never stops).
    fn stop(&self) -> Option<(usize, StopReason)> {
        None
    }
}

impl<C: ControlSide> ControlSide for &mut C {
    fn kind(&self) -> ControllerKind {
        (**self).kind()
    }
    fn step(&mut self, step: usize, reading: &Reading, world: &mut World) -> ControlOutput {
        (**self).step(step, reading, world)
    }
    fn rejected_steps(&self) -> u32 {
        (**self).rejected_steps()
    }
    fn stop(&self) -> Option<(usize, StopReason)> {
        (**self).stop()
    }
}
