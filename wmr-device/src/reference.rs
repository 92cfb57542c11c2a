//! The references the host can load: built-in shapes placed in the world
//! with a speed scale, a bounded buffer of timed waypoints interpolated by
//! cubic Hermite curves, a velocity command integrated into a virtual
//! vehicle, and the braking profile of a controlled stop.

use crate::limits::{LimitExceeded, Quantity, RobotLimits, MAX_POSITION_M, SHAPE_LENGTH_M};
use controller_core::math::{atan2, sin_cos, sqrt, wrap_angle};
use controller_core::trajectory::{
    tangent_sample, Circle, FigureEight, Line, PaperCurve, PaperHeading, RefSample, Reference,
    Trajectory,
};
use controller_core::Pose;
use heapless::Deque;
use wmr_protocol::{BuiltinReference, BuiltinShape, PoseMsg, Waypoint, SEGMENT_POINTS};

/// Largest accepted speed scale.
pub const MAX_SPEED_SCALE: f32 = 10.0;
/// Smallest accepted speed scale (a reference slowed a hundredfold).
pub const MIN_SPEED_SCALE: f32 = 0.01;
/// Waypoints the trajectory buffer holds.
pub const WAYPOINT_CAPACITY: usize = 64;

/// Protocol pose to controller-core pose.
pub fn pose_from_msg(p: PoseMsg) -> Pose {
    Pose::new(p.x_m, p.y_m, p.theta_rad)
}

/// Controller-core pose to protocol pose.
pub fn pose_to_msg(p: Pose) -> PoseMsg {
    PoseMsg {
        x_m: p.x_m,
        y_m: p.y_m,
        theta_rad: p.theta_rad,
    }
}

/// A built-in shape placed rigidly in the world and time-scaled; validated
/// by [`PlacedReference::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacedReference {
    shape: Reference,
    scale: f32,
    /// Rotation φ and the translation applied after rotating about the
    /// shape's start point `origin`.
    phi_rad: f32,
    origin: [f32; 2],
    target: [f32; 2],
}

impl PlacedReference {
    /// [`Self::within`] the absolute limits
    /// ([`MAX_SPEED_MPS`](crate::limits::MAX_SPEED_MPS),
    /// [`MAX_YAW_RATE_RADPS`](crate::limits::MAX_YAW_RATE_RADPS)); the
    /// device checks against its robot's.
    pub fn new(r: &BuiltinReference) -> Option<Self> {
        Self::within(r, &RobotLimits::ABSOLUTE)
    }

