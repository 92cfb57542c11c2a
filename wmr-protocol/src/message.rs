//! Every message of the link, typed. Host → robot: [`Request`] (each with a
//! sequence number chosen by the host, echoed in the reply). Robot → host:
//! [`Reply`] (answers, telemetry and events). Units are in the field names;
//! `book/src/reference/protocol.md` documents every variant and field.

use controller_core::runtime::param_table::Param;
use heapless::Vec;
use serde::{Deserialize, Serialize};

/// Waypoints per [`Request::TrajectorySegment`] (bounded so a frame stays
/// below [`MAX_BODY`](crate::MAX_BODY)).
pub const SEGMENT_POINTS: usize = 8;

/// Planar pose of the tracked point G in the world frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseMsg {
    /// x \[m\].
    pub x_m: f32,
    /// y \[m\].
    pub y_m: f32,
    /// Heading θ \[rad\].
    pub theta_rad: f32,
}

impl PoseMsg {
    /// True when every coordinate is finite.
    pub fn is_finite(&self) -> bool {
        self.x_m.is_finite() && self.y_m.is_finite() && self.theta_rad.is_finite()
    }
}

/// A built-in parametric reference of the robot (controller-core's
/// `trajectory` module).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BuiltinShape {
    /// The paper's curve x = a_x cos wt, y = a_y cos 3wt (smooth signed heading).
    PaperCurve {
        /// a_x \[m\].
        ax_m: f32,
        /// a_y \[m\].
        ay_m: f32,
        /// w \[rad/s\].
        w_radps: f32,
    },
    /// Circle about the origin, counter-clockwise from (R, 0).
    Circle {
        /// Radius \[m\].
        radius_m: f32,
        /// Speed \[m/s\].
        speed_mps: f32,
    },
    /// Figure-eight x = A sin wt, y = (A/2) sin 2wt.
    FigureEight {
        /// Half-width A \[m\].
        amplitude_m: f32,
        /// w \[rad/s\].
        w_radps: f32,
    },
    /// Straight line along +x from the origin.
    Line {
        /// Speed \[m/s\] (signed).
        speed_mps: f32,
    },
}

/// A built-in reference placed in the world: shape, rigid start-pose
/// transform and speed scale.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BuiltinReference {
    /// The shape in its own frame.
    pub shape: BuiltinShape,
    /// `None`: the shape's frame is the world frame. `Some(p)`: the shape
    /// is moved rigidly so that its pose at t = 0 is `p`.
    pub start: Option<PoseMsg>,
    /// Time scale s > 0: the robot follows r(s·t) (speeds × s, accelerations × s²).
    pub speed_scale: f32,
}

/// One timed waypoint of an uploaded trajectory.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Waypoint {
    /// Time since arming \[s\] (strictly increasing along the trajectory).
    pub t_s: f32,
    /// Pose at `t_s`.
    pub pose: PoseMsg,
    /// Linear velocity v \[m/s\] (signed) at `t_s`.
    pub v_mps: f32,
    /// Angular velocity ω \[rad/s\] at `t_s`.
    pub omega_radps: f32,
}

/// A parameter the host can read and (where marked) write. Its name,
/// unit, range and who may change it when are in controller-core's
/// parameter table ([`ParamId::param`]); the variants are the wire ids, in
/// the table's wire order (`param_table::WIRE`; a test checks both).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamId {
    /// Per-wheel torque limit \[N·m\] (hold only).
    TorqueLimitNm,
    /// Kinematic gain k_x of eq. (14) (hold only).
    Kx,
    /// Kinematic gain k_y of eq. (14) (hold only).
    Ky,
    /// Kinematic gain k_θ of eq. (14) (hold only).
    Ktheta,
    /// Sliding-surface gain k_s of eq. (20) (hold only).
    Ks,
    /// Stall torque of the safety supervisor \[N·m\] (hold only).
    StallTorqueNm,
    /// Stall time of the safety supervisor \[ticks\] (hold only).
    StallTicks,
    /// Telemetry rate \[Hz\] (any state; 0 = off).
    TelemetryRateHz,
    /// Link-silence timeout while moving under host control \[ms\] (any state).
    LinkTimeoutMs,
    /// Acceleration limit of velocity commands \[m/s²\] (hold only).
    AccelMps2,
    /// Angular acceleration limit of velocity commands \[rad/s²\] (hold only).
    AngAccelRadps2,
    /// Deceleration of a controlled stop \[m/s²\] (hold only).
    BrakeDecelMps2,
    /// Largest |v| a velocity command may ask \[m/s\] (hold only).
    MaxSpeedMps,
    /// Largest |ω| a velocity command may ask \[rad/s\] (hold only).
    MaxYawRateRadps,
    /// Control period \[s\] (read only).
    ControlPeriodS,
}

