//! The bridge's core, without DDS: the robot's link on one side, ROS 2
//! messages (as plain structs) on the other. `main.rs` only moves messages
//! between this and ros2-client.
//!
//! **Motion is enabled, not implied.** `cmd_vel` and paths move the robot
//! only after the arm service (or `--enable`): a stale publisher on the
//! network does not start a robot that was just connected. Disarm and
//! emergency stop disable it again. Once enabled, a `cmd_vel` while the
//! robot holds selects velocity mode and arms it, so that after a
//! `VelocityTimeout` stop (a silent publisher) the next command drives
//! again, as Nav2 expects.
//!
//! **Timeouts.** Each `cmd_vel` is forwarded as one velocity command with
//! the bridge's `cmd_timeout_ms` (the robot's own timeout: the bridge
//! never refreshes a command itself), so a silent publisher makes the
//! *robot* brake to a stop `cmd_timeout_ms` after the last command,
//! whatever the bridge does. The bridge keeps the link alive with clock
//! syncs every keep-alive period (a fifth of the robot's link timeout),
//! which also keep the robot-time offset fresh for stamping poses.

use crate::convert::{
    external_pose_request, g_of_axle, planar, pose_msg, velocity_command, Limits, Refusal,
    MAX_POSITION_M,
};
use crate::msg::{Path, PoseWithCovarianceStamped, SetOdometryRequest};
use crate::profile;
use ros_mcap::msg::{DiagnosticStatus, KeyValue, Twist};
use ros_mcap::{Geometry, LogFrame, RosFrames, RosMessages, TimeMap};
use std::time::{Duration, Instant};
use wmr::session::{
    self, telemetry_gap, ClockTracker, ComOffset, Motion, PoseTally, Pump, SegmentStream,
    StreamError, TELEMETRY_SILENCE,
};
use wmr::{Link, LinkError};
use wmr_protocol::{
    ErrorCode, Event, ModeMsg, ParamId, Reply, Request, RunStateMsg, StopCode, Telemetry,
    TELEMETRY_ALL,
};

/// The bridge's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// Telemetry (and so `/odom`, `/tf`, `/joint_states`) rate \[Hz\].
    pub rate_hz: u16,
    /// Timeout of each forwarded `cmd_vel` on the robot \[ms\] (1..=5000).
    pub cmd_timeout_ms: u16,
    /// d, G ahead of the axle \[m\], when given (`--com-offset-m`); `None`:
    /// the robot's own (`body.com_offset_m` of the robot file it runs,
    /// [`wmr::session::com_offset_m`]).
    pub com_offset_m: Option<f64>,
    /// Fraction of the robot's speed and acceleration limits a path's
    /// profile uses, in (0, 1] (the rest is the controller's margin).
    pub path_limit_fraction: f64,
    /// Motion enabled from the start (no arm service call needed).
    pub enable: bool,
}

/// Default `cmd_timeout_ms`: `wmr drive`'s, three missed commands of a
/// 10 Hz publisher.
pub const DEFAULT_CMD_TIMEOUT_MS: u16 = 300;
/// Default telemetry rate \[Hz\] (Nav2's controllers run at 20 Hz).
pub const DEFAULT_RATE_HZ: u16 = 50;
/// Default [`Config::path_limit_fraction`].
pub const DEFAULT_PATH_LIMIT_FRACTION: f64 = 0.8;
/// Clock-sync samples kept; the shortest round trip among them sets the
/// offset.
const SYNC_WINDOW: usize = 16;

/// Why the bridge's settings are refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// The telemetry rate.
    #[error("rate {0} Hz is not in 1..=1000 Hz")]
    Rate(u16),
    /// The cmd_vel timeout.
    #[error("cmd_vel timeout {0} ms is not in 1..=5000 ms (the robot's range)")]
    CmdTimeout(u16),
    /// The path limit fraction.
    #[error("path limit fraction {0} is not in (0, 1]")]
    PathLimitFraction(f64),
}

impl Config {
    /// Checked settings.
    pub fn new(
        rate_hz: u16,
        cmd_timeout_ms: u16,
        com_offset_m: Option<f64>,
        path_limit_fraction: f64,
        enable: bool,
    ) -> Result<Self, ConfigError> {
        if !(1..=1000).contains(&rate_hz) {
            return Err(ConfigError::Rate(rate_hz));
        }
        if !(1..=5000).contains(&cmd_timeout_ms) {
            return Err(ConfigError::CmdTimeout(cmd_timeout_ms));
        }
        if !(path_limit_fraction.is_finite()
            && path_limit_fraction > 0.0
            && path_limit_fraction <= 1.0)
        {
            return Err(ConfigError::PathLimitFraction(path_limit_fraction));
        }
        Ok(Self {
            rate_hz,
            cmd_timeout_ms,
            com_offset_m,
            path_limit_fraction,
            enable,
        })
    }
}

/// Why the bridge cannot go on.
#[derive(Clone, Debug, PartialEq)]
pub enum Fatal {
    /// The link failed.
    Link(LinkError),
    /// No telemetry for [`TELEMETRY_SILENCE`].
    Silence,
    /// The robot's constants are not a robot.
    Robot(String),
}

