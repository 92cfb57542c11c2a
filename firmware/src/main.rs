//! Differential-drive trajectory-tracking firmware: controller-core's runtime
//! at 1 kHz from two quadrature encoders to two PWM H-bridge channels.
//!
//! Everything that is not a register access lives in
//! `controller_core::runtime` (host-tested); this crate binds the embassy
//! peripherals to its traits ([`board`]), sets the constants ([`config`]),
//! and adds the watchdog, the panic path and the telemetry.
#![no_std]
#![no_main]

mod board;
mod config;
mod link;

use controller_core::runtime::{ArmingButton, LoopTimer, NoGyro, WheelOdometryOnly};
use defmt::{error, info, unwrap, warn};
use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_time::{Duration, Instant, Ticker};
use static_cell::StaticCell;
use wmr_device::Device;
use wmr_protocol::RunStateMsg;
#[cfg(feature = "rtt-telemetry")]
use {controller_core::runtime::CycleStats, cortex_m::peripheral::DWT};

/// The host-link device and runtime with the firmware's pose history.
type Robot = Device<{ config::POSE_HISTORY_TICKS }>;

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // Motor lines defined low before the clocks start (HSE start, PLL lock).
    board::outputs_low_early();
    let mut board = board::init();

    // DWT cycle counter for the control step's execution time (RTT
    // telemetry).
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
        "loop {=u64} Hz, PWM {=u32} Hz full scale {=u16} counts, watchdog {=u32} us, telemetry every {=u32} ticks",
        board::CONTROL_HZ,
        board::PWM_FREQ.0,
        full_scale,
        board::WATCHDOG_TIMEOUT_US,
        board::TELEMETRY_DECIMATION
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
    info!("gyro: none (the IMU driver is a later step): heading from the wheels");
    info!(
        "pose source: external poses from the host link (wmr pose-feed), used up to {=usize} ms late; without them wheel odometry only, blind to slip and actuator faults",
        controller_core::estimator::PoseEstimator::<{ config::POSE_HISTORY_TICKS }>::GUARANTEED_DEPTH_TICKS
    );

    let (device, timer, button) = match (
        Robot::with_estimator(config::DEVICE, cfg, config::ESTIMATOR),
        LoopTimer::from_config(&cfg),
        ArmingButton::new(board::BUTTON_DEBOUNCE_TICKS),
    ) {
        (Ok(d), Ok(t), Ok(b)) => (d, t, b),
        _ => {
            // Never armed: motors stay off, the watchdog is not started.
            error!("invalid configuration; motors stay disabled");
            loop {
                cortex_m::asm::wfi();
            }
        }
    };
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
    spawner.spawn(unwrap!(control_task(board, device, timer, button).ok()));
}

#[embassy_executor::task]
async fn control_task(
    mut b: board::Board,
    dev: &'static mut Robot,
    mut timer: LoopTimer,
    mut button: ArmingButton,
) {
    let mut ticker = Ticker::every(Duration::from_hz(board::CONTROL_HZ));
    b.watchdog.unleash();
    // Execution time of the step in CPU cycles: only the RTT telemetry
    // reports it.
    #[cfg(feature = "rtt-telemetry")]
    let mut cycles = CycleStats::new();
    let mut state = dev.state();
    let mut n: u32 = 0;
    loop {
        // Late ticks arrive back to back; the timer measures them against
        // the schedule t0 + n·1 ms and gives the runtime the true dt.
        ticker.next().await;
        let now_us = Instant::now().as_micros() as u32;
        let timing = timer.tick(now_us);

        // Host link: bytes in and out through bounded pipes, never waiting.
        link::receive(dev);
        #[cfg(feature = "rtt-telemetry")]
        let c0 = DWT::cycle_count();
        let rep = dev.tick(
            now_us,
            &mut b.encoders,
            &mut b.motors,
            &mut NoGyro,
            &mut WheelOdometryOnly,
            timing,
        );
        #[cfg(feature = "rtt-telemetry")]
        cycles.record(DWT::cycle_count().wrapping_sub(c0));
        link::transmit(dev);
        b.watchdog.pet();

        // Operator button: arm / disarm / clear a latched stop, without a host.
        if button.press(b.button.pressed()) {
            dev.button_pressed(&mut b.motors);
        }
        if let Some(reason) = rep.stopped {
            error!("SAFE STOP latched: {} (motors disabled)", reason);
        }
        if let Some(h) = rep.pace.transition {
            warn!(
                "health: {} -> {} ({}), transitions={=u32}",
                h.from, h.to, h.reason, rep.pace.transitions
            );
        }
        if dev.state() != state {
            state = dev.state();
            match state {
                RunStateMsg::Running => info!("state: RUNNING (reference t = 0)"),
                RunStateMsg::Stopping => info!("state: STOPPING (controlled stop)"),
                RunStateMsg::Hold => info!("state: HOLD (motors off)"),
                RunStateMsg::Stopped => error!("state: STOPPED (press the button or `wmr clear`)"),
            }
        }

        n = n.wrapping_add(1);
        // RTT telemetry (opt-in: the host link carries telemetry, `wmr record`).
        #[cfg(feature = "rtt-telemetry")]
        if n % board::TELEMETRY_DECIMATION == 0 {
            telemetry(&rep, &mut cycles);
        }
        #[cfg(feature = "rtt-telemetry")]
        if n % board::CONTROL_HZ as u32 == 0 {
            let s = dev.control().status();
            let t = timer.stats();
            info!(
                "status ticks={=u32} run={=u32} overruns={=u32} late={=u32} max_late_us={=u32} max_loop_us={=u32} enc_jumps={=u32} input_faults={=u32} tau_sat={=u32} duty_sat={=u32} stops={=u32}",
                s.ticks,
                s.run_ticks,
                s.overruns,
                t.late_ticks,
                t.max_lateness_us,
                s.max_loop_time_us,
                s.encoder_jumps,
                s.input_faults,
                s.torque_saturated,
                s.duty_saturated,
                s.stops
            );
        }
    }
}

/// Two decimated lines: tracking (`trk`) and estimates/timing (`est`).
#[cfg(feature = "rtt-telemetry")]
fn telemetry(r: &controller_core::runtime::TickReport, cycles: &mut CycleStats) {
    let d = &r.diag;
    let p = &r.pose;
    info!(
        "trk t={=f32} pose=[{=f32},{=f32},{=f32}] e=[{=f32},{=f32},{=f32}] eta=[{=f32},{=f32}] tau=[{=f32},{=f32}] duty=[{=i32},{=i32}]",
        r.t_s,
        p.x_m,
        p.y_m,
        p.theta_rad,
        d.error[0],
        d.error[1],
        d.error[2],
        r.eta.v_mps,
        r.eta.omega_radps,
        r.torque_nm[0],
        r.torque_nm[1],
        r.duty[0].signed(),
        r.duty[1].signed()
    );
    info!(
        "pace tau={=f32} s={=f32} health={} reason={} eps_hat={=f32}",
        r.pace.tau_s, r.pace.scale, r.pace.mode, r.pace.reason, r.pace.fault_ratio
    );
    let c = cycles.take();
    info!(
        "est rho=[{=f32},{=f32}] D=[{=f32},{=f32}] F=[{=f32},{=f32}] cyc_mean={=u32} cyc_max={=u32} (SYSCLK {=u32} Hz)",
        d.rho_hat[0],
        d.rho_hat[1],
        d.d_hat[0],
        d.d_hat[1],
        d.f_hat[0],
        d.f_hat[1],
        c.mean(),
        c.max(),
        board::SYSCLK_HZ
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
