//! The history a late measurement is applied to (book/src/explanation/decisions.md D31):
//! per tick only what the prediction needs to replay it ([`Tick`], 16 B:
//! stamp, Δt with the gyro and standstill flags, Δs, the gyro rate or the
//! wheels' Δθ), and every `K` ticks a snapshot of the posterior (state and
//! packed covariance, 80 B), [`SNAPSHOTS`] of them. Besides, the posterior
//! at the latest accepted measurement's tick (`Fix`): measurements are used
//! in timestamp order, so a later one never lands before it, and replaying
//! from it keeps that correction. Per snapshot too, the gyro-vs-wheel sums of
//! the interval it closes (12 B, [`super::gyro_scale`], D36): the snapshot's
//! tick applies that update, live and re-propagated alike.
//!
//! A measurement nearest to the tick `back` ticks before the newest starts
//! from the newest snapshot at or before that tick (or the fix, if later),
//! replays the stored inputs to the tick with the forward prediction's
//! arithmetic (at most `K − 1` predictions), and is applied there; the
//! re-propagation to now ([`super::repropagation`]) rewrites the snapshots
//! it passes. Since every stored posterior came out of the same arithmetic
//! on the same inputs, the replayed state is the one the filter had at
//! that tick, bit for bit.

use super::gyro_scale;
use super::predict::{Filter, Input};
use super::{PoseEstimator, N, NP};

/// Posterior snapshots kept: the history covers `SNAPSHOTS − 1` intervals
/// of `K = ⌈H / SNAPSHOTS⌉` ticks at least.
pub(super) const SNAPSHOTS: usize = 16;

/// Flags in the top bits of a [`Tick`]'s Δt: a Δt in (0, 0.1] s has a
/// zero sign bit and a zero top exponent bit (it is below 2).
const GYRO_USED: u32 = 1 << 31;
const STILL: u32 = 1 << 30;

/// One tick's inputs, compact.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Tick {
    /// The tick's time \[µs\].
    pub(super) stamp_us: u32,
    /// Δt's f32 bits, with [`GYRO_USED`] and [`STILL`].
    dt_flags: u32,
    ds_m: f32,
    /// The gyro rate \[rad/s\] when used, else the wheels' Δθ \[rad\].
    yaw: f32,
}

impl Tick {
    pub(super) fn new(stamp_us: u32, u: &Input) -> Self {
        let mut dt_flags = u.dt_s.to_bits() & !(GYRO_USED | STILL);
        if u.gyro_used {
            dt_flags |= GYRO_USED;
        }
        if u.still {
            dt_flags |= STILL;
        }
        Self {
            stamp_us,
            dt_flags,
            ds_m: u.ds_m,
            yaw: u.yaw,
        }
    }

    /// The inputs, exactly as [`Tick::new`] got them.
    #[inline(always)]
    pub(super) fn input(&self) -> Input {
        Input {
            dt_s: f32::from_bits(self.dt_flags & !(GYRO_USED | STILL)),
            ds_m: self.ds_m,
            yaw: self.yaw,
            gyro_used: self.dt_flags & GYRO_USED != 0,
            still: self.dt_flags & STILL != 0,
        }
    }
}

/// A posterior: state and packed covariance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Snapshot {
    x: [f32; N],
    p: [f32; NP],
}

impl Snapshot {
    pub(super) fn of(f: &Filter) -> Self {
        Self { x: f.x, p: f.p }
    }

    pub(super) fn filter(&self) -> Filter {
        Filter::new(self.x, self.p)
    }
}

/// The posterior at the latest accepted measurement's tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Fix {
    /// Ticks before the newest.
    pub(super) back: usize,
    pub(super) post: Snapshot,
}

impl<const H: usize> PoseEstimator<H> {
    /// Ticks between snapshots: ⌈H / [`SNAPSHOTS`]⌉ (at least 1).
    pub(super) const SNAPSHOT_EVERY: usize = if H <= SNAPSHOTS {
        1
    } else {
        H.div_ceil(SNAPSHOTS)
    };