    /// Validates and places `r`; `None` when a parameter is not finite or
    /// out of its physical range (D41): lengths in
    /// [`SHAPE_LENGTH_M`], the start within
    /// [`MAX_POSITION_M`], and the shape's
    /// peak speed and yaw rate (bounded analytically, times the speed
    /// scale) within the robot's top speed and yaw rate.
    pub fn within(r: &BuiltinReference, lim: &RobotLimits) -> Option<Self> {
        let len_ok = |l: f32| l >= SHAPE_LENGTH_M.0 && l <= SHAPE_LENGTH_M.1;
        // (lengths, peak |v| [m/s], peak |ω| [rad/s], peak |p̈| [m/s²]) at
        // speed scale 1 (|p̈| bounds |v̇|: tangential and centripetal).
        let (lengths, v_peak, w_peak, a_peak) = match r.shape {
            // v = −w·(ax sin u, 3ay sin 3u): |v| ≤ w·√(ax² + 9ay²); the
            // heading follows W = w·(ax, 3ay(1 + 2cos 2u)) (v = −sin u·W),
            // which turns at most at ax·w·12ay·w²/(ax·w)² = 12·ay·w/ax;
            // p̈ = −w²·(ax cos u, 9ay cos 3u): |p̈| ≤ w²·√(ax² + 81ay²).
            BuiltinShape::PaperCurve {
                ax_m,
                ay_m,
                w_radps,
            } => (
                [ax_m, ay_m],
                w_radps * sqrt(ax_m * ax_m + 9.0 * ay_m * ay_m),
                12.0 * ay_m * w_radps / ax_m,
                w_radps * w_radps * sqrt(ax_m * ax_m + 81.0 * ay_m * ay_m),
            ),
            BuiltinShape::Circle {
                radius_m,
                speed_mps,
            } => (
                [radius_m; 2],
                speed_mps,
                speed_mps / radius_m,
                speed_mps * speed_mps / radius_m,
            ),
            // |v| ≤ √2·A·w; |ω| = |ẋÿ − ẏẍ|/|v|² ≤ 3A²w³/(0.4375·A²w²) < 7w;
            // p̈ = −A·w²·(sin wt, 2 sin 2wt): |p̈| ≤ √5·A·w².
            BuiltinShape::FigureEight {
                amplitude_m,
                w_radps,
            } => (
                [amplitude_m; 2],
                core::f32::consts::SQRT_2 * amplitude_m * w_radps,
                7.0 * w_radps,
                sqrt(5.0) * amplitude_m * w_radps * w_radps,
            ),
            BuiltinShape::Line { speed_mps } => ([SHAPE_LENGTH_M.0; 2], speed_mps.abs(), 0.0, 0.0),
        };
        let s = r.speed_scale;
        let physical = lengths.iter().all(|&l| len_ok(l))
            && s * v_peak <= lim.top_speed_mps
            && s * w_peak <= lim.top_yaw_rate_radps
            && s * s * a_peak <= lim.top_accel_mps2;
        if !physical {
            return None;
        }
        let shape = match r.shape {
            BuiltinShape::PaperCurve {
                ax_m,
                ay_m,
                w_radps,
            } => Reference::Paper(PaperCurve {
                ax_m,
                ay_m,
                w_radps,
                heading: PaperHeading::SignedSmooth,
            }),
            BuiltinShape::Circle {
                radius_m,
                speed_mps,
            } => Reference::Circle(Circle {
                radius_m,
                speed_mps,
            }),
            BuiltinShape::FigureEight {
                amplitude_m,
                w_radps,
            } => Reference::FigureEight(FigureEight {
                amplitude_m,
                w_radps,
            }),
            BuiltinShape::Line { speed_mps } => Reference::Line(Line {
                start: Pose::new(0.0, 0.0, 0.0),
                speed_mps,
            }),
        };
        let shape = shape.validate().ok()?;
        let s = r.speed_scale;
        if !(MIN_SPEED_SCALE..=MAX_SPEED_SCALE).contains(&s) {
            return None;
        }
        let r0 = shape.sample(0.0).pose;
        let (phi_rad, origin, target) = match r.start {
            None => (0.0, [0.0; 2], [0.0; 2]),
            Some(p)
                if p.is_finite()
                    && p.x_m.abs() <= MAX_POSITION_M
                    && p.y_m.abs() <= MAX_POSITION_M =>
            {
                (
                    wrap_angle(p.theta_rad - r0.theta_rad),
                    [r0.x_m, r0.y_m],
                    [p.x_m, p.y_m],
                )
            }
            Some(_) => return None,
        };
        Some(Self {
            shape,
            scale: s,
            phi_rad,
            origin,
            target,
        })
    }
}

impl Trajectory for PlacedReference {
    fn sample(&self, t_s: f32) -> RefSample {
        let s = self.scale;
        let r = self.shape.sample(s * t_s);
        let (sn, cs) = sin_cos(self.phi_rad);
        let dx = r.pose.x_m - self.origin[0];
        let dy = r.pose.y_m - self.origin[1];
        RefSample {
            pose: Pose::new(
                self.target[0] + cs * dx - sn * dy,
                self.target[1] + sn * dx + cs * dy,
                r.pose.theta_rad + self.phi_rad,
            ),
            v_mps: s * r.v_mps,
            omega_radps: s * r.omega_radps,
            v_dot_mps2: s * s * r.v_dot_mps2,
            omega_dot_radps2: s * s * r.omega_dot_radps2,
        }
    }
}

/// Why a segment was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SegmentError {
    /// No upload begun, wrong index or non-increasing time.
    OutOfOrder,
    /// Not enough room.
    Full,
    /// A non-finite or unphysical value.
    Invalid,
    /// The curve from waypoint `index` to the next one asks more than the
    /// robot can do ([`check_segment`]).
    BeyondLimits {
        /// Trajectory index of the segment's first waypoint.
        index: u32,
        /// What, how much and the limit.
        exceeded: LimitExceeded,
    },
}

/// `x <= limit`, false for NaN (a NaN peak is beyond every limit, and
/// replaces any running maximum).
fn at_most(x: f32, limit: f32) -> bool {
    x <= limit
}

/// The device's check of the Hermite curve from `a` to `b` at upload, cut
/// to what fits in a control tick (firmware-emu's worst-tick budget, 20,000
/// instructions; [`check_segment`]'s 33 samples of 8 waypoints cost 55,000):
/// the acceleration |p̈| exactly (its larger end) and the speed bounded
/// from above by the control polygons of the velocity's quadratic Bézier
/// split in four (de Casteljau; at most 15 % above the peak, a quarter
/// turn between two waypoints, 1.5 %). The yaw rate is left to the
/// per-tick check ([`RobotLimits::check_sample`]); the host checks it at
/// the samples first (`wmr upload --robot`, [`check_segment`]).
pub fn check_segment_on_device(
    a: &Waypoint,
    b: &Waypoint,
    lim: &RobotLimits,
) -> Result<(), LimitExceeded> {
    let sc = |w: &Waypoint| sin_cos(w.pose.theta_rad);
    check_segment_with(a, sc(a), b, sc(b), lim)
}

