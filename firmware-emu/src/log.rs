//! The board's log: lines over semihosting to QEMU's stdout.
//!
//! `run.sh` parses the `status` lines (key=value); keep their keys.

use cortex_m_semihosting::{debug, hprintln};
use robot_app::AppEvent;

/// Prints one application event.
pub fn event(event: &AppEvent<'_>) {
    match event {
        AppEvent::Started => hprintln!(
            "started: control loop at {} Hz, watchdog on (reset {} us after the last feed)",
            crate::config::CONTROL_HZ,
            crate::config::WATCHDOG_TIMEOUT_US
        ),
        AppEvent::State(s) => hprintln!("state: {:?}", s),
        AppEvent::SafeStop(r) => hprintln!("SAFE STOP latched: {:?} (motors disabled)", r),
        AppEvent::Health {
            transition,
            transitions,
        } => hprintln!(
            "health: {:?} -> {:?} ({:?}), transitions={}",
            transition.from,
            transition.to,
            transition.reason,
            transitions
        ),
        AppEvent::Status(s) => {
            let p = crate::sim::report();
            hprintln!(
                "status ticks={} late={} overruns={} max_late_us={} insn_mean={} insn_max={} insn_max_link={} link_ticks={} feeds={} rx_dropped={} plant_insn_max={} true_pose=[{:.3},{:.3},{:.3}]",
                s.ticks,
                s.late_ticks,
                s.overrun_episodes,
                s.max_lateness_us,
                s.tick_cycles_mean,
                s.tick_cycles_max,
                s.tick_cycles_max_link,
                s.link_ticks,
                s.watchdog_feeds,
                s.rx_dropped_bytes,
                p.step_insn_max,
                p.pose[0],
                p.pose[1],
                p.pose[2]
            )
        }
        // Telemetry goes over the link (`wmr record`); other events: none yet.
        _ => {}
    }
}

/// A fatal error of the emulated board: motors off, one line, QEMU exits
/// with status 1.
pub fn fail(what: &str) -> ! {
    crate::sim::kill_motors();
    hprintln!("FATAL: {}", what);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
