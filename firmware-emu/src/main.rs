//! The firmware's application on an emulated board: QEMU's MPS2 AN386
//! (Cortex-M4F) with the simulated robot in the guest.
//!
//! This file is the wiring diagram: the board, the device and the tasks.
//! The tasks are the firmware's own (robot-app's control task and link
//! pumps, wmr-device, controller-core); the robot constants are the STM32
//! firmware's `firmware/src/config.rs`, compiled here unchanged. Only the
//! board differs: [`sim`] (the simulated robot), [`time`] (SysTick time
//! driver), [`uart`] (the link), [`watchdog`], [`log`] (semihosting).
//!
//! Module graph (no cycles): `main` -> every module; `board` -> `sim`,
//! `time`, `watchdog`, `log`, `config`; `log` -> `sim`, `config`; `sim` ->
//! `time`; `config` (the STM32 firmware's, a leaf) -> none.
#![no_std]
#![no_main]

mod board;
#[allow(dead_code)] // the STM32 firmware's constants; not all apply here
#[path = "../../firmware/src/config.rs"]
mod config;
mod log;
mod sim;
mod time;
mod uart;
mod watchdog;

use cortex_m_rt::{entry, exception, ExceptionFrame};
use cortex_m_semihosting::{debug, hprintln};
use embassy_executor::{InterruptExecutor, SendSpawner};
use robot_app::{pump_rx, pump_tx, AppConfig, ArmingButton, ControlTask, LinkPipes, LoopTimer};
use static_cell::StaticCell;
use wmr_device::{Device, DeviceConfig};

use board::EmuBoard;

/// The host-link device and runtime with the firmware's pose history.
type Robot = Device<{ config::POSE_HISTORY_TICKS }>;

static PIPES: LinkPipes = LinkPipes::new();

#[entry]
fn main() -> ! {
    let Some(cp) = cortex_m::Peripherals::take() else {
        log::fail("core peripherals taken twice");
    };
    time::init(cp.SYST);
    hprintln!(
        "==== trajectory-tracking firmware {} (emulated board) ====",
        env!("CARGO_PKG_VERSION")
    );
    hprintln!("board: {}", board::CHIP);

    // The STM32 firmware's configuration; the board's own: PWM full scale
    // (the F411's), the gyro (sim-robot's MEMS preset: its full scale),
    // and the handshake says "simulated".
    let robot = config::default_robot();
    let mut facts = config::board_facts(board::PWM_FULL_SCALE);
    facts.gyro_saturation_radps = Some(sim::gyro_saturation_radps());
    let robot_file::Derived {
        runtime: cfg,
        estimator,
    } = robot.derive(&facts, config::PLACEHOLDER_REFERENCE);
    let dev_cfg = DeviceConfig {
        // No robot store here (no flash model): not the firmware's
        // CAP_ROBOT_STORE, so `wmr robot push` says so.
        capabilities: (config::CAPABILITIES & !wmr_protocol::CAP_ROBOT_STORE)
            | wmr_protocol::CAP_SIMULATED,
        ..config::device(&robot, board::CHIP_ID)
    };
    let (device, timer, button) = match (
        Robot::with_estimator(dev_cfg, cfg, estimator),
        LoopTimer::from_config(&cfg),
        ArmingButton::new(config::BUTTON_DEBOUNCE_TICKS),
    ) {
        (Ok(d), Ok(t), Ok(b)) => (d, t, b),
        _ => log::fail("invalid configuration; motors stay disabled"),
    };
    let period_us = timer.period_us();
    let Ok(task) = ControlTask::new(timer, button, AppConfig::DEFAULT) else {
        log::fail("invalid loop period");
    };
    if sim::init(&cfg).is_err() {
        log::fail("simulated hardware");
    }
    hprintln!(
        "link: UART0 at {} baud (QEMU -serial), wmr-protocol {}; gyro: simulated MEMS (1 kHz); pose source: external poses over the link",
        uart::BAUD,
        wmr_protocol::PROTOCOL_VERSION
    );
    hprintln!("state: HOLD (motors off). Load a reference with wmr and arm.");

    static ROBOT: StaticCell<Robot> = StaticCell::new();
    let device = ROBOT.init(device);
    let (rx, tx) = uart::Uart0::new(time::CPU_HZ).split();
    // The executor runs in an interrupt at the lowest priority; the time
    // driver's and the UART's interrupts (priority 0) preempt it. Thread
    // mode spins on NOPs instead of sleeping (WFI): under `-icount
    // sleep=off` (run.sh) virtual time is then the instruction count alone,
    // so a host that keeps QEMU off the CPU cannot make a tick late (with
    // WFI and sleep=on, idle virtual time followed the host's clock, and a
    // host wake-up 5 ms late latched LoopOverrun: README, "QEMU command
    // line"). The guest runs slower than real time. Not `spin_loop()`: its
    // YIELD makes QEMU leave the CPU loop on every instruction.
    let mut nvic = cp.NVIC;
    // SAFETY: set before the executor starts, as InterruptExecutor requires.
    unsafe { nvic.set_priority(ExecutorIrq, EXECUTOR_PRIORITY) };
    let spawner = EXECUTOR.start(ExecutorIrq);
    spawn_all(spawner, device, task, rx, tx, cfg, period_us);
    loop {
        cortex_m::asm::nop();
    }
}

