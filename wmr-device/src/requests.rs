//! Request handling: each decoded request checked against the state
//! (no arming without a loaded mode or with a latched stop, configuration
//! only in hold) and answered with an ack, a nack with a typed error, or
//! its reply; the arm/disarm transitions and the link watchdog.

use crate::framing::{bump, Framing, RX_BYTES_PER_TICK};
use crate::limits::{RobotLimits, MAX_POSITION_M, REST_HOLD_S};
use crate::params::{self, in_hold, DeviceConfig, MAX_TELEMETRY_RATE_HZ, MAX_VELOCITY_TIMEOUT_MS};
use crate::reference::{pose_from_msg, PlacedReference, SegmentError, VirtualVehicle};
use crate::robot::RobotRecord;
use crate::selection::{Measured, Mode, Selected, Selector, StopPolicy, VelocityCmd};
use crate::telemetry::{counters, TelemetryScheduler};
use crate::wheel_test::WheelTest;
use controller_core::estimator::{PoseMeasurement, RejectReason};
use controller_core::runtime::{ControlLoop, MotorDriver, RunState, StopReason, TickReport};
use controller_core::trajectory::RefSample;
use wmr_protocol::{
    BoardReport, Counters, Decoded, ErrorCode, Event, PoseRejects, Reply, Request, RobotInfo,
    RunStateMsg, StatusMsg, StopCode, WheelTestEnd, PROTOCOL_VERSION, TELEMETRY_ALL,
};

/// One request's answer.
type Answer = Result<Option<Reply>, ErrorCode>;

/// The host session: who armed, when the host was last heard, the pose it
/// sent for the next tick, and the stops to report.
pub(crate) struct Session {
    /// Armed under host control (the link watchdog runs).
    pub host_armed: bool,
    /// Robot time of the last valid frame \[µs\].
    pub last_rx_us: u32,
    /// Robot time of this tick \[µs\].
    pub now_us: u32,
    /// Robot µs per host ms ([`crate::Device::set_host_clock`]; 1000 on a
    /// real robot).
    pub robot_us_per_host_ms: u32,
    /// The host's pose measurement for the next tick.
    pub pending_pose: Option<PoseMeasurement>,
    /// The last stop's cause.
    pub last_stop: Option<StopCode>,
    /// The stop not yet reported in an event.
    pub pending_cause: Option<StopCode>,
    /// What the board reports in the status (its reset cause, set once at
    /// boot, and its link port's losses, kept current by the board).
    pub board: BoardReport,
}

impl Session {
    /// A duration the host gave in its own ms (the link timeout, a
    /// velocity command's timeout) in robot µs, at most 2³¹ − 1 (the
    /// wrapping clock's comparisons).
    pub fn host_ms_us(&self, ms: u32) -> u32 {
        ms.saturating_mul(self.robot_us_per_host_ms)
            .min(i32::MAX as u32)
    }
}

fn stop_code(r: StopReason) -> StopCode {
    match r {
        StopReason::ControllerInput(_) => StopCode::ControllerInput,
        StopReason::EncoderJump { .. } => StopCode::EncoderJump,
        StopReason::EncoderStalled { .. } => StopCode::EncoderStalled,
        StopReason::LoopOverrun { .. } => StopCode::LoopOverrun,
        StopReason::Commanded => StopCode::Commanded,
        StopReason::DirectionMismatch { .. } => StopCode::DirectionMismatch,
        _ => StopCode::Other,
    }
}

fn pose_error(r: RejectReason) -> ErrorCode {
    match r {
        RejectReason::NonFinite => ErrorCode::PoseNonFinite,
        RejectReason::BadStdDev => ErrorCode::PoseBadStdDev,
        RejectReason::FromFuture => ErrorCode::PoseFromFuture,
        RejectReason::OutOfOrder => ErrorCode::PoseOutOfOrder,
        // TooOld, and the gate (never at this check).
        _ => ErrorCode::PoseTooOld,
    }
}

