//! The ROS 2 messages the logs carry, as serde structs whose field order is
//! the message definition's (CDR encodes fields in order, aligned to their
//! size, with no names), and their `ros2msg` schemas: the Jazzy definitions
//! with every dependency after the top-level type, each behind an
//! `================================================================================`
//! line and `MSG: pkg/Type`, as ROS 2 bags store them. Comments of the
//! upstream `.msg` files are left out; fields, types, constants and defaults
//! are Jazzy's (checked in CI against the Jazzy definitions `rosbags` ships:
//! `ros-mcap/check/mcap_check.py`).
//!
//! A ROS 2 bridge can publish these same structs: they serialise to the
//! bytes any ROS 2 node sends (CDR little endian behind the 4-byte
//! encapsulation header, [`encode`]).

use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Time {
    /// Seconds (Unix time in these logs).
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// The time `ns` nanoseconds after the epoch (seconds saturate at
    /// `i32::MAX`, in 2038).
    pub fn from_ns(ns: u64) -> Self {
        Self {
            sec: (ns / 1_000_000_000).min(i32::MAX as u64) as i32,
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    /// Nanoseconds after the epoch (0 before it).
    pub fn to_ns(self) -> u64 {
        (self.sec.max(0) as u64) * 1_000_000_000 + self.nanosec as u64
    }
}

/// `std_msgs/msg/Header`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// When the data was taken (robot time mapped to host time).
    pub stamp: Time,
    /// Frame of the data.
    pub frame_id: String,
}

/// `geometry_msgs/msg/Point` \[m\].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x \[m\].
    pub x: f64,
    /// y \[m\].
    pub y: f64,
    /// z \[m\].
    pub z: f64,
}

/// `geometry_msgs/msg/Vector3`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Quaternion {
    /// The rotation by `yaw_rad` about z.
    pub fn from_yaw(yaw_rad: f64) -> Self {
        let (s, c) = (0.5 * yaw_rad).sin_cos();
        Self {
            x: 0.0,
            y: 0.0,
            z: s,
            w: c,
        }
    }

    /// The yaw \[rad\] of a rotation about z, in (−π, π].
    pub fn yaw(&self) -> f64 {
        (2.0 * (self.w * self.z + self.x * self.y))
            .atan2(1.0 - 2.0 * (self.y * self.y + self.z * self.z))
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position \[m\].
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

/// A `float64[36]` row-major 6×6 covariance (x, y, z, rotation about x, y,
/// z). serde derives arrays up to 32 elements, so it is held as 32 + 4:
/// a fixed-size array has no length in CDR, so the bytes are those of 36
/// consecutive `float64`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Covariance([f64; 32], [f64; 4]);

impl Covariance {
    /// The diagonal `d`, zero elsewhere.
    pub fn diagonal(d: [f64; 6]) -> Self {
        let mut m = [0.0; 36];
        for (i, v) in d.iter().enumerate() {
            m[7 * i] = *v;
        }
        Self::from_array(m)
    }

    /// From the 36 entries, row major.
    pub fn from_array(m: [f64; 36]) -> Self {
        let mut a = [0.0; 32];
        let mut b = [0.0; 4];
        a.copy_from_slice(&m[..32]);
        b.copy_from_slice(&m[32..]);
        Self(a, b)
    }

    /// The 36 entries, row major.
    pub fn to_array(&self) -> [f64; 36] {
        let mut m = [0.0; 36];
        m[..32].copy_from_slice(&self.0);
        m[32..].copy_from_slice(&self.1);
        m
    }
}

/// `geometry_msgs/msg/PoseWithCovariance`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// Pose.
    pub pose: Pose,
    /// Covariance \[m², rad²\].
    pub covariance: Covariance,
}

/// `geometry_msgs/msg/Twist`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity \[m/s\].
    pub linear: Vector3,
    /// Angular velocity \[rad/s\].
    pub angular: Vector3,
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// Twist.
    pub twist: Twist,
    /// Covariance \[(m/s)², (rad/s)²\].
    pub covariance: Covariance,
}

/// `nav_msgs/msg/Odometry`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Stamp and the pose's frame (`odom`).
    pub header: Header,
    /// The twist's frame (`base_link`).
    pub child_frame_id: String,
    /// Pose of the child frame in `header.frame_id`.
    pub pose: PoseWithCovariance,
    /// Velocity in the child frame.
    pub twist: TwistWithCovariance,
}

