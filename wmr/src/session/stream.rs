//! Streaming a waypoint trajectory in segments: the one streamer of
//! `wmr upload`, `identify run` and the ROS 2 bridge's paths. It sends
//! segments until the robot's buffer is full and says so; the caller
//! decides how to wait (the CLI waits on the robot while keeping the link
//! alive, the bridge retries from its poll loop).

use crate::link::{Link, LinkError};
use std::time::{Duration, Instant};
use wmr_protocol::{ErrorCode, Reply, Request, Waypoint, SEGMENT_POINTS};

/// The segments of a waypoint upload, in order.
pub fn segments(points: &[Waypoint]) -> Vec<Request> {
    points
        .chunks(SEGMENT_POINTS)
        .enumerate()
        .map(|(i, c)| Request::TrajectorySegment {
            first_index: (i * SEGMENT_POINTS) as u32,
            points: c.iter().copied().collect(),
        })
        .collect()
}

/// Why a segment was not taken.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StreamError {
    /// The robot refused a segment as beyond its limits.
    #[error(
        "the robot refused the segment from waypoint {first_waypoint}: a waypoint, or the \
         curve from the one before it, asks more than the robot's speed, yaw rate \
         or acceleration; `wmr upload FILE --robot ROBOT.toml` names which"
    )]
    BeyondLimits {
        /// Index of the segment's first waypoint.
        first_waypoint: usize,
    },
    /// The robot refused a segment for another reason.
    #[error("the robot refused the segment from waypoint {first_waypoint}: {}", .error.reason())]
    Refused {
        /// Index of the segment's first waypoint.
        first_waypoint: usize,
        /// The robot's reason.
        error: ErrorCode,
    },
    /// The link failed.
    #[error(transparent)]
    Link(#[from] LinkError),
}

impl From<StreamError> for LinkError {
    fn from(e: StreamError) -> Self {
        match e {
            StreamError::Link(l) => l,
            StreamError::Refused { error, .. } => {
                LinkError::Nack("TrajectorySegment".into(), error)
            }
            e @ StreamError::BeyondLimits { .. } => LinkError::Io(e.to_string()),
        }
    }
}

/// Where a [`SegmentStream::pump`] left off.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pump {
    /// Every segment was acknowledged.
    Done,
    /// The robot's buffer is full: pump again once it drained.
    BufferFull,
}

/// Wait before re-sending a segment the robot's full buffer refused, when
/// pumping from a poll loop ([`SegmentStream::pump_when_due`]).
pub const SEGMENT_RETRY: Duration = Duration::from_millis(50);

/// A trajectory being sent segment by segment.
#[derive(Clone, Debug)]
pub struct SegmentStream {
    segs: Vec<Request>,
    next: usize,
    points: usize,
    retry_at: Option<Instant>,
}

impl SegmentStream {
    /// Announces `points` to the robot (`TrajectoryBegin`) and returns the
    /// stream of their segments, none sent yet.
    pub fn begin(link: &mut Link, points: &[Waypoint]) -> Result<Self, LinkError> {
        link.command(&Request::TrajectoryBegin {
            total_points: points.len() as u32,
        })?;
        Ok(Self::of(points))
    }

    /// The stream of `points` (no `TrajectoryBegin` sent).
    pub fn of(points: &[Waypoint]) -> Self {
        Self {
            segs: segments(points),
            next: 0,
            points: points.len(),
            retry_at: None,
        }
    }

    /// Sends segments until all are acknowledged or the robot's buffer is
    /// full.
    pub fn pump(&mut self, link: &mut Link) -> Result<Pump, StreamError> {
        while self.next < self.segs.len() {
            match link.request(&self.segs[self.next])? {
                Reply::TrajectoryAck { .. } => self.next += 1,
                Reply::Nack {
                    error: ErrorCode::BufferFull,
                    ..
                } => return Ok(Pump::BufferFull),
                Reply::Nack {
                    error: ErrorCode::InvalidValue,
                    ..
                } => {
                    return Err(StreamError::BeyondLimits {
                        first_waypoint: self.next * SEGMENT_POINTS,
                    })
                }
                Reply::Nack { error, .. } => {
                    return Err(StreamError::Refused {
                        first_waypoint: self.next * SEGMENT_POINTS,
                        error,
                    })
                }
                r => return Err(LinkError::Unexpected(format!("{r:?}")).into()),
            }
        }
        Ok(Pump::Done)
    }

    /// [`Self::pump`] from a poll loop: nothing (`None`) while a full
    /// buffer refused a segment less than [`SEGMENT_RETRY`] ago.
    pub fn pump_when_due(&mut self, link: &mut Link) -> Result<Option<Pump>, StreamError> {
        let now = Instant::now();
        if self.retry_at.is_some_and(|t| now < t) {
            return Ok(None);
        }
        self.retry_at = None;
        let p = self.pump(link)?;
        if p == Pump::BufferFull {
            self.retry_at = Some(now + SEGMENT_RETRY);
        }
        Ok(Some(p))
    }

    /// Every segment acknowledged.
    pub fn done(&self) -> bool {
        self.next == self.segs.len()
    }

    /// Waypoints acknowledged so far.
    pub fn points_sent(&self) -> usize {
        (self.next * SEGMENT_POINTS).min(self.points)
    }

    /// Segments acknowledged so far.
    pub fn segments_sent(&self) -> usize {
        self.next
    }

    /// Segments in the trajectory.
    pub fn segment_count(&self) -> usize {
        self.segs.len()
    }

    /// Waypoints in the trajectory.
    pub fn points(&self) -> usize {
        self.points
    }
}
