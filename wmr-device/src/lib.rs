//! # wmr-device
//!
//! The robot side of the host link, hardware-agnostic, `no_std`, no
//! allocation: [`Device`] sits between [`wmr_protocol`] frames and the
//! controller-core [`ControlLoop`]. The firmware and the simulated robot
//! (`hil-sim device`) run the same code.
//!
//! Per tick ([`Device::tick`]), with bounded work:
//!
//! 1. decode at most [`RX_BYTES_PER_TICK`] received bytes and handle the
//!    requests in them, each validated against the state (no arming
//!    without a loaded mode or with a latched stop, configuration only in
//!    hold); every request is answered with an ack, a nack with a typed
//!    error, or its reply;
//! 2. the watchdogs: link silence while running under host control, the
//!    velocity command's timeout, the end of an uploaded trajectory: each
//!    starts a controlled stop (the reference decelerates along its path,
//!    then the robot disarms);
//! 3. the reference of this tick (built-in, waypoints, velocity or braking)
//!    and one [`ControlLoop::tick_with_reference`];
//! 4. state-change events and at most one telemetry frame.
//!
//! The link never blocks the loop: received bytes go into a bounded buffer
//! ([`Device::push_rx`], overflow counted), replies into a bounded send
//! buffer drained by [`Device::pop_tx`] (a frame that does not fit is
//! dropped and counted). Boot state is hold: motors off until a mode is
//! loaded and armed.
#![no_std]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod reference;

use controller_core::estimator::{EstimatorConfig, PoseMeasurement, HISTORY_LEN};
use controller_core::runtime::{
    ControlLoop, Gyro, MotorDriver, PoseSource, RunState, RuntimeConfig, RuntimeConfigError,
    StopReason, TickReport, TickTiming, WheelEncoders,
};
use controller_core::trajectory::{RefSample, Trajectory};
use heapless::Deque;
use reference::{
    pose_from_msg, pose_to_msg, PlacedReference, SegmentError, VirtualVehicle, WaypointBuffer,
};
use wmr_protocol::{
    encode, BoardReport, BuiltinReference, Counters, Decoded, ErrorCode, EstimatorTelemetry, Event,
    FrameDecoder, ModeMsg, ParamId, Reply, Request, RobotInfo, RunStateMsg, StatusMsg, StopCode,
    Telemetry, TelemetrySelection, TrackingTelemetry, MAX_FRAME, PROTOCOL_VERSION, TELEMETRY_ALL,
    TELEMETRY_COUNTERS, TELEMETRY_ESTIMATORS, TELEMETRY_TRACKING,
};

/// Receive buffer \[bytes\].
pub const RX_CAPACITY: usize = 256;
/// Send buffer \[bytes\].
pub const TX_CAPACITY: usize = 1024;
/// Received bytes decoded per tick at most (bounded work per tick; 128 kB/s
/// at 1 kHz, above a 921 600 baud UART).
pub const RX_BYTES_PER_TICK: usize = 128;
/// External poses older than this are refused \[µs\].
pub const MAX_POSE_AGE_US: i32 = 100_000;
/// External poses stamped further ahead than this are refused \[µs\].
pub const MAX_POSE_LEAD_US: i32 = 10_000;
/// Longest velocity-command timeout \[ms\].
pub const MAX_VELOCITY_TIMEOUT_MS: u16 = 5000;

/// Link settings of the device; every field is a [`ParamId`] the host can
/// read, and write where the protocol allows.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkConfig {
    /// Controlled stop after this long without a valid frame while running
    /// under host control \[ms\] (50..=10000).
    pub link_timeout_ms: u32,
    /// Acceleration limit of velocity commands \[m/s²\].
    pub accel_mps2: f32,
    /// Angular acceleration limit of velocity commands \[rad/s²\].
    pub ang_accel_radps2: f32,
    /// Deceleration of a controlled stop \[m/s²\].
    pub brake_decel_mps2: f32,
    /// Largest |v| of a velocity command \[m/s\].
    pub max_speed_mps: f32,
    /// Largest |ω| of a velocity command \[rad/s\].
    pub max_yaw_rate_radps: f32,
    /// Telemetry rate \[Hz\] (0 = off).
    pub telemetry_rate_hz: u16,
    /// Telemetry groups.
    pub telemetry_selection: TelemetrySelection,
}

impl LinkConfig {
    /// Defaults: 500 ms link timeout, 1 m/s² and 3 rad/s² for velocity
    /// commands, 1 m/s² braking, 1 m/s and 3 rad/s command limits,
    /// telemetry off.
    pub const DEFAULT: Self = Self {
        link_timeout_ms: 500,
        accel_mps2: 1.0,
        ang_accel_radps2: 3.0,
        brake_decel_mps2: 1.0,
        max_speed_mps: 1.0,
        max_yaw_rate_radps: 3.0,
        telemetry_rate_hz: 0,
        telemetry_selection: TELEMETRY_ALL,
    };

