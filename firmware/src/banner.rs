//! The startup banner: what runs, on what, with which settings (defmt over
//! RTT; `wmr params get` shows the configuration over the link too).

use defmt::{error, info};

use crate::{board, config};

/// What runs, on what, with which settings.
pub fn banner(
    board: &board::Board,
    robot: &robot_file::Robot,
    full_scale: u16,
    cfg: &controller_core::runtime::RuntimeConfig,
) {
    info!(
        "==== trajectory-tracking firmware {=str} ====",
        env!("CARGO_PKG_VERSION")
    );
    info!("chip: {=str}", board::CHIP);
    info!("last reset: {} (RCC_CSR)", board.reset_cause);
    if board.clock == board::ClockSource::HsiFallback {
        error!(
            "HSE did not start within {=u32} polls (0.3-0.4 s): running on the internal HSI (same SYSCLK, ~1 % accuracy, no USB)",
            board::HSE_STARTUP_TIMEOUT_MS
        );
    }
    info!(
        "loop {=u64} Hz, PWM {=u32} Hz full scale {=u16} counts, watchdog {=u32} us",
        config::CONTROL_HZ,
        robot.bridge.pwm_frequency_hz,
        full_scale,
        config::WATCHDOG_TIMEOUT_US,
    );
    info!("reference: from the host (wmr upload / drive); button: a circle of 0.5 m radius at 0.2 m/s from the start pose");
    // The full configuration (the host link shows it too: `wmr params get`).
    #[cfg(feature = "rtt-telemetry")]
    {
        info!("controller: {}", cfg.controller);
        info!("initial pose: {}", cfg.initial_pose);
        info!("encoder: {}", cfg.encoder);
        info!("motor: {} inverted {}", cfg.motor, cfg.motor_inverted);
        info!("safety: {}", cfg.safety);
    }
    #[cfg(not(feature = "rtt-telemetry"))]
    let _ = cfg;
    #[cfg(feature = "imu")]
    info!(
        "gyro: MPU-6050 on I2C1 (PB8 SCL, PB9 SDA) at 0x{=u8:x}: probing (heading from the wheels until it answers)",
        config::IMU_I2C_ADDRESS
    );
    #[cfg(not(feature = "imu"))]
    info!("gyro: none (built without the `imu` feature): heading from the wheels");
    info!(
        "pose source: external poses from the host link (wmr pose-feed), used up to {=usize} ms late; without them wheel odometry only, blind to slip and actuator faults",
        controller_core::estimator::PoseEstimator::<{ config::POSE_HISTORY_TICKS }>::GUARANTEED_DEPTH_TICKS
    );
}