/// [`check_segment_on_device`] with the headings' (sin, cos) given (each
/// waypoint's computed once by [`WaypointBuffer::push`]).
fn check_segment_with(
    a: &Waypoint,
    (sa, ca): (f32, f32),
    b: &Waypoint,
    (sb, cb): (f32, f32),
    lim: &RobotLimits,
) -> Result<(), LimitExceeded> {
    let h = b.t_s - a.t_s;
    let m0 = [h * a.v_mps * ca, h * a.v_mps * sa];
    let m1 = [h * b.v_mps * cb, h * b.v_mps * sb];
    let d = [
        3.0 * (b.pose.x_m - a.pose.x_m) - m0[0] - m1[0],
        3.0 * (b.pose.y_m - a.pose.y_m) - m0[1] - m1[1],
    ];
    // Squared norms, one square root at the end of each bound (the
    // tick's budget: 8 segments in one tick).
    let norm2 = |v: [f32; 2]| v[0] * v[0] + v[1] * v[1];
    let e0 = [d[0] - m0[0], d[1] - m0[1]];
    let e1 = [m1[0] - d[0], m1[1] - d[1]];
    let accel = 2.0 * sqrt(norm2(e0).max(norm2(e1))) / (h * h);
    if !at_most(accel, lim.top_accel_mps2) {
        return Err(LimitExceeded {
            quantity: Quantity::AccelMps2,
            value: accel,
            limit: lim.top_accel_mps2,
        });
    }
    // dp/ds = m0(1−s)² + 2d·s(1−s) + m1·s²: a quadratic Bézier with control
    // points m0, d, m1, split at s = 1/4, 1/2, 3/4; its norm is at most the
    // largest control point's of the piece it is in.
    let at = |s: f32| {
        let (u, w) = ((1.0 - s) * (1.0 - s), 2.0 * s * (1.0 - s));
        [
            m0[0] * u + d[0] * w + m1[0] * s * s,
            m0[1] * u + d[1] * w + m1[1] * s * s,
        ]
    };
    // The middle control point of the piece [s0, s1]: B(s0) + (s1 − s0)/2 · B'(s0).
    let mid = |s0: f32, s1: f32| {
        let p = at(s0);
        let k = s1 - s0;
        [
            p[0] + k * (e0[0] * (1.0 - s0) + e1[0] * s0),
            p[1] + k * (e0[1] * (1.0 - s0) + e1[1] * s0),
        ]
    };
    let mut peak2 = norm2(m0).max(norm2(m1));
    for i in 0..4 {
        let s0 = i as f32 * 0.25;
        peak2 = peak2.max(norm2(mid(s0, s0 + 0.25)));
        if i > 0 {
            peak2 = peak2.max(norm2(at(s0)));
        }
    }
    let speed = sqrt(peak2) / h;
    if !at_most(speed, lim.top_speed_mps) {
        return Err(LimitExceeded {
            quantity: Quantity::SpeedMps,
            value: speed,
            limit: lim.top_speed_mps,
        });
    }
    Ok(())
}

/// Intervals of a Hermite segment in [`check_segment`] (33 samples).
pub const SEGMENT_CHECK_SAMPLES: usize = 32;

