//! # ros-mcap
//!
//! ROS 2-encoded MCAP logs of the robot (`wmr record --mcap`) and of the
//! simulator (`hil-sim run --mcap`): the same topics, the same messages,
//! so a robot log and a simulated run open side by side in Foxglove,
//! PlotJuggler or `ros2 bag`. Every message is CDR (little endian) with its
//! `ros2msg` schema ([`msg`]), on the topics a ROS 2 bridge publishes:
//!
//! | topic | type | content |
//! |---|---|---|
//! | `/odom` | `nav_msgs/msg/Odometry` | frame `odom`, child `base_link` (the axle midpoint), the estimator's pose converted from G (see below), η as the twist, the robot estimator's pose and twist covariance (telemetry group 8, [`odom_covariances`]; fixed [`POSE_COVARIANCE`], [`TWIST_COVARIANCE`] without it) |
//! | `/tf` | `tf2_msgs/msg/TFMessage` | `odom` → `base_link`, the same pose |
//! | `/joint_states` | `sensor_msgs/msg/JointState` | `right_wheel_joint`, `left_wheel_joint`: wheel rates from η, angles their integral, effort the torque |
//! | `/diagnostics` | `diagnostic_msgs/msg/DiagnosticArray` | run state, health and reason, last stop, fault estimates, counters: on a change and every [`DIAGNOSTICS_PERIOD_NS`] |
//! | `/wmr/tracking` | `wmr_msgs/msg/Tracking` | every column of the trace CSV and the duty ([`msg::Tracking`]) |
//!
//! **G and base_link.** The controller tracks G, the point d ahead of the
//! axle midpoint O_B ([`Geometry::com_offset_m`]); the telemetry's pose is
//! the estimator's pose of G. REP-105's `base_link` is the axle midpoint:
//! O_B = G − d·(cos θ, sin θ), same heading. η = (v, ω) is O_B's forward
//! speed and the yaw rate (the paper's S(q), eq. 2), so the twist in
//! `base_link` is (v, 0, 0; 0, 0, ω) with no conversion. `/wmr/tracking`
//! keeps the pose of G, as the CSV does.
//!
//! **Time.** Every message is stamped (header and MCAP log time) with the
//! host time, in Unix nanoseconds, of the robot time the sample was taken
//! at: `stamp = robot_time + offset`, the offset measured by clock sync
//! when the recording starts ([`TimeMap`]). A simulation maps its
//! simulated time from the wall clock at the run's start.
//!
//! **Reading back.** [`read_trace`] returns the rows of `/wmr/tracking`
//! while running or stopping, the same [`TraceSample`]s the CSV of the
//! same run holds (f32 telemetry widened to f64 both ways, so equal bit for
//! bit), and [`read_log`] dispatches on the file's first bytes, so the
//! metrics come from either file.
#![deny(missing_docs)]

mod frames;
#[cfg(feature = "live")]
pub mod live;
pub mod msg;
mod reader;
mod telemetry;
mod writer;

pub use frames::{
    counter_values, diagnostic_status, health_name, odom_covariances, DiagFrame,
    EstimatorCovariance, LogFrame, RosFrames, RosMessages,
};
pub use reader::sample_of_tracking;
pub use reader::{is_mcap, read_log, read_messages, read_trace, LoggedMessage};
pub use telemetry::sample_of_telemetry;
pub use writer::{LogStats, McapLog};

pub use track_log::TraceSample;

