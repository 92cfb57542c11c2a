//! Robot, motor, encoder and safety constants: the one place to set them for
//! your robot. Units are SI and named in the field names; the types document
//! every field (`controller_core::RobotParams`,
//! `controller_core::runtime::{MotorParams, EncoderParams, SafetyLimits}`).
//!
//! A leaf: it names nothing of this crate (board, IMU driver, log), only
//! library types, so `firmware-emu` compiles it unchanged (`#[path]`) and
//! supplies its own board. What depends on the chip (its handshake name)
//! is a parameter ([`device`]).

use controller_core::controller::{DEFAULT_K_Y, DEFAULT_TORQUE_LIMIT_NM};
use controller_core::eso::EsoParams;
use controller_core::estimator::EstimatorConfig;
use controller_core::fault_observer::FaultObserverGains;
use controller_core::kinematic::{KinematicGains, DEFAULT_LARGE_ERROR_M};
use controller_core::pacer::PacingConfig;
use controller_core::runtime::{
    BridgeMode, BridgeParams, EncoderParams, MotorParams, RuntimeConfig, SafetyLimits,
    MIRRORED_LEFT,
};
use controller_core::trajectory::{PaperCurve, PaperHeading, Reference};
use controller_core::{ControllerConfig, ControllerKind, InputLimits, RobotParams};
use wmr_device::{DeviceConfig, LinkConfig};
use wmr_protocol::BuiltinReference;

/// Control loop rate \[Hz\] (the controller's `period_s` is its inverse).
pub const CONTROL_HZ: u64 = 1000;
/// Watchdog timeout \[µs\]; the control task feeds it at the end of every
/// completed tick (robot-app), so a loop stalled this long resets the chip.
pub const WATCHDOG_TIMEOUT_US: u32 = 50_000;
/// Local telemetry lines every this many ticks (50 -> 20 Hz at 1 kHz;
/// `rtt-telemetry` only).
pub const TELEMETRY_DECIMATION: u32 = 50;
/// Button debounce \[ticks\]: held this long counts as one press
/// (`controller_core::runtime::ArmingButton`).
pub const BUTTON_DEBOUNCE_TICKS: u16 = 20;

/// Which of the paper's controllers runs.
pub const CONTROLLER: ControllerKind = ControllerKind::Proposed;

/// Per-wheel torque limit \[N·m\] the controller saturates at:
/// controller-core's default (the paper gives none, DECISIONS D14). Set it
/// to what your motors and gearboxes can deliver.
pub const TORQUE_LIMIT_NM: f32 = DEFAULT_TORQUE_LIMIT_NM;

/// Kinematic-loop gains, eq. (14): Table 2's k_x = 1.2, k_th = 5 with
/// controller-core's k_y (the printed 250 is unstable on reversals,
/// DECISIONS D8), and the large-error bound of the lateral term (clean
/// start from a large offset, D23; `with_large_error_bound(0.0)` = as printed).
pub const KINEMATIC_GAINS: KinematicGains = KinematicGains {
    k_y: DEFAULT_K_Y,
    ..KinematicGains::paper()
}
.with_large_error_bound(DEFAULT_LARGE_ERROR_M);

/// Robot body: mass, inertia, wheel radius, half track, centre-of-mass
/// offset. Default: the paper's Table 1 (15 kg, r = 0.1 m, track 0.4 m,
/// d = 0.05 m): measure and replace for a real robot.
pub const ROBOT: RobotParams = RobotParams::paper();

/// Motors, gearbox, supply and PWM: controller-core's example 24 V
/// gear-motor (`MotorParams::EXAMPLE`: k = 0.05 N·m/A, R = 0.5 Ω, 12:1 at
/// 85 %, 24 V, duty limit 0.95), the same values the simulator drives.
/// `duty_full_scale` is replaced at start-up by the PWM timer's real
/// resolution. Measure and replace for a real robot.
pub const MOTOR: MotorParams = MotorParams::EXAMPLE;

