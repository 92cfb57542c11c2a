//! The server's decisions, without any I/O (as [`super::mux`] is its
//! routing): whether the robot reset ([`ResetWatch`]), which clock sample
//! to keep ([`BestClock`]), when to keep the link alive and when to stay
//! silent so that the robot's own link-silence stop protects it
//! ([`KeepAlive`]), and the client requests held while the link is down
//! ([`Held`]). Time comes in as arguments; `server.rs` is the I/O loop
//! around these.

use super::mux::ClientId;
use crate::session::ClockSample;
use crate::timing::LinkTiming;
use std::time::{Duration, Instant};
use wmr_protocol::{Request, RunStateMsg};

/// The robot's clock going back by more than this is a reset \[µs\]
/// (frames may arrive a little out of order through the server's own
/// requests and a client's).
pub const RESET_MARGIN_US: i32 = 10_000;
/// Readings of the robot's clock older than this are not compared (the
/// u32 µs clock wraps after 71 min; half of that is unambiguous).
pub const CLOCK_COMPARE_WITHIN: Duration = Duration::from_secs(1800);

/// Tells a robot reset from the robot's clock and tick count going back.
#[derive(Clone, Copy, Debug, Default)]
pub struct ResetWatch {
    last_robot_us: Option<(u32, Instant)>,
    last_ticks: Option<u32>,
}

impl ResetWatch {
    /// Why a clock reading of `robot_us` at `now` is a reset (its clock
    /// went back by more than [`RESET_MARGIN_US`]), if it is.
    pub fn clock_went_back(&self, robot_us: u32, now: Instant) -> Option<String> {
        let (last, at) = self.last_robot_us?;
        let back = robot_us.wrapping_sub(last) as i32;
        (back < -RESET_MARGIN_US && now.duration_since(at) < CLOCK_COMPARE_WITHIN).then(|| {
            format!(
                "its clock went back from {:.3} s to {:.3} s",
                last as f64 * 1e-6,
                robot_us as f64 * 1e-6
            )
        })
    }

    /// A clock reading (telemetry, a clock sync): the reset it reveals.
    pub fn clock(&mut self, robot_us: u32, now: Instant) -> Option<String> {
        let why = self.clock_went_back(robot_us, now);
        self.last_robot_us = Some((robot_us, now));
        why
    }

    /// A status (clock and tick count): the reset it reveals.
    pub fn status(&mut self, robot_us: u32, ticks: u32, now: Instant) -> Option<String> {
        let why = self.clock_went_back(robot_us, now).or_else(|| {
            self.last_ticks
                .filter(|&l| ticks < l)
                .map(|l| format!("its tick count went back from {l} to {ticks}"))
        });
        self.last_robot_us = Some((robot_us, now));
        self.last_ticks = Some(ticks);
        why
    }

    /// After a reset: the tick count starts again.
    pub fn forget_ticks(&mut self) {
        self.last_ticks = None;
    }
}

/// How long the best clock sample is kept against slower ones.
pub const CLOCK_KEEP: Duration = Duration::from_secs(10);

/// The best recent clock sample: the shortest round trip of the last
/// [`CLOCK_KEEP`] (its midpoint is the best estimate of when the robot
/// read its clock), replaced by any sample once older.
#[derive(Clone, Copy, Debug, Default)]
pub struct BestClock {
    best: Option<(ClockSample, Instant)>,
}

impl BestClock {
    /// Offers a sample taken at `now`; `true` when it is the first.
    pub fn offer(&mut self, s: ClockSample, now: Instant) -> bool {
        let first = self.best.is_none();
        let better = self
            .best
            .is_none_or(|(c, at)| s.rtt_us <= c.rtt_us || now.duration_since(at) > CLOCK_KEEP);
        if better {
            self.best = Some((s, now));
        }
        first
    }

    /// The sample kept.
    pub fn best(&self) -> Option<ClockSample> {
        self.best.map(|(c, _)| c)
    }
}

/// What the keep-alive schedule sends now.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Due {
    /// A clock-sync keep-alive.
    pub keep_alive: bool,
    /// A status request.
    pub status: bool,
}

