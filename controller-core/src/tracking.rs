//! Tracking error, eqs. (8)-(9) and the error model (11)-(12).

use crate::math::{sin_cos, wrap_angle};
use crate::types::Pose;

/// Tracking error e = \[e_x, e_y, e_θ\] with sin e_θ and cos e_θ, which the
/// laws use several times per step and so are computed once, here.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackingError {
    /// \[e_x \[m\], e_y \[m\], e_θ \[rad\]\].
    pub e: [f32; 3],
    /// sin e_θ.
    pub sin_eth: f32,
    /// cos e_θ.
    pub cos_eth: f32,
}

impl From<[f32; 3]> for TrackingError {
    #[inline]
    fn from(e: [f32; 3]) -> Self {
        let (sin_eth, cos_eth) = sin_cos(e[2]);
        Self {
            e,
            sin_eth,
            cos_eth,
        }
    }
}

/// Tracking error of eq. (8): the world-frame error \[x_s − x, y_s − y, θ_s − θ\]
/// rotated by −θ, with e_θ wrapped to (−π, π]. (The printed eq. (8) repeats
/// `x_s − x` three times: D2.)
#[inline]
pub fn tracking_error(pose: &Pose, reference: &Pose) -> TrackingError {
    let (s, c) = sin_cos(pose.theta_rad);
    let dx = reference.x_m - pose.x_m;
    let dy = reference.y_m - pose.y_m;
    TrackingError::from([
        c * dx + s * dy,
        -s * dx + c * dy,
        wrap_angle(reference.theta_rad - pose.theta_rad),
    ])
}

/// Error dynamics ė of eq. (11) with the actual body velocities
/// η_r = η − F (eq. 10), and the tracked point G a distance `d` ahead of the
/// axle (the −d·ω_r term in ė_y that eq. (9) omits: D4).
///
/// * ė_x = ω_r·e_y − v_r + v_s·cos e_θ
/// * ė_y = −ω_r·(e_x + d) + v_s·sin e_θ
/// * ė_θ = ω_s − ω_r
#[inline]
pub fn error_rate(
    te: &TrackingError,
    eta: [f32; 2],
    fault: [f32; 2],
    v_s: f32,
    omega_s: f32,
    d_m: f32,
) -> [f32; 3] {
    let (e, se, ce) = (te.e, te.sin_eth, te.cos_eth);
    let v_r = eta[0] - fault[0];
    let w_r = eta[1] - fault[1];
    [
        w_r * e[1] - v_r + v_s * ce,
        -w_r * (e[0] + d_m) + v_s * se,
        omega_s - w_r,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integrates a unicycle-with-offset robot and a reference with RK-free
    /// tiny Euler steps and checks that the finite difference of eq. (8)
    /// matches eq. (11) (the −d·ω term included).
    #[test]
    fn error_rate_matches_finite_difference() {
        let d = 0.05f32;
        let (v, w) = (0.7f32, -0.4f32);
        let fault = [0.1f32, 0.05];
        let (vs, ws) = (0.9f32, 0.3f32);
        let body = |p: Pose| -> [f32; 3] {
            let (s, c) = sin_cos(p.theta_rad);
            let (vr, wr) = (v - fault[0], w - fault[1]);
            [vr * c - d * wr * s, vr * s + d * wr * c, wr]
        };
        let refr = |p: Pose| -> [f32; 3] {
            let (s, c) = sin_cos(p.theta_rad);
            [vs * c, vs * s, ws]
        };
        let p = Pose::new(0.3, -0.2, 0.4);
        let r = Pose::new(0.8, 0.1, 0.9);
        let h = 1e-3f32;
        let (bp, br) = (body(p), refr(r));
        let p2 = Pose::new(
            p.x_m + h * bp[0],
            p.y_m + h * bp[1],
            p.theta_rad + h * bp[2],
        );
        let r2 = Pose::new(
            r.x_m + h * br[0],
            r.y_m + h * br[1],
            r.theta_rad + h * br[2],
        );
        let e1 = tracking_error(&p, &r);
        let e2 = tracking_error(&p2, &r2);
        let rate = error_rate(&e1, [v, w], fault, vs, ws, d);
        let (e1, e2) = (e1.e, e2.e);
        for i in 0..3 {
            let fd = (e2[i] - e1[i]) / h;
            assert!(
                (fd - rate[i]).abs() < 5e-3,
                "component {i}: fd {fd} model {}",
                rate[i]
            );
        }
    }

    #[test]
    fn error_is_zero_on_reference_and_rotation_invariant_norm() {
        let p = Pose::new(1.0, 2.0, 0.5);
        assert_eq!(tracking_error(&p, &p).e, [0.0, 0.0, 0.0]);
        let r = Pose::new(4.0, -2.0, 0.0);
        let te = tracking_error(&p, &r);
        let (s, c) = sin_cos(te.e[2]);
        assert!(te.sin_eth == s && te.cos_eth == c);
        let e = te.e;
        let n = (e[0] * e[0] + e[1] * e[1]).sqrt();
        assert!((n - 5.0).abs() < 1e-5);
    }
}
