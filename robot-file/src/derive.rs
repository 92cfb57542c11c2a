//! What the runtime, the simulator and the firmware take from a robot:
//! every derived value with its formula (book/src/explanation/robot-file.md, "Derived values").

use crate::error::{Reason, RobotError};
use crate::sections::Robot;
use controller_core::estimator::EstimatorConfig;
use controller_core::friction::FrictionModel;
use controller_core::health::HealthParams;
use controller_core::kinematic::DEFAULT_LARGE_ERROR_M;
use controller_core::pacer::PacingConfig;
use controller_core::runtime::{EncoderParams, MotorParams, RuntimeConfig, SafetyLimits};
use controller_core::trajectory::Reference;
use controller_core::{ControllerConfig, ControllerKind, RobotParams};

/// Control period the derivations assume \[s\]: the paper's 1 kHz
/// (`ControllerConfig::paper(..).period_s`).
pub const CONTROL_PERIOD_S: f32 = ControllerConfig::paper(ControllerKind::Proposed).period_s;
/// The encoder jump limit is the count change per tick at this multiple of
/// the no-load wheel speed (faster is no wheel: a glitch or a slipped count).
pub const JUMP_SPEED_FACTOR: f32 = 2.5;
/// The stall check arms at this fraction of the torque limit.
pub const STALL_TORQUE_FRACTION: f32 = 0.2;
/// A wheel pushing that hard without a count for this long is stalled \[s\].
pub const STALL_TIME_S: f32 = 0.25;
/// The direction check gives a verdict from this fraction of the torque
/// limit (D110; the paper robot's 10 N·m: 1 N·m, D74's example) ...
pub const DIRECTION_TORQUE_FRACTION: f32 = 0.1;
/// ... or from this multiple of the wheel's Coulomb friction, whichever is
/// larger (the model omits friction; it shifts the measurement by the
/// friction's acceleration: D109's midpoint must be clear of it).
pub const DIRECTION_FRICTION_FACTOR: f32 = 1.5;

/// The friction compensation's smoothing rate as a fraction of the wheel
/// rate at `limits.max_speed_mps` (D175): at 5 % of top speed it gives half
/// the Coulomb torque, at 50 % 91 % of it.
pub const FRICTION_SMOOTHING_FRACTION: f32 = 0.05;
/// The direction check's acceleration tolerance in quanta of the windowed
/// rate estimate over a block (one count per speed window, differenced
/// over a block): 3 quanta, 9.8 rad/s² for the paper robot's encoder
/// (D74's example 10 rad/s²), 89 rad/s² for the 2 kg robot's 1,320 counts
/// and 8-tick window (D110).
pub const DIRECTION_ACCEL_QUANTA: f32 = 3.0;
/// The direction check's block is lengthened (from `SafetyLimits::EXAMPLE`'s
/// 20 ticks) until its acceleration tolerance is at most this fraction of
/// the margin a miswired wheel's runaway equilibrium leaves, ½·W_ii × the
/// torque limit (`SafetyLimits::validate_direction`, D112): the 2 kg
/// robot's coarse encoder gets 48-tick blocks, a paper robot held to
/// 2 N·m 60-tick ones.
pub const DIRECTION_ACCEL_MARGIN_FRACTION: f32 = 0.4;
/// The longest block the derivation picks \[s\] (a slower check is no
/// check: the stall check's 0.25 s is shorter).
pub const DIRECTION_MAX_BLOCK_S: f32 = 0.25;

impl Robot {
    /// Mean wheel radius \[m\].
    pub fn mean_wheel_radius_m(&self) -> f32 {
        0.5 * (self.body.wheel_radius_m[0] + self.body.wheel_radius_m[1])
    }

    /// Stall torque at the wheel, η·N·k·V/R \[N·m\].
    pub fn stall_torque_nm(&self) -> f32 {
        let m = &self.motors;
        m.gear_efficiency * m.gear_ratio * m.torque_constant_nm_per_a * m.supply_voltage_v
            / m.resistance_ohm
    }

