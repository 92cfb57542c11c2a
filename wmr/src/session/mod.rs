//! # The host session: everything a program driving the robot does
//!
//! One implementation, used by the `wmr` commands, `wmr serve` (the clock
//! sample) and the ROS 2 bridge (wmr-ros2), of:
//!
//! - **the clock** ([`ClockSample`], [`clock_sync`], [`ClockTracker`],
//!   [`PoseClock`]): robot time against host time, for stamping poses in
//!   robot time and telemetry in Unix time;
//! - **keep-alive** ([`TelemetryStream`] while telemetry flows, [`Watch`]
//!   while waiting on a moving robot, [`ClockTracker::resync`] for a
//!   program that needs fresh clock samples anyway): the robot hears from
//!   the host within its link timeout ([`crate::timing`]);
//! - **segment streaming** ([`SegmentStream`]): a waypoint trajectory sent
//!   in segments while the robot's buffer takes them;
//! - **motion and state commands** ([`Motion`], [`velocity`], [`status`],
//!   [`get_param`]), and the pose tally of a pose stream ([`PoseTally`]);
//! - **the robot on the link** ([`robot_in_force`], [`com_offset_m`]): the
//!   robot file the robot runs, when it can tell.
//!
//! Every function takes the [`Link`] it works on: the session's state
//! (clock window, keep-alive schedule, stream position) lives beside the
//! link in the caller, as the bridge keeps both in one struct.

mod clock;
mod pose;
mod robot;
mod stream;
mod wait;

pub use clock::{clock_sync, host_us, Capture, ClockSample, ClockTracker, PoseClock};
pub use pose::PoseTally;
pub use robot::{
    com_offset_m, has_store, read_record, record_crc32, robot_in_force, robot_of_record,
    timer_clock_of_chip, ComOffset, ComOffsetSource, NotKnown, RecordRead, RecordStep,
};
pub use stream::{segments, Pump, SegmentStream, StreamError, SEGMENT_RETRY};
pub use wait::{expect_cause, until_rest, Step, Stop, Watch};

use crate::link::{HelloInfo, Link, LinkError};
use std::time::{Duration, Instant};
use wmr_protocol::{ParamId, Reply, Request, StatusMsg, TELEMETRY_ALL};

/// An I/O error (writing the output, reading input) as a link error.
pub fn io(e: std::io::Error) -> LinkError {
    LinkError::Io(e.to_string())
}

/// The handshake's information: the last handshake's, else a new one.
pub fn hello(link: &mut Link) -> Result<HelloInfo, LinkError> {
    match link.last_hello.clone() {
        Some(h) => Ok(h),
        None => link.hello(),
    }
}

/// The robot's status.
pub fn status(link: &mut Link) -> Result<StatusMsg, LinkError> {
    match link.command(&Request::GetStatus)? {
        Reply::Status { status, .. } => Ok(status),
        r => Err(LinkError::Unexpected(format!("{r:?}"))),
    }
}

/// One parameter's value, read from the robot.
pub fn get_param(link: &mut Link, id: ParamId) -> Result<f32, LinkError> {
    match link.command(&Request::GetParam(id))? {
        Reply::Param { value, .. } => Ok(value),
        r => Err(LinkError::Unexpected(format!("{r:?}"))),
    }
}

/// Reads the robot's link timeout and times the link from it (keep-alive,
/// answer timeout: [`crate::timing::LinkTiming`]).
pub fn adopt_link_timeout(link: &mut Link) -> Result<(), LinkError> {
    let lt = get_param(link, ParamId::LinkTimeoutMs)?;
    if lt.is_finite() && lt >= 1.0 {
        link.set_link_timeout_ms(lt as u32);
    }
    Ok(())
}

/// The commands that change the run state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Start driving the loaded reference or velocity mode.
    Arm,
    /// Stop driving (motors off, not latched).
    Disarm,
    /// Latched stop, motors off at once.
    EmergencyStop,
    /// Clear a latched stop (back to hold).
    ClearStop,
}

impl Motion {
    /// The request.
    pub fn request(self) -> Request {
        match self {
            Self::Arm => Request::Arm,
            Self::Disarm => Request::Disarm,
            Self::EmergencyStop => Request::EmergencyStop,
            Self::ClearStop => Request::ClearStop,
        }
    }