/// Topic of the odometry.
pub const TOPIC_ODOM: &str = "/odom";
/// Topic of the transforms.
pub const TOPIC_TF: &str = "/tf";
/// Topic of the wheel joints.
pub const TOPIC_JOINT_STATES: &str = "/joint_states";
/// Topic of the diagnostics.
pub const TOPIC_DIAGNOSTICS: &str = "/diagnostics";
/// Topic of the tracking and estimator telemetry.
pub const TOPIC_TRACKING: &str = "/wmr/tracking";
/// Every topic with its message type, in one order: the MCAP writer's
/// channels and the live view's (`live`), so both carry the same topics
/// and schemas ([`RosMessages::encoded`] gives the messages in this order).
pub const CHANNELS: [(&str, &str); 5] = [
    (TOPIC_ODOM, "nav_msgs/msg/Odometry"),
    (TOPIC_TF, "tf2_msgs/msg/TFMessage"),
    (TOPIC_JOINT_STATES, "sensor_msgs/msg/JointState"),
    (TOPIC_TRACKING, "wmr_msgs/msg/Tracking"),
    (TOPIC_DIAGNOSTICS, "diagnostic_msgs/msg/DiagnosticArray"),
];
/// The odometry frame.
pub const FRAME_ODOM: &str = "odom";
/// The robot's frame: the axle midpoint.
pub const FRAME_BASE: &str = "base_link";
/// Wheel joint names, \[right, left\] as in the telemetry.
pub const WHEEL_JOINTS: [&str; 2] = ["right_wheel_joint", "left_wheel_joint"];
/// Diagnostics are written on every change and at least this often \[ns\].
pub const DIAGNOSTICS_PERIOD_NS: u64 = 1_000_000_000;

/// `/odom`'s pose covariance diagonal (x, y, z, roll, pitch, yaw) \[m²,
/// rad²\] when a frame has no estimator covariance (a simulated trace,
/// or telemetry without group 8; protocol 5 robots send the estimator's:
/// [`odom_covariances`]): 1 cm in x and y, 0.01 rad in yaw, and 10⁶ for
/// the three coordinates a planar robot does not estimate (REP-105's
/// "unknown" convention).
pub const POSE_COVARIANCE: [f64; 6] = [1e-4, 1e-4, 1e6, 1e6, 1e6, 1e-4];
/// `/odom`'s twist covariance diagonal \[(m/s)², (rad/s)²\] without an
/// estimator covariance: 0.01 m/s in v, 0.01 rad/s in ω, 10⁶ for the rest.
pub const TWIST_COVARIANCE: [f64; 6] = [1e-4, 1e6, 1e6, 1e6, 1e6, 1e-4];

/// Why a log could not be written or read.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum LogError {
    /// A geometry value that no robot has (what and why).
    Geometry(String),
    /// Creating, writing or reading the file.
    Io(String),
    /// The MCAP layer.
    Mcap(String),
    /// A message that does not encode or decode.
    Cdr(String),
}

impl std::fmt::Display for LogError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Geometry(e) => write!(f, "robot geometry: {e}"),
            Self::Io(e) => write!(f, "{e}"),
            Self::Mcap(e) => write!(f, "MCAP: {e}"),
            Self::Cdr(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for LogError {}

/// A `--com-offset-m` flag's value (clap's `value_parser`): d \[m\]
/// within `body.com_offset_m`'s range in the parameter table, refused
/// naming the field, the value, the limit and what to set.
pub fn parse_com_offset_m(s: &str) -> Result<f64, String> {
    use controller_core::runtime::param_table::{RobotBounds, BODY_COM_OFFSET_M};
    let d: f64 = s
        .trim()
        .parse()
        .map_err(|e| format!("body.com_offset_m: {s:?} is not a number ({e}): give d in metres"))?;
    BODY_COM_OFFSET_M
        .check(d as f32, &RobotBounds::ABSOLUTE)
        .map_err(|e| e.to_string())?;
    Ok(d)
}

/// The robot's geometry the messages need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geometry {
    /// Wheel radius r \[m\].
    pub wheel_radius_m: f64,
    /// Half the wheel track h \[m\].
    pub half_track_m: f64,
    /// d: G ahead of the axle midpoint \[m\].
    pub com_offset_m: f64,
}

impl Geometry {
    /// Checked against the robot file's parameter table (one place for each
    /// range): r as `body.wheel_radius_m`, 2h as `body.track_m`, d as
    /// `body.com_offset_m`; the error names the field, the value, the
    /// limit and what to set.
    pub fn new(
        wheel_radius_m: f64,
        half_track_m: f64,
        com_offset_m: f64,
    ) -> Result<Self, LogError> {
        use controller_core::runtime::param_table::{
            Param, RobotBounds, BODY_COM_OFFSET_M, BODY_TRACK_M, BODY_WHEEL_RADIUS_M,
        };
        let check = |p: &Param, v: f64| {
            p.check(v as f32, &RobotBounds::ABSOLUTE)
                .map_err(|e| LogError::Geometry(e.to_string()))
        };
        check(&BODY_WHEEL_RADIUS_M, wheel_radius_m)?;
        check(&BODY_TRACK_M, 2.0 * half_track_m)?;
        check(&BODY_COM_OFFSET_M, com_offset_m)?;
        Ok(Self {
            wheel_radius_m,
            half_track_m,
            com_offset_m,
        })
    }