    /// No-load wheel speed, V/(k·N) \[rad/s\].
    pub fn no_load_wheel_speed_radps(&self) -> f32 {
        let m = &self.motors;
        m.supply_voltage_v / (m.torque_constant_nm_per_a * m.gear_ratio)
    }

    /// The speed the smaller wheel holds at `bridge.max_duty_fraction`
    /// against its friction \[m/s\]: the motor's torque at duty d and rate
    /// ω, τ_s·(d − ω/ω₀), equals c + b·ω at
    /// ω = (τ_s·d − c)/(τ_s/ω₀ + b), with τ_s the stall torque and ω₀ the
    /// no-load speed (both wheels; the slower counts).
    pub fn friction_limited_speed_mps(&self) -> f32 {
        let stall = self.stall_torque_nm();
        let w0 = self.no_load_wheel_speed_radps();
        let d = self.bridge.max_duty_fraction;
        let m = &self.motors;
        let [r0, r1] = self.body.wheel_radius_m;
        let wheel = |i: usize| {
            let w = (stall * d - m.coulomb_friction_nm[i])
                / (stall / w0 + m.viscous_friction_nms_per_rad[i]);
            w.max(0.0)
        };
        (r0 * wheel(0)).min(r1 * wheel(1))
    }

    /// No-load forward speed of the smaller wheel, r_min·V/(k·N) \[m/s\].
    pub fn no_load_speed_mps(&self) -> f32 {
        let [r0, r1] = self.body.wheel_radius_m;
        r0.min(r1) * self.no_load_wheel_speed_radps()
    }

    /// The controller's model: mean wheel radius, half track = track/2
    /// (per-wheel radii reach the runtime through the encoder scale, D60).
    pub fn robot_params(&self) -> RobotParams {
        let b = &self.body;
        RobotParams {
            mass_kg: b.mass_kg,
            inertia_kgm2: b.inertia_kgm2,
            wheel_inertia_kgm2: b.wheel_inertia_kgm2,
            wheel_radius_m: self.mean_wheel_radius_m(),
            half_track_m: 0.5 * b.track_m,
            com_offset_m: b.com_offset_m,
        }
    }

    /// The configuration of controller `kind`: the paper's for `kind` with
    /// this robot's model, torque limit and gains (its `[gains.<kind>]`
    /// section, or Table 2's).
    pub fn controller_config(&self, kind: ControllerKind) -> ControllerConfig {
        let mut c = ControllerConfig::paper(kind);
        c.robot = self.robot_params();
        c.torque_limit_nm = self.limits.torque_nm;
        c.friction = self.friction_model();
        self.gains.resolved(kind).apply(&mut c);
        c
    }

    /// The controller's friction model (eq. 7f, D175): the file's
    /// `motors.viscous_friction_nms_per_rad` and `motors.coulomb_friction_nm`,
    /// the Coulomb term smoothed over [`FRICTION_SMOOTHING_FRACTION`] of the
    /// wheel rate at `limits.max_speed_mps`.
    pub fn friction_model(&self) -> FrictionModel {
        let m = &self.motors;
        if m.coulomb_friction_nm == [0.0; 2] && m.viscous_friction_nms_per_rad == [0.0; 2] {
            return FrictionModel::NONE; // the paper's model (7), exactly
        }
        let top_wheel_rate_radps = self.limits.max_speed_mps / self.mean_wheel_radius_m();
        FrictionModel {
            viscous_nms_per_rad: m.viscous_friction_nms_per_rad,
            coulomb_nm: m.coulomb_friction_nm,
            smoothing_radps: FRICTION_SMOOTHING_FRACTION * top_wheel_rate_radps,
        }
    }

