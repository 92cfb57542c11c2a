//! The bridge's command line ([`Args`]): in the library so that the
//! book's reference (`book/src/reference/cli/wmr-ros2.md`, tests/reference.rs)
//! is generated from the same definitions the binary parses.

use crate::{bridge, topics};
use clap::{Parser, ValueEnum};
use std::path::PathBuf;

/// Exit status when the bridge stops on a failure (the link, a DDS
/// entity, a robot that cannot tell its `body.com_offset_m`): the line
/// after `wmr-ros2: ` on stderr says why; the robot brakes to a stop
/// after its link timeout.
pub const EXIT_FAILURE: u8 = 1;

/// Every exit status of the bridge but clap's usage error (the book's
/// reference, errors.md, adds it from clap).
pub const EXIT_CODES: [(i32, &str); 2] = [
    (
        0,
        "ended on purpose: SIGINT, SIGTERM or `--for-s` (the robot disarmed, the MCAP log finished)",
    ),
    (
        EXIT_FAILURE as i32,
        "a failure: the line after `wmr-ros2:` on stderr says why (the robot brakes to a stop after its link timeout)",
    ),
];

/// The cmd_vel message type (`--cmd-vel-type`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CmdVelType {
    /// geometry_msgs/TwistStamped: what Nav2's controller_server and velocity_smoother publish by default from Kilted on (enable_stamped_cmd_vel true; false in Jazzy), and the only cmd_vel diff_drive_controller takes since Jazzy.
    Stamped,
    /// geometry_msgs/Twist: what Jazzy's Nav2 publishes by default (enable_stamped_cmd_vel false), and teleop_twist_keyboard.
    Twist,
}

/// The ROS 2 distribution whose Nav2 defaults the bridge follows
/// (book/src/how-to/ros2.md, "Conventions").
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Distro {
    /// Jazzy Jalisco (Nav2 publishes Twist).
    Jazzy,
    /// Kilted Kaiju (Nav2 publishes TwistStamped).
    Kilted,
    /// Lyrical Luth (Nav2 publishes TwistStamped).
    Lyrical,
}

impl Distro {
    /// The cmd_vel type Nav2's controller_server publishes by default
    /// (nav2_util/twist_publisher.hpp: enable_stamped_cmd_vel).
    pub fn nav2_cmd_vel(self) -> CmdVelType {
        match self {
            Self::Jazzy => CmdVelType::Twist,
            Self::Kilted | Self::Lyrical => CmdVelType::Stamped,
        }
    }
}

/// Which service request/reply mappings the bridge answers
/// (`--service-mapping`, D150).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Mapping {
    /// Each request's own: rmw_fastrtps's (a related sample identity) or rmw_cyclonedds's (its header); anything else refused.
    Auto,
    /// Only rmw_fastrtps's (RPC over DDS "enhanced"); others refused.
    Enhanced,
    /// Only rmw_cyclonedds's request header; others refused.
    Cyclone,
}

/// ROS 2 bridge for the trajectory-tracking robot (book/src/how-to/ros2.md): /odom,
/// /tf, /joint_states, /diagnostics, /wmr/tracking out; cmd_vel, a path,
/// localiser poses and /initialpose in; arm, disarm, emergency stop and
/// clear stop as std_srvs/Trigger services. Exits non-zero when the link
/// fails (the robot brakes to a stop after its link timeout).
#[derive(Debug, Parser)]
#[command(name = "wmr-ros2", version)]
pub struct Args {
    /// The robot's serial port or pty (`hil-sim device --pty` prints one); through its `wmr serve` when one listens on the port's default socket.
    #[arg(long, env = "WMR_PORT")]
    pub port: Option<String>,
    /// A `wmr serve` socket to connect through (book/src/how-to/serve.md).
    #[arg(long, env = "WMR_SERVE")]
    pub serve: Option<PathBuf>,
    /// Telemetry (/odom, /tf, /joint_states) rate [Hz].
    #[arg(long, default_value_t = bridge::DEFAULT_RATE_HZ)]
    pub rate_hz: u16,
    /// Timeout of each cmd_vel on the robot [ms]: a silent publisher stops the robot this long after its last command (then it brakes).
    #[arg(long, default_value_t = bridge::DEFAULT_CMD_TIMEOUT_MS)]
    pub cmd_timeout_ms: u16,
    /// The ROS 2 distribution whose Nav2 defaults to follow (the cmd_vel type); ROS sets ROS_DISTRO.
    #[arg(long, value_enum, env = "ROS_DISTRO", default_value_t = Distro::Jazzy)]
    pub ros_distro: Distro,
    /// cmd_vel message type [default: the one Nav2 of --ros-distro publishes: twist for jazzy, stamped for kilted and lyrical].
    #[arg(long, value_enum)]
    pub cmd_vel_type: Option<CmdVelType>,
    /// cmd_vel topic.
    #[arg(long, default_value = topics::DEFAULT_CMD_VEL)]
    pub cmd_vel_topic: String,
    /// Topic of the paths to follow (nav_msgs/Path).
    #[arg(long, default_value = topics::DEFAULT_PATH)]
    pub path_topic: String,
    /// Topic of a localiser's poses (geometry_msgs/PoseWithCovarianceStamped; AMCL's by default), fused by the robot's estimator at their stamps when in the `odom` frame (a pose in another frame, such as AMCL's `map`, is refused: book/src/how-to/ros2.md, "Frames").
    #[arg(long, default_value = topics::DEFAULT_LOCALISER)]
    pub localiser_topic: String,
    /// d, G ahead of the axle midpoint [m] [default: body.com_offset_m of the robot file the robot runs, read from its store; the bridge does not start when the robot cannot tell].
    #[arg(long, value_name = "M", value_parser = ros_mcap::parse_com_offset_m)]
    pub com_offset_m: Option<f64>,
    /// Fraction of the robot's speed and acceleration limits a path's profile uses.
    #[arg(long, default_value_t = bridge::DEFAULT_PATH_LIMIT_FRACTION)]
    pub path_limit_fraction: f64,
    /// Enable motion at start (else call the arm service first).
    #[arg(long)]
    pub enable: bool,
    /// Service request/reply mapping of the callers (their RMW's).
    #[arg(long, value_enum, default_value_t = Mapping::Auto)]
    pub service_mapping: Mapping,
    /// Node name.
    #[arg(long, default_value = "wmr_bridge")]
    pub node_name: String,
    /// DDS domain (ROS_DOMAIN_ID).
    #[arg(long, env = "ROS_DOMAIN_ID", default_value_t = 0)]
    pub domain_id: u16,
    /// Also log what is bridged to this MCAP file (the `wmr record --mcap` format).
    #[arg(long)]
    pub mcap: Option<PathBuf>,
    /// Also serve a live view to Foxglove (a ws-protocol WebSocket server
    /// with the topics and schemas of the MCAP logs; book/src/how-to/foxglove.md).
    #[arg(long)]
    pub live: bool,
    /// Where the live view listens (`--live-host`, `--live-port`).
    #[command(flatten)]
    pub live_at: ros_mcap::live::LiveArgs,
    /// Run this long, then disarm and exit 0 [s] (default: until SIGINT/SIGTERM, which also disarm and exit 0, or a link failure, exit 1).
    #[arg(long)]
    pub for_s: Option<f64>,
}
