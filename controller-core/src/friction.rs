//! Wheel friction in the dynamic loop: a departure from the paper's model (7)
//! (book/src/explanation/paper-departures.md, D175).
//!
//! The paper's reduced model η̇ = Mη + Nτ (7) has no friction. A real
//! gearmotor loses a Coulomb torque c and a viscous torque b·φ̇ at each
//! wheel; on a small plastic gearbox c is half the torque limit, which the
//! ESO then has to learn as "disturbance" (and the baselines, which have no
//! ESO, never learn). With friction the model reads
//!
//! η̇ = Mη + N(τ − τ_f),  τ_f,i = b_i·φ̇_i + c_i·φ̇_i/(|φ̇_i| + w)        (7f)
//!
//! and the three controllers alike add the friction at the wheel rates the
//! dynamic loop's reference asks for, φ̇_c = wheel rates of η_c (eq. 14):
//!
//! τ = N⁻¹(…)  of eq. (24)  +  τ̂_f(φ̇_c)                                  (24f)
//!
//! At η_c, not at the measured rates: the compensation is a feedforward of
//! the motion the kinematic loop commands, free of the encoders' quantised
//! rate estimate (no noise fed through the Coulomb term's steep middle),
//! and it pushes a wheel the way the loop wants it to go (at the path's
//! rates it would push against a turn in place that corrects a heading).
//!
//! * smooth near zero speed: x/(|x| + w) is continuous with slope 1/w at 0
//!   (no switching, no chatter as a reference wheel rate crosses zero);
//! * never drives a wheel the loop does not ask to move: τ̂_f(0) = 0, and
//!   its sign is the commanded wheel rate's;
//! * bounded: |τ̂_f,i| ≤ c_i + b_i·|φ̇_r,i|, and the sum with the law's
//!   torque is saturated at the torque limit like any request;
//! * the ESO (eq. 18, `Proposed`) is fed the applied torque less τ̂_f, so
//!   it estimates what the friction model misses, not the friction twice.
//!
//! Cost: a handful of multiply-adds and one division per wheel, and
//! nothing at all for a robot without friction (the paper's).

use crate::error::ConfigError;
use crate::math::{all_non_negative, all_positive};

/// The controller's model of the wheels' friction (from the robot file's
/// `motors.*_friction_*`, or identified).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrictionModel {
    /// Viscous coefficient b per wheel `[right, left]` \[N·m·s/rad\].
    pub viscous_nms_per_rad: [f32; 2],
    /// Coulomb (dry) torque c per wheel `[right, left]` \[N·m\].
    pub coulomb_nm: [f32; 2],
    /// Smoothing rate w of the Coulomb term \[rad/s\]: at |φ̇| = w it
    /// compensates half of c (> 0).
    pub smoothing_radps: f32,
}

impl FrictionModel {
    /// No friction (the paper's model (7)): the compensation is zero.
    pub const NONE: Self = Self {
        viscous_nms_per_rad: [0.0; 2],
        coulomb_nm: [0.0; 2],
        smoothing_radps: 1.0,
    };

    /// Checks every field: b, c finite and ≥ 0, w finite and > 0, and each
    /// wheel's c below `torque_limit_nm` (else no torque within the limit
    /// ever moves the wheel).
    pub fn validate(self, torque_limit_nm: f32) -> Result<Self, ConfigError> {
        let [b0, b1] = self.viscous_nms_per_rad;
        let [c0, c1] = self.coulomb_nm;
        let w = self.smoothing_radps;
        let ok = all_non_negative(&[b0, b1, c0, c1])
            && all_positive(&[w, torque_limit_nm - c0, torque_limit_nm - c1]);
        if ok {
            Ok(self)
        } else {
            Err(ConfigError::InvalidFriction)
        }
    }

    /// True when there is any friction to compensate.
    #[inline]
    pub fn is_some(&self) -> bool {
        let [b0, b1] = self.viscous_nms_per_rad;
        let [c0, c1] = self.coulomb_nm;
        b0 != 0.0 || b1 != 0.0 || c0 != 0.0 || c1 != 0.0
    }

    /// τ̂_f of (7f) at the wheel rates `wheel_rates_radps` `[right, left]`
    /// \[N·m\]: b·φ̇ + c·φ̇/(|φ̇| + w), per wheel.
    #[inline]
    pub fn torque_nm(&self, wheel_rates_radps: [f32; 2]) -> [f32; 2] {
        core::array::from_fn(|i| {
            let x = wheel_rates_radps[i];
            self.viscous_nms_per_rad[i] * x
                + self.coulomb_nm[i] * x / (x.abs() + self.smoothing_radps)
        })
    }
}

impl Default for FrictionModel {
    fn default() -> Self {
        Self::NONE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> FrictionModel {
        FrictionModel {
            viscous_nms_per_rad: [0.001, 0.002],
            coulomb_nm: [0.06, 0.05],
            smoothing_radps: 1.0,
        }
    }

    /// Zero at rest, odd, and c + b·x in the limit (|x| ≫ w): the Coulomb
    /// term is c·x/(|x| + w), exactly half of c at |x| = w.
    #[test]
    fn zero_at_rest_odd_and_tends_to_coulomb_plus_viscous() {
        let f = model();
        assert_eq!(f.torque_nm([0.0, 0.0]), [0.0, 0.0]);
        let a = f.torque_nm([3.0, -3.0]);
        let b = f.torque_nm([-3.0, 3.0]);
        assert_eq!(a[0], -b[0]);
        assert_eq!(a[1], -b[1]);
        let half = f.torque_nm([1.0, 1.0]);
        assert!((half[0] - (0.001 + 0.03)).abs() < 1e-7);
        let far = f.torque_nm([1e4, 1e4]);
        assert!((far[0] - (0.06 * 1e4 / (1e4 + 1.0) + 10.0)).abs() < 1e-4);
    }

    /// Never beyond c + b·|x| (the bound the module docs state), and its
    /// sign is the wheel rate's, over a sweep of rates.
    #[test]
    fn bounded_and_signed_like_the_rate() {
        let f = model();
        for k in -2000..=2000 {
            let x = k as f32 * 0.01;
            let t = f.torque_nm([x, x]);
            for i in 0..2 {
                let bound = f.coulomb_nm[i] + f.viscous_nms_per_rad[i] * x.abs();
                assert!(t[i].abs() <= bound * (1.0 + 1e-6), "x {x}: {t:?}");
                assert!(t[i] * x >= 0.0, "x {x}: sign {t:?}");
            }
        }
    }

    #[test]
    fn validate_refuses_friction_at_the_limit_and_bad_numbers() {
        assert!(model().validate(0.12).is_ok());
        assert!(FrictionModel::NONE.validate(0.12).is_ok());
        for bad in [
            FrictionModel {
                coulomb_nm: [0.12, 0.0],
                ..model()
            },
            FrictionModel {
                viscous_nms_per_rad: [-1e-3, 0.0],
                ..model()
            },
            FrictionModel {
                smoothing_radps: 0.0,
                ..model()
            },
            FrictionModel {
                coulomb_nm: [f32::NAN, 0.0],
                ..model()
            },
            FrictionModel {
                viscous_nms_per_rad: [f32::INFINITY, 0.0],
                ..model()
            },
        ] {
            assert_eq!(bad.validate(0.12), Err(ConfigError::InvalidFriction));
        }
    }
}
