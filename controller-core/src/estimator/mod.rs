//! Pose estimator: wheel odometry and a z-gyro fused with delayed external
//! pose measurements (an extended Kalman filter with a history buffer).
//!
//! State: the axle midpoint O_B = (x, y), the heading θ, the gyro bias
//! b and the speed scale k (body speed / wheel-derived speed: below 1 when
//! the wheels slip or an actuator fault holds the body back); the pose of G is O_B + d·\[cos θ, sin θ\] (the same geometry as
//! [`Odometry`](crate::runtime::Odometry)).
//!
//! * **Prediction, every tick** ([`PoseEstimator::predict`]): the distance
//!   Δs the wheels rolled and the heading change Δθ = (gyro − b)·Δt, or
//!   the wheels' Δθ when the gyro is absent, stale, saturated or not
//!   finite ([`GyroState`]); O_B moves by k·Δs along θ + Δθ/2. After
//!   `standstill_ticks` with both wheels still, the gyro's reading is a
//!   measurement of its bias (zero-rate update). On the tick that closes
//!   each snapshot interval (17 ticks), the gyro's yaw against the wheels'
//!   over it updates the speed scale k and b (not the pose, which does not
//!   jump: a Schmidt update): the body turns by k times
//!   what the wheels report, so k is seen without external poses whenever
//!   the robot turns (`gyro_scale.rs`, D36; the re-propagation applies it on
//!   the same ticks from the same stored sums). The covariance update
//!   F·P·Fᵀ + Q is written out over F's seven non-zero partials on the
//!   packed upper triangle of P, in place, with one sin/cos per tick
//!   (`predict.rs`; tested against the dense f64 update).
//! * **Correction** ([`PoseEstimator::correct`]): a pose of G taken at
//!   `stamp_us` (in the robot's clock, up to
//!   [`PoseEstimator::GUARANTEED_DEPTH_TICKS`] ticks ago: 255 for the
//!   default [`HISTORY_LEN`] = 272). The filter keeps, per tick, only the
//!   inputs of the prediction (16 B), and every 17 ticks a snapshot of the
//!   state and covariance (`history.rs`, book/src/explanation/decisions.md D31). The
//!   measurement restores the snapshot at or before its stamp, replays the
//!   stored inputs to the stamp, updates there, then the later ticks are
//!   re-propagated from the stored inputs with the same arithmetic as the
//!   forward prediction, so the estimate at *now* equals what it would have
//!   been had the measurement arrived on time (D25). The innovation is
//!   gated by its squared Mahalanobis distance (chi-square); the heading
//!   innovation is wrapped. Measurements are used in timestamp order: one
//!   older than the last accepted is refused ([`RejectReason::OutOfOrder`]).
//!   [`PoseEstimator::correct_within`] bounds the re-propagation done at
//!   once (the runtime does 24 ticks per tick, plus at most 16 replayed to
//!   the stamp) and [`PoseEstimator::resume`] continues it in later ticks;
//!   the result is the same bit for bit, it only lands a few ticks later
//!   (D30).
//! * **Output** ([`Estimate`]): `filter_pose` is the filter's estimate of G;
//!   `pose`, for the controller, is the same with each correction's jump
//!   spread over about two measurement intervals (a decaying offset, time
//!   constant at most `output_smoothing_s`), so that a low-rate source (UWB
//!   at 10 Hz) does not hand the controller steps.
//!
//! `no_std`, f32, fixed memory chosen at compile time
//! (`PoseEstimator<H>`): 16 B per tick of history plus 16 snapshots of
//! 80 B and their interval's gyro-vs-wheel sums of 12 B (5.8 KiB for 272
//! ticks; the former full posterior per tick was 104 B), no panics: any non-finite input is refused or replaced, and a
//! prediction or correction that would make the state non-finite is
//! dropped.

#![allow(clippy::needless_range_loop)] // small matrices read best indexed

mod config;
mod gyro_scale;
mod history;
mod odom_covariance;
mod predict;
mod repropagation;
mod types;

use repropagation::Repropagation;

pub use config::{EstimatorConfig, EstimatorConfigError, CHI2_999_2DOF, CHI2_999_3DOF};
pub use odom_covariance::OdomCovariance;
pub use types::{
    Estimate, EstimatorStatus, GyroSample, GyroState, PoseMeasurement, RejectCounts, RejectReason,
};

