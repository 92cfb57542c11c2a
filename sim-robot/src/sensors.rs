//! Simulated sensors beyond the encoders: a z-axis rate gyro ([`SimGyro`])
//! and an external pose source ([`SimPoseSource`]: motion capture, UWB...).
//! Both are deterministic for a seed ([`SimRng`]) and implement the
//! runtime's [`Gyro`] and [`PoseSource`] traits, so the firmware's runtime
//! runs against them unchanged.
//!
//! Times are the simulation's seconds; stamps are the robot's µs clock
//! (`t·10⁶` wrapped to `u32`, as the runtime's loop timer sees it).

use crate::math::{cos, round};
use controller_core::estimator::{GyroSample, PoseMeasurement};
use controller_core::runtime::{Gyro, PoseSource};
use controller_core::Pose;

/// Smallest standard deviation a simulated source reports (a source with
/// zero noise still claims some uncertainty, as real ones do) \[m or rad\].
pub const MIN_REPORTED_STD: f64 = 1.0e-4;

/// Most measurements in flight (taken, not yet delivered).
pub const POSE_QUEUE_LEN: usize = 128;

/// A sensor model parameter rejected at construction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SensorModelError {
    /// A rate must be finite and > 0.
    NonPositiveRate,
    /// A noise, bias, latency, jitter or size must be finite (and >= 0
    /// where it is a magnitude).
    InvalidValue,
    /// A probability or fraction must be in \[0, 1\].
    InvalidFraction,
    /// An outage window must be finite with start <= end.
    InvalidOutage,
}

impl core::fmt::Display for SensorModelError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::NonPositiveRate => "sensor rate must be > 0",
            Self::InvalidValue => {
                "sensor noise, bias, latency, jitter and sizes must be finite, >= 0"
            }
            Self::InvalidFraction => "sensor probabilities must be in [0, 1]",
            Self::InvalidOutage => "outage window must be finite with start <= end",
        })
    }
}

/// SplitMix64: a small deterministic generator for the sensor noise.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SimRng(u64);

impl SimRng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in \[0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in the open interval (lo, hi) (a draw of exactly lo is
    /// rejected and redrawn).
    pub fn uniform_open(&mut self, lo: f64, hi: f64) -> f64 {
        loop {
            let u = self.uniform();
            if u > 0.0 {
                return lo + (hi - lo) * u;
            }
        }
    }

    /// Standard normal (Box-Muller with the first uniform from (0, 1) by
    /// rejection): the draws of the scenarios and of ideal sensing's
    /// measurement noise. [`Self::normal`], the sensors' draw, takes it from
    /// (0, 1] instead; both are kept so that every seed gives the run it
    /// always gave.
    pub fn normal_open(&mut self) -> f64 {
        let u1 = self.uniform_open(0.0, 1.0);
        let u2 = self.uniform();
        crate::math::sqrt(-2.0 * crate::math::ln(u1)) * cos(core::f64::consts::TAU * u2)
    }

    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // (0, 1]
        let u2 = self.uniform();
        libm::sqrt(-2.0 * libm::log(u1)) * cos(core::f64::consts::TAU * u2)
    }
}

/// The robot's µs clock at simulation time `t_s`.
pub fn stamp_us(t_s: f64) -> u32 {
    round(t_s * 1e6) as i64 as u32
}

/// A z-gyro: reading = (1 + scale_error)·ω + bias + white noise, clipped
/// at ±saturation; the bias walks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GyroModel {
    /// White noise density (angle random walk) \[rad/s/√Hz\].
    pub noise_density_radps_per_sqrt_hz: f64,
    /// Initial bias \[rad/s\].
    pub bias_radps: f64,
    /// Bias random walk \[rad/s/√s\].
    pub bias_walk_radps_per_sqrt_s: f64,
    /// Scale-factor error (0.01 = reads 1 % high).
    pub scale_error: f64,
    /// Full scale: readings clip at ± this \[rad/s\].
    pub saturation_radps: f64,
    /// Output data rate \[Hz\].
    pub rate_hz: f64,
}