    /// The motor model's parameters for a PWM timer of `duty_full_scale`
    /// counts at 100 %.
    pub fn motor_params(&self, duty_full_scale: u16) -> MotorParams {
        let m = &self.motors;
        MotorParams {
            torque_constant_nm_per_a: m.torque_constant_nm_per_a,
            winding_resistance_ohm: m.resistance_ohm,
            gear_ratio: m.gear_ratio,
            gear_efficiency: m.gear_efficiency,
            supply_voltage_v: m.supply_voltage_v,
            max_duty_fraction: self.bridge.max_duty_fraction,
            duty_full_scale,
        }
    }

    /// The encoders' parameters; each wheel's radius reaches the runtime as
    /// its `radius_scale` r_i/r̄ (D60).
    pub fn encoder_params(&self) -> EncoderParams {
        let e = &self.encoders;
        let r = self.mean_wheel_radius_m();
        let [r0, r1] = self.body.wheel_radius_m;
        EncoderParams {
            counts_per_wheel_rev: e.counts_per_wheel_rev,
            inverted: e.inverted,
            speed_window_ticks: e.speed_window_ticks,
            radius_scale: [r0 / r, r1 / r],
        }
    }

    /// Encoder counts per control tick of `period_s` at wheel speed
    /// `wheel_speed_radps`: ω·T·cpr/(2π).
    pub fn counts_per_tick(&self, wheel_speed_radps: f32, period_s: f32) -> f32 {
        wheel_speed_radps * period_s * self.encoders.counts_per_wheel_rev
            / (2.0 * core::f32::consts::PI)
    }

    /// The runtime's safety thresholds for a control period `period_s`:
    /// - jump limit: counts per tick at [`JUMP_SPEED_FACTOR`] × the no-load
    ///   wheel speed, rounded up, at least 4, at most `i16::MAX`;
    /// - stall torque: [`STALL_TORQUE_FRACTION`] × `limits.torque_nm`;
    /// - stall ticks: [`STALL_TIME_S`] / period;
    /// - overrun limit: half a period;
    /// - consecutive overruns and input faults: `SafetyLimits::EXAMPLE`'s.
    pub fn safety_limits(&self, period_s: f32) -> SafetyLimits {
        let jump = self.counts_per_tick(
            JUMP_SPEED_FACTOR * self.no_load_wheel_speed_radps(),
            period_s,
        );
        let jump = libm::ceilf(jump).clamp(4.0, i16::MAX as f32) as u16;
        let stall_ticks = libm::roundf(STALL_TIME_S / period_s).clamp(1.0, u16::MAX as f32) as u16;
        let overrun = libm::roundf(0.5 * period_s * 1e6).max(1.0) as u32;
        let e = SafetyLimits::EXAMPLE;
        let friction = self.motors.coulomb_friction_nm[0].max(self.motors.coulomb_friction_nm[1]);
        let limit = self.limits.torque_nm;
        let (block_ticks, accel) = self.direction_block(period_s);
        SafetyLimits {
            max_counts_per_tick: jump,
            stall_torque_nm: STALL_TORQUE_FRACTION * limit,
            stall_ticks,
            overrun_limit_us: overrun,
            // At most half the limit (validate_direction's bound): a robot
            // whose friction is above a third of its limit gets a check
            // whose midpoint is less clear of friction.
            direction_torque_nm: (DIRECTION_TORQUE_FRACTION * limit)
                .max(DIRECTION_FRICTION_FACTOR * friction)
                .min(0.5 * limit),
            direction_accel_radps2: accel,
            direction_block_ticks: block_ticks,
            ..e
        }
    }