use crate::health::EstimatorHealth;
use crate::math::{sin_cos, wrap_angle};
use crate::types::Pose;
use gyro_scale::Window;
use history::{Fix, Snapshot, Tick, SNAPSHOTS};
use predict::{ix, Filter, Input, NoiseSq, SPEED_SCALE_RANGE};

/// Default ticks of history: 272 ticks of inputs with a posterior snapshot
/// every 17, so that a measurement taken up to 255 ticks ago (255 ms at
/// 1 kHz, above the 250 ms latency bound) can always be used
/// ([`PoseEstimator::GUARANTEED_DEPTH_TICKS`]).
pub const HISTORY_LEN: usize = 272;

/// Age of the latest accepted external pose beyond which the estimator
/// reports itself degraded (once it has used one) \[µs\]: ten periods of
/// the slowest source the presets have (UWB, 10 Hz), or four times the
/// longest delay it accepts (250 ms).
pub const POSE_STALE_US: u32 = 1_000_000;

/// State dimension: x, y of O_B, θ, gyro bias, speed scale.
const N: usize = 5;
/// Packed upper-triangle size.
const NP: usize = N * (N + 1) / 2;
/// Smallest diagonal variance kept after a correction (f32 round-off).
const MIN_VAR: f32 = 1.0e-12;
/// Largest plausible wheel speed \[m/s\] and yaw rate \[rad/s\]: larger
/// increments are glitches and are not integrated.
const MAX_SPEED_MPS: f32 = 50.0;
const MAX_YAW_RATE_RADPS: f32 = 200.0;
/// Largest |coordinate| \[m\] and std. dev. \[m or rad\] of a usable
/// measurement (beyond: implausible, refused).
const MAX_COORD_M: f32 = 1.0e5;
const MAX_STD: f32 = 1.0e3;
/// A correction moving G by more than this (|Δx| + |Δy| \[m\]) is not
/// smoothed: the output jumps with the filter (a reset, a long outage).
const MAX_SMOOTHED_JUMP_M: f32 = 0.5;
/// The output smoothing's time constant in mean measurement intervals.
const SMOOTHING_INTERVALS: f32 = 2.0;
/// Gain of the running mean of the measurement interval.
const INTERVAL_GAIN: f32 = 0.1;
/// Longest tick the prediction integrates \[s\].
const MAX_DT_S: f32 = 0.1;
/// Δt used when the caller's is not positive or not finite \[s\].
const FALLBACK_DT_S: f32 = 1.0e-3;

type Mat = [[f32; N]; N];

fn pack(p: &Mat) -> [f32; NP] {
    let mut t = [0.0; NP];
    for i in 0..N {
        for j in i..N {
            t[ix(i, j)] = p[i][j];
        }
    }
    t
}

fn unpack(t: &[f32; NP]) -> Mat {
    core::array::from_fn(|i| core::array::from_fn(|j| t[ix(i.min(j), i.max(j))]))
}

/// The tick's Δt, Δs, Δθ when [`PoseEstimator::predict`]'s are out of the
/// usual range, and whether the increments were plausible: Δt not positive
/// or not finite becomes 1 ms, beyond `MAX_DT_S` is cut to it; increments
/// faster than `MAX_SPEED_MPS` or `MAX_YAW_RATE_RADPS` (or not finite)
/// become 0.
#[cold]
fn unusual_increments(dt_s: f32, ds_m: f32, dth_rad: f32) -> (f32, f32, f32, bool) {
    let dt_s = if dt_s > 0.0 && dt_s <= MAX_DT_S {
        dt_s
    } else if dt_s > MAX_DT_S && dt_s.is_finite() {
        MAX_DT_S
    } else {
        FALLBACK_DT_S
    };
    let plausible =
        ds_m.abs() <= MAX_SPEED_MPS * dt_s && dth_rad.abs() <= MAX_YAW_RATE_RADPS * dt_s;
    if plausible {
        (dt_s, ds_m, dth_rad, true)
    } else {
        (dt_s, 0.0, 0.0, false)
    }
}

fn all_finite(x: &[f32; N], p: &Mat) -> bool {
    x.iter().all(|v| v.is_finite()) && p.iter().flatten().all(|v| v.is_finite())
}

