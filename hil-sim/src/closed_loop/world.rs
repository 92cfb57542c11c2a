//! The scenario's simulated world ([`sim_robot::World`]): its plant (the
//! plant robot of the scenario, [`Scenario::plant_robot`], through
//! sim-robot's [`WorldConfig::of_robot`], with the scenario's mass and
//! inertia scales, actuation delay and electrical lag), perturbations,
//! faults and instruments, built in one place for every loop hil-sim
//! closes (`run`, the HIL runs, the robot behind the link).

use crate::scenario::Scenario;
use controller_core::runtime::RuntimeConfig;
use controller_core::ControllerConfig;
use sim_robot::plant::ActuatorDynamics;
use sim_robot::world::{DeadEncoder, Faults, HardwareSensing, IdealSensing, Instruments};
use sim_robot::{World, WorldConfig};

/// The world of `scn` behind a controller configured as `model` with these
/// instruments (None: the plant robot's own encoders, motors and motor
/// directions with the scenario's gyro and pose source) and dead encoder.
fn world(
    scn: &Scenario,
    model: &RuntimeConfig,
    instruments: Option<Instruments>,
    dead_encoder: Option<DeadEncoder>,
    wiring: sim_robot::world::Wiring,
) -> Result<World, String> {
    let err = |e: String| format!("scenario '{}': {e}", scn.name);
    let robot = scn.plant_robot().map_err(err)?;
    let of_robot = WorldConfig::of_robot(&robot, model).map_err(|e| err(e.to_string()))?;
    let mut plant = of_robot.plant;
    plant.mass_kg *= scn.plant.mass_scale;
    plant.inertia_kgm2 *= scn.plant.inertia_scale;
    plant.actuator = ActuatorDynamics {
        delay_s: scn.plant.actuation_delay_s,
        electrical_time_constant_s: scn.plant.electrical_time_constant_s,
    };
    let instruments = match instruments {
        Some(i) => i,
        None => Instruments::Hardware(plant_hardware(scn, model)?),
    };
    World::new(&WorldConfig {
        plant,
        perturbations: scn.perturbations(),
        initial_pose: scn.initial_pose,
        period_s: scn.control_period_s,
        substeps: scn.substeps,
        seed: scn.seed,
        instruments,
        faults: Faults {
            wheel_torque_scale: scn.perturbations.wheel_torque_scale,
            dead_encoder,
            wiring,
        },
    })
    .map_err(|e| err(e.to_string()))
}

/// Ideal sensing for the bare controller of `controller`: the true pose of
/// G with the scenario's `pose_noise_m`/`heading_noise_rad`, the wheel rates
/// over the controller's period, torques applied exactly.
pub fn ideal_world(scn: &Scenario, controller: &ControllerConfig) -> Result<World, String> {
    let ideal = IdealSensing {
        position_noise_m: scn.sensing.pose_noise_m,
        heading_noise_rad: scn.sensing.heading_noise_rad,
        rate_period_s: controller.period_s as f64,
    };
    let model = scn.runtime_config(*controller, scn.safety_limits());
    world(
        scn,
        &model,
        Some(Instruments::Ideal(ideal)),
        None,
        sim_robot::world::Wiring::CORRECT,
    )
}

/// The simulated hardware behind the firmware runtime of `runtime`: the
/// plant robot's encoders and motors, the gyro and external pose source of
/// the scenario's sensing preset (with its overrides), and a dead encoder
/// `(wheel, from_s)` if asked.
pub fn hardware_world(
    scn: &Scenario,
    runtime: &RuntimeConfig,
    dead_encoder: Option<(usize, f64)>,
) -> Result<World, String> {
    let dead = dead_encoder.map(|(wheel, from_s)| DeadEncoder { wheel, from_s });
    world(scn, runtime, None, dead, sim_robot::world::Wiring::CORRECT)
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

/// The plant robot's hardware (sim-robot's mapping of the robot file,
/// [`WorldConfig::of_robot`]: its encoders counting the true wheel angle,
/// its motors at the PWM resolution of `model`, its motor directions) with
/// the scenario's gyro and external pose source.
fn plant_hardware(scn: &Scenario, model: &RuntimeConfig) -> Result<HardwareSensing, String> {
    let err = |e: String| format!("scenario '{}': {e}", scn.name);
    let sensors = scn.sensor_setup().map_err(err)?;
    let robot = scn.plant_robot().map_err(err)?;
    match WorldConfig::of_robot(&robot, model)
        .map_err(|e| err(e.to_string()))?
        .instruments
    {
        Instruments::Hardware(hw) => Ok(HardwareSensing {
            gyro: sensors.gyro,
            pose_source: sensors.pose,
            ..hw
        }),
        Instruments::Ideal(_) => Err(err("sim-robot's robot file mapping has no hardware".into())),
    }
}

/// [`hardware_world`] with `miswire`'s mistakes.
pub fn hardware_world_miswired(
    scn: &Scenario,
    runtime: &RuntimeConfig,
    dead_encoder: Option<(usize, f64)>,
    miswire: &Miswire,
) -> Result<World, String> {
    let mut hw = plant_hardware(scn, runtime)?;
    if let Some(c) = miswire.counts_per_wheel_rev {
        hw.encoder.counts_per_wheel_rev = c;
    }
    let dead = dead_encoder.map(|(wheel, from_s)| DeadEncoder { wheel, from_s });
    world(
        scn,
        runtime,
        Some(Instruments::Hardware(hw)),
        dead,
        miswire.wiring,
    )
}