/// What a telemetry frame carries (bit set; see the `TELEMETRY_*` constants).
pub type TelemetrySelection = u8;
/// Telemetry group: pose, reference, tracking error, η, η_c, torques, duties.
pub const TELEMETRY_TRACKING: TelemetrySelection = 1;
/// Telemetry group: sliding variable, ρ̂, D̂, F̂, estimator status.
pub const TELEMETRY_ESTIMATORS: TelemetrySelection = 2;
/// Telemetry group: tick and fault counters.
pub const TELEMETRY_COUNTERS: TelemetrySelection = 4;
/// Telemetry group: the pose estimator's covariance (protocol 5).
pub const TELEMETRY_COVARIANCE: TelemetrySelection = 8;
/// Every telemetry group.
pub const TELEMETRY_ALL: TelemetrySelection = 15;

/// Host → robot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Request {
    /// Handshake: the host's protocol version; answered by [`Reply::Hello`].
    Hello {
        /// [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION) of the host.
        version: u16,
    },
    /// Status: answered by [`Reply::Status`].
    GetStatus,
    /// Start driving the loaded reference or velocity mode.
    Arm,
    /// Stop driving (motors off, not latched).
    Disarm,
    /// Latch a safe stop at once (motors off on this tick).
    EmergencyStop,
    /// Clear a latched stop (back to hold).
    ClearStop,
    /// Re-anchor the pose estimate (hold only).
    SetPose(PoseMsg),
    /// An external pose measurement (motion capture, camera...).
    ExternalPose {
        /// When it was measured, robot clock \[µs\] (see [`Request::ClockSync`]).
        t_robot_us: u32,
        /// The measured pose.
        pose: PoseMsg,
        /// Standard deviations of x, y \[m\] and θ \[rad\].
        std_dev: [f32; 3],
    },
    /// Clock sync: answered by [`Reply::ClockSync`] with the robot's time.
    ClockSync {
        /// Host time when sent \[µs\] (echoed).
        host_time_us: u64,
    },
    /// Load a built-in reference (hold only).
    SetReference(BuiltinReference),
    /// Start a waypoint upload (hold only): clears the buffer.
    TrajectoryBegin {
        /// Total waypoints that will follow (≥ 2).
        total_points: u32,
    },
    /// The next waypoints of the upload (streamed while running too).
    TrajectorySegment {
        /// Index of the first waypoint of this segment in the trajectory.
        first_index: u32,
        /// Up to [`SEGMENT_POINTS`] waypoints.
        points: Vec<Waypoint, SEGMENT_POINTS>,
    },
    /// Velocity command, like ROS `cmd_vel`: selects velocity mode in hold,
    /// refreshes it while running.
    Velocity {
        /// v \[m/s\].
        v_mps: f32,
        /// ω \[rad/s\].
        omega_radps: f32,
        /// The command expires this long after it arrives \[ms\] (1..=5000).
        timeout_ms: u16,
    },
    /// Read a parameter: answered by [`Reply::Param`].
    GetParam(ParamId),
    /// Write a parameter: acknowledged, or refused with a typed error.
    SetParam {
        /// Which.
        id: ParamId,
        /// New value, in the parameter's unit.
        value: f32,
    },
    /// Telemetry groups and rate.
    SetTelemetry {
        /// Bit set of `TELEMETRY_*` groups.
        selection: TelemetrySelection,
        /// Frames per second (0 = off).
        rate_hz: u16,
    },
    /// Start a robot-record upload (hold only, protocol 4): clears the
    /// staging buffer; `total_len` bytes follow in [`Request::RobotChunk`]s.
    RobotBegin {
        /// Length of the whole record \[bytes\] (1..=[`ROBOT_BLOB_MAX`]).
        total_len: u16,
    },
    /// The next bytes of the record (in order: `offset` = bytes received).
    RobotChunk {
        /// Offset of the first byte in the record \[bytes\].
        offset: u16,
        /// Up to [`ROBOT_CHUNK`] bytes.
        data: Vec<u8, ROBOT_CHUNK>,
    },
    /// Validate the whole staged record on the robot and store it in flash
    /// (hold only, motors off). Answered when the write has finished: an
    /// ack, [`Reply::RobotRejected`] naming the field, or a nack.
    RobotCommit,
    /// Read `ROBOT_CHUNK` bytes of the stored record from `offset`:
    /// answered by [`Reply::RobotData`].
    RobotRead {
        /// Offset \[bytes\].
        offset: u16,
    },
    /// Restart the robot (hold only): acknowledged, then the robot resets
    /// and boots with the stored record.
    Reboot,
    // --- commissioning (issue 18, `wmr commission`) ---
    /// Drive one wheel open-loop for a bounded time (hold only, motors
    /// off; commissioning): acknowledged at the start, then answered by
    /// [`Reply::WheelTestDone`] when the test ends (its time is up, any
    /// other request but `GetStatus`/`GetParam`, link silence, a stop).
    WheelTest(WheelTestCmd),
}

/// Longest wheel test \[ms\] ([`Request::WheelTest`]).
pub const WHEEL_TEST_MAX_MS: u16 = 2000;