/// Wheel odometry, a z-gyro and delayed external poses fused in an EKF
/// with a history buffer; see the [module docs](self).
#[derive(Clone, Debug)]
pub struct PoseEstimator<const H: usize = HISTORY_LEN> {
    cfg: EstimatorConfig,
    /// Distance d from the axle midpoint to G \[m\] (measurements are of G),
    /// given by the owner from the robot's parameters.
    com_offset_m: f32,
    noise_sq: NoiseSq,
    /// The live state (at the newest tick).
    filter: Filter,
    /// Inputs of the last `len` ticks (ring, newest at `head`).
    ticks: [Tick; H],
    head: usize,
    len: usize,
    /// Posterior snapshots every `SNAPSHOT_EVERY` ticks (ring, newest at
    /// `snap_head`, `since_snapshot` ticks before the newest tick).
    snaps: [Snapshot; SNAPSHOTS],
    snap_head: usize,
    snap_len: usize,
    since_snapshot: usize,
    /// The gyro-vs-wheel yaw sums since the latest snapshot, and those of
    /// the interval ending at each snapshot (`gyro_scale.rs`, D36).
    window: Window,
    windows: [Window; SNAPSHOTS],
    /// The posterior at the latest accepted measurement's tick.
    fix: Option<Fix>,
    now_us: u32,
    last_accepted_stamp_us: Option<u32>,
    consecutive_outliers: u16,
    still_ticks: u16,
    estimate: Estimate,
    status: EstimatorStatus,
    /// Output offset \[m, m, rad\]: `filter_pose − pose`, decaying.
    offset: [f32; 3],
    /// Running mean of the time between accepted measurements \[s\].
    mean_interval_s: Option<f32>,
    /// The output offset's time constant \[s\] (from `mean_interval_s`).
    smoothing_tau_s: f32,
    /// A correction whose re-propagation is not finished (see
    /// [`PoseEstimator::correct_within`]).
    pending: Option<Repropagation>,
}

impl PoseEstimator {
    /// Validates `cfg` and starts with G at `start` (bias 0, speed scale 1),
    /// G `com_offset_m` ahead of the axle midpoint (the robot's
    /// [`RobotParams::com_offset_m`](crate::RobotParams::com_offset_m)),
    /// with [`HISTORY_LEN`] ticks of history.
    pub fn new(
        cfg: EstimatorConfig,
        com_offset_m: f32,
        start: Pose,
    ) -> Result<Self, EstimatorConfigError> {
        Self::with_history(cfg, com_offset_m, start)
    }
}

impl<const H: usize> PoseEstimator<H> {
    /// As [`PoseEstimator::new`], with `H` (>= 1) ticks of history.
    pub fn with_history(
        cfg: EstimatorConfig,
        com_offset_m: f32,
        start: Pose,
    ) -> Result<Self, EstimatorConfigError> {
        if H == 0 {
            return Err(EstimatorConfigError::InvalidCount);
        }
        let cfg = cfg.validate()?;
        if !(start.is_finite() && com_offset_m.is_finite()) {
            return Err(EstimatorConfigError::NonFinitePose);
        }
        let g = start;
        let th = wrap_angle(g.theta_rad);
        let (s, c) = sin_cos(th);
        let d = com_offset_m;
        let x = [g.x_m - d * c, g.y_m - d * s, th, 0.0, 1.0];
        let mut p = [0.0; NP];
        p[ix(0, 0)] = cfg.initial_position_std_m * cfg.initial_position_std_m;
        p[ix(1, 1)] = p[ix(0, 0)];
        p[ix(2, 2)] = cfg.initial_heading_std_rad * cfg.initial_heading_std_rad;
        p[ix(3, 3)] = cfg.initial_bias_std_radps * cfg.initial_bias_std_radps;
        p[ix(4, 4)] = cfg.initial_speed_scale_std * cfg.initial_speed_scale_std;
        let mut e = Self {
            noise_sq: NoiseSq::of(&cfg),
            smoothing_tau_s: cfg.output_smoothing_s,
            cfg,
            com_offset_m,
            filter: Filter::new(x, p),
            ticks: [Tick::default(); H],
            head: 0,
            len: 0,
            snaps: [Snapshot::default(); SNAPSHOTS],
            snap_head: 0,
            snap_len: 0,
            since_snapshot: 0,
            window: Window::default(),
            windows: [Window::default(); SNAPSHOTS],
            fix: None,
            now_us: 0,
            last_accepted_stamp_us: None,
            consecutive_outliers: 0,
            still_ticks: 0,
            estimate: Estimate::default(),
            offset: [0.0; 3],
            mean_interval_s: None,
            pending: None,
            status: EstimatorStatus {
                since_accepted_us: u32::MAX,
                ..EstimatorStatus::default()
            },
        };
        e.refresh(&Input::default());
        Ok(e)
    }