/// Checks the cubic Hermite curve from `a` to `b` (as [`hermite`] drives
/// it; `b.t_s > a.t_s`) against the robot's limits `lim` (issue 31 item 1:
/// each waypoint within the limits is not enough, the curve between two
/// can ask far more):
///
/// * speed: an upper bound of the peak from [`SEGMENT_CHECK_SAMPLES`]
///   intervals of the velocity polynomial, each bounded by its Taylor
///   expansion (exact for a quadratic), within O(1/N²) of the peak;
/// * acceleration |p̈| (tangential and centripetal together, so at least
///   |v̇|): exact, p̈ is linear in time and peaks at an end;
/// * yaw rate ω = (ṗ × p̈)/|ṗ|² at the samples (near a standstill, where
///   [`hermite`] interpolates the heading, the heading's change over the
///   segment's time); between samples the device's per-tick check
///   ([`RobotLimits::check_sample`]) holds it.
///
/// Cost: two sines and cosines and about 33 × 30 multiplications, no
/// trigonometry per sample.
pub fn check_segment(a: &Waypoint, b: &Waypoint, lim: &RobotLimits) -> Result<(), LimitExceeded> {
    let h = b.t_s - a.t_s;
    let (sa, ca) = sin_cos(a.pose.theta_rad);
    let (sb, cb) = sin_cos(b.pose.theta_rad);
    let m0 = [h * a.v_mps * ca, h * a.v_mps * sa];
    let m1 = [h * b.v_mps * cb, h * b.v_mps * sb];
    let d = [
        3.0 * (b.pose.x_m - a.pose.x_m) - m0[0] - m1[0],
        3.0 * (b.pose.y_m - a.pose.y_m) - m0[1] - m1[1],
    ];
    let norm = |v: [f32; 2]| sqrt(v[0] * v[0] + v[1] * v[1]);
    // dp/ds = m0(1−s)² + 2d·s(1−s) + m1·s² (a quadratic Bézier), and
    // d²p/ds² = 2[(d − m0)(1 − s) + (m1 − d)s]: ṗ = (dp/ds)/h, p̈ = (d²p/ds²)/h².
    let e0 = [d[0] - m0[0], d[1] - m0[1]];
    let e1 = [m1[0] - d[0], m1[1] - d[1]];
    let dd_max = 2.0 * norm(e0).max(norm(e1));
    let accel = dd_max / (h * h);
    let exceeded = |quantity, value, limit| LimitExceeded {
        quantity,
        value,
        limit,
    };
    if !at_most(accel, lim.top_accel_mps2) {
        return Err(exceeded(Quantity::AccelMps2, accel, lim.top_accel_mps2));
    }
    let n = SEGMENT_CHECK_SAMPLES;
    let step = 1.0 / n as f32;
    // dp/ds is a quadratic: from a sample s_i, dp/ds(s_i + τ) =
    // B_i + B'_i·τ + ½B''·τ² exactly, so over [s_i, s_i + step] its norm is
    // at most max(|B_i|, |B_i + B'_i·step|) (a linear function's norm is
    // convex) + ½|B''|·step²: a bound within O(step²) of the peak.
    let b2nd = 2.0 * norm([e1[0] - e0[0], e1[1] - e0[1]]);
    let mut speed_bound = 0.0f32;
    let mut omega_peak = 0.0f32;
    for i in 0..=n {
        let s = i as f32 * step;
        let (u, w) = ((1.0 - s) * (1.0 - s), 2.0 * s * (1.0 - s));
        let bs = [
            m0[0] * u + d[0] * w + m1[0] * s * s,
            m0[1] * u + d[1] * w + m1[1] * s * s,
        ];
        let dds = [
            2.0 * (e0[0] * (1.0 - s) + e1[0] * s),
            2.0 * (e0[1] * (1.0 - s) + e1[1] * s),
        ];
        let b2 = bs[0] * bs[0] + bs[1] * bs[1];
        let speed = sqrt(b2) / h;
        let ahead = norm([bs[0] + dds[0] * step, bs[1] + dds[1] * step]);
        let interval = if i < n {
            sqrt(b2).max(ahead) + 0.5 * b2nd * step * step
        } else {
            sqrt(b2)
        };
        if !at_most(interval / h, speed_bound) {
            speed_bound = interval / h;
        }
        let omega = if speed < MIN_TANGENT_SPEED_MPS {
            wrap_angle(b.pose.theta_rad - a.pose.theta_rad) / h
        } else {
            (bs[0] * dds[1] - bs[1] * dds[0]) / (h * b2)
        };
        if !at_most(omega.abs(), omega_peak) {
            omega_peak = omega.abs();
        }
    }
    if !at_most(speed_bound, lim.top_speed_mps) {
        return Err(exceeded(Quantity::SpeedMps, speed_bound, lim.top_speed_mps));
    }
    if !at_most(omega_peak, lim.top_yaw_rate_radps) {
        return Err(exceeded(
            Quantity::YawRateRadps,
            omega_peak,
            lim.top_yaw_rate_radps,
        ));
    }
    Ok(())
}

/// The bounded buffer of an uploaded trajectory.
#[derive(Clone, Debug, Default)]
pub struct WaypointBuffer {
    points: Deque<Waypoint, WAYPOINT_CAPACITY>,
    /// Trajectory index of `points[0]`.
    head_index: u32,
    /// Index the next segment must start at.
    next_index: u32,
    total: u32,
    begun: bool,
}

