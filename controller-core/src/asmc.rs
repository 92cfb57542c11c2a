//! Integral sliding surface (20) and (adaptive) sliding-mode torque law (22)-(24).
//!
//! s = e_η + k_s ∫e_η dt                                     (20)
//! τ = N⁻¹(η̇_c − Mη − x̂3 + k_s e_η + ρ̂ tanh(s))             (24)
//!
//! The printed adaptation ρ̂' = ρ|s|(1 + 2|atan(ξ/s)|/(e_ρ π)) divides by the
//! unknown e_ρ = ρ − ρ̂ and cannot be implemented (D12). We use, per channel,
//!
//! ρ̂' = γ·max(|s| − δ, 0) − σ·(ρ̂ − ρ0),  ρ̂ ∈ \[ρ_min, ρ_max\],
//!
//! frozen while the torque saturates: a dead zone δ against noise-driven
//! drift, σ-leakage towards ρ0 and hard bounds, so ρ̂ is bounded for any s.

use crate::error::ConfigError;
use crate::math::tanh;
use crate::math::{all_non_negative, all_positive};

/// Adaptive switching gain parameters (per channel, same values for v and ω).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdaptiveGain {
    /// γ: adaptation rate (Table 2's ρ = 0.1).
    pub gamma: f32,
    /// δ: dead zone on |s| (Table 2's ξ = 0.01).
    pub dead_zone: f32,
    /// σ \[1/s\]: leakage rate towards ρ0.
    pub leakage: f32,
    /// Initial value and leakage target ρ0.
    pub rho0: f32,
    /// Lower bound ρ_min.
    pub rho_min: f32,
    /// Upper bound ρ_max.
    pub rho_max: f32,
}

impl AdaptiveGain {
    /// The defaults (also [`Default::default`]); a constant so that
    /// configurations built from it are data, not code.
    pub const DEFAULT: Self = Self {
        gamma: 0.1,
        dead_zone: 0.01,
        leakage: 0.01,
        rho0: 0.1,
        rho_min: 0.0,
        rho_max: 5.0,
    };
}

impl Default for AdaptiveGain {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Switching gain of the sliding-mode term.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Switching {
    /// Fixed gain K (plain SMC baseline).
    Fixed(f32),
    /// Adaptive gain ρ̂ (ASMC and the proposed controller).
    Adaptive(AdaptiveGain),
}

/// Parameters of the sliding-mode velocity loop.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlidingParams {
    /// k_s \[1/s\] (Table 2: 5 for the baselines, 50 for the proposed).
    pub k_s: f32,
    /// Switching gain.
    pub switching: Switching,
}

impl SlidingParams {
    /// Validates the parameters.
    pub fn validate(self) -> Result<Self, ConfigError> {
        if !all_positive(&[self.k_s]) {
            return Err(ConfigError::NonPositiveGain);
        }
        match self.switching {
            Switching::Fixed(k) if !all_non_negative(&[k]) => Err(ConfigError::NonPositiveGain),
            Switching::Adaptive(a) => {
                // ρ_min <= ρ0 <= ρ_max as non-negative differences.
                if all_non_negative(&[
                    a.gamma,
                    a.dead_zone,
                    a.leakage,
                    a.rho0,
                    a.rho_min,
                    a.rho_max,
                    a.rho0 - a.rho_min,
                    a.rho_max - a.rho0,
                ]) {
                    Ok(self)
                } else {
                    Err(ConfigError::InvalidAdaptation)
                }
            }
            _ => Ok(self),
        }
    }

    /// Initial switching gain per channel.
    pub fn rho_initial(&self) -> f32 {
        match self.switching {
            Switching::Fixed(k) => k,
            Switching::Adaptive(a) => a.rho0,
        }
    }
}

/// State of the sliding loop.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlidingState {
    /// ∫e_η dt per channel \[m, rad\].
    pub integral: [f32; 2],
    /// ρ̂ per channel.
    pub rho_hat: [f32; 2],
}

impl SlidingParams {
    /// Sliding variable s of eq. (20).
    #[inline]
    pub fn surface(&self, st: &SlidingState, e_eta: [f32; 2]) -> [f32; 2] {
        [
            e_eta[0] + self.k_s * st.integral[0],
            e_eta[1] + self.k_s * st.integral[1],
        ]
    }