impl GyroModel {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), SensorModelError> {
        let nonneg = |x: f64| x.is_finite() && x >= 0.0;
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return Err(SensorModelError::NonPositiveRate);
        }
        let ok = nonneg(self.noise_density_radps_per_sqrt_hz)
            && self.bias_radps.is_finite()
            && nonneg(self.bias_walk_radps_per_sqrt_s)
            && self.scale_error.is_finite()
            && self.saturation_radps.is_finite()
            && self.saturation_radps > 0.0;
        if ok {
            Ok(())
        } else {
            Err(SensorModelError::InvalidValue)
        }
    }
}

/// A simulated gyro: call [`SimGyro::update`] every tick with the true yaw
/// rate; [`Gyro::sample`] gives the latest sample (taken at its own rate).
#[derive(Clone, Debug)]
pub struct SimGyro {
    model: GyroModel,
    rng: SimRng,
    bias_radps: f64,
    next_t_s: f64,
    last: Option<GyroSample>,
}

impl SimGyro {
    /// A gyro of `model` with noise from `seed`.
    pub fn new(model: GyroModel, seed: u64) -> Result<Self, SensorModelError> {
        model.validate()?;
        Ok(Self {
            model,
            rng: SimRng::new(seed),
            bias_radps: model.bias_radps,
            next_t_s: 0.0,
            last: None,
        })
    }

    /// The current (walking) bias \[rad/s\].
    pub fn bias_radps(&self) -> f64 {
        self.bias_radps
    }

    /// At time `t_s` with the body's true yaw rate: takes a sample if one is due.
    pub fn update(&mut self, t_s: f64, true_rate_radps: f64) {
        if t_s + 1e-9 < self.next_t_s {
            return;
        }
        let m = &self.model;
        let period = 1.0 / m.rate_hz;
        self.next_t_s = if self.last.is_none() {
            t_s + period
        } else {
            self.next_t_s + period
        };
        self.bias_radps += m.bias_walk_radps_per_sqrt_s * libm::sqrt(period) * self.rng.normal();
        let noise = m.noise_density_radps_per_sqrt_hz * libm::sqrt(m.rate_hz) * self.rng.normal();
        let r = (1.0 + m.scale_error) * true_rate_radps + self.bias_radps + noise;
        let r = r.clamp(-m.saturation_radps, m.saturation_radps);
        self.last = Some(GyroSample {
            rate_radps: r as f32,
            stamp_us: stamp_us(t_s),
        });
    }
}

impl Gyro for SimGyro {
    fn sample(&mut self) -> Option<GyroSample> {
        self.last
    }
}

/// An external pose source: samples the true pose of G at `rate_hz`,
/// delivers each `latency_s` + U(0, `jitter_s`) later (in order), with
/// Gaussian position and heading noise; loses samples with probability
/// `dropout`, takes none inside `outage_s`, and replaces a fraction
/// `outlier_fraction` by the true position displaced `outlier_m` in a
/// random direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSourceModel {
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Delay from taking to delivering \[s\].
    pub latency_s: f64,
    /// Extra delay, uniform in \[0, jitter\] \[s\].
    pub jitter_s: f64,
    /// Std. dev. of the position noise per coordinate \[m\].
    pub position_noise_m: f64,
    /// Std. dev. of the heading noise \[rad\]; `None` = no heading (UWB).
    pub heading_noise_rad: Option<f64>,
    /// Probability that a sample is lost.
    pub dropout: f64,
    /// No samples are taken in \[start, end) \[s\].
    pub outage_s: Option<[f64; 2]>,
    /// Fraction of samples that are outliers.
    pub outlier_fraction: f64,
    /// Size of an outlier's position error \[m\].
    pub outlier_m: f64,
}

