//! Differential-drive trajectory-tracking firmware: controller-core's runtime
//! at 1 kHz from two quadrature encoders to two PWM H-bridge channels.
//!
//! Everything that is not a register access lives in `robot-app` (the
//! control task, the link pipes, the button and watchdog policy) and
//! `controller_core::runtime`, both host-tested; this crate binds the
//! embassy peripherals to robot-app's `Board` trait ([`board`]), sets the
//! constants ([`config`]), carries the link's transport ([`link`]), the
//! log lines ([`log`]), the banner ([`banner`]) and the panic and fault
//! paths ([`fault`]). `main` is the wiring: board, device, tasks (module
//! graph without cycles: `.ci/module_cycles.py`).
#![no_std]
#![no_main]

mod banner;
mod board;
mod config;
mod fault;
#[cfg(feature = "imu")]
mod imu;
mod link;
mod log;
mod motors;
mod store;

use controller_core::runtime::{ArmingButton, LoopTimer};
use defmt::{error, info, unwrap};
use defmt_rtt as _;
use embassy_executor::Spawner;
use robot_app::ControlTask;
use static_cell::StaticCell;
use wmr_device::{Device, DeviceConfigError};

/// The host-link device and runtime with the firmware's pose history.
type Robot = Device<{ config::POSE_HISTORY_TICKS }>;

/// The robot store over the flash controller (sequential-storage).
type Store = robot_app::store::FlashRecord<store::StoreFlash>;

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // Motor lines defined low before the clocks start (HSE start, PLL lock).
    board::outputs_low_early();
    // The clocks, then the robot record (store::boot_robot: the flash's or
    // the compiled-in robot), then the motor outputs in its [bridge]: the
    // motor lines stay low GPIO outputs through the load (board::init).
    static STORE: StaticCell<Store> = StaticCell::new();
    let (mut board, (flash, boot)) = board::init(|p| async move {
        let Some(flash) = store::store(p) else {
            never_armed()
        };
        let flash = STORE.init(flash);
        let boot = store::boot_robot(flash).await;
        (boot.robot.bridge.params(), (flash, boot))
    })
    .await;
    let robot = &boot.robot;

    log::enable_cycle_counter();
    // A full scale beyond 16 bits becomes 0: refused by the configuration check.
    let full_scale = u16::try_from(board.motors.full_scale()).unwrap_or(0);
    let derived = config::derive(robot, full_scale);
    let (cfg, estimator) = (derived.runtime, derived.estimator);
    banner::banner(&board, robot, full_scale, &cfg);

    // The device (about 12 KiB: the runtime, its estimator history, the
    // link's buffers) built in its static (StaticCell::init_with writes the
    // constructor's result there), not on this frame and then moved: moved
    // by value, each copy was 12 KiB of main's 50 KiB frame (D104, D116).
    static ROBOT: StaticCell<Result<Robot, DeviceConfigError>> = StaticCell::new();
    let device = match ROBOT
        .init_with(|| Robot::with_estimator(config::device(robot, board::CHIP_ID), cfg, estimator))
    {
        Ok(d) => d,
        Err(_) => never_armed(),
    };
    let Some(task) = LoopTimer::from_config(&cfg)
        .ok()
        .zip(ArmingButton::new(config::BUTTON_DEBOUNCE_TICKS).ok())
        .and_then(|(timer, button)| ControlTask::new(timer, button, config::APP).ok())
    else {
        never_armed()
    };
    // The IMU in its own task: it probes and configures the chip while the
    // control task starts, and never holds it up (board::BoardGyro reads
    // its newest sample; none until the chip answers).
    #[cfg(feature = "imu")]
    if let Some(p) = board.imu.take() {
        imu::start(&spawner, p, config::imu_yaw(robot));
    }
    link::start_if_present(&spawner, board.link.take());
    info!("state: HOLD (motors off). Load a reference with wmr and arm, or press the button (slow circle).");
    device.board_report_mut().reset_cause = board.reset_cause;
    device.attach_robot_store(robot_store::validate_robot, boot.record(), boot.source);
    spawner.spawn(unwrap!(control(board, device, task, flash).ok()));
}

/// robot-app's control task with this board's types.
#[embassy_executor::task]
async fn control(
    mut board: board::Board,
    device: &'static mut Robot,
    task: ControlTask,
    flash: &'static mut Store,
) {
    task.run_with_store(&mut board, device, &link::PIPES, flash)
        .await
}

/// An invalid configuration: the motors stay off, the watchdog is never
/// started, nothing is spawned.
fn never_armed() -> ! {
    error!("invalid configuration; motors stay disabled");
    loop {
        cortex_m::asm::wfi();
    }
}