    /// The validated configuration.
    pub fn config(&self) -> &EstimatorConfig {
        &self.cfg
    }

    /// The centre-of-mass offset d \[m\] it was built with.
    pub fn com_offset_m(&self) -> f32 {
        self.com_offset_m
    }

    /// The estimate at the latest tick.
    pub fn estimate(&self) -> &Estimate {
        &self.estimate
    }

    /// Carries the counters of `old` (poses accepted, refused by reason,
    /// resets, standstill updates) into this estimator: a re-anchored pose
    /// (`SetPose`) does not erase what was counted and reported (issue 31
    /// item 6).
    pub(crate) fn keep_counters(&mut self, old: &EstimatorStatus) {
        self.status.accepted = old.accepted;
        self.status.rejected = old.rejected;
        self.status.resets = old.resets;
        self.status.standstill_updates = old.standstill_updates;
    }

    /// Carries what `old` learned of the sensors, the gyro bias and the
    /// speed scale with their covariance block, into this estimator, built
    /// at a pose the user gave (`SetPose`: `/initialpose`, `set_odometry`).
    /// A given pose says nothing of the gyro or the wheels: forgetting them
    /// let the heading drift at the full gyro bias (0.01 rad/s in the
    /// `imu` preset) until standstill updates learned it again. The given
    /// pose is independent of them, so its cross-covariance is 0. How
    /// long the wheels have stood still is kept too.
    pub(crate) fn keep_calibration(&mut self, old: &Self) {
        // Nor does it move the robot: one standing still stays still, and
        // its zero-rate updates go on from the first tick after the set
        // (reset, 200 ticks integrated the unlearned part of the bias and
        // the gyro's noise: 1e-4 rad in the interop check's hold).
        self.still_ticks = old.still_ticks;
        for i in 3..N {
            self.filter.x[i] = old.filter.x[i];
            for j in i..N {
                self.filter.p[ix(i, j)] = old.filter.p[ix(i, j)];
            }
        }
        self.refresh(&Input::default());
    }

    /// Status for logs and telemetry. Its counters are kept as they
    /// happen; the covariance diagonal, the bias, the speed scale and the
    /// time since the last accepted pose are read from the filter here,
    /// when asked, not copied on every tick (the typical tick's budget,
    /// BENCHMARKS.md).
    pub fn status(&self) -> EstimatorStatus {
        let mut s = self.status;
        let p = &self.filter.p;
        s.covariance_diag = [
            p[ix(0, 0)],
            p[ix(1, 1)],
            p[ix(2, 2)],
            p[ix(3, 3)],
            p[ix(4, 4)],
        ];
        s.gyro_bias_radps = self.filter.x[3];
        s.speed_scale = self.filter.x[4];
        s.since_accepted_us = self.since_accepted_us();
        s
    }

    /// The gyro on the latest tick (without the rest of [`Self::status`]).
    #[inline]
    pub fn gyro_state(&self) -> GyroState {
        self.status.gyro
    }

    /// Time from the latest accepted measurement's stamp to the latest
    /// tick \[µs\] (`u32::MAX` until the first).
    #[inline]
    fn since_accepted_us(&self) -> u32 {
        match self.last_accepted_stamp_us {
            Some(t) => self.now_us.wrapping_sub(t),
            None => u32::MAX,
        }
    }

    /// Health for the health machine ([`crate::health`]), from the latest
    /// tick: `Degraded` when external poses were used but none has been
    /// accepted for [`POSE_STALE_US`] (the pose drifts on the wheels and
    /// gyro alone: an outage, or every measurement gated); `Ok` otherwise
    /// (odometry without a pose source is the configuration, not a
    /// degradation). The estimator never reports `Failed`: it refuses
    /// non-finite inputs, and a non-finite estimate would be refused by the
    /// controller's input check (a controller fault, a hard stop).
    #[inline]
    pub fn health(&self) -> EstimatorHealth {
        if self.status.accepted > 0 && self.since_accepted_us() > POSE_STALE_US {
            EstimatorHealth::Degraded
        } else {
            EstimatorHealth::Ok
        }
    }

