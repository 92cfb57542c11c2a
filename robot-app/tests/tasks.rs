//! The firmware's tasks on the host: robot-app's control task (the code
//! the STM32 and emulated boards run) on embassy's std executor with
//! embassy-time's mock clock, a mock board with the simulated robot, and a
//! host speaking wmr-protocol through the link pipes (tests/common).
//!
//! The mock clock moves only when the test thread advances it, one period
//! at a time, and waits for every tick due: timing is exact, so a tick
//! that is late, missing or doubled is a bug, not noise.

mod common;

use std::sync::atomic::Ordering;
use std::time::Duration as StdDuration;

use common::*;
use embassy_time::{Duration, MockDriver};
use wmr_protocol::{Event, Reply, Request, RunStateMsg, StopCode, TELEMETRY_ALL};

/// Safety limits of the configuration under test (SafetyLimits::EXAMPLE).
fn safety() -> controller_core::runtime::SafetyLimits {
    runtime_config().safety
}

fn assert_on_schedule(times_us: &[u64], first_tick: u64) {
    for (k, &t) in times_us.iter().enumerate() {
        assert_eq!(
            t,
            (first_tick + k as u64) * PERIOD_US,
            "tick {k} ran at {t} µs, off the 1 kHz schedule"
        );
    }
}

/// 1 kHz cadence; the watchdog started before the first tick and fed once
/// per completed tick; the status counts the same.
#[test]
fn ticks_at_1khz_and_feeds_the_watchdog_once_per_tick() {
    let mut rig = Rig::start();
    rig.run_ms(1000);
    let o = rig.obs();
    assert_eq!(o.tick_times_us.len(), 1000);
    assert_on_schedule(&o.tick_times_us, 1);
    assert_eq!(
        o.watchdog_started_at,
        Some(0),
        "started before the first tick"
    );
    assert_eq!(o.feeds, 1000);
    let s = o.last_status.expect("a status every 1000 ticks");
    assert_eq!((s.ticks, s.watchdog_feeds), (1000, 1000));
    assert_eq!(
        (s.late_ticks, s.overrun_episodes, s.max_lateness_us),
        (0, 0, 0)
    );
    assert!(!o.motors_enabled, "hold at boot: motors off");
}

/// A task that blocks the executor (or a hung driver) starves the control
/// task: the watchdog is not fed for as long (the STM32's IWDG resets the
/// chip after 50 ms), and when the loop resumes the catch-up burst is one
/// overrun episode that latches a safe stop while running.
#[test]
fn a_stalled_executor_stops_the_feeding_and_latches_a_stop_when_running() {
    let mut rig = Rig::start();
    rig.run_ms(10);
    rig.press_button(DEBOUNCE_TICKS as u32);
    assert_eq!(
        rig.state(),
        RunStateMsg::Running,
        "the button arms its circle"
    );
    rig.run_ms(100);
    assert!(rig.obs().motors_enabled);
    let (ticks0, feeds0) = (rig.ticks(), rig.obs().feeds);

    let k = rig.knobs();
    k.hog_hold.store(true, Ordering::SeqCst);
    k.hog_go.signal(());
    while !k.hog_active.load(Ordering::SeqCst) {
        std::thread::sleep(StdDuration::from_micros(100));
    }
    // 60 ms of robot time pass while the executor is blocked.
    for _ in 0..60 {
        MockDriver::get().advance(Duration::from_micros(PERIOD_US));
    }
    std::thread::sleep(StdDuration::from_millis(30));
    assert_eq!(rig.ticks(), ticks0, "no tick while the executor is blocked");
    assert_eq!(rig.obs().feeds, feeds0, "no feed while the loop is stalled");

    k.hog_hold.store(false, Ordering::SeqCst);
    let due = rig.due_ticks();
    rig.wait_until("the loop catches up", |o| o.feeds as usize >= due);
    rig.run_ms(5);
    let o = rig.obs();
    assert_eq!(o.feeds as usize, o.tick_times_us.len(), "feeding resumed");
    assert!(
        o.events
            .iter()
            .any(|e| e.starts_with("SafeStop(LoopOverrun")),
        "a sustained overrun latches a safe stop: {:?}",
        o.events
    );
    assert!(!o.motors_enabled, "motors off after the stop");
    drop(o);
    let s = rig.status();
    assert_eq!(s.state, RunStateMsg::Stopped);
    assert_eq!(
        s.counters.overruns, 1,
        "the stall and its burst are one episode"
    );
    assert_eq!(s.counters.stops, 1);
}