impl PoseSourceModel {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), SensorModelError> {
        let nonneg = |x: f64| x.is_finite() && x >= 0.0;
        let frac = |x: f64| (0.0..=1.0).contains(&x);
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return Err(SensorModelError::NonPositiveRate);
        }
        let ok = nonneg(self.latency_s)
            && nonneg(self.jitter_s)
            && nonneg(self.position_noise_m)
            && self.heading_noise_rad.is_none_or(nonneg)
            && nonneg(self.outlier_m);
        if !ok {
            return Err(SensorModelError::InvalidValue);
        }
        if !(frac(self.dropout) && frac(self.outlier_fraction)) {
            return Err(SensorModelError::InvalidFraction);
        }
        if let Some([a, b]) = self.outage_s {
            if !(a.is_finite() && b.is_finite() && a <= b) {
                return Err(SensorModelError::InvalidOutage);
            }
        }
        Ok(())
    }
}

/// Counters of a [`SimPoseSource`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PoseSourceStats {
    /// Samples taken (including lost ones and outliers).
    pub taken: u32,
    /// Lost by `dropout`, or because the queue was full.
    pub dropped: u32,
    /// Samples replaced by an outlier.
    pub outliers: u32,
    /// Measurements handed to the runtime.
    pub delivered: u32,
}

/// A simulated external pose source: call [`SimPoseSource::update`] every
/// tick with the true pose of G; [`PoseSource::measurement`] hands out
/// what has arrived by then, oldest first.
#[derive(Clone, Debug)]
pub struct SimPoseSource {
    model: PoseSourceModel,
    rng: SimRng,
    next_t_s: f64,
    started: bool,
    now_s: f64,
    last_deliver_s: f64,
    queue: [(f64, PoseMeasurement); POSE_QUEUE_LEN],
    head: usize,
    len: usize,
    /// Counters.
    pub stats: PoseSourceStats,
}

impl SimPoseSource {
    /// A source of `model` with noise from `seed`.
    pub fn new(model: PoseSourceModel, seed: u64) -> Result<Self, SensorModelError> {
        model.validate()?;
        let empty = PoseMeasurement {
            stamp_us: 0,
            pose: Pose::default(),
            position_std_m: 1.0,
            heading_std_rad: None,
        };
        Ok(Self {
            model,
            rng: SimRng::new(seed),
            next_t_s: 0.0,
            started: false,
            now_s: 0.0,
            last_deliver_s: 0.0,
            queue: [(0.0, empty); POSE_QUEUE_LEN],
            head: 0,
            len: 0,
            stats: PoseSourceStats::default(),
        })
    }

    /// At time `t_s` with the true pose of G `[x, y, θ]`: takes a sample if
    /// one is due (and the source is not in an outage).
    pub fn update(&mut self, t_s: f64, true_pose: [f64; 3]) {
        self.now_s = t_s;
        if self.started && t_s + 1e-9 < self.next_t_s {
            return;
        }
        let m = self.model;
        self.next_t_s = if self.started {
            self.next_t_s + 1.0 / m.rate_hz
        } else {
            t_s + 1.0 / m.rate_hz
        };
        self.started = true;
        if m.outage_s.is_some_and(|[a, b]| t_s >= a && t_s < b) {
            return;
        }
        self.stats.taken += 1;
        // Draw every number for every sample so a knob does not shift the
        // noise sequence of the others.
        let (nx, ny, nth) = (self.rng.normal(), self.rng.normal(), self.rng.normal());
        let (u_drop, u_out, u_dir, u_jit) = (
            self.rng.uniform(),
            self.rng.uniform(),
            self.rng.uniform(),
            self.rng.uniform(),
        );
        if u_drop < m.dropout || self.len == POSE_QUEUE_LEN {
            self.stats.dropped += 1;
            return;
        }
        let mut x = true_pose[0] + m.position_noise_m * nx;
        let mut y = true_pose[1] + m.position_noise_m * ny;
        if u_out < m.outlier_fraction {
            let a = core::f64::consts::TAU * u_dir;
            x += m.outlier_m * cos(a);
            y += m.outlier_m * crate::math::sin(a);
            self.stats.outliers += 1;
        }
        let th = true_pose[2] + m.heading_noise_rad.unwrap_or(0.0) * nth;
        let th = libm::atan2(crate::math::sin(th), cos(th));
        let deliver = (t_s + m.latency_s + m.jitter_s * u_jit).max(self.last_deliver_s);
        self.last_deliver_s = deliver;
        let meas = PoseMeasurement {
            stamp_us: stamp_us(t_s),
            pose: Pose::new(x as f32, y as f32, th as f32),
            position_std_m: m.position_noise_m.max(MIN_REPORTED_STD) as f32,
            heading_std_rad: m.heading_noise_rad.map(|s| s.max(MIN_REPORTED_STD) as f32),
        };
        let tail = (self.head + self.len) % POSE_QUEUE_LEN;
        self.queue[tail] = (deliver, meas);
        self.len += 1;
    }
}

