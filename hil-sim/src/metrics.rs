//! Run metrics: defined in the `track-log` crate (shared with the host tool
//! `wmr`, so a robot log and a simulation are measured by the same code).

pub use track_log::metrics::*;
