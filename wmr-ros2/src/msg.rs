//! The ROS 2 messages the bridge subscribes to and its service types, as
//! serde structs in the definition's field order (CDR encodes fields in
//! order, with no names). The messages it publishes are ros-mcap's
//! ([`ros_mcap::msg`]): the MCAP logs and the bridge share them. Field
//! names, types and order are Jazzy's (`geometry_msgs`, `nav_msgs`,
//! `std_srvs`); the CI interop check (`wmr-ros2/check/`) defines the same
//! types independently in CycloneDDS's IDL and exchanges them.

use ros_mcap::msg::{Covariance, Header, Pose, PoseWithCovariance, Twist};
use serde::{Deserialize, Serialize};

/// `geometry_msgs/msg/TwistStamped` (Nav2's `cmd_vel` since Jazzy).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TwistStamped {
    /// Stamp and frame (`base_link`).
    pub header: Header,
    /// The velocity \[m/s, rad/s\].
    pub twist: Twist,
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

/// `nav_msgs/msg/Path`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Path {
    /// Stamp and frame of the path.
    pub header: Header,
    /// The poses, in order.
    pub poses: Vec<PoseStamped>,
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped` (a localiser's output,
/// RViz's `/initialpose`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovarianceStamped {
    /// Stamp (capture time) and frame.
    pub header: Header,
    /// Pose of `base_link` and its covariance (x, y, z, roll, pitch, yaw).
    pub pose: PoseWithCovariance,
}

impl PoseWithCovarianceStamped {
    /// The covariance's 36 entries, row major.
    pub fn covariance(&self) -> [f64; 36] {
        Covariance::to_array(&self.pose.covariance)
    }
}

/// `std_srvs/srv/Trigger` request (an empty message: CDR carries one byte).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TriggerRequest {
    /// The placeholder member ROS 2 gives an empty message.
    pub structure_needs_at_least_one_member: u8,
}

/// `std_srvs/srv/Trigger` response.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TriggerResponse {
    /// The request was carried out.
    pub success: bool,
    /// What happened, or why not.
    pub message: String,
}

impl ros2_client::Message for TriggerRequest {}
impl ros2_client::Message for TriggerResponse {}

/// `control_msgs/srv/SetOdometry` request (diff_drive_controller's
/// `~/set_odometry`): the pose of `base_link` in `odom` to set.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SetOdometryRequest {
    /// x \[m\].
    pub x: f64,
    /// y \[m\].
    pub y: f64,
    /// z \[m\] (a planar robot: 0).
    pub z: f64,
    /// Roll \[rad\] (0).
    pub roll: f64,
    /// Pitch \[rad\] (0).
    pub pitch: f64,
    /// Yaw \[rad\].
    pub yaw: f64,
}

/// `control_msgs/srv/SetOdometry` response.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SetOdometryResponse {
    /// The pose was set.
    pub success: bool,
    /// What happened, or why not.
    pub message: String,
}

impl ros2_client::Message for SetOdometryRequest {}
impl ros2_client::Message for SetOdometryResponse {}
