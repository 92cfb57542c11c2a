//! Small deterministic PRNG so a seed fully determines a run: the
//! simulated robot's SplitMix64 generator ([`sim_robot::sensors::SimRng`])
//! with the draws the scenarios need.

use sim_robot::sensors::SimRng;

/// SplitMix64 generator.
#[derive(Clone, Debug)]
pub struct Rng(SimRng);

impl Rng {
    /// Generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(SimRng::new(seed))
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0.uniform()
    }

    /// Uniform in the open interval (lo, hi).
    pub fn uniform_open(&mut self, lo: f64, hi: f64) -> f64 {
        self.0.uniform_open(lo, hi)
    }

    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        self.0.normal_open()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_mean_and_normal_variance() {
        let mut r = Rng::new(7);
        let n = 200_000;
        let mean: f64 = (0..n).map(|_| r.uniform()).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.005);
        let var: f64 = (0..n).map(|_| r.normal().powi(2)).sum::<f64>() / n as f64;
        assert!((var - 1.0).abs() < 0.02);
    }
}
