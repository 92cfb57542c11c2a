//! The firmware's application above the registers.
//!
//! Everything the robot does between its peripherals and the control law
//! lives here, written against a small [`Board`] trait:
//!
//! * [`control_task`]: the 1 kHz loop: schedule check ([`LoopTimer`]), host
//!   bytes in, one [`Device::tick`] (reference, controller, estimator,
//!   governor, health, telemetry), host bytes out, the watchdog fed, the arm
//!   button, events for the board's log;
//! * [`link`]: the host link's two bounded byte pipes and the pumps that
//!   move bytes between them and a byte-stream port (a UART) without the
//!   control task ever waiting on the port;
//! * [`store`]: the robot record's flash write between two ticks (in hold,
//!   motors off, the watchdog stretched) and its load at boot;
//! * [`imu`]: the gyro's logic above the registers (conversion, probe and
//!   read-back checks, the frozen/implausible monitor, the retry backoff,
//!   the sample cell the control tick reads).
//!
//! A board provides encoders, a motor driver, a gyro, a board-side pose
//! source, the button, the watchdog, a cycle counter and a log sink. Three
//! boards run this code: the STM32 boards in `firmware/` (embassy-stm32),
//! the emulated Cortex-M4 in `firmware-emu/` (QEMU `mps2-an386`, the
//! simulated robot in the guest) and the mock boards of the host tests
//! (`tests/` of this crate, embassy's std executor with embassy-time's mock
//! clock). Each binary's `main` builds its board, the device and the
//! timers, and spawns the tasks; the tasks are generic functions, and a
//! one-line `#[embassy_executor::task]` wrapper in the binary gives each its
//! concrete types (embassy tasks cannot be generic).
//!
//! `no_std`, no allocation, f32; it never panics on input.
#![no_std]
#![deny(missing_docs)]

pub mod board;
pub mod control;
pub mod imu;
pub mod link;
pub mod reset;
pub mod store;

pub use board::{AppEvent, Board, BoardIo, StatusSummary};
pub use control::{control_task, AppConfig, AppConfigError, ControlTask};
pub use link::{pump_rx, pump_rx_ring, pump_tx, LinkPipes, TX_CHUNK_BYTES};

// Re-exported for the boards.
pub use controller_core::runtime::{ArmingButton, LoopTimer};
pub use wmr_device::Device;

/// What the arm button drives when the host has loaded nothing: a circle of
/// 0.5 m radius at 0.2 m/s starting at the origin facing +x (where the
/// firmware's odometry starts), counter-clockwise. Not the paper's curve:
/// that one reaches about 2 m/s (upload it with `wmr upload` when the robot
/// has room). The firmware's default and the host tests' device use it.
pub const DEFAULT_BUTTON_REFERENCE: wmr_protocol::BuiltinReference =
    wmr_protocol::BuiltinReference {
        shape: wmr_protocol::BuiltinShape::Circle {
            radius_m: 0.5,
            speed_mps: 0.2,
        },
        start: Some(wmr_protocol::PoseMsg {
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
        }),
        speed_scale: 1.0,
    };
