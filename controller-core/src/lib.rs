//! # controller-core
//!
//! `no_std`, `f32`, allocation-free implementation of the dual-loop trajectory
//! tracking controller of Tran et al., "Advanced trajectory tracking control for
//! wheeled mobile robots under actuator faults and slippage", for a
//! differential-drive robot, plus the two baselines of the paper's section 4.
//!
//! * Kinematic loop: tracking error (eq. 8), actuator-fault observer (eq. 13),
//!   backstepping law (eq. 14).
//! * Dynamic loop: fal-ESO (eqs. 18-19), integral sliding surface (eq. 20) and
//!   adaptive sliding-mode torque law (eq. 24).
//!
//! The same [`Controller`] runs in the firmware and in the simulator. Every
//! departure from the printed paper is recorded in `book/src/explanation/paper-departures.md`.
//!
//! Conventions: SI units, named in identifiers (`torque_nm`, `wheel_radius_m`).
//! Wheel-indexed arrays are `[right, left]`; velocity arrays are `[v, ω]`.
#![cfg_attr(not(test), no_std)]
#![deny(missing_docs)]
#![cfg_attr(test, allow(clippy::needless_range_loop))]
#![forbid(unsafe_code)]

pub mod asmc;
pub mod controller;
pub mod error;
pub mod eso;
pub mod estimator;
pub mod fault_observer;
pub mod friction;
pub mod governor;
pub mod health;
pub mod kinematic;
pub mod math;
pub mod model;
pub mod pacer;
pub mod params;
pub mod runtime;
pub mod tracking;
pub mod trajectory;
pub mod types;

pub use controller::{
    Controller, ControllerConfig, ControllerKind, Diagnostics, InputLimits, StepInput, StepOutput,
};
pub use error::{ConfigError, InputFault};
pub use model::ReducedModel;
pub use params::RobotParams;
pub use trajectory::{RefSample, Trajectory};
pub use types::{Pose, Vel2};