/// A wheel test ([`Request::WheelTest`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelTestCmd {
    /// The wheel: 0 right, 1 left.
    pub wheel: u8,
    /// Open-loop torque at standstill \[N·m\], forward positive (after
    /// the robot's motor inversion flag), 0 < |τ| ≤ the cap.
    pub torque_nm: f32,
    /// Duration \[ms\] (1..=[`WHEEL_TEST_MAX_MS`]).
    pub duration_ms: u16,
}

/// Why a wheel test ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WheelTestEnd {
    /// Its time was up.
    Completed,
    /// Another request ended it.
    Command,
    /// No valid frame for longer than the link timeout.
    LinkLost,
    /// The runtime latched a stop.
    Stopped,
    /// A wheel's count changed by more than the runtime's jump limit in
    /// one tick (the loop checks jumps only while running: the test
    /// checks them itself).
    EncoderJump,
}

/// What a wheel test measured ([`Reply::WheelTestDone`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelTestResult {
    /// The wheel driven (0 right, 1 left).
    pub wheel: u8,
    /// The torque asked \[N·m\].
    pub torque_nm: f32,
    /// The signed duty applied to the driven wheel's bridge \[counts\]
    /// (after the motor inversion flag).
    pub duty: i32,
    /// Ticks the wheel was driven.
    pub ticks: u32,
    /// Why it ended.
    pub end: WheelTestEnd,
    /// Encoder count change `[right, left]` over the test, forward
    /// positive after the encoder inversion flags.
    pub counts: [i32; 2],
    /// Integral of the gyro's yaw rate over the test \[rad\]
    /// (counter-clockwise positive); `None` without a gyro sample.
    pub gyro_yaw_rad: Option<f32>,
}

/// Largest robot record on the link and in flash \[bytes\] (robot-file's
/// `MAX_ENCODED_LEN`).
pub const ROBOT_BLOB_MAX: usize = 512;
/// Record bytes per [`Request::RobotChunk`] / [`Reply::RobotData`].
pub const ROBOT_CHUNK: usize = 128;
/// Longest field path in a [`RobotFault`] \[bytes\].
pub const ROBOT_FIELD_LEN: usize = 48;

/// Validates a whole robot record (robot-file's `Robot::decode`: header,
/// CRC-32, every field); the fault names the field. The robot side (store,
/// device) takes one from the board, which knows the robot type.
pub type RobotValidator = fn(&[u8]) -> Result<(), RobotFault>;

/// Why a robot record was refused (robot-file's decode and validation
/// errors, in wire form).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum RobotFaultKind {
    /// Shorter than its header and CRC, or than its header says.
    Truncated,
    /// Not a robot record (magic).
    BadMagic,
    /// Another record format than the robot's build reads.
    UnsupportedFormat,
    /// Length inconsistent (too long, bytes after the CRC).
    BadLength,
    /// The record's CRC-32 does not match: corrupted.
    BadCrc,
    /// The payload is not a robot.
    Malformed,
    /// A field is NaN or infinite.
    NotFinite,
    /// A field is outside its physical range (`range`).
    OutOfRange,
    /// A field is inconsistent with another one.
    Inconsistent,
    /// The controller or the runtime refused the configuration the
    /// robot derives from the record.
    Refused,
}

/// A refused robot record: what is wrong and where.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotFault {
    /// What is wrong.
    pub kind: RobotFaultKind,
    /// The field's TOML path (e.g. `body.wheel_radius_m[1]`), empty when
    /// the record as a whole is refused; cut at [`ROBOT_FIELD_LEN`] bytes.
    pub field: heapless::String<ROBOT_FIELD_LEN>,
    /// The accepted range \[min, max\] for [`RobotFaultKind::OutOfRange`].
    pub range: Option<[f32; 2]>,
}

impl RobotFault {
    /// A fault of `kind` at `field` (cut to [`ROBOT_FIELD_LEN`] bytes on a
    /// character boundary).
    pub fn new(kind: RobotFaultKind, field: &str, range: Option<[f32; 2]>) -> Self {
        let mut f = heapless::String::new();
        for c in field.chars() {
            if f.push(c).is_err() {
                break;
            }
        }
        Self {
            kind,
            field: f,
            range,
        }
    }
}

impl RobotFaultKind {
    /// One-line reason, as the host tool prints it.
    pub const fn reason(self) -> &'static str {
        match self {
            Self::Truncated => "record truncated",
            Self::BadMagic => "not a robot record",
            Self::UnsupportedFormat => "record format not supported by the robot's build",
            Self::BadLength => "record length inconsistent",
            Self::BadCrc => "record CRC-32 mismatch (corrupted)",
            Self::Malformed => "record payload malformed",
            Self::NotFinite => "not a finite number",
            Self::OutOfRange => "outside its physical range",
            Self::Inconsistent => "inconsistent with another field",
            Self::Refused => "refused by the controller or the runtime",
        }
    }
}

