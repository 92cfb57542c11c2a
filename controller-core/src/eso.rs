//! Nonlinear extended state observer with fal, eqs. (18)-(19).
//!
//! One observer per velocity channel (v, ω). As NOTES.md points out, (17)-(18)
//! are third-order while the velocity model (7) is first order. We keep the
//! third-order structure and the Table 2 gains by taking x1 = ∫η dt, the
//! wheel-odometry integral (distance and heading from the encoders), so that
//! x̂2 estimates η and x̂3 estimates the lumped disturbance D of (7) (D10):
//!
//! * ė₁ = η − x̂2 − λ1·e₁          (e₁ = x1 − x̂1; x̂1' = x̂2 + λ1 e₁)
//! * x̂2' = Mη + Nτ + x̂3 + λ2·fal(e₁, ζ, α)
//! * x̂3' = λ3·fal(e₁, ζ, α)
//!
//! The printed signs (−λ1 e, −λ2 fal, −λ3 fal with e = x1 − x̂1) make the
//! observer unstable; the known term Mη (f(x1) of eq. 17) is restored (D11).
//! The state is e₁ rather than x̂1, so the absolute odometry integral (which
//! grows without bound) never has to be stored in f32.
//!
//! Anti-windup: `known_accel` must use the torque actually applied (after
//! saturation), so the observer models the real input and does not wind up.

use crate::error::ConfigError;
use crate::math::{all_non_negative, all_positive};
use crate::math::{clamp_abs, powf};

/// fal(e, ζ, α), eq. (19): linear with slope ζ^(α−1) inside |e| <= ζ,
/// |e|^α·sign(e) outside. Continuous at ±ζ.
#[inline]
pub fn fal(e: f32, zeta: f32, alpha: f32) -> f32 {
    fal_with_slope(e, zeta, alpha, powf(zeta, alpha - 1.0))
}

/// [`fal`] with the linear-zone slope ζ^(α−1) given (precomputed once by
/// [`EsoParams::fal_slope`]: a powf costs about 110 instructions on the M4F).
#[inline]
pub fn fal_with_slope(e: f32, zeta: f32, alpha: f32, slope: f32) -> f32 {
    let a = e.abs();
    if a <= zeta {
        e * slope
    } else {
        let y = powf(a, alpha);
        if e > 0.0 {
            y
        } else {
            -y
        }
    }
}

/// ESO parameters (Table 2: α = 0.01, ζ = 0.1, λ = (10, 20, 30)).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EsoParams {
    /// λ1, λ2, λ3.
    pub lambda: [f32; 3],
    /// ζ: half-width of the linear zone of fal.
    pub zeta: f32,
    /// α in (0, 1).
    pub alpha: f32,
    /// Bound on |x̂3| per channel \[m/s², rad/s²\]; 0 switches the
    /// compensation off (D̂ ≡ 0: the proposed controller's dynamic loop is
    /// then ASMC's, issue 34).
    pub max_disturbance: [f32; 2],
}

impl EsoParams {
    /// The defaults (also [`Default::default`]); a constant so that
    /// configurations built from it are data, not code.
    pub const DEFAULT: Self = Self {
        lambda: [10.0, 20.0, 30.0],
        zeta: 0.1,
        alpha: 0.01,
        max_disturbance: [20.0, 40.0],
    };
}

impl Default for EsoParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl EsoParams {
    /// Validates the parameters.
    pub fn validate(self) -> Result<Self, ConfigError> {
        let [l1, l2, l3] = self.lambda;
        let [d0, d1] = self.max_disturbance;
        if !all_positive(&[l1, l2, l3]) || !all_non_negative(&[d0, d1]) {
            return Err(ConfigError::NonPositiveGain);
        }
        // 0 < α < 1 as two positive values.
        if !all_positive(&[self.zeta, self.alpha, 1.0 - self.alpha]) {
            return Err(ConfigError::InvalidFal);
        }
        Ok(self)
    }

    /// Slope of fal inside its linear zone, ζ^(α−1).
    pub fn fal_slope(&self) -> f32 {
        powf(self.zeta, self.alpha - 1.0)
    }
}

/// Observer state for both channels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EsoState {
    /// e₁ = x1 − x̂1 per channel \[m, rad\].
    pub e1: [f32; 2],
    /// x̂2 ≈ η \[m/s, rad/s\].
    pub x2: [f32; 2],
    /// x̂3 ≈ D \[m/s², rad/s²\].
    pub x3: [f32; 2],
    /// False until initialised from the first measurement.
    pub primed: bool,
}

