//! Actuator-fault observer, eq. (13).
//!
//! The printed observer is ż = −L(e)\[g2(z + p(e)) + f(e) + g1(e)u\],
//! F̂ = z + p(e), with p, L = ∂p/∂e left open. We choose (D5)
//!
//! p(e) = \[l_v·e_x, l_ω·e_θ\],  L = \[\[l_v, 0, 0\], \[0, 0, l_ω\]\],
//!
//! so that, for a constant fault, dF̂/dt = L·g2(e)·(F − F̂) with
//! L·g2 = \[\[l_v, −l_v·e_y\], \[0, l_ω\]\]: upper triangular with eigenvalues
//! l_v, l_ω > 0 for every e, and F̂ → F exponentially.
//!
//! Implementation: F̂ itself is the state (F̂ = z + p(e) ⇒ ΔF̂ = ż·Δt + L·Δe),
//! which makes the wrap of e_θ at ±π harmless (Δe_θ is wrapped).
//! With this L only rows 1 and 3 of the bracket are needed:
//!
//! * ż_v = −l_v·(F̂_v − e_y F̂_ω + ω_s e_y − u_1 − e_y u_2)
//! * ż_ω = −l_ω·(F̂_ω + u_2)
//!
//! with u = \[v − v_s cos e_θ, ω_s − ω\] (eq. 12, g1 row 1 sign corrected: D6).

use crate::error::ConfigError;
use crate::math::{all_non_negative, all_positive};
use crate::math::{clamp_abs, wrap_angle};
use crate::tracking::TrackingError;

/// Observer gains and bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultObserverGains {
    /// l_v \[1/s\]: convergence rate of Δv̂.
    pub l_v: f32,
    /// l_ω \[1/s\]: convergence rate of Δω̂.
    pub l_omega: f32,
    /// Bound on |F̂| \[m/s, rad/s\]: the estimate is clamped to it; 0
    /// switches the observer's correction off (F̂ ≡ 0, issue 34).
    pub max_estimate: [f32; 2],
}

impl FaultObserverGains {
    /// The defaults (also [`Default::default`]); a constant so that
    /// configurations built from it are data, not code.
    pub const DEFAULT: Self = Self {
        l_v: 5.0,
        l_omega: 5.0,
        max_estimate: [1.5, 2.0],
    };
}

impl Default for FaultObserverGains {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl FaultObserverGains {
    /// Validates the gains.
    pub fn validate(self) -> Result<Self, ConfigError> {
        let [m0, m1] = self.max_estimate;
        if all_positive(&[self.l_v, self.l_omega]) && all_non_negative(&[m0, m1]) {
            Ok(self)
        } else {
            Err(ConfigError::NonPositiveGain)
        }
    }
}

/// Observer state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultObserverState {
    /// F̂ = \[Δv̂ \[m/s\], Δω̂ \[rad/s\]\].
    pub f_hat: [f32; 2],
    /// Tracking error at the previous update (with its cos e_θ, reused).
    pub e_prev: TrackingError,
    /// False until the first update has stored `e_prev`.
    pub primed: bool,
}

