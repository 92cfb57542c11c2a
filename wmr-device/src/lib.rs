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
//!
//! Modules, each using only those listed before it (checked by
//! `tests/layers.rs`): [`framing`] (bytes and frames), [`limits`] (the
//! physical limits, D41), [`reference`](mod@reference) (the references),
//! [`params`] (configuration and parameters), [`robot`] (the robot record:
//! upload, validation, the pending flash write), [`wheel_test`] (the
//! commissioning wheel test), `telemetry` (telemetry and
//! events), `selection` (which reference drives each tick, controlled
//! stops), `requests` (request handling against the state); [`Device`]
//! here wires them.
#![no_std]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod framing;
pub mod limits;
pub mod params;
pub mod reference;
mod requests;
pub mod robot;
mod selection;
mod telemetry;
pub mod wheel_test;

use controller_core::estimator::{EstimatorConfig, PoseMeasurement, HISTORY_LEN};
use controller_core::runtime::{
    ControlLoop, Gyro, MotorDriver, PoseSource, RunState, RuntimeConfig, TickReport, TickTiming,
    WheelEncoders,
};
use controller_core::trajectory::{RefSample, Trajectory};
use framing::Framing;
use limits::RobotLimits;
use reference::PlacedReference;
use requests::Handler;
use selection::Mode;
use wheel_test::{HoldOff, Tap};
use wmr_protocol::{
    BoardReport, Counters, ModeMsg, RobotSource, RunStateMsg, StopCode, WheelTestEnd,
};

pub use framing::{RX_BYTES_PER_TICK, RX_CAPACITY, TX_CAPACITY};
pub use params::{
    check_set, DeviceConfig, DeviceConfigError, LinkConfig, SetParamError, MAX_VELOCITY_TIMEOUT_MS,
};

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

/// The robot side of the host link around a [`ControlLoop`]: the framing
/// layer (bytes, frames, link counters) and the request handler (the
/// configuration, the runtime, the reference selection, telemetry and the
/// host session).
pub struct Device<const H: usize = HISTORY_LEN> {
    framing: Framing,
    handler: Handler<H>,
}

impl<const H: usize> Device<H> {
    /// Validates both configurations and builds a device in hold, with the
    /// example estimator tuning ([`EstimatorConfig::EXAMPLE`]).
    pub fn new(cfg: DeviceConfig, runtime: RuntimeConfig) -> Result<Self, DeviceConfigError> {
        Self::with_estimator(cfg, runtime, EstimatorConfig::EXAMPLE)
    }

    /// [`Self::new`] with a given estimator tuning (`H` ticks of history:
    /// the oldest external pose it can use).
    pub fn with_estimator(
        cfg: DeviceConfig,
        runtime: RuntimeConfig,
        estimator: EstimatorConfig,
    ) -> Result<Self, DeviceConfigError> {
        let control = ControlLoop::<H>::with_estimator(runtime, estimator)
            .map_err(DeviceConfigError::Runtime)?;
        let limits = RobotLimits::of(control.config());
        let cfg = cfg.validate(&limits)?;
        params::check_physical(control.config(), &cfg.link, &limits)?;
        Ok(Self {
            framing: Framing::new(),
            handler: Handler::new(cfg, control, limits),
        })
    }

    /// What the board reports in the status (its reset cause, set once
    /// at boot, and its link port's losses, kept current by the board).
    pub fn board_report_mut(&mut self) -> &mut BoardReport {
        &mut self.handler.session.board
    }

    /// The host's clock against the robot's: robot µs per host ms (at
    /// least 1). 1000, the default, on a real robot, whose clock is the
    /// host's. A simulated robot running N times faster than real time
    /// (`hil-sim device --speed N`) sets N·1000: the durations the host
    /// gives and keeps in its own time (the link timeout, against which it
    /// paces its keep-alive; a velocity command's timeout, against which
    /// it paces the refresh) then count the host's time, so the link
    /// watchdog sees the host's cadence as the host keeps it at any speed
    /// (issue 32, D140). A simulation that falls behind N only lengthens
    /// them in wall time.
    pub fn set_host_clock(&mut self, robot_us_per_host_ms: u32) {
        self.handler.session.robot_us_per_host_ms = robot_us_per_host_ms.max(1);
    }

    /// Attaches the board's robot store (protocol 4): `record` is the
    /// robot record in force and `source` where it came from; uploads are
    /// checked as a whole with `validate` before anything is stored.
    /// Without it the robot requests are refused with `NoStore`.
    pub fn attach_robot_store(
        &mut self,
        validate: robot::RobotValidator,
        record: &[u8],
        source: RobotSource,
    ) {
        self.handler.robot.attach(validate, record, source);
    }

    /// The validated robot record waiting for its flash write: the board
    /// writes it outside the control tick (in hold, motors off) and then
    /// calls [`Self::robot_write_done`]. Arming is refused meanwhile.
    pub fn pending_robot_write(&self) -> Option<&[u8]> {
        match self.handler.control.state() {
            RunState::Disarmed => self.handler.robot.pending_write(),
            _ => None,
        }
    }

    /// The board's write of [`Self::pending_robot_write`] finished (`ok`:
    /// stored and read back equal); the commit is answered now.
    pub fn robot_write_done(&mut self, ok: bool) {
        self.handler.robot_write_done(&mut self.framing, ok);
    }

