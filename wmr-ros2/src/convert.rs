//! Conversions between ROS 2 messages and the robot's link: poses of
//! `base_link` (REP-105: the axle midpoint O_B) and of G, the point the
//! controller tracks, d ahead of the axle; covariances to the standard
//! deviations the robot's estimator takes; velocity commands within the
//! robot's limits; ROS stamps to robot time.

use ros_mcap::msg::{Pose, Quaternion};
use ros_mcap::Geometry;
use wmr::session::{Capture, PoseClock};
use wmr_protocol::{PoseMsg, Request};

/// Why a message was not forwarded to the robot.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Refusal {
    /// A value is NaN or infinite (which field).
    NotFinite(&'static str),
    /// A value no robot can take (what and why).
    Implausible(String),
    /// The message needs another robot state (what the robot is doing).
    WrongState(String),
    /// Motion is not enabled: call the arm service (or start with --enable).
    NotEnabled,
    /// The robot refused it (its reason).
    Robot(String),
    /// A pose in a frame the bridge does not fuse (which and why).
    WrongFrame(String),
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotFinite(w) => write!(f, "{w} is NaN or infinite"),
            Self::Implausible(w) => write!(f, "{w}"),
            Self::WrongState(w) => write!(f, "{w}"),
            Self::NotEnabled => write!(
                f,
                "motion not enabled: call the arm service (or start wmr-ros2 with --enable)"
            ),
            Self::Robot(w) => write!(f, "the robot refused it: {w}"),
            Self::WrongFrame(w) => write!(f, "{w}"),
        }
    }
}

/// Farthest position the robot takes \[m\] (its `SetPose` limit, D41).
pub const MAX_POSITION_M: f64 = 1000.0;

/// The planar pose \[x m, y m, yaw rad\] of a 3-D pose: its position and
/// the yaw of its orientation (a tilted quaternion's yaw about z). The
/// quaternion must be of unit length within 1 % (a zero quaternion is not
/// a pose).
pub fn planar(p: &Pose) -> Result<[f64; 3], Refusal> {
    let q = p.orientation;
    let v = [p.position.x, p.position.y, q.x, q.y, q.z, q.w];
    if v.iter().any(|x| !x.is_finite()) {
        return Err(Refusal::NotFinite("pose"));
    }
    let n2 = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w;
    if (n2.sqrt() - 1.0).abs() > 0.01 {
        return Err(Refusal::Implausible(format!(
            "orientation quaternion of length {:.4} (not a rotation)",
            n2.sqrt()
        )));
    }
    if p.position.x.abs() > MAX_POSITION_M || p.position.y.abs() > MAX_POSITION_M {
        return Err(Refusal::Implausible(format!(
            "position ({}, {}) m beyond ±{MAX_POSITION_M} m",
            p.position.x, p.position.y
        )));
    }
    Ok([p.position.x, p.position.y, q.yaw()])
}

/// The pose of G of the axle midpoint's pose `b`: G = O_B + d·(cos θ, sin θ)
/// (the inverse of [`Geometry::axle_of`]).
pub fn g_of_axle(geometry: &Geometry, b: [f64; 3]) -> [f64; 3] {
    let (s, c) = b[2].sin_cos();
    let d = geometry.com_offset_m;
    [b[0] + d * c, b[1] + d * s, b[2]]
}

/// The link's pose message of a pose \[m, m, rad\].
pub fn pose_msg(p: [f64; 3]) -> PoseMsg {
    PoseMsg {
        x_m: p[0] as f32,
        y_m: p[1] as f32,
        theta_rad: p[2] as f32,
    }
}

