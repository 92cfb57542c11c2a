//! The control loop and its safety supervisor.

use super::encoder::{CountSample, EncoderParams, WheelCounts};
use super::motor::{DutyCommand, MotorModel, MotorParams};
use super::odometry::Odometry;
use super::{MotorDriver, PoseSource, RuntimeConfigError, Wheel, WheelEncoders};
use crate::controller::{Controller, ControllerConfig, ControllerKind, Diagnostics, StepInput};
use crate::error::InputFault;
use crate::trajectory::{PaperCurve, PaperHeading, RefSample, Reference, Trajectory};
use crate::types::{Pose, Vel2};

/// Thresholds of the safety supervisor.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SafetyLimits {
    /// Largest plausible |count change| of one wheel in one tick \[counts\]
    /// (1..=32767); beyond it the reading is a glitch ([`StopReason::EncoderJump`]).
    /// Set it to about twice the no-load wheel speed in counts per tick.
    pub max_counts_per_tick: u16,
    /// |Commanded wheel torque| \[N·m\] at or above which a wheel must move.
    pub stall_torque_nm: f32,
    /// Consecutive ticks at or above `stall_torque_nm` with no count change
    /// that mean a stalled wheel or a dead encoder ([`StopReason::EncoderStalled`]).
    pub stall_ticks: u16,
    /// Measured loop time \[µs\] above which a tick counts as an overrun.
    pub overrun_limit_us: u32,
    /// Consecutive overruns that latch [`StopReason::LoopOverrun`] (>= 1).
    pub max_consecutive_overruns: u16,
    /// Consecutive controller input faults that latch
    /// [`StopReason::ControllerInput`] (>= 1; 1 latches on the first).
    pub max_consecutive_input_faults: u16,
}

impl SafetyLimits {
    /// Example limits for a 1 kHz loop with [`EncoderParams::EXAMPLE`] and
    /// [`MotorParams::EXAMPLE`] (no-load wheel speed 40 rad/s = 153 counts/ms):
    /// jump > 400 counts/tick, stall at >= 2 N·m for 250 ms, overrun above
    /// 1.5 ms with 5 in a row latching, the first NaN/implausible input latching.
    pub const EXAMPLE: Self = Self {
        max_counts_per_tick: 400,
        stall_torque_nm: 2.0,
        stall_ticks: 250,
        overrun_limit_us: 1500,
        max_consecutive_overruns: 5,
        max_consecutive_input_faults: 1,
    };

    /// Checks every field.
    pub fn validate(self) -> Result<Self, RuntimeConfigError> {
        let ok = self.max_counts_per_tick > 0
            && self.max_counts_per_tick <= i16::MAX as u16
            && self.stall_torque_nm.is_finite()
            && self.stall_torque_nm > 0.0
            && self.stall_ticks > 0
            && self.overrun_limit_us > 0
            && self.max_consecutive_overruns > 0
            && self.max_consecutive_input_faults > 0;
        if ok {
            Ok(self)
        } else {
            Err(RuntimeConfigError::InvalidSafetyLimit)
        }
    }
}

/// Everything the runtime needs, validated by [`ControlLoop::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RuntimeConfig {
    /// The controller (kind, robot parameters, gains, torque limit, period).
    pub controller: ControllerConfig,
    /// The reference trajectory, sampled at t = ticks since arming × period.
    pub reference: Reference,
    /// Pose of G where wheel odometry starts.
    pub initial_pose: Pose,
    /// Encoder resolution, mounting and speed window.
    pub encoder: EncoderParams,
    /// Motor, gearbox, supply and PWM constants.
    pub motor: MotorParams,
    /// Per wheel `[right, left]`: flip the direction output (mirrored motor).
    pub motor_inverted: [bool; 2],
    /// Safety thresholds.
    pub safety: SafetyLimits,
}

