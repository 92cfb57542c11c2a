//! Every host-side time of the link, derived in one place from the robot's
//! link timeout (`link_timeout_ms`: the robot brakes to a stop when no valid
//! frame arrives for that long while the host drives it).
//!
//! The rule: whatever single frame is lost, the robot hears from the host
//! again well inside its link timeout. A keep-alive goes out every fifth of
//! the timeout and an unanswered request is re-sent after a fifth, so one
//! lost frame leaves the robot without a frame for at most 2/5 of its timeout
//! (two lost in a row: 3/5). Before (issue 21 item 5) a lost request cost a
//! 500 ms answer timeout plus a retry, longer than the 500 ms link timeout.

use std::time::Duration;

/// The robot's link timeout when it cannot be read (wmr-device's default).
pub const DEFAULT_LINK_TIMEOUT_MS: u32 = 500;

/// Shortest answer timeout \[ms\] (a pty or USB round trip is ~1 ms; a UART
/// at 115 200 baud sends the largest frame in ~25 ms).
const MIN_ANSWER_TIMEOUT_MS: u64 = 30;

/// The link's timing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkTiming {
    /// The robot's link timeout.
    pub link_timeout: Duration,
    /// Period of keep-alive frames while the robot moves.
    pub keep_alive: Duration,
    /// How long to wait for an answer before sending the request again.
    pub answer_timeout: Duration,
    /// Times a request is sent before [`crate::LinkError::NoAnswer`].
    pub attempts: u32,
    /// Period of status requests while waiting on the robot (a lost stop
    /// event is found by the next status).
    pub status_every: Duration,
    /// A wait gives up when no frame at all arrived for this long: by then
    /// the robot has begun its controlled stop (its link timeout has passed
    /// four times over).
    pub silence_limit: Duration,
}

impl LinkTiming {
    /// Timing for a robot whose link timeout is `link_timeout_ms`.
    pub fn from_link_timeout_ms(link_timeout_ms: u32) -> Self {
        let lt = u64::from(link_timeout_ms.max(1));
        let fifth = (lt / 5).max(MIN_ANSWER_TIMEOUT_MS);
        Self {
            link_timeout: Duration::from_millis(lt),
            keep_alive: Duration::from_millis(fifth),
            answer_timeout: Duration::from_millis(fifth),
            attempts: 3,
            status_every: Duration::from_millis((lt / 2).max(fifth)),
            silence_limit: Duration::from_millis(4 * lt),
        }
    }

    /// The same timing with another answer timeout (`wmr --timeout-ms`).
    pub fn with_answer_timeout(self, answer_timeout: Duration) -> Self {
        Self {
            answer_timeout,
            ..self
        }
    }
}

impl Default for LinkTiming {
    fn default() -> Self {
        Self::from_link_timeout_ms(DEFAULT_LINK_TIMEOUT_MS)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whatever the link timeout, one lost frame (a keep-alive period plus an
    /// answer timeout before the re-send) and even two lost in a row leave
    /// the robot a frame inside its timeout.
    #[test]
    fn one_or_two_lost_frames_stay_inside_the_link_timeout() {
        for lt in [150u32, 200, 500, 1000, 10_000] {
            let t = LinkTiming::from_link_timeout_ms(lt);
            assert!(
                t.keep_alive + t.answer_timeout < t.link_timeout / 2,
                "{t:?}"
            );
            assert!(
                t.keep_alive + 2 * t.answer_timeout < t.link_timeout,
                "{t:?}"
            );
            assert!(t.status_every < t.link_timeout && t.silence_limit > t.link_timeout);
        }
    }
}