    /// The direction check's block \[ticks\] and acceleration tolerance
    /// \[rad/s²\] for a control period `period_s`: the tolerance is
    /// [`DIRECTION_ACCEL_QUANTA`] quanta of the windowed rate estimate over
    /// a block, and the block the shortest from `SafetyLimits::EXAMPLE`'s
    /// (20 ticks) up to [`DIRECTION_MAX_BLOCK_S`] for which that is at most
    /// [`DIRECTION_ACCEL_MARGIN_FRACTION`] × ½·W_ii·`limits.torque_nm`
    /// (W_ii: eq. 7's own-wheel acceleration per N·m, the controller's model).
    pub fn direction_block(&self, period_s: f32) -> (u16, f32) {
        let q = self.rate_quantum_radps(period_s);
        let min = SafetyLimits::EXAMPLE.direction_block_ticks as f32;
        let max = libm::floorf(DIRECTION_MAX_BLOCK_S / period_s).max(min);
        let ticks = match controller_core::model::ReducedModel::new(&self.robot_params()) {
            Ok(m) => {
                let w = m.wheel_accel_map();
                let margin = 0.5 * w[0][0].min(w[1][1]) * self.limits.torque_nm;
                let want = DIRECTION_ACCEL_QUANTA * q
                    / (DIRECTION_ACCEL_MARGIN_FRACTION * margin * period_s);
                libm::ceilf(want).clamp(min, max)
            }
            Err(_) => min,
        };
        (
            ticks as u16,
            DIRECTION_ACCEL_QUANTA * q / (ticks * period_s),
        )
    }

    /// The windowed wheel-rate estimate's resolution \[rad/s\]: one count of
    /// the coarser wheel (the larger radius scale) per speed window
    /// (`encoders.speed_window_ticks` periods of `period_s`): the runtime's
    /// own definition ([`EncoderParams::rate_quantum_radps`]), the one its
    /// validation of the derived thresholds uses.
    pub fn rate_quantum_radps(&self, period_s: f32) -> f32 {
        self.encoder_params().rate_quantum_radps(period_s)
    }

    /// The PWM timer's counts at 100 % duty for this robot's
    /// `bridge.pwm_frequency_hz` on a timer clocked at `timer_clock_hz`
    /// (`BridgeParams::duty_full_scale`); an error naming
    /// `bridge.pwm_frequency_hz` when that is outside 100..=65,535 levels.
    pub fn pwm_full_scale(&self, timer_clock_hz: u32) -> Result<u16, RobotError> {
        self.bridge
            .params()
            .duty_full_scale(timer_clock_hz)
            .ok_or(RobotError::new(
                "bridge.pwm_frequency_hz",
                Reason::Inconsistent {
                    with: "the board's timer clock",
                    why: "duty resolution outside 100..=65535 levels",
                },
            ))
    }

    /// The one derivation (D139): everything the runtime takes from this
    /// robot on `board`, following `reference` (a run's, not a robot
    /// value; the firmware's placeholder until the host loads one).
    ///
    /// - the controller `control.controller` with this robot's model,
    ///   torque limit and gains ([`Self::controller_config`]) at the
    ///   board's control period; with `control.clean_start` the
    ///   large-error bound of D23 ([`DEFAULT_LARGE_ERROR_M`]) where the
    ///   gains leave it unbounded as printed, without it eq. (14) as
    ///   printed;
    /// - the start pose `control.initial_*`, the encoders, motors (at the
    ///   board's PWM resolution), motor directions, the safety limits for
    ///   the period ([`Self::safety_limits`]) and pacing
    ///   (`control.governor`; the health machine's position-error
    ///   thresholds at the robot's `limits.max_speed_mps`,
    ///   [`health_for_speed`]);
    /// - the pose estimator's tuning: controller-core's example with the
    ///   file's `[estimator]` noises and the board's gyro saturation.
    ///
    /// Nothing else builds a `RuntimeConfig` from robot values: the
    /// firmware, firmware-emu, hil-sim (which first edits a copy of the
    /// robot with the scenario's overrides), the simulated device, wmr and
    /// bench-m4 call this. It does not validate: a robot read with
    /// [`Robot::decode`] or `from_toml_str` is valid, an edited one is
    /// checked with [`Robot::validate`]; `ControlLoop::new` checks the
    /// result again.
    pub fn derive(&self, board: &BoardFacts, reference: Reference) -> Derived {
        let kind = self.control.controller;
        let mut controller = self.controller_config(kind);
        controller.period_s = board.control_period_s;
        let printed = ControllerConfig::paper(kind).kinematic.large_error_m;
        controller.kinematic.large_error_m = match self.control.clean_start {
            false => printed,
            true if controller.kinematic.large_error_m == printed => DEFAULT_LARGE_ERROR_M,
            true => controller.kinematic.large_error_m,
        };
        let runtime = RuntimeConfig {
            controller,
            reference,
            initial_pose: self.control.initial_pose(),
            encoder: self.encoder_params(),
            motor: self.motor_params(board.pwm_full_scale),
            motor_inverted: self.bridge.motor_inverted,
            safety: self.safety_limits(board.control_period_s),
            pacing: {
                let mut p = match self.control.governor {
                    true => PacingConfig::on(),
                    false => PacingConfig::off(),
                };
                p.health = health_for_speed(p.health, self.limits.max_speed_mps);
                p
            },
        };
        let mut estimator = EstimatorConfig::EXAMPLE;
        self.estimator.apply(&mut estimator);
        if let Some(s) = board.gyro_saturation_radps {
            estimator.gyro_saturation_radps = s;
        }
        Derived { runtime, estimator }
    }
}