impl PoseSource for SimPoseSource {
    fn measurement(&mut self) -> Option<PoseMeasurement> {
        if self.len == 0 {
            return None;
        }
        let (deliver, m) = self.queue[self.head];
        if deliver > self.now_s + 1e-9 {
            return None;
        }
        self.head = (self.head + 1) % POSE_QUEUE_LEN;
        self.len -= 1;
        self.stats.delivered += 1;
        Some(m)
    }
}

/// The named sensing presets of the simulator (hil-sim `--sensing`,
/// book/src/reference/scenario-file.md), also used by the Cortex-M4F benchmark.
/// The gyro of the `imu`, `mocap` and `uwb` presets: a MEMS gyro of the
/// BMI088 / ICM-42688 class at its 2000 °/s range, read every tick.
pub const PRESET_GYRO: GyroModel = GyroModel {
    noise_density_radps_per_sqrt_hz: 2.5e-4,
    bias_radps: 0.005,
    bias_walk_radps_per_sqrt_s: 1.0e-4,
    scale_error: 0.005,
    saturation_radps: 34.9,
    rate_hz: 1000.0,
};

/// Motion capture: pose of G at 100 Hz, 10 ms latency (+ up to 1 ms
/// jitter), 2 mm and 0.005 rad noise.
pub const PRESET_MOCAP: PoseSourceModel = PoseSourceModel {
    rate_hz: 100.0,
    latency_s: 0.010,
    jitter_s: 0.001,
    position_noise_m: 0.002,
    heading_noise_rad: Some(0.005),
    dropout: 0.0,
    outage_s: None,
    outlier_fraction: 0.0,
    outlier_m: 1.0,
};

/// UWB: position at 10 Hz, 100 ms latency (+ up to 5 ms jitter), 5 cm
/// noise, no heading.
pub const PRESET_UWB: PoseSourceModel = PoseSourceModel {
    rate_hz: 10.0,
    latency_s: 0.100,
    jitter_s: 0.005,
    position_noise_m: 0.05,
    heading_noise_rad: None,
    dropout: 0.0,
    outage_s: None,
    outlier_fraction: 0.0,
    outlier_m: 1.0,
};

#[cfg(test)]
mod tests {
    use super::*;

    fn mocap() -> PoseSourceModel {
        PoseSourceModel {
            rate_hz: 100.0,
            latency_s: 0.01,
            jitter_s: 0.002,
            position_noise_m: 0.002,
            heading_noise_rad: Some(0.005),
            dropout: 0.0,
            outage_s: None,
            outlier_fraction: 0.0,
            outlier_m: 1.0,
        }
    }

    /// Run a source for `secs` at 1 kHz on a static pose; returns the
    /// delivered measurements' (deliver time, measurement).
    fn collect(
        model: PoseSourceModel,
        secs: f64,
    ) -> (SimPoseSource, std::vec::Vec<(f64, PoseMeasurement)>) {
        let mut s = SimPoseSource::new(model, 7).unwrap();
        let mut out = std::vec::Vec::new();
        for k in 0..(secs * 1000.0) as usize {
            let t = k as f64 * 1e-3;
            s.update(t, [1.0, 2.0, 3.0]);
            while let Some(m) = s.measurement() {
                out.push((t, m));
            }
        }
        (s, out)
    }

