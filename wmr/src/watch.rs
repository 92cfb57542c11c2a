//! Waiting on a moving robot without hanging: keep-alive frames on the
//! link's schedule, a status request every [`LinkTiming::status_every`] (a
//! lost stop event is found by the next status), stop events read as they
//! come, and an error once nothing at all has arrived for
//! [`LinkTiming::silence_limit`]. `upload --arm` and `drive` wait through it.
//! [`LiveStatus`] is `wmr watch`'s one-line view of a telemetry frame.

use crate::link::{Link, LinkError};
use crate::timing::LinkTiming;
use std::time::{Duration, Instant};
use wmr_protocol::{Event, Reply, Request, RunStateMsg, StopCode};

/// A stop the robot reported: its state (hold or latched stop) and cause.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stop {
    /// `Hold` or `Stopped`.
    pub state: RunStateMsg,
    /// Why (the event's cause, or the status's last stop).
    pub cause: Option<StopCode>,
}

impl std::fmt::Display for Stop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.cause {
            Some(c) => write!(f, "{:?} ({c:?})", self.state),
            None => write!(f, "{:?} (-)", self.state),
        }
    }
}

/// What one [`Watch::step`] saw.
#[derive(Debug, Default)]
pub struct Step {
    /// Answers other than status (acks and nacks of what the caller sent).
    pub answers: Vec<(u16, Reply)>,
    /// The robot is braking (a controlled stop has begun).
    pub stopping: bool,
    /// The robot is at rest in hold or a latched stop.
    pub stopped: Option<Stop>,
}

/// The schedule of keep-alives and status requests of one wait.
pub struct Watch {
    timing: LinkTiming,
    t0: Instant,
    last_keep: Option<Instant>,
    last_status: Option<Instant>,
    /// Sequence numbers this watch sent (recent first out): answers to
    /// anything else (a late answer to an earlier request) are ignored.
    sent: std::collections::VecDeque<u16>,
}

impl Watch {
    /// A watch on `link`'s timing; the first step sends a status request.
    pub fn new(link: &Link) -> Self {
        Self {
            timing: link.timing(),
            t0: Instant::now(),
            last_keep: None,
            last_status: None,
            sent: std::collections::VecDeque::new(),
        }
    }

    /// The link's timing.
    pub fn timing(&self) -> LinkTiming {
        self.timing
    }

    /// One round: sends `keep` (or, with `None`, a clock-sync keep-alive) when
    /// `period` has passed since the last one, a status request when due,
    /// reads for up to 20 ms. Fails when no frame has arrived for the
    /// silence limit.
    pub fn step(
        &mut self,
        link: &mut Link,
        keep: Option<&Request>,
        period: Duration,
    ) -> Result<Step, LinkError> {
        let now = Instant::now();
        if self.last_keep.is_none_or(|t| now - t >= period) {
            let seq = match keep {
                Some(r) => link.send(r)?,
                None => link.send(&Request::ClockSync {
                    host_time_us: self.t0.elapsed().as_micros() as u64,
                })?,
            };
            self.remember(seq);
            self.last_keep = Some(now);
        }
        if self
            .last_status
            .is_none_or(|t| now - t >= self.timing.status_every)
        {
            let seq = link.send(&Request::GetStatus)?;
            self.remember(seq);
            self.last_status = Some(now);
        }
        let mut step = Step::default();
        for (seq, r) in link.receive(Duration::from_millis(20))? {
            if !self.sent.contains(&seq) {
                continue;
            }
            match r {
                Reply::Status { status, .. } => match status.state {
                    RunStateMsg::Hold | RunStateMsg::Stopped => {
                        step.stopped = Some(Stop {
                            state: status.state,
                            cause: status.last_stop,
                        })
                    }
                    RunStateMsg::Stopping => step.stopping = true,
                    RunStateMsg::Running => {}
                },
                // Keep-alive answers: nothing to do.
                Reply::ClockSync { .. } => {}
                r => step.answers.push((seq, r)),
            }
        }
        while let Some(r) = link.stream.pop_front() {
            match r {
                Reply::Event(Event::StateChanged {
                    state: state @ (RunStateMsg::Hold | RunStateMsg::Stopped),
                    cause,
                }) => step.stopped = Some(Stop { state, cause }),
                Reply::Event(Event::StateChanged {
                    state: RunStateMsg::Stopping,
                    ..
                })
                | Reply::Event(Event::LinkLost) => step.stopping = true,
                _ => {}
            }
        }
        let silent = link.last_rx().elapsed();
        if step.stopped.is_none() && silent > self.timing.silence_limit {
            return Err(LinkError::NoAnswer(format!(
                "anything for {:.1} s (line down or robot off; a moving robot brakes to a stop after its {} ms link timeout)",
                silent.as_secs_f64(),
                self.timing.link_timeout.as_millis()
            )));
        }
        Ok(step)
    }

    fn remember(&mut self, seq: u16) {
        if self.sent.len() >= 64 {
            self.sent.pop_front();
        }
        self.sent.push_back(seq);
    }