/// `geometry_msgs/msg/Transform`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Translation \[m\].
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Stamp and parent frame.
    pub header: Header,
    /// Child frame.
    pub child_frame_id: String,
    /// Child in parent.
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    /// Transforms.
    pub transforms: Vec<TransformStamped>,
}

/// `sensor_msgs/msg/JointState`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    /// Stamp (no frame).
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions \[rad\].
    pub position: Vec<f64>,
    /// Velocities \[rad/s\].
    pub velocity: Vec<f64>,
    /// Efforts \[N·m\].
    pub effort: Vec<f64>,
}

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct KeyValue {
    /// Key.
    pub key: String,
    /// Value.
    pub value: String,
}

/// `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// `OK` 0, `WARN` 1, `ERROR` 2, `STALE` 3.
    pub level: u8,
    /// What is reported on.
    pub name: String,
    /// One line.
    pub message: String,
    /// Which device.
    pub hardware_id: String,
    /// Values.
    pub values: Vec<KeyValue>,
}

impl DiagnosticStatus {
    /// Level `OK`.
    pub const OK: u8 = 0;
    /// Level `WARN`.
    pub const WARN: u8 = 1;
    /// Level `ERROR`.
    pub const ERROR: u8 = 2;
    /// Level `STALE`.
    pub const STALE: u8 = 3;
}

/// `diagnostic_msgs/msg/DiagnosticArray`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Stamp.
    pub header: Header,
    /// Statuses.
    pub status: Vec<DiagnosticStatus>,
}

/// `wmr_msgs/msg/Tracking` ([`TRACKING_MSG`]): one telemetry sample of
/// the tracking and estimator groups, every column of the trace CSV
/// (`track_log::TraceSample`) plus what the CSV leaves out. Poses are of G
/// (d ahead of the axle midpoint), as the controller tracks it. `NaN` =
/// not known (the true fault in a robot log, the estimators with that
/// telemetry group off, the duty in a simulation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tracking {
    /// Stamp, frame `odom`.
    pub header: Header,
    /// Reference time since arming \[s\].
    pub t_s: f64,
    /// Run state (`RunStateMsg` index: 0 hold, 1 running, 2 stopping, 3 stopped).
    pub state: u8,
    /// Reference pose of G \[x m, y m, θ rad\].
    pub ref_pose: [f64; 3],
    /// Estimated pose of G (the true pose in a simulation) \[m, m, rad\].
    pub pose: [f64; 3],
    /// Position error |reference − pose| \[m\].
    pub pos_err_m: f64,
    /// World-frame error \[x_s − x, y_s − y\] \[m\].
    pub err_xy_m: [f64; 2],
    /// Tracking error e_x, e_y \[m\], e_θ \[rad\] in the robot frame (eq. 8).
    pub e: [f64; 3],
    /// Measured η = \[v m/s, ω rad/s\].
    pub eta: [f64; 2],
    /// η_c (eq. 14) \[m/s, rad/s\].
    pub eta_c: [f64; 2],
    /// Torque \[right, left\] \[N·m\].
    pub torque_nm: [f64; 2],
    /// PWM duty \[right, left\] (signed counts).
    pub duty: [f64; 2],
    /// Sliding variable s (eq. 20).
    pub s: [f64; 2],
    /// ρ̂.
    pub rho_hat: [f64; 2],
    /// D̂.
    pub d_hat: [f64; 2],
    /// F̂ = \[Δv̂ m/s, Δω̂ rad/s\].
    pub f_hat: [f64; 2],
    /// Injected fault F = ε·η (simulation only).
    pub f_true: [f64; 2],
    /// Torque request beyond the limit.
    pub saturated: bool,
    /// Governor time scale (1 = nominal speed).
    pub time_scale: f64,
    /// Governed reference time τ \[s\].
    pub tau_s: f64,
    /// Health: 0 nominal, 1 degraded, 2 safe stop.
    pub health: u8,
    /// Health reason index (`track_log::HEALTH_REASONS`).
    pub health_reason: u8,
    /// An external pose was fused on this tick.
    pub external_pose: bool,
    /// The runtime flagged an input fault.
    pub input_fault: bool,
}

/// CDR little-endian encapsulation header (`CDR_LE`, options 0).
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// A message as ROS 2 sends it: [`CDR_LE_HEADER`], then the fields in
/// CDR (aligned from the byte after the header).
pub fn encode<T: Serialize>(msg: &T) -> Result<Vec<u8>, String> {
    let body = cdr_encoding::to_vec::<T, byteorder::LittleEndian>(msg)
        .map_err(|e| format!("CDR encoding: {e}"))?;
    let mut out = Vec::with_capacity(4 + body.len());
    out.extend_from_slice(&CDR_LE_HEADER);
    out.extend_from_slice(&body);
    Ok(out)
}

