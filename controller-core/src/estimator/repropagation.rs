//! Re-propagation of the history after a late correction, in slices: a
//! correction 250 ticks late re-runs 250 predictions, more than one tick's
//! time budget on a small MCU. [`PoseEstimator::correct_within`] does at
//! most a given number of them at once and leaves the rest pending;
//! [`PoseEstimator::resume`] continues in later ticks (each new tick adds
//! one entry to re-propagate) until the corrected branch reaches the newest
//! entry and replaces the live state. The arithmetic per entry is the
//! forward prediction's, on the same stored inputs, so the result equals
//! [`PoseEstimator::correct`]'s bit for bit (tested). The branch rewrites
//! the posterior snapshots it passes (D31).

use super::gyro_scale;
use super::history::Snapshot;
use super::predict::Filter;
use super::PoseEstimator;

/// A correction being re-propagated: the corrected branch's state at the
/// entry `back` ticks before the newest one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Repropagation {
    /// Entries still to re-propagate (from the branch's entry to the newest).
    pub(super) back: usize,
    /// The branch's state and covariance.
    pub(super) filter: Filter,
    /// The correction reset the pose (its jump is not smoothed).
    pub(super) reset: bool,
}

impl<const H: usize> PoseEstimator<H> {
    /// A correction's re-propagation is pending: the estimate is still the
    /// uncorrected one.
    pub fn is_repropagating(&self) -> bool {
        self.pending.is_some()
    }

    /// Continues a pending re-propagation by at most `max_ticks` entries;
    /// returns how many it did. When it reaches the newest entry the
    /// corrected state replaces the live one.
    pub fn resume(&mut self, max_ticks: usize) -> usize {
        let Some(mut r) = self.pending.take() else {
            return 0;
        };
        let n = r.back.min(max_ticks);
        let mut f = r.filter;
        // Ring index of the branch's tick; each step moves to the next.
        let mut i = (self.head + H - r.back) % H;
        for k in (r.back - n..r.back).rev() {
            i = if i + 1 == H { 0 } else { i + 1 };
            self.predict_into(&mut f, &self.ticks[i].input());
            if let Some(slot) = self.snapshot_slot(k) {
                // The tick closes a gyro-vs-wheel interval (D36), as live.
                gyro_scale::update(&mut f, &self.windows[slot], &self.noise_sq);
                self.snaps[slot] = Snapshot::of(&f);
            }
        }
        r.back -= n;
        if r.back == 0 {
            self.finish_correction(f, r.reset);
        } else {
            r.filter = f;
            self.pending = Some(r);
        }
        n
    }

    /// A new tick was appended: one more entry to re-propagate. If the
    /// branch's entry would fall out of the history, the re-propagation is
    /// finished now.
    pub(super) fn pending_tick(&mut self) {
        let Some(r) = &mut self.pending else {
            return;
        };
        r.back += 1;
        if r.back >= H {
            self.resume(usize::MAX);
        }
    }
}
