//! Typed refusals of `wmr upload`: what, the value, the limit and what to
//! do (issue 37). Apart from [`crate::upload`] so that [`crate::link`]'s
//! error can carry them without an import cycle.

/// A waypoint or the curve between two beyond a robot's limits, with the
/// value, the limit and what to do.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WaypointError {
    /// The robot file does not give a board to derive the limits with.
    #[error("robot {robot}: {error}")]
    Robot {
        /// The robot's name.
        robot: String,
        /// Why.
        error: robot_file::RobotError,
    },
    /// A waypoint's own speed or yaw rate is beyond the robot's.
    #[error(
        "waypoint {index} (t {t_s:.3} s): v {v_mps} m/s, ω {omega_radps} rad/s; robot {robot} \
         goes at most {top_speed_mps:.3} m/s and {top_yaw_rate_radps:.3} rad/s (its no-load \
         speed): {}", ScaleHint(*.scale)
    )]
    Waypoint {
        /// Its index in the file.
        index: usize,
        /// Its time [s].
        t_s: f32,
        /// Its speed [m/s].
        v_mps: f32,
        /// Its yaw rate [rad/s].
        omega_radps: f32,
        /// The robot's name.
        robot: String,
        /// The robot's top speed [m/s].
        top_speed_mps: f32,
        /// The robot's top yaw rate [rad/s].
        top_yaw_rate_radps: f32,
        /// The least `--scale-time` with which the whole path fits.
        scale: Option<f32>,
    },
    /// The curve between two waypoints is beyond the robot's limits.
    #[error(
        "segment {index} (waypoints {index} to {}, t {t0_s:.3} to {t1_s:.3} s): the curve \
         between them reaches a {quantity} of {value:.3} {unit}, above robot {robot}'s \
         {limit:.3} {unit}: {}", .index + 1, ScaleHint(*.scale)
    )]
    Segment {
        /// Index of its first waypoint.
        index: usize,
        /// Its start [s].
        t0_s: f32,
        /// Its end [s].
        t1_s: f32,
        /// What is too large (speed, acceleration, yaw rate).
        quantity: &'static str,
        /// Its unit.
        unit: &'static str,
        /// The curve's value.
        value: f32,
        /// The robot's limit.
        limit: f32,
        /// The robot's name.
        robot: String,
        /// The least `--scale-time` with which the whole path fits.
        scale: Option<f32>,
    },
}

impl WaypointError {
    /// The error of a path already run `k` times slower: its hint counts
    /// from the file as written.
    pub fn times(mut self, k: f32) -> Self {
        if let Self::Waypoint { scale, .. } | Self::Segment { scale, .. } = &mut self {
            *scale = scale.map(|s| (s * k * 100.0).ceil() / 100.0);
        }
        self
    }
}

/// What to do about a path too fast for a robot.
struct ScaleHint(Option<f32>);

impl std::fmt::Display for ScaleHint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            Some(k) => write!(
                f,
                "slow the path down: `--scale-time {k:.2}` (of the file as written) runs it {k:.2} \
                 times slower (every speed ÷{k:.2}, acceleration ÷{:.2}), the least within this \
                 robot's limits (a path at its limits leaves no torque to correct errors: take \
                 more), or edit the waypoints",
                k * k
            ),
            None => write!(
                f,
                "give the waypoints more time between them, or more of them along the path \
                 (`--scale-time K` runs the whole path K times slower)"
            ),
        }
    }
}

/// Largest time scale `wmr::upload::least_scale` tries.
pub const MAX_SCALE_TIME: f32 = 100.0;

/// Why `upload` refused a file.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum UploadError {
    /// Longer than the robot's buffer without `--arm`.
    #[error(
        "{file}: {points} waypoints ({duration_s:.1} s) do not fit the robot's buffer of \
         {capacity}: the rest must stream while the robot runs, so `upload` alone cannot load \
         it (and a later `record --arm` would run only the first part). Stream it while it \
         runs:\n  wmr {link} upload {file} --arm\nand to record it meanwhile, through a \
         server:\n  wmr {link} serve &\n  wmr {link} record --seconds {record_s:.0} --out \
         run.csv &\n  wmr {link} upload {file} --arm"
    )]
    BeyondBuffer {
        /// The file.
        file: String,
        /// Its waypoints.
        points: usize,
        /// Its duration [s].
        duration_s: f32,
        /// The robot's buffer [waypoints].
        capacity: usize,
        /// `--port PATH` or `--serve SOCKET`.
        link: String,
        /// Robot time to record: the path and its stop [s].
        record_s: f32,
    },
    /// A waypoint or segment beyond the robot's limits.
    #[error("{file}: {error}")]
    Waypoints {
        /// The file.
        file: String,
        /// What and by how much.
        error: WaypointError,
    },
    /// The robot refused a segment and cannot tell its robot file.
    #[error(
        "{file}: {error}; the robot's own file is not readable ({why}): give it with --robot \
         ROBOT.toml, or slow the path down with --scale-time K (K times slower)"
    )]
    Unexplained {
        /// The file.
        file: String,
        /// The robot's refusal.
        error: String,
        /// Why its file is not known.
        why: String,
    },
    /// `--scale-time` out of range.
    #[error("--scale-time {0}: give a factor in (0, {MAX_SCALE_TIME}] (2 runs the path twice as slowly)")]
    BadScale(f32),
}