    /// Checks every field.
    pub fn validate(self) -> Result<Self, DeviceConfigError> {
        // (value, upper bound): 0 < value <= bound (NaN fails), one loop.
        let in_range = [
            (self.accel_mps2, 20.0),
            (self.ang_accel_radps2, 50.0),
            (self.brake_decel_mps2, 20.0),
            (self.max_speed_mps, 10.0),
            (self.max_yaw_rate_radps, 30.0),
        ]
        .iter()
        .all(|&(x, hi)| x > 0.0 && x <= hi);
        let ok = (50..=10_000).contains(&self.link_timeout_ms)
            && in_range
            && self.telemetry_rate_hz <= 1000;
        if ok {
            Ok(self)
        } else {
            Err(DeviceConfigError::InvalidLink)
        }
    }
}

/// Everything a [`Device`] is built from besides the runtime.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceConfig {
    /// Chip or board name sent in the handshake (≤ 16 bytes).
    pub chip: &'static str,
    /// `CAP_*` bits sent in the handshake.
    pub capabilities: u16,
    /// Link settings.
    pub link: LinkConfig,
    /// What the arm button drives when the host has loaded nothing
    /// (`None`: the button arms only a loaded mode).
    pub button_reference: Option<BuiltinReference>,
}

/// A device configuration rejected at construction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum DeviceConfigError {
    /// The runtime configuration.
    Runtime(RuntimeConfigError),
    /// A link setting is out of range.
    InvalidLink,
    /// The chip name is longer than 16 bytes.
    ChipName,
    /// The button reference is invalid.
    ButtonReference,
}

impl core::fmt::Display for DeviceConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Runtime(e) => write!(f, "runtime: {e}"),
            Self::InvalidLink => f.write_str("link setting out of range"),
            Self::ChipName => f.write_str("chip name longer than 16 bytes"),
            Self::ButtonReference => f.write_str("invalid button reference"),
        }
    }
}

/// What the robot drives when armed (compared with `matches!`: a derived
/// `PartialEq` would compare the references' floats, and cost flash).
#[derive(Clone, Copy, Debug)]
enum Mode {
    None,
    Builtin(PlacedReference),
    Trajectory,
    Velocity,
}

/// The velocity command.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct VelocityCmd {
    target: [f32; 2],
    /// Robot time the command expires \[µs\]; `None` when expired.
    expires_us: Option<u32>,
}

/// A controlled stop in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Braking {
    vehicle: VirtualVehicle,
    rates: [f32; 2],
    ticks_left: u32,
    cause: StopCode,
}

/// Link counters kept by the device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct LinkCounters {
    rx_frames: u32,
    rx_errors: u32,
    rx_overflow: u32,
    tx_dropped: u32,
    nacks: u32,
}

/// One request's answer.
type Answer = Result<Option<Reply>, ErrorCode>;

/// The pose source of one tick: the host's measurement if one arrived
/// (first), then the board's.
struct HostOrBoard<'a, P: PoseSource> {
    host: Option<PoseMeasurement>,
    board: &'a mut P,
}

impl<P: PoseSource> PoseSource for HostOrBoard<'_, P> {
    fn measurement(&mut self) -> Option<PoseMeasurement> {
        self.host.take().or_else(|| self.board.measurement())
    }
}

/// A reference sample computed by the device for this tick.
struct Fixed(RefSample);

impl Trajectory for Fixed {
    fn sample(&self, _t_s: f32) -> RefSample {
        self.0
    }
}

/// The robot side of the host link around a [`ControlLoop`].
pub struct Device<const H: usize = HISTORY_LEN> {
    cfg: DeviceConfig,
    control: ControlLoop<H>,
    period_s: f32,
    decoder: FrameDecoder<MAX_FRAME>,
    rx: Deque<u8, RX_CAPACITY>,
    tx: Deque<u8, TX_CAPACITY>,
    link: LinkCounters,
    mode: Mode,
    waypoints: WaypointBuffer,
    velocity: VelocityCmd,
    vehicle: VirtualVehicle,
    braking: Option<Braking>,
    host_armed: bool,
    last_rx_us: u32,
    now_us: u32,
    pending_pose: Option<PoseMeasurement>,
    last_ref: RefSample,
    last_stop: Option<StopCode>,
    reported_state: RunStateMsg,
    pending_cause: Option<StopCode>,
    telemetry_seq: u32,
    telemetry_countdown: u32,
    board: BoardReport,
}

fn stop_code(r: StopReason) -> StopCode {
    match r {
        StopReason::ControllerInput(_) => StopCode::ControllerInput,
        StopReason::EncoderJump { .. } => StopCode::EncoderJump,
        StopReason::EncoderStalled { .. } => StopCode::EncoderStalled,
        StopReason::LoopOverrun { .. } => StopCode::LoopOverrun,
        StopReason::Commanded => StopCode::Commanded,
        _ => StopCode::Other,
    }
}