/// Where the robot in force came from (status, protocol 4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RobotSource {
    /// The compiled-in default: the board has no robot store.
    #[default]
    Builtin,
    /// The record in flash.
    Flash,
    /// The compiled-in default: no record in flash.
    DefaultMissing,
    /// The compiled-in default: the record in flash is corrupt or invalid.
    DefaultCorrupt,
}

/// The robot part of [`StatusMsg`] (protocol 4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotReport {
    /// Where the robot in force came from.
    pub source: RobotSource,
    /// CRC-32 (ISO-HDLC) of the record in force (the default's encoding
    /// when it is the default).
    pub active_crc32: u32,
    /// CRC-32 of the record now in flash (0: none); differs from
    /// `active_crc32` after a write until the robot reboots into it.
    pub stored_crc32: u32,
    /// Successful record writes since boot.
    pub writes: u16,
    /// Failed record writes since boot.
    pub write_failures: u16,
}

/// Why a request was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ErrorCode {
    /// The frame's protocol version differs from the robot's.
    VersionMismatch,
    /// The frame's CRC does not match its content.
    BadCrc,
    /// The frame does not decode into a request.
    Malformed,
    /// The frame is longer than [`MAX_FRAME`](crate::MAX_FRAME).
    TooLong,
    /// Not allowed while running (disarm first).
    Busy,
    /// Arming needs a loaded reference, a complete trajectory or a velocity command.
    NoReference,
    /// A safe stop is latched: clear it first.
    Latched,
    /// A value is NaN, infinite or outside its physical range
    /// (book/src/reference/protocol.md, "Parameters" and the requests' rows).
    InvalidValue,
    /// The parameter cannot be written.
    ReadOnly,
    /// The trajectory buffer is full: send the segment again later.
    BufferFull,
    /// A segment does not continue the upload (index, time order, no begin).
    OutOfOrder,
    /// The command does not apply in the current mode.
    WrongMode,
    /// Arming needs the whole declared upload (or a full buffer when the
    /// trajectory is longer than it): segments are missing.
    UploadIncomplete,
    /// External pose refused: a coordinate is NaN, infinite or implausibly
    /// large.
    PoseNonFinite,
    /// External pose refused: a position std dev is not in (0, 1000], or
    /// a heading std dev is negative or above 1000 (0 = no heading).
    PoseBadStdDev,
    /// External pose refused: stamped after the robot's current tick.
    PoseFromFuture,
    /// External pose refused: older than the estimator's history.
    PoseTooOld,
    /// External pose refused: stamped before the last accepted one.
    PoseOutOfOrder,
    /// External pose refused: another one waits for the same tick.
    PoseQueueFull,
    /// The board has no robot store (protocol 4).
    NoStore,
    /// The flash write of the robot record failed; the previous record
    /// is still the stored one (protocol 4).
    StoreFailed,
    // --- commissioning (issue 18) ---
    /// A wheel test's torque is above the commissioning cap
    /// (the torque limit, and the stall torque at the duty limit).
    AboveTestCap,
}

/// The robot's run state as the host sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RunStateMsg {
    /// Motors off, waiting for a reference or velocity command and arm (boot state).
    Hold,
    /// Tracking the reference or velocity command.
    Running,
    /// Braking to a standstill along the reference, then hold.
    Stopping,
    /// Latched safe stop: motors off until cleared.
    Stopped,
}

/// What the robot drives when armed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ModeMsg {
    /// Nothing loaded: arming is refused.
    None,
    /// A built-in reference.
    Builtin,
    /// An uploaded waypoint trajectory.
    Trajectory,
    /// Velocity commands.
    Velocity,
}

/// Why the robot stopped (a latched stop or a controlled stop).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StopCode {
    /// The controller rejected its input.
    ControllerInput,
    /// An implausible encoder jump.
    EncoderJump,
    /// A wheel did not move under torque.
    EncoderStalled,
    /// Sustained loop overrun.
    LoopOverrun,
    /// Emergency stop request or stop command.
    Commanded,
    /// No valid frame for longer than the link timeout while moving.
    LinkSilence,
    /// The velocity command expired.
    VelocityTimeout,
    /// The uploaded trajectory ended (every declared waypoint driven).
    TrajectoryEnd,
    /// Disarmed by the host or the button.
    Disarmed,
    /// Any other runtime stop: a reference beyond the robot's limits, or
    /// a trajectory that ran out of streamed waypoints before its declared
    /// end (issue 37, D195).
    Other,
    /// A wheel accelerated against its commanded torque for the direction
    /// check's window: a motor or encoder wired backwards (version 4).
    DirectionMismatch,
}

/// Something that happened on the robot, pushed without a request.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event {
    /// The run state changed.
    StateChanged {
        /// New state.
        state: RunStateMsg,
        /// Why, when it is a stop.
        cause: Option<StopCode>,
    },
    /// The link went quiet while moving: a controlled stop began.
    LinkLost,
}