    /// Steps (clock-sync keep-alives) until the robot is at rest, for at
    /// most `within`.
    pub fn until_stopped(&mut self, link: &mut Link, within: Duration) -> Result<Stop, LinkError> {
        let end = Instant::now() + within;
        let period = self.timing.keep_alive;
        loop {
            if let Some(s) = self.step(link, None, period)?.stopped {
                return Ok(s);
            }
            if Instant::now() >= end {
                return Err(LinkError::NoAnswer(format!(
                    "a stop within {:.1} s (the robot still reports it is moving)",
                    within.as_secs_f64()
                )));
            }
        }
    }
}

/// `wmr watch`'s compact status line of each telemetry frame, and the
/// last stop seen in events.
#[derive(Clone, Debug, Default)]
pub struct LiveStatus {
    last_stop: Option<StopCode>,
}

impl LiveStatus {
    /// Notes a stop cause from an event.
    pub fn event(&mut self, e: &Event) {
        if let Event::StateChanged { cause: Some(c), .. } = e {
            self.last_stop = Some(*c);
        }
    }

    /// One line: robot time, state, pose of G, speed, errors, torque,
    /// health and reason, the last stop, counters (`-` for a group the
    /// frame lacks).
    pub fn line(&self, t: &wmr_protocol::Telemetry) -> String {
        use std::fmt::Write as _;
        let mut s = format!(
            "{:>9.3} s {:<8}",
            t.t_robot_us as f64 * 1e-6,
            format!("{:?}", t.state)
        );
        match &t.tracking {
            Some(tr) => {
                let ex = tr.ref_pose.x_m - tr.pose.x_m;
                let ey = tr.ref_pose.y_m - tr.pose.y_m;
                let reason = track_log::HEALTH_REASONS
                    .get(tr.health_reason as usize)
                    .copied()
                    .unwrap_or("?");
                let health = ["nominal", "degraded", "safe stop"]
                    .get(tr.health as usize)
                    .copied()
                    .unwrap_or("?");
                let _ = write!(
                    s,
                    " | G {:.3} {:.3} m {:.3} rad | v {:.3} m/s w {:.3} rad/s | err {:.3} m (e {:.3} {:.3} m {:.3} rad) | tau {:.2} {:.2} N·m{} | {health} ({reason})",
                    tr.pose.x_m,
                    tr.pose.y_m,
                    tr.pose.theta_rad,
                    tr.eta[0],
                    tr.eta[1],
                    (ex * ex + ey * ey).sqrt(),
                    tr.error[0],
                    tr.error[1],
                    tr.error[2],
                    tr.torque_nm[0],
                    tr.torque_nm[1],
                    if tr.saturated { " sat" } else { "" },
                );
            }
            None => s.push_str(" | no tracking telemetry"),
        }
        match self.last_stop {
            Some(c) => {
                let _ = write!(s, " | last stop {c:?}");
            }
            None => s.push_str(" | last stop -"),
        }
        if let Some(c) = &t.counters {
            let _ = write!(
                s,
                " | ext poses {} stops {} enc jumps {} overruns {} rx err {} tx drop {} nacks {}",
                c.external_poses,
                c.stops,
                c.encoder_jumps,
                c.overruns,
                c.rx_errors,
                c.tx_dropped,
                c.nacks
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wmr_protocol::{Counters, PoseMsg, Telemetry, TrackingTelemetry};

    #[test]
    fn live_line_shows_state_pose_error_health_stop_and_counters() {
        let mut live = LiveStatus::default();
        let mut t = Telemetry {
            seq: 1,
            t_robot_us: 12_345_000,
            t_ref_s: 1.0,
            state: RunStateMsg::Running,
            tracking: Some(TrackingTelemetry {
                pose: PoseMsg {
                    x_m: 1.0,
                    y_m: 2.0,
                    theta_rad: 0.5,
                },
                ref_pose: PoseMsg {
                    x_m: 1.3,
                    y_m: 2.4,
                    theta_rad: 0.5,
                },
                eta: [0.25, -0.125],
                health: 1,
                health_reason: 1,
                ..Default::default()
            }),
            estimators: None,
            counters: Some(Counters {
                external_poses: 7,
                nacks: 2,
                ..Default::default()
            }),
        };
        let l = live.line(&t);
        for part in [
            "12.345 s Running",
            "G 1.000 2.000 m 0.500 rad",
            "v 0.250 m/s w -0.125 rad/s",
            // |(0.3, 0.4)| = 0.5 m.
            "err 0.500 m",
            "degraded (saturation)",
            "last stop -",
            "ext poses 7",
            "nacks 2",
        ] {
            assert!(l.contains(part), "{part:?} not in {l:?}");
        }
        assert!(!l.contains('\n'));
        live.event(&Event::StateChanged {
            state: RunStateMsg::Stopped,
            cause: Some(StopCode::EncoderJump),
        });
        t.tracking = None;
        t.state = RunStateMsg::Stopped;
        let l = live.line(&t);
        assert!(
            l.contains("Stopped")
                && l.contains("last stop EncoderJump")
                && l.contains("no tracking"),
            "{l}"
        );
    }
}