/// The standard deviations \[σx m, σy m, σθ rad\] of G's pose, from the
/// covariance of `base_link`'s pose at heading `theta_rad` (row-major 6×6:
/// x, y, z, roll, pitch, yaw). G = O_B + d·(cos θ, sin θ), so with
/// J = ∂G/∂(x, y, θ) = [[1, 0, −d sin θ], [0, 1, d cos θ], [0, 0, 1]] the
/// covariance of G is J Σ Jᵀ (Σ the x, y, yaw block); the robot's
/// estimator takes its diagonal (the off-diagonal terms are dropped: the
/// link carries three standard deviations). A yaw variance of 10⁶ or more
/// (REP-105's "unknown") or a σθ beyond the robot's 1000 gives σθ = 0:
/// position only.
pub fn std_dev_of_g(
    geometry: &Geometry,
    cov: &[f64; 36],
    theta_rad: f64,
) -> Result<[f32; 3], Refusal> {
    let idx = [0usize, 1, 5];
    let mut s = [[0.0f64; 3]; 3];
    for (i, &a) in idx.iter().enumerate() {
        for (j, &b) in idx.iter().enumerate() {
            s[i][j] = cov[6 * a + b];
        }
    }
    if s.iter().flatten().any(|v| !v.is_finite()) {
        return Err(Refusal::NotFinite("covariance"));
    }
    if s[0][0] <= 0.0 || s[1][1] <= 0.0 || s[2][2] < 0.0 {
        return Err(Refusal::Implausible(format!(
            "covariance diagonal (x {}, y {}, yaw {}): position variances must be > 0, yaw ≥ 0",
            s[0][0], s[1][1], s[2][2]
        )));
    }
    let yaw_known = s[2][2] < UNKNOWN_VARIANCE;
    let (sn, cs) = theta_rad.sin_cos();
    let d = geometry.com_offset_m;
    let j = [[1.0, 0.0, -d * sn], [0.0, 1.0, d * cs], [0.0, 0.0, 1.0]];
    // J Σ Jᵀ, the diagonal only; an unknown yaw does not spread into x, y
    // (its variance is a marker, not a measurement).
    let mut sig = s;
    if !yaw_known {
        sig[2] = [0.0; 3];
        for row in sig.iter_mut() {
            row[2] = 0.0;
        }
    }
    let var = |r: usize| -> f64 {
        let mut acc = 0.0;
        for a in 0..3 {
            for b in 0..3 {
                acc += j[r][a] * sig[a][b] * j[r][b];
            }
        }
        acc
    };
    let sx = var(0).max(0.0).sqrt();
    let sy = var(1).max(0.0).sqrt();
    let st = if yaw_known { s[2][2].sqrt() } else { 0.0 };
    // The robot takes σ in (0, 1000] m for positions, [0, 1000] rad for the
    // heading (book/src/reference/protocol.md, ExternalPose).
    if !(sx > 0.0 && sx <= 1000.0 && sy > 0.0 && sy <= 1000.0) {
        return Err(Refusal::Implausible(format!(
            "position std dev ({sx:.3e}, {sy:.3e}) m not in (0, 1000] m"
        )));
    }
    let st = if st > 1000.0 { 0.0 } else { st };
    Ok([sx as f32, sy as f32, st as f32])
}

/// A yaw variance this large is REP-105's "unknown": the pose carries a
/// position only \[rad²\].
pub const UNKNOWN_VARIANCE: f64 = 1e6;

/// The `ExternalPose` request of a localiser's pose of `base_link` with
/// its covariance, taken at ROS time `stamp_ns` (Unix ns; 0 = not stamped:
/// stamped on arrival), arrived at host time `arrival_us` (µs since the
/// clock's t0): G's pose, G's standard deviations and the stamp in robot
/// time through the link's clock sync. A position-only pose (yaw variance
/// ≥ [`UNKNOWN_VARIANCE`]) has no heading to put G d ahead along: the
/// robot's own heading estimate `heading_rad` is used (when known).
pub fn external_pose_request(
    geometry: &Geometry,
    clock: &PoseClock,
    pose: &Pose,
    cov: &[f64; 36],
    stamp_ns: u64,
    arrival_us: u64,
    heading_rad: Option<f64>,
) -> Result<Request, Refusal> {
    let mut b = planar(pose)?;
    if cov[35] >= UNKNOWN_VARIANCE {
        if let Some(h) = heading_rad.filter(|h| h.is_finite()) {
            b[2] = h;
        }
    }
    let std_dev = std_dev_of_g(geometry, cov, b[2])?;
    let capture = if stamp_ns == 0 {
        Capture::Arrival
    } else {
        Capture::UnixS(stamp_ns as f64 * 1e-9)
    };
    Ok(Request::ExternalPose {
        t_robot_us: clock.robot_stamp_us(capture, arrival_us),
        pose: pose_msg(g_of_axle(geometry, b)),
        std_dev,
    })
}