    /// The latest tick's time \[µs\].
    pub fn now_us(&self) -> u32 {
        self.now_us
    }

    /// The full covariance at the latest tick (x, y of O_B, θ, bias,
    /// speed scale).
    pub fn covariance(&self) -> [[f32; N]; N] {
        unpack(&self.filter.p)
    }

    /// One tick: the tick at `now_us` (robot clock) came `dt_s` after the
    /// previous one; the wheels rolled `ds_m` (axle midpoint) and turned the
    /// body by `dtheta_wheel_rad`; `gyro` is the latest gyro sample, if any.
    pub fn predict(
        &mut self,
        now_us: u32,
        dt_s: f32,
        ds_m: f32,
        dtheta_wheel_rad: f32,
        gyro: Option<GyroSample>,
    ) -> &Estimate {
        // Non-finite or physically impossible increments are dropped.
        let usual = dt_s > 0.0
            && dt_s <= MAX_DT_S
            && ds_m.abs() <= MAX_SPEED_MPS * dt_s
            && dtheta_wheel_rad.abs() <= MAX_YAW_RATE_RADPS * dt_s;
        let (dt_s, ds_m, dtheta_wheel_rad, plausible) = if usual {
            (dt_s, ds_m, dtheta_wheel_rad, true)
        } else {
            unusual_increments(dt_s, ds_m, dtheta_wheel_rad)
        };
        let gyro_state = match gyro {
            Some(g)
                if g.rate_radps.abs() < self.cfg.gyro_saturation_radps
                    && now_us.wrapping_sub(g.stamp_us) <= self.cfg.gyro_stale_us =>
            {
                GyroState::Ok
            }
            _ => self.gyro_fallback(gyro),
        };
        let gyro_used = gyro_state == GyroState::Ok;
        if ds_m == 0.0 && dtheta_wheel_rad == 0.0 && plausible {
            self.still_ticks = self.still_ticks.saturating_add(1);
        } else {
            self.still_ticks = 0;
        }
        let input = Input {
            dt_s,
            ds_m,
            yaw: match gyro {
                Some(g) if gyro_used => g.rate_radps,
                _ => dtheta_wheel_rad,
            },
            gyro_used,
            still: gyro_used && self.still_ticks >= self.cfg.standstill_ticks,
        };
        predict::predict(&mut self.filter, &input, &self.noise_sq);
        self.window.add(&input, dtheta_wheel_rad);
        // The output offset decays with time constant τ = min(output_smoothing_s,
        // SMOOTHING_INTERVALS × the mean interval between measurements):
        // a jump is spread over about two intervals (factor 1/(1 + Δt/τ)).
        let tau = self.smoothing_tau_s;
        let decay = if tau > 0.0 { tau / (tau + dt_s) } else { 0.0 };
        for o in &mut self.offset {
            *o *= decay;
        }
        if input.still {
            self.status.standstill_updates = self.status.standstill_updates.saturating_add(1);
        }
        self.now_us = now_us;
        self.push_tick(now_us, &input);
        self.status.gyro = gyro_state;
        self.pending_tick();
        self.refresh(&input);
        &self.estimate
    }

    /// Why the gyro sample is not used.
    #[cold]
    fn gyro_fallback(&self, gyro: Option<GyroSample>) -> GyroState {
        match gyro {
            None => GyroState::Absent,
            Some(g) if !g.rate_radps.is_finite() => GyroState::NonFinite,
            Some(g) if g.rate_radps.abs() >= self.cfg.gyro_saturation_radps => GyroState::Saturated,
            Some(_) => GyroState::Stale,
        }
    }

    /// The prediction of one tick on `f` (to replay and re-propagate
    /// the history: the live one's arithmetic).
    #[inline(always)]
    fn predict_into(&self, f: &mut Filter, u: &Input) {
        predict::predict(f, u, &self.noise_sq);
    }

    /// Uses the pose measurement `m` (taken at `m.stamp_us`, not after the
    /// latest tick, not older than the history); `Err` says why not.
    pub fn correct(&mut self, m: &PoseMeasurement) -> Result<(), RejectReason> {
        self.correct_within(m, usize::MAX).map(|_| ())
    }

