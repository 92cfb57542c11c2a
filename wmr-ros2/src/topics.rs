//! Every topic and service of the bridge: name, ROS type and QoS, in one
//! table (`main.rs` creates them from it; `book/src/reference/ros2-interface.md` lists it).
//!
//! QoS as Nav2 expects it (Jazzy):
//! - `/odom`, `/joint_states`, `/diagnostics`, `/wmr/tracking`: reliable,
//!   volatile, keep last 10 (Nav2's odometry subscribers use the system
//!   default, reliable; a reliable writer also serves best-effort readers
//!   such as Foxglove's or `SensorDataQoS` ones). A full send window never
//!   blocks the bridge: the sample is dropped and counted
//!   ([`WhenFull::Fail`]).
//! - `/tf`: reliable, volatile, keep last 100 (tf2's broadcaster and
//!   listener profile).
//! - `cmd_vel`, localiser poses: best effort, volatile, keep last 1 — a
//!   best-effort reader matches both reliable (Nav2's controller server,
//!   teleop) and best-effort writers, and only the newest command counts.
//! - `/initialpose`, the path: reliable, volatile, keep last 1 (RViz and
//!   Nav2 publish them reliable; a one-off message must not be lost).
//! - services: reliable, volatile, keep last 10 (rmw's services default).

use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::QosProfile;

/// The direction of a topic, seen from the bridge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// The bridge publishes.
    Publish,
    /// The bridge subscribes.
    Subscribe,
}

/// One topic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TopicSpec {
    /// ROS name (absolute).
    pub name: &'static str,
    /// Package.
    pub package: &'static str,
    /// Type.
    pub type_name: &'static str,
    /// Publish or subscribe.
    pub direction: Direction,
    /// Reliable (else best effort).
    pub reliable: bool,
    /// History depth.
    pub depth: usize,
}

impl TopicSpec {
    /// The DDS type name ROS 2 uses (`nav_msgs::msg::dds_::Odometry_`).
    pub fn dds_type(&self) -> String {
        format!("{}::msg::dds_::{}_", self.package, self.type_name)
    }

    /// The DDS topic name (`rt/odom`).
    pub fn dds_topic(&self) -> String {
        format!("rt{}", self.name)
    }

    /// The QoS profile.
    pub fn qos(&self) -> QosProfile {
        let base = if self.reliable {
            QosProfile::publisher_default().reliability_reliable(WhenFull::Fail)
        } else {
            QosProfile::subscription_default().reliability_best_effort()
        };
        base.durability(Durability::Volatile)
            .history(History::KeepLast { depth: self.depth })
    }
}

const fn publish(
    name: &'static str,
    package: &'static str,
    ty: &'static str,
    depth: usize,
) -> TopicSpec {
    TopicSpec {
        name,
        package,
        type_name: ty,
        direction: Direction::Publish,
        reliable: true,
        depth,
    }
}

/// `/odom`.
pub const ODOM: TopicSpec = publish(ros_mcap::TOPIC_ODOM, "nav_msgs", "Odometry", 10);
/// `/tf`.
pub const TF: TopicSpec = publish(ros_mcap::TOPIC_TF, "tf2_msgs", "TFMessage", 100);
/// `/joint_states`.
pub const JOINT_STATES: TopicSpec = publish(
    ros_mcap::TOPIC_JOINT_STATES,
    "sensor_msgs",
    "JointState",
    10,
);
/// `/diagnostics`.
pub const DIAGNOSTICS: TopicSpec = publish(
    ros_mcap::TOPIC_DIAGNOSTICS,
    "diagnostic_msgs",
    "DiagnosticArray",
    10,
);
/// `/wmr/tracking`.
pub const TRACKING: TopicSpec = publish(ros_mcap::TOPIC_TRACKING, "wmr_msgs", "Tracking", 10);

/// `cmd_vel` (`TwistStamped` by default, `Twist` with `--cmd-vel-type twist`).
pub fn cmd_vel(name: &'static str, stamped: bool) -> TopicSpec {
    TopicSpec {
        name,
        package: "geometry_msgs",
        type_name: if stamped { "TwistStamped" } else { "Twist" },
        direction: Direction::Subscribe,
        reliable: false,
        depth: 1,
    }
}

/// The path to follow.
pub fn path(name: &'static str) -> TopicSpec {
    TopicSpec {
        name,
        package: "nav_msgs",
        type_name: "Path",
        direction: Direction::Subscribe,
        reliable: true,
        depth: 1,
    }
}

/// A localiser's poses.
pub fn localiser(name: &'static str) -> TopicSpec {
    TopicSpec {
        name,
        package: "geometry_msgs",
        type_name: "PoseWithCovarianceStamped",
        direction: Direction::Subscribe,
        reliable: false,
        depth: 1,
    }
}

/// `/initialpose`.
pub const INITIAL_POSE: TopicSpec = TopicSpec {
    name: "/initialpose",
    package: "geometry_msgs",
    type_name: "PoseWithCovarianceStamped",
    direction: Direction::Subscribe,
    reliable: true,
    depth: 1,
};

/// Default `cmd_vel` topic.
pub const DEFAULT_CMD_VEL: &str = "/cmd_vel";
/// Default path topic (not Nav2's `/plan`: a path sent here is driven).
pub const DEFAULT_PATH: &str = "/wmr/path";
/// Default localiser topic: where Nav2's AMCL publishes its pose
/// (nav2_amcl/src/amcl_node.cpp, `amcl_pose`, at Jazzy, Kilted, Lyrical).
pub const DEFAULT_LOCALISER: &str = "/amcl_pose";

/// The set-odometry service under the node's name (`/wmr_bridge/set_odometry`),
/// `control_msgs/srv/SetOdometry` as diff_drive_controller's
/// `~/set_odometry` (ros2_controllers 6.4.0).
pub const SET_ODOMETRY: &str = "set_odometry";

/// The services (`std_srvs/srv/Trigger` each), under the node's namespace.
pub const SERVICES: [&str; 4] = [
    "/wmr/arm",
    "/wmr/disarm",
    "/wmr/emergency_stop",
    "/wmr/clear_stop",
];

/// Services QoS.
pub fn service_qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ros_naming_of_dds_types_and_topics() {
        assert_eq!(ODOM.dds_type(), "nav_msgs::msg::dds_::Odometry_");
        assert_eq!(ODOM.dds_topic(), "rt/odom");
        assert_eq!(TF.dds_topic(), "rt/tf");
        assert_eq!(
            cmd_vel(DEFAULT_CMD_VEL, true).dds_type(),
            "geometry_msgs::msg::dds_::TwistStamped_"
        );
    }
}