/// The robot's velocity limits \[m/s, rad/s\] (its `max_speed_mps`,
/// `max_yaw_rate_radps`) and accelerations \[m/s², rad/s²\] (`accel_mps2`,
/// `ang_accel_radps2`), read at connection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Largest |v| \[m/s\].
    pub max_speed_mps: f64,
    /// Largest |ω| \[rad/s\].
    pub max_yaw_rate_radps: f64,
    /// Acceleration \[m/s²\].
    pub accel_mps2: f64,
    /// Angular acceleration \[rad/s²\].
    pub ang_accel_radps2: f64,
}

impl Limits {
    /// Checked: each finite and > 0, and below what no wheeled robot
    /// reaches (20 m/s, 100 rad/s, 50 m/s², 500 rad/s²).
    pub fn new(
        max_speed_mps: f64,
        max_yaw_rate_radps: f64,
        accel_mps2: f64,
        ang_accel_radps2: f64,
    ) -> Result<Self, String> {
        for (v, name, hi) in [
            (max_speed_mps, "max_speed_mps", 20.0),
            (max_yaw_rate_radps, "max_yaw_rate_radps", 100.0),
            (accel_mps2, "accel_mps2", 50.0),
            (ang_accel_radps2, "ang_accel_radps2", 500.0),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= hi) {
                return Err(format!("robot limit {name} = {v} is not in (0, {hi}]"));
            }
        }
        Ok(Self {
            max_speed_mps,
            max_yaw_rate_radps,
            accel_mps2,
            ang_accel_radps2,
        })
    }

    /// These limits scaled by `f` in (0, 1] (speeds by f, accelerations by f).
    pub fn scaled(&self, f: f64) -> Self {
        let f = if f.is_finite() {
            f.clamp(1e-3, 1.0)
        } else {
            1.0
        };
        Self {
            max_speed_mps: self.max_speed_mps * f,
            max_yaw_rate_radps: self.max_yaw_rate_radps * f,
            accel_mps2: self.accel_mps2 * f,
            ang_accel_radps2: self.ang_accel_radps2 * f,
        }
    }
}

/// A `cmd_vel` twist as the robot's velocity command: v = linear.x,
/// ω = angular.z (a planar robot: the other four components must be zero
/// within 1e-6 or the command is refused, it asks for something this robot
/// cannot do). Beyond the limits both are scaled by the same factor, so the
/// path's curvature v/ω is kept; returns the command and whether it was
/// scaled.
pub fn velocity_command(
    linear: [f64; 3],
    angular: [f64; 3],
    limits: &Limits,
    timeout_ms: u16,
) -> Result<(Request, bool), Refusal> {
    if linear.iter().chain(angular.iter()).any(|v| !v.is_finite()) {
        return Err(Refusal::NotFinite("twist"));
    }
    let others = [linear[1], linear[2], angular[0], angular[1]];
    if others.iter().any(|v| v.abs() > 1e-6) {
        return Err(Refusal::Implausible(format!(
            "twist with linear.y/z or angular.x/y nonzero ({others:?}): a differential-drive robot moves along x and turns about z only"
        )));
    }
    let (v, w) = (linear[0], angular[2]);
    let k = 1.0f64
        .min(limits.max_speed_mps / v.abs().max(1e-12))
        .min(limits.max_yaw_rate_radps / w.abs().max(1e-12));
    Ok((
        Request::Velocity {
            v_mps: (v * k) as f32,
            omega_radps: (w * k) as f32,
            timeout_ms,
        },
        k < 1.0,
    ))
}