/// Robot constants sent in the handshake.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotInfo {
    /// Wheel radius r \[m\].
    pub wheel_radius_m: f32,
    /// Half track h \[m\].
    pub half_track_m: f32,
    /// Mass m \[kg\].
    pub mass_kg: f32,
    /// Control period \[s\].
    pub control_period_s: f32,
    /// Per-wheel torque limit \[N·m\].
    pub torque_limit_nm: f32,
}

/// Capability bits of [`Reply::Hello`].
pub type Capabilities = u16;
/// Accepts external pose measurements.
pub const CAP_EXTERNAL_POSE: Capabilities = 1;
/// Accepts waypoint trajectories.
pub const CAP_TRAJECTORY: Capabilities = 2;
/// Accepts velocity commands.
pub const CAP_VELOCITY: Capabilities = 4;
/// A simulated robot (`hil-sim device`).
pub const CAP_SIMULATED: Capabilities = 8;
/// Stores the robot record in flash (`Request::Robot*`, protocol 4).
pub const CAP_ROBOT_STORE: Capabilities = 16;

/// Status counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counters {
    /// Control ticks since boot.
    pub ticks: u32,
    /// Controller steps since the last arming.
    pub run_ticks: u32,
    /// Overrun episodes.
    pub overruns: u32,
    /// Largest time between two ticks \[µs\].
    pub max_loop_time_us: u32,
    /// Implausible encoder jumps.
    pub encoder_jumps: u32,
    /// Rejected controller inputs.
    pub input_faults: u32,
    /// Torque-saturated steps.
    pub torque_saturated: u32,
    /// Duty-saturated wheel-steps.
    pub duty_saturated: u32,
    /// External pose measurements used.
    pub external_poses: u32,
    /// Latched stops.
    pub stops: u32,
    /// Valid frames received.
    pub rx_frames: u32,
    /// Frames dropped: bad CRC, malformed, too long, wrong version.
    pub rx_errors: u32,
    /// Received bytes dropped because the receive buffer was full.
    pub rx_overflow: u32,
    /// Outgoing frames dropped because the send buffer was full.
    pub tx_dropped: u32,
    /// Requests refused with a nack.
    pub nacks: u32,
}

/// Reply to [`Request::GetStatus`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StatusMsg {
    /// Run state.
    pub state: RunStateMsg,
    /// Loaded mode.
    pub mode: ModeMsg,
    /// The last stop's cause (latched or controlled), if any.
    pub last_stop: Option<StopCode>,
    /// Robot clock \[µs\].
    pub t_robot_us: u32,
    /// Waypoints in the trajectory buffer.
    pub buffered_points: u16,
    /// Every counter.
    pub counters: Counters,
    /// External poses the estimator refused after the link accepted them
    /// (chi-square gate, a history that moved on), and those of a board
    /// pose source, by reason.
    pub pose_rejects: PoseRejects,
    /// Telemetry frames not sent because a value in them was NaN or
    /// infinite (a runtime fault; the frame's sequence number is skipped).
    pub nonfinite_telemetry: u32,
    /// What the board itself reports: its last reset's cause and its link
    /// port's own losses (protocol 3).
    pub board: BoardReport,
    /// The robot record: where the robot in force came from, its hash and
    /// the stored one's (protocol 4).
    pub robot: RobotReport,
}

/// Why the robot's MCU last reset, read from its reset controller at boot
/// (STM32: the RCC_CSR flags, then cleared).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetCause {
    /// Not known (a board without a reset controller, e.g. simulated).
    #[default]
    Unknown,
    /// Power-on (or power-down) reset: the supply came up.
    PowerOn,
    /// Brown-out: the supply dipped below the BOR threshold.
    BrownOut,
    /// The NRST pin (the reset button or a debugger), nothing else flagged.
    Pin,
    /// Software reset (SYSRESETREQ: a debugger's reset or the firmware's).
    Software,
    /// The independent watchdog: the control loop stopped feeding it.
    IndependentWatchdog,
    /// The window watchdog.
    WindowWatchdog,
    /// Low-power management (entering standby or stop when not allowed).
    LowPower,
}

/// The board's own report in [`StatusMsg`]: the last reset's cause and the
/// link port's losses before the protocol handler, since boot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardReport {
    /// Why the MCU last reset.
    pub reset_cause: ResetCause,
    /// Received bytes the port dropped before the protocol handler (its
    /// receive pipe or the UART's ring buffer full).
    pub port_rx_dropped: u32,
    /// Receive errors the port's hardware flagged (UART overrun, framing,
    /// noise, parity).
    pub port_rx_errors: u32,
}

