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

use controller_core::runtime::{ControlLoop, CycleStats, RunState, TickReport, WheelOdometryOnly};
use cortex_m::peripheral::DWT;
use defmt::{error, info, unwrap, warn};
use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_time::{Duration, Instant, Ticker};

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let board = board::init();

    // DWT cycle counter for the control step's execution time.
    let mut cp = unwrap!(cortex_m::Peripherals::take());
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();

    let full_scale = board.motors.full_scale();
    let full_scale = if full_scale <= u16::MAX as u32 {
        full_scale as u16
    } else {
        0 // rejected by the configuration check below
    };
    let cfg = config::runtime_config(full_scale);
    info!(
        "==== trajectory-tracking firmware {} ====",
        env!("CARGO_PKG_VERSION")
    );
    info!("chip: {}", board::CHIP);
    info!(
        "loop {=u64} Hz, PWM {=u32} Hz full scale {=u16} counts, watchdog {=u32} us, telemetry every {=u32} ticks",
        board::CONTROL_HZ,
        board::PWM_FREQ.0,
        full_scale,
        board::WATCHDOG_TIMEOUT_US,
        board::TELEMETRY_DECIMATION
    );
    info!("controller: {}", cfg.controller);
    info!("reference: {}", cfg.reference);
    info!("initial pose: {}", cfg.initial_pose);
    info!("encoder: {}", cfg.encoder);
    info!("motor: {} inverted {}", cfg.motor, cfg.motor_inverted);
    info!("safety: {}", cfg.safety);
    info!("pose source: wheel odometry only (slip and actuator faults are invisible to it)");

    let control = match ControlLoop::new(cfg) {
        Ok(c) => c,
        Err(e) => {
            // Never armed: motors stay off, the watchdog is not started.
            error!("invalid configuration: {}; motors stay disabled", e);
            loop {
                cortex_m::asm::wfi();
            }
        }
    };
    info!("state: DISARMED (motors off). Press the button to arm.");
    spawner.spawn(unwrap!(control_task(board, control)));
}

/// Debounced press detector.
struct Debounce {
    held: u16,
}

impl Debounce {
    /// True once per press held for `BUTTON_DEBOUNCE_TICKS`.
    fn press(&mut self, down: bool) -> bool {
        if !down {
            self.held = 0;
            return false;
        }
        self.held = self.held.saturating_add(1);
        self.held == board::BUTTON_DEBOUNCE_TICKS
    }
}

#[embassy_executor::task]
async fn control_task(mut b: board::Board, mut cl: ControlLoop) {
    let mut ticker = Ticker::every(Duration::from_hz(board::CONTROL_HZ));
    b.watchdog.unleash();
    let mut cycles = CycleStats::new();
    let mut button = Debounce { held: 0 };
    let mut last_start: Option<Instant> = None;
    let mut state = cl.state();
    let mut n: u32 = 0;
    loop {
        ticker.next().await;
        let start = Instant::now();
        let loop_us = match last_start {
            Some(t) => (start - t).as_micros().min(u32::MAX as u64) as u32,
            None => 0,
        };
        last_start = Some(start);

        let c0 = DWT::cycle_count();
        let rep = cl.tick(
            &mut b.encoders,
            &mut b.motors,
            &mut WheelOdometryOnly,
            loop_us,
        );
        cycles.record(DWT::cycle_count().wrapping_sub(c0));
        b.watchdog.pet();

        // Operator button: arm when disarmed, disarm when running, clear a
        // latched stop (back to disarmed) when stopped.
        if button.press(b.button.pressed()) {
            match cl.state() {
                RunState::Disarmed => match cl.arm() {
                    Ok(()) => {}
                    Err(e) => warn!("arm refused: {}", e),
                },
                RunState::Running => cl.disarm(&mut b.motors),
                RunState::Stopped(_) => cl.reset(),
            }
        }
        if let Some(reason) = rep.stopped {
            error!("SAFE STOP latched: {} (motors disabled)", reason);
        }
        if cl.state() != state {
            state = cl.state();
            match state {
                RunState::Running => info!("state: RUNNING (reference t = 0)"),
                RunState::Disarmed => info!("state: DISARMED (motors off)"),
                RunState::Stopped(r) => error!("state: STOPPED {} (press button to reset)", r),
            }
        }

        n = n.wrapping_add(1);
        if n % board::TELEMETRY_DECIMATION == 0 {
            telemetry(&rep, &mut cycles);
        }
        if n % board::CONTROL_HZ as u32 == 0 {
            let s = cl.status();
            info!(
                "status ticks={=u32} run={=u32} overruns={=u32} max_loop_us={=u32} enc_jumps={=u32} input_faults={=u32} tau_sat={=u32} duty_sat={=u32} stops={=u32}",
                s.ticks,
                s.run_ticks,
                s.overruns,
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
fn telemetry(r: &TickReport, cycles: &mut CycleStats) {
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
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    board::motors_off_raw();
    if let Some(loc) = info.location() {
        error!("PANIC at {}:{} (motors off)", loc.file(), loc.line());
    } else {
        error!("PANIC (motors off)");
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
    loop {
        cortex_m::asm::nop();
    }
}