    /// [`Self::correct`], re-propagating at most `max_ticks` ticks of
    /// history now (a pending re-propagation is finished first); the rest
    /// is done by [`Self::resume`] in later ticks. Until it is done
    /// ([`Self::is_repropagating`]), the estimate stays the uncorrected one;
    /// once done, state and covariance are bit for bit those [`Self::correct`]
    /// gives (the output smoothing takes the jump when it is applied).
    /// `Ok` holds the number of ticks re-propagated now (not counting the
    /// at most `⌈H/16⌉ − 1` ticks replayed from the snapshot before the
    /// measurement's stamp, D31).
    pub fn correct_within(
        &mut self,
        m: &PoseMeasurement,
        max_ticks: usize,
    ) -> Result<usize, RejectReason> {
        self.resume(usize::MAX);
        let r = self.try_correct(m, max_ticks);
        if let Err(reason) = r {
            self.status.rejected.count(reason);
        }
        r
    }

    /// The rules a measurement must pass before the chi-square gate, as
    /// [`Self::correct`] applies them when it is used on the tick stamped
    /// `now_us`: finite and plausible coordinates, standard deviations in
    /// (0, 1000], not after `now_us`, not older than the history, not
    /// before the last accepted one. The host link checks a pose with this
    /// same function when it arrives, so that the host is told why it is
    /// refused (the gate, and a history that moved on by the time the pose
    /// is used, can still reject it later: counted in
    /// [`EstimatorStatus::rejected`]).
    pub fn admissible_at(&self, m: &PoseMeasurement, now_us: u32) -> Result<(), RejectReason> {
        let heading_finite = m.heading_std_rad.is_none() || m.pose.theta_rad.is_finite();
        let ok_coord = |v: f32| v.abs() <= MAX_COORD_M; // false for NaN
        if !(ok_coord(m.pose.x_m) && ok_coord(m.pose.y_m) && heading_finite) {
            return Err(RejectReason::NonFinite);
        }
        let ok_std = |s: f32| s > 0.0 && s <= MAX_STD; // false for NaN
        if !ok_std(m.position_std_m) || !m.heading_std_rad.is_none_or(ok_std) {
            return Err(RejectReason::BadStdDev);
        }
        let Some(oldest) = self.oldest_usable() else {
            return Err(RejectReason::TooOld);
        };
        if (now_us.wrapping_sub(m.stamp_us) as i32) < 0 {
            return Err(RejectReason::FromFuture);
        }
        if (m.stamp_us.wrapping_sub(self.tick_at(oldest).stamp_us) as i32) < 0 {
            return Err(RejectReason::TooOld);
        }
        if let Some(last) = self.last_accepted_stamp_us {
            if (m.stamp_us.wrapping_sub(last) as i32) < 0 {
                return Err(RejectReason::OutOfOrder);
            }
        }
        Ok(())
    }

