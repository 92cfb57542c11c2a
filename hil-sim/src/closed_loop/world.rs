//! The scenario's simulated world ([`sim_robot::World`]): its plant (the
//! controller model's robot with the scenario's mass and inertia scales),
//! perturbations, faults and instruments, built in one place for every
//! loop hil-sim closes (`run`, the HIL runs, the robot behind the link).

use crate::scenario::Scenario;
use controller_core::runtime::RuntimeConfig;
use controller_core::{ControllerConfig, RobotParams};
use sim_robot::world::{DeadEncoder, Faults, HardwareSensing, IdealSensing, Instruments};
use sim_robot::{PlantParams, World, WorldConfig};

/// The world of `scn` around `robot` with these instruments and dead encoder.
fn world(
    scn: &Scenario,
    robot: &RobotParams,
    instruments: Instruments,
    dead_encoder: Option<DeadEncoder>,
    wiring: sim_robot::world::Wiring,
) -> Result<World, String> {
    World::new(&WorldConfig {
        plant: PlantParams::from_robot(robot, scn.mass_scale, scn.inertia_scale),
        perturbations: scn.perturbations(),
        initial_pose: scn.initial_pose,
        period_s: scn.control_period_s,
        substeps: scn.substeps,
        seed: scn.seed,
        instruments,
        faults: Faults {
            wheel_torque_scale: scn.wheel_torque_scale,
            dead_encoder,
            wiring,
        },
    })
    .map_err(|e| format!("scenario '{}': {e}", scn.name))
}

/// Ideal sensing for the bare controller of `controller`: the true pose of
/// G with the scenario's `pose_noise_m`/`heading_noise_rad`, the wheel rates
/// over the controller's period, torques applied exactly.
pub fn ideal_world(scn: &Scenario, controller: &ControllerConfig) -> Result<World, String> {
    let ideal = IdealSensing {
        position_noise_m: scn.pose_noise_m,
        heading_noise_rad: scn.heading_noise_rad,
        rate_period_s: controller.period_s as f64,
    };
    world(
        scn,
        &controller.robot,
        Instruments::Ideal(ideal),
        None,
        sim_robot::world::Wiring::CORRECT,
    )
}

/// The simulated hardware behind the firmware runtime of `runtime`: its
/// encoders and motors, the gyro and external pose source of the
/// scenario's sensing preset (with its overrides), and a dead encoder
/// `(wheel, from_s)` if asked.
pub fn hardware_world(
    scn: &Scenario,
    runtime: &RuntimeConfig,
    dead_encoder: Option<(usize, f64)>,
) -> Result<World, String> {
    hardware_world_miswired(scn, runtime, dead_encoder, &Miswire::default())
}

/// Wiring mistakes of the robot behind the link (`hil-sim device
/// --miswire`, `wmr commission`'s test): the plant's wiring faults and an
/// encoder resolution other than the runtime's.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Miswire {
    /// The wiring faults.
    pub wiring: sim_robot::world::Wiring,
    /// The plant's encoder counts per wheel revolution (None: the runtime's).
    pub counts_per_wheel_rev: Option<f32>,
}

/// [`hardware_world`] with `miswire`'s mistakes.
pub fn hardware_world_miswired(
    scn: &Scenario,
    runtime: &RuntimeConfig,
    dead_encoder: Option<(usize, f64)>,
    miswire: &Miswire,
) -> Result<World, String> {
    let sensors = scn.sensor_setup()?;
    let mut encoder = runtime.encoder;
    if let Some(c) = miswire.counts_per_wheel_rev {
        encoder.counts_per_wheel_rev = c;
    }
    let hw = HardwareSensing {
        encoder,
        motor: runtime.motor,
        motor_inverted: runtime.motor_inverted,
        gyro: sensors.gyro,
        pose_source: sensors.pose,
    };
    let dead = dead_encoder.map(|(wheel, from_s)| DeadEncoder { wheel, from_s });
    world(
        scn,
        &runtime.controller.robot,
        Instruments::Hardware(hw),
        dead,
        miswire.wiring,
    )
}
