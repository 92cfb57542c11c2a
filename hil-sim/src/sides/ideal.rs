//! The bare controller with ideal sensing as the controller side of the
//! closed loop ([`crate::closed_loop`]).

use crate::closed_loop::{ControlOutput, ControlSide};
use controller_core::health::{EstimatorHealth, HealthMode};
use controller_core::pacer::{PacerState, PacingConfig};
use controller_core::trajectory::{Reference, Trajectory};
use controller_core::{Controller, ControllerConfig, ControllerKind, StepInput};
use sim_robot::world::{Actuation, Reading};
use sim_robot::World;

/// The bare controller with ideal measurements (`Sensing::Ideal`, the
/// paper's setting): the world's exact measurements (the pose of G, the
/// wheel rates from the exact wheel-angle change over the last period; see
/// [`sim_robot::world::IdealSensing`]) into η through eq. (3)
/// ([`controller_core::RobotParams::eta_from_wheel_rates`]), torque applied
/// exactly.
///
/// With pacing on, the reference governor and the health machine
/// ([`controller_core::pacer`]) choose the reference time τ and the
/// controller tracks `reference` at τ; a safe stop outputs zero torque
/// from then on.
pub struct IdealSide {
    ctrl: Controller,
    pacer: controller_core::pacer::Pacer,
    pace: PacerState,
    reference: Reference,
    /// Steps without an ideal reading (a world with hardware sensing).
    missing_readings: u32,
}

impl IdealSide {
    /// The controller of `cfg`, paced by `pacing` along `reference`.
    pub fn new(
        cfg: ControllerConfig,
        pacing: PacingConfig,
        reference: Reference,
    ) -> Result<Self, String> {
        let pacer = controller_core::pacer::Pacer::new(pacing, &cfg)
            .map_err(|e| format!("pacing config: {e}"))?;
        Ok(Self {
            ctrl: Controller::new(cfg).map_err(|e| format!("controller config: {e}"))?,
            pace: pacer.initial_state(),
            pacer,
            reference,
            missing_readings: 0,
        })
    }
}

impl ControlSide for IdealSide {
    fn kind(&self) -> ControllerKind {
        self.ctrl.config().kind
    }

    fn step(&mut self, _step: usize, reading: &Reading, _world: &mut World) -> ControlOutput {
        let ideal = reading.ideal.unwrap_or_else(|| {
            // Not an ideal world: nothing to measure with; the torque below
            // is zeroed and the step counted as rejected.
            self.missing_readings += 1;
            sim_robot::world::IdealReading {
                pose: controller_core::Pose::default(),
                wheel_rate_radps: [0.0; 2],
            }
        });
        let eta = self
            .ctrl
            .config()
            .robot
            .eta_from_wheel_rates(ideal.wheel_rate_radps);
        let reference = if self.pacer.enabled() {
            self.pacer.reference(&self.pace, &self.reference, 0.0)
        } else {
            self.reference.sample(reading.t_s as f32)
        };
        let out = self.ctrl.step(&StepInput {
            reference,
            pose: ideal.pose,
            eta,
        });
        let pace = self
            .pacer
            .update(&mut self.pace, &out.diag, eta, EstimatorHealth::Ok);
        let torque = if pace.mode == HealthMode::SafeStop || reading.ideal.is_none() {
            [0.0; 2]
        } else {
            out.torque_nm.map(f64::from)
        };
        ControlOutput {
            actuation: Actuation::Torque(torque),
            eta_measured: [eta.v_mps as f64, eta.omega_radps as f64],
            diag: out.diag,
            reference,
            pace,
            pose_used: ideal.pose,
        }
    }

    fn rejected_steps(&self) -> u32 {
        self.ctrl.rejected_steps() + self.missing_readings
    }
}
