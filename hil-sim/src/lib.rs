//! # hil-sim
//!
//! Host-side simulator for `controller-core`: the paper's plant (kinematics
//! (3) with slip σ and lateral skid U_D, reduced dynamics (6) with P1 and an
//! external disturbance τ_d, and the actuator fault (10)) integrated in f64
//! with RK4, closed through the exact controller code the firmware runs, at
//! the controller's own period with zero-order hold. Only sensors and
//! actuators are simulated; no controller code lives here.
#![deny(missing_docs)]
#![cfg_attr(test, allow(clippy::needless_range_loop))]

pub mod bench;
pub mod cli;
pub mod closed_loop;
pub mod device;
pub mod hil;
pub mod limits;
pub mod log_report;
pub mod metrics;
pub mod montecarlo;
pub mod plot;
pub mod progress;
pub mod random_robot;
pub mod report;
pub mod rng;
pub mod scenario;
pub mod scenario_file;
pub mod sensing;
pub mod shard;
pub mod sides;
pub mod sim;
pub mod sweep;
pub mod tune;

pub use metrics::Metrics;
pub use scenario::Scenario;
pub use sim::{run, SimOutput, TraceSample};
pub use sim_robot::{Plant, PlantParams, PlantState};
