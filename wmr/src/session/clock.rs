//! The robot's clock seen from the host: one clock-sync exchange
//! ([`ClockSample`]), the best of a few ([`clock_sync`]), a window of recent
//! ones kept fresh by the keep-alive ([`ClockTracker`]), and what they stamp
//! with: poses in robot time ([`PoseClock`]) and telemetry in host Unix time
//! ([`ros_mcap::TimeMap`]).

use crate::link::{Link, LinkError};
use std::collections::VecDeque;
use std::time::Instant;
use wmr_protocol::{Reply, Request};

/// One clock-sync exchange: the robot's time and the host time (µs since
/// the caller's `t0`) at the midpoint of its round trip.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClockSample {
    /// The robot's clock \[µs\] (u32 on the wire, widened).
    pub robot_us: u64,
    /// Host time at the round trip's midpoint \[µs since t0\].
    pub host_mid_us: u64,
    /// The round trip \[µs\].
    pub rtt_us: u64,
}

impl ClockSample {
    /// The sample of an exchange sent at host time `sent_us` and answered
    /// with `robot_time_us` at `recv_us` (both µs since t0); `None` when the
    /// answer came "before" it was sent (an echo of another t0).
    pub fn of_exchange(sent_us: u64, recv_us: u64, robot_time_us: u32) -> Option<Self> {
        let rtt_us = recv_us.checked_sub(sent_us)?;
        Some(Self {
            robot_us: robot_time_us as u64,
            host_mid_us: sent_us + rtt_us / 2,
            rtt_us,
        })
    }

    /// Clock offset robot − host \[µs\].
    pub fn offset_us(&self) -> i64 {
        self.robot_us as i64 - self.host_mid_us as i64
    }
}

/// Host time since `t0` \[µs\].
pub fn host_us(t0: Instant) -> u64 {
    t0.elapsed().as_micros() as u64
}

/// The best of `n` clock-sync exchanges: the one with the shortest round
/// trip (its midpoint is the best estimate of when the robot read its clock).
pub fn clock_sync(link: &mut Link, t0: Instant, n: usize) -> Result<ClockSample, LinkError> {
    let mut best: Option<ClockSample> = None;
    for _ in 0..n.max(1) {
        let sent = host_us(t0);
        match link.command(&Request::ClockSync { host_time_us: sent })? {
            Reply::ClockSync { robot_time_us, .. } => {
                let s = ClockSample::of_exchange(sent, host_us(t0), robot_time_us).ok_or_else(
                    || LinkError::Unexpected("ClockSync answered before sent".into()),
                )?;
                if best.is_none_or(|b| s.rtt_us < b.rtt_us) {
                    best = Some(s);
                }
            }
            r => return Err(LinkError::Unexpected(format!("{r:?}"))),
        }
    }
    best.ok_or_else(|| LinkError::NoAnswer("ClockSync".into()))
}

/// When a pose was taken, as a `pose-feed` line or a localiser's stamp
/// gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Capture {
    /// No time given: the pose is stamped when its line arrives.
    Arrival,
    /// Host Unix time \[s\] (a localiser's header stamp).
    UnixS(f64),
    /// This long before the line arrived \[s\] (`@-0.08`).
    AgoS(f64),
}

/// Host time and robot time, for stamping poses: `host_us` counts from
/// `t0`, `unix_t0_ns` is the Unix time at `t0`, and the clock offset
/// robot − host is from [`clock_sync`].
#[derive(Clone, Copy, Debug)]
pub struct PoseClock {
    /// Unix time at t0 \[ns\].
    pub unix_t0_ns: u64,
    /// Robot − host clock offset \[µs\].
    pub offset_us: i64,
    /// How much earlier than its arrival a pose without a capture time is
    /// stamped \[µs\]: the offset's uncertainty, so that the stamp is never
    /// in the robot's future (refused as `PoseFromFuture`).
    pub arrival_margin_us: u64,
}