fn ref_is_finite(r: &RefSample) -> bool {
    finite(&[
        r.pose.x_m,
        r.pose.y_m,
        r.pose.theta_rad,
        r.v_mps,
        r.omega_radps,
        r.v_dot_mps2,
        r.omega_dot_radps2,
    ])
}

fn finite(xs: &[f32]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

/// The state requests are checked against, and what they change.
pub(crate) struct Handler<const H: usize> {
    pub cfg: DeviceConfig,
    /// The robot's physical limits (from the runtime configuration).
    pub limits: RobotLimits,
    pub control: ControlLoop<H>,
    pub selector: Selector,
    pub telemetry: TelemetryScheduler,
    pub session: Session,
    /// The robot record (upload, stored record, pending write).
    pub robot: RobotRecord,
    /// The commissioning wheel test in progress.
    pub wheel_test: Option<WheelTest>,
}

impl<const H: usize> Handler<H> {
    pub fn new(cfg: DeviceConfig, control: ControlLoop<H>, limits: RobotLimits) -> Self {
        Self {
            cfg,
            limits,
            control,
            selector: Selector::new(),
            telemetry: TelemetryScheduler::new(),
            session: Session {
                host_armed: false,
                last_rx_us: 0,
                now_us: 0,
                robot_us_per_host_ms: 1000,
                pending_pose: None,
                last_stop: None,
                pending_cause: None,
                board: BoardReport::default(),
            },
            robot: RobotRecord::new(),
            wheel_test: None,
        }
    }

    pub fn period_s(&self) -> f32 {
        self.control.config().controller.period_s
    }

    fn running(&self) -> bool {
        self.control.state() == RunState::Running
    }

    /// The run state as the host sees it.
    pub fn state(&self) -> RunStateMsg {
        match self.control.state() {
            RunState::Disarmed => RunStateMsg::Hold,
            RunState::Running if self.selector.braking.is_some() => RunStateMsg::Stopping,
            RunState::Running => RunStateMsg::Running,
            RunState::Stopped(_) => RunStateMsg::Stopped,
        }
    }

    pub fn counters(&self, framing: &Framing) -> Counters {
        counters(self.control.status(), &framing.counters)
    }

    /// Decodes at most [`RX_BYTES_PER_TICK`] received bytes and answers
    /// every request in them.
    // Out of line: one copy (smaller firmware; the call costs nothing here).
    #[inline(never)]
    pub fn process_rx(&mut self, framing: &mut Framing, motors: &mut impl MotorDriver) {
        let mut chunk = [0u8; RX_BYTES_PER_TICK];
        let n = framing.take_rx(&mut chunk);
        let mut rest = &chunk[..n];
        let mut frame_error_sent = false;
        while !rest.is_empty() {
            let (decoded, r) = framing.decoder.feed::<Request>(rest);
            rest = r;
            match decoded {
                None => {}
                Some(Decoded::Frame { seq, msg }) => {
                    bump(&mut framing.counters.rx_frames);
                    self.session.last_rx_us = self.session.now_us;
                    // Any request but a read ends a wheel test first.
                    if !matches!(msg, Request::GetStatus | Request::GetParam(_)) {
                        self.end_wheel_test(framing, motors, WheelTestEnd::Command);
                    }
                    if let Request::RobotCommit = msg {
                        // Answered when the board's write has finished.
                        if let Some(answer) = self.robot_commit(seq) {
                            answer_with(framing, seq, answer);
                        }
                        continue;
                    }
                    let answer = self.handle(seq, msg, framing, motors);
                    answer_with(framing, seq, answer);
                }
                Some(Decoded::OtherVersion { seq, msg, .. }) => {
                    bump(&mut framing.counters.rx_errors);
                    let answer = match msg {
                        Some(Request::Hello { .. }) => Ok(Some(self.hello(seq))),
                        _ => Err(ErrorCode::VersionMismatch),
                    };
                    answer_with(framing, seq, answer);
                }
                Some(Decoded::Error { seq, error }) => {
                    bump(&mut framing.counters.rx_errors);
                    match seq {
                        Some(seq) => answer_with(framing, seq, Err(error)),
                        // At most one per tick: a flood of garbage cannot
                        // crowd telemetry and answers out of the link.
                        None if !frame_error_sent => {
                            frame_error_sent = framing.send(&Reply::FrameError { error });
                        }
                        None => {}
                    }
                }
            }
        }
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

    fn status(&self, framing: &Framing) -> StatusMsg {
        StatusMsg {
            state: self.state(),
            mode: self.selector.mode_msg(),
            last_stop: self.session.last_stop,
            t_robot_us: self.session.now_us,
            buffered_points: self.selector.waypoints.len() as u16,
            counters: self.counters(framing),
            pose_rejects: {
                let r = &self.control.estimator().status().rejected;
                PoseRejects {
                    non_finite: r.non_finite,
                    bad_std_dev: r.bad_std_dev,
                    from_future: r.from_future,
                    too_old: r.too_old,
                    out_of_order: r.out_of_order,
                    outlier: r.outlier,
                }
            },
            nonfinite_telemetry: self.telemetry.nonfinite_frames(),
            board: self.session.board,
            robot: self.robot.report(),
        }
    }

    /// `RobotCommit`: `None` when the write is now pending (answered by
    /// [`Self::robot_write_done`]).
    fn robot_commit(&mut self, seq: u16) -> Option<Answer> {
        if let Err(e) = self.robot_hold() {
            return Some(Err(e));
        }
        match self.robot.commit(seq) {
            Ok(None) => None,
            Ok(Some(fault)) => Some(Ok(Some(Reply::RobotRejected { seq, fault }))),
            Err(e) => Some(Err(e)),
        }
    }

    /// The board finished the pending record write: answers the commit.
    pub fn robot_write_done(&mut self, framing: &mut Framing, ok: bool) {
        if let Some((seq, r)) = self.robot.write_done(ok) {
            answer_with(framing, seq, r.map(|_| None));
        }
    }

    /// Record writes and reboots: in hold only (motors off), never with a
    /// latched stop or while running.
    fn robot_hold(&self) -> Result<(), ErrorCode> {
        match self.control.state() {
            RunState::Disarmed => Ok(()),
            RunState::Stopped(_) => Err(ErrorCode::Latched),
            RunState::Running => Err(ErrorCode::Busy),
        }
    }

    // Out of line: one copy (smaller firmware; the call costs nothing here).
    #[inline(never)]
    fn handle(
        &mut self,
        seq: u16,
        req: Request,
        framing: &Framing,
        motors: &mut impl MotorDriver,
    ) -> Answer {
        let now_us = self.session.now_us;
        match req {
            Request::Hello { .. } => Ok(Some(self.hello(seq))),
            Request::GetStatus => Ok(Some(Reply::Status {
                seq,
                status: self.status(framing),
            })),
            Request::Arm => self.arm(true).map(|_| None),
            Request::RobotBegin { total_len } => {
                self.robot_hold()?;
                self.robot.begin(total_len).map(|_| None)
            }
            Request::RobotChunk { offset, data } => {
                self.robot_hold()?;
                self.robot.chunk(offset, &data).map(|_| None)
            }
            // Handled before (its answer may wait for the write).
            Request::RobotCommit => Err(ErrorCode::WrongMode),
            Request::RobotRead { offset } => {
                let (total_len, chunk) = self.robot.read(offset)?;
                let mut data = heapless::Vec::new();
                // Never fails: a chunk is at most ROBOT_CHUNK bytes.
                let _ = data.extend_from_slice(chunk);
                Ok(Some(Reply::RobotData {
                    seq,
                    total_len,
                    offset,
                    data,
                }))
            }
            Request::Reboot => {
                self.robot_hold()?;
                self.robot.request_reboot().map(|_| None)
            }
            Request::WheelTest(cmd) => {
                self.robot_hold()?;
                if self.robot.write_pending() || self.robot.reboot_requested() {
                    return Err(ErrorCode::Busy);
                }
                self.wheel_test = Some(WheelTest::start(seq, cmd, self.control.config())?);
                Ok(None)
            }
            Request::Disarm => {
                self.disarm(motors, StopCode::Disarmed);
                Ok(None)
            }
            Request::EmergencyStop => {
                self.control.stop(motors);
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
                // Within the physical range of positions (D41): a pose at
                // 3.4e38 m makes the tracking error, and η_c, infinite.
                // Refused as such in any state, then only in hold.
                let ok = |c: f32| c.abs() <= MAX_POSITION_M;
                if !(ok(p.x_m) && ok(p.y_m) && p.theta_rad.is_finite()) {
                    return Err(ErrorCode::InvalidValue);
                }
                in_hold(self.control.state())?;
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
                if self.session.pending_pose.is_some() {
                    return Err(ErrorCode::PoseQueueFull);
                }
                // One position std dev (the larger); a zero, negative or
                // NaN one in x or y is refused (NaN marks it). A zero
                // heading std dev means "no heading" (position only).
                let (sx, sy, h) = (std_dev[0], std_dev[1], std_dev[2]);
                let m = PoseMeasurement {
                    stamp_us: t_robot_us,
                    pose: pose_from_msg(pose),
                    position_std_m: if sx > 0.0 && sy > 0.0 {
                        sx.max(sy)
                    } else {
                        f32::NAN
                    },
                    heading_std_rad: if h == 0.0 { None } else { Some(h) },
                };
                // The estimator's own rules, for the tick that will use it.
                self.control
                    .estimator()
                    .admissible_at(&m, now_us)
                    .map_err(pose_error)?;
                self.session.pending_pose = Some(m);
                Ok(None)
            }
            Request::ClockSync { host_time_us } => Ok(Some(Reply::ClockSync {
                seq,
                host_time_us,
                robot_time_us: now_us,
            })),
            Request::SetReference(r) => {
                in_hold(self.control.state())?;
                let placed =
                    PlacedReference::within(&r, &self.limits).ok_or(ErrorCode::InvalidValue)?;
                self.selector.mode = Mode::Builtin(placed);
                self.selector.waypoints.clear();
                Ok(None)
            }
            Request::TrajectoryBegin { total_points } => {
                in_hold(self.control.state())?;
                if total_points < 2 {
                    return Err(ErrorCode::InvalidValue);
                }
                self.selector.waypoints.begin(total_points);
                self.selector.mode = Mode::None;
                Ok(None)
            }
            Request::TrajectorySegment {
                first_index,
                points,
            } => {
                let running = self.running();
                let sel = &mut self.selector;
                if running && !matches!(sel.mode, Mode::Trajectory) {
                    return Err(ErrorCode::WrongMode);
                }
                let now = running.then(|| self.control.reference_time_s());
                sel.waypoints
                    .push(first_index, &points, now, &self.limits)
                    .map_err(|e| match e {
                        SegmentError::OutOfOrder => ErrorCode::OutOfOrder,
                        SegmentError::Full => ErrorCode::BufferFull,
                        SegmentError::Invalid | SegmentError::BeyondLimits { .. } => {
                            ErrorCode::InvalidValue
                        }
                    })?;
                if !running && sel.waypoints.ready() {
                    sel.mode = Mode::Trajectory;
                }
                Ok(Some(Reply::TrajectoryAck {
                    seq,
                    next_index: sel.waypoints.next_index(),
                    free: sel.waypoints.free() as u16,
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
                let sel = &mut self.selector;
                match (self.control.state(), sel.mode) {
                    (RunState::Running, Mode::Velocity) if sel.braking.is_none() => {}
                    (RunState::Running, _) => return Err(ErrorCode::WrongMode),
                    _ => {
                        sel.mode = Mode::Velocity;
                        sel.waypoints.clear();
                    }
                }
                sel.velocity = VelocityCmd {
                    target: [v_mps, omega_radps],
                    expires_us: Some(
                        now_us.wrapping_add(self.session.host_ms_us(timeout_ms as u32)),
                    ),
                };
                Ok(None)
            }
            Request::GetParam(id) => Ok(Some(Reply::Param {
                seq,
                id,
                value: params::read(self.control.config(), &self.cfg.link, id),
            })),
            Request::SetParam { id, value } => {
                params::write(
                    &mut self.control,
                    &mut self.cfg.link,
                    &self.limits,
                    id,
                    value,
                )?;
                if id == wmr_protocol::ParamId::TelemetryRateHz {
                    self.telemetry.restart();
                }
                Ok(None)
            }
            Request::SetTelemetry { selection, rate_hz } => {
                if rate_hz > MAX_TELEMETRY_RATE_HZ || selection & !TELEMETRY_ALL != 0 {
                    return Err(ErrorCode::InvalidValue);
                }
                self.cfg.link.telemetry_rate_hz = rate_hz;
                self.cfg.link.telemetry_selection = selection;
                self.telemetry.restart();
                Ok(None)
            }
        }
    }

    /// Arms the loaded mode (`host`: under host control, with the link
    /// watchdog).
    pub fn arm(&mut self, host: bool) -> Result<(), ErrorCode> {
        // Never with a flash write pending or a restart coming.
        if self.robot.write_pending() || self.robot.reboot_requested() {
            return Err(ErrorCode::Busy);
        }
        match self.control.state() {
            RunState::Running if self.selector.braking.is_some() => return Err(ErrorCode::Busy),
            RunState::Running => return Ok(()),
            RunState::Stopped(_) => return Err(ErrorCode::Latched),
            RunState::Disarmed => {}
        }
        if !self.selector.ready() {
            return Err(match self.selector.mode {
                Mode::Trajectory => ErrorCode::UploadIncomplete,
                _ => ErrorCode::NoReference,
            });
        }
        self.control.arm().map_err(|_| ErrorCode::Latched)?;
        self.selector.vehicle = VirtualVehicle::at_rest(self.control.estimator().estimate().pose);
        self.selector.braking = None;
        self.session.host_armed = host;
        self.session.last_rx_us = self.session.now_us;
        self.session.pending_cause = None;
        Ok(())
    }

    pub fn disarm(&mut self, motors: &mut impl MotorDriver, cause: StopCode) {
        let was_running = self.running();
        self.control.disarm(motors);
        self.selector.on_disarm();
        if was_running {
            self.on_stop(cause);
        }
    }

    pub fn on_stop(&mut self, cause: StopCode) {
        self.session.last_stop = Some(cause);
        self.session.pending_cause = Some(cause);
        self.selector.on_stop();
    }

    /// The link watchdog: a controlled stop after the link timeout without
    /// a valid frame while running under host control.
    pub fn watchdogs(&mut self, framing: &mut Framing) {
        if !self.running() || self.selector.braking.is_some() {
            return;
        }
        let s = &self.session;
        let silent_us = s.now_us.wrapping_sub(s.last_rx_us);
        if s.host_armed && silent_us > s.host_ms_us(self.cfg.link.link_timeout_ms) {
            framing.send(&Reply::Event(Event::LinkLost));
            let policy = self.stop_policy();
            self.selector
                .start_braking(true, &self.cfg.link, &policy, StopCode::LinkSilence);
        }
    }

    /// This tick's reference; finishes a controlled stop (disarm) when the
    /// robot is at rest or at the stop's bound.
    pub fn reference_for_tick(&mut self, motors: &mut impl MotorDriver) -> RefSample {
        let running = self.running();
        let t_ref_s = self.control.reference_time_s();
        let now_us = self.session.now_us;
        let policy = self.stop_policy();
        match self
            .selector
            .select(running, t_ref_s, now_us, &self.cfg.link, &policy)
        {
            Selected::Drive(r) => r,
            Selected::Finished(cause, rest) => {
                self.disarm(motors, cause);
                rest
            }
        }
    }

    /// The longest controlled stop with the braking settings in force
    /// \[ticks\] ([`RobotLimits::stop_bound_ticks`]): the motors are cut
    /// then at the latest.
    pub fn stop_cap_ticks(&self) -> u32 {
        let l = &self.cfg.link;
        self.limits
            .stop_bound_ticks(l.brake_decel_mps2, l.ang_accel_radps2)
    }

    /// How a controlled stop runs with the settings in force (the rest
    /// thresholds of [`crate::limits`]).
    pub fn stop_policy(&self) -> StopPolicy {
        let period_s = self.period_s();
        let ticks = |s: f32| ((s / period_s) as u32).max(1);
        StopPolicy {
            period_s,
            cap_ticks: self.stop_cap_ticks(),
            rest_hold_ticks: ticks(REST_HOLD_S),
            rest_speed_mps: self.limits.rest_speed_mps,
            limits: self.limits,
        }
    }

    /// After the control tick: the stop it reported, the state event and
    /// the telemetry frame.
    pub fn after_tick(&mut self, framing: &mut Framing, rep: &TickReport) {
        // A non-finite reference (a runtime fault) is never kept: a later
        // controlled stop or hold starts from the last finite one.
        if ref_is_finite(&rep.reference) {
            self.selector.last_ref = rep.reference;
        }
        let [v, w] = [rep.eta.v_mps, rep.eta.omega_radps];
        let b = self.control.config().controller.robot.half_track_m;
        self.selector.measured = Measured {
            pose: rep.pose,
            eta: [v, w],
            wheel_mps: [v + b * w, v - b * w],
        };
        if let Some(r) = rep.stopped {
            self.on_stop(stop_code(r));
        }
        self.report_state(framing);
        let state = self.state();
        let period_s = self.period_s();
        let estimator = self.control.estimator();
        self.telemetry.tick(
            framing,
            &self.cfg.link,
            period_s,
            self.session.now_us,
            state,
            self.control.status(),
            rep,
            || estimator.odom_covariance(),
        );
    }

    /// Ends the wheel test in progress, if any, for `end`: motors off now,
    /// its result sent.
    pub fn end_wheel_test(
        &mut self,
        framing: &mut Framing,
        motors: &mut impl MotorDriver,
        end: WheelTestEnd,
    ) {
        if let Some(t) = self.wheel_test.take() {
            motors.disable();
            framing.send(&Reply::WheelTestDone {
                seq: t.seq(),
                result: t.result(end),
            });
        }
    }

    /// Link silence during a wheel test ends it.
    pub fn wheel_test_watchdog(&mut self, framing: &mut Framing, motors: &mut impl MotorDriver) {
        let s = &self.session;
        let silent_us = s.now_us.wrapping_sub(s.last_rx_us);
        if self.wheel_test.is_some() && silent_us > s.host_ms_us(self.cfg.link.link_timeout_ms) {
            self.end_wheel_test(framing, motors, WheelTestEnd::LinkLost);
        }
    }

    pub fn report_state(&mut self, framing: &mut Framing) {
        let state = self.state();
        let cause = self.selector.braking_cause();
        self.telemetry
            .report_state(framing, state, cause, &mut self.session.pending_cause);
    }
}

/// Sends the answer to request `seq` (nacks counted).
fn answer_with(framing: &mut Framing, seq: u16, answer: Answer) {
    let reply = match answer {
        Ok(Some(r)) => r,
        Ok(None) => Reply::Ack { seq },
        Err(error) => {
            bump(&mut framing.counters.nacks);
            Reply::Nack { seq, error }
        }
    };
    framing.send(&reply);
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::runtime::Wheel;

    /// Each latched runtime stop has its own code on the link; the
    /// direction check's is not folded into `Other` (issue 18).
    #[test]
    fn runtime_stops_map_to_their_codes() {
        for wheel in Wheel::BOTH {
            assert_eq!(
                stop_code(StopReason::DirectionMismatch { wheel }),
                StopCode::DirectionMismatch
            );
            assert_eq!(
                stop_code(StopReason::EncoderStalled { wheel }),
                StopCode::EncoderStalled
            );
        }
        assert_eq!(stop_code(StopReason::Commanded), StopCode::Commanded);
    }
}