impl std::fmt::Display for Fatal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Link(e) => write!(f, "{e}"),
            Self::Silence => write!(
                f,
                "no telemetry from the robot for {} s",
                TELEMETRY_SILENCE.as_secs()
            ),
            Self::Robot(e) => write!(f, "{e}"),
        }
    }
}

impl From<LinkError> for Fatal {
    fn from(e: LinkError) -> Self {
        Self::Link(e)
    }
}

/// What a message or a service call did.
pub type Outcome = Result<Result<String, Refusal>, Fatal>;

/// Counters of what came in from ROS and what went out to the robot.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    /// `cmd_vel` messages received.
    pub cmd_vel: u64,
    /// Forwarded to the robot and acknowledged.
    pub cmd_vel_forwarded: u64,
    /// Refused as stale (stamped longer ago than the command timeout) or
    /// from the future (more than `MAX_FUTURE_STAMP_NS` ahead).
    pub cmd_vel_stale: u64,
    /// Scaled down to the robot's limits (curvature kept).
    pub cmd_vel_scaled: u64,
    /// Not forwarded or refused (see `last_refusal`).
    pub cmd_vel_refused: u64,
    /// Paths received.
    pub paths: u64,
    /// Paths uploaded (all segments acknowledged).
    pub paths_uploaded: u64,
    /// Paths refused.
    pub paths_refused: u64,
    /// Initial poses set.
    pub initial_poses: u64,
    /// Initial poses refused.
    pub initial_poses_refused: u64,
    /// Localiser poses not sent (bad message) — those the robot refused
    /// are in the pose tally.
    pub poses_invalid: u64,
    /// Localiser poses and initial poses refused for their frame (not
    /// `odom`: AMCL's `map`).
    pub poses_wrong_frame: u64,
    /// Telemetry frames not published: stamped at or before the last one
    /// published (tf2 warns on a repeated stamp).
    pub frames_repeated: u64,
    /// Set-odometry calls that set the pose.
    pub odometry_sets: u64,
    /// Service requests refused unanswered and not acted on (neither
    /// mapping's request id, another mapping than the one accepted, or not
    /// of the service's type; D150).
    pub service_requests_refused: u64,
    /// Telemetry frames received.
    pub frames: u64,
    /// Telemetry frames lost (gaps in their sequence numbers).
    pub frames_dropped: u64,
    /// Link-lost events from the robot.
    pub link_lost_events: u64,
    /// The last refusal, for `/diagnostics`.
    pub last_refusal: String,
}

/// A path being uploaded (and streamed while it runs).
#[derive(Clone, Debug)]
struct UploadState {
    stream: SegmentStream,
    armed: bool,
}

/// The bridge.
pub struct Bridge {
    link: Link,
    cfg: Config,
    geometry: Geometry,
    com_offset: ComOffset,
    limits: Limits,
    frames: RosFrames,
    clock: ClockTracker,
    time_map: TimeMap,
    brake_decel_mps2: f64,
    last_frame: Instant,
    last_seq: Option<u32>,
    state: RunStateMsg,
    mode: ModeMsg,
    last_stop: Option<StopCode>,
    enabled: bool,
    upload: Option<UploadState>,
    queued_path: Option<Vec<wmr_protocol::Waypoint>>,
    last_log_frame: Option<LogFrame>,
    stamps: StampGate,
    /// What came in and went out.
    pub stats: Stats,
    /// Localiser poses sent and refused by reason.
    pub poses: PoseTally,
}

fn param(link: &mut Link, id: ParamId) -> Result<f32, Fatal> {
    Ok(session::get_param(link, id)?)
}

/// A command stamped at `stamp_ns` is stale at `now_ns` when older than
/// the command timeout (a stamp in the future is not: clocks differ a
/// little between hosts).
pub fn stale(stamp_ns: u64, now_ns: u64, cmd_timeout_ms: u16) -> bool {
    now_ns.saturating_sub(stamp_ns) > cmd_timeout_ms as u64 * 1_000_000
}

/// How far ahead of this host's clock a command's stamp may be \[ns\]:
/// hosts' clocks differ a little (NTP keeps them within milliseconds),
/// never by a second.
pub const MAX_FUTURE_STAMP_NS: u64 = 1_000_000_000;

/// A command stamped at `stamp_ns` is from the future at `now_ns` when
/// ahead by more than [`MAX_FUTURE_STAMP_NS`] (issue 31 item 6: a
/// `cmd_vel` stamped 1,000 s ahead was taken).
pub fn from_future(stamp_ns: u64, now_ns: u64) -> bool {
    stamp_ns.saturating_sub(now_ns) > MAX_FUTURE_STAMP_NS
}

/// A pose's frame must be the one the robot's estimate is published in
/// (`odom`; tf2's leading slash allowed): a pose in another frame, such as
/// AMCL's `map`, is refused, never fused as `odom` — map → odom is the
/// localiser's own transform (REP-105: `odom` stays continuous), and
/// transforming it back through that transform gives the odometry itself.
pub fn odom_frame(frame_id: &str) -> Result<(), Refusal> {
    if frame_id.strip_prefix('/').unwrap_or(frame_id) == ros_mcap::FRAME_ODOM {
        return Ok(());
    }
    Err(Refusal::WrongFrame(format!(
        "pose in frame {frame_id:?}, not {:?}: the robot's estimate is the odom frame; a map-frame localiser (AMCL) corrects map -> odom itself (REP-105), so its poses are not fused (publish poses in {:?} to fuse them)",
        ros_mcap::FRAME_ODOM,
        ros_mcap::FRAME_ODOM
    )))
}