/// The executor's interrupt: Timer1's line (IRQ 9), a timer this board
/// leaves stopped, pended from software by the executor.
const EXECUTOR_IRQ: i16 = 9;
/// Lowest priority (whatever the number of priority bits implemented).
const EXECUTOR_PRIORITY: u8 = 0xE0;

#[derive(Clone, Copy)]
struct ExecutorIrq;

// SAFETY: IRQ 9 is Timer1's on the mps2-an386; nothing enables Timer1.
unsafe impl cortex_m::interrupt::InterruptNumber for ExecutorIrq {
    fn number(self) -> u16 {
        EXECUTOR_IRQ as u16
    }
}

static EXECUTOR: InterruptExecutor = InterruptExecutor::new();

fn spawn_all(
    spawner: SendSpawner,
    device: &'static mut Robot,
    task: ControlTask,
    rx: uart::Rx,
    tx: uart::Tx,
    cfg: controller_core::runtime::RuntimeConfig,
    period_us: u32,
) {
    let ok = [
        control(EmuBoard::new(), device, task).map(|t| spawner.spawn(t)),
        link_rx(rx).map(|t| spawner.spawn(t)),
        link_tx(tx).map(|t| spawner.spawn(t)),
        plant(cfg, period_us).map(|t| spawner.spawn(t)),
        #[cfg(feature = "stall-test")]
        stall().map(|t| spawner.spawn(t)),
    ];
    if ok.iter().any(|r| r.is_err()) {
        log::fail("task spawn");
    }
}

#[embassy_executor::task]
async fn control(mut board: EmuBoard, dev: &'static mut Robot, task: ControlTask) {
    robot_app::control_task(&mut board, dev, &PIPES, task).await
}

#[embassy_executor::task]
async fn link_rx(mut rx: uart::Rx) {
    pump_rx(&mut rx, &PIPES).await
}

#[embassy_executor::task]
async fn link_tx(mut tx: uart::Tx) {
    pump_tx(&mut tx, &PIPES).await
}

#[embassy_executor::task]
async fn plant(cfg: controller_core::runtime::RuntimeConfig, period_us: u32) {
    log::fail(sim::plant_task(cfg, period_us).await)
}

/// `stall-test`: 3 s after boot, a task hogs the executor for good (a
/// driver hanging); the control loop stops, so does the feeding.
#[cfg(feature = "stall-test")]
#[embassy_executor::task]
async fn stall() {
    embassy_time::Timer::after_secs(3).await;
    hprintln!("stall-test: hogging the executor from now on");
    loop {
        cortex_m::asm::nop();
    }
}

#[exception]
fn SysTick() {
    time::on_systick();
}

/// Device interrupts (cortex-m-rt without a device crate routes them all
/// here with their number).
#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    match irqn {
        uart::UART0_RX_IRQ => uart::on_rx(),
        uart::UART0_TX_IRQ => uart::on_tx(),
        time::TIMER0_IRQ => time::on_timer0(),
        // SAFETY: the executor's own interrupt, after its start.
        EXECUTOR_IRQ => unsafe { EXECUTOR.on_interrupt() },
        _ => {
            sim::kill_motors();
            hprintln!("unexpected interrupt {} (motors off)", irqn);
            debug::exit(debug::EXIT_FAILURE);
        }
    }
}

/// The watchdog's first expiry (its interrupt is wired to NMI): the loop
/// has not fed it for half the timeout. Motors off, then wait for its
/// reset (the other half).
#[exception]
unsafe fn NonMaskableInt() {
    sim::kill_motors();
    hprintln!(
        "WATCHDOG: the control loop stopped feeding; motors off, reset in {} us",
        config::WATCHDOG_TIMEOUT_US / 2
    );
    loop {
        cortex_m::asm::nop();
    }
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    sim::kill_motors();
    hprintln!("HARD FAULT at pc={:#010x} (motors off)", frame.pc());
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::nop();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    sim::kill_motors();
    hprintln!("PANIC: {} (motors off)", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::nop();
    }
}
