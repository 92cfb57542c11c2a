//! Waiting on a moving robot without hanging: keep-alive frames on the
//! link's schedule, a status request every [`LinkTiming::status_every`] (a
//! lost stop event is found by the next status), stop events read as they
//! come, and an error once nothing at all has arrived for
//! [`LinkTiming::silence_limit`]. `upload --arm`, `drive` and a segment
//! stream waiting on a full buffer wait through it.

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

/// What a stop's cause means and what to do about it.
pub fn stop_advice(cause: Option<StopCode>) -> &'static str {
    match cause {
        None => "the robot did not say why: `wmr status` shows its last stop",
        Some(StopCode::TrajectoryEnd) => "the trajectory ended",
        Some(StopCode::Disarmed) => "disarmed by a host or the button",
        Some(StopCode::VelocityTimeout) => {
            "the velocity command expired: `wmr drive` refreshes it for --for seconds"
        }
        Some(StopCode::LinkSilence) => {
            "no frame from the host for link_timeout_ms: keep a command talking to the robot \
             while it moves (`wmr record`, `pose-feed`, `upload --arm`; several at once through \
             `wmr serve`)"
        }
        Some(StopCode::Other) => {
            "a reference beyond the robot's limits, or a trajectory that ran out of streamed \
             waypoints before its end (one longer than the robot's buffer runs only with \
             `wmr upload FILE --arm`, which streams the rest); `wmr upload FILE --robot \
             ROBOT.toml` checks a path against the limits"
        }
        Some(StopCode::Commanded) => "an emergency stop: `wmr clear` releases it",
        Some(StopCode::EncoderJump | StopCode::EncoderStalled | StopCode::DirectionMismatch) => {
            "a wheel or encoder misbehaved (latched): check the wiring with `wmr commission`, \
             then `wmr clear`"
        }
        Some(StopCode::LoopOverrun) => {
            "the control loop overran its period (latched): `wmr status` shows the loop time; \
             `wmr clear` releases it"
        }
        Some(StopCode::ControllerInput) => {
            "the controller refused its input (latched): `wmr status` shows the counters; \
             `wmr clear` releases it"
        }
    }
}

/// `Ok` when `stop` has one of the `expected` causes, else the unexpected
/// stop (what ended `what`).
pub fn expect_cause(stop: Stop, expected: &[StopCode], what: &str) -> Result<(), LinkError> {
    match stop.cause {
        Some(c) if expected.contains(&c) => Ok(()),
        c => Err(LinkError::UnexpectedStop(format!(
            "{stop} during {what} (expected {expected:?}): {}",
            stop_advice(c)
        ))),
    }
}

/// Keeps the link alive until the robot is at rest and returns why it
/// stopped (silence beyond the link timing's limit is an error).
pub fn until_rest(link: &mut Link) -> Result<Stop, LinkError> {
    let mut watch = Watch::new(link);
    let period = watch.timing().keep_alive;
    loop {
        if let Some(s) = watch.step(link, None, period)?.stopped {
            return Ok(s);
        }
    }
}