/// Encoders: counts per *wheel* revolution after ×4 decoding and gearbox,
/// which counter runs backwards when driving forward, and the speed window:
/// controller-core's example (`EncoderParams::EXAMPLE`: 500 lines × 4 × 12
/// = 24 000 counts/rev, left mirrored, 4 ms window), the simulator's too.
pub const ENCODER: EncoderParams = EncoderParams::EXAMPLE;

/// Per wheel `[right, left]`: flip the DIR output (left motor mirrored).
pub const MOTOR_INVERTED: [bool; 2] = MIRRORED_LEFT;

/// The H-bridge wiring: input scheme, PWM frequency, zero-duty behaviour
/// (`BridgeParams`; pins per mode in the README's "Wiring"). Default:
/// PWM + DIR at 20 kHz, braking at zero duty. The mode can be chosen at
/// build time with `BRIDGE_MODE=pwm-dir|two-pwm|pwm-in1-in2` (CI builds
/// an image of each for stm32-emu); the board takes it as a run-time value,
/// so every mode's code is in every image.
pub const BRIDGE: BridgeParams = BridgeParams {
    mode: bridge_mode(option_env!("BRIDGE_MODE")),
    ..BridgeParams::EXAMPLE
};

/// `BRIDGE_MODE` at build time: unset or `pwm-dir`, `two-pwm`,
/// `pwm-in1-in2`; anything else fails the build.
const fn bridge_mode(name: Option<&str>) -> BridgeMode {
    const fn eq(a: &[u8], b: &[u8]) -> bool {
        if a.len() != b.len() {
            return false;
        }
        let mut i = 0;
        while i < a.len() {
            if a[i] != b[i] {
                return false;
            }
            i += 1;
        }
        true
    }
    match name {
        None => BridgeMode::PwmDir,
        Some(n) if eq(n.as_bytes(), b"pwm-dir") => BridgeMode::PwmDir,
        Some(n) if eq(n.as_bytes(), b"two-pwm") => BridgeMode::TwoPwm,
        Some(n) if eq(n.as_bytes(), b"pwm-in1-in2") => BridgeMode::PwmIn1In2,
        Some(_) => panic!("BRIDGE_MODE must be pwm-dir, two-pwm or pwm-in1-in2"),
    }
}

/// Safety thresholds (see `SafetyLimits`): jump > 400 counts/ms
/// (2.6× the 40 rad/s no-load speed), stall at >= 2 N·m for 250 ms, a tick
/// more than 0.5 ms behind its schedule is late and 5 late ticks in a row
/// latch, first bad input latching, a wheel accelerating against its
/// torque (>= 1 N·m, >= 10 rad/s²) for 80 ms latching (the direction
/// check: a motor or encoder wired backwards).
pub const SAFETY: SafetyLimits = SafetyLimits::EXAMPLE;

/// Ticks of pose-estimator history: the oldest external pose (sent over the
/// host link, `wmr pose-feed`) the runtime can still use. The history keeps
/// 16 B of inputs per tick and a posterior snapshot (80 B) every 17 ticks
/// (docs/DECISIONS.md D31): 272 ticks are 5.6 KiB and cover poses up to
/// 255 ms late at 1 kHz (`PoseEstimator::<272>::GUARANTEED_DEPTH_TICKS`),
/// above the 250 ms latency bound of issue 9 (UWB, a lidar localiser).
pub const POSE_HISTORY_TICKS: usize = controller_core::estimator::HISTORY_LEN;

/// Where odometry and the estimator start: the origin facing +x.
pub const INITIAL_POSE: controller_core::Pose = controller_core::Pose::new(0.0, 0.0, 0.0);