impl RuntimeConfig {
    /// Example: `kind` with the paper's gains, the paper's curve
    /// ([`PaperHeading::SignedSmooth`]), odometry starting on the reference's
    /// initial pose, and the `EXAMPLE` encoder, motor and safety constants.
    pub fn example(kind: ControllerKind) -> Self {
        let reference = Reference::Paper(PaperCurve::paper(PaperHeading::SignedSmooth));
        Self {
            controller: ControllerConfig::paper(kind),
            reference,
            initial_pose: reference.sample(0.0).pose,
            encoder: EncoderParams::EXAMPLE,
            motor: MotorParams::EXAMPLE,
            motor_inverted: [false, true],
            safety: SafetyLimits::EXAMPLE,
        }
    }
}

/// Why the loop latched a safe stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StopReason {
    /// The controller rejected its input (NaN, infinite or implausible pose,
    /// velocity or reference, or its internal state reset).
    ControllerInput(InputFault),
    /// A wheel's count changed by more than `max_counts_per_tick`.
    EncoderJump {
        /// Which wheel.
        wheel: Wheel,
        /// The implausible change \[counts\].
        delta: i32,
    },
    /// A wheel did not move for `stall_ticks` while commanded at least
    /// `stall_torque_nm`.
    EncoderStalled {
        /// Which wheel.
        wheel: Wheel,
    },
    /// `max_consecutive_overruns` loop overruns in a row.
    LoopOverrun {
        /// The last measured loop time \[µs\].
        loop_time_us: u32,
    },
    /// Stopped on request ([`ControlLoop::stop`]).
    Commanded,
}

/// Supervisor state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RunState {
    /// Motors disabled, waiting for [`ControlLoop::arm`] (the boot state).
    Disarmed,
    /// Controller running, motors driven.
    Running,
    /// Latched safe stop: motors disabled until [`ControlLoop::reset`].
    Stopped(StopReason),
}

/// Why [`ControlLoop::arm`] refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ArmError {
    /// A safe stop is latched; [`ControlLoop::reset`] first.
    Latched(StopReason),
}

/// Counters for logging (lifetime totals unless noted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Status {
    /// Current state.
    pub state: RunState,
    /// Ticks since construction.
    pub ticks: u32,
    /// Controller steps since the last arming (the reference time base).
    pub run_ticks: u32,
    /// Ticks whose measured loop time exceeded the limit.
    pub overruns: u32,
    /// Current run of consecutive overruns.
    pub consecutive_overruns: u16,
    /// Largest measured loop time \[µs\].
    pub max_loop_time_us: u32,
    /// Implausible encoder jumps (also counted while disarmed).
    pub encoder_jumps: u32,
    /// Controller steps rejected for bad input.
    pub input_faults: u32,
    /// Steps where the controller clamped its torque request.
    pub torque_saturated: u32,
    /// Wheel-steps where the duty was clamped (the supply could not deliver
    /// the torque at that speed).
    pub duty_saturated: u32,
    /// External pose measurements used.
    pub external_poses: u32,
    /// Safe stops latched.
    pub stops: u32,
}

/// What one tick did, for telemetry and for the simulator.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickReport {
    /// State after this tick.
    pub state: RunState,
    /// Set on the tick that latched a safe stop.
    pub stopped: Option<StopReason>,
    /// Reference time of this step \[s\] (ticks since arming × period).
    pub t_s: f32,
    /// Pose given to the controller (external measurement or odometry).
    pub pose: Pose,
    /// Wheel odometry pose of G (re-anchored on external measurements).
    pub odometry: Pose,
    /// True when `pose` came from the [`PoseSource`].
    pub external_pose: bool,
    /// Encoder deltas and wheel rates.
    pub counts: CountSample,
    /// Measured η = \[v, ω\] from the wheel rates.
    pub eta: Vel2,
    /// Reference sample.
    pub reference: RefSample,
    /// Wheel torques commanded this tick \[N·m\] `[right, left]` (0 when not running).
    pub torque_nm: [f32; 2],
    /// Duty written `[right, left]` (after `motor_inverted`).
    pub duty: [DutyCommand; 2],
    /// True when the driver was enabled and written; false when disabled.
    pub motors_enabled: bool,
    /// Controller diagnostics (default when the controller did not run).
    pub diag: Diagnostics,
}

