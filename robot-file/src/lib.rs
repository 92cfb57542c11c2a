//! The robot file: one description of a differential-drive robot, validated
//! as a whole, from which the runtime, the simulator, the emulated board and
//! the firmware take every robot-dependent value (book/src/how-to/robot-file.md).
//!
//! - [`Robot`]: the sections of the file (body, motors, encoders, bridge,
//!   IMU, limits, gains), field names with units.
//! - [`Robot::validate`]: physical ranges and consistency; a [`RobotError`]
//!   names the field by its TOML path and the reason.
//! - [`Robot::encode`] / [`Robot::decode`]: the binary form for flash and the
//!   link (header, postcard payload, CRC-32), no_std, no allocation.
//! - With the `std` feature: [`Robot::from_toml_str`],
//!   [`Robot::to_toml_string`] and [`json_schema`].
//! - Derivations ([`Robot::robot_params`], [`Robot::controller_config`],
//!   [`Robot::motor_params`], [`Robot::encoder_params`],
//!   [`Robot::safety_limits`]) and the one derivation of the runtime,
//!   [`Robot::derive`].
#![no_std]
#![deny(missing_docs)]

#[cfg(feature = "std")]
extern crate std;

mod binary;
#[cfg(feature = "std")]
pub mod build_script;
mod derive;
mod error;
mod sections;
#[cfg(feature = "std")]
mod text;
mod validate;

pub use binary::{DecodeError, EncodeError, BINARY_VERSION, HEADER_LEN, MAGIC, MAX_ENCODED_LEN};
pub use derive::{
    health_for_speed, BoardFacts, Derived, CONTROL_PERIOD_S, HEALTH_DEFAULT_SPEED_MPS,
    JUMP_SPEED_FACTOR, STALL_TIME_S, STALL_TORQUE_FRACTION,
};
pub use error::{Reason, RobotError};
pub use sections::{
    Body, Bridge, Control, Encoders, Eso, Estimator, GainSet, Gains, Imu, Kinematic, Limits,
    Motors, Name, Observer, Robot, Sliding, SwitchingGain, YawAxis, FORMAT, NAME_MAX_LEN,
};
#[cfg(feature = "std")]
pub use text::{field_paths, json_schema, RobotFileError};
pub use validate::{
    FIELDS, GAIN_FIELDS, MAX_GAIN, MAX_WHEEL_RADIUS_MISMATCH, SUPPORTED_TIMER_CLOCKS_HZ,
};