/// External pose measurements the estimator refused, by reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseRejects {
    /// A coordinate NaN, infinite or implausibly large.
    pub non_finite: u32,
    /// A standard deviation out of range.
    pub bad_std_dev: u32,
    /// Stamped after the tick.
    pub from_future: u32,
    /// Older than the history.
    pub too_old: u32,
    /// Before the last accepted one.
    pub out_of_order: u32,
    /// Failed the chi-square gate.
    pub outlier: u32,
}

/// Telemetry group [`TELEMETRY_TRACKING`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackingTelemetry {
    /// Pose given to the controller.
    pub pose: PoseMsg,
    /// Reference pose.
    pub ref_pose: PoseMsg,
    /// Tracking error \[e_x m, e_y m, e_θ rad\] in the robot frame (eq. 8).
    pub error: [f32; 3],
    /// Measured η = \[v m/s, ω rad/s\].
    pub eta: [f32; 2],
    /// η_c = \[v_c m/s, ω_c rad/s\] (eq. 14).
    pub eta_c: [f32; 2],
    /// Wheel torques \[right, left\] \[N·m\].
    pub torque_nm: [f32; 2],
    /// Signed PWM duty \[right, left\] \[counts\].
    pub duty: [i32; 2],
    /// The torque request exceeded the limit this tick.
    pub saturated: bool,
    /// Reference governor time scale s after this tick (1 = nominal speed).
    pub time_scale: f32,
    /// Governed reference time τ the next tick uses \[s\].
    pub tau_s: f32,
    /// Health mode: 0 nominal, 1 degraded, 2 safe stop.
    pub health: u8,
    /// Reason published with the health mode (controller-core's
    /// `HealthReason` as its index, 0 = none).
    pub health_reason: u8,
}

/// Telemetry group [`TELEMETRY_ESTIMATORS`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EstimatorTelemetry {
    /// Sliding variable s (eq. 20).
    pub s: [f32; 2],
    /// Switching gain ρ̂ (or K).
    pub rho_hat: [f32; 2],
    /// ESO disturbance estimate D̂.
    pub d_hat: [f32; 2],
    /// Fault estimate F̂ = \[Δv̂ m/s, Δω̂ rad/s\].
    pub f_hat: [f32; 2],
    /// The pose came from an external measurement this tick.
    pub external_pose: bool,
    /// The controller rejected its input this tick.
    pub input_fault: bool,
}

/// A compact `f32` on the wire: bfloat16, the upper 16 bits of the IEEE
/// 754 single (sign, 8-bit exponent, 7-bit mantissa), rounded to nearest
/// even: the range of an `f32`, a relative error of at most 2⁻⁸ (0.4 %),
/// two bytes (D155). Non-finite values stay non-finite.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Bf16(pub [u8; 2]);

impl Bf16 {
    /// `x` rounded to the nearest bfloat16 (ties to even).
    pub fn from_f32(x: f32) -> Self {
        let b = x.to_bits();
        let h = if x.is_nan() {
            (b >> 16) | 0x40 // a quiet NaN whatever the payload
        } else {
            let round = 0x7FFF + ((b >> 16) & 1);
            (b + round) >> 16 // an overflow rounds to infinity, as it should
        };
        Self((h as u16).to_le_bytes())
    }

    /// The value as an `f32` (exact).
    pub fn to_f32(self) -> f32 {
        f32::from_bits((u16::from_le_bytes(self.0) as u32) << 16)
    }
}

/// Telemetry group [`TELEMETRY_COVARIANCE`]: the pose estimator's
/// uncertainty as ROS's `/odom` reports it, for the axle midpoint O_B
/// (`base_link`), each value a [`Bf16`]. Computed by the robot only when a
/// frame carrying it is sent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CovarianceTelemetry {
    /// Upper triangle of the covariance of (x, y, θ) of O_B, row by row:
    /// xx \[m²\], xy \[m²\], xθ \[m·rad\], yy \[m²\], yθ \[m·rad\], θθ \[rad²\].
    pub pose: [Bf16; 6],
    /// Variances of v \[(m/s)²\] and ω \[(rad/s)²\].
    pub twist: [Bf16; 2],
}

impl CovarianceTelemetry {
    /// Rounds the pose covariance's upper triangle and the twist variances
    /// (units as in the fields).
    pub fn from_f32(pose: [f32; 6], twist: [f32; 2]) -> Self {
        Self {
            pose: pose.map(Bf16::from_f32),
            twist: twist.map(Bf16::from_f32),
        }
    }

    /// The pose covariance's upper triangle (xx, xy, xθ, yy, yθ, θθ).
    pub fn pose_f32(&self) -> [f32; 6] {
        self.pose.map(Bf16::to_f32)
    }

    /// The twist variances (v, ω).
    pub fn twist_f32(&self) -> [f32; 2] {
        self.twist.map(Bf16::to_f32)
    }
}