impl PoseClock {
    /// The clock of a sync exchange taken at Unix time `unix_t0_ns` (= t0)
    /// with a robot of control period `period_s`: the robot read its clock
    /// somewhere in the round trip and only at a tick, so the offset is
    /// uncertain by half the round trip plus a period (the arrival margin).
    pub fn from_sync(sync: ClockSample, unix_t0_ns: u64, period_s: f32) -> Self {
        let period_us = if period_s.is_finite() && period_s > 0.0 && period_s < 1.0 {
            (period_s as f64 * 1e6).round() as u64
        } else {
            1000
        };
        Self {
            unix_t0_ns,
            offset_us: sync.offset_us(),
            arrival_margin_us: sync.rtt_us.div_ceil(2) + period_us,
        }
    }

    /// Robot time \[µs, u32 clock\] of a pose taken as `capture` says, its
    /// line having arrived at host time `arrival_us` (µs since t0).
    pub fn robot_stamp_us(&self, capture: Capture, arrival_us: u64) -> u32 {
        let host_us = match capture {
            Capture::Arrival => arrival_us as i64 - self.arrival_margin_us as i64,
            Capture::AgoS(a) => arrival_us as i64 - (a * 1e6).round() as i64,
            Capture::UnixS(t) => {
                ((t * 1e9) as i128 - self.unix_t0_ns as i128).div_euclid(1000) as i64
            }
        };
        (host_us + self.offset_us) as u32
    }

    /// The `ExternalPose` request of a pose of G \[m, m, rad\] with
    /// standard deviations `std`, taken as `capture` says and arrived at
    /// `arrival_us`.
    pub fn request(
        &self,
        pose: [f32; 3],
        std: [f32; 3],
        capture: Capture,
        arrival_us: u64,
    ) -> Request {
        Request::ExternalPose {
            t_robot_us: self.robot_stamp_us(capture, arrival_us),
            pose: wmr_protocol::PoseMsg {
                x_m: pose[0],
                y_m: pose[1],
                theta_rad: pose[2],
            },
            std_dev: std,
        }
    }
}

/// The session's clock: synchronised at the start (the best of 5
/// exchanges), then one exchange per [`ClockTracker::resync`] (the
/// session's keep-alive), the best round trip of the last `window`
/// samples setting the offset, so that stamps follow the robot's clock as
/// it drifts against the host's (a crystal's 50 ppm exceeds a 1 ms arrival
/// margin within 20 s; a simulated robot on a loaded machine falls behind
/// in steps). `pose-feed` keeps a window of 1 (the latest exchange), the
/// ROS 2 bridge 16.
#[derive(Clone, Debug)]
pub struct ClockTracker {
    t0: Instant,
    unix_t0_ns: u64,
    period_s: f32,
    window: usize,
    syncs: VecDeque<ClockSample>,
    last: Instant,
}

impl ClockTracker {
    /// Exchanges in the first sync.
    pub const FIRST_EXCHANGES: usize = 5;

    /// The first sync with a robot of control period `period_s`; `window`
    /// samples kept (at least 1).
    pub fn start(link: &mut Link, period_s: f32, window: usize) -> Result<Self, LinkError> {
        let t0 = Instant::now();
        let unix_t0_ns = ros_mcap::unix_now_ns();
        let first = clock_sync(link, t0, Self::FIRST_EXCHANGES)?;
        Ok(Self::with_first(t0, unix_t0_ns, period_s, window, first))
    }

    /// A tracker whose first sample is `first`, taken against `t0` (Unix
    /// time `unix_t0_ns`): tests and callers with their own exchange.
    pub fn with_first(
        t0: Instant,
        unix_t0_ns: u64,
        period_s: f32,
        window: usize,
        first: ClockSample,
    ) -> Self {
        Self {
            t0,
            unix_t0_ns,
            period_s,
            window: window.max(1),
            syncs: VecDeque::from([first]),
            last: Instant::now(),
        }
    }

    /// Adds a sample (oldest dropped beyond the window).
    pub fn push(&mut self, s: ClockSample) {
        self.syncs.push_back(s);
        while self.syncs.len() > self.window {
            self.syncs.pop_front();
        }
        self.last = Instant::now();
    }