    /// The axle midpoint O_B (`base_link`) of the pose of G \[m, m, rad\].
    pub fn axle_of(&self, g: [f64; 3]) -> [f64; 3] {
        let (s, c) = g[2].sin_cos();
        [
            g[0] - self.com_offset_m * c,
            g[1] - self.com_offset_m * s,
            g[2],
        ]
    }

    /// Wheel rates \[right, left\] \[rad/s\] of η = \[v, ω\]:
    /// (v ± h·ω)/r (the paper's S(q), rows φ̇_R, φ̇_L).
    pub fn wheel_rates(&self, eta: [f64; 2]) -> [f64; 2] {
        let (r, h) = (self.wheel_radius_m, self.half_track_m);
        [(eta[0] + h * eta[1]) / r, (eta[0] - h * eta[1]) / r]
    }
}

/// Robot time (µs, the telemetry's u32 clock that wraps every 71.6 min)
/// to host time (Unix ns): unwraps the clock and adds the offset measured
/// once at the start.
#[derive(Clone, Copy, Debug)]
pub struct TimeMap {
    /// Host Unix time \[ns\] at robot time 0 of the unwrapped clock.
    offset_ns: i128,
    last_us: Option<u32>,
    wraps: u64,
}

impl TimeMap {
    /// A map where robot time `robot_us` was host Unix time `host_ns`.
    pub fn new(robot_us: u32, host_ns: u64) -> Self {
        Self {
            offset_ns: host_ns as i128 - robot_us as i128 * 1000,
            last_us: Some(robot_us),
            wraps: 0,
        }
    }

    /// Host Unix time \[ns\] of robot time `robot_us` (samples in order; a
    /// step back by more than half the clock's range is a wrap).
    pub fn host_ns(&mut self, robot_us: u32) -> u64 {
        if let Some(l) = self.last_us {
            if robot_us < l && l - robot_us > u32::MAX / 2 {
                self.wraps += 1;
            }
        }
        self.last_us = Some(robot_us);
        let us = self.wraps as i128 * (1i128 << 32) + robot_us as i128;
        (self.offset_ns + us * 1000).max(0) as u64
    }
}

/// d \[m\] when the robot does not say (the link's `RobotInfo` has no
/// d): the paper robot's (Table 1, `RobotParams::paper`, the one place).
pub fn default_com_offset_m() -> f64 {
    controller_core::RobotParams::paper().com_offset_m as f64
}

/// Now as Unix time \[ns\] (0 if the clock is before 1970).
pub fn unix_now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Writes a simulated run's trace (`hil-sim run --mcap`): each row at
/// Unix time `start_ns` + its t, in the running state, no duty, counters or
/// stop (the simulator has none); the pose is the true pose of G.
pub fn write_sim_trace(
    path: &std::path::Path,
    geometry: Geometry,
    trace: &[TraceSample],
    start_ns: u64,
) -> Result<LogStats, LogError> {
    let mut log = McapLog::create(path, geometry, "hil-sim run")?;
    for s in trace {
        log.write(&sim_frame(s, start_ns))?;
    }
    log.finish()
}

/// The log frame of a simulated trace row at Unix time `start_ns` + its
/// t: the running state, no duty, counters, stop or covariance (the
/// simulator has none). `hil-sim run --mcap` and `--live` both use it.
pub fn sim_frame(s: &TraceSample, start_ns: u64) -> LogFrame {
    LogFrame {
        stamp_ns: start_ns + (s.t_s.max(0.0) * 1e9).round() as u64,
        sample: *s,
        duty: None,
        external_pose: false,
        input_fault: false,
        diag: DiagFrame {
            state: wmr_protocol::RunStateMsg::Running,
            last_stop: None,
            counters: None,
        },
        covariance: None,
    }
}

#[cfg(test)]
mod tests;