    /// Rate, latency within [latency, latency + jitter] (plus at most one
    /// tick), in order, noise std within 5 % of the model's.
    #[test]
    fn pose_source_rate_latency_noise() {
        let (s, out) = collect(mocap(), 20.0);
        assert!((out.len() as i64 - 2000).abs() <= 2, "{}", out.len());
        let mut prev = 0u32;
        let mut sq = 0.0;
        for (t, m) in &out {
            let lat = t - m.stamp_us as f64 * 1e-6;
            assert!((0.01 - 1e-9..=0.013 + 1e-9).contains(&lat), "{lat}");
            assert!(m.stamp_us >= prev);
            prev = m.stamp_us;
            sq += (m.pose.x_m as f64 - 1.0).powi(2);
        }
        let sd = (sq / out.len() as f64).sqrt();
        assert!((sd / 0.002 - 1.0).abs() < 0.05, "{sd}");
        assert_eq!(s.stats.delivered as usize, out.len());
    }

    /// Dropouts, the outage window and outliers in the proportions asked.
    #[test]
    fn pose_source_dropouts_outage_outliers() {
        let model = PoseSourceModel {
            dropout: 0.1,
            outage_s: Some([5.0, 7.0]),
            outlier_fraction: 0.05,
            ..mocap()
        };
        let (s, out) = collect(model, 20.0);
        assert!(out.iter().all(|(_, m)| {
            let t = m.stamp_us as f64 * 1e-6;
            !(5.0..7.0).contains(&t)
        }));
        assert_eq!(s.stats.taken, 1800);
        let drop = s.stats.dropped as f64 / s.stats.taken as f64;
        assert!((drop - 0.1).abs() < 0.02, "{drop}");
        let far = out
            .iter()
            .filter(|(_, m)| (m.pose.x_m - 1.0).hypot(m.pose.y_m - 2.0) > 0.5)
            .count();
        assert_eq!(far as u32, s.stats.outliers);
        let frac = far as f64 / out.len() as f64;
        assert!((frac - 0.05).abs() < 0.015, "{frac}");
    }

    /// Gyro: mean reading = (1 + scale)·ω + bias, std = density·√rate,
    /// clipped at saturation, sampled at its rate.
    #[test]
    fn gyro_statistics_and_saturation() {
        let model = GyroModel {
            noise_density_radps_per_sqrt_hz: 0.002,
            bias_radps: 0.01,
            bias_walk_radps_per_sqrt_s: 0.0,
            scale_error: 0.02,
            saturation_radps: 5.0,
            rate_hz: 500.0,
        };
        let mut g = SimGyro::new(model, 3).unwrap();
        let (mut n, mut sum, mut sq, mut last) = (0, 0.0, 0.0, u32::MAX);
        for k in 0..100_000 {
            let t = k as f64 * 1e-3;
            g.update(t, 1.0);
            let s = g.sample().unwrap();
            if s.stamp_us != last {
                last = s.stamp_us;
                n += 1;
                sum += s.rate_radps as f64;
                sq += (s.rate_radps as f64).powi(2);
            }
        }
        assert_eq!(n, 50_000);
        let mean = sum / n as f64;
        let sd = (sq / n as f64 - mean * mean).sqrt();
        assert!((mean - 1.03).abs() < 1e-3, "{mean}");
        let want = 0.002 * 500f64.sqrt();
        assert!((sd / want - 1.0).abs() < 0.05, "{sd} vs {want}");
        g.update(1000.0, 100.0);
        assert_eq!(g.sample().unwrap().rate_radps, 5.0);
    }

    #[test]
    fn invalid_models_rejected() {
        assert!(SimPoseSource::new(
            PoseSourceModel {
                rate_hz: 0.0,
                ..mocap()
            },
            1
        )
        .is_err());
        assert!(SimPoseSource::new(
            PoseSourceModel {
                dropout: 1.5,
                ..mocap()
            },
            1
        )
        .is_err());
        assert!(SimPoseSource::new(
            PoseSourceModel {
                outage_s: Some([3.0, 2.0]),
                ..mocap()
            },
            1
        )
        .is_err());
    }
}