    /// Sends it; `Err(LinkError::Nack)` with the robot's reason when refused.
    pub fn send(self, link: &mut Link) -> Result<(), LinkError> {
        link.command(&self.request()).map(|_| ())
    }
}

/// A velocity command \[m/s, rad/s\] the robot drops after `timeout_ms`.
pub fn velocity(v_mps: f32, omega_radps: f32, timeout_ms: u16) -> Request {
    Request::Velocity {
        v_mps,
        omega_radps,
        timeout_ms,
    }
}

/// No telemetry frame for this long: the link is dead.
pub const TELEMETRY_SILENCE: Duration = Duration::from_secs(2);

/// Telemetry frames missing between sequence numbers `last` and `seq`; a
/// number going back is a robot that restarted its count (a reset, seen
/// through `wmr serve`), not four billion frames lost.
pub fn telemetry_gap(last: u32, seq: u32) -> u64 {
    match seq.wrapping_sub(last) {
        d if d > 0 && d <= 1 << 31 => (d - 1) as u64,
        _ => 0,
    }
}

/// Telemetry on at a rate, read frame by frame with the link kept alive
/// (a clock-sync frame every keep-alive period: the robot brakes after its
/// link timeout of silence) and its gaps counted; an error after
/// [`TELEMETRY_SILENCE`] without a frame.
pub struct TelemetryStream {
    t0: Instant,
    keep_alive: Duration,
    last_ping: Instant,
    last_frame: Instant,
    last_seq: Option<u32>,
    /// Frames missing (gaps in their sequence numbers).
    pub dropped: u64,
    /// Frames received.
    pub frames: u64,
}

impl TelemetryStream {
    /// Turns every telemetry group on at `rate_hz`.
    pub fn start(link: &mut Link, rate_hz: u16) -> Result<Self, LinkError> {
        link.command(&Request::SetTelemetry {
            selection: TELEMETRY_ALL,
            rate_hz,
        })?;
        let now = Instant::now();
        Ok(Self {
            t0: now,
            keep_alive: link.timing().keep_alive,
            last_ping: now,
            last_frame: now,
            last_seq: None,
            dropped: 0,
            frames: 0,
        })
    }

    /// The next telemetry frame or event within 20 ms (`None`: nothing
    /// yet), after a keep-alive when one is due.
    pub fn next(&mut self, link: &mut Link) -> Result<Option<Reply>, LinkError> {
        self.next_within(link, Duration::from_millis(20))
    }

    /// [`Self::next`] waiting up to `wait`.
    pub fn next_within(
        &mut self,
        link: &mut Link,
        wait: Duration,
    ) -> Result<Option<Reply>, LinkError> {
        if self.last_ping.elapsed() >= self.keep_alive {
            link.send(&Request::ClockSync {
                host_time_us: host_us(self.t0),
            })?;
            self.last_ping = Instant::now();
        }
        let r = link.next_stream(wait)?;
        if let Some(Reply::Telemetry(t)) = &r {
            self.last_frame = Instant::now();
            self.frames += 1;
            if let Some(s) = self.last_seq {
                self.dropped += telemetry_gap(s, t.seq);
            }
            self.last_seq = Some(t.seq);
        }
        if self.last_frame.elapsed() > TELEMETRY_SILENCE {
            return Err(LinkError::NoAnswer(format!(
                "telemetry (no frame for {} s)",
                TELEMETRY_SILENCE.as_secs()
            )));
        }
        Ok(r)
    }

    /// Telemetry off (best effort: the stream is over either way).
    pub fn stop(self, link: &mut Link) {
        let _ = link.command(&Request::SetTelemetry {
            selection: TELEMETRY_ALL,
            rate_hz: 0,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gaps in telemetry numbers: the frames between, across the u32 wrap;
    /// none for a repeat or a count that restarted (a robot reset).
    #[test]
    fn telemetry_gaps() {
        assert_eq!(telemetry_gap(5, 6), 0);
        assert_eq!(telemetry_gap(5, 9), 3);
        assert_eq!(telemetry_gap(u32::MAX, 1), 1);
        assert_eq!(telemetry_gap(5, 5), 0);
        assert_eq!(telemetry_gap(4000, 2), 0);
    }
}