/// The runtime: encoders, odometry, controller, motor model and supervisor.
#[derive(Clone, Debug)]
pub struct ControlLoop {
    cfg: RuntimeConfig,
    controller: Controller,
    motor: MotorModel,
    counts: WheelCounts,
    odometry: Odometry,
    status: Status,
    stall_ticks: [u16; 2],
    consecutive_input_faults: u16,
    last_torque_nm: [f32; 2],
}

impl ControlLoop {
    /// Validates `cfg` and builds a disarmed loop.
    pub fn new(cfg: RuntimeConfig) -> Result<Self, RuntimeConfigError> {
        let controller = Controller::new(cfg.controller)?;
        cfg.reference.validate()?;
        if !cfg.initial_pose.is_finite() {
            return Err(RuntimeConfigError::NonFiniteInitialPose);
        }
        let motor = MotorModel::new(cfg.motor)?;
        let counts = WheelCounts::new(cfg.encoder)?;
        cfg.safety.validate()?;
        let odometry = Odometry::new(cfg.controller.robot, cfg.initial_pose);
        Ok(Self {
            cfg,
            controller,
            motor,
            counts,
            odometry,
            status: Status {
                state: RunState::Disarmed,
                ticks: 0,
                run_ticks: 0,
                overruns: 0,
                consecutive_overruns: 0,
                max_loop_time_us: 0,
                encoder_jumps: 0,
                input_faults: 0,
                torque_saturated: 0,
                duty_saturated: 0,
                external_poses: 0,
                stops: 0,
            },
            stall_ticks: [0; 2],
            consecutive_input_faults: 0,
            last_torque_nm: [0.0; 2],
        })
    }

    /// The validated configuration.
    pub fn config(&self) -> &RuntimeConfig {
        &self.cfg
    }

    /// The motor model (its forward model is the simulator's actuator).
    pub fn motor_model(&self) -> &MotorModel {
        &self.motor
    }

    /// The controller (for its configuration and model).
    pub fn controller(&self) -> &Controller {
        &self.controller
    }

    /// Status counters.
    pub fn status(&self) -> &Status {
        &self.status
    }

    /// Current state.
    pub fn state(&self) -> RunState {
        self.status.state
    }

    /// Current wheel-odometry pose of G.
    pub fn odometry(&self) -> Pose {
        self.odometry.pose()
    }

    /// Re-anchors the odometry at `pose` (ignored when not finite).
    pub fn set_odometry(&mut self, pose: Pose) {
        self.odometry.set_pose(pose);
    }

    /// Starts the controller: from [`RunState::Disarmed`], resets the
    /// controller's integrators and the reference time to 0. No-op when
    /// already running; refused while a stop is latched.
    pub fn arm(&mut self) -> Result<(), ArmError> {
        match self.status.state {
            RunState::Running => Ok(()),
            RunState::Stopped(r) => Err(ArmError::Latched(r)),
            RunState::Disarmed => {
                self.controller.reset();
                self.status.run_ticks = 0;
                self.stall_ticks = [0; 2];
                self.consecutive_input_faults = 0;
                self.status.consecutive_overruns = 0;
                self.last_torque_nm = [0.0; 2];
                self.status.state = RunState::Running;
                Ok(())
            }
        }
    }

    /// Stops driving and disables `motors` (not latched: [`Self::arm`] may
    /// restart). A latched stop stays latched.
    pub fn disarm(&mut self, motors: &mut impl MotorDriver) {
        if self.status.state == RunState::Running {
            self.status.state = RunState::Disarmed;
        }
        self.last_torque_nm = [0.0; 2];
        motors.disable();
    }

    /// Latches [`StopReason::Commanded`] (unless a stop is already latched)
    /// and disables `motors`.
    pub fn stop(&mut self, motors: &mut impl MotorDriver) {
        if !matches!(self.status.state, RunState::Stopped(_)) {
            self.latch(StopReason::Commanded);
        }
        motors.disable();
    }