/// The message in `bytes` (encapsulation header and CDR, either byte order).
pub fn decode<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, String> {
    if bytes.len() < 4 || bytes[0] != 0 || bytes[1] > 1 {
        return Err("not a CDR message (no CDR encapsulation header)".into());
    }
    let r = if bytes[1] == 1 {
        cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(&bytes[4..])
    } else {
        cdr_encoding::from_bytes::<T, byteorder::BigEndian>(&bytes[4..])
    };
    r.map(|(m, _)| m).map_err(|e| format!("CDR decoding: {e}"))
}

const SEPARATOR: &str =
    "================================================================================\n";

/// Jazzy definitions (without comments) by ROS 1-style name.
const DEFS: &[(&str, &str)] = &[
    ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
    (
        "std_msgs/Header",
        "builtin_interfaces/Time stamp\nstring frame_id\n",
    ),
    ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n"),
    ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
    (
        "geometry_msgs/Quaternion",
        "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    ),
    (
        "geometry_msgs/Pose",
        "Point position\nQuaternion orientation\n",
    ),
    (
        "geometry_msgs/PoseWithCovariance",
        "Pose pose\nfloat64[36] covariance\n",
    ),
    ("geometry_msgs/Twist", "Vector3 linear\nVector3 angular\n"),
    (
        "geometry_msgs/TwistWithCovariance",
        "Twist twist\nfloat64[36] covariance\n",
    ),
    (
        "geometry_msgs/Transform",
        "Vector3 translation\nQuaternion rotation\n",
    ),
    (
        "geometry_msgs/TransformStamped",
        "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
    ),
    (
        "nav_msgs/Odometry",
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n",
    ),
    (
        "tf2_msgs/TFMessage",
        "geometry_msgs/TransformStamped[] transforms\n",
    ),
    (
        "sensor_msgs/JointState",
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
    ),
    ("diagnostic_msgs/KeyValue", "string key\nstring value\n"),
    (
        "diagnostic_msgs/DiagnosticStatus",
        "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\nstring message\nstring hardware_id\nKeyValue[] values\n",
    ),
    (
        "diagnostic_msgs/DiagnosticArray",
        "std_msgs/Header header\nDiagnosticStatus[] status\n",
    ),
    ("wmr_msgs/Tracking", TRACKING_MSG),
];

/// `wmr_msgs/msg/Tracking`, the project's message (the field docs are on
/// [`Tracking`]).
pub const TRACKING_MSG: &str = "\
# One telemetry sample of wmr's tracking and estimator groups. Poses are of G,
# d ahead of the axle midpoint. NaN = not known.
std_msgs/Header header
float64 t_s
uint8 state
float64[3] ref_pose
float64[3] pose
float64 pos_err_m
float64[2] err_xy_m
float64[3] e
float64[2] eta
float64[2] eta_c
float64[2] torque_nm
float64[2] duty
float64[2] s
float64[2] rho_hat
float64[2] d_hat
float64[2] f_hat
float64[2] f_true
bool saturated
float64 time_scale
float64 tau_s
uint8 health
uint8 health_reason
bool external_pose
bool input_fault
";

fn def(name: &str) -> &'static str {
    DEFS.iter()
        .find(|(n, _)| *n == name)
        .map(|(_, d)| *d)
        .unwrap_or("")
}

/// The complex types `text` uses, fully qualified (`pkg/Type`; an
/// unqualified one is of `pkg`).
fn uses(pkg: &str, text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let ty = line.split_whitespace().next().unwrap_or("");
        let ty = ty.split('[').next().unwrap_or("");
        if ty.chars().next().is_some_and(|c| c.is_ascii_uppercase()) {
            out.push(format!("{pkg}/{ty}"));
        } else if ty.contains('/') {
            out.push(ty.to_string());
        }
    }
    out
}

/// The `ros2msg` schema of `name` (`pkg/msg/Type`): its definition, then
/// each type it depends on (depth first, once) behind the separator line
/// and `MSG: pkg/Type`.
pub fn schema(name: &str) -> String {
    let short = name.replace("/msg/", "/");
    let mut text = def(&short).to_string();
    let mut done = vec![short.clone()];
    let mut todo: Vec<String> = uses(pkg_of(&short), def(&short));
    todo.reverse();
    while let Some(t) = todo.pop() {
        if done.contains(&t) {
            continue;
        }
        let d = def(&t);
        text.push_str(SEPARATOR);
        text.push_str(&format!("MSG: {t}\n"));
        text.push_str(d);
        let mut more = uses(pkg_of(&t), d);
        more.reverse();
        todo.extend(more);
        done.push(t);
    }
    text
}