/// The speed limit controller-core's default health thresholds
/// (`HealthParams::DEFAULT`: 0.3 m degraded, 0.2 m acquired, 2 m lost) are
/// for: the paper robot's `limits.max_speed_mps` \[m/s\].
pub const HEALTH_DEFAULT_SPEED_MPS: f32 = 1.0;

/// `health` with its position-error thresholds scaled to a robot whose
/// speed limit is `max_speed_mps`: the distance it covers at that speed in
/// the time the robot of [`HEALTH_DEFAULT_SPEED_MPS`] covers the default's
/// (0.3 s degraded, 0.2 s acquired, 2 s lost; issue 34, D206: a robot
/// tracking within its limits is nominal, and a slow one no longer lags its
/// reference by seconds before any check notices). Computed once when the
/// configuration is derived; the monitor squares them when it is built, so
/// the tick is unchanged. Not inlined: inlined into bench-m4's
/// `run_tick` (which derives the configuration, then runs the ticks) it
/// moved the M4F typical tick's max from 2,996 to 3,036 instructions, over
/// the 3,000 budget, with the same thresholds (measured).
#[inline(never)]
pub fn health_for_speed(health: HealthParams, max_speed_mps: f32) -> HealthParams {
    let scale = max_speed_mps / HEALTH_DEFAULT_SPEED_MPS;
    HealthParams {
        error_degraded_m: health.error_degraded_m * scale,
        acquired_m: health.acquired_m * scale,
        lost_path_m: health.lost_path_m * scale,
        ..health
    }
}

/// What a derivation needs from the board (or the simulated one) that a
/// robot file cannot know.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardFacts {
    /// PWM timer counts at 100 % duty (read back from the timer;
    /// [`Robot::pwm_full_scale`] for a timer clock).
    pub pwm_full_scale: u16,
    /// Control period \[s\] (the firmware's 1 kHz loop: [`CONTROL_PERIOD_S`]).
    pub control_period_s: f32,
    /// Where the board's gyro clips \[rad/s\] (a reading there is not
    /// trusted); `None`: the estimator example's.
    pub gyro_saturation_radps: Option<f32>,
}

impl BoardFacts {
    /// A board whose PWM timer runs at `timer_clock_hz`, at the paper's
    /// 1 kHz ([`CONTROL_PERIOD_S`]), without a gyro saturation of its own.
    pub fn of_timer(robot: &Robot, timer_clock_hz: u32) -> Result<Self, RobotError> {
        Ok(Self {
            pwm_full_scale: robot.pwm_full_scale(timer_clock_hz)?,
            control_period_s: CONTROL_PERIOD_S,
            gyro_saturation_radps: None,
        })
    }
}

/// Everything a robot gives the runtime ([`Robot::derive`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Derived {
    /// The runtime's configuration (controller, reference, start pose,
    /// encoders, motors, safety limits, pacing).
    pub runtime: RuntimeConfig,
    /// The pose estimator's tuning.
    pub estimator: EstimatorConfig,
}