    /// Clears a latched stop (back to [`RunState::Disarmed`]; motors stay
    /// disabled until [`Self::arm`]). Lifetime counters are kept.
    pub fn reset(&mut self) {
        if matches!(self.status.state, RunState::Stopped(_)) {
            self.status.state = RunState::Disarmed;
        }
        self.stall_ticks = [0; 2];
        self.consecutive_input_faults = 0;
        self.status.consecutive_overruns = 0;
    }

    fn latch(&mut self, reason: StopReason) {
        self.status.state = RunState::Stopped(reason);
        self.status.stops = self.status.stops.saturating_add(1);
        self.last_torque_nm = [0.0; 2];
    }

    fn running(&self) -> bool {
        self.status.state == RunState::Running
    }

    /// One control period. `loop_time_us` is the measured time since the
    /// previous tick started \[µs\] (0 when unknown, e.g. on the first tick).
    ///
    /// Never panics; on any safety violation while running it latches a
    /// stop, disables `motors` and reports the reason in
    /// [`TickReport::stopped`].
    pub fn tick(
        &mut self,
        encoders: &mut impl WheelEncoders,
        motors: &mut impl MotorDriver,
        pose_source: &mut impl PoseSource,
        loop_time_us: u32,
    ) -> TickReport {
        let safety = self.cfg.safety;
        let dt = self.cfg.controller.period_s;
        let st = &mut self.status;
        st.ticks = st.ticks.wrapping_add(1);
        let mut stop: Option<StopReason> = None;

        // 1. Loop timing.
        st.max_loop_time_us = st.max_loop_time_us.max(loop_time_us);
        if loop_time_us > safety.overrun_limit_us {
            st.overruns = st.overruns.saturating_add(1);
            st.consecutive_overruns = st.consecutive_overruns.saturating_add(1);
            if st.state == RunState::Running
                && st.consecutive_overruns >= safety.max_consecutive_overruns
            {
                stop = Some(StopReason::LoopOverrun { loop_time_us });
            }
        } else {
            st.consecutive_overruns = 0;
        }

        // 2. Encoders: plausibility, deltas, rates, η.
        let raw = encoders.counts();
        let delta = self.counts.peek_delta(raw);
        let limit = safety.max_counts_per_tick as i32;
        let jump = Wheel::BOTH
            .into_iter()
            .find(|w| delta[w.index()].abs() > limit);
        let sample = match jump {
            Some(wheel) => {
                self.status.encoder_jumps = self.status.encoder_jumps.saturating_add(1);
                self.counts.resync(raw);
                if stop.is_none() && self.running() {
                    stop = Some(StopReason::EncoderJump {
                        wheel,
                        delta: delta[wheel.index()],
                    });
                }
                CountSample::default()
            }
            None => self.counts.update(raw, dt),
        };
        let robot = &self.cfg.controller.robot;
        let eta = robot.eta_from_wheel_rates(sample.rate_radps);

        // 3. Pose.
        self.odometry.update(sample.dphi_rad);
        let (pose, external_pose) = match pose_source.pose() {
            Some(p) => {
                self.status.external_poses = self.status.external_poses.saturating_add(1);
                self.odometry.set_pose(p);
                (p, true)
            }
            None => (self.odometry.pose(), false),
        };

        // 4. Reference and controller.
        let t_s = self.status.run_ticks as f32 * dt;
        let reference = self.cfg.reference.sample(t_s);
        let mut diag = Diagnostics::default();
        let mut torque = [0.0f32; 2];
        let mut duty = [DutyCommand::ZERO; 2];
        let mut enabled = false;
        if self.running() && stop.is_none() {
            let out = self.controller.step(&StepInput {
                reference,
                pose,
                eta,
            });
            diag = out.diag;
            if let Some(f) = diag.fault {
                self.status.input_faults = self.status.input_faults.saturating_add(1);
                self.consecutive_input_faults = self.consecutive_input_faults.saturating_add(1);
                if self.consecutive_input_faults >= safety.max_consecutive_input_faults {
                    stop = Some(StopReason::ControllerInput(f));
                }
            } else {
                self.consecutive_input_faults = 0;
            }
            if diag.saturated {
                self.status.torque_saturated = self.status.torque_saturated.saturating_add(1);
            }
            // Stall: the torque applied during the elapsed tick moved nothing.
            for w in Wheel::BOTH {
                let i = w.index();
                let n = &mut self.stall_ticks[i];
                if self.last_torque_nm[i].abs() >= safety.stall_torque_nm && sample.delta[i] == 0 {
                    *n = n.saturating_add(1);
                } else {
                    *n = 0;
                }
                if *n >= safety.stall_ticks && stop.is_none() {
                    stop = Some(StopReason::EncoderStalled { wheel: w });
                }
            }
            if stop.is_none() {
                // 5. Torque -> duty at each wheel's measured rate.
                torque = out.torque_nm;
                for i in 0..2 {
                    let req = self.motor.duty_for_torque(torque[i], sample.rate_radps[i]);
                    if req.saturated {
                        self.status.duty_saturated = self.status.duty_saturated.saturating_add(1);
                    }
                    let mut cmd = req.command;
                    if self.cfg.motor_inverted[i] && cmd.duty > 0 {
                        cmd.reverse = !cmd.reverse;
                    }
                    duty[i] = cmd;
                }
                motors.set(duty);
                enabled = true;
                self.last_torque_nm = torque;
                self.status.run_ticks = self.status.run_ticks.saturating_add(1);
            }
        }

        // 6. Safe stop.
        if let Some(r) = stop {
            self.latch(r);
        }
        if !enabled {
            self.last_torque_nm = [0.0; 2];
            motors.disable();
        }

        TickReport {
            state: self.status.state,
            stopped: stop,
            t_s,
            pose,
            odometry: self.odometry.pose(),
            external_pose,
            counts: sample,
            eta,
            reference,
            torque_nm: torque,
            duty,
            motors_enabled: enabled,
            diag,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::{Encoder, WheelOdometryOnly};
    use crate::trajectory::Line;

    #[derive(Clone, Copy, Default)]
    struct Enc(u16);
    impl Encoder for Enc {
        fn count(&mut self) -> u16 {
            self.0
        }
    }

    #[derive(Default)]
    struct Driver {
        enabled: bool,
        duty: [DutyCommand; 2],
        sets: u32,
        disables: u32,
    }
    impl MotorDriver for Driver {
        fn set(&mut self, cmd: [DutyCommand; 2]) {
            self.enabled = true;
            self.duty = cmd;
            self.sets += 1;
        }
        fn disable(&mut self) {
            self.enabled = false;
            self.duty = [DutyCommand::ZERO; 2];
            self.disables += 1;
        }
    }

    struct Ext(Option<Pose>);
    impl PoseSource for Ext {
        fn pose(&mut self) -> Option<Pose> {
            self.0
        }
    }

    /// A straight line from the origin along +x at `speed`.
    fn line_cfg(speed: f32) -> RuntimeConfig {
        let start = Pose::new(0.0, 0.0, 0.0);
        RuntimeConfig {
            reference: Reference::Line(Line {
                start,
                speed_mps: speed,
            }),
            initial_pose: start,
            ..RuntimeConfig::example(ControllerKind::Proposed)
        }
    }

    struct Rig {
        cl: ControlLoop,
        enc: [Enc; 2],
        drv: Driver,
    }

    impl Rig {
        fn new(cfg: RuntimeConfig) -> Self {
            Self {
                cl: ControlLoop::new(cfg).unwrap(),
                enc: [Enc(0); 2],
                drv: Driver::default(),
            }
        }
        fn tick(&mut self) -> TickReport {
            self.cl
                .tick(&mut self.enc, &mut self.drv, &mut WheelOdometryOnly, 1000)
        }
    }

    #[test]
    fn motors_disabled_until_armed() {
        let mut r = Rig::new(line_cfg(0.5));
        assert_eq!(r.cl.state(), RunState::Disarmed);
        for _ in 0..50 {
            let rep = r.tick();
            assert!(!rep.motors_enabled);
            assert_eq!(rep.torque_nm, [0.0; 2]);
        }
        assert_eq!(r.drv.sets, 0);
        assert_eq!(r.drv.disables, 50);
        assert_eq!(r.cl.status().run_ticks, 0);
        r.cl.arm().unwrap();
        let rep = r.tick();
        assert!(rep.motors_enabled && r.drv.enabled && r.drv.sets == 1);
        assert_eq!(rep.state, RunState::Running);
        // The reference lies ahead of the robot: it must push forward on both wheels.
        assert!(rep.torque_nm[0] > 0.0 && rep.torque_nm[1] > 0.0, "{rep:?}");
        // Left motor mirrored (motor_inverted = [false, true]): forward torque
        // at rest drives the left direction output in reverse.
        assert!(!r.drv.duty[0].reverse && r.drv.duty[1].reverse);
        assert!(r.drv.duty[0].duty > 0);
        // Disarm turns the outputs off and stops stepping.
        r.cl.disarm(&mut r.drv);
        assert!(!r.drv.enabled);
        assert!(!r.tick().motors_enabled);
    }

    /// Reference time is ticks since arming × period.
    #[test]
    fn reference_time_counts_from_arming() {
        let mut r = Rig::new(line_cfg(0.5));
        for _ in 0..10 {
            r.tick();
        }
        r.cl.arm().unwrap();
        let mut last = r.tick();
        assert_eq!(last.t_s, 0.0);
        for _ in 0..99 {
            last = r.tick();
        }
        assert!((last.t_s - 0.099).abs() < 1e-6);
        assert!((last.reference.pose.x_m - 0.5 * 0.099).abs() < 1e-5);
    }

    fn assert_latched(r: &mut Rig, reason: StopReason) {
        assert_eq!(r.cl.state(), RunState::Stopped(reason));
        assert!(!r.drv.enabled);
        let sets = r.drv.sets;
        for _ in 0..20 {
            let rep = r.tick();
            assert!(!rep.motors_enabled && rep.torque_nm == [0.0; 2]);
            assert_eq!(rep.state, RunState::Stopped(reason));
        }
        assert_eq!(r.drv.sets, sets, "driver written after the stop");
        assert_eq!(r.cl.arm(), Err(ArmError::Latched(reason)));
        r.cl.reset();
        assert_eq!(r.cl.state(), RunState::Disarmed);
        assert_eq!(r.cl.arm(), Ok(()));
    }

    #[test]
    fn nan_pose_latches_safe_stop() {
        let mut r = Rig::new(line_cfg(0.5));
        r.cl.arm().unwrap();
        for _ in 0..5 {
            r.tick();
        }
        let mut ext = Ext(Some(Pose::new(f32::NAN, 0.0, 0.0)));
        let rep = r.cl.tick(&mut r.enc, &mut r.drv, &mut ext, 1000);
        let reason = StopReason::ControllerInput(InputFault::NonFinitePose);
        assert_eq!(rep.stopped, Some(reason));
        assert!(!rep.motors_enabled);
        assert_eq!(r.cl.status().input_faults, 1);
        assert_eq!(r.cl.status().stops, 1);
        // The NaN did not poison the odometry.
        assert!(r.cl.odometry().is_finite());
        assert_latched(&mut r, reason);
    }

    #[test]
    fn isolated_input_faults_tolerated_when_configured() {
        let mut cfg = line_cfg(0.5);
        cfg.safety.max_consecutive_input_faults = 3;
        let mut r = Rig::new(cfg);
        r.cl.arm().unwrap();
        let mut bad = Ext(Some(Pose::new(0.0, f32::INFINITY, 0.0)));
        let mut good = Ext(Some(Pose::new(0.0, 0.0, 0.0)));
        for _ in 0..4 {
            for _ in 0..2 {
                let rep = r.cl.tick(&mut r.enc, &mut r.drv, &mut bad, 1000);
                assert!(rep.stopped.is_none());
                assert_eq!(rep.torque_nm, [0.0; 2]);
            }
            r.cl.tick(&mut r.enc, &mut r.drv, &mut good, 1000);
        }
        assert_eq!(r.cl.state(), RunState::Running);
        assert_eq!(r.cl.status().input_faults, 8);
        for k in 0..3 {
            let rep = r.cl.tick(&mut r.enc, &mut r.drv, &mut bad, 1000);
            assert_eq!(rep.stopped.is_some(), k == 2);
        }
        assert_latched(
            &mut r,
            StopReason::ControllerInput(InputFault::NonFinitePose),
        );
    }

    #[test]
    fn encoder_jump_latches_but_wrap_does_not() {
        let mut r = Rig::new(line_cfg(0.0));
        r.enc = [Enc(65_500), Enc(30)];
        r.cl.arm().unwrap();
        r.tick();
        // Right: 65500 -> 100 is +136 counts (wrap), left (mirrored): 30 -> 0 is +30.
        r.enc = [Enc(100), Enc(0)];
        let rep = r.tick();
        assert_eq!(rep.counts.delta, [136, 30]);
        assert!(rep.stopped.is_none());
        // 401 counts in one tick on the left wheel: beyond the 400 limit.
        r.enc[1].0 = r.enc[1].0.wrapping_sub(401);
        let rep = r.tick();
        let reason = StopReason::EncoderJump {
            wheel: Wheel::Left,
            delta: 401,
        };
        assert_eq!(rep.stopped, Some(reason));
        assert_eq!(r.cl.status().encoder_jumps, 1);
        assert_latched(&mut r, reason);
    }

    #[test]
    fn jump_while_disarmed_is_counted_not_latched_nor_integrated() {
        let mut r = Rig::new(line_cfg(0.0));
        r.tick();
        r.enc[0].0 = 20_000;
        let rep = r.tick();
        assert!(rep.stopped.is_none());
        assert_eq!(r.cl.state(), RunState::Disarmed);
        assert_eq!(r.cl.status().encoder_jumps, 1);
        assert_eq!(r.cl.odometry(), Pose::new(0.0, 0.0, 0.0));
    }

    /// Encoders frozen while the controller pushes hard: the stop latches
    /// exactly `stall_ticks` ticks after the first tick commanding at least
    /// the stall torque (each later tick sees that torque produce no count).
    #[test]
    fn stalled_encoder_latches() {
        let mut cfg = line_cfg(1.0);
        cfg.safety.stall_torque_nm = 0.5;
        cfg.safety.stall_ticks = 40;
        let mut r = Rig::new(cfg);
        r.cl.arm().unwrap();
        let mut first_high: Option<u32> = None;
        let mut stopped_at = None;
        for k in 0..2000u32 {
            let rep = r.tick();
            if let Some(reason) = rep.stopped {
                assert_eq!(
                    reason,
                    StopReason::EncoderStalled {
                        wheel: Wheel::Right
                    }
                );
                stopped_at = Some(k);
                break;
            }
            if rep.torque_nm[0].abs() >= 0.5 {
                first_high.get_or_insert(k);
            } else {
                assert!(first_high.is_none(), "torque dropped below the threshold");
            }
        }
        let first = first_high.expect("controller never pushed");
        assert_eq!(stopped_at, Some(first + 40));
        assert_latched(
            &mut r,
            StopReason::EncoderStalled {
                wheel: Wheel::Right,
            },
        );
    }

    /// The same push with wheels that turn (one count per tick) never stalls.
    #[test]
    fn moving_wheels_do_not_stall() {
        let mut cfg = line_cfg(1.0);
        cfg.safety.stall_torque_nm = 0.5;
        cfg.safety.stall_ticks = 40;
        let mut r = Rig::new(cfg);
        r.cl.arm().unwrap();
        for _ in 0..500 {
            r.enc[0].0 = r.enc[0].0.wrapping_add(1);
            r.enc[1].0 = r.enc[1].0.wrapping_sub(1);
            let rep = r.tick();
            assert!(rep.stopped.is_none());
        }
        assert_eq!(r.cl.state(), RunState::Running);
    }

    #[test]
    fn overruns_counted_and_latched_when_consecutive() {
        let mut r = Rig::new(line_cfg(0.0));
        r.cl.arm().unwrap();
        let t = |r: &mut Rig, us| {
            r.cl.tick(&mut r.enc, &mut r.drv, &mut WheelOdometryOnly, us)
        };
        // 4 overruns (limit 1500 µs, 5 in a row latch), then a normal tick.
        for _ in 0..4 {
            assert!(t(&mut r, 1501).stopped.is_none());
        }
        assert!(t(&mut r, 1500).stopped.is_none());
        assert_eq!(r.cl.status().overruns, 4);
        assert_eq!(r.cl.status().consecutive_overruns, 0);
        for k in 0..5 {
            let rep = t(&mut r, 3000);
            assert_eq!(rep.stopped.is_some(), k == 4);
        }
        assert_eq!(r.cl.status().overruns, 9);
        assert_eq!(r.cl.status().max_loop_time_us, 3000);
        assert_latched(&mut r, StopReason::LoopOverrun { loop_time_us: 3000 });
    }

    #[test]
    fn commanded_stop_latches() {
        let mut r = Rig::new(line_cfg(0.5));
        r.cl.arm().unwrap();
        r.tick();
        assert!(r.drv.enabled);
        r.cl.stop(&mut r.drv);
        assert!(!r.drv.enabled);
        assert_latched(&mut r, StopReason::Commanded);
    }

    /// Both encoders advance n counts per tick (left counter mirrored):
    /// v = r·2π·n/(cpr·dt), ω = 0, and G advances by v·t along the heading.
    #[test]
    fn encoder_ticks_give_analytic_speed_and_odometry() {
        let mut r = Rig::new(line_cfg(0.0));
        let n = 10u16;
        let ticks = 1000;
        let mut rep = r.tick();
        for _ in 0..ticks {
            r.enc[0].0 = r.enc[0].0.wrapping_add(n);
            r.enc[1].0 = r.enc[1].0.wrapping_sub(n);
            rep = r.tick();
        }
        let v = 0.1 * 2.0 * core::f32::consts::PI * n as f32 / (24_000.0 * 1e-3);
        assert!((rep.eta.v_mps - v).abs() < 1e-4 * v, "{:?}", rep.eta);
        assert!(rep.eta.omega_radps.abs() < 1e-6);
        let p = r.cl.odometry();
        assert!((p.x_m - v * ticks as f32 * 1e-3).abs() < 1e-4, "{p:?}");
        assert!(p.y_m.abs() < 1e-6 && p.theta_rad.abs() < 1e-6);
    }

    #[test]
    fn external_pose_used_and_reanchors_odometry() {
        let mut r = Rig::new(line_cfg(0.5));
        r.cl.arm().unwrap();
        let p = Pose::new(0.3, -0.2, 0.1);
        let rep = r.cl.tick(&mut r.enc, &mut r.drv, &mut Ext(Some(p)), 1000);
        assert!(rep.external_pose);
        assert_eq!(rep.pose, p);
        let o = r.cl.odometry();
        assert!((o.x_m - p.x_m).abs() < 1e-6 && (o.y_m - p.y_m).abs() < 1e-6);
        assert_eq!(r.cl.status().external_poses, 1);
    }

    #[test]
    fn invalid_config_rejected() {
        let mut cfg = line_cfg(0.5);
        cfg.safety.stall_ticks = 0;
        assert_eq!(
            ControlLoop::new(cfg).err(),
            Some(RuntimeConfigError::InvalidSafetyLimit)
        );
        let mut cfg = line_cfg(0.5);
        cfg.initial_pose.x_m = f32::NAN;
        assert_eq!(
            ControlLoop::new(cfg).err(),
            Some(RuntimeConfigError::NonFiniteInitialPose)
        );
        let mut cfg = line_cfg(0.5);
        cfg.controller.period_s = 0.0;
        assert_eq!(
            ControlLoop::new(cfg).err(),
            Some(RuntimeConfigError::Core(crate::ConfigError::InvalidPeriod))
        );
        let mut cfg = line_cfg(0.5);
        cfg.motor.gear_efficiency = 0.0;
        assert_eq!(
            ControlLoop::new(cfg).err(),
            Some(RuntimeConfigError::InvalidGearEfficiency)
        );
    }
}
