//! # wmr
//!
//! Host tool for the trajectory-tracking robot: talks [`wmr_protocol`] over a
//! serial port, a USB CDC-ACM port or the pseudo-terminal of the simulated
//! robot (`hil-sim device --pty`). See `wmr --help` and the README.
#![deny(missing_docs)]

pub mod cli;
pub mod commission;
pub mod identify;
pub mod link;
pub mod record;
pub mod robot;
pub mod serve;
pub mod timing;
pub mod upload;
pub mod watch;

pub use link::{HelloInfo, Link, LinkError};