/// Puts the covariances of the pose (of `base_link`, row-major 6×6: x, y,
/// z, roll, pitch, yaw) and of the twist into an `/odom` message: the one
/// place the bridge's `/odom` covariance is set besides ros-mcap's
/// `RosFrames` (which fills its fixed ones), for the estimator's
/// covariance once the link carries it (issue 35, the other half).
pub fn set_odom_covariance(
    odom: &mut ros_mcap::msg::Odometry,
    pose_cov: [f64; 36],
    twist_cov: [f64; 36],
) {
    odom.pose.covariance = ros_mcap::msg::Covariance::from_array(pose_cov);
    odom.twist.covariance = ros_mcap::msg::Covariance::from_array(twist_cov);
}

/// Admits telemetry stamps strictly after the last one admitted: `/odom`
/// and `/tf` never repeat a stamp nor go back (tf2 warns on a repeated
/// stamp; issue 35 saw three `/odom` of one stamp at start, and a clock
/// re-anchoring may step the stamps back by microseconds).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StampGate {
    last_ns: Option<u64>,
}

impl StampGate {
    /// True when `stamp_ns` is after every stamp admitted before (and
    /// admits it).
    pub fn admit(&mut self, stamp_ns: u64) -> bool {
        if self.last_ns.is_some_and(|l| stamp_ns <= l) {
            return false;
        }
        self.last_ns = Some(stamp_ns);
        true
    }
}

fn nack_reason(e: &LinkError) -> Option<ErrorCode> {
    match e {
        LinkError::Nack(_, c) => Some(*c),
        _ => None,
    }
}

impl Bridge {
    /// Connects over `link` (after its handshake or not): reads the robot's
    /// constants and limits, syncs the clocks, turns telemetry on.
    pub fn connect(mut link: Link, cfg: Config) -> Result<Self, Fatal> {
        let hello = link.hello()?;
        session::adopt_link_timeout(&mut link)?;
        // d from the robot file the robot runs unless given.
        let com_offset = session::com_offset_m(&mut link, cfg.com_offset_m)?;
        // Every robot value from the robot on the link (issue 35): a robot
        // that cannot tell its d is not given the paper robot's.
        if let session::ComOffsetSource::PaperDefault(why) = &com_offset.source {
            return Err(Fatal::Robot(format!(
                "d (body.com_offset_m) is not known from the robot on the link: {why}; give --com-offset-m (the robot file's body.com_offset_m) or push and boot its robot file (wmr robot push)"
            )));
        }
        let geometry = Geometry::new(
            hello.robot.wheel_radius_m as f64,
            hello.robot.half_track_m as f64,
            com_offset.com_offset_m,
        )
        .map_err(|e| Fatal::Robot(e.to_string()))?;
        let limits = Limits::new(
            param(&mut link, ParamId::MaxSpeedMps)? as f64,
            param(&mut link, ParamId::MaxYawRateRadps)? as f64,
            param(&mut link, ParamId::AccelMps2)? as f64,
            param(&mut link, ParamId::AngAccelRadps2)? as f64,
        )
        .map_err(Fatal::Robot)?;
        let brake_decel_mps2 = param(&mut link, ParamId::BrakeDecelMps2)? as f64;
        let clock = ClockTracker::start(&mut link, hello.robot.control_period_s, SYNC_WINDOW)?;
        let st = session::status(&mut link)?;
        link.command(&Request::SetTelemetry {
            selection: TELEMETRY_ALL,
            rate_hz: cfg.rate_hz,
        })?;
        let enabled = cfg.enable;
        Ok(Self {
            time_map: clock.time_map(),
            clock,
            link,
            cfg,
            geometry,
            com_offset,
            limits,
            frames: RosFrames::new(geometry),
            brake_decel_mps2,
            last_frame: Instant::now(),
            last_seq: None,
            state: st.state,
            mode: st.mode,
            last_stop: st.last_stop,
            enabled,
            upload: None,
            queued_path: None,
            last_log_frame: None,
            stamps: StampGate::default(),
            stats: Stats::default(),
            poses: PoseTally::default(),
        })
    }

    /// The robot's geometry (r and h from the handshake, d as
    /// [`Self::com_offset`] says).
    pub fn geometry(&self) -> Geometry {
        self.geometry
    }

    /// d and where it came from (given, the robot's file, the paper's).
    pub fn com_offset(&self) -> &ComOffset {
        &self.com_offset
    }

    /// The robot's limits read at connection.
    pub fn limits(&self) -> Limits {
        self.limits
    }

    /// The run state last seen.
    pub fn state(&self) -> RunStateMsg {
        self.state
    }

    /// The link (tests).
    pub fn link_mut(&mut self) -> &mut Link {
        &mut self.link
    }

    /// Host time since the bridge's t0 \[µs\].
    pub fn host_us(&self) -> u64 {
        self.clock.host_us()
    }

    /// Robot − host clock offset \[µs\] and the round trip it was measured with.
    pub fn clock_offset(&self) -> (i64, u64) {
        let b = self.clock.best();
        (b.offset_us(), b.rtt_us)
    }