/// One telemetry frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Telemetry {
    /// Telemetry frame number (wraps; a gap is a dropped frame).
    pub seq: u32,
    /// Robot clock at the tick \[µs\].
    pub t_robot_us: u32,
    /// Reference time \[s\] (since arming).
    pub t_ref_s: f32,
    /// Run state.
    pub state: RunStateMsg,
    /// Group [`TELEMETRY_TRACKING`].
    pub tracking: Option<TrackingTelemetry>,
    /// Group [`TELEMETRY_ESTIMATORS`].
    pub estimators: Option<EstimatorTelemetry>,
    /// Group [`TELEMETRY_COUNTERS`].
    pub counters: Option<Counters>,
    /// Group [`TELEMETRY_COVARIANCE`] (protocol 5).
    pub covariance: Option<CovarianceTelemetry>,
}

fn all_finite(xs: &[f32]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

impl Telemetry {
    /// True when every float in the frame is finite (the robot sends no
    /// other telemetry).
    pub fn is_finite(&self) -> bool {
        let tracking = self.tracking.as_ref().is_none_or(|t| {
            t.pose.is_finite()
                && t.ref_pose.is_finite()
                && all_finite(&t.error)
                && all_finite(&t.eta)
                && all_finite(&t.eta_c)
                && all_finite(&t.torque_nm)
                && all_finite(&[t.time_scale, t.tau_s])
        });
        let estimators = self.estimators.as_ref().is_none_or(|e| {
            all_finite(&e.s)
                && all_finite(&e.rho_hat)
                && all_finite(&e.d_hat)
                && all_finite(&e.f_hat)
        });
        let covariance = self
            .covariance
            .as_ref()
            .is_none_or(|c| all_finite(&c.pose_f32()) && all_finite(&c.twist_f32()));
        self.t_ref_s.is_finite() && tracking && estimators && covariance
    }
}

impl Reply {
    /// The sequence number of the request this reply answers; `None` for
    /// streams (telemetry, events) and frame errors.
    pub fn seq(&self) -> Option<u16> {
        match self {
            Reply::Ack { seq }
            | Reply::Nack { seq, .. }
            | Reply::Hello { seq, .. }
            | Reply::Status { seq, .. }
            | Reply::Param { seq, .. }
            | Reply::ClockSync { seq, .. }
            | Reply::TrajectoryAck { seq, .. }
            | Reply::RobotRejected { seq, .. }
            | Reply::RobotData { seq, .. }
            | Reply::WheelTestDone { seq, .. } => Some(*seq),
            Reply::FrameError { .. } | Reply::Telemetry(_) | Reply::Event(_) => None,
        }
    }
}

/// Robot → host.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Reply {
    /// The request `seq` was accepted.
    Ack {
        /// Sequence number of the request.
        seq: u16,
    },
    /// The request `seq` was refused.
    Nack {
        /// Sequence number of the request.
        seq: u16,
        /// Why.
        error: ErrorCode,
    },
    /// A frame was dropped before its sequence number could be read.
    FrameError {
        /// Why.
        error: ErrorCode,
    },
    /// Answer to [`Request::Hello`].
    Hello {
        /// Sequence number of the request.
        seq: u16,
        /// The robot's [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION).
        version: u16,
        /// `CAP_*` bits.
        capabilities: Capabilities,
        /// Chip or board name, e.g. `stm32f411ce` or `sim`.
        chip: heapless::String<16>,
        /// Robot constants.
        robot: RobotInfo,
    },
    /// Answer to [`Request::GetStatus`].
    Status {
        /// Sequence number of the request.
        seq: u16,
        /// The status.
        status: StatusMsg,
    },
    /// Answer to [`Request::GetParam`].
    Param {
        /// Sequence number of the request.
        seq: u16,
        /// Which.
        id: ParamId,
        /// Its value, in its unit.
        value: f32,
    },
    /// Answer to [`Request::ClockSync`].
    ClockSync {
        /// Sequence number of the request.
        seq: u16,
        /// The host's time, echoed \[µs\].
        host_time_us: u64,
        /// Robot clock when the request was handled \[µs\].
        robot_time_us: u32,
    },
    /// Answer to [`Request::TrajectorySegment`]: accepted, with flow control.
    TrajectoryAck {
        /// Sequence number of the request.
        seq: u16,
        /// Index the next segment must start at.
        next_index: u32,
        /// Free waypoint slots in the buffer.
        free: u16,
    },
    /// A telemetry frame.
    Telemetry(Telemetry),
    /// An event.
    Event(Event),
    /// Answer to [`Request::RobotCommit`]: the staged record was refused
    /// (nothing was stored).
    RobotRejected {
        /// Sequence number of the request.
        seq: u16,
        /// What is wrong and where.
        fault: RobotFault,
    },
    /// Answer to [`Request::RobotRead`].
    RobotData {
        /// Sequence number of the request.
        seq: u16,
        /// Length of the whole stored record \[bytes\].
        total_len: u16,
        /// Offset of `data` \[bytes\].
        offset: u16,
        /// Up to [`ROBOT_CHUNK`] bytes (empty at or past the end).
        data: Vec<u8, ROBOT_CHUNK>,
    },
    // --- commissioning (issue 18) ---
    /// A wheel test ended (motors off on this tick): the second answer
    /// to its [`Request::WheelTest`], after the ack.
    WheelTestDone {
        /// Sequence number of the `WheelTest` request.
        seq: u16,
        /// What it measured.
        result: WheelTestResult,
    },
}