impl EsoParams {
    /// One Euler step of length `dt_s` with the measured η held over the step
    /// and `known_accel` = Mη + Nτ_applied (computes the fal slope; the
    /// controller uses [`Self::update_with_slope`] with it precomputed).
    pub fn update(&self, st: &mut EsoState, eta: [f32; 2], known_accel: [f32; 2], dt_s: f32) {
        self.update_with_slope(st, eta, known_accel, dt_s, self.fal_slope());
    }

    /// [`Self::update`] with the fal slope ζ^(α−1) given.
    #[inline(always)]
    pub fn update_with_slope(
        &self,
        st: &mut EsoState,
        eta: [f32; 2],
        known_accel: [f32; 2],
        dt_s: f32,
        fal_slope: f32,
    ) {
        if !st.primed {
            *st = EsoState {
                x2: eta,
                primed: true,
                ..EsoState::default()
            };
        }
        let [l1, l2, l3] = self.lambda;
        for i in 0..2 {
            let e = st.e1[i];
            let fe = fal_with_slope(e, self.zeta, self.alpha, fal_slope);
            let de = eta[i] - st.x2[i] - l1 * e;
            let dx2 = known_accel[i] + st.x3[i] + l2 * fe;
            let dx3 = l3 * fe;
            st.e1[i] = e + de * dt_s;
            st.x2[i] += dx2 * dt_s;
            st.x3[i] = clamp_abs(st.x3[i] + dx3 * dt_s, self.max_disturbance[i]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fal_continuous_at_zeta_and_odd() {
        for &(z, a) in &[(0.1f32, 0.01f32), (0.5, 0.5), (1.0, 0.25), (0.02, 0.9)] {
            for s in [1.0f32, -1.0] {
                let inside = fal(s * z * (1.0 - 1e-6), z, a);
                let outside = fal(s * z * (1.0 + 1e-6), z, a);
                assert!(
                    (inside - outside).abs() < 1e-4,
                    "z {z} a {a}: {inside} vs {outside}"
                );
            }
            assert!((fal(0.3, z, a) + fal(-0.3, z, a)).abs() < 1e-7);
            assert_eq!(fal(0.0, z, a), 0.0);
        }
    }

    /// Plant η̇ = u + D with a constant D = 2 (a first-order plant like eq. 7):
    /// the observer's x̂3 must recover D. Linearised, the slowest pole of
    /// s³ + λ1 s² + λ2 k s + λ3 k (k = ζ^(α−1) ≈ 9.77) is about −1.6 rad/s,
    /// so after 5 s the error is below e^(−8) of the initial one, and below 2 %.
    #[test]
    fn recovers_constant_disturbance_on_first_order_plant() {
        let p = EsoParams::default();
        let mut st = EsoState::default();
        let dt = 1e-3f32;
        let d = [2.0f32, -1.5];
        let mut eta = [0.0f32, 0.0];
        let mut t = 0.0;
        while t < 8.0 {
            let u = [libm::sinf(t), 0.5 * libm::cosf(2.0 * t)];
            p.update(&mut st, eta, u, dt);
            for i in 0..2 {
                eta[i] += (u[i] + d[i]) * dt;
            }
            t += dt;
            if t > 5.0 {
                for i in 0..2 {
                    assert!(
                        (st.x3[i] - d[i]).abs() < 0.02 * d[i].abs(),
                        "t {t} ch {i} x3 {}",
                        st.x3[i]
                    );
                }
            }
        }
        for i in 0..2 {
            assert!((st.x2[i] - eta[i]).abs() < 1e-2);
        }
    }

    #[test]
    fn linear_zone_poles_are_stable() {
        // Routh-Hurwitz for s³ + a2 s² + a1 s + a0: all > 0 and a2·a1 > a0.
        let p = EsoParams::default();
        let k = p.fal_slope();
        let (a2, a1, a0) = (p.lambda[0], p.lambda[1] * k, p.lambda[2] * k);
        assert!(a2 > 0.0 && a1 > 0.0 && a0 > 0.0 && a2 * a1 > a0);
    }

    #[test]
    fn rejects_bad_fal() {
        let p = EsoParams {
            alpha: 1.0,
            ..Default::default()
        };
        assert_eq!(p.validate(), Err(ConfigError::InvalidFal));
        let p = EsoParams {
            lambda: [1.0, -1.0, 1.0],
            ..Default::default()
        };
        assert_eq!(p.validate(), Err(ConfigError::NonPositiveGain));
        // A zero clamp is the ESO switched off; a negative one is refused.
        let off = EsoParams {
            max_disturbance: [0.0, 0.0],
            ..Default::default()
        };
        assert!(off.validate().is_ok());
        let p = EsoParams {
            max_disturbance: [-1.0, 0.0],
            ..Default::default()
        };
        assert_eq!(p.validate(), Err(ConfigError::NonPositiveGain));
    }
}