    fn try_correct(
        &mut self,
        m: &PoseMeasurement,
        max_ticks: usize,
    ) -> Result<usize, RejectReason> {
        self.admissible_at(m, self.now_us)?;
        let Some(oldest) = self.oldest_usable() else {
            return Err(RejectReason::TooOld);
        };
        // The tick nearest in time: the newest tick at or before the stamp
        // (binary search on the ages, which grow with `back`), then the
        // closer of it and the next one.
        let age = self.now_us.wrapping_sub(m.stamp_us);
        let (mut lo, mut hi) = (0, oldest);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.now_us.wrapping_sub(self.tick_at(mid).stamp_us) >= age {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        let mut back = lo;
        if back > 0 {
            let before = self.tick_at(back).stamp_us;
            let after = self.tick_at(back - 1).stamp_us;
            if after.wrapping_sub(m.stamp_us) < m.stamp_us.wrapping_sub(before) {
                back -= 1;
            }
        }
        let (start, _) = self.posterior_at(back);
        let (mut x, mut p) = (start.x, unpack(&start.p));
        let resets = self.status.resets;
        match self.update(&mut x, &mut p, m, true) {
            Ok(()) => self.consecutive_outliers = 0,
            Err(RejectReason::Outlier) => {
                self.consecutive_outliers = self.consecutive_outliers.saturating_add(1);
                if self.consecutive_outliers < self.cfg.max_consecutive_outliers {
                    return Err(RejectReason::Outlier);
                }
                // The estimate has drifted (a long outage, a kidnapped robot):
                // forget the pose, keep the bias, take this measurement.
                self.reset_pose_covariance(&mut p);
                self.update(&mut x, &mut p, m, false)?;
                self.consecutive_outliers = 0;
                self.status.resets = self.status.resets.saturating_add(1);
            }
            Err(r) => return Err(r),
        }
        let corrected = Filter::new(x, pack(&p));
        let post = Snapshot::of(&corrected);
        self.fix = Some(Fix { back, post });
        if let Some(slot) = self.snapshot_slot(back) {
            self.snaps[slot] = post;
        }
        if let Some(last) = self.last_accepted_stamp_us {
            let dt = m.stamp_us.wrapping_sub(last) as f32 * 1e-6;
            let i = match self.mean_interval_s {
                Some(i) => i + INTERVAL_GAIN * (dt.min(1.0) - i),
                None => dt.min(1.0),
            };
            self.mean_interval_s = Some(i);
            self.smoothing_tau_s = self.cfg.output_smoothing_s.min(SMOOTHING_INTERVALS * i);
        }
        self.last_accepted_stamp_us = Some(m.stamp_us);
        self.status.accepted = self.status.accepted.saturating_add(1);
        // Re-propagate the later ticks from their stored inputs.
        self.pending = Some(Repropagation {
            back,
            filter: corrected,
            reset: self.status.resets != resets,
        });
        Ok(self.resume(max_ticks))
    }

    /// Applies a finished correction: the live state becomes the
    /// re-propagated one; the jump of the filter's pose goes into the
    /// output offset (unless it is big or the pose was reset).
    fn finish_correction(&mut self, f: Filter, reset: bool) {
        let before = self.filter_pose();
        self.filter = f;
        let after = self.filter_pose();
        let jump = [
            after.x_m - before.x_m,
            after.y_m - before.y_m,
            wrap_angle(after.theta_rad - before.theta_rad),
        ];
        let big = jump[0].abs() + jump[1].abs() > MAX_SMOOTHED_JUMP_M;
        if self.cfg.output_smoothing_s > 0.0 && !big && !reset {
            for (o, j) in self.offset.iter_mut().zip(jump) {
                *o += j;
            }
            self.offset[2] = wrap_angle(self.offset[2]);
        } else {
            self.offset = [0.0; 3];
        }
        let input = self.tick_at(0).input();
        self.refresh(&input);
    }

    /// Position and heading variances to a wide prior, their correlations
    /// dropped (after `max_consecutive_outliers` gated measurements).
    fn reset_pose_covariance(&self, p: &mut Mat) {
        let big = [1.0e4, 1.0e4, 10.0];
        for i in 0..3 {
            for j in 0..N {
                if i != j {
                    p[i][j] = 0.0;
                    p[j][i] = 0.0;
                }
            }
            p[i][i] = big[i];
        }
    }

    /// The EKF update of `(x, p)` with `m`; with `gate`, refuses an
    /// innovation beyond the chi-square gate. `(x, p)` are untouched on error.
    fn update(
        &mut self,
        x: &mut [f32; N],
        p: &mut Mat,
        m: &PoseMeasurement,
        gate: bool,
    ) -> Result<(), RejectReason> {
        let d = self.com_offset_m;
        let (s, c) = sin_cos(x[2]);
        let n = if m.heading_std_rad.is_some() { 3 } else { 2 };
        let nu = [
            m.pose.x_m - (x[0] + d * c),
            m.pose.y_m - (x[1] + d * s),
            if n == 3 {
                wrap_angle(m.pose.theta_rad - x[2])
            } else {
                0.0
            },
        ];
        // H rows: [1, 0, −d s, 0, 0], [0, 1, d c, 0, 0], [0, 0, 1, 0, 0].
        let h: [[f32; N]; 3] = [
            [1.0, 0.0, -d * s, 0.0, 0.0],
            [0.0, 1.0, d * c, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0, 0.0],
        ];
        let rp = m.position_std_m * m.position_std_m;
        let r = [rp, rp, m.heading_std_rad.map_or(1.0, |sh| sh * sh)];
        // The components one at a time (R is diagonal): scalar updates
        // linearised at the prior, each innovation corrected by the earlier
        // components' state change, give the batch EKF update and its
        // Mahalanobis distance (the sum of the sequential normalised
        // innovations squared) without a matrix inverse, in one small loop
        // (flash: the batch form cost 1.2 KiB more). Equivalence:
        // tests::sequential_update_equals_batch.
        let mut nx = *x;
        let mut np = *p;
        let mut e = nu;
        let mut d2 = 0.0;
        for a in 0..n {
            let ha = &h[a];
            let ph: [f32; N] = core::array::from_fn(|i| (0..N).map(|k| np[i][k] * ha[k]).sum());
            let sa = (0..N).map(|k| ha[k] * ph[k]).sum::<f32>() + r[a];
            if !(sa.is_finite() && sa > 0.0) {
                return Err(RejectReason::NonFinite);
            }
            let inv = 1.0 / sa;
            d2 += e[a] * e[a] * inv;
            let k: [f32; N] = core::array::from_fn(|i| ph[i] * inv);
            for i in 0..N {
                nx[i] += k[i] * e[a];
                for j in 0..N {
                    np[i][j] -= k[i] * ph[j];
                }
            }
            for b in a + 1..n {
                e[b] -= (0..N).map(|i| h[b][i] * k[i] * e[a]).sum::<f32>();
            }
        }
        self.status.last_innovation = nu;
        self.status.last_mahalanobis_sq = d2;
        let limit = if n == 3 {
            self.cfg.chi2_gate_3dof
        } else {
            self.cfg.chi2_gate_2dof
        };
        if !d2.is_finite() || d2 < 0.0 {
            return Err(RejectReason::NonFinite);
        }
        if gate && d2 > limit {
            return Err(RejectReason::Outlier);
        }
        nx[2] = wrap_angle(nx[2]);
        nx[4] = nx[4].clamp(SPEED_SCALE_RANGE.0, SPEED_SCALE_RANGE.1);
        symmetrise(&mut np);
        for (i, row) in np.iter_mut().enumerate() {
            row[i] = row[i].max(MIN_VAR);
        }
        if !all_finite(&nx, &np) {
            return Err(RejectReason::NonFinite);
        }
        *x = nx;
        *p = np;
        Ok(())
    }

    /// The filter's pose of G.
    fn filter_pose(&self) -> Pose {
        let d = self.com_offset_m;
        let f = &self.filter;
        Pose::new(f.x[0] + d * f.cos_th, f.x[1] + d * f.sin_th, f.x[2])
    }

    /// The estimate and status from the live state; `input` is the newest
    /// tick's.
    #[inline(never)]
    fn refresh(&mut self, input: &Input) {
        let g = self.filter_pose();
        let o = self.offset;
        let inv_dt = if input.dt_s > 0.0 {
            1.0 / input.dt_s
        } else {
            1.0
        };
        let yaw = if input.gyro_used {
            input.yaw - self.filter.x[3]
        } else {
            input.yaw * inv_dt
        };
        self.estimate = Estimate {
            pose: Pose::new(g.x_m - o[0], g.y_m - o[1], wrap_angle(g.theta_rad - o[2])),
            filter_pose: g,
            v_mps: input.ds_m * inv_dt,
            yaw_rate_radps: yaw,
        };
    }
}

fn symmetrise(p: &mut Mat) {
    for i in 0..N {
        for j in (i + 1)..N {
            let v = 0.5 * (p[i][j] + p[j][i]);
            p[i][j] = v;
            p[j][i] = v;
        }
    }
}

/// Inverse of a 3x3 matrix by cofactors; `None` when singular or not finite
/// (the batch update of the tests).
#[cfg(test)]
fn invert3(m: &[[f32; 3]; 3]) -> Option<[[f32; 3]; 3]> {
    let c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
    let c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
    let c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    let det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
    if !(det.is_finite() && det > 0.0) {
        return None;
    }
    let id = 1.0 / det;
    let inv = [
        [
            c00 * id,
            (m[0][2] * m[2][1] - m[0][1] * m[2][2]) * id,
            (m[0][1] * m[1][2] - m[0][2] * m[1][1]) * id,
        ],
        [
            c01 * id,
            (m[0][0] * m[2][2] - m[0][2] * m[2][0]) * id,
            (m[0][2] * m[1][0] - m[0][0] * m[1][2]) * id,
        ],
        [
            c02 * id,
            (m[0][1] * m[2][0] - m[0][0] * m[2][1]) * id,
            (m[0][0] * m[1][1] - m[0][1] * m[1][0]) * id,
        ],
    ];
    inv.iter().flatten().all(|v| v.is_finite()).then_some(inv)
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_history;
#[cfg(test)]
mod tests_predict;