    fn resync(&mut self) -> Result<(), Fatal> {
        self.clock.resync(&mut self.link)?;
        // Stamps follow the robot's clock as it drifts against the host's
        // (50 ppm is 0.18 s an hour): the map is re-anchored at the best
        // recent sync.
        self.time_map = self.clock.time_map();
        Ok(())
    }

    fn refuse(&mut self, r: Refusal) -> Result<String, Refusal> {
        self.stats.last_refusal = r.to_string();
        Err(r)
    }

    /// Reads the link for up to `wait`: keeps it alive, streams pending
    /// path segments, and returns the messages of each telemetry frame
    /// (with the bridge's own status on `/diagnostics`).
    pub fn poll(&mut self, wait: Duration) -> Result<Vec<(LogFrame, RosMessages)>, Fatal> {
        if self.clock.last_sync().elapsed() >= self.link.timing().keep_alive {
            self.resync()?;
        }
        self.stream_segments()?;
        let mut out = Vec::new();
        let mut w = wait;
        for _ in 0..64 {
            match self.link.next_stream(w)? {
                None => break,
                Some(Reply::Telemetry(t)) => {
                    if let Some(m) = self.telemetry(&t) {
                        out.push(m);
                    }
                }
                Some(Reply::Event(e)) => self.event(e),
                Some(_) => {}
            }
            w = Duration::ZERO;
        }
        if self.last_frame.elapsed() > TELEMETRY_SILENCE {
            return Err(Fatal::Silence);
        }
        if self.state == RunStateMsg::Hold && self.upload.as_ref().is_none_or(|u| u.armed) {
            if let Some(pts) = self.queued_path.take() {
                if let Err(r) = self.start_upload(pts)? {
                    self.stats.paths_refused += 1;
                    self.stats.last_refusal = format!("queued path: {r}");
                }
            }
        }
        Ok(out)
    }

    fn event(&mut self, e: Event) {
        match e {
            Event::StateChanged { state, cause } => {
                self.state = state;
                if cause.is_some() {
                    self.last_stop = cause;
                }
                if state != RunStateMsg::Running {
                    if let Some(u) = &self.upload {
                        if u.armed {
                            self.upload = None;
                        }
                    }
                }
            }
            Event::LinkLost => self.stats.link_lost_events += 1,
        }
    }

    /// The messages of one telemetry frame (`None` without the tracking
    /// group); also the frame as the MCAP log writes it.
    fn telemetry(&mut self, t: &Telemetry) -> Option<(LogFrame, RosMessages)> {
        self.last_frame = Instant::now();
        self.stats.frames += 1;
        if let Some(s) = self.last_seq {
            self.stats.frames_dropped += telemetry_gap(s, t.seq);
        }
        self.last_seq = Some(t.seq);
        if t.state != self.state {
            self.state = t.state;
            if t.state != RunStateMsg::Running {
                if let Some(u) = &self.upload {
                    if u.armed {
                        self.upload = None;
                    }
                }
            }
        }
        let stamp = self.time_map.host_ns(t.t_robot_us);
        if !self.stamps.admit(stamp) {
            self.stats.frames_repeated += 1;
            return None;
        }
        let f = LogFrame::of_telemetry(t, stamp, self.last_stop)?;
        self.last_log_frame = Some(f);
        let mut m = self.frames.messages(&f);
        if let Some(d) = &mut m.diagnostics {
            d.status.push(self.bridge_status());
        }
        Some((f, m))
    }