/// Ticks slower than the period: each is late by more than the last; the
/// runtime latches after `max_consecutive_overruns` of them. Once the ticks
/// are fast again the loop is back on its schedule.
#[test]
fn sustained_slow_ticks_latch_a_stop_and_the_loop_recovers_its_schedule() {
    let mut rig = Rig::start();
    rig.press_button(DEBOUNCE_TICKS as u32);
    rig.run_ms(50);
    assert_eq!(rig.state(), RunStateMsg::Running);
    let ticks0 = rig.ticks();
    rig.knobs().tick_cost_us.store(1200, Ordering::SeqCst);
    MockDriver::get().advance(Duration::from_micros(PERIOD_US));
    rig.wait_until("the overrun stop", |o| {
        o.events
            .iter()
            .any(|e| e.starts_with("SafeStop(LoopOverrun"))
    });
    rig.knobs().tick_cost_us.store(0, Ordering::SeqCst);
    let slow_ticks = rig.obs().stop_at_tick.unwrap() - ticks0;
    // Lateness grows by 0.2 ms per slow tick; the limit is
    // `overrun_limit_us`, then `max_consecutive_overruns` late ticks latch.
    let lim = safety();
    let first_late = (lim.overrun_limit_us / 200 + 1) as usize;
    let expected = first_late + lim.max_consecutive_overruns as usize;
    assert!(
        slow_ticks.abs_diff(expected) <= 1,
        "latched after {slow_ticks} slow ticks, expected about {expected}"
    );
    // The catch-up burst (every tick due, back to back), then on schedule.
    let due = rig.due_ticks();
    rig.wait_until("the loop catches up", |o| o.feeds as usize >= due);
    // The slow ticks left the clock between two periods: advance it to the
    // next period boundary (the test's clock steps are whole periods).
    let rem = rig.now_us() % PERIOD_US;
    MockDriver::get().advance(Duration::from_micros(PERIOD_US - rem));
    rig.run_ms(2);
    let n = rig.ticks();
    rig.run_ms(100);
    let o = rig.obs();
    let first = o.tick_times_us[n] / PERIOD_US;
    assert_on_schedule(&o.tick_times_us[n..], first);
    assert_eq!(o.tick_times_us.len() - n, 100);
    assert_eq!(o.feeds as usize, o.tick_times_us.len());
}

/// The button: presses shorter than the debounce never count; a full press
/// arms; a long press counts once; a press disarms; a latched stop is
/// cleared by one press and the next arms again.
#[test]
fn button_debounce_and_arming_policy() {
    let mut rig = Rig::start();
    rig.run_ms(5);
    for n in [1, 5, DEBOUNCE_TICKS as u32 - 1] {
        rig.press_button(n);
        rig.run_ms(3);
    }
    assert!(rig.obs().states.is_empty(), "glitches do nothing");
    assert!(!rig.obs().motors_enabled);

    rig.press_button(DEBOUNCE_TICKS as u32);
    assert_eq!(rig.state(), RunStateMsg::Running);
    rig.run_ms(20);
    assert!(rig.obs().motors_enabled, "running drives the motors");

    // Held for 500 ticks: one press (disarm), not a disarm-arm-disarm train.
    rig.knobs().button.store(true, Ordering::SeqCst);
    rig.run_ms(500);
    rig.knobs().button.store(false, Ordering::SeqCst);
    rig.run_ms(5);
    {
        let o = rig.obs();
        let running = o
            .states
            .iter()
            .filter(|s| s.1 == RunStateMsg::Running)
            .count();
        assert_eq!(running, 1, "a long press counts once: {:?}", o.states);
        assert_eq!(o.states.last().unwrap().1, RunStateMsg::Hold);
        assert!(!o.motors_enabled);
    }

    // A latched stop (host emergency stop): one press clears, the next arms.
    assert!(matches!(
        rig.request(&Request::EmergencyStop),
        Reply::Ack { .. }
    ));
    rig.run_ms(2);
    assert_eq!(rig.state(), RunStateMsg::Stopped);
    rig.press_button(DEBOUNCE_TICKS as u32);
    assert_eq!(rig.state(), RunStateMsg::Hold, "a press clears the latch");
    assert!(!rig.obs().motors_enabled, "clearing does not arm");
    rig.press_button(DEBOUNCE_TICKS as u32);
    assert_eq!(rig.state(), RunStateMsg::Running);
}