impl WaypointBuffer {
    /// Clears the buffer and expects `total` waypoints.
    pub fn begin(&mut self, total: u32) {
        *self = Self {
            total,
            begun: true,
            ..Self::default()
        };
    }

    /// Drops everything.
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// Appends a segment; waypoints already passed at reference time
    /// `t_now_s` (all but the one before it) make room when needed. Each
    /// waypoint must be finite and physical for `lim`: |x|, |y| within
    /// [`MAX_POSITION_M`], |v| within the top speed, |ω| within the top yaw
    /// rate. A segment already held (same index, same waypoints: a retry
    /// after a lost acknowledgement) is accepted again without change.
    pub fn push(
        &mut self,
        first_index: u32,
        points: &[Waypoint],
        t_now_s: Option<f32>,
        lim: &RobotLimits,
    ) -> Result<(), SegmentError> {
        if self.begun && first_index < self.next_index && self.holds(first_index, points) {
            // A retry after a lost acknowledgement: the same segment again.
            return Ok(());
        }
        if !self.begun || first_index != self.next_index {
            return Err(SegmentError::OutOfOrder);
        }
        if self.next_index as u64 + points.len() as u64 > self.total as u64 {
            return Err(SegmentError::OutOfOrder);
        }
        let mut last_t = self.points.back().map(|w| w.t_s);
        let mut prev = self.points.back().map(|w| (*w, sin_cos(w.pose.theta_rad)));
        for (k, w) in points.iter().enumerate() {
            // Written so that NaN fails every comparison.
            let physical = w.t_s.is_finite()
                && w.pose.theta_rad.is_finite()
                && w.pose.x_m.abs() <= MAX_POSITION_M
                && w.pose.y_m.abs() <= MAX_POSITION_M
                && w.v_mps.abs() <= lim.top_speed_mps
                && w.omega_radps.abs() <= lim.top_yaw_rate_radps;
            if !physical || w.t_s < 0.0 {
                return Err(SegmentError::Invalid);
            }
            if last_t.is_some_and(|t| w.t_s <= t) {
                return Err(SegmentError::OutOfOrder);
            }
            last_t = Some(w.t_s);
            // The curve from the previous waypoint (held, or of this
            // segment) to this one.
            let sc = sin_cos(w.pose.theta_rad);
            if let Some((a, sca)) = prev {
                let index = (first_index + k as u32).wrapping_sub(1);
                check_segment_with(&a, sca, w, sc, lim)
                    .map_err(|exceeded| SegmentError::BeyondLimits { index, exceeded })?;
            }
            prev = Some((*w, sc));
        }
        if let Some(t) = t_now_s {
            while self.points.len() >= 2 && self.points.iter().nth(1).is_some_and(|w| w.t_s <= t) {
                if self.free() >= points.len() {
                    break;
                }
                self.points.pop_front();
                self.head_index += 1;
            }
        }
        if self.free() < points.len() {
            return Err(SegmentError::Full);
        }
        for w in points {
            // Cannot fail: room checked above.
            let _ = self.points.push_back(*w);
        }
        self.next_index += points.len() as u32;
        Ok(())
    }

    /// The buffer holds exactly `points` from trajectory index `first`.
    fn holds(&self, first: u32, points: &[Waypoint]) -> bool {
        let Some(skip) = first.checked_sub(self.head_index) else {
            return false; // already passed and dropped: cannot tell
        };
        let end = skip as usize + points.len();
        end <= self.points.len()
            && self
                .points
                .iter()
                .skip(skip as usize)
                .zip(points)
                .all(|(a, b)| a == b)
    }

    /// Free slots.
    pub fn free(&self) -> usize {
        WAYPOINT_CAPACITY - self.points.len()
    }

    /// Waypoints held.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Index the next segment must start at.
    pub fn next_index(&self) -> u32 {
        self.next_index
    }

    /// Drivable from t = 0: at least two waypoints, the first one held.
    pub fn ready(&self) -> bool {
        self.begun && self.head_index == 0 && self.points.len() >= 2
    }

    /// Can be armed (D42): [`Self::ready`], and either every declared
    /// waypoint has arrived or the buffer has no room for the next segment
    /// (a trajectory longer than the buffer: the rest streams while
    /// running). A cut upload (48 of 80 waypoints, room for more) cannot.
    pub fn armable(&self) -> bool {
        let rest = self.total.saturating_sub(self.next_index) as usize;
        self.ready() && (self.complete() || self.free() < rest.min(SEGMENT_POINTS))
    }

    /// Every waypoint of the upload has arrived.
    pub fn complete(&self) -> bool {
        self.begun && self.next_index == self.total
    }