    /// The bridge's own `/diagnostics` status.
    pub fn bridge_status(&self) -> DiagnosticStatus {
        let s = &self.stats;
        let (off, rtt) = self.clock_offset();
        let mut values = Vec::new();
        let mut kv = |k: &str, v: String| {
            values.push(KeyValue {
                key: k.into(),
                value: v,
            })
        };
        kv("motion_enabled", self.enabled.to_string());
        kv("mode", format!("{:?}", self.mode));
        kv("cmd_vel_received", s.cmd_vel.to_string());
        kv("cmd_vel_forwarded", s.cmd_vel_forwarded.to_string());
        kv("cmd_vel_scaled", s.cmd_vel_scaled.to_string());
        kv("cmd_vel_refused", s.cmd_vel_refused.to_string());
        kv("cmd_vel_stale", s.cmd_vel_stale.to_string());
        kv("cmd_timeout_ms", self.cfg.cmd_timeout_ms.to_string());
        kv("rate_hz", self.cfg.rate_hz.to_string());
        kv("max_speed_mps", self.limits.max_speed_mps.to_string());
        kv(
            "max_yaw_rate_radps",
            self.limits.max_yaw_rate_radps.to_string(),
        );
        kv("accel_mps2", self.limits.accel_mps2.to_string());
        kv("ang_accel_radps2", self.limits.ang_accel_radps2.to_string());
        kv("brake_decel_mps2", self.brake_decel_mps2.to_string());
        kv("com_offset_m", self.geometry.com_offset_m.to_string());
        kv(
            "path_limit_fraction",
            self.cfg.path_limit_fraction.to_string(),
        );
        kv("paths_received", s.paths.to_string());
        kv("paths_uploaded", s.paths_uploaded.to_string());
        kv("paths_refused", s.paths_refused.to_string());
        kv(
            "path_upload",
            match &self.upload {
                None => "none".into(),
                Some(u) => format!(
                    "{} of {} segments sent ({} waypoints), {}",
                    u.stream.segments_sent(),
                    u.stream.segment_count(),
                    u.stream.points(),
                    if u.armed { "running" } else { "loaded" }
                ),
            },
        );
        kv("path_queued", self.queued_path.is_some().to_string());
        kv("initial_poses", s.initial_poses.to_string());
        kv("initial_poses_refused", s.initial_poses_refused.to_string());
        kv("localiser_poses", self.poses.to_string().replace('\n', ";"));
        kv("localiser_poses_invalid", s.poses_invalid.to_string());
        kv("poses_wrong_frame", s.poses_wrong_frame.to_string());
        kv("odometry_sets", s.odometry_sets.to_string());
        kv(
            "service_requests_refused",
            s.service_requests_refused.to_string(),
        );
        kv("telemetry_frames_repeated", s.frames_repeated.to_string());
        kv("telemetry_frames", s.frames.to_string());
        kv("telemetry_frames_dropped", s.frames_dropped.to_string());
        kv("link_lost_events", s.link_lost_events.to_string());
        kv("clock_offset_us", off.to_string());
        kv("clock_sync_rtt_us", rtt.to_string());
        kv(
            "link_timeout_ms",
            self.link.timing().link_timeout.as_millis().to_string(),
        );
        kv("last_refusal", s.last_refusal.clone());
        let level = if s.frames_dropped > 0 || s.link_lost_events > 0 {
            DiagnosticStatus::WARN
        } else {
            DiagnosticStatus::OK
        };
        DiagnosticStatus {
            level,
            name: "wmr: ros2 bridge".into(),
            message: format!(
                "motion {}, {} cmd_vel forwarded, {} refused; {}",
                if self.enabled { "enabled" } else { "disabled" },
                s.cmd_vel_forwarded,
                s.cmd_vel_refused,
                if s.last_refusal.is_empty() {
                    "no refusal".to_string()
                } else {
                    format!("last refusal: {}", s.last_refusal)
                }
            ),
            hardware_id: "wmr".into(),
            values,
        }
    }

    /// A `cmd_vel`: a `Twist` (`stamp_ns` `None`), or a `TwistStamped`'s
    /// twist and stamp (Unix ns; 0 = not stamped). A stamped command older
    /// than the command timeout is refused: a command delayed on its way
    /// (a starved host, a DDS backlog) must not restart a robot that has
    /// already stopped because it was late.
    pub fn cmd_vel(&mut self, tw: &Twist, stamp_ns: Option<u64>) -> Outcome {
        self.stats.cmd_vel += 1;
        let r = match stamp_ns.filter(|s| *s != 0) {
            Some(s) if from_future(s, ros_mcap::unix_now_ns()) => {
                self.stats.cmd_vel_stale += 1;
                Ok(self.refuse(Refusal::Implausible(format!(
                    "stamped {:.3} s in the future (more than {} s ahead of this host's clock: \
                     synchronise the clocks)",
                    s.saturating_sub(ros_mcap::unix_now_ns()) as f64 * 1e-9,
                    MAX_FUTURE_STAMP_NS / 1_000_000_000
                ))))
            }
            Some(s) if stale(s, ros_mcap::unix_now_ns(), self.cfg.cmd_timeout_ms) => {
                self.stats.cmd_vel_stale += 1;
                Ok(self.refuse(Refusal::WrongState(format!(
                    "stale: stamped {:.0} ms ago, beyond the command timeout of {} ms",
                    ros_mcap::unix_now_ns().saturating_sub(s) as f64 * 1e-6,
                    self.cfg.cmd_timeout_ms
                ))))
            }
            _ => self.cmd_vel_inner(tw),
        };
        match &r {
            Ok(Ok(_)) => self.stats.cmd_vel_forwarded += 1,
            Ok(Err(_)) => self.stats.cmd_vel_refused += 1,
            Err(_) => {}
        }
        r
    }

    fn cmd_vel_inner(&mut self, tw: &Twist) -> Outcome {
        let (req, scaled) = match velocity_command(
            [tw.linear.x, tw.linear.y, tw.linear.z],
            [tw.angular.x, tw.angular.y, tw.angular.z],
            &self.limits,
            self.cfg.cmd_timeout_ms,
        ) {
            Ok(r) => r,
            Err(r) => return Ok(self.refuse(r)),
        };
        if !self.enabled {
            return Ok(self.refuse(Refusal::NotEnabled));
        }
        match self.state {
            RunStateMsg::Stopped => {
                return Ok(self.refuse(Refusal::WrongState(format!(
                    "a stop is latched ({}): call clear_stop",
                    self.last_stop
                        .map_or_else(|| "cause unknown".into(), |c| format!("{c:?}"))
                ))))
            }
            RunStateMsg::Stopping => {
                return Ok(self.refuse(Refusal::WrongState(
                    "the robot is braking to a stop: commands resume once it holds".into(),
                )))
            }
            RunStateMsg::Running if self.mode != ModeMsg::Velocity => {
                return Ok(self.refuse(Refusal::WrongState(format!(
                    "the robot is tracking a {:?} reference: cmd_vel applies once it ends (or disarm)",
                    self.mode
                ))))
            }
            _ => {}
        }
        if scaled {
            self.stats.cmd_vel_scaled += 1;
        }
        match self.link.command(&req) {
            Ok(_) => {}
            Err(e) => {
                return match nack_reason(&e) {
                    Some(c) => Ok(self.refuse(Refusal::Robot(c.reason().into()))),
                    None => Err(e.into()),
                }
            }
        }
        if self.state == RunStateMsg::Hold {
            self.mode = ModeMsg::Velocity;
            self.upload = None;
            match Motion::Arm.send(&mut self.link) {
                Ok(_) => self.state = RunStateMsg::Running,
                Err(e) => {
                    return match nack_reason(&e) {
                        Some(c) => Ok(self.refuse(Refusal::Robot(format!("arm: {}", c.reason())))),
                        None => Err(e.into()),
                    }
                }
            }
            return Ok(Ok("velocity mode selected and armed".into()));
        }
        Ok(Ok("forwarded".into()))
    }