    /// The oldest tick a measurement can always be applied to, in ticks
    /// before the newest (once `H` ticks have been predicted): a pose taken
    /// this many ticks ago (at 1 kHz: ms) is never [`TooOld`]. 255 for
    /// the default [`HISTORY_LEN`](super::HISTORY_LEN) = 272; `H − 1` for
    /// `H` <= 16.
    ///
    /// [`TooOld`]: super::RejectReason::TooOld
    pub const GUARANTEED_DEPTH_TICKS: usize = {
        let k = Self::SNAPSHOT_EVERY;
        let mut worst = usize::MAX;
        let mut s = 0;
        while s < k && s < H {
            let mut j = (H - 1 - s) / k;
            if j > SNAPSHOTS - 1 {
                j = SNAPSHOTS - 1;
            }
            let d = s + j * k;
            if d < worst {
                worst = d;
            }
            s += 1;
        }
        if worst == usize::MAX {
            0
        } else {
            worst
        }
    };

    /// The tick `back` ticks before the newest (`back < self.len`).
    #[inline(always)]
    pub(super) fn tick_at(&self, back: usize) -> &Tick {
        &self.ticks[(self.head + H - back) % H]
    }

    /// The snapshot slot of the tick `back` ticks before the newest, if it
    /// has one.
    #[inline(always)]
    pub(super) fn snapshot_slot(&self, back: usize) -> Option<usize> {
        let k = Self::SNAPSHOT_EVERY;
        let rel = back.checked_sub(self.since_snapshot)?;
        let j = rel / k;
        (rel % k == 0 && j < self.snap_len).then(|| (self.snap_head + SNAPSHOTS - j) % SNAPSHOTS)
    }

    /// The oldest tick (ticks before the newest) with a snapshot whose
    /// later inputs are all kept: the oldest a measurement can land on.
    pub(super) fn oldest_usable(&self) -> Option<usize> {
        if self.snap_len == 0 {
            return None;
        }
        let k = Self::SNAPSHOT_EVERY;
        let j = (self.snap_len - 1).min((self.len - 1 - self.since_snapshot) / k);
        Some(self.since_snapshot + j * k)
    }

    /// Appends the newest tick (`self.filter` is its posterior): its
    /// inputs, and a snapshot every `K` ticks.
    #[inline(always)]
    pub(super) fn push_tick(&mut self, stamp_us: u32, input: &Input) {
        let next = self.head + 1;
        self.head = if self.len == 0 || next == H { 0 } else { next };
        if self.len < H {
            self.len += 1;
        }
        self.ticks[self.head] = Tick::new(stamp_us, input);
        self.since_snapshot += 1;
        if self.snap_len == 0 || self.since_snapshot == Self::SNAPSHOT_EVERY {
            let next = self.snap_head + 1;
            self.snap_head = if self.snap_len == 0 || next == SNAPSHOTS {
                0
            } else {
                next
            };
            if self.snap_len < SNAPSHOTS {
                self.snap_len += 1;
            }
            // The gyro-vs-wheel update of the speed scale closes the
            // interval (D36), before the snapshot, as in the re-propagation.
            self.windows[self.snap_head] = core::mem::take(&mut self.window);
            gyro_scale::update(
                &mut self.filter,
                &self.windows[self.snap_head],
                &self.noise_sq,
            );
            self.snaps[self.snap_head] = Snapshot::of(&self.filter);
            self.since_snapshot = 0;
        }
        if let Some(fix) = &mut self.fix {
            fix.back += 1;
            if fix.back >= H {
                self.fix = None;
            }
        }
    }

    /// The posterior at the tick `back` ticks before the newest (`back` <=
    /// [`Self::oldest_usable`]): the newest snapshot or fix at or before it,
    /// with the inputs up to that tick replayed. Returns it and the number
    /// of predictions replayed.
    pub(super) fn posterior_at(&self, back: usize) -> (Filter, usize) {
        let k = Self::SNAPSHOT_EVERY;
        let j = back.saturating_sub(self.since_snapshot).div_ceil(k);
        let mut from = self.since_snapshot + j * k;
        let mut f = self.snaps[(self.snap_head + SNAPSHOTS - j) % SNAPSHOTS].filter();
        if let Some(fix) = &self.fix {
            if fix.back >= back && fix.back < from {
                from = fix.back;
                f = fix.post.filter();
            }
        }
        for b in (back..from).rev() {
            self.predict_into(&mut f, &self.tick_at(b).input());
        }
        (f, from - back)
    }
}