impl ParamId {
    /// Every parameter, in wire order.
    pub const ALL: [ParamId; 15] = [
        Self::TorqueLimitNm,
        Self::Kx,
        Self::Ky,
        Self::Ktheta,
        Self::Ks,
        Self::StallTorqueNm,
        Self::StallTicks,
        Self::TelemetryRateHz,
        Self::LinkTimeoutMs,
        Self::AccelMps2,
        Self::AngAccelRadps2,
        Self::BrakeDecelMps2,
        Self::MaxSpeedMps,
        Self::MaxYawRateRadps,
        Self::ControlPeriodS,
    ];

    /// Its declaration in the parameter table (controller-core
    /// `param_table`): name, unit, range, access.
    pub fn param(self) -> &'static Param {
        use controller_core::runtime::param_table as t;
        match self {
            Self::TorqueLimitNm => &t::LIMITS_TORQUE_NM,
            Self::Kx => &t::GAINS_K_X,
            Self::Ky => &t::GAINS_K_Y,
            Self::Ktheta => &t::GAINS_K_TH,
            Self::Ks => &t::GAINS_K_S,
            Self::StallTorqueNm => &t::STALL_TORQUE_NM,
            Self::StallTicks => &t::STALL_TICKS,
            Self::TelemetryRateHz => &t::TELEMETRY_RATE_HZ,
            Self::LinkTimeoutMs => &t::LIMITS_LINK_TIMEOUT_MS,
            Self::AccelMps2 => &t::LIMITS_MAX_ACCEL_MPS2,
            Self::AngAccelRadps2 => &t::ANG_ACCEL_RADPS2,
            Self::BrakeDecelMps2 => &t::BRAKE_DECEL_MPS2,
            Self::MaxSpeedMps => &t::LIMITS_MAX_SPEED_MPS,
            Self::MaxYawRateRadps => &t::LIMITS_MAX_YAW_RATE_RADPS,
            Self::ControlPeriodS => &t::CONTROL_PERIOD,
        }
    }

    /// The name the host tool uses (`wmr params get NAME`): the robot
    /// file's path (the parameter table's).
    pub fn name(self) -> &'static str {
        self.param().name
    }

    /// The parameter of a [`Self::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }
}

impl ErrorCode {
    /// One-line reason, as the host tool prints it.
    pub const fn reason(self) -> &'static str {
        match self {
            Self::VersionMismatch => "protocol version mismatch",
            Self::BadCrc => "frame CRC mismatch",
            Self::Malformed => "malformed frame",
            Self::TooLong => "frame too long",
            Self::Busy => "not allowed while running (disarm first)",
            Self::NoReference => "no reference, trajectory or velocity command loaded",
            Self::Latched => "a safe stop is latched (clear it first)",
            Self::InvalidValue => "value NaN, infinite or outside its physical range",
            Self::ReadOnly => "parameter is read-only",
            Self::BufferFull => "trajectory buffer full",
            Self::OutOfOrder => "segment does not continue the upload",
            Self::WrongMode => "command does not apply in the current mode",
            Self::UploadIncomplete => "trajectory upload incomplete (segments missing)",
            Self::PoseNonFinite => "pose coordinate NaN, infinite or implausibly large",
            Self::PoseBadStdDev => "pose std dev zero, negative or above 1000",
            Self::PoseFromFuture => "pose stamped in the robot's future",
            Self::PoseTooOld => "pose older than the estimator's history",
            Self::PoseOutOfOrder => "pose stamped before the last accepted one",
            Self::PoseQueueFull => "another pose waits for the same tick",
            Self::NoStore => "the robot has no robot store",
            Self::StoreFailed => "flash write failed (the previous record is kept)",
            Self::AboveTestCap => "wheel-test torque above the commissioning cap",
        }
    }
}

/// The built-in shapes by the names of the simulator's `trajectory` key
/// (`paper`, `circle`, `figure8`, `line`), with the simulator's parameters
/// (hil-sim tests that both sample the same reference).
pub fn named_shape(name: &str) -> Option<BuiltinShape> {
    match name {
        "paper" => Some(BuiltinShape::PaperCurve {
            ax_m: 4.0,
            ay_m: 3.0,
            w_radps: 0.2,
        }),
        "circle" => Some(BuiltinShape::Circle {
            radius_m: 2.0,
            speed_mps: 0.5,
        }),
        "figure8" => Some(BuiltinShape::FigureEight {
            amplitude_m: 3.0,
            w_radps: 0.2,
        }),
        "line" => Some(BuiltinShape::Line { speed_mps: 0.5 }),
        _ => None,
    }
}