fn pkg_of(name: &str) -> &str {
    name.split('/').next().unwrap_or("")
}

/// Every schema name of the logs (`pkg/msg/Type`).
pub const SCHEMAS: [&str; 5] = [
    "nav_msgs/msg/Odometry",
    "tf2_msgs/msg/TFMessage",
    "sensor_msgs/msg/JointState",
    "diagnostic_msgs/msg/DiagnosticArray",
    "wmr_msgs/msg/Tracking",
];

#[cfg(test)]
mod tests {
    use super::*;

    /// The CDR layout worked out by hand from the CDR rules (every
    /// primitive aligned to its size from the byte after the 4-byte
    /// encapsulation header; a string is its u32 length with the
    /// terminating NUL, the bytes and the NUL).
    #[test]
    fn header_and_odometry_bytes_follow_the_cdr_rules() {
        let h = Header {
            stamp: Time { sec: 2, nanosec: 3 },
            frame_id: "odom".into(),
        };
        let b = encode(&h).unwrap();
        assert_eq!(
            b,
            [0, 1, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0, 5, 0, 0, 0, b'o', b'd', b'o', b'm', 0]
        );
        let odo = Odometry {
            header: h,
            child_frame_id: "base_link".into(),
            pose: PoseWithCovariance {
                pose: Pose {
                    position: Point {
                        x: 1.5,
                        y: 0.0,
                        z: 0.0,
                    },
                    orientation: Quaternion::from_yaw(0.0),
                },
                covariance: Covariance::diagonal([1.0; 6]),
            },
            twist: TwistWithCovariance {
                twist: Twist::default(),
                covariance: Covariance::diagonal([2.0; 6]),
            },
        };
        let b = encode(&odo).unwrap();
        // Body: header 17 bytes, pad to 20, child_frame_id 4 + 10 = 34,
        // pad to 40 for the first float64 (x = 1.5 at body offset 40).
        assert_eq!(&b[4 + 17..4 + 20], &[0, 0, 0]);
        assert_eq!(&b[4 + 20..4 + 24], &10u32.to_le_bytes());
        assert_eq!(&b[4 + 40..4 + 48], &1.5f64.to_le_bytes());
        // pose 7 + 36, twist 6 + 36 float64 follow with no padding.
        assert_eq!(b.len(), 4 + 40 + 8 * (7 + 36 + 6 + 36));
        let back: Odometry = decode(&b).unwrap();
        assert_eq!(back, odo);
    }

    #[test]
    fn quaternion_of_a_yaw_turns_back() {
        for yaw in [-3.0, -1.0, 0.0, 0.5, 3.1] {
            assert!((Quaternion::from_yaw(yaw).yaw() - yaw).abs() < 1e-12);
        }
    }

    #[test]
    fn schemas_name_each_dependency_once() {
        let s = schema("nav_msgs/msg/Odometry");
        assert!(s.starts_with("std_msgs/Header header\n"));
        for dep in [
            "std_msgs/Header",
            "builtin_interfaces/Time",
            "geometry_msgs/PoseWithCovariance",
            "geometry_msgs/Pose",
            "geometry_msgs/Point",
            "geometry_msgs/Quaternion",
            "geometry_msgs/TwistWithCovariance",
            "geometry_msgs/Twist",
            "geometry_msgs/Vector3",
        ] {
            let tag = format!("{SEPARATOR}MSG: {dep}\n");
            assert_eq!(s.matches(&tag).count(), 1, "{dep} in\n{s}");
        }
        assert_eq!(s.matches("MSG: ").count(), 9);
        let d = schema("diagnostic_msgs/msg/DiagnosticArray");
        assert!(d.contains("MSG: diagnostic_msgs/DiagnosticStatus\n"));
        assert!(d.contains("MSG: diagnostic_msgs/KeyValue\n"));
        for name in SCHEMAS {
            // Every type used has a definition.
            let s = schema(name);
            for part in s.split(SEPARATOR).skip(1) {
                let head = part.lines().next().unwrap();
                assert!(!def(&head["MSG: ".len()..]).is_empty(), "{head}");
            }
        }
    }
}
