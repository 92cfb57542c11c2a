//! # robot-identify
//!
//! Identification of a differential-drive robot from one recorded run
//! (`wmr identify run`, or the simulated robot behind `hil-sim device`):
//! each wheel's radius and the track from the heading and the external
//! poses against the encoders, then the reduced model's mass, inertia and
//! centre-of-mass offset (D1), per-wheel viscous and Coulomb friction and
//! the motor's EMF constant from the duties, by linear least squares with
//! 95 % confidence intervals, the residual and a richness check that says
//! which parameters the run could not determine and why.
//!
//! * [`excitation`]: the run's reference (controller-core's
//!   [`Excitation`](controller_core::trajectory::Excitation)) as waypoints,
//!   checked against the robot's limits;
//! * [`log`]: the identification log (rows from telemetry, CSV);
//! * [`filter`]: the zero-phase Savitzky-Golay filter applied to every column;
//! * [`lsq`]: least squares with covariance and condition number;
//! * [`fit`]: the fit itself; [`report`]: its text and robot-file output.
//!
//! The equations and what is identifiable from which sensors:
//! `book/src/how-to/identification.md`.
#![deny(missing_docs)]

pub mod excitation;
pub mod filter;
pub mod fit;
pub mod log;
pub mod lsq;
pub mod report;

pub use fit::{identify, Dynamics, Estimate, FitError, FitOptions, Form, Identification, Prior};
pub use log::{read_id_csv, write_id_csv, IdRow, RowBuilder};