/// The runtime configuration with `MOTOR`'s placeholder PWM full scale.
/// Constants (this one, [`ESTIMATOR`] and [`DEVICE`]) rather than
/// functions: the compiler then folds them into the device's
/// construction (about 370 B less flash than building them at run time).
const RUNTIME: RuntimeConfig = {
    // Every field named: the sliding loop's k_s and switching gain are
    // Table 2's for CONTROLLER (k_s = 50 proposed, 5 baselines; adaptive
    // ρ̂ or the fixed SMC gain), the observers take controller-core's
    // defaults (fault observer eq. 13, fal-ESO eq. 18).
    let controller = ControllerConfig {
        kind: CONTROLLER,
        robot: ROBOT,
        kinematic: KINEMATIC_GAINS,
        fault_observer: FaultObserverGains::DEFAULT,
        eso: EsoParams::DEFAULT,
        sliding: ControllerConfig::paper(CONTROLLER).sliding,
        torque_limit_nm: TORQUE_LIMIT_NM,
        period_s: 1.0 / CONTROL_HZ as f32,
        input_limits: InputLimits::DEFAULT,
    };
    RuntimeConfig {
        controller,
        // The host link supplies the reference (boot state hold): this one
        // is never driven, it only completes the runtime's configuration.
        reference: Reference::Paper(PaperCurve::paper(PaperHeading::SignedSmooth)),
        initial_pose: INITIAL_POSE,
        encoder: ENCODER,
        motor: MOTOR,
        motor_inverted: MOTOR_INVERTED,
        safety: SAFETY,
        // Reference governor and health machine (DECISIONS D22, D24).
        pacing: PacingConfig::on(),
    }
};

/// The full runtime configuration; `pwm_full_scale` is the PWM timer's
/// counts at 100 % duty.
pub fn runtime_config(pwm_full_scale: u16) -> RuntimeConfig {
    let mut cfg = RUNTIME;
    cfg.motor.duty_full_scale = pwm_full_scale;
    cfg
}

/// The pose estimator's tuning: controller-core's example (a MEMS gyro,
/// external poses from the host link). It starts at the runtime's initial
/// pose ([`INITIAL_POSE`]) with the robot's centre-of-mass offset, both
/// taken from the runtime configuration by the control loop.
#[cfg(not(feature = "imu"))]
pub const ESTIMATOR: EstimatorConfig = EstimatorConfig::EXAMPLE;
/// The pose estimator's tuning: controller-core's example (a MEMS gyro,
/// external poses from the host link; start pose and centre-of-mass offset
/// from the runtime configuration), and the IMU's saturation: a reading
/// within 2 % of the configured full scale ([`IMU_RANGE`]) counts as
/// saturated (the chip clips there), so the estimator uses the wheels' yaw
/// rate for it. ±500 °/s: 0.98 × 8.73 = 8.56 rad/s.
#[cfg(feature = "imu")]
pub const ESTIMATOR: EstimatorConfig = EstimatorConfig {
    gyro_saturation_radps: 0.98 * IMU_RANGE.limit_radps(),
    ..EstimatorConfig::EXAMPLE
};

/// How the IMU is mounted (`imu` feature): which sensor axis is the
/// robot's vertical axis (up) and whether it points down. Default: the
/// module flat, components up (sensor z up): a counter-clockwise turn seen
/// from above reads positive, the controller's θ convention. Mounted upside
/// down: `inverted: true`; mounted on its edge: the axis that is vertical.
/// Check it by turning the robot by hand: `wmr status` / the `est` line
/// must show the gyro's yaw rate with the sign of the wheels' one.
#[cfg(feature = "imu")]
pub const IMU_YAW: robot_app::imu::YawMapping = robot_app::imu::YawMapping {
    axis: robot_app::imu::Axis::Z,
    inverted: false,
};

/// Gyro full scale (`imu` feature): ±500 °/s = ±8.73 rad/s. A wheeled
/// robot turns far slower while tracking (the button's circle: 0.4 rad/s);
/// only a spin in place at full motor speed exceeds it (the example motors,
/// 40 rad/s no-load × 0.1 m wheels on a 0.2 m half track: at most
/// 4 / 0.2 = 20 rad/s), and such a reading counts as saturated, so the
/// estimator uses the wheels meanwhile. One count is 2.7e-4 rad/s.
#[cfg(feature = "imu")]
pub const IMU_RANGE: robot_app::imu::GyroRange = robot_app::imu::GyroRange::Dps500;