    /// The host asked for a restart (acknowledged; in hold): the board
    /// resets once the acknowledgement has left.
    pub fn reboot_requested(&self) -> bool {
        self.handler.robot.reboot_requested()
    }

    /// The robot record's status report.
    pub fn robot_report(&self) -> wmr_protocol::RobotReport {
        self.handler.robot.report()
    }

    /// The runtime.
    pub fn control(&self) -> &ControlLoop<H> {
        &self.handler.control
    }

    /// The run state as the host sees it.
    pub fn state(&self) -> RunStateMsg {
        self.handler.state()
    }

    /// The cause of the last stop (controlled, latched or a disarm), as
    /// the status reports it.
    pub fn last_stop(&self) -> Option<StopCode> {
        self.handler.session.last_stop
    }

    /// The loaded mode.
    pub fn mode(&self) -> ModeMsg {
        self.handler.selector.mode_msg()
    }

    /// Every counter.
    pub fn counters(&self) -> Counters {
        self.handler.counters(&self.framing)
    }

    /// The link settings in force.
    pub fn link_config(&self) -> &LinkConfig {
        &self.handler.cfg.link
    }

    /// Queues received bytes; returns how many fit (the rest are dropped
    /// and counted in `rx_overflow`). Never blocks.
    pub fn push_rx(&mut self, bytes: &[u8]) -> usize {
        self.framing.push_rx(bytes)
    }

    /// Free space of the receive buffer \[bytes\].
    pub fn rx_free(&self) -> usize {
        self.framing.rx_free()
    }

    /// Moves queued outgoing bytes into `out`; returns how many.
    pub fn pop_tx(&mut self, out: &mut [u8]) -> usize {
        self.framing.pop_tx(out)
    }

    /// Outgoing bytes queued.
    pub fn tx_len(&self) -> usize {
        self.framing.tx_len()
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
        let h = &mut self.handler;
        h.session.now_us = now_us;
        h.process_rx(&mut self.framing, motors);
        h.watchdogs(&mut self.framing);
        h.wheel_test_watchdog(&mut self.framing, motors);
        let reference = h.reference_for_tick(motors);
        let mut pose = HostOrBoard {
            host: h.session.pending_pose.take(),
            board: pose_source,
        };
        let rep = if h.wheel_test.is_some() {
            // The loop runs disarmed; its disable is held back until the
            // test's decision below (module wheel_test, D88).
            let mut m = HoldOff {
                inner: motors,
                disable_asked: false,
            };
            let mut g = Tap {
                inner: gyro,
                last: None,
            };
            let jumps = h.control.status().encoder_jumps;
            let rep = h.control.tick_with_reference(
                encoders,
                &mut m,
                &mut g,
                &mut pose,
                timing,
                &Fixed(reference),
            );
            let clean =
                rep.state == RunState::Disarmed && rep.stopped.is_none() && !rep.motors_enabled;
            let period_s = h.period_s();
            let end = match h.wheel_test.as_mut() {
                Some(t) => {
                    let jumped = h.control.status().encoder_jumps != jumps;
                    t.step(rep.counts.delta, g.last, period_s, jumped)
                }
                None => Some(WheelTestEnd::Command),
            };
            let end = if clean {
                end
            } else {
                Some(WheelTestEnd::Stopped)
            };
            match (h.wheel_test.as_ref(), end) {
                (Some(t), None) => motors.set(t.duty()),
                (_, end) => {
                    let end = end.unwrap_or(WheelTestEnd::Stopped);
                    h.end_wheel_test(&mut self.framing, motors, end);
                    motors.disable();
                }
            }
            rep
        } else {
            h.control.tick_with_reference(
                encoders,
                motors,
                gyro,
                &mut pose,
                timing,
                &Fixed(reference),
            )
        };
        // A pose the runtime did not take (a re-propagation in progress)
        // waits for the next tick instead of being lost.
        h.session.pending_pose = pose.host;
        h.after_tick(&mut self.framing, &rep);
        rep
    }

    /// The arm button (a debounced press, see
    /// [`ArmingButton`](controller_core::runtime::ArmingButton)): disarms
    /// while running or stopping, clears a latched stop, else arms the
    /// loaded mode, or the configured button reference when none is loaded.
    /// Works without a host (the link watchdog stays off).
    pub fn button_pressed(&mut self, motors: &mut impl MotorDriver) {
        let h = &mut self.handler;
        // A wheel test in progress: the press ends it, nothing else.
        if h.wheel_test.is_some() {
            h.end_wheel_test(&mut self.framing, motors, WheelTestEnd::Command);
            return;
        }
        match h.control.state() {
            RunState::Running => h.disarm(motors, StopCode::Disarmed),
            RunState::Stopped(_) => h.control.reset(),
            RunState::Disarmed => {
                if matches!(h.selector.mode, Mode::None) {
                    if let Some(p) = h
                        .cfg
                        .button_reference
                        .as_ref()
                        .and_then(|b| PlacedReference::within(b, &h.limits))
                    {
                        h.selector.mode = Mode::Builtin(p);
                    }
                }
                let _ = h.arm(false);
            }
        }
        h.report_state(&mut self.framing);
    }
}
