//! # sim-robot
//!
//! The one simulated differential-drive robot of the project, `no_std`
//! (f64 through `libm`; the `std` feature uses the platform's faster
//! trigonometry): the paper's plant ([`Plant`]: kinematics (3) with slip and
//! skid, reduced dynamics (6), the actuator fault (10)), the section-4
//! perturbations ([`PerturbationProfile`]), the simulated hardware in raw
//! units ([`SimEncoders`], [`SimDriver`], [`MotorDrive`]) and the simulated
//! gyro and external pose source ([`SimGyro`], [`SimPoseSource`]).
//!
//! The host simulator (`hil-sim`), the closed-loop tests, the Cortex-M4F
//! benchmark and an emulated board drive this same plant. Only sensors and
//! actuators are simulated here; no controller code lives in this crate.
#![cfg_attr(not(test), no_std)]
#![deny(missing_docs)]
#![forbid(unsafe_code)]
#![cfg_attr(test, allow(clippy::needless_range_loop))]

#[cfg(feature = "std")]
extern crate std;

pub mod hardware;
pub mod math;
pub mod perturbation;
pub mod plant;
pub mod sensors;
/// The fakes tests share (feature `test-doubles`): controller-core's
/// scripted encoder, recording motor driver, one-shot pose source and line
/// configuration, next to this crate's simulated hardware.
#[cfg(feature = "test-doubles")]
pub mod test_doubles {
    pub use controller_core::runtime::test_doubles::*;
}
pub mod world;

pub use hardware::{MotorDrive, SimDriver, SimEncoders};
pub use perturbation::{PerturbationGrid, PerturbationProfile};
pub use plant::{
    ActuatorDynamics, Drive, Perturbation, Plant, PlantParams, PlantParamsError, PlantState,
    TorqueScaled, WheelFriction,
};
pub use sensors::{GyroModel, PoseSourceModel, SimGyro, SimPoseSource};
pub use world::{
    Actuation, DeadEncoder, Faults, HardwareSensing, IdealSensing, Instruments, Reading, Wiring,
    World, WorldConfig, WorldError,
};
