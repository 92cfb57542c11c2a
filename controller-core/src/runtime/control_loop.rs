//! The control loop and its safety supervisor: one [`ControlLoop::tick`] per
//! control period, from raw encoder counts to motor duty.

use super::config::{RuntimeConfig, SafetyLimits};
use super::direction::{DirectionCheck, Prediction};
use super::encoder::{CountSample, WheelCounts};
use super::error::RuntimeConfigError;
use super::hardware::Wheel;
use super::hardware::{Gyro, MotorDriver, PoseSource, WheelEncoders, MAX_POSES_PER_TICK};
use super::motor::{DutyCommand, MotorModel};
use super::state::{ArmError, ReconfigureError, RunState, Status, StopReason, TickReport};
use super::timing::TickTiming;
use crate::controller::{Controller, ControllerConfig, Diagnostics, StepInput};
use crate::estimator::{EstimatorConfig, EstimatorStatus, PoseEstimator, HISTORY_LEN};
use crate::health::HealthMode;
use crate::pacer::{Pacer, PacerState};
use crate::trajectory::Trajectory;
use crate::types::Pose;

/// History ticks the estimator re-propagates per tick after a late pose
/// measurement (the rest in later ticks, [`PoseEstimator::correct_within`]):
/// bounds a tick's cost on a small MCU (about 400 Cortex-M4F instructions
/// per tick re-propagated, BENCHMARKS.md). A correction 250 ticks late
/// takes effect 11 ticks later; one 10 ticks late (motion capture) at once.
pub const MAX_REPROPAGATION_PER_TICK: usize = 24;

/// The runtime: encoders, pose estimator, controller, motor model and
/// supervisor. `H` is the estimator's history in ticks (the oldest usable
/// pose measurement; 104 bytes per tick): [`HISTORY_LEN`] by default, 1
/// for a robot without an external pose source.
#[derive(Clone, Debug)]
pub struct ControlLoop<const H: usize = HISTORY_LEN> {
    cfg: RuntimeConfig,
    controller: Controller,
    motor: MotorModel,
    counts: WheelCounts,
    estimator: PoseEstimator<H>,
    status: Status,
    stall_ticks: [u16; 2],
    consecutive_input_faults: u16,
    /// The torque delivered during the tick now elapsing \[N·m\]: the
    /// commanded one, or the clamped duty's where the duty saturated.
    last_torque_nm: [f32; 2],
    /// The torque the step may command \[N·m\]: [`MotorModel::torque_bound_nm`]
    /// at the rate resolution `bound_quantum_radps` (recomputed when the
    /// resolution changes: while the window fills, after a late tick; NaN
    /// forces it).
    bound_nm: f32,
    bound_quantum_radps: f32,
    direction: DirectionCheck,
    /// Eq. (7) to wheel accelerations for the direction check (from the
    /// controller's model; rebuilt by [`Self::reconfigure`]).
    prediction: Prediction,
    pacer: Pacer,
    pace: PacerState,
}

impl ControlLoop {
    /// Validates `cfg` and builds a disarmed loop with the example pose
    /// estimator tuning ([`EstimatorConfig::EXAMPLE`]) and [`HISTORY_LEN`]
    /// ticks of history.
    pub fn new(cfg: RuntimeConfig) -> Result<Self, RuntimeConfigError> {
        Self::with_estimator(cfg, EstimatorConfig::EXAMPLE)
    }
}