    /// The reference at `t_s`, or `None` past the last buffered waypoint.
    pub fn sample(&self, t_s: f32) -> Option<RefSample> {
        let first = self.points.front()?;
        if t_s <= first.t_s {
            return Some(hold_sample(first));
        }
        self.points
            .iter()
            .zip(self.points.iter().skip(1))
            .find(|(_, b)| t_s <= b.t_s)
            .map(|(a, b)| hermite(a, b, t_s))
    }

    /// The last buffered waypoint.
    pub fn last(&self) -> Option<Waypoint> {
        self.points.back().copied()
    }
}

fn hold_sample(w: &Waypoint) -> RefSample {
    RefSample {
        pose: pose_from_msg(w.pose),
        v_mps: w.v_mps,
        omega_radps: w.omega_radps,
        v_dot_mps2: 0.0,
        omega_dot_radps2: 0.0,
    }
}

/// Speed of the Hermite curve below which the heading is interpolated \[m/s\].
const MIN_TANGENT_SPEED_MPS: f32 = 1e-3;

/// Cubic Hermite between two waypoints: positions and velocity vectors
/// v·(cos θ, sin θ) at both ends; heading along the tangent (flipped where
/// the interpolated v is negative); ω, v̇, ω̇ from the exact derivatives.
pub fn hermite(a: &Waypoint, b: &Waypoint, t_s: f32) -> RefSample {
    let h = b.t_s - a.t_s;
    let s = ((t_s - a.t_s) / h).clamp(0.0, 1.0);
    let (sa, ca) = sin_cos(a.pose.theta_rad);
    let (sb, cb) = sin_cos(b.pose.theta_rad);
    let p0 = [a.pose.x_m, a.pose.y_m];
    let p1 = [b.pose.x_m, b.pose.y_m];
    let m0 = [h * a.v_mps * ca, h * a.v_mps * sa];
    let m1 = [h * b.v_mps * cb, h * b.v_mps * sb];
    let (s2, s3) = (s * s, s * s * s);
    let c0 = [
        2.0 * s3 - 3.0 * s2 + 1.0,
        s3 - 2.0 * s2 + s,
        -2.0 * s3 + 3.0 * s2,
        s3 - s2,
    ];
    let c1 = [
        6.0 * s2 - 6.0 * s,
        3.0 * s2 - 4.0 * s + 1.0,
        -6.0 * s2 + 6.0 * s,
        3.0 * s2 - 2.0 * s,
    ];
    let c2 = [
        12.0 * s - 6.0,
        6.0 * s - 4.0,
        -12.0 * s + 6.0,
        6.0 * s - 2.0,
    ];
    let c3 = [12.0, 6.0, -12.0, 6.0];
    let comb = |c: [f32; 4], scale: f32| {
        core::array::from_fn::<f32, 2, _>(|k| {
            (c[0] * p0[k] + c[1] * m0[k] + c[2] * p1[k] + c[3] * m1[k]) * scale
        })
    };
    let p = comb(c0, 1.0);
    let d1 = comb(c1, 1.0 / h);
    let d2 = comb(c2, 1.0 / (h * h));
    let d3 = comb(c3, 1.0 / (h * h * h));
    let v_lin = a.v_mps + s * (b.v_mps - a.v_mps);
    let speed2 = d1[0] * d1[0] + d1[1] * d1[1];
    if speed2 < MIN_TANGENT_SPEED_MPS * MIN_TANGENT_SPEED_MPS {
        let dth = wrap_angle(b.pose.theta_rad - a.pose.theta_rad);
        return RefSample {
            pose: Pose::new(p[0], p[1], a.pose.theta_rad + s * dth),
            v_mps: 0.0,
            omega_radps: dth / h,
            v_dot_mps2: 0.0,
            omega_dot_radps2: 0.0,
        };
    }
    let mut r = tangent_sample(p, d1, d2, d3);
    if v_lin < 0.0 {
        r.pose.theta_rad = wrap_angle(r.pose.theta_rad + core::f32::consts::PI);
        r.v_mps = -r.v_mps;
        r.v_dot_mps2 = -r.v_dot_mps2;
    }
    r
}

/// A unicycle reference integrated tick by tick: the virtual vehicle of
/// velocity commands and of controlled stops.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VirtualVehicle {
    /// The current sample (pose, v, ω and their rates of change).
    pub sample: RefSample,
}

impl VirtualVehicle {
    /// Standing at `pose`.
    pub fn at_rest(pose: Pose) -> Self {
        Self {
            sample: RefSample {
                pose,
                ..RefSample::default()
            },
        }
    }

