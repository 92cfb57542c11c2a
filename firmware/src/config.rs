//! The firmware's configuration: the compiled-in robot (a robot file,
//! `robot_file::Robot`, book/src/how-to/robot-file.md: geometry, motors, encoders, bridge,
//! IMU mounting, limits, gains) and what is the firmware's own (loop rate,
//! watchdog, logs, the IMU's bus). Everything the runtime and the link need
//! is built from a `Robot` by the one derivation ([`derive`], [`device`]),
//! so a robot read from flash replaces the default whole.
//!
//! A leaf: it names nothing of this crate (board, IMU driver, log), only
//! library types, so `firmware-emu` compiles it unchanged (`#[path]`) and
//! supplies its own board. What depends on the chip (its handshake name)
//! is a parameter ([`device`]).

use controller_core::trajectory::{PaperCurve, PaperHeading, Reference};
use robot_file::{BoardFacts, Derived, Robot};
use wmr_device::DeviceConfig;
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

/// The compiled-in robot's binary form (`Robot::encode`): `build.rs` reads
/// the robot file `ROBOT_FILE` (default `../robots/paper.toml`; relative
/// paths from `firmware/`), validates it (a bad file fails the build with
/// the field, line and reason) and writes it to `OUT_DIR`. Body, motors,
/// encoders, bridge, IMU mounting, limits and gains all come from it
/// (book/src/how-to/robot-file.md); nothing here repeats a value of it. The firmware's
/// `BRIDGE_MODE=pwm-dir|two-pwm|pwm-in1-in2` at build time replaces the
/// file's `bridge.mode` in this record (CI builds an image of each for
/// stm32-emu); a robot stored in flash runs with its own `[bridge]`
/// whatever the image's (store.rs, D115).
pub static DEFAULT_ROBOT_BYTES: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/robot.bin"));

/// The compiled-in robot, decoded (and validated again) from
/// [`DEFAULT_ROBOT_BYTES`]; the robot of the flash record overrides it at
/// boot when one is stored. The build decoded the same bytes with the same
/// code, so the fallback, the paper's robot, is never taken unless the
/// image itself is corrupt.
pub fn default_robot() -> Robot {
    Robot::decode(DEFAULT_ROBOT_BYTES).unwrap_or_else(|_| Robot::paper())
}

/// Ticks of pose-estimator history: the oldest external pose (sent over the
/// host link, `wmr pose-feed`) the runtime can still use. The history keeps
/// 16 B of inputs per tick and a posterior snapshot (80 B) every 17 ticks
/// (book/src/explanation/decisions.md D31): 272 ticks are 5.6 KiB and cover poses up to
/// 255 ms late at 1 kHz (`PoseEstimator::<272>::GUARANTEED_DEPTH_TICKS`),
/// above the 250 ms latency bound of issue 9 (UWB, a lidar localiser).
pub const POSE_HISTORY_TICKS: usize = controller_core::estimator::HISTORY_LEN;

/// What the board tells the one derivation (`Robot::derive`, D139): the
/// PWM timer's counts at 100 % duty (`pwm_full_scale`, read back from the
/// timer), the loop rate [`CONTROL_HZ`] and, with the `imu` feature, where
/// the gyro clips ([`GYRO_SATURATION_RADPS`]). The controller, its gains,
/// the clean start, the governor and the start pose are the robot file's
/// (`[control]`, `[gains]`).
pub fn board_facts(pwm_full_scale: u16) -> BoardFacts {
    BoardFacts {
        pwm_full_scale,
        control_period_s: 1.0 / CONTROL_HZ as f32,
        #[cfg(feature = "imu")]
        gyro_saturation_radps: Some(GYRO_SATURATION_RADPS),
        #[cfg(not(feature = "imu"))]
        gyro_saturation_radps: None,
    }
}

/// The reference a derivation completes the runtime configuration with:
/// the host link supplies the real one (boot state hold), so the paper
/// curve is never driven.
pub const PLACEHOLDER_REFERENCE: Reference =
    Reference::Paper(PaperCurve::paper(PaperHeading::SignedSmooth));

/// Everything `robot` gives the runtime on this board ([`board_facts`]).
pub fn derive(robot: &Robot, pwm_full_scale: u16) -> Derived {
    robot.derive(&board_facts(pwm_full_scale), PLACEHOLDER_REFERENCE)
}

/// Where the gyro clips for the estimator (`imu` feature): a reading
/// within 2 % of the configured full scale ([`IMU_RANGE`]) counts as
/// saturated (the chip clips there), so the estimator uses the wheels'
/// yaw rate for it. ±500 °/s: 0.98 × 8.73 = 8.56 rad/s.
#[cfg(feature = "imu")]
pub const GYRO_SATURATION_RADPS: f32 = 0.98 * IMU_RANGE.limit_radps();

/// How the IMU is mounted (`imu` feature), from the robot file's
/// `imu.yaw_axis`: which sensor axis is the robot's vertical axis and
/// whether it points down (a counter-clockwise turn seen from above must
/// read positive, the controller's θ convention). Check it by turning the
/// robot by hand: `wmr status` / the `est` line must show the gyro's yaw
/// rate with the sign of the wheels' one.
#[cfg(feature = "imu")]
pub fn imu_yaw(robot: &Robot) -> robot_app::imu::YawMapping {
    use robot_app::imu::Axis;
    let (axis, sign) = robot.imu.yaw_axis.axis_and_sign();
    robot_app::imu::YawMapping {
        axis: match axis {
            0 => Axis::X,
            1 => Axis::Y,
            _ => Axis::Z,
        },
        inverted: sign < 0.0,
    }
}

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

/// What this firmware can do over the host link (handshake). The robot
/// store is always there (main.rs never arms without it): without
/// `CAP_ROBOT_STORE` `wmr robot push/pull` refused every board (found by
/// stm32-emu's push check).
pub const CAPABILITIES: u16 = wmr_protocol::CAP_EXTERNAL_POSE
    | wmr_protocol::CAP_TRAJECTORY
    | wmr_protocol::CAP_VELOCITY
    | wmr_protocol::CAP_ROBOT_STORE;

/// The host link handler's configuration of `robot` (its link timeout and
/// command limits) for the board named `chip` in the handshake (the
/// board's `CHIP_ID`, at most 16 bytes).
pub fn device(robot: &Robot, chip: &'static str) -> DeviceConfig {
    DeviceConfig::of_robot(robot, chip, CAPABILITIES, Some(BUTTON_REFERENCE))
}

/// The control task's local logs: a status line every second and the
/// tracking lines at 20 Hz, printed only with the `rtt-telemetry` feature
/// (`Board::LOGS_STATUS`; the host link carries the telemetry otherwise,
/// `wmr record`).
pub const APP: robot_app::AppConfig = robot_app::AppConfig {
    status_every_ticks: CONTROL_HZ as u32,
    telemetry_every_ticks: TELEMETRY_DECIMATION,
};