    /// A `nav_msgs/Path`: profiled (or timed), uploaded at once when the
    /// robot holds (else queued until it does; a newer path replaces a
    /// queued one), armed when motion is enabled.
    pub fn path(&mut self, p: &Path) -> Outcome {
        self.stats.paths += 1;
        let lim = self.limits.scaled(self.cfg.path_limit_fraction);
        let pts = match profile::waypoints(p, &self.geometry, &lim) {
            Ok(w) => w,
            Err(r) => {
                self.stats.paths_refused += 1;
                return Ok(self.refuse(r));
            }
        };
        match self.state {
            RunStateMsg::Stopped => {
                self.stats.paths_refused += 1;
                Ok(self.refuse(Refusal::WrongState(
                    "a stop is latched: call clear_stop, then send the path again".into(),
                )))
            }
            RunStateMsg::Hold if self.upload.as_ref().is_none_or(|u| !u.armed) => {
                let r = self.start_upload(pts)?;
                if r.is_err() {
                    self.stats.paths_refused += 1;
                }
                Ok(r)
            }
            _ => {
                self.queued_path = Some(pts);
                Ok(Ok(
                    "queued: uploaded when the robot holds (the current run ends or a disarm)"
                        .into(),
                ))
            }
        }
    }

    fn start_upload(
        &mut self,
        pts: Vec<wmr_protocol::Waypoint>,
    ) -> Result<Result<String, Refusal>, Fatal> {
        let n = pts.len();
        let stream = match SegmentStream::begin(&mut self.link, &pts) {
            Ok(s) => s,
            Err(e) => {
                return match nack_reason(&e) {
                    Some(c) => Ok(self.refuse(Refusal::Robot(c.reason().into()))),
                    None => Err(e.into()),
                }
            }
        };
        self.mode = ModeMsg::Trajectory;
        self.upload = Some(UploadState {
            stream,
            armed: false,
        });
        self.stream_segments()?;
        if self.enabled {
            self.arm_upload()
        } else {
            Ok(Ok(format!(
                "{n} waypoints loaded; call the arm service to run them"
            )))
        }
    }

    fn arm_upload(&mut self) -> Result<Result<String, Refusal>, Fatal> {
        match Motion::Arm.send(&mut self.link) {
            Ok(_) => {
                self.state = RunStateMsg::Running;
                if let Some(u) = &mut self.upload {
                    u.armed = true;
                    if u.stream.done() {
                        self.stats.paths_uploaded += 1;
                    }
                }
                Ok(Ok("path uploaded and armed".into()))
            }
            Err(e) => match nack_reason(&e) {
                Some(c) => Ok(self.refuse(Refusal::Robot(format!("arm: {}", c.reason())))),
                None => Err(e.into()),
            },
        }
    }

    /// Sends the pending segments until the robot's buffer is full (the
    /// session's streamer, pumped from the poll loop).
    fn stream_segments(&mut self) -> Result<(), Fatal> {
        let Some(u) = &mut self.upload else {
            return Ok(());
        };
        if u.stream.done() {
            return Ok(());
        }
        match u.stream.pump_when_due(&mut self.link) {
            Ok(Some(Pump::Done)) if u.armed => self.stats.paths_uploaded += 1,
            Ok(_) => {}
            Err(StreamError::Link(e)) => return Err(e.into()),
            Err(e) => {
                self.upload = None;
                self.stats.paths_refused += 1;
                self.stats.last_refusal = format!("path segment refused: {e}");
            }
        }
        Ok(())
    }

    /// A localiser's pose (the base_link's pose with covariance), arrived
    /// now: sent as an external pose of G stamped in robot time.
    pub fn localiser_pose(&mut self, p: &PoseWithCovarianceStamped) -> Outcome {
        let arrival = self.host_us();
        if let Err(r) = odom_frame(&p.header.frame_id) {
            self.stats.poses_wrong_frame += 1;
            return Ok(self.refuse(r));
        }
        let cov = p.covariance();
        let clock = self.clock.pose_clock();
        let req = match external_pose_request(
            &self.geometry,
            &clock,
            &p.pose.pose,
            &cov,
            p.header.stamp.to_ns(),
            arrival,
            self.last_log_frame.map(|f| f.sample.pose[2]),
        ) {
            Ok(r) => r,
            Err(r) => {
                self.stats.poses_invalid += 1;
                return Ok(self.refuse(r));
            }
        };
        match self.link.command(&req) {
            Ok(_) => {
                self.poses.accepted();
                Ok(Ok("fused".into()))
            }
            Err(e) => match nack_reason(&e) {
                Some(c) => {
                    self.poses.refused(c);
                    Ok(self.refuse(Refusal::Robot(c.reason().into())))
                }
                None => Err(e.into()),
            },
        }
    }