impl<const H: usize> ControlLoop<H> {
    /// Validates `cfg` and `estimator` (the estimator's tuning) and builds
    /// a disarmed loop. The estimator starts at `cfg.initial_pose` with the
    /// controller's robot geometry (`cfg.controller.robot.com_offset_m`):
    /// the runtime configuration is the one description of both.
    pub fn with_estimator(
        cfg: RuntimeConfig,
        estimator: EstimatorConfig,
    ) -> Result<Self, RuntimeConfigError> {
        let controller = Controller::new(cfg.controller)?;
        cfg.reference.validate()?;
        if !cfg.initial_pose.is_finite() {
            return Err(RuntimeConfigError::NonFiniteInitialPose);
        }
        let motor = MotorModel::new(cfg.motor)?;
        let counts = WheelCounts::new(cfg.encoder)?;
        validate_direction(&cfg.safety, &controller, &cfg.encoder)?;
        let prediction = Prediction::new(
            controller.model(),
            &motor,
            &cfg.safety,
            cfg.controller.period_s,
        );
        let pacer = Pacer::new(cfg.pacing, &cfg.controller)?;
        let estimator = PoseEstimator::with_history(
            estimator,
            cfg.controller.robot.com_offset_m,
            cfg.initial_pose,
        )?;
        Ok(Self {
            pace: pacer.initial_state(),
            pacer,
            cfg,
            controller,
            motor,
            counts,
            estimator,
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
                torque_bounded: 0,
                external_poses: 0,
                stops: 0,
            },
            stall_ticks: [0; 2],
            consecutive_input_faults: 0,
            last_torque_nm: [0.0; 2],
            bound_nm: 0.0,
            bound_quantum_radps: f32::NAN,
            direction: DirectionCheck::default(),
            prediction,
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

    /// Re-anchors the pose: the estimator restarts at `pose` with its
    /// configured initial pose uncertainty (history dropped; its counters,
    /// and the gyro bias and speed scale it learned, kept). Refused while
    /// running or for a non-finite pose.
    pub fn set_pose(&mut self, pose: Pose) -> Result<(), ReconfigureError> {
        if self.running() {
            return Err(ReconfigureError::Running);
        }
        let counters = self.estimator.status();
        let mut anchored = PoseEstimator::with_history(
            *self.estimator.config(),
            self.cfg.controller.robot.com_offset_m,
            pose,
        )
        .map_err(|e| ReconfigureError::Invalid(e.into()))?;
        anchored.keep_counters(&counters);
        anchored.keep_calibration(&self.estimator);
        self.estimator = anchored;
        Ok(())
    }

    /// Reference time \[s\] the next tick samples its reference at: the
    /// governed time τ with pacing on, ticks since arming × period without.
    /// A caller that computes the reference itself (the host link) samples
    /// it here and passes it to [`Self::tick_with_reference`], so the
    /// governor's time scaling applies to it too.
    pub fn reference_time_s(&self) -> f32 {
        if self.cfg.pacing.enabled {
            self.pacer.status(&self.pace).tau_s
        } else {
            self.status.run_ticks as f32 * self.cfg.controller.period_s
        }
    }

    /// The pose estimator (its estimate, covariance and configuration).
    pub fn estimator(&self) -> &PoseEstimator<H> {
        &self.estimator
    }

    /// The estimator's status: covariance, innovations, accepted and
    /// rejected measurements, gyro state and bias.
    pub fn estimator_status(&self) -> EstimatorStatus {
        self.estimator.status()
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
                self.direction = DirectionCheck::start(self.counts.last_rate_radps());
                self.pace = self.pacer.initial_state();
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

    /// Replaces the controller configuration (gains, torque limit) and the
    /// safety limits, validated; refused while running. The controller
    /// restarts from its initial state; odometry and counters are kept.
    pub fn reconfigure(
        &mut self,
        controller: ControllerConfig,
        safety: SafetyLimits,
    ) -> Result<(), ReconfigureError> {
        if self.running() {
            return Err(ReconfigureError::Running);
        }
        let invalid = |e| ReconfigureError::Invalid(RuntimeConfigError::Core(e));
        let new = Controller::new(controller).map_err(invalid)?;
        // The pacer's saturation and health thresholds follow the gains and limit.
        let pacer = Pacer::new(self.cfg.pacing, &controller).map_err(invalid)?;
        validate_direction(&safety, &new, &self.cfg.encoder).map_err(ReconfigureError::Invalid)?;
        self.prediction = Prediction::new(new.model(), &self.motor, &safety, controller.period_s);
        self.controller = new;
        self.pace = pacer.initial_state();
        self.pacer = pacer;
        self.cfg.controller = controller;
        self.cfg.safety = safety;
        self.bound_quantum_radps = f32::NAN; // the limit may have changed
        Ok(())
    }

    fn latch(&mut self, reason: StopReason) {
        self.status.state = RunState::Stopped(reason);
        self.status.stops = self.status.stops.saturating_add(1);
        self.last_torque_nm = [0.0; 2];
    }

    fn running(&self) -> bool {
        self.status.state == RunState::Running
    }

    /// One control period. `timing` is this tick's measurement by the
    /// loop's [`LoopTimer`](super::LoopTimer): its true elapsed time feeds
    /// the wheel-rate estimate and scales the encoder-jump limit, its
    /// lateness against the schedule drives the overrun check, and its
    /// `now_us` is the robot time that gyro samples and pose measurements
    /// are matched against. `gyro` ([`NoGyro`](super::NoGyro)) and
    /// `pose_source` ([`WheelOdometryOnly`](super::WheelOdometryOnly)) may
    /// be absent: the loop runs on the wheels alone.
    ///
    /// Never panics; on any safety violation while running it latches a
    /// stop, disables `motors` and reports the reason in
    /// [`TickReport::stopped`].
    pub fn tick(
        &mut self,
        encoders: &mut impl WheelEncoders,
        motors: &mut impl MotorDriver,
        gyro: &mut impl Gyro,
        pose_source: &mut impl PoseSource,
        timing: TickTiming,
    ) -> TickReport {
        let reference = self.cfg.reference;
        self.tick_with_reference(encoders, motors, gyro, pose_source, timing, &reference)
    }

    /// [`Self::tick`] tracking `reference` (sampled at the same reference
    /// time) instead of the configured one: for references that are not a
    /// compiled-in [`Reference`](crate::trajectory::Reference), such as an
    /// uploaded trajectory or a velocity command (the host link).
    pub fn tick_with_reference(
        &mut self,
        encoders: &mut impl WheelEncoders,
        motors: &mut impl MotorDriver,
        gyro: &mut impl Gyro,
        pose_source: &mut impl PoseSource,
        timing: TickTiming,
        reference: &impl Trajectory,
    ) -> TickReport {
        self.status.ticks = self.status.ticks.wrapping_add(1);
        // 1. Loop timing, 2. encoders: the first violation found wins.
        let mut stop = self.check_timing(&timing);
        let (sample, jump) = self.read_wheels(encoders, &timing);
        stop = stop.or(jump);
        let eta = self
            .cfg
            .controller
            .robot
            .eta_from_wheel_rates(sample.rate_radps);
        // 3. Pose: the estimator's fusion of wheels, gyro and external poses.
        let (pose, external_pose) = self.measure_pose(sample.dphi_rad, gyro, pose_source, &timing);
        // 4. Reference and controller, 5. torque -> duty.
        let t_s = self.status.run_ticks as f32 * self.cfg.controller.period_s;
        // The step's input built in place (the reference sampled into it).
        let input = StepInput {
            reference: self.pacer.reference(&self.pace, reference, t_s),
            pose,
            eta,
        };
        let mut torque = [0.0f32; 2];
        let mut duty = [DutyCommand::ZERO; 2];
        let mut enabled = false;
        // The step's output is written in place (no copy of its diagnostics).
        let out = if self.running() && stop.is_none() {
            Some(self.controller.step(&input))
        } else {
            None
        };
        if let Some(step) = &out {
            stop = self
                .supervise_step(&step.diag)
                .or(self.check_stall(&sample))
                .or(self.direction.update(
                    &self.prediction,
                    self.status.run_ticks,
                    [eta.v_mps, eta.omega_radps],
                    self.last_torque_nm,
                    sample.rate_radps,
                ));
            if stop.is_none() {
                torque = step.torque_nm;
            }
        }
        // Governor and health (crate::pacer) after a step: a hard fault stops.
        let pace = match &out {
            Some(step) => {
                let pace =
                    self.pacer
                        .update(&mut self.pace, &step.diag, eta, self.estimator.health());
                if pace.mode == HealthMode::SafeStop {
                    stop = stop.or(Some(StopReason::Health(pace.reason)));
                }
                pace
            }
            None => self.pacer.status(&self.pace),
        };
        if out.is_some() && stop.is_none() {
            // The delivered torque (`duty_for` bounds it and replaces a
            // clamped wheel's).
            self.last_torque_nm = torque;
            duty = self.duty_for(&mut torque, &sample);
            motors.set(duty);
            enabled = true;
            self.status.run_ticks = self.status.run_ticks.saturating_add(1);
        } else {
            torque = [0.0; 2];
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
            external_pose,
            estimate: *self.estimator.estimate(),
            gyro: self.estimator.gyro_state(),
            counts: sample,
            eta,
            reference: input.reference,
            torque_nm: torque,
            duty,
            motors_enabled: enabled,
            diag: match out {
                Some(step) => step.diag,
                None => Diagnostics::default(),
            },
            pace,
        }
    }

    /// Step 1: overrun accounting from the [`LoopTimer`](super::LoopTimer)'s
    /// measurement; a sustained overrun while running stops.
    fn check_timing(&mut self, timing: &TickTiming) -> Option<StopReason> {
        let st = &mut self.status;
        st.max_loop_time_us = st.max_loop_time_us.max(timing.elapsed_us);
        st.overruns = st.overruns.saturating_add(timing.new_overrun as u32);
        st.consecutive_overruns = timing.consecutive_late;
        (st.state == RunState::Running && timing.sustained_overrun).then_some(
            StopReason::LoopOverrun {
                lateness_us: timing.lateness_us,
            },
        )
    }

    /// Step 2: encoder counts to deltas and rates over the true elapsed time.
    /// An implausible jump (beyond `max_counts_per_tick` per elapsed period)
    /// is counted, resynchronised and not integrated; while running it stops.
    fn read_wheels(
        &mut self,
        encoders: &mut impl WheelEncoders,
        timing: &TickTiming,
    ) -> (CountSample, Option<StopReason>) {
        let raw = encoders.counts();
        let delta = self.counts.peek_delta(raw);
        let limit = (self.cfg.safety.max_counts_per_tick as u32)
            .saturating_mul(timing.elapsed_periods)
            .min(i16::MAX as u32) as i32;
        let jump = Wheel::BOTH
            .into_iter()
            .find(|w| delta[w.index()].abs() > limit);
        match jump {
            Some(wheel) => {
                self.status.encoder_jumps = self.status.encoder_jumps.saturating_add(1);
                self.counts.resync(raw);
                let stop = self.running().then_some(StopReason::EncoderJump {
                    wheel,
                    delta: delta[wheel.index()],
                });
                (CountSample::default(), stop)
            }
            None => (self.counts.apply(raw, delta, timing.elapsed_s()), None),
        }
    }

    /// Step 3: the estimator predicts from this tick's wheel increments
    /// and the gyro, then takes up to [`MAX_POSES_PER_TICK`] measurements
    /// from the pose source (late ones are re-propagated to now, at most
    /// [`MAX_REPROPAGATION_PER_TICK`] ticks of history per tick). No plain
    /// odometry runs beside it (D32: without a gyro and external poses the
    /// estimate is wheel odometry). Returns the fused pose of G and whether a
    /// measurement was accepted. The controller's η stays the wheel-derived
    /// one (D26).
    fn measure_pose(
        &mut self,
        dphi_rad: [f32; 2],
        gyro: &mut impl Gyro,
        pose_source: &mut impl PoseSource,
        timing: &TickTiming,
    ) -> (Pose, bool) {
        let inc = self.cfg.controller.robot.eta_from_wheel_rates(dphi_rad);
        self.estimator.predict(
            timing.now_us,
            timing.elapsed_s(),
            inc.v_mps,
            inc.omega_radps,
            gyro.sample(),
        );
        // A pending re-propagation goes on; new measurements wait in the
        // source until it is done.
        let mut used = self.estimator.resume(MAX_REPROPAGATION_PER_TICK);
        let mut accepted = false;
        for _ in 0..MAX_POSES_PER_TICK {
            if self.estimator.is_repropagating() {
                break;
            }
            let Some(m) = pose_source.measurement() else {
                break;
            };
            let budget = MAX_REPROPAGATION_PER_TICK.saturating_sub(used);
            if let Ok(n) = self.estimator.correct_within(&m, budget) {
                used += n;
                accepted = true;
                self.status.external_poses = self.status.external_poses.saturating_add(1);
            }
        }
        (self.estimator.estimate().pose, accepted)
    }

    /// Step 4 supervision: input faults (latching after
    /// `max_consecutive_input_faults`) and saturation counting.
    fn supervise_step(&mut self, diag: &Diagnostics) -> Option<StopReason> {
        if diag.saturated {
            self.status.torque_saturated = self.status.torque_saturated.saturating_add(1);
        }
        match diag.fault {
            Some(f) => {
                self.status.input_faults = self.status.input_faults.saturating_add(1);
                self.consecutive_input_faults = self.consecutive_input_faults.saturating_add(1);
                (self.consecutive_input_faults >= self.cfg.safety.max_consecutive_input_faults)
                    .then_some(StopReason::ControllerInput(f))
            }
            None => {
                self.consecutive_input_faults = 0;
                None
            }
        }
    }

    /// Stall: the torque applied during the elapsed tick moved nothing, for
    /// `stall_ticks` in a row (both wheels counted; the first reported).
    fn check_stall(&mut self, sample: &CountSample) -> Option<StopReason> {
        let safety = &self.cfg.safety;
        let mut stop = None;
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
        stop
    }

    /// The torque to command so that what the motor *delivers* (its
    /// current) stays within the torque limit although the duty is computed
    /// at an estimated rate ([`MotorModel::torque_bound_nm`] at the
    /// estimate's resolution this tick; D176).
    fn torque_bound_nm(&mut self, rate_quantum_radps: f32) -> f32 {
        if rate_quantum_radps != self.bound_quantum_radps {
            self.bound_quantum_radps = rate_quantum_radps;
            self.bound_nm = self
                .motor
                .torque_bound_nm(self.cfg.controller.torque_limit_nm, rate_quantum_radps);
        }
        self.bound_nm
    }

    /// Step 5: torque to duty and direction at each wheel's measured rate
    /// (the motor model's inverse), flipped for mirrored motors. Where the
    /// duty clamps, `last_torque_nm` becomes the torque the clamped duty
    /// delivers at that rate by the same model (b_V·V_supply·duty − b·φ̇):
    /// what the stall and direction checks judge the wheel on (D111).
    ///
    /// First the torque is scaled (both wheels by one factor, the steering
    /// kept, as [`crate::controller::saturate`] does) to at most
    /// [`Self::torque_bound_nm`], so that the delivered torque stays within
    /// the limit (D176; the controller's ESO and anti-windup see the torque
    /// before this scaling, which differs only while the rate window fills
    /// after a start, by at most b·δ).
    fn duty_for(&mut self, torque_nm: &mut [f32; 2], sample: &CountSample) -> [DutyCommand; 2] {
        let bound = self.torque_bound_nm(sample.rate_quantum_radps);
        let (t0, t1) = (torque_nm[0].abs(), torque_nm[1].abs());
        let peak = if t0 > t1 { t0 } else { t1 };
        if peak > bound {
            self.status.torque_bounded = self.status.torque_bounded.saturating_add(1);
            let k = bound / peak;
            *torque_nm = [torque_nm[0] * k, torque_nm[1] * k];
            self.last_torque_nm = *torque_nm;
        }
        let torque_nm = *torque_nm;
        core::array::from_fn(|i| {
            let rate = sample.rate_radps[i];
            let req = self.motor.duty_for_torque(torque_nm[i], rate);
            if req.saturated {
                self.status.duty_saturated = self.status.duty_saturated.saturating_add(1);
                self.last_torque_nm[i] = self.motor.torque_for_duty(req.command, rate);
            }
            let mut cmd = req.command;
            if self.cfg.motor_inverted[i] && cmd.duty > 0 {
                cmd.reverse = !cmd.reverse;
            }
            cmd
        })
    }
}

/// [`SafetyLimits::validate_direction`] for the controller's model, torque
/// limit and period and the encoders' rate-estimate quantum (the coarser
/// wheel's count over one speed window).
fn validate_direction(
    safety: &SafetyLimits,
    controller: &Controller,
    encoder: &super::encoder::EncoderParams,
) -> Result<SafetyLimits, RuntimeConfigError> {
    let c = controller.config();
    let w = controller.model().wheel_accel_map();
    let quantum = encoder.rate_quantum_radps(c.period_s);
    safety.validate_direction(c.torque_limit_nm, w[0][0].min(w[1][1]), quantum, c.period_s)
}

#[cfg(test)]
#[path = "control_loop_tests.rs"]
mod tests;