    /// Continuing from `sample`.
    pub fn from_sample(sample: RefSample) -> Self {
        Self { sample }
    }

    /// Advances one period `dt_s` with the rates `v_dot`, `omega_dot`
    /// (midpoint rule for the pose).
    pub fn advance(&mut self, dt_s: f32, v_dot: f32, omega_dot: f32) {
        let r = &mut self.sample;
        let v1 = r.v_mps + v_dot * dt_s;
        let w1 = r.omega_radps + omega_dot * dt_s;
        let v_mid = 0.5 * (r.v_mps + v1);
        let w_mid = 0.5 * (r.omega_radps + w1);
        let (s, c) = sin_cos(r.pose.theta_rad + 0.5 * w_mid * dt_s);
        r.pose = Pose::new(
            r.pose.x_m + v_mid * c * dt_s,
            r.pose.y_m + v_mid * s * dt_s,
            wrap_angle(r.pose.theta_rad + w_mid * dt_s),
        );
        r.v_mps = v1;
        r.omega_radps = w1;
    }

    /// The rate that moves `x` toward `target` by at most `limit`·`dt_s`
    /// in one period, exactly reaching it when closer.
    pub fn ramp_rate(x: f32, target: f32, limit: f32, dt_s: f32) -> f32 {
        let d = target - x;
        let step = limit * dt_s;
        if d.abs() <= step {
            d / dt_s
        } else if d > 0.0 {
            limit
        } else {
            -limit
        }
    }
}