/// A host flooding the link with garbage (3 x 64 B before every tick of
/// the mock clock, more than the 128 B a tick takes: the 512 B pipe fills
/// whatever the machine's speed): every tick on time, at most
/// `RX_BYTES_PER_TICK` bytes handled per tick, the excess dropped and
/// counted, the garbage counted as frame errors, nothing armed.
#[test]
fn a_flooding_host_never_delays_a_tick() {
    let mut rig = Rig::start();
    let garbage: Vec<u8> = (0..64u32).map(|i| (i * 37 + 11) as u8).collect();
    let (mut flooded, mut kept) = (0u32, 0u32);
    for _ in 0..300 {
        for _ in 0..3 {
            kept += rig.pipes.port_received(&garbage) as u32;
            flooded += garbage.len() as u32;
        }
        rig.run_ms(1);
    }
    let dropped = rig.pipes.rx_dropped_bytes();
    assert_eq!(flooded, kept + dropped, "every byte kept or counted");
    assert!(dropped > 0, "the flood exceeded the pipe");
    let consumed = kept as usize - rig.pipes.rx_len();
    assert!(
        consumed <= 300 * wmr_device::RX_BYTES_PER_TICK,
        "the control task took {consumed} bytes in 300 ticks"
    );
    {
        let o = rig.obs();
        assert_eq!(o.tick_times_us.len(), 300);
        assert_on_schedule(&o.tick_times_us, 1);
        assert!(o.states.is_empty(), "garbage never changes the state");
    }
    rig.resync();
    let s = rig.status();
    assert!(
        s.counters.rx_errors > 0,
        "garbage counted: {:?}",
        s.counters
    );
    assert_eq!(s.state, RunStateMsg::Hold);
}

/// A host that goes silent while the robot moves under its control: a
/// controlled stop once the link timeout has passed, ticks on time
/// throughout. A host that stops reading: telemetry dropped and counted,
/// ticks on time.
#[test]
fn link_silence_stops_the_robot_and_a_deaf_host_costs_only_telemetry() {
    let mut rig = Rig::start();
    let r = rig.request(&Request::Velocity {
        v_mps: 0.2,
        omega_radps: 0.0,
        timeout_ms: 5000,
    });
    assert!(matches!(r, Reply::Ack { .. }), "{r:?}");
    assert!(matches!(rig.request(&Request::Arm), Reply::Ack { .. }));
    let last_frame_us = rig.now_us();
    let timeout_us = wmr_device::LinkConfig::DEFAULT.link_timeout_ms as u64 * 1000;
    rig.run_ms(400);
    assert_eq!(
        rig.state(),
        RunStateMsg::Running,
        "silence shorter than the timeout"
    );
    rig.run_ms(1600);
    {
        let o = rig.obs();
        let stop = o
            .states
            .iter()
            .find(|s| s.1 == RunStateMsg::Stopping)
            .expect("a controlled stop");
        let after = stop.0 - last_frame_us;
        assert!(
            after >= timeout_us && after <= timeout_us + 5 * PERIOD_US,
            "stopped {after} µs after the last frame (timeout {timeout_us} µs)"
        );
        assert_eq!(o.states.last().unwrap().1, RunStateMsg::Hold);
        let n = o.tick_times_us.len();
        assert_eq!(n, rig.due_ticks());
        assert_on_schedule(&o.tick_times_us, 1);
    }
    rig.read_replies();
    assert!(
        rig.replies
            .iter()
            .any(|r| matches!(r, Reply::Event(Event::LinkLost))),
        "the robot tells the host why it stopped"
    );
    assert_eq!(rig.status().last_stop, Some(StopCode::LinkSilence));

    // Telemetry at 200 Hz that nobody reads for 2 s.
    let r = rig.request(&Request::SetTelemetry {
        selection: TELEMETRY_ALL,
        rate_hz: 200,
    });
    assert!(matches!(r, Reply::Ack { .. }), "{r:?}");
    let n0 = rig.ticks();
    rig.run_ms(2000);
    assert_eq!(rig.ticks() - n0, 2000);
    let s = rig.status();
    assert!(
        s.counters.tx_dropped > 0,
        "dropped telemetry counted: {:?}",
        s.counters
    );
}

/// The link port's own losses (its hardware's receive errors, bytes its
/// driver's ring dropped) reach the host's `wmr status` through the
/// control task, which copies them into the device's board report.
#[test]
fn the_ports_losses_reach_the_hosts_status() {
    let mut rig = Rig::start();
    rig.run_ms(5);
    let s = rig.status();
    assert_eq!((s.board.port_rx_errors, s.board.port_rx_dropped), (0, 0));
    rig.pipes.count_port_errors(3);
    // A driver ring of 0 bytes: every byte is a ring drop.
    for _ in 0..5 {
        assert!(!rig.pipes.port_hw_byte(0));
    }
    rig.run_ms(2);
    let s = rig.status();
    assert_eq!(s.board.port_rx_errors, 3);
    assert_eq!(s.board.port_rx_dropped, 5);
}
