//! The emulated board: robot-app's [`Board`] on QEMU's MPS2 AN386 with the
//! simulated robot behind the peripherals.
//!
//! | Board item | here |
//! |---|---|
//! | encoders, motors, gyro | [`crate::sim`] handles (sim-robot's counters, H-bridge, MEMS gyro) |
//! | pose source | none on the board (external poses over the link) |
//! | button | none (the host arms) |
//! | watchdog | the CMSDK APB watchdog ([`crate::watchdog`]) |
//! | `cycles()` | SysTick under `-icount shift=0`: guest instructions |
//! | log | semihosting ([`crate::log`]) |
//! | link | UART0 ([`crate::uart`]) |

use controller_core::runtime::WheelOdometryOnly;
use embassy_time::Instant;
use robot_app::{AppEvent, Board, BoardIo};

use crate::sim::{EmuEncoders, EmuGyro, EmuMotors};

/// Chip name for the host link's handshake (at most 16 bytes).
pub const CHIP_ID: &str = "mps2-an386-emu";
/// Board name for the banner.
pub const CHIP: &str =
    "QEMU mps2-an386 (Cortex-M4F, 25 MHz SysTick; -icount: 1 instruction per ns)";
/// PWM counts at full duty: the STM32F411 Black Pill's (96 MHz / 20 kHz),
/// so the duty quantisation is that board's.
pub const PWM_FULL_SCALE: u16 = 4800;

/// The emulated board.
pub struct EmuBoard {
    encoders: EmuEncoders,
    motors: EmuMotors,
    gyro: EmuGyro,
    pose_source: WheelOdometryOnly,
}

impl EmuBoard {
    /// The board (call [`crate::sim::init`] first).
    pub fn new() -> Self {
        Self {
            encoders: EmuEncoders,
            motors: EmuMotors,
            gyro: EmuGyro,
            pose_source: WheelOdometryOnly,
        }
    }
}

impl Board for EmuBoard {
    type Encoders = EmuEncoders;
    type Motors = EmuMotors;
    type Gyro = EmuGyro;
    type PoseSource = WheelOdometryOnly;

    fn io(&mut self) -> BoardIo<'_, EmuEncoders, EmuMotors, EmuGyro, WheelOdometryOnly> {
        BoardIo {
            encoders: &mut self.encoders,
            motors: &mut self.motors,
            gyro: &mut self.gyro,
            pose_source: &mut self.pose_source,
        }
    }

    fn motors(&mut self) -> &mut EmuMotors {
        &mut self.motors
    }

    fn button_pressed(&mut self) -> bool {
        false
    }

    fn start_watchdog(&mut self) {
        crate::watchdog::start(crate::time::CPU_HZ, crate::config::WATCHDOG_TIMEOUT_US);
        // The loop's first period starts now: the plant's phase.
        crate::sim::LOOP_START.signal(Instant::now());
    }

    fn feed_watchdog(&mut self) {
        crate::watchdog::feed();
    }

    fn cycles(&mut self) -> u32 {
        crate::time::instructions()
    }

    fn event(&mut self, event: &AppEvent<'_>) {
        crate::log::event(event);
    }
}
