//! What the application needs from a board, and what it tells the board.

use controller_core::health::HealthTransition;
use controller_core::runtime::{
    Gyro, MotorDriver, PoseSource, StopReason, TickReport, WheelEncoders,
};
use wmr_protocol::RunStateMsg;

/// The robot's peripherals as the application uses them.
///
/// Implementations: the STM32 boards (`firmware/src/board.rs`: timer
/// encoders, TIM1 PWM H-bridge, IWDG, DWT), the emulated board
/// (`firmware-emu/`: the simulated robot behind the same traits, SysTick
/// under `-icount` as the cycle counter) and the host tests' mock boards.
///
/// Motor safety does not rest on this trait alone: a board must hold its
/// outputs off from reset until [`MotorDriver::set`] is first called, and
/// its panic and fault handlers must cut them without going through it.
pub trait Board {
    /// `(right, left)` wheel encoders.
    type Encoders: WheelEncoders;
    /// The two motor channels, disabled until the runtime arms.
    type Motors: MotorDriver;
    /// The z-axis gyro ([`NoGyro`](controller_core::runtime::NoGyro) when
    /// the board has none).
    type Gyro: Gyro;
    /// A pose source on the board (e.g. a localiser on a second port);
    /// [`WheelOdometryOnly`](controller_core::runtime::WheelOdometryOnly)
    /// when poses come only over the host link.
    type PoseSource: PoseSource;

    /// Whether the board logs [`AppEvent::Status`] and
    /// [`AppEvent::Telemetry`]. `false` (a flash-constrained board whose
    /// host link carries the telemetry) lets the compiler drop the task's
    /// execution-time bookkeeping and both events.
    const LOGS_STATUS: bool = true;

    /// Borrows the peripherals the control tick uses, all at once.
    fn io(&mut self) -> BoardIo<'_, Self::Encoders, Self::Motors, Self::Gyro, Self::PoseSource>;

    /// The motor driver alone (button actions outside the tick).
    fn motors(&mut self) -> &mut Self::Motors;

    /// True while the operator button is held (raw level; the application
    /// debounces it).
    fn button_pressed(&mut self) -> bool;

    /// Starts the hardware watchdog. Called once, just before the first
    /// control tick: a board that never reaches the loop (an invalid
    /// configuration) never starts it.
    fn start_watchdog(&mut self);

    /// Feeds the watchdog. Only the control task calls it, once per
    /// completed tick: when the loop stalls (a task hogging the executor,
    /// a hang in a driver), the feeding stops and the watchdog resets the
    /// chip, which boots with the motors off.
    fn feed_watchdog(&mut self);

    /// A robot-record flash write is about to start (in hold, motors off,
    /// outside the control tick). On an F4 a sector erase stalls every
    /// flash read for up to seconds, longer than the loop's watchdog
    /// timeout: the board stretches its watchdog beyond the longest write
    /// here (and feeds it). Default: nothing (a flash that does not stall).
    fn flash_write_begins(&mut self) {}

    /// The robot-record write ended: the watchdog back to the loop's
    /// timeout, fed. Default: nothing.
    fn flash_write_ends(&mut self) {}

    /// Restarts the MCU (the host's `Reboot`, after the acknowledgement has
    /// left). The STM32 boards reset the core; the default does nothing
    /// (the board keeps running the robot it booted with).
    fn reboot(&mut self) {}

    /// A free-running, wrapping cycle counter (DWT CYCCNT on an STM32;
    /// guest instructions on the emulated board); 0 when the board has
    /// none. Used for the tick's execution-time statistics.
    fn cycles(&mut self) -> u32;

    /// Something worth logging happened (state changes, safe stops, health
    /// transitions, the periodic status). The board prints it its own way
    /// (defmt over RTT, semihosting) or ignores it; it must not block.
    fn event(&mut self, event: &AppEvent<'_>);
}

/// The peripherals one control tick uses.
pub struct BoardIo<'a, E, M, G, P> {
    /// Encoders.
    pub encoders: &'a mut E,
    /// Motor driver.
    pub motors: &'a mut M,
    /// Gyro.
    pub gyro: &'a mut G,
    /// Board-side pose source.
    pub pose_source: &'a mut P,
}

/// Events of the control task, for the board's log.
#[derive(Clone, Copy, Debug)]
#[non_exhaustive]
pub enum AppEvent<'a> {
    /// The loop starts (first tick); the watchdog has just been started.
    Started,
    /// The run state changed (arming, a controlled stop ended, a latched
    /// stop cleared, ...).
    State(RunStateMsg),
    /// The runtime latched a safe stop this tick (motors disabled).
    SafeStop(StopReason),
    /// The health machine changed mode this tick.
    Health {
        /// The transition.
        transition: HealthTransition,
        /// Transitions so far.
        transitions: u32,
    },
    /// Every [`AppConfig::telemetry_every_ticks`](crate::AppConfig) ticks:
    /// the tick's full report (for a board that logs telemetry locally).
    Telemetry(&'a TickReport),
    /// Every [`AppConfig::status_every_ticks`](crate::AppConfig) ticks.
    Status(StatusSummary),
    /// A robot-record write to flash ended (`ok`: stored and read back
    /// equal) after `duration_us` of stalled loop (motors off, in hold).
    RobotWritten {
        /// Stored and read back equal.
        ok: bool,
        /// How long the loop paused \[µs\].
        duration_us: u32,
    },
}

/// The periodic status: loop timing and the tick's execution time since the
/// last status.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StatusSummary {
    /// Ticks run since boot.
    pub ticks: u32,
    /// Ticks that started later than the late limit (since boot).
    pub late_ticks: u32,
    /// Overrun episodes (since boot).
    pub overrun_episodes: u32,
    /// Largest lateness of a tick \[µs\] (since boot).
    pub max_lateness_us: u32,
    /// Mean execution time of the tick (link bytes in, device tick, link
    /// bytes out) since the last status, in [`Board::cycles`] units.
    pub tick_cycles_mean: u32,
    /// Largest execution time of a tick since the last status.
    pub tick_cycles_max: u32,
    /// Largest execution time of a tick that moved link bytes (received a
    /// request or queued telemetry) since the last status.
    pub tick_cycles_max_link: u32,
    /// Ticks that moved link bytes since the last status.
    pub link_ticks: u32,
    /// Watchdog feeds since boot.
    pub watchdog_feeds: u32,
    /// Host bytes dropped because the receive pipe was full, since boot.
    pub rx_dropped_bytes: u32,
}
