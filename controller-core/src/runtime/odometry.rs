//! Wheel odometry of the tracked point G.
//!
//! The axle midpoint O_B is integrated from the wheel angle increments
//! (Δs = r(Δφ_R + Δφ_L)/2, Δθ = r(Δφ_R − Δφ_L)/(2h), the same map as
//! [`RobotParams::eta_from_wheel_rates`]) with the heading at the middle of
//! the step (second order in Δθ); G is then `d = com_offset_m` ahead of O_B:
//! G = O_B + d·\[cos θ, sin θ\].
//!
//! Wheel odometry sees what the wheels did, not what the body did: wheel
//! slip and an actuator fault that changes the body's motion without
//! changing the wheel rotation are invisible to it (see the runtime's
//! [`super::PoseSource`]).

use crate::math::{sin_cos, wrap_angle};
use crate::params::RobotParams;
use crate::types::Pose;

/// Odometry state: the axle midpoint O_B and the heading.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Odometry {
    robot: RobotParams,
    /// Axle midpoint x \[m\].
    mid_x_m: f32,
    /// Axle midpoint y \[m\].
    mid_y_m: f32,
    /// Heading θ \[rad\], wrapped to (−π, π].
    theta_rad: f32,
}

impl Odometry {
    /// Odometry starting with G at `g` (the robot's parameters are trusted
    /// to be validated by the caller, e.g. the controller's configuration).
    pub fn new(robot: RobotParams, g: Pose) -> Self {
        let mut o = Self {
            robot,
            mid_x_m: 0.0,
            mid_y_m: 0.0,
            theta_rad: 0.0,
        };
        o.set_pose(g);
        o
    }

    /// Re-anchors the odometry so that G is at `g` (e.g. on an external
    /// pose measurement). A non-finite `g` is ignored.
    pub fn set_pose(&mut self, g: Pose) {
        if !g.is_finite() {
            return;
        }
        let th = wrap_angle(g.theta_rad);
        let (s, c) = sin_cos(th);
        let d = self.robot.com_offset_m;
        self.mid_x_m = g.x_m - d * c;
        self.mid_y_m = g.y_m - d * s;
        self.theta_rad = th;
    }

    /// Integrates one step of wheel angle increments `[right, left]` \[rad\].
    /// Non-finite increments are ignored (the pose keeps its last value).
    pub fn update(&mut self, dphi_rad: [f32; 2]) {
        if !(dphi_rad[0].is_finite() && dphi_rad[1].is_finite()) {
            return;
        }
        // The wheel-rate -> η map is linear, so it maps angle increments to
        // [Δs, Δθ] just as it maps rates to [v, ω].
        let inc = self.robot.eta_from_wheel_rates(dphi_rad);
        let (ds, dth) = (inc.v_mps, inc.omega_radps);
        let (s, c) = sin_cos(self.theta_rad + 0.5 * dth);
        self.mid_x_m += ds * c;
        self.mid_y_m += ds * s;
        self.theta_rad = wrap_angle(self.theta_rad + dth);
    }

    /// Pose of the tracked point G.
    pub fn pose(&self) -> Pose {
        let (s, c) = sin_cos(self.theta_rad);
        let d = self.robot.com_offset_m;
        Pose::new(self.mid_x_m + d * c, self.mid_y_m + d * s, self.theta_rad)
    }

    /// Pose of the axle midpoint O_B.
    pub fn axle_midpoint(&self) -> Pose {
        Pose::new(self.mid_x_m, self.mid_y_m, self.theta_rad)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::PI;

    fn robot() -> RobotParams {
        RobotParams::paper() // r = 0.1, h = 0.2, d = 0.05
    }

    /// Both wheels turn by the same angle: G moves r·φ along the heading.
    #[test]
    fn straight_drive() {
        let th0 = 0.6f32;
        let mut o = Odometry::new(robot(), Pose::new(1.0, 2.0, th0));
        let step = 0.01f32; // rad per tick per wheel
        for _ in 0..1000 {
            o.update([step, step]);
        }
        let dist = 0.1 * step * 1000.0; // r·φ = 1 m
        let p = o.pose();
        assert!((p.x_m - (1.0 + dist * th0.cos())).abs() < 1e-4, "{p:?}");
        assert!((p.y_m - (2.0 + dist * th0.sin())).abs() < 1e-4);
        assert!((p.theta_rad - th0).abs() < 1e-6);
    }

    /// Wheels turn opposite: the axle midpoint stays put, θ turns by
    /// r·(φ_R − φ_L)/(2h), and G moves on a circle of radius d about O_B.
    #[test]
    fn pure_rotation() {
        let mut o = Odometry::new(robot(), Pose::new(0.05, 0.0, 0.0));
        let step = 0.002f32;
        let n = 1000;
        for _ in 0..n {
            o.update([step, -step]);
        }
        // θ = r·2φ/(2h) = 0.1·2·2/(0.4) = 1 rad.
        let th = 0.1 * (2.0 * step * n as f32) / (2.0 * 0.2);
        let mid = o.axle_midpoint();
        assert!(mid.x_m.abs() < 1e-5 && mid.y_m.abs() < 1e-5, "{mid:?}");
        let p = o.pose();
        assert!((p.theta_rad - th).abs() < 1e-4);
        assert!((p.x_m - 0.05 * th.cos()).abs() < 1e-5);
        assert!((p.y_m - 0.05 * th.sin()).abs() < 1e-5);
    }

    /// Right wheel faster: the midpoint follows a circle of radius
    /// R = h(φ_R + φ_L)/(φ_R − φ_L); after a half turn it is 2R to the left.
    #[test]
    fn constant_curvature_arc_and_wrap() {
        let (pr, pl) = (0.003f32, 0.001f32);
        let mut o = Odometry::new(robot(), Pose::new(0.05, 0.0, 0.0));
        let dth = 0.1 * (pr - pl) / 0.4;
        let n = libm::roundf(PI / dth) as usize;
        for _ in 0..n {
            o.update([pr, pl]);
        }
        let radius = 0.2 * (pr + pl) / (pr - pl); // 0.4 m
        let mid = o.axle_midpoint();
        let turned = n as f32 * dth;
        // Midpoint on the circle centred at (0, R).
        assert!((mid.x_m - radius * turned.sin()).abs() < 1e-3, "{mid:?}");
        assert!((mid.y_m - radius * (1.0 - turned.cos())).abs() < 1e-3);
        // Keep turning past π: heading stays wrapped.
        for _ in 0..n {
            o.update([pr, pl]);
        }
        let th = o.pose().theta_rad;
        assert!(th > -PI && th <= PI);
        assert!(wrap_angle(th - 2.0 * turned).abs() < 1e-3);
    }

    #[test]
    fn non_finite_input_ignored() {
        let mut o = Odometry::new(robot(), Pose::new(1.0, 1.0, 0.3));
        let before = o.pose();
        o.update([f32::NAN, 0.0]);
        o.set_pose(Pose::new(f32::INFINITY, 0.0, 0.0));
        assert_eq!(o.pose(), before);
    }
}