    /// `/initialpose`: re-anchors the estimate at the pose of G of the
    /// given base_link pose (the robot holds; its covariance is not used:
    /// `SetPose` carries none).
    pub fn initial_pose(&mut self, p: &PoseWithCovarianceStamped) -> Outcome {
        if let Err(r) = odom_frame(&p.header.frame_id) {
            self.stats.poses_wrong_frame += 1;
            self.stats.initial_poses_refused += 1;
            return Ok(self.refuse(r));
        }
        let b = match planar(&p.pose.pose) {
            Ok(b) => b,
            Err(r) => {
                self.stats.initial_poses_refused += 1;
                return Ok(self.refuse(r));
            }
        };
        let g = g_of_axle(&self.geometry, b);
        match self.link.command(&Request::SetPose(pose_msg(g))) {
            Ok(_) => {
                self.stats.initial_poses += 1;
                Ok(Ok("pose set".into()))
            }
            Err(e) => match nack_reason(&e) {
                Some(c) => {
                    self.stats.initial_poses_refused += 1;
                    Ok(self.refuse(Refusal::Robot(c.reason().into())))
                }
                None => Err(e.into()),
            },
        }
    }

    /// The set-odometry service (`control_msgs/srv/SetOdometry`, as
    /// diff_drive_controller's `~/set_odometry`): re-anchors the estimate at
    /// the pose of G of the given `base_link` pose in `odom` (the robot
    /// holds, as for `/initialpose`). A planar robot: z, roll and pitch
    /// must be 0.
    pub fn set_odometry(&mut self, q: &SetOdometryRequest) -> Outcome {
        let v = [q.x, q.y, q.z, q.roll, q.pitch, q.yaw];
        if v.iter().any(|x| !x.is_finite()) {
            return Ok(self.refuse(Refusal::NotFinite("set_odometry pose")));
        }
        if q.z != 0.0 || q.roll != 0.0 || q.pitch != 0.0 {
            return Ok(self.refuse(Refusal::Implausible(format!(
                "set_odometry z {} m, roll {} rad, pitch {} rad: a planar robot takes 0 for each (x, y, yaw only)",
                q.z, q.roll, q.pitch
            ))));
        }
        if q.x.abs() > MAX_POSITION_M || q.y.abs() > MAX_POSITION_M {
            return Ok(self.refuse(Refusal::Implausible(format!(
                "set_odometry position ({}, {}) m beyond ±{MAX_POSITION_M} m",
                q.x, q.y
            ))));
        }
        let g = g_of_axle(&self.geometry, [q.x, q.y, q.yaw]);
        match self.link.command(&Request::SetPose(pose_msg(g))) {
            Ok(_) => {
                self.stats.odometry_sets += 1;
                Ok(Ok(format!(
                    "odometry set to ({}, {}, {} rad)",
                    q.x, q.y, q.yaw
                )))
            }
            Err(e) => match nack_reason(&e) {
                Some(c) => Ok(self.refuse(Refusal::Robot(c.reason().into()))),
                None => Err(e.into()),
            },
        }
    }

    fn simple(&mut self, req: Request, done: &str) -> Outcome {
        match self.link.command(&req) {
            Ok(_) => Ok(Ok(done.into())),
            Err(e) => match nack_reason(&e) {
                Some(c) => Ok(self.refuse(Refusal::Robot(c.reason().into()))),
                None => Err(e.into()),
            },
        }
    }

    /// A robot parameter, read from the robot (ROS `get_parameters`).
    pub fn get_param(&mut self, id: ParamId) -> Result<f32, Fatal> {
        param(&mut self.link, id)
    }

    /// Sets a robot parameter through the link (ROS `set_parameters`):
    /// refused with the robot's reason (range, "hold only"). A limit the
    /// bridge uses (speed, yaw rate, accelerations, braking) takes effect
    /// in the bridge too: cmd_vel scaling, path profiles, `/diagnostics`.
    pub fn set_param(&mut self, id: ParamId, value: f32) -> Outcome {
        let r = match self.link.command(&Request::SetParam { id, value }) {
            Ok(_) => Ok("set".to_string()),
            Err(e) => match nack_reason(&e) {
                // The link carries only the code: say the range (the
                // parameter table's, as `wmr params set` does).
                Some(c @ ErrorCode::InvalidValue) => self.refuse(Refusal::Robot(format!(
                    "{}; {}",
                    c.reason(),
                    wmr::params::robot_range(id.param())
                ))),
                Some(c) => self.refuse(Refusal::Robot(c.reason().into())),
                None => return Err(e.into()),
            },
        };
        if r.is_ok() {
            let v = value as f64;
            let mut new = self.limits;
            match id {
                ParamId::MaxSpeedMps => new.max_speed_mps = v,
                ParamId::MaxYawRateRadps => new.max_yaw_rate_radps = v,
                ParamId::AccelMps2 => new.accel_mps2 = v,
                ParamId::AngAccelRadps2 => new.ang_accel_radps2 = v,
                ParamId::BrakeDecelMps2 => self.brake_decel_mps2 = v,
                _ => {}
            }
            // The robot took it, so it is within the robot's own (tighter)
            // ranges: Limits::new failing is a robot that is not a robot,
            // as at connection.
            self.limits = Limits::new(
                new.max_speed_mps,
                new.max_yaw_rate_radps,
                new.accel_mps2,
                new.ang_accel_radps2,
            )
            .map_err(Fatal::Robot)?;
        }
        Ok(r)
    }