/// Heading of a velocity vector (for tests and the host tool).
pub fn heading_of(vx: f32, vy: f32) -> f32 {
    atan2(vy, vx)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wp(t: f32, x: f32, y: f32, th: f32, v: f32, w: f32) -> Waypoint {
        Waypoint {
            t_s: t,
            pose: PoseMsg {
                x_m: x,
                y_m: y,
                theta_rad: th,
            },
            v_mps: v,
            omega_radps: w,
        }
    }

    /// Hermite segments pass through both waypoints with their velocity
    /// (forwards and backwards), and the sample's v and ω are the
    /// derivatives of its own pose (central differences).
    #[test]
    fn hermite_interpolates_ends_and_is_self_consistent() {
        for sign in [1.0f32, -1.0] {
            let a = wp(1.0, 0.0, 0.0, 0.0, sign * 0.5, 0.0);
            let b = wp(3.0, sign * 1.0, 0.6, 0.6, sign * 0.5, 0.0);
            let ra = hermite(&a, &b, 1.0);
            let rb = hermite(&a, &b, 3.0);
            assert!((ra.pose.x_m - 0.0).abs() < 1e-6 && (rb.pose.y_m - 0.6).abs() < 1e-6);
            assert!((ra.v_mps - sign * 0.5).abs() < 1e-5, "{}", ra.v_mps);
            assert!((ra.pose.theta_rad - 0.0).abs() < 1e-5);
            assert!((wrap_angle(rb.pose.theta_rad - 0.6)).abs() < 1e-5);
            let h = 1e-3;
            let mut t = 1.05;
            while t < 2.95 {
                let (p, m, n) = (
                    hermite(&a, &b, t - h),
                    hermite(&a, &b, t),
                    hermite(&a, &b, t + h),
                );
                let vx = (n.pose.x_m - p.pose.x_m) / (2.0 * h);
                let vy = (n.pose.y_m - p.pose.y_m) / (2.0 * h);
                let (s, c) = sin_cos(m.pose.theta_rad);
                assert!((vx - m.v_mps * c).abs() < 2e-3 && (vy - m.v_mps * s).abs() < 2e-3);
                let w = wrap_angle(n.pose.theta_rad - p.pose.theta_rad) / (2.0 * h);
                assert!(
                    (w - m.omega_radps).abs() < 5e-3,
                    "t {t}: {w} vs {}",
                    m.omega_radps
                );
                t += 0.1;
            }
        }
    }

    /// `check_segment`'s speed and acceleration against an independent
    /// evaluation: the curve `hermite` drives, sampled every 1/2000 of the
    /// segment (speed from the sample's v; acceleration from central
    /// differences of the position every 1/200). The speed bound is never below the
    /// dense peak and within 2 % (+1 mm/s) above it; the acceleration is
    /// exact.
    #[test]
    fn segment_bounds_hold_against_the_dense_curve() {
        use proptest::prelude::*;
        let lim = RobotLimits::ABSOLUTE;
        let mut runner = proptest::test_runner::TestRunner::default();
        let coords = (
            0.05f32..3.0,
            -2.0f32..2.0,
            -2.0f32..2.0,
            -3.2f32..3.2,
            -3.2f32..3.2,
            -2.0f32..2.0,
            -2.0f32..2.0,
        );
        runner
            .run(&coords, |(h, x, y, th0, th1, v0, v1)| {
                let a = wp(0.0, 0.0, 0.0, th0, v0, 0.0);
                let b = wp(h, x, y, th1, v1, 0.0);
                let n = 2000;
                let pos = |t: f32| {
                    let r = hermite(&a, &b, t);
                    [r.pose.x_m as f64, r.pose.y_m as f64]
                };
                let (mut v_peak, mut a_peak) = (0.0f64, 0.0f64);
                for i in 0..=n {
                    let t = h * i as f32 / n as f32;
                    v_peak = v_peak.max(hermite(&a, &b, t).v_mps.abs() as f64);
                    // Every 10th sample, differenced over 10: coarse
                    // enough for f32 positions (a central second
                    // difference is exact for a cubic).
                    if i >= 10 && i <= n - 10 && i % 10 == 0 {
                        let dt = (10.0 * h / n as f32) as f64;
                        let (p0, p1, p2) = (
                            pos(t - 10.0 * h / n as f32),
                            pos(t),
                            pos(t + 10.0 * h / n as f32),
                        );
                        let acc = [
                            (p2[0] - 2.0 * p1[0] + p0[0]) / (dt * dt),
                            (p2[1] - 2.0 * p1[1] + p0[1]) / (dt * dt),
                        ];
                        a_peak = a_peak.max(acc[0].hypot(acc[1]));
                    }
                }
                // Limits just below the bound make it report the bound.
                let tight = RobotLimits {
                    top_speed_mps: 0.0,
                    top_accel_mps2: f32::MAX,
                    ..lim
                };
                let e = check_segment(&a, &b, &tight).unwrap_err();
                let bound = e.value as f64;
                prop_assert!(bound >= v_peak * (1.0 - 1e-4) - 1e-5, "{bound} < {v_peak}");
                prop_assert!(bound <= v_peak * 1.02 + 1e-3, "{bound} vs {v_peak}");
                // The device's cheaper bound: never below the peak, at most
                // 15 % (+1 mm/s) above it.
                let e = check_segment_on_device(
                    &a,
                    &b,
                    &RobotLimits {
                        top_speed_mps: 0.0,
                        top_accel_mps2: f32::MAX,
                        ..lim
                    },
                )
                .unwrap_err();
                let dev = e.value as f64;
                prop_assert!(dev >= v_peak * (1.0 - 1e-4) - 1e-5, "{dev} < {v_peak}");
                prop_assert!(dev <= v_peak * 1.15 + 1e-3, "{dev} vs {v_peak}");
                let tight = RobotLimits {
                    top_accel_mps2: 0.0,
                    ..lim
                };
                let e = check_segment(&a, &b, &tight).unwrap_err();
                let acc = e.value as f64;
                // f32 positions differenced: a few 1e-3 relative.
                prop_assert!(
                    (acc - a_peak).abs() <= 0.02 * acc + 0.05,
                    "{acc} vs {a_peak}"
                );
                Ok(())
            })
            .unwrap();
    }

    /// A placed, scaled line starts on the requested pose, heads its way
    /// and runs at s times its speed.
    #[test]
    fn placed_reference_starts_on_the_start_pose() {
        let r = PlacedReference::new(&BuiltinReference {
            shape: BuiltinShape::Circle {
                radius_m: 2.0,
                speed_mps: 0.5,
            },
            start: Some(PoseMsg {
                x_m: 1.0,
                y_m: -1.0,
                theta_rad: 0.0,
            }),
            speed_scale: 0.5,
        })
        .unwrap();
        let s0 = r.sample(0.0);
        assert!((s0.pose.x_m - 1.0).abs() < 1e-5 && (s0.pose.y_m + 1.0).abs() < 1e-5);
        assert!(s0.pose.theta_rad.abs() < 1e-5);
        assert!((s0.v_mps - 0.25).abs() < 1e-6);
        // A quarter circle of radius 2 (π m) at 0.25 m/s takes 4π s and
        // ends 2 m ahead and 2 m to the left, heading +y.
        let q = r.sample(core::f32::consts::PI / 0.25);
        assert!(
            (q.pose.x_m - 3.0).abs() < 1e-3 && (q.pose.y_m - 1.0).abs() < 1e-3,
            "{q:?}"
        );
        let bad = BuiltinReference {
            shape: BuiltinShape::Line { speed_mps: 0.1 },
            start: None,
            speed_scale: 0.0,
        };
        assert!(PlacedReference::new(&bad).is_none());
    }
}
