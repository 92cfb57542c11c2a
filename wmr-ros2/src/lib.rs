//! # wmr-ros2
//!
//! A ROS 2 bridge for the trajectory-tracking robot on a pure-Rust ROS 2
//! client (`ros2-client` over RustDDS: no ROS installation), talking to
//! the robot through wmr's checked link ([`wmr::Link`]). See
//! `book/src/reference/ros2-interface.md` for the topics, services, QoS, and
//! `book/src/explanation/ros2.md` for the frames and how G is
//! handled; this library is the mapping, testable without DDS:
//!
//! - [`convert`]: base_link ↔ G, covariances, velocity commands, stamps;
//! - [`profile`]: a `nav_msgs/Path` into timed waypoints within the limits;
//! - [`bridge`]: the link side (keep-alive, clock sync, state, uploads,
//!   services), producing the messages ros-mcap builds for the MCAP logs
//!   ([`ros_mcap::RosFrames`]), so the logs and the live topics agree;
//! - [`params`]: the robot's parameters as ROS parameters;
//! - [`cli`]: the binary's command line;
//! - [`topics`]: every topic and service with its type and QoS;
//! - [`msg`]: the message types the bridge subscribes to;
//! - [`rpc`]: each service caller's request/reply mapping (D150);
//! - [`services`]: the services on DDS, answered in the caller's mapping.
#![deny(missing_docs)]

pub mod bridge;
pub mod cli;
pub mod convert;
pub mod msg;
pub mod params;
pub mod profile;
pub mod rpc;
pub mod services;
pub mod topics;

pub use bridge::{Bridge, Config, Fatal};