    /// The arm service: enables motion; a loaded path starts at once.
    pub fn arm(&mut self) -> Outcome {
        if self.state == RunStateMsg::Stopped {
            return Ok(self.refuse(Refusal::WrongState(
                "a stop is latched: call clear_stop first".into(),
            )));
        }
        self.enabled = true;
        if self.state == RunStateMsg::Hold && self.upload.as_ref().is_some_and(|u| !u.armed) {
            return self.arm_upload();
        }
        Ok(Ok(
            "motion enabled: the robot arms on the next cmd_vel or path".into(),
        ))
    }

    /// The disarm service: disables motion, drops a queued path, disarms.
    pub fn disarm(&mut self) -> Outcome {
        self.enabled = false;
        self.queued_path = None;
        if matches!(self.state, RunStateMsg::Running | RunStateMsg::Stopping) {
            let r = self.simple(Motion::Disarm.request(), "disarmed; motion disabled")?;
            if r.is_ok() {
                self.state = RunStateMsg::Hold;
                self.upload = None;
            }
            return Ok(r);
        }
        self.upload = None;
        Ok(Ok("motion disabled (the robot was not running)".into()))
    }

    /// The emergency-stop service: latches a stop at once (any state),
    /// disables motion.
    pub fn emergency_stop(&mut self) -> Outcome {
        self.enabled = false;
        self.queued_path = None;
        self.upload = None;
        let r = self.simple(
            Motion::EmergencyStop.request(),
            "emergency stop latched; motion disabled (clear_stop, then arm)",
        )?;
        if r.is_ok() {
            self.state = RunStateMsg::Stopped;
            self.last_stop = Some(StopCode::Commanded);
        }
        Ok(r)
    }

    /// The clear-stop service: clears a latched stop (back to hold).
    pub fn clear_stop(&mut self) -> Outcome {
        let r = self.simple(Motion::ClearStop.request(), "stop cleared: hold")?;
        if r.is_ok() {
            self.state = RunStateMsg::Hold;
        }
        Ok(r)
    }

    /// Stops telemetry and disarms a robot the bridge drives (when the
    /// bridge ends on purpose).
    pub fn shutdown(&mut self) {
        if matches!(self.state, RunStateMsg::Running) {
            let _ = Motion::Disarm.send(&mut self.link);
        }
        let _ = self.link.command(&Request::SetTelemetry {
            selection: TELEMETRY_ALL,
            rate_hz: 0,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stale_commands_are_those_older_than_the_timeout() {
        let now = 1_764_632_000_000_000_000u64;
        assert!(!stale(now - 299_000_000, now, 300));
        assert!(stale(now - 301_000_000, now, 300));
        // From the future (another host's clock ahead): not stale.
        assert!(!stale(now + 50_000_000, now, 300));
        // A little ahead is another host's clock; 1,000 s ahead is not.
        assert!(!from_future(now + 50_000_000, now));
        assert!(from_future(now + 1_000 * 1_000_000_000, now));
    }

    #[test]
    fn stamps_never_repeat_nor_go_back() {
        let mut g = StampGate::default();
        // three frames of one stamp at start (as issue 35 saw on /odom),
        // then later ones, then one stepped back
        let stamps = [10, 10, 10, 20, 30, 25, 30, 40];
        let admitted: Vec<u64> = stamps.into_iter().filter(|&s| g.admit(s)).collect();
        assert_eq!(admitted, vec![10, 20, 30, 40]);
    }

    #[test]
    fn a_map_frame_pose_is_not_taken_as_odom() {
        assert!(odom_frame("odom").is_ok());
        assert!(odom_frame("/odom").is_ok());
        for f in ["map", "", "base_link", "odom_combined"] {
            let e = odom_frame(f).unwrap_err().to_string();
            assert!(
                e.contains(&format!("{f:?}")) && e.contains("REP-105"),
                "{e}"
            );
        }
    }

    #[test]
    fn settings_are_checked() {
        assert!(Config::new(50, 300, Some(0.05), 0.8, false).is_ok());
        assert!(Config::new(0, 300, Some(0.05), 0.8, false).is_err());
        assert!(Config::new(50, 0, Some(0.05), 0.8, false).is_err());
        assert!(Config::new(50, 6000, Some(0.05), 0.8, false).is_err());
        assert!(Config::new(50, 300, Some(0.05), 0.0, false).is_err());
        assert!(Config::new(50, 300, Some(0.05), f64::NAN, false).is_err());
    }
}
