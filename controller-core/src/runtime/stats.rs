//! Execution-time statistics (e.g. DWT cycle counts of the control step).

/// Mean and maximum of `u32` samples since the last [`CycleStats::take`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleStats {
    count: u32,
    sum: u64,
    max: u32,
}

impl CycleStats {
    /// Empty statistics.
    pub const fn new() -> Self {
        Self {
            count: 0,
            sum: 0,
            max: 0,
        }
    }

    /// Adds one sample.
    pub fn record(&mut self, sample: u32) {
        self.count = self.count.saturating_add(1);
        self.sum = self.sum.saturating_add(sample as u64);
        self.max = self.max.max(sample);
    }

    /// Number of samples.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// Mean (rounded down), 0 without samples.
    pub fn mean(&self) -> u32 {
        if self.count == 0 {
            0
        } else {
            (self.sum / self.count as u64) as u32
        }
    }

    /// Largest sample, 0 without samples.
    pub fn max(&self) -> u32 {
        self.max
    }

    /// Returns the statistics so far and starts a new window.
    pub fn take(&mut self) -> Self {
        core::mem::take(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_max_and_window() {
        let mut s = CycleStats::new();
        assert_eq!((s.mean(), s.max()), (0, 0));
        for x in [100, 300, 200, 400] {
            s.record(x);
        }
        let w = s.take();
        assert_eq!((w.count(), w.mean(), w.max()), (4, 250, 400));
        assert_eq!(s.count(), 0);
        s.record(u32::MAX);
        s.record(u32::MAX);
        assert_eq!(s.mean(), u32::MAX);
    }
}