    /// The bracket of eq. (24): the body acceleration request
    /// η̇_c − Mη − x̂3 + k_s e_η + ρ̂ tanh(s); τ = N⁻¹·(this).
    #[inline]
    pub fn accel_request(
        &self,
        st: &SlidingState,
        eta_c_dot: [f32; 2],
        m_eta: [f32; 2],
        d_hat: [f32; 2],
        e_eta: [f32; 2],
        s: [f32; 2],
    ) -> [f32; 2] {
        let mut a = [0.0; 2];
        for i in 0..2 {
            a[i] = eta_c_dot[i] - m_eta[i] - d_hat[i]
                + self.k_s * e_eta[i]
                + st.rho_hat[i] * tanh(s[i]);
        }
        a
    }

    /// Advances ∫e_η and ρ̂ by `dt_s`. Both are frozen while `saturated`
    /// (conditional integration anti-windup).
    pub fn advance(
        &self,
        st: &mut SlidingState,
        e_eta: [f32; 2],
        s: [f32; 2],
        saturated: bool,
        dt_s: f32,
    ) {
        if saturated {
            return;
        }
        for i in 0..2 {
            st.integral[i] += e_eta[i] * dt_s;
            if let Switching::Adaptive(a) = self.switching {
                // max(|s| − δ, 0) without `f32::max`, which is a call to
                // fmaxf on the M4F (no VMAXNM); a NaN gives 0 as with `max`.
                let excess = s[i].abs() - a.dead_zone;
                let drive = if excess > 0.0 { excess } else { 0.0 };
                let r =
                    st.rho_hat[i] + (a.gamma * drive - a.leakage * (st.rho_hat[i] - a.rho0)) * dt_s;
                // Not f32::clamp: its panic message links float formatting (~14 KiB).
                st.rho_hat[i] = if r > a.rho_max {
                    a.rho_max
                } else if r < a.rho_min {
                    a.rho_min
                } else {
                    r
                };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn adaptive() -> SlidingParams {
        SlidingParams {
            k_s: 5.0,
            switching: Switching::Adaptive(AdaptiveGain::default()),
        }
    }

    /// Under a persistent disturbance that no gain within bounds can reject
    /// (|s| never reaches the dead zone), ρ̂ grows but stays within ρ_max.
    #[test]
    fn rho_hat_bounded_under_persistent_disturbance() {
        let p = adaptive();
        let mut st = SlidingState {
            rho_hat: [0.1; 2],
            ..Default::default()
        };
        for _ in 0..1_000_000 {
            // s pinned far from zero (persistent, unrejected disturbance)
            p.advance(&mut st, [0.0, 0.0], [3.0, -3.0], false, 1e-3);
        }
        let Switching::Adaptive(a) = p.switching else {
            unreachable!()
        };
        for r in st.rho_hat {
            assert!(r <= a.rho_max && r >= a.rho_min);
            assert!(r > 1.0, "ρ̂ should have adapted upwards, got {r}");
        }
    }

    /// Inside the dead zone ρ̂ leaks back to ρ0 at rate σ (analytic exponential).
    #[test]
    fn rho_hat_leaks_to_rho0_in_dead_zone() {
        let p = adaptive();
        let mut st = SlidingState {
            rho_hat: [2.0; 2],
            ..Default::default()
        };
        let dt = 1e-3;
        for _ in 0..100_000 {
            p.advance(&mut st, [0.0; 2], [0.005, 0.0], false, dt);
        }
        // ρ̂(t) = ρ0 + (2 − ρ0)·e^(−σ t), t = 100 s, σ = 0.01.
        let expected = 0.1 + 1.9 * libm::expf(-1.0);
        assert!(
            (st.rho_hat[0] - expected).abs() < 1e-2,
            "{} vs {expected}",
            st.rho_hat[0]
        );
    }

    #[test]
    fn frozen_while_saturated() {
        let p = adaptive();
        let mut st = SlidingState {
            rho_hat: [0.5; 2],
            integral: [0.1, 0.2],
        };
        let before = st;
        p.advance(&mut st, [1.0, 1.0], [5.0, 5.0], true, 1e-3);
        assert_eq!(st, before);
    }

    #[test]
    fn validation() {
        let bad = SlidingParams {
            k_s: 0.0,
            switching: Switching::Fixed(1.0),
        };
        assert_eq!(bad.validate(), Err(ConfigError::NonPositiveGain));
        let bad = SlidingParams {
            k_s: 1.0,
            switching: Switching::Adaptive(AdaptiveGain {
                rho_max: 0.01,
                ..Default::default()
            }),
        };
        assert_eq!(bad.validate(), Err(ConfigError::InvalidAdaptation));
    }
}
