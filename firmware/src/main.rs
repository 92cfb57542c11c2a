//! Differential-drive trajectory-tracking firmware: controller-core's runtime
//! at 1 kHz from two quadrature encoders to two PWM H-bridge channels.
//!
//! Everything that is not a register access lives in `robot-app` (the
//! control task, the link pipes, the button and watchdog policy) and
//! `controller_core::runtime`, both host-tested; this crate binds the
//! embassy peripherals to robot-app's `Board` trait ([`board`]), sets the
//! constants ([`config`]), carries the link's transport ([`link`]) and the
//! log lines ([`log`]), and the panic and fault paths. `main` is the wiring:
//! board, device, tasks.
#![no_std]
#![no_main]

mod board;
mod config;
#[cfg(feature = "imu")]
mod imu;
mod link;
mod log;

use controller_core::runtime::{ArmingButton, LoopTimer};
use defmt::{error, info, unwrap};
use defmt_rtt as _;
use embassy_executor::Spawner;
use robot_app::ControlTask;
use static_cell::StaticCell;
use wmr_device::Device;

/// The host-link device and runtime with the firmware's pose history.
type Robot = Device<{ config::POSE_HISTORY_TICKS }>;

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // Motor lines defined low before the clocks start (HSE start, PLL lock).
    board::outputs_low_early();
    let mut board = board::init();

    // DWT cycle counter for the tick's execution time (RTT status lines).
    #[cfg(feature = "rtt-telemetry")]
    {
        let mut cp = unwrap!(cortex_m::Peripherals::take());
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
    }

    let full_scale = board.motors.full_scale();
    let full_scale = if full_scale <= u16::MAX as u32 {
        full_scale as u16
    } else {
        0 // rejected by the configuration check below
    };
    let cfg = config::runtime_config(full_scale);
    banner(&board, full_scale, &cfg);

    let (device, task) = match (
        Robot::with_estimator(config::DEVICE, cfg, config::ESTIMATOR),
        LoopTimer::from_config(&cfg)
            .ok()
            .zip(ArmingButton::new(config::BUTTON_DEBOUNCE_TICKS).ok()),
    ) {
        (Ok(d), Some((timer, button))) => match ControlTask::new(timer, button, config::APP) {
            Ok(t) => (d, t),
            Err(_) => never_armed(),
        },
        _ => never_armed(),
    };
    // The IMU in its own task: it probes and configures the chip while the
    // control task starts, and never holds it up (board::BoardGyro reads
    // its newest sample; none until the chip answers).
    #[cfg(feature = "imu")]
    if let Some(p) = board.imu.take() {
        imu::start(&spawner, p);
    }
    match board.link.take() {
        Some(p) => {
            link::start(&spawner, p);
            info!(
                "host link: wmr-protocol {=u16}",
                wmr_protocol::PROTOCOL_VERSION
            );
        }
        None => error!("host link off (no USB clock on the HSI)"),
    }
    info!("state: HOLD (motors off). Load a reference with wmr and arm, or press the button (slow circle).");
    // The device (about 7 KiB) in a static of its own, the task holds a
    // reference: moved into the task by value, the future would hold it
    // twice (the argument and the local it is moved into).
    static ROBOT: StaticCell<Robot> = StaticCell::new();
    let device = ROBOT.init(device);
    spawner.spawn(unwrap!(control(board, device, task).ok()));
}

/// robot-app's control task with this board's types.
#[embassy_executor::task]
async fn control(mut board: board::Board, device: &'static mut Robot, task: ControlTask) {
    robot_app::control_task(&mut board, device, &link::PIPES, task).await
}

/// An invalid configuration: the motors stay off, the watchdog is never
/// started, nothing is spawned.
fn never_armed() -> ! {
    error!("invalid configuration; motors stay disabled");
    loop {
        cortex_m::asm::wfi();
    }
}

/// What runs, on what, with which settings.
fn banner(board: &board::Board, full_scale: u16, cfg: &controller_core::runtime::RuntimeConfig) {
    info!(
        "==== trajectory-tracking firmware {=str} ====",
        env!("CARGO_PKG_VERSION")
    );
    info!("chip: {=str}", board::CHIP);
    if board.clock == board::ClockSource::HsiFallback {
        error!(
            "HSE did not start within {=u32} ms: running on the internal HSI (same SYSCLK, ~1 % accuracy, no USB)",
            board::HSE_STARTUP_TIMEOUT_MS
        );
    }
    info!(
        "loop {=u64} Hz, PWM {=u32} Hz full scale {=u16} counts, watchdog {=u32} us",
        config::CONTROL_HZ,
        board::PWM_FREQ.0,
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
        board::IMU_I2C_ADDRESS
    );
    #[cfg(not(feature = "imu"))]
    info!("gyro: none (built without the `imu` feature): heading from the wheels");
    info!(
        "pose source: external poses from the host link (wmr pose-feed), used up to {=usize} ms late; without them wheel odometry only, blind to slip and actuator faults",
        controller_core::estimator::PoseEstimator::<{ config::POSE_HISTORY_TICKS }>::GUARANTEED_DEPTH_TICKS
    );
}

/// Panic: motor outputs off first (raw register writes), then log and stop
/// in a fault the debugger sees; without a debugger the watchdog resets the
/// chip, which boots with the motors disabled.
///
/// The handler does not read `info` unless the `panic-location` feature is
/// on: reading it keeps every panic site's message arguments, file names
/// and `core::fmt` in the image (12 to 19 KiB of flash). probe-rs halts on
/// the `udf` below (HardFault) and prints the backtrace with file and line.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    board::motors_off_raw();
    #[cfg(feature = "panic-location")]
    if let Some(loc) = info.location() {
        error!("PANIC at {}:{} (motors off)", loc.file(), loc.line());
    } else {
        error!("PANIC (motors off)");
    }
    #[cfg(not(feature = "panic-location"))]
    {
        let _ = info;
        error!("PANIC (motors off; location: the backtrace, or build with `panic-location`)");
    }
    cortex_m::asm::udf()
}

/// `defmt::panic!` / `unwrap!` end here (after logging their message).
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    board::motors_off_raw();
    cortex_m::asm::udf()
}

/// Hard faults (including the `udf` above): outputs off, then wait for the
/// watchdog reset.
#[cortex_m_rt::exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    board::motors_off_raw();
    wait_for_watchdog()
}

/// NMI (the clock security system on an HSE failure, or any other source):
/// outputs off, no logging (an NMI may interrupt a log in progress), then
/// wait for the watchdog reset.
#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() {
    board::motors_off_raw();
    wait_for_watchdog()
}

/// Every exception and interrupt without a handler (cortex-m-rt's default is
/// an endless loop that leaves the outputs running): outputs off, then the
/// interrupt number for device interrupts (`irqn` >= 0; system exceptions
/// are not logged), then wait for the watchdog reset.
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    board::motors_off_raw();
    if irqn >= 0 {
        error!("unexpected interrupt {=i16} (motors off)", irqn);
    }
    wait_for_watchdog()
}

/// Spins until the independent watchdog resets the chip (within
/// `WATCHDOG_TIMEOUT_US` of the last feed when it runs; before it is
/// started, e.g. a fault during init, the board stays here with the outputs
/// off until power-cycled or reset by a debugger).
fn wait_for_watchdog() -> ! {
    loop {
        cortex_m::asm::nop();
    }
}