    /// One exchange, added to the window.
    pub fn resync(&mut self, link: &mut Link) -> Result<(), LinkError> {
        let s = clock_sync(link, self.t0, 1)?;
        self.push(s);
        Ok(())
    }

    /// When the last sample was taken.
    pub fn last_sync(&self) -> Instant {
        self.last
    }

    /// The sample with the shortest round trip in the window.
    pub fn best(&self) -> ClockSample {
        // The window is never empty: it starts with one sample and only
        // drops beyond its (≥ 1) length.
        self.syncs
            .iter()
            .copied()
            .min_by_key(|s| s.rtt_us)
            .unwrap_or(ClockSample {
                robot_us: 0,
                host_mid_us: 0,
                rtt_us: u64::MAX,
            })
    }

    /// The clock for stamping poses, from [`Self::best`].
    pub fn pose_clock(&self) -> PoseClock {
        PoseClock::from_sync(self.best(), self.unix_t0_ns, self.period_s)
    }

    /// Robot time → host Unix time, anchored at [`Self::best`] (a recent
    /// sync: within the clock's half range of 35 min, so its wrap count
    /// starts right).
    pub fn time_map(&self) -> ros_mcap::TimeMap {
        let b = self.best();
        ros_mcap::TimeMap::new(b.robot_us as u32, self.unix_t0_ns + b.host_mid_us * 1000)
    }

    /// Host time since t0 \[µs\] (a pose's arrival).
    pub fn host_us(&self) -> u64 {
        host_us(self.t0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A capture time maps to robot time through the clock offset: 80 ms
    /// before arrival is 80 000 µs before the arrival's robot time, and a
    /// Unix stamp lands where the host clock read it.
    #[test]
    fn capture_times_map_to_robot_time() {
        let sync = ClockSample {
            robot_us: 5_500_000,
            host_mid_us: 500_000,
            rtt_us: 301,
        };
        let clock = PoseClock::from_sync(sync, 1_764_632_000_000_000_000, 0.001);
        assert_eq!(clock.offset_us, 5_000_000);
        let arrival = 2_000_000;
        let at = 7_000_000;
        // At arrival less the offset's uncertainty: ⌈301/2⌉ µs + one period.
        assert_eq!(
            clock.robot_stamp_us(Capture::Arrival, arrival),
            at - 151 - 1000
        );
        assert_eq!(
            clock.robot_stamp_us(Capture::AgoS(0.08), arrival),
            at - 80_000
        );
        // t0 + 1.92 s in Unix time = 80 ms before the arrival at t0 + 2 s.
        assert_eq!(
            clock.robot_stamp_us(Capture::UnixS(1_764_632_001.92), arrival),
            at - 80_000
        );
    }

    /// The midpoint of an exchange is halfway through its round trip; an
    /// answer stamped before its request is no sample.
    #[test]
    fn an_exchange_is_read_at_its_midpoint() {
        let s = ClockSample::of_exchange(1_000, 1_300, 9_000).unwrap();
        assert_eq!(
            (s.host_mid_us, s.rtt_us, s.offset_us()),
            (1_150, 300, 7_850)
        );
        assert_eq!(ClockSample::of_exchange(1_300, 1_000, 9_000), None);
    }

    /// The window keeps the shortest round trip of its last `n` samples:
    /// a slow exchange never replaces a fast one inside the window, and the
    /// fast one ages out after `n` more.
    #[test]
    fn the_window_keeps_the_best_recent_sample() {
        let s = |robot_us, rtt_us| ClockSample {
            robot_us,
            host_mid_us: 0,
            rtt_us,
        };
        let mut c = ClockTracker::with_first(Instant::now(), 0, 0.001, 3, s(10, 100));
        c.push(s(20, 500));
        c.push(s(30, 400));
        assert_eq!(c.best(), s(10, 100));
        c.push(s(40, 450));
        assert_eq!(c.best(), s(30, 400));
        // Window 1: always the latest (pose-feed's re-sync).
        let mut one = ClockTracker::with_first(Instant::now(), 0, 0.001, 1, s(10, 100));
        one.push(s(20, 900));
        assert_eq!(one.best(), s(20, 900));
    }
}