impl FaultObserverGains {
    /// One observer step over `dt_s`, from the previous error to `te`, with the
    /// measured wheel-derived η held over the step and the reference v_s, ω_s.
    /// Returns the new F̂.
    #[inline(always)]
    pub fn update(
        &self,
        st: &mut FaultObserverState,
        te: &TrackingError,
        eta: [f32; 2],
        v_s: f32,
        omega_s: f32,
        dt_s: f32,
    ) -> [f32; 2] {
        if !st.primed {
            st.e_prev = *te;
            st.primed = true;
            return st.f_hat;
        }
        let (e, ep) = (te.e, st.e_prev.e);
        let f = st.f_hat;
        // u from eq. (12), evaluated at the start of the step.
        let u1 = eta[0] - v_s * st.e_prev.cos_eth;
        let u2 = omega_s - eta[1];
        // ż (eq. 13) with the chosen L.
        let zv = -self.l_v * (f[0] - ep[1] * f[1] + omega_s * ep[1] - u1 - ep[1] * u2);
        let zw = -self.l_omega * (f[1] + u2);
        // ΔF̂ = ż·Δt + L·Δe.
        let dex = e[0] - ep[0];
        let deth = wrap_angle(e[2] - ep[2]);
        st.f_hat = [
            clamp_abs(f[0] + zv * dt_s + self.l_v * dex, self.max_estimate[0]),
            clamp_abs(f[1] + zw * dt_s + self.l_omega * deth, self.max_estimate[1]),
        ];
        st.e_prev = *te;
        st.f_hat
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::sin_cos;
    use crate::tracking::error_rate;

    /// Integrates the error dynamics (11) with a constant fault F and an
    /// arbitrary (non-stabilising) input: F̂ must converge to F at the rate
    /// set by l_v, l_ω regardless of the trajectory of e.
    #[test]
    fn converges_to_constant_fault_in_error_dynamics() {
        let g = FaultObserverGains {
            l_v: 5.0,
            l_omega: 5.0,
            max_estimate: [2.0, 2.0],
        };
        let mut st = FaultObserverState::default();
        let fault = [0.15f32, -0.08f32];
        let mut e = [0.4f32, -0.3, 0.2];
        let dt = 1e-3f32;
        let mut worst_after_1s = 0.0f32;
        for k in 0..3000 {
            let t = k as f32 * dt;
            let (s, c) = sin_cos(0.7 * t);
            let eta = [0.6 + 0.2 * s, 0.3 * c];
            let (vs, ws) = (0.5 + 0.1 * c, 0.2);
            g.update(&mut st, &e.into(), eta, vs, ws, dt);
            // d = 0: eq. (11) as the observer models it.
            let de = error_rate(&e.into(), eta, fault, vs, ws, 0.0);
            for i in 0..3 {
                e[i] += de[i] * dt;
            }
            if t > 1.0 {
                let err = (st.f_hat[0] - fault[0])
                    .abs()
                    .max((st.f_hat[1] - fault[1]).abs());
                worst_after_1s = worst_after_1s.max(err);
            }
        }
        // Rate 5/s: after 1 s the error is below e^-5 ≈ 0.7 % of the initial 0.15.
        assert!(worst_after_1s < 0.01, "worst {worst_after_1s}");
        assert!((st.f_hat[0] - fault[0]).abs() < 1e-3 && (st.f_hat[1] - fault[1]).abs() < 1e-3);
    }

    #[test]
    fn zero_fault_stays_zero() {
        let g = FaultObserverGains::default();
        let mut st = FaultObserverState::default();
        let mut e = [0.2f32, 0.1, -0.1];
        let dt = 1e-3;
        for _ in 0..2000 {
            let eta = [0.5, 0.1];
            g.update(&mut st, &e.into(), eta, 0.4, 0.0, dt);
            let de = error_rate(&e.into(), eta, [0.0, 0.0], 0.4, 0.0, 0.0);
            for i in 0..3 {
                e[i] += de[i] * dt;
            }
        }
        assert!(
            st.f_hat[0].abs() < 2e-3 && st.f_hat[1].abs() < 2e-3,
            "{:?}",
            st.f_hat
        );
    }

    #[test]
    fn rejects_bad_gains() {
        let g = FaultObserverGains {
            l_v: 0.0,
            ..Default::default()
        };
        assert_eq!(g.validate(), Err(ConfigError::NonPositiveGain));
        let off = FaultObserverGains {
            max_estimate: [0.0, 0.0],
            ..Default::default()
        };
        assert!(off.validate().is_ok());
        let g = FaultObserverGains {
            max_estimate: [0.0, f32::NAN],
            ..Default::default()
        };
        assert_eq!(g.validate(), Err(ConfigError::NonPositiveGain));
    }
}
