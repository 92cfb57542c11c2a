//! A `nav_msgs/Path` as the robot's timed waypoints.
//!
//! The path's poses are of `base_link` (REP-105). The controller tracks G,
//! d ahead of the axle, so each pose is moved to its G (d along its
//! heading: exact on straight stretches and at rest; on a curve of radius
//! R the axle runs within about d²/R of the given path). A path whose
//! stamps increase strictly is taken with those times (its speeds from
//! the differences, refused beyond the limits); a path without times (all
//! stamps equal, as planners send them) gets a speed profile: the G path
//! resampled every [`MAX_SPACING_M`], its heading along the path, speed
//! capped by the speed limit and by the yaw-rate limit over the local
//! curvature (v ≤ ω_max/|κ|), a forward and a backward pass with the
//! acceleration limit (from rest, to rest), then ω = κ·v, and the speed
//! lowered where |Δω/Δt| would exceed the angular acceleration limit.
//! The robot interpolates between waypoints by cubic Hermite curves
//! (wmr-device's `reference::hermite`).

use crate::convert::{g_of_axle, planar, Limits, Refusal};
use crate::msg::Path;
use ros_mcap::Geometry;
use wmr_protocol::{PoseMsg, Waypoint};

/// Longest spacing of the profiled waypoints \[m\].
pub const MAX_SPACING_M: f64 = 0.05;
/// Poses closer than this to the previous one are dropped \[m\].
pub const MIN_SPACING_M: f64 = 1e-3;
/// Most waypoints a path may become (a 100 m path at 5 cm spacing): the
/// robot streams them, but a bound keeps a runaway message bounded.
pub const MAX_WAYPOINTS: usize = 2000;

fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    a - t * ((a + std::f64::consts::PI) / t).floor()
}

/// The timed waypoints of `path` for a robot of `geometry` within `limits`.
pub fn waypoints(
    path: &Path,
    geometry: &Geometry,
    limits: &Limits,
) -> Result<Vec<Waypoint>, Refusal> {
    if path.poses.len() < 2 {
        return Err(Refusal::Implausible(format!(
            "a path of {} poses: at least 2",
            path.poses.len()
        )));
    }
    let mut base = Vec::with_capacity(path.poses.len());
    for p in &path.poses {
        base.push((planar(&p.pose)?, p.header.stamp.to_ns()));
    }
    let stamps: Vec<u64> = base.iter().map(|b| b.1).collect();
    let timed = stamps.windows(2).all(|w| w[1] > w[0]);
    if timed {
        timed_waypoints(&base, geometry, limits)
    } else {
        let pts: Vec<[f64; 2]> = base.iter().map(|(p, _)| [p[0], p[1]]).collect();
        profiled(&pts, base[0].0[2], geometry, limits)
    }
}

/// A path with its own times: G's poses at those times, v and ω from the
/// differences (central inside, one-sided at the ends, zero at both ends
/// when the path starts and ends at rest: its first and last steps).
fn timed_waypoints(
    base: &[([f64; 3], u64)],
    geometry: &Geometry,
    limits: &Limits,
) -> Result<Vec<Waypoint>, Refusal> {
    if base.len() > MAX_WAYPOINTS {
        return Err(Refusal::Implausible(format!(
            "{} poses: at most {MAX_WAYPOINTS}",
            base.len()
        )));
    }
    let t0 = base[0].1;
    let g: Vec<[f64; 3]> = base.iter().map(|(p, _)| g_of_axle(geometry, *p)).collect();
    let t: Vec<f64> = base.iter().map(|(_, s)| (s - t0) as f64 * 1e-9).collect();
    let n = g.len();
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
        let dt = t[b] - t[a];
        let (sn, cs) = g[i][2].sin_cos();
        let v = ((g[b][0] - g[a][0]) * cs + (g[b][1] - g[a][1]) * sn) / dt;
        let w = wrap(g[b][2] - g[a][2]) / dt;
        if v.abs() > limits.max_speed_mps * 1.001 || w.abs() > limits.max_yaw_rate_radps * 1.001 {
            return Err(Refusal::Implausible(format!(
                "the path's times ask v = {v:.3} m/s, ω = {w:.3} rad/s at pose {i}: beyond the robot's {:.3} m/s, {:.3} rad/s (send it without times for a profile within the limits)",
                limits.max_speed_mps, limits.max_yaw_rate_radps
            )));
        }
        out.push(Waypoint {
            t_s: t[i] as f32,
            pose: PoseMsg {
                x_m: g[i][0] as f32,
                y_m: g[i][1] as f32,
                theta_rad: g[i][2] as f32,
            },
            v_mps: v as f32,
            omega_radps: w as f32,
        });
    }
    Ok(out)
}