/// The quaternion of a yaw (re-exported for the path code).
pub fn yaw_quaternion(yaw_rad: f64) -> Quaternion {
    Quaternion::from_yaw(yaw_rad)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ros_mcap::msg::Point;

    fn geo() -> Geometry {
        Geometry::new(0.1, 0.2, 0.05).unwrap()
    }

    fn pose(x: f64, y: f64, yaw: f64) -> Pose {
        Pose {
            position: Point { x, y, z: 0.0 },
            orientation: Quaternion::from_yaw(yaw),
        }
    }

    #[test]
    fn g_and_axle_are_inverse() {
        let g = geo();
        for &(x, y, th) in &[(0.0, 0.0, 0.0), (1.5, -2.0, 2.8), (-3.0, 0.4, -1.2)] {
            let gp = g_of_axle(&g, [x, y, th]);
            // G is d ahead along the heading.
            assert!(((gp[0] - x).hypot(gp[1] - y) - 0.05).abs() < 1e-12);
            let back = g.axle_of(gp);
            for k in 0..3 {
                assert!((back[k] - [x, y, th][k]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn planar_pose_refuses_what_is_no_pose() {
        assert!((planar(&pose(1.0, 2.0, 0.7)).unwrap()[2] - 0.7).abs() < 1e-12);
        let mut p = pose(0.0, 0.0, 0.0);
        p.orientation.w = 0.0;
        assert!(matches!(planar(&p), Err(Refusal::Implausible(_))));
        p = pose(f64::NAN, 0.0, 0.0);
        assert_eq!(planar(&p), Err(Refusal::NotFinite("pose")));
        p = pose(2000.0, 0.0, 0.0);
        assert!(matches!(planar(&p), Err(Refusal::Implausible(_))));
    }

    /// G's spread from the heading's uncertainty: σ² = σ_O² + d²σθ² along
    /// the lateral direction (first-order propagation), checked against a
    /// Monte-Carlo of the same transform.
    #[test]
    fn covariance_propagates_to_g() {
        let g = geo();
        let mut cov = [0.0; 36];
        let (sx, sy, st) = (0.02f64, 0.03f64, 0.2f64);
        cov[0] = sx * sx;
        cov[7] = sy * sy;
        cov[35] = st * st;
        // Heading 0: G = O + d(cos θ, sin θ), lateral is y.
        let s = std_dev_of_g(&g, &cov, 0.0).unwrap();
        assert!((s[0] as f64 - sx).abs() < 1e-6);
        let want_y = (sy * sy + 0.05f64.powi(2) * st * st).sqrt();
        assert!((s[1] as f64 - want_y).abs() < 1e-6, "{s:?}");
        assert!((s[2] as f64 - st).abs() < 1e-6);
        // Monte-Carlo (small σθ so first order holds): deterministic LCG.
        let th0 = 0.9f64;
        let s = std_dev_of_g(&g, &cov, th0).unwrap();
        let mut seed = 12345u64;
        let mut normal = || {
            let mut u = || {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((seed >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        let n = 200_000;
        let (mut mx, mut my, mut mxx, mut myy) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..n {
            let b = [sx * normal(), sy * normal(), th0 + 0.02 * normal()];
            let p = g_of_axle(&g, b);
            mx += p[0];
            my += p[1];
            mxx += p[0] * p[0];
            myy += p[1] * p[1];
        }
        let nf = n as f64;
        let vx = mxx / nf - (mx / nf).powi(2);
        let vy = myy / nf - (my / nf).powi(2);
        let mut cov2 = cov;
        cov2[35] = 0.02 * 0.02;
        let s2 = std_dev_of_g(&g, &cov2, th0).unwrap();
        assert!((vx.sqrt() / s2[0] as f64 - 1.0).abs() < 0.01, "{vx} {s2:?}");
        assert!((vy.sqrt() / s2[1] as f64 - 1.0).abs() < 0.01, "{vy} {s2:?}");
        assert!(s[0] > 0.0);
    }

    #[test]
    fn unknown_yaw_is_position_only_and_bad_covariances_are_refused() {
        let g = geo();
        let mut cov = [0.0; 36];
        cov[0] = 1e-4;
        cov[7] = 1e-4;
        cov[35] = 1e6;
        let s = std_dev_of_g(&g, &cov, 0.3).unwrap();
        assert_eq!(s[2], 0.0);
        assert!((s[0] - 0.01).abs() < 1e-6 && (s[1] - 0.01).abs() < 1e-6);
        cov[0] = 0.0;
        assert!(matches!(
            std_dev_of_g(&g, &cov, 0.0),
            Err(Refusal::Implausible(_))
        ));
        cov[0] = f64::NAN;
        assert_eq!(
            std_dev_of_g(&g, &cov, 0.0),
            Err(Refusal::NotFinite("covariance"))
        );
    }

    fn lim() -> Limits {
        Limits::new(1.0, 3.0, 1.0, 10.0).unwrap()
    }

    #[test]
    fn twist_beyond_the_limits_keeps_its_curvature() {
        let (r, scaled) = velocity_command([2.0, 0.0, 0.0], [0.0, 0.0, 1.0], &lim(), 300).unwrap();
        let Request::Velocity {
            v_mps,
            omega_radps,
            timeout_ms,
        } = r
        else {
            panic!("{r:?}")
        };
        assert!(scaled);
        assert_eq!(timeout_ms, 300);
        assert!((v_mps - 1.0).abs() < 1e-6);
        // Curvature ω/v = 0.5 1/m kept.
        assert!((omega_radps / v_mps - 0.5).abs() < 1e-6);
        let (r, scaled) = velocity_command([0.0, 0.0, 0.0], [0.0, 0.0, -6.0], &lim(), 300).unwrap();
        assert!(scaled);
        assert!(
            matches!(r, Request::Velocity { omega_radps, .. } if (omega_radps + 3.0).abs() < 1e-6)
        );
        let (_, scaled) = velocity_command([0.5, 0.0, 0.0], [0.0, 0.0, 1.0], &lim(), 300).unwrap();
        assert!(!scaled);
        assert!(matches!(
            velocity_command([0.5, 0.2, 0.0], [0.0; 3], &lim(), 300),
            Err(Refusal::Implausible(_))
        ));
        assert_eq!(
            velocity_command([f64::INFINITY, 0.0, 0.0], [0.0; 3], &lim(), 300),
            Err(Refusal::NotFinite("twist"))
        );
    }

    #[test]
    fn limits_are_checked() {
        assert!(Limits::new(0.0, 1.0, 1.0, 1.0).is_err());
        assert!(Limits::new(1.0, f64::NAN, 1.0, 1.0).is_err());
        assert!(Limits::new(1.0, 1.0, 1e9, 1.0).is_err());
    }

    /// A localiser's stamp becomes the robot time the clock sync says:
    /// with robot = host + offset, a pose taken 80 ms before arrival is
    /// stamped 80 ms before the arrival's robot time.
    #[test]
    fn localiser_stamp_is_converted_to_robot_time() {
        let g = geo();
        let sync = wmr::session::ClockSample {
            robot_us: 5_000_000,
            host_mid_us: 1_000_000,
            rtt_us: 200,
        };
        let unix_t0_ns = 1_764_632_000_000_000_000u64;
        let clock = PoseClock::from_sync(sync, unix_t0_ns, 0.001);
        let mut cov = [0.0; 36];
        cov[0] = 1e-4;
        cov[7] = 1e-4;
        cov[35] = 1e-2;
        let arrival_us = 2_000_000; // host µs since t0
        let stamp_ns = unix_t0_ns + (arrival_us - 80_000) * 1000;
        let r = external_pose_request(
            &g,
            &clock,
            &pose(1.0, 2.0, 0.0),
            &cov,
            stamp_ns,
            arrival_us,
            Some(1.0),
        )
        .unwrap();
        let Request::ExternalPose {
            t_robot_us,
            pose: p,
            std_dev,
        } = r
        else {
            panic!()
        };
        assert_eq!(t_robot_us, (arrival_us - 80_000 + 4_000_000) as u32);
        assert!((p.x_m - 1.05).abs() < 1e-6 && (p.y_m - 2.0).abs() < 1e-6);
        assert!((std_dev[2] - 0.1).abs() < 1e-6);
        // Position only: G is d ahead along the robot's own heading, not
        // along the message's meaningless orientation.
        cov[35] = UNKNOWN_VARIANCE;
        let r = external_pose_request(
            &g,
            &clock,
            &pose(1.0, 2.0, 0.0),
            &cov,
            0,
            arrival_us,
            Some(std::f64::consts::FRAC_PI_2),
        )
        .unwrap();
        let Request::ExternalPose {
            pose: p, std_dev, ..
        } = r
        else {
            panic!()
        };
        assert!(
            (p.x_m - 1.0).abs() < 1e-6 && (p.y_m - 2.05).abs() < 1e-6,
            "{p:?}"
        );
        assert_eq!(std_dev[2], 0.0);
    }
}
