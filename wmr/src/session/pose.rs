//! What was sent of a pose stream (`pose-feed`, the bridge's localiser
//! poses) and how the robot answered.

use std::time::{Duration, Instant};
use wmr_protocol::ErrorCode;

/// Poses sent, refused by reason, and not answered.
#[derive(Debug, Default)]
pub struct PoseTally {
    sent: u64,
    refused: Vec<(ErrorCode, u64)>,
    /// Poses the robot did not answer.
    pub lost: u64,
    /// Since when no pose was answered (None: the last one was).
    silent_since: Option<Instant>,
}

impl PoseTally {
    /// One pose sent and acknowledged.
    pub fn accepted(&mut self) {
        self.sent += 1;
        self.silent_since = None;
    }

    /// One pose sent and not answered at `now`; returns how long no pose
    /// has been answered.
    pub fn lost(&mut self, now: Instant) -> Duration {
        self.sent += 1;
        self.lost += 1;
        now - *self.silent_since.get_or_insert(now)
    }

    /// One pose sent and refused with `e`.
    pub fn refused(&mut self, e: ErrorCode) {
        self.sent += 1;
        self.silent_since = None;
        match self.refused.iter_mut().find(|(c, _)| *c == e) {
            Some((_, n)) => *n += 1,
            None => self.refused.push((e, 1)),
        }
    }

    /// Poses refused, all reasons.
    pub fn refused_total(&self) -> u64 {
        self.refused.iter().map(|(_, n)| n).sum()
    }
}

impl std::fmt::Display for PoseTally {
    /// `N poses sent, M refused` and one `  K: reason` line per reason.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} poses sent, {} refused, {} lost",
            self.sent,
            self.refused_total(),
            self.lost
        )?;
        for (e, n) in &self.refused {
            write!(f, "\n  {n}: {}", e.reason())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// pose-feed's silence (issue 31 item 6): measured from the first
    /// unanswered pose, reset by any answer, counted in the tally's line.
    #[test]
    fn pose_feed_counts_lost_poses_and_their_silence() {
        let mut t = PoseTally::default();
        let t0 = Instant::now();
        assert_eq!(t.lost(t0), Duration::ZERO);
        assert_eq!(
            t.lost(t0 + Duration::from_millis(500)),
            Duration::from_millis(500)
        );
        t.accepted();
        assert_eq!(t.lost(t0 + Duration::from_secs(20)), Duration::ZERO);
        assert_eq!(t.lost, 3);
        assert_eq!(t.to_string(), "4 poses sent, 0 refused, 3 lost");
    }

    #[test]
    fn pose_tally_counts_refusals_by_reason() {
        let mut t = PoseTally::default();
        t.accepted();
        t.refused(ErrorCode::PoseBadStdDev);
        t.refused(ErrorCode::PoseNonFinite);
        t.refused(ErrorCode::PoseBadStdDev);
        assert_eq!(t.refused_total(), 3);
        let text = t.to_string();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("4 poses sent, 3 refused, 0 lost"));
        assert_eq!(
            lines.next(),
            Some(format!("  2: {}", ErrorCode::PoseBadStdDev.reason()).as_str())
        );
        assert_eq!(
            lines.next(),
            Some(format!("  1: {}", ErrorCode::PoseNonFinite.reason()).as_str())
        );
        assert_eq!(lines.next(), None);
    }
}
