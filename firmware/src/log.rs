//! The application's events as defmt lines over RTT (probe-rs shows them).

use defmt::{error, info, warn};
use robot_app::AppEvent;
use wmr_protocol::RunStateMsg;

/// Logs one event of the control task (`sysclk_hz`: the core clock, the
/// unit of the status line's cycle counts).
pub fn event(event: &AppEvent<'_>, sysclk_hz: u32) {
    #[cfg(not(feature = "rtt-telemetry"))]
    let _ = sysclk_hz;
    match event {
        AppEvent::Started => info!("control loop running; watchdog started"),
        AppEvent::State(state) => match state {
            RunStateMsg::Running => info!("state: RUNNING (reference t = 0)"),
            RunStateMsg::Stopping => info!("state: STOPPING (controlled stop)"),
            RunStateMsg::Hold => info!("state: HOLD (motors off)"),
            RunStateMsg::Stopped => error!("state: STOPPED (press the button or `wmr clear`)"),
        },
        AppEvent::SafeStop(reason) => error!("SAFE STOP latched: {} (motors disabled)", reason),
        AppEvent::Health {
            transition: h,
            transitions,
        } => warn!(
            "health: {} -> {} ({}), transitions={=u32}",
            h.from, h.to, h.reason, transitions
        ),
        #[cfg(feature = "rtt-telemetry")]
        AppEvent::Telemetry(r) => telemetry(r),
        #[cfg(feature = "rtt-telemetry")]
        AppEvent::Status(s) => info!(
            "status ticks={=u32} late={=u32} overrun_episodes={=u32} max_late_us={=u32} tick_cyc_mean={=u32} tick_cyc_max={=u32} tick_cyc_max_link={=u32} (SYSCLK {=u32} Hz) rx_dropped={=u32}",
            s.ticks,
            s.late_ticks,
            s.overrun_episodes,
            s.max_lateness_us,
            s.tick_cycles_mean,
            s.tick_cycles_max,
            s.tick_cycles_max_link,
            sysclk_hz,
            s.rx_dropped_bytes
        ),
        _ => {}
    }
}

/// Three decimated lines: tracking (`trk`), pace and estimates (`est`).
#[cfg(feature = "rtt-telemetry")]
fn telemetry(r: &controller_core::runtime::TickReport) {
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
    info!(
        "est rho=[{=f32},{=f32}] D=[{=f32},{=f32}] F=[{=f32},{=f32}]",
        d.rho_hat[0], d.rho_hat[1], d.d_hat[0], d.d_hat[1], d.f_hat[0], d.f_hat[1]
    );
}

/// Starts the DWT cycle counter for the tick's execution time (the RTT
/// status lines of `rtt-telemetry`); nothing without that feature.
pub fn enable_cycle_counter() {
    #[cfg(feature = "rtt-telemetry")]
    {
        let mut cp = defmt::unwrap!(cortex_m::Peripherals::take());
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
    }
}