fn finite(xs: &[f32]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

impl<const H: usize> Device<H> {
    /// Validates both configurations and builds a device in hold, with the
    /// example estimator tuning ([`EstimatorConfig::example`]).
    pub fn new(cfg: DeviceConfig, runtime: RuntimeConfig) -> Result<Self, DeviceConfigError> {
        let estimator =
            EstimatorConfig::example(runtime.controller.robot.com_offset_m, runtime.initial_pose);
        Self::with_estimator(cfg, runtime, estimator)
    }

    /// [`Self::new`] with a given estimator tuning (`H` ticks of history:
    /// the oldest external pose it can use).
    pub fn with_estimator(
        cfg: DeviceConfig,
        runtime: RuntimeConfig,
        estimator: EstimatorConfig,
    ) -> Result<Self, DeviceConfigError> {
        cfg.link.validate()?;
        if cfg.chip.len() > 16 {
            return Err(DeviceConfigError::ChipName);
        }
        if let Some(b) = &cfg.button_reference {
            PlacedReference::new(b).ok_or(DeviceConfigError::ButtonReference)?;
        }
        let control = ControlLoop::<H>::with_estimator(runtime, estimator)
            .map_err(DeviceConfigError::Runtime)?;
        let period_s = runtime.controller.period_s;
        Ok(Self {
            cfg,
            control,
            period_s,
            decoder: FrameDecoder::new(),
            rx: Deque::new(),
            tx: Deque::new(),
            link: LinkCounters::default(),
            mode: Mode::None,
            waypoints: WaypointBuffer::default(),
            velocity: VelocityCmd::default(),
            vehicle: VirtualVehicle::default(),
            braking: None,
            host_armed: false,
            last_rx_us: 0,
            now_us: 0,
            pending_pose: None,
            last_ref: RefSample::default(),
            last_stop: None,
            reported_state: RunStateMsg::Hold,
            pending_cause: None,
            telemetry_seq: 0,
            telemetry_countdown: 0,
            board: BoardReport::default(),
        })
    }

    /// What the board reports in the status (its reset cause, set once
    /// at boot, and its link port's losses, kept current by the board).
    pub fn board_report_mut(&mut self) -> &mut BoardReport {
        &mut self.board
    }

    /// The runtime.
    pub fn control(&self) -> &ControlLoop<H> {
        &self.control
    }

    /// The run state as the host sees it.
    pub fn state(&self) -> RunStateMsg {
        match self.control.state() {
            RunState::Disarmed => RunStateMsg::Hold,
            RunState::Running if self.braking.is_some() => RunStateMsg::Stopping,
            RunState::Running => RunStateMsg::Running,
            RunState::Stopped(_) => RunStateMsg::Stopped,
        }
    }

    /// The loaded mode.
    pub fn mode(&self) -> ModeMsg {
        match self.mode {
            Mode::None => ModeMsg::None,
            Mode::Builtin(_) => ModeMsg::Builtin,
            Mode::Trajectory => ModeMsg::Trajectory,
            Mode::Velocity => ModeMsg::Velocity,
        }
    }

    /// Every counter.
    pub fn counters(&self) -> Counters {
        let s = self.control.status();
        Counters {
            ticks: s.ticks,
            run_ticks: s.run_ticks,
            overruns: s.overruns,
            max_loop_time_us: s.max_loop_time_us,
            encoder_jumps: s.encoder_jumps,
            input_faults: s.input_faults,
            torque_saturated: s.torque_saturated,
            duty_saturated: s.duty_saturated,
            external_poses: s.external_poses,
            stops: s.stops,
            rx_frames: self.link.rx_frames,
            rx_errors: self.link.rx_errors,
            rx_overflow: self.link.rx_overflow,
            tx_dropped: self.link.tx_dropped,
            nacks: self.link.nacks,
        }
    }

    /// The link settings in force.
    pub fn link_config(&self) -> &LinkConfig {
        &self.cfg.link
    }

    /// Queues received bytes; returns how many fit (the rest are dropped
    /// and counted in `rx_overflow`). Never blocks.
    pub fn push_rx(&mut self, bytes: &[u8]) -> usize {
        let mut n = 0;
        for &b in bytes {
            if self.rx.push_back(b).is_err() {
                break;
            }
            n += 1;
        }
        let dropped = (bytes.len() - n) as u32;
        self.link.rx_overflow = self.link.rx_overflow.saturating_add(dropped);
        n
    }

    /// Free space of the receive buffer \[bytes\].
    pub fn rx_free(&self) -> usize {
        RX_CAPACITY - self.rx.len()
    }

    /// Moves queued outgoing bytes into `out`; returns how many.
    pub fn pop_tx(&mut self, out: &mut [u8]) -> usize {
        let mut n = 0;
        while n < out.len() {
            match self.tx.pop_front() {
                Some(b) => {
                    out[n] = b;
                    n += 1;
                }
                None => break,
            }
        }
        n
    }

    /// Outgoing bytes queued.
    pub fn tx_len(&self) -> usize {
        self.tx.len()
    }

    /// One control period at robot time `now_us` (a wrapping µs clock):
    /// requests, watchdogs, the reference, the control loop, events and
    /// telemetry. Never panics, never blocks.
    pub fn tick(
        &mut self,
        now_us: u32,
        encoders: &mut impl WheelEncoders,
        motors: &mut impl MotorDriver,
        gyro: &mut impl Gyro,
        pose_source: &mut impl PoseSource,
        timing: TickTiming,
    ) -> TickReport {
        self.now_us = now_us;
        self.process_rx(motors);
        self.watchdogs();
        let reference = self.reference_for_tick(motors);
        let mut pose = HostOrBoard {
            host: self.pending_pose.take(),
            board: pose_source,
        };
        let rep = self.control.tick_with_reference(
            encoders,
            motors,
            gyro,
            &mut pose,
            timing,
            &Fixed(reference),
        );
        self.last_ref = rep.reference;
        if let Some(r) = rep.stopped {
            self.on_stop(stop_code(r));
        }
        self.report_state();
        self.telemetry(&rep);
        rep
    }

    /// The arm button (a debounced press, see
    /// [`ArmingButton`](controller_core::runtime::ArmingButton)): disarms
    /// while running or stopping, clears a latched stop, else arms the
    /// loaded mode, or the configured button reference when none is loaded.
    /// Works without a host (the link watchdog stays off).
    pub fn button_pressed(&mut self, motors: &mut impl MotorDriver) {
        match self.control.state() {
            RunState::Running => self.disarm(motors, StopCode::Disarmed),
            RunState::Stopped(_) => self.control.reset(),
            RunState::Disarmed => {
                if matches!(self.mode, Mode::None) {
                    if let Some(p) = self
                        .cfg
                        .button_reference
                        .as_ref()
                        .and_then(PlacedReference::new)
                    {
                        self.mode = Mode::Builtin(p);
                    }
                }
                let _ = self.arm(false);
            }
        }
        self.report_state();
    }

    // Out of line: one copy (smaller firmware; the call costs nothing here).
    #[inline(never)]
    fn process_rx(&mut self, motors: &mut impl MotorDriver) {
        let mut chunk = [0u8; RX_BYTES_PER_TICK];
        let mut n = 0;
        while n < chunk.len() {
            match self.rx.pop_front() {
                Some(b) => {
                    chunk[n] = b;
                    n += 1;
                }
                None => break,
            }
        }
        let mut rest = &chunk[..n];
        let mut frame_error_sent = false;
        while !rest.is_empty() {
            let (decoded, r) = self.decoder.feed::<Request>(rest);
            rest = r;
            match decoded {
                None => {}
                Some(Decoded::Frame { seq, msg }) => {
                    self.link.rx_frames = self.link.rx_frames.saturating_add(1);
                    self.last_rx_us = self.now_us;
                    let answer = self.handle(seq, msg, motors);
                    self.answer(seq, answer);
                }
                Some(Decoded::OtherVersion { seq, msg, .. }) => {
                    self.link.rx_errors = self.link.rx_errors.saturating_add(1);
                    let answer = match msg {
                        Some(Request::Hello { .. }) => Ok(Some(self.hello(seq))),
                        _ => Err(ErrorCode::VersionMismatch),
                    };
                    self.answer(seq, answer);
                }
                Some(Decoded::Error { seq, error }) => {
                    self.link.rx_errors = self.link.rx_errors.saturating_add(1);
                    match seq {
                        Some(seq) => self.answer(seq, Err(error)),
                        // At most one per tick: a flood of garbage cannot
                        // crowd telemetry and answers out of the link.
                        None if !frame_error_sent => {
                            frame_error_sent = self.send(&Reply::FrameError { error });
                        }
                        None => {}
                    }
                }
            }
        }
    }

    fn answer(&mut self, seq: u16, answer: Answer) {
        let reply = match answer {
            Ok(Some(r)) => r,
            Ok(None) => Reply::Ack { seq },
            Err(error) => {
                self.link.nacks = self.link.nacks.saturating_add(1);
                Reply::Nack { seq, error }
            }
        };
        self.send(&reply);
    }

    /// Queues a frame; drops (and counts) it when the send buffer is full.
    fn send(&mut self, reply: &Reply) -> bool {
        let mut buf = [0u8; MAX_FRAME];
        let Ok(frame) = encode(reply, 0, &mut buf) else {
            self.link.tx_dropped = self.link.tx_dropped.saturating_add(1);
            return false;
        };
        if TX_CAPACITY - self.tx.len() < frame.len() {
            self.link.tx_dropped = self.link.tx_dropped.saturating_add(1);
            return false;
        }
        for &b in frame.iter() {
            let _ = self.tx.push_back(b);
        }
        true
    }

    fn hello(&self, seq: u16) -> Reply {
        let c = self.control.config().controller;
        let mut chip = heapless::String::new();
        let _ = chip.push_str(self.cfg.chip);
        Reply::Hello {
            seq,
            version: PROTOCOL_VERSION,
            capabilities: self.cfg.capabilities,
            chip,
            robot: RobotInfo {
                wheel_radius_m: c.robot.wheel_radius_m,
                half_track_m: c.robot.half_track_m,
                mass_kg: c.robot.mass_kg,
                control_period_s: c.period_s,
                torque_limit_nm: c.torque_limit_nm,
            },
        }
    }

    fn status(&self) -> StatusMsg {
        StatusMsg {
            state: self.state(),
            mode: self.mode(),
            last_stop: self.last_stop,
            t_robot_us: self.now_us,
            buffered_points: self.waypoints.len() as u16,
            counters: self.counters(),
            board: self.board,
        }
    }

    fn in_hold(&self) -> Result<(), ErrorCode> {
        match self.control.state() {
            RunState::Running => Err(ErrorCode::Busy),
            _ => Ok(()),
        }
    }

    /// The reference time of this tick: the runtime's (governed when its
    /// pacing is on, so an uploaded reference slows down like a built-in one).
    fn ref_time_s(&self) -> f32 {
        self.control.reference_time_s()
    }

    // Out of line: one copy (smaller firmware; the call costs nothing here).
    #[inline(never)]
    fn handle(&mut self, seq: u16, req: Request, motors: &mut impl MotorDriver) -> Answer {
        match req {
            Request::Hello { .. } => Ok(Some(self.hello(seq))),
            Request::GetStatus => Ok(Some(Reply::Status {
                seq,
                status: self.status(),
            })),
            Request::Arm => self.arm(true).map(|_| None),
            Request::Disarm => {
                self.disarm(motors, StopCode::Disarmed);
                Ok(None)
            }
            Request::EmergencyStop => {
                self.control.stop(motors);
                self.braking = None;
                self.velocity = VelocityCmd::default();
                self.on_stop(StopCode::Commanded);
                Ok(None)
            }
            Request::ClearStop => match self.control.state() {
                RunState::Stopped(_) => {
                    self.control.reset();
                    Ok(None)
                }
                _ => Err(ErrorCode::WrongMode),
            },
            Request::SetPose(p) => {
                self.in_hold()?;
                if !p.is_finite() {
                    return Err(ErrorCode::InvalidValue);
                }
                self.control
                    .set_pose(pose_from_msg(p))
                    .map_err(|_| ErrorCode::InvalidValue)?;
                Ok(None)
            }
            Request::ExternalPose {
                t_robot_us,
                pose,
                std_dev,
            } => {
                if !pose.is_finite() || !finite(&std_dev) || std_dev.iter().any(|s| *s < 0.0) {
                    return Err(ErrorCode::InvalidValue);
                }
                let age = self.now_us.wrapping_sub(t_robot_us) as i32;
                if !(-MAX_POSE_LEAD_US..=MAX_POSE_AGE_US).contains(&age) {
                    return Err(ErrorCode::Stale);
                }
                // Validated again, with a reason, by the estimator; a zero
                // heading std dev means "no heading" (position only).
                self.pending_pose = Some(PoseMeasurement {
                    stamp_us: t_robot_us,
                    pose: pose_from_msg(pose),
                    position_std_m: std_dev[0].max(std_dev[1]),
                    heading_std_rad: (std_dev[2] > 0.0).then_some(std_dev[2]),
                });
                Ok(None)
            }
            Request::ClockSync { host_time_us } => Ok(Some(Reply::ClockSync {
                seq,
                host_time_us,
                robot_time_us: self.now_us,
            })),
            Request::SetReference(r) => {
                self.in_hold()?;
                let placed = PlacedReference::new(&r).ok_or(ErrorCode::InvalidValue)?;
                self.mode = Mode::Builtin(placed);
                self.waypoints.clear();
                Ok(None)
            }
            Request::TrajectoryBegin { total_points } => {
                self.in_hold()?;
                if total_points < 2 {
                    return Err(ErrorCode::InvalidValue);
                }
                self.waypoints.begin(total_points);
                self.mode = Mode::None;
                Ok(None)
            }
            Request::TrajectorySegment {
                first_index,
                points,
            } => {
                let running = self.control.state() == RunState::Running;
                if running && !matches!(self.mode, Mode::Trajectory) {
                    return Err(ErrorCode::WrongMode);
                }
                let now = running.then(|| self.ref_time_s());
                self.waypoints
                    .push(first_index, &points, now)
                    .map_err(|e| match e {
                        SegmentError::OutOfOrder => ErrorCode::OutOfOrder,
                        SegmentError::Full => ErrorCode::BufferFull,
                        SegmentError::Invalid => ErrorCode::InvalidValue,
                    })?;
                if !running && self.waypoints.ready() {
                    self.mode = Mode::Trajectory;
                }
                Ok(Some(Reply::TrajectoryAck {
                    seq,
                    next_index: self.waypoints.next_index(),
                    free: self.waypoints.free() as u16,
                }))
            }
            Request::Velocity {
                v_mps,
                omega_radps,
                timeout_ms,
            } => {
                let l = &self.cfg.link;
                let ok = v_mps.is_finite()
                    && omega_radps.is_finite()
                    && v_mps.abs() <= l.max_speed_mps
                    && omega_radps.abs() <= l.max_yaw_rate_radps
                    && (1..=MAX_VELOCITY_TIMEOUT_MS).contains(&timeout_ms);
                if !ok {
                    return Err(ErrorCode::InvalidValue);
                }
                match (self.control.state(), self.mode) {
                    (RunState::Running, Mode::Velocity) if self.braking.is_none() => {}
                    (RunState::Running, _) => return Err(ErrorCode::WrongMode),
                    _ => {
                        self.mode = Mode::Velocity;
                        self.waypoints.clear();
                    }
                }
                self.velocity = VelocityCmd {
                    target: [v_mps, omega_radps],
                    expires_us: Some(self.now_us.wrapping_add(timeout_ms as u32 * 1000)),
                };
                Ok(None)
            }
            Request::GetParam(id) => Ok(Some(Reply::Param {
                seq,
                id,
                value: self.param(id),
            })),
            Request::SetParam { id, value } => self.set_param(id, value).map(|_| None),
            Request::SetTelemetry { selection, rate_hz } => {
                if rate_hz > 1000 || selection & !TELEMETRY_ALL != 0 {
                    return Err(ErrorCode::InvalidValue);
                }
                self.cfg.link.telemetry_rate_hz = rate_hz;
                self.cfg.link.telemetry_selection = selection;
                self.telemetry_countdown = 0;
                Ok(None)
            }
        }
    }

    /// Arms the loaded mode (`host`: under host control, with the link
    /// watchdog).
    fn arm(&mut self, host: bool) -> Result<(), ErrorCode> {
        match self.control.state() {
            RunState::Running if self.braking.is_some() => return Err(ErrorCode::Busy),
            RunState::Running => return Ok(()),
            RunState::Stopped(_) => return Err(ErrorCode::Latched),
            RunState::Disarmed => {}
        }
        let ready = match self.mode {
            Mode::None => false,
            Mode::Builtin(_) | Mode::Velocity => true,
            Mode::Trajectory => self.waypoints.ready(),
        };
        if !ready {
            return Err(ErrorCode::NoReference);
        }
        self.control.arm().map_err(|_| ErrorCode::Latched)?;
        self.vehicle = VirtualVehicle::at_rest(self.control.estimator().estimate().pose);
        self.host_armed = host;
        self.last_rx_us = self.now_us;
        self.braking = None;
        self.pending_cause = None;
        Ok(())
    }

    fn disarm(&mut self, motors: &mut impl MotorDriver, cause: StopCode) {
        let was_running = self.control.state() == RunState::Running;
        self.control.disarm(motors);
        self.braking = None;
        self.velocity = VelocityCmd::default();
        if matches!(self.mode, Mode::Trajectory) && !self.waypoints.ready() {
            self.mode = Mode::None;
        }
        if was_running {
            self.on_stop(cause);
        }
    }

    fn on_stop(&mut self, cause: StopCode) {
        self.last_stop = Some(cause);
        self.pending_cause = Some(cause);
        self.braking = None;
        self.velocity = VelocityCmd::default();
    }

    /// Starts a controlled stop from the last reference sample: v and ω
    /// fall linearly to zero together (the path's curvature is kept) at
    /// the braking deceleration.
    fn start_braking(&mut self, cause: StopCode) {
        if self.braking.is_some() || self.control.state() != RunState::Running {
            return;
        }
        let r = self.last_ref;
        let l = &self.cfg.link;
        let t_v = r.v_mps.abs() / l.brake_decel_mps2;
        let t_w = r.omega_radps.abs() / l.ang_accel_radps2;
        let ticks = ((t_v.max(t_w) / self.period_s) as u32).saturating_add(1);
        let t = ticks as f32 * self.period_s;
        self.braking = Some(Braking {
            vehicle: VirtualVehicle::from_sample(RefSample {
                v_dot_mps2: -r.v_mps / t,
                omega_dot_radps2: -r.omega_radps / t,
                ..r
            }),
            rates: [-r.v_mps / t, -r.omega_radps / t],
            ticks_left: ticks,
            cause,
        });
    }

    fn watchdogs(&mut self) {
        if self.control.state() != RunState::Running || self.braking.is_some() {
            return;
        }
        let silent_us = self.now_us.wrapping_sub(self.last_rx_us);
        if self.host_armed && silent_us > self.cfg.link.link_timeout_ms.saturating_mul(1000) {
            self.send(&Reply::Event(Event::LinkLost));
            self.start_braking(StopCode::LinkSilence);
        }
    }

    /// This tick's reference; finishes a controlled stop (disarm) when the
    /// braking reference stands still.
    fn reference_for_tick(&mut self, motors: &mut impl MotorDriver) -> RefSample {
        let dt = self.period_s;
        if let Some(b) = &mut self.braking {
            if b.ticks_left == 0 {
                let cause = b.cause;
                let rest = b.vehicle.sample;
                self.disarm(motors, cause);
                return RefSample {
                    v_mps: 0.0,
                    omega_radps: 0.0,
                    v_dot_mps2: 0.0,
                    omega_dot_radps2: 0.0,
                    ..rest
                };
            }
            let out = b.vehicle.sample;
            b.vehicle.advance(dt, b.rates[0], b.rates[1]);
            b.ticks_left -= 1;
            return out;
        }
        if self.control.state() != RunState::Running {
            return self.last_ref;
        }
        let t = self.ref_time_s();
        match self.mode {
            Mode::None => self.last_ref,
            Mode::Builtin(p) => p.sample(t),
            Mode::Trajectory => match self.waypoints.sample(t) {
                Some(r) => r,
                None => {
                    self.start_braking(StopCode::TrajectoryEnd);
                    self.reference_for_tick(motors)
                }
            },
            Mode::Velocity => {
                let expired = match self.velocity.expires_us {
                    Some(e) => (self.now_us.wrapping_sub(e) as i32) >= 0,
                    None => true,
                };
                // No live command (expired, or armed without one): stop.
                if expired {
                    self.velocity = VelocityCmd::default();
                    self.start_braking(StopCode::VelocityTimeout);
                    return self.reference_for_tick(motors);
                }
                let l = &self.cfg.link;
                let s = self.vehicle.sample;
                let a =
                    VirtualVehicle::ramp_rate(s.v_mps, self.velocity.target[0], l.accel_mps2, dt);
                let al = VirtualVehicle::ramp_rate(
                    s.omega_radps,
                    self.velocity.target[1],
                    l.ang_accel_radps2,
                    dt,
                );
                let mut out = s;
                out.v_dot_mps2 = a;
                out.omega_dot_radps2 = al;
                self.vehicle.advance(dt, a, al);
                out
            }
        }
    }

    fn report_state(&mut self) {
        let state = self.state();
        if state != self.reported_state {
            self.reported_state = state;
            let cause = match state {
                RunStateMsg::Running => None,
                RunStateMsg::Stopping => self.braking.map(|b| b.cause),
                _ => self.pending_cause.take(),
            };
            self.send(&Reply::Event(Event::StateChanged { state, cause }));
        }
    }

    // Out of line: one copy (smaller firmware; the call costs nothing here).
    #[inline(never)]
    fn telemetry(&mut self, rep: &TickReport) {
        let rate = self.cfg.link.telemetry_rate_hz;
        if rate == 0 {
            return;
        }
        if self.telemetry_countdown > 0 {
            self.telemetry_countdown -= 1;
            return;
        }
        let every = ((1.0 / (rate as f32 * self.period_s)) + 0.5) as u32;
        self.telemetry_countdown = every.max(1) - 1;
        // Keep room for a reply: telemetry only when two frames still fit.
        if TX_CAPACITY - self.tx.len() < 2 * MAX_FRAME {
            self.link.tx_dropped = self.link.tx_dropped.saturating_add(1);
            self.telemetry_seq = self.telemetry_seq.wrapping_add(1);
            return;
        }
        let sel = self.cfg.link.telemetry_selection;
        let d = &rep.diag;
        let duty = rep.duty.map(|c| {
            if c.reverse {
                -(c.duty as i32)
            } else {
                c.duty as i32
            }
        });
        let t = Telemetry {
            seq: self.telemetry_seq,
            t_robot_us: self.now_us,
            t_ref_s: rep.t_s,
            state: self.state(),
            tracking: (sel & TELEMETRY_TRACKING != 0).then(|| TrackingTelemetry {
                pose: pose_to_msg(rep.pose),
                ref_pose: pose_to_msg(rep.reference.pose),
                error: d.error,
                eta: rep.eta.as_array(),
                eta_c: d.eta_c,
                torque_nm: rep.torque_nm,
                duty,
                saturated: d.saturated,
                time_scale: rep.pace.scale,
                tau_s: rep.pace.tau_s,
                health: rep.pace.mode as u8,
                health_reason: rep.pace.reason as u8,
            }),
            estimators: (sel & TELEMETRY_ESTIMATORS != 0).then(|| EstimatorTelemetry {
                s: d.s,
                rho_hat: d.rho_hat,
                d_hat: d.d_hat,
                f_hat: d.f_hat,
                external_pose: rep.external_pose,
                input_fault: d.fault.is_some(),
            }),
            counters: (sel & TELEMETRY_COUNTERS != 0).then(|| self.counters()),
        };
        self.telemetry_seq = self.telemetry_seq.wrapping_add(1);
        self.send(&Reply::Telemetry(t));
    }

    fn param(&self, id: ParamId) -> f32 {
        let c = &self.control.config().controller;
        let s = &self.control.config().safety;
        let l = &self.cfg.link;
        match id {
            ParamId::TorqueLimitNm => c.torque_limit_nm,
            ParamId::Kx => c.kinematic.k_x,
            ParamId::Ky => c.kinematic.k_y,
            ParamId::Ktheta => c.kinematic.k_th,
            ParamId::Ks => c.sliding.k_s,
            ParamId::StallTorqueNm => s.stall_torque_nm,
            ParamId::StallTicks => s.stall_ticks as f32,
            ParamId::TelemetryRateHz => l.telemetry_rate_hz as f32,
            ParamId::LinkTimeoutMs => l.link_timeout_ms as f32,
            ParamId::AccelMps2 => l.accel_mps2,
            ParamId::AngAccelRadps2 => l.ang_accel_radps2,
            ParamId::BrakeDecelMps2 => l.brake_decel_mps2,
            ParamId::MaxSpeedMps => l.max_speed_mps,
            ParamId::MaxYawRateRadps => l.max_yaw_rate_radps,
            ParamId::ControlPeriodS => self.period_s,
        }
    }

    // Out of line: one copy (smaller firmware; the call costs nothing here).
    #[inline(never)]
    fn set_param(&mut self, id: ParamId, value: f32) -> Result<(), ErrorCode> {
        if !value.is_finite() {
            return Err(ErrorCode::InvalidValue);
        }
        let as_int = |hi: f32| -> Result<u32, ErrorCode> {
            if value >= 0.0 && value <= hi && value == (value as u32) as f32 {
                Ok(value as u32)
            } else {
                Err(ErrorCode::InvalidValue)
            }
        };
        // Any state: telemetry and the link timeout.
        match id {
            ParamId::TelemetryRateHz => {
                self.cfg.link.telemetry_rate_hz = as_int(1000.0)? as u16;
                self.telemetry_countdown = 0;
                return Ok(());
            }
            ParamId::LinkTimeoutMs => {
                let mut l = self.cfg.link;
                l.link_timeout_ms = as_int(u32::MAX as f32)?;
                self.cfg.link = l.validate().map_err(|_| ErrorCode::InvalidValue)?;
                return Ok(());
            }
            ParamId::ControlPeriodS => return Err(ErrorCode::ReadOnly),
            _ => {}
        }
        self.in_hold()?;
        let mut c = self.control.config().controller;
        let mut s = self.control.config().safety;
        let mut l = self.cfg.link;
        match id {
            ParamId::TorqueLimitNm => c.torque_limit_nm = value,
            ParamId::Kx => c.kinematic.k_x = value,
            ParamId::Ky => c.kinematic.k_y = value,
            ParamId::Ktheta => c.kinematic.k_th = value,
            ParamId::Ks => c.sliding.k_s = value,
            ParamId::StallTorqueNm => s.stall_torque_nm = value,
            ParamId::StallTicks => s.stall_ticks = as_int(u16::MAX as f32)? as u16,
            ParamId::AccelMps2 => l.accel_mps2 = value,
            ParamId::AngAccelRadps2 => l.ang_accel_radps2 = value,
            ParamId::BrakeDecelMps2 => l.brake_decel_mps2 = value,
            ParamId::MaxSpeedMps => l.max_speed_mps = value,
            ParamId::MaxYawRateRadps => l.max_yaw_rate_radps = value,
            ParamId::TelemetryRateHz | ParamId::LinkTimeoutMs | ParamId::ControlPeriodS => {}
        }
        let l = l.validate().map_err(|_| ErrorCode::InvalidValue)?;
        self.control.reconfigure(c, s).map_err(|e| match e {
            controller_core::runtime::ReconfigureError::Running => ErrorCode::Busy,
            _ => ErrorCode::InvalidValue,
        })?;
        self.cfg.link = l;
        Ok(())
    }
}