/// The speed profile of the base path `pts` (its first heading
/// `theta0_rad` gives where G starts; G's path is then profiled).
fn profiled(
    pts: &[[f64; 2]],
    theta0_rad: f64,
    geometry: &Geometry,
    limits: &Limits,
) -> Result<Vec<Waypoint>, Refusal> {
    // Drop repeated points.
    let mut p: Vec<[f64; 2]> = Vec::with_capacity(pts.len());
    for q in pts {
        if p.last()
            .is_none_or(|l| (q[0] - l[0]).hypot(q[1] - l[1]) >= MIN_SPACING_M)
        {
            p.push(*q);
        }
    }
    if p.len() < 2 {
        return Err(Refusal::Implausible(
            "the path's poses all lie within 1 mm: nothing to drive".into(),
        ));
    }
    // Headings of the base path: along each segment, the bisector at a
    // vertex; the first pose's own heading is ignored when it is not the
    // path's (a planner's poses often carry none).
    let _ = theta0_rad;
    let seg = |i: usize| (p[i + 1][1] - p[i][1]).atan2(p[i + 1][0] - p[i][0]);
    let m = p.len();
    let mut th = vec![0.0; m];
    th[0] = seg(0);
    th[m - 1] = seg(m - 2);
    for (i, t) in th.iter_mut().enumerate().take(m - 1).skip(1) {
        let (a, b) = (seg(i - 1), seg(i));
        *t = a + 0.5 * wrap(b - a);
    }
    // G's points, resampled.
    let g: Vec<[f64; 2]> = (0..m)
        .map(|i| {
            let q = g_of_axle(geometry, [p[i][0], p[i][1], th[i]]);
            [q[0], q[1]]
        })
        .collect();
    let mut r: Vec<[f64; 2]> = vec![g[0]];
    for w in g.windows(2) {
        let l = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        let k = (l / MAX_SPACING_M).ceil().max(1.0) as usize;
        for j in 1..=k {
            let f = j as f64 / k as f64;
            r.push([
                w[0][0] + f * (w[1][0] - w[0][0]),
                w[0][1] + f * (w[1][1] - w[0][1]),
            ]);
        }
        if r.len() > MAX_WAYPOINTS {
            return Err(Refusal::Implausible(format!(
                "the path is longer than {MAX_WAYPOINTS} waypoints at {MAX_SPACING_M} m"
            )));
        }
    }
    let r: Vec<[f64; 2]> = {
        let mut out: Vec<[f64; 2]> = Vec::with_capacity(r.len());
        for q in r {
            if out
                .last()
                .is_none_or(|l| (q[0] - l[0]).hypot(q[1] - l[1]) >= MIN_SPACING_M)
            {
                out.push(q);
            }
        }
        out
    };
    let n = r.len();
    if n < 2 {
        return Err(Refusal::Implausible("the path is too short".into()));
    }
    let ds: Vec<f64> = r
        .windows(2)
        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .collect();
    let gseg = |i: usize| (r[i + 1][1] - r[i][1]).atan2(r[i + 1][0] - r[i][0]);
    // Heading of G's path, unwrapped (continuous).
    let mut h = vec![0.0; n];
    h[0] = gseg(0);
    for i in 1..n {
        let target = if i == n - 1 {
            gseg(n - 2)
        } else {
            let (a, b) = (gseg(i - 1), gseg(i));
            a + 0.5 * wrap(b - a)
        };
        h[i] = h[i - 1] + wrap(target - h[i - 1]);
    }
    // Curvature dθ/ds at each point.
    let kappa: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
            let s: f64 = ds[a..b].iter().sum();
            if s > 0.0 {
                (h[b] - h[a]) / s
            } else {
                0.0
            }
        })
        .collect();
    let mut cap: Vec<f64> = kappa
        .iter()
        .map(|k| {
            limits
                .max_speed_mps
                .min(limits.max_yaw_rate_radps / k.abs().max(1e-9))
        })
        .collect();
    cap[0] = 0.0;
    cap[n - 1] = 0.0;
    let a = limits.accel_mps2;
    let mut v = vec![0.0; n];
    let mut t = vec![0.0; n];
    for _round in 0..60 {
        v.copy_from_slice(&cap);
        for i in 0..n - 1 {
            v[i + 1] = v[i + 1].min((v[i] * v[i] + 2.0 * a * ds[i]).sqrt());
        }
        for i in (0..n - 1).rev() {
            v[i] = v[i].min((v[i + 1] * v[i + 1] + 2.0 * a * ds[i]).sqrt());
        }
        for i in 0..n - 1 {
            let mean = 0.5 * (v[i] + v[i + 1]);
            // A segment driven from rest to rest (both ends at 0) cannot
            // happen past the first pass (a > 0, ds > 0).
            let dt = if mean > 0.0 {
                ds[i] / mean
            } else {
                f64::INFINITY
            };
            // Never faster in heading than the yaw-rate limit.
            let dt = dt.max((h[i + 1] - h[i]).abs() / limits.max_yaw_rate_radps);
            t[i + 1] = t[i] + dt;
        }
        // Angular acceleration: lower the cap where |Δω|/Δt is too large.
        let mut ok = true;
        for i in 0..n - 1 {
            let (w0, w1) = (kappa[i] * v[i], kappa[i + 1] * v[i + 1]);
            let dt = t[i + 1] - t[i];
            if (w1 - w0).abs() > limits.ang_accel_radps2 * dt * 1.0001 {
                ok = false;
                let j = if w1.abs() > w0.abs() { i + 1 } else { i };
                cap[j] = v[j] * 0.9;
            }
        }
        if ok {
            break;
        }
    }
    if t.iter().any(|x| !x.is_finite()) {
        return Err(Refusal::Implausible(
            "no speed profile for this path within the robot's limits".into(),
        ));
    }
    Ok((0..n)
        .map(|i| Waypoint {
            t_s: t[i] as f32,
            pose: PoseMsg {
                x_m: r[i][0] as f32,
                y_m: r[i][1] as f32,
                theta_rad: wrap(h[i]) as f32,
            },
            v_mps: v[i] as f32,
            omega_radps: (kappa[i] * v[i]) as f32,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::PoseStamped;
    use ros_mcap::msg::{Header, Point, Pose, Quaternion, Time};

    fn geo() -> Geometry {
        Geometry::new(0.1, 0.2, 0.05).unwrap()
    }

    fn lim() -> Limits {
        Limits::new(0.5, 2.0, 0.5, 5.0).unwrap()
    }

    fn path(pts: &[(f64, f64, f64, u64)]) -> Path {
        Path {
            header: Header::default(),
            poses: pts
                .iter()
                .map(|&(x, y, yaw, t)| PoseStamped {
                    header: Header {
                        stamp: Time::from_ns(t),
                        frame_id: "odom".into(),
                    },
                    pose: Pose {
                        position: Point { x, y, z: 0.0 },
                        orientation: Quaternion::from_yaw(yaw),
                    },
                })
                .collect(),
        }
    }

    /// A straight 2 m line at v_max 0.5, a 0.5 m/s²: the trapezoid takes
    /// L/v + v/a = 4 + 1 = 5 s (accelerating 0.25 m each end).
    #[test]
    fn straight_line_takes_the_trapezoids_time() {
        let w = waypoints(
            &path(&[(0.0, 0.0, 0.0, 0), (2.0, 0.0, 0.0, 0)]),
            &geo(),
            &lim(),
        )
        .unwrap();
        let last = w.last().unwrap();
        assert!((last.t_s - 5.0).abs() < 0.02, "{}", last.t_s);
        // G is d ahead of the axle: the line of G runs from 0.05 to 2.05.
        assert!((w[0].pose.x_m - 0.05).abs() < 1e-6);
        assert!((last.pose.x_m - 2.05).abs() < 1e-6);
        assert_eq!(w[0].v_mps, 0.0);
        assert_eq!(last.v_mps, 0.0);
        assert!(w
            .iter()
            .all(|p| p.v_mps <= 0.5 + 1e-6 && p.omega_radps.abs() < 1e-6));
        assert!(w.windows(2).all(|p| p[1].t_s > p[0].t_s));
        assert!(w
            .windows(2)
            .all(|p| ((p[1].pose.x_m - p[0].pose.x_m) as f64) <= MAX_SPACING_M + 1e-6));
    }

    /// The base on a circle of radius R puts G on one of √(R² + d²)
    /// (d ahead, tangent heading). At R = 0.5 m the yaw-rate limit 2 rad/s
    /// does not bind (0.5 m/s over 0.502 m is 1 rad/s); at R = 0.1 m it caps
    /// v at 2 rad/s · 0.1118 m = 0.224 m/s. Every limit holds throughout.
    #[test]
    fn curvature_caps_the_speed_and_every_limit_holds() {
        for (radius, vmax) in [(0.5, 0.5), (0.1, 2.0 * (0.01f64 + 0.0025).sqrt())] {
            let pts: Vec<(f64, f64, f64, u64)> = (0..=200)
                .map(|k| {
                    let a = k as f64 / 200.0 * std::f64::consts::TAU;
                    (radius * a.sin(), radius * (1.0 - a.cos()), a, 0)
                })
                .collect();
            let w = waypoints(&path(&pts), &geo(), &lim()).unwrap();
            let peak = w.iter().map(|p| p.v_mps).fold(0.0f32, f32::max) as f64;
            assert!(peak <= vmax * 1.03 + 1e-6, "r {radius}: peak {peak}");
            assert!(peak >= vmax * 0.7, "r {radius}: peak {peak}");
            for p in w.windows(2) {
                let dt = (p[1].t_s - p[0].t_s) as f64;
                assert!(dt > 0.0);
                let acc = (p[1].v_mps - p[0].v_mps).abs() as f64 / dt;
                let alpha = (p[1].omega_radps - p[0].omega_radps).abs() as f64 / dt;
                assert!(acc <= 0.5 * 1.05 + 1e-3, "accel {acc}");
                assert!(alpha <= 5.0 * 1.05 + 1e-3, "alpha {alpha}");
                assert!(p[0].omega_radps.abs() as f64 <= 2.0 * 1.001);
            }
        }
    }

    /// Integrating the profile's (v, ω) as a unicycle from the first
    /// waypoint ends near the last one: speeds, headings and times agree.
    #[test]
    fn profile_is_consistent_with_unicycle_kinematics() {
        let pts: Vec<(f64, f64, f64, u64)> = (0..=40)
            .map(|k| {
                let x = k as f64 * 0.05;
                (x, 0.3 * (x * 1.5).sin(), 0.0, 0)
            })
            .collect();
        let w = waypoints(&path(&pts), &geo(), &lim()).unwrap();
        let (mut x, mut y, mut th) = (
            w[0].pose.x_m as f64,
            w[0].pose.y_m as f64,
            w[0].pose.theta_rad as f64,
        );
        for p in w.windows(2) {
            let dt = (p[1].t_s - p[0].t_s) as f64;
            let steps = 20;
            for k in 0..steps {
                let f = (k as f64 + 0.5) / steps as f64;
                let v = p[0].v_mps as f64 + f * (p[1].v_mps - p[0].v_mps) as f64;
                let om = p[0].omega_radps as f64 + f * (p[1].omega_radps - p[0].omega_radps) as f64;
                x += v * th.cos() * dt / steps as f64;
                y += v * th.sin() * dt / steps as f64;
                th += om * dt / steps as f64;
            }
        }
        let l = w.last().unwrap();
        let err = (x - l.pose.x_m as f64).hypot(y - l.pose.y_m as f64);
        assert!(err < 0.03, "unicycle ends {err} m from the last waypoint");
    }

    #[test]
    fn timed_paths_keep_their_times_and_are_checked() {
        let s = 1_000_000_000u64;
        let w = waypoints(
            &path(&[
                (0.0, 0.0, 0.0, 10 * s),
                (0.2, 0.0, 0.0, 11 * s),
                (0.4, 0.0, 0.0, 12 * s),
            ]),
            &geo(),
            &lim(),
        )
        .unwrap();
        assert_eq!(w.len(), 3);
        assert_eq!(w[2].t_s, 2.0);
        assert!((w[1].v_mps - 0.2).abs() < 1e-6);
        // 1 m in 1 s is beyond 0.5 m/s.
        let e = waypoints(
            &path(&[(0.0, 0.0, 0.0, s), (1.0, 0.0, 0.0, 2 * s)]),
            &geo(),
            &lim(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("beyond"), "{e}");
    }

    #[test]
    fn degenerate_paths_are_refused() {
        assert!(waypoints(&path(&[(0.0, 0.0, 0.0, 0)]), &geo(), &lim()).is_err());
        assert!(waypoints(
            &path(&[(1.0, 1.0, 0.0, 0), (1.0, 1.0 + 1e-5, 0.0, 0)]),
            &geo(),
            &lim()
        )
        .is_err());
        assert!(waypoints(
            &path(&[(0.0, 0.0, 0.0, 0), (f64::NAN, 0.0, 0.0, 0)]),
            &geo(),
            &lim()
        )
        .is_err());
        assert!(waypoints(
            &path(&[(0.0, 0.0, 0.0, 0), (200.0, 0.0, 0.0, 0)]),
            &geo(),
            &lim()
        )
        .is_err());
    }
}