/// The server's own keep-alives and status requests while the link is up:
/// sent while a client has sent something within the robot's link timeout
/// or the robot is not moving; while it moves and no client is alive the
/// server is silent (a probe after twice the link timeout without any
/// frame), so that the robot's link-silence stop fires when its driver is
/// gone (D97).
#[derive(Clone, Copy, Debug, Default)]
pub struct KeepAlive {
    last_keep: Option<Instant>,
    last_status: Option<Instant>,
}

impl KeepAlive {
    /// What is due at `now`: `last_client_rx` the last client frame,
    /// `last_tx` the last frame to the robot, `state` its last known run
    /// state, `status_every` the status period. What it returns is taken
    /// as sent.
    pub fn due(
        &mut self,
        now: Instant,
        timing: &LinkTiming,
        status_every: Duration,
        last_client_rx: Option<Instant>,
        last_tx: Instant,
        state: Option<RunStateMsg>,
    ) -> Due {
        let lt = timing.link_timeout;
        let client_alive = last_client_rx.is_some_and(|t| now.duration_since(t) < lt);
        let moving = matches!(state, Some(RunStateMsg::Running | RunStateMsg::Stopping));
        let probe = now.duration_since(last_tx) >= 2 * lt;
        let mut due = Due::default();
        if client_alive || !moving || probe {
            if self
                .last_keep
                .is_none_or(|t| now.duration_since(t) >= timing.keep_alive)
            {
                due.keep_alive = true;
                self.last_keep = Some(now);
            }
            if self
                .last_status
                .is_none_or(|t| now.duration_since(t) >= status_every)
            {
                due.status = true;
                self.last_status = Some(now);
            }
        }
        due
    }

    /// A status was just requested otherwise (after the handshake).
    pub fn status_sent(&mut self, now: Instant) {
        self.last_status = Some(now);
    }
}

/// Client requests received while the link is not up: held for
/// `hold_for`, at most `max` (the oldest dropped first).
#[derive(Debug)]
pub struct Held {
    hold_for: Duration,
    max: usize,
    held: Vec<(ClientId, u16, Request, Instant)>,
}

impl Held {
    /// An empty queue.
    pub fn new(hold_for: Duration, max: usize) -> Self {
        Self {
            hold_for,
            max: max.max(1),
            held: Vec::new(),
        }
    }

    /// Holds a request received at `now`; returns how many were dropped
    /// (expired ones are not counted here: [`Self::release`] counts them).
    pub fn hold(&mut self, id: ClientId, seq: u16, req: Request, now: Instant) -> u64 {
        let mut dropped = 0;
        let before = self.held.len();
        let hold_for = self.hold_for;
        self.held.retain(|h| now.duration_since(h.3) < hold_for);
        let expired = (before - self.held.len()) as u64;
        if self.held.len() >= self.max {
            self.held.remove(0);
            dropped += 1;
        }
        self.held.push((id, seq, req, now));
        dropped + expired
    }