/// Gyro low-pass filter (`imu` feature), the MPU-6050's DLPF_CFG:
/// 2 = 98 Hz bandwidth, 2.8 ms delay, 1 kHz output rate (MPU-6050 register
/// map rev 4.2, register 26). Far above the robot's yaw dynamics (a few Hz)
/// and below the 500 Hz Nyquist rate of the 1 kHz sampling; motor and gear
/// vibration above 100 Hz is attenuated. 3 (42 Hz, 4.8 ms) for a robot
/// that vibrates more.
#[cfg(feature = "imu")]
pub const IMU_DLPF: u8 = 2;

/// The IMU's 7-bit I2C address (`imu` feature): 0x68 (MPU-6050 AD0 low,
/// as on GY-521 modules; 0x69 with AD0 high).
#[cfg(feature = "imu")]
pub const IMU_I2C_ADDRESS: u8 = 0x68;

/// I2C clock for the IMU \[Hz\] (`imu` feature): fast mode (a gyro read
/// is about 0.25 ms).
#[cfg(feature = "imu")]
pub const IMU_I2C_HZ: u32 = 400_000;

/// The gyro's plausibility checks (`imu` feature, `robot_app::imu::GyroMonitor`):
/// 50 bit-identical 3-axis readings in a row (50 ms at 1 kHz; a live
/// chip's noise of about 3 counts RMS per axis never repeats that long)
/// freeze it, so the estimator uses the wheels; a rate beyond 25 rad/s on
/// any axis is implausible (the example robot spins at most at 20 rad/s,
/// see [`IMU_RANGE`]; with ±500 °/s the chip clips at 8.73 rad/s, so this
/// bound matters for the wider ranges).
#[cfg(feature = "imu")]
pub const IMU_MONITOR: robot_app::imu::MonitorConfig = robot_app::imu::MonitorConfig {
    frozen_after: 50,
    max_rate_radps: 25.0,
};

/// What the arm button drives when the host has loaded nothing:
/// robot-app's default, a circle of 0.5 m radius at 0.2 m/s starting where
/// odometry starts (the origin, facing +x), counter-clockwise. Not the
/// paper's curve: that one reaches about 2 m/s (upload it with `wmr upload`
/// when the robot has room).
pub const BUTTON_REFERENCE: BuiltinReference = robot_app::DEFAULT_BUTTON_REFERENCE;

/// Link settings: 500 ms link-silence timeout while moving under host
/// control, velocity-command limits, braking deceleration, telemetry off
/// until the host asks (`LinkConfig::DEFAULT`).
pub const LINK: LinkConfig = LinkConfig::DEFAULT;

/// What this firmware can do over the host link (handshake).
pub const CAPABILITIES: u16 =
    wmr_protocol::CAP_EXTERNAL_POSE | wmr_protocol::CAP_TRAJECTORY | wmr_protocol::CAP_VELOCITY;

/// The host link handler's configuration for the board named `chip` in the
/// handshake (the board's `CHIP_ID`, at most 16 bytes). A `const fn`: used
/// in a constant, it folds into the device's construction.
pub const fn device(chip: &'static str) -> DeviceConfig {
    DeviceConfig {
        chip,
        capabilities: CAPABILITIES,
        link: LINK,
        button_reference: Some(BUTTON_REFERENCE),
    }
}

/// The control task's local logs: a status line every second and the
/// tracking lines at 20 Hz, printed only with the `rtt-telemetry` feature
/// (`Board::LOGS_STATUS`; the host link carries the telemetry otherwise,
/// `wmr record`).
pub const APP: robot_app::AppConfig = robot_app::AppConfig {
    status_every_ticks: CONTROL_HZ as u32,
    telemetry_every_ticks: TELEMETRY_DECIMATION,
};