    /// The link is up at `now`: the requests still fresh whose client is
    /// still connected (`connected`), in arrival order, and how many were
    /// dropped.
    pub fn release(
        &mut self,
        now: Instant,
        connected: impl Fn(ClientId) -> bool,
    ) -> (Vec<(ClientId, u16, Request)>, u64) {
        let mut out = Vec::new();
        let mut dropped = 0;
        for (id, seq, req, at) in std::mem::take(&mut self.held) {
            if now.duration_since(at) < self.hold_for && connected(id) {
                out.push((id, seq, req));
            } else {
                dropped += 1;
            }
        }
        (out, dropped)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reset is the robot's clock going back by more than the margin:
    /// not a small step back (frames out of order), not the u32 clock's
    /// wrap (forward through zero), and a tick count going back is one
    /// even when the clock looks fine.
    #[test]
    fn resets_are_the_clock_or_the_ticks_going_back() {
        let t = Instant::now();
        let mut w = ResetWatch::default();
        assert_eq!(w.clock(5_000_000, t), None);
        assert_eq!(w.clock(4_995_000, t), None, "5 ms back: out of order");
        assert!(w
            .clock(1_000_000, t)
            .unwrap()
            .contains("from 4.995 s to 1.000 s"));
        let mut w = ResetWatch::default();
        assert_eq!(w.clock(u32::MAX - 1_000, t), None);
        assert_eq!(w.clock(2_000, t), None, "the wrap is forward");
        let mut w = ResetWatch::default();
        assert_eq!(w.status(10_000_000, 900, t), None);
        assert!(w.status(10_500_000, 20, t).unwrap().contains("tick count"));
        // Readings half an hour apart are not compared (ambiguous wrap).
        let mut w = ResetWatch::default();
        w.clock(3_000_000_000, t);
        assert_eq!(w.clock(1_000, t + CLOCK_COMPARE_WITHIN), None);
    }

    /// The kept sample is the shortest round trip of the last 10 s; an
    /// older one gives way to any new one (the clocks drift).
    #[test]
    fn the_best_clock_is_the_shortest_recent_round_trip() {
        let s = |rtt_us| ClockSample {
            robot_us: 0,
            host_mid_us: 0,
            rtt_us,
        };
        let t = Instant::now();
        let mut c = BestClock::default();
        assert!(c.offer(s(300), t));
        assert!(!c.offer(s(900), t + Duration::from_secs(1)));
        assert_eq!(c.best(), Some(s(300)));
        c.offer(s(200), t + Duration::from_secs(2));
        assert_eq!(c.best(), Some(s(200)));
        c.offer(s(900), t + Duration::from_secs(13));
        assert_eq!(c.best(), Some(s(900)));
    }

    /// D97: a moving robot whose clients fell silent hears nothing from
    /// the server until the probe after twice its link timeout, so its
    /// own link-silence stop (at one link timeout) comes first; a robot at
    /// rest or one with a live client is kept alive every keep-alive period.
    #[test]
    fn a_moving_robot_without_a_live_client_is_left_to_its_silence_stop() {
        let timing = LinkTiming::from_link_timeout_ms(500);
        let every = Duration::from_millis(250);
        let t0 = Instant::now();
        let ms = |m| t0 + Duration::from_millis(m);
        let running = Some(RunStateMsg::Running);
        let mut k = KeepAlive::default();
        // A client spoke at t0: kept alive while it is within 500 ms.
        let d = k.due(ms(0), &timing, every, Some(ms(0)), ms(0), running);
        assert_eq!(
            d,
            Due {
                keep_alive: true,
                status: true
            }
        );
        assert_eq!(
            k.due(ms(50), &timing, every, Some(ms(0)), ms(0), running),
            Due::default()
        );
        assert!(
            k.due(ms(100), &timing, every, Some(ms(0)), ms(0), running)
                .keep_alive
        );
        // The client silent since t0; the robot still running: nothing
        // from 500 ms (its link timeout) until the probe at 2 × 500 ms
        // after the last frame sent at 100 ms.
        for m in (500..1100).step_by(10) {
            assert_eq!(
                k.due(ms(m), &timing, every, Some(ms(0)), ms(100), running),
                Due::default(),
                "at {m} ms"
            );
        }
        assert!(
            k.due(ms(1100), &timing, every, Some(ms(0)), ms(100), running)
                .keep_alive
        );
        // At rest: kept alive without any client.
        let mut k = KeepAlive::default();
        let hold = Some(RunStateMsg::Hold);
        assert!(
            k.due(ms(5000), &timing, every, None, ms(4999), hold)
                .keep_alive
        );
    }

    /// Requests held while the link is down: the oldest dropped beyond the
    /// cap, expired ones dropped and counted, those of a client gone
    /// dropped at release, the rest released in order.
    #[test]
    fn held_requests_expire_and_are_capped() {
        let t = Instant::now();
        let mut h = Held::new(Duration::from_secs(1), 2);
        assert_eq!(h.hold(1, 10, Request::GetStatus, t), 0);
        assert_eq!(h.hold(2, 20, Request::Arm, t), 0);
        assert_eq!(
            h.hold(1, 11, Request::Disarm, t),
            1,
            "cap 2: the oldest goes"
        );
        let (out, dropped) = h.release(t + Duration::from_millis(500), |id| id == 1);
        assert_eq!(dropped, 1, "client 2 left");
        assert_eq!(out, vec![(1, 11, Request::Disarm)]);
        assert_eq!(h.hold(1, 12, Request::Arm, t), 0);
        let (out, dropped) = h.release(t + Duration::from_secs(1), |_| true);
        assert!(out.is_empty());
        assert_eq!(dropped, 1, "held 1 s: expired");
    }
}
