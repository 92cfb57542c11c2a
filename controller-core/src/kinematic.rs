//! Kinematic backstepping law, eq. (14), its Lyapunov function (15) and the
//! analytic derivative η̇_c the dynamic loop needs.

use crate::error::ConfigError;
use crate::math::{all_non_negative, all_positive};
use crate::tracking::TrackingError;

/// Gains of eq. (14) (paper Table 2: k_x = 1.2, k_y = 250, k_th = 5).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct KinematicGains {
    /// k_x \[1/s\].
    pub k_x: f32,
    /// k_y \[rad/m²\].
    pub k_y: f32,
    /// k_th \[1/s\].
    pub k_th: f32,
    /// Include the printed `2·e_y·Δω̂` term in v_c. Off by default: the
    /// derivation of (16) does not need it and it makes V̇_K sign-indefinite (D7).
    pub printed_2ey_term: bool,
    /// Length L \[m\] of the large-error bound of the lateral term (D23):
    /// k_y·v_s·e_y becomes k_y·g·v_s·e_y with g = 1/(1 + (e_x² + e_y²)/L²),
    /// which is eq. (14) for |e| ≪ L, bounded by k_y·|v_s|·L/2 for any
    /// error, and keeps V̇ ≤ 0 for V = (L²/2)·ln(1 + |e|²/L²) + (1 − cos e_θ)/k_y.
    /// 0 = off: eq. (14) as printed (the paper's setting).
    pub large_error_m: f32,
}

/// Default L of [`KinematicGains::large_error_m`] when the bound is on \[m\] (D23).
pub const DEFAULT_LARGE_ERROR_M: f32 = 1.0;

impl KinematicGains {
    /// Table 2 values with k_y as printed (250).
    pub const fn paper() -> Self {
        Self {
            k_x: 1.2,
            k_y: 250.0,
            k_th: 5.0,
            printed_2ey_term: false,
            large_error_m: 0.0,
        }
    }

    /// These gains with the large-error bound of length `l_m` (0 = off).
    pub const fn with_large_error_bound(self, l_m: f32) -> Self {
        Self {
            large_error_m: l_m,
            ..self
        }
    }

    /// g = 1/(1 + (e_x² + e_y²)/L²) and 1/L² (g = 1 when the bound is off).
    #[inline]
    fn lateral_weight(&self, e: [f32; 3]) -> (f32, f32) {
        if self.large_error_m > 0.0 {
            let inv_l2 = 1.0 / (self.large_error_m * self.large_error_m);
            (1.0 / (1.0 + (e[0] * e[0] + e[1] * e[1]) * inv_l2), inv_l2)
        } else {
            (1.0, 0.0)
        }
    }

    /// Validates the gains.
    pub fn validate(self) -> Result<Self, ConfigError> {
        if all_positive(&[self.k_x, self.k_y, self.k_th]) && all_non_negative(&[self.large_error_m])
        {
            Ok(self)
        } else {
            Err(ConfigError::NonPositiveGain)
        }
    }

    /// η_c = \[v_c, ω_c\] of eq. (14):
    /// v_c = v_s cos e_θ + k_x e_x + Δv̂ (+ 2e_yΔω̂ if enabled),
    /// ω_c = ω_s + k_y v_s e_y + k_th sin e_θ + Δω̂.
    #[inline]
    pub fn eta_c(&self, te: &TrackingError, v_s: f32, omega_s: f32, f_hat: [f32; 2]) -> [f32; 2] {
        let (e, se, ce) = (te.e, te.sin_eth, te.cos_eth);
        let mut v = v_s * ce + self.k_x * e[0] + f_hat[0];
        if self.printed_2ey_term {
            v += 2.0 * e[1] * f_hat[1];
        }
        if self.large_error_m > 0.0 {
            let (g, _) = self.lateral_weight(e);
            return [
                v,
                omega_s + self.k_y * g * v_s * e[1] + self.k_th * se + f_hat[1],
            ];
        }
        [
            v,
            omega_s + self.k_y * v_s * e[1] + self.k_th * se + f_hat[1],
        ]
    }

    /// dη_c/dt by the chain rule, given ė (eq. 11 with the measured η and F̂),
    /// v̇_s, ω̇_s, treating F̂ as constant over the step (D9).
    #[inline]
    pub fn eta_c_dot(
        &self,
        te: &TrackingError,
        e_dot: [f32; 3],
        v_s: f32,
        v_s_dot: f32,
        omega_s_dot: f32,
        f_hat: [f32; 2],
    ) -> [f32; 2] {
        let (e, se, ce) = (te.e, te.sin_eth, te.cos_eth);
        let mut vd = v_s_dot * ce - v_s * se * e_dot[2] + self.k_x * e_dot[0];
        if self.printed_2ey_term {
            vd += 2.0 * e_dot[1] * f_hat[1];
        }
        if self.large_error_m > 0.0 {
            // d/dt (g·v_s·e_y), ġ = −2g²(e_x ė_x + e_y ė_y)/L².
            let (g, inv_l2) = self.lateral_weight(e);
            let g_dot = -2.0 * g * g * (e[0] * e_dot[0] + e[1] * e_dot[1]) * inv_l2;
            let lat = g_dot * v_s * e[1] + g * (v_s_dot * e[1] + v_s * e_dot[1]);
            let wd = omega_s_dot + self.k_y * lat + self.k_th * ce * e_dot[2];
            return [vd, wd];
        }
        let wd =
            omega_s_dot + self.k_y * (v_s_dot * e[1] + v_s * e_dot[1]) + self.k_th * ce * e_dot[2];
        [vd, wd]
    }

    /// V_K = (1 − cos e_θ)/k_y + (e_x² + e_y²)/2, eq. (15).
    #[inline]
    pub fn lyapunov(&self, te: &TrackingError) -> f32 {
        let e = te.e;
        (1.0 - te.cos_eth) / self.k_y + 0.5 * (e[0] * e[0] + e[1] * e[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::error_rate;

    /// Integrates the closed kinematic loop (η = η_c exactly, d = 0, the
    /// constant fault `fault` with a perfect estimate) from `e0` for `steps`
    /// Euler steps of 0.1 ms under the reference speeds `reference(t)` =
    /// (v_s, ω_s), calls `check(te, η_c, (v_s, ω_s))` at every step, and asserts that `lyap` never increases
    /// (up to the step's O(dt²) error) and ends below 1e-3 of its start.
    fn assert_lyapunov_decreases(
        g: &KinematicGains,
        e0: [f32; 3],
        fault: [f32; 2],
        steps: u32,
        reference: impl Fn(f32) -> (f32, f32),
        lyap: impl Fn([f32; 3]) -> f32,
        mut check: impl FnMut(&TrackingError, [f32; 2], (f32, f32)),
    ) {
        let what = format!("k_y {}, v_s(0) {}", g.k_y, reference(0.0).0);
        let mut e = e0;
        let dt = 1e-4f32;
        let mut v_prev = lyap(e);
        let v0 = v_prev;
        for k in 0..steps {
            let t = k as f32 * dt;
            let (vs, ws) = reference(t);
            let te = TrackingError::from(e);
            let eta = g.eta_c(&te, vs, ws, fault);
            check(&te, eta, (vs, ws));
            let de = error_rate(&te, eta, fault, vs, ws, 0.0);
            for i in 0..3 {
                e[i] += de[i] * dt;
            }
            let v = lyap(e);
            assert!(v <= v_prev + 1e-6, "{what} t {t}: V rose {v_prev} -> {v}");
            v_prev = v;
        }
        assert!(v_prev < 1e-3 * v0, "{what}: V {v_prev} of {v0}");
    }

    /// Closed kinematic loop (η = η_c exactly, d = 0, constant fault with a
    /// perfect estimate): V_K of eq. (15) never increases and e → 0.
    #[test]
    fn lyapunov_decreases_in_closed_kinematic_loop() {
        for k_y in [25.0f32, 250.0] {
            let g = KinematicGains {
                k_y,
                ..KinematicGains::paper()
            };
            assert_lyapunov_decreases(
                &g,
                [1.0, -0.8, 0.6],
                [0.1, 0.05],
                100_000,
                |t| (0.5 + 0.2 * libm::sinf(0.3 * t), 0.2 * libm::cosf(0.5 * t)),
                |e| g.lyapunov(&e.into()),
                |_, _, _| {},
            );
        }
    }

    /// With the printed 2e_yΔω̂ term V_K can increase (why it is off by default).
    #[test]
    fn printed_2ey_term_breaks_monotonic_decrease() {
        let g = KinematicGains {
            printed_2ey_term: true,
            ..KinematicGains::paper()
        };
        let fault = [0.0f32, 0.5];
        let e = [-0.01f32, 1.0, 0.0]; // V̇ gains −2·e_x·e_y·Δω > 0 here
        let (vs, ws) = (0.0, 0.0);
        let te = TrackingError::from(e);
        let eta = g.eta_c(&te, vs, ws, fault);
        let de = error_rate(&te, eta, fault, vs, ws, 0.0);
        let vdot = e[0] * de[0] + e[1] * de[1] + libm::sinf(e[2]) * de[2] / g.k_y;
        assert!(vdot > 0.0, "V̇ = {vdot}");
    }

    #[test]
    fn eta_c_dot_matches_finite_difference() {
        let g = KinematicGains {
            k_y: 25.0,
            ..KinematicGains::paper()
        };
        let e = [0.3f32, -0.2, 0.4];
        let de = [0.1f32, 0.05, -0.2];
        let (vs, vsd, ws, wsd) = (0.7f32, 0.3f32, 0.2f32, -0.1f32);
        let f = [0.05f32, 0.02];
        let h = 1e-3f32;
        let step = |s: f32| {
            let ee = [e[0] + s * de[0], e[1] + s * de[1], e[2] + s * de[2]];
            g.eta_c(&ee.into(), vs + s * vsd, ws + s * wsd, f)
        };
        let (a, b) = (step(-h), step(h));
        let an = g.eta_c_dot(&e.into(), de, vs, vsd, wsd, f);
        for i in 0..2 {
            let fd = (b[i] - a[i]) / (2.0 * h);
            assert!((fd - an[i]).abs() < 1e-2, "{i}: {fd} vs {}", an[i]);
        }
    }

    /// With the large-error bound (D23), V = (L²/2)·ln(1 + |e|²/L²) +
    /// (1 − cos e_θ)/k_y never increases along the closed kinematic loop
    /// (d = 0, exact fault estimate), from a 3.35 m offset as in the paper's
    /// start, for reversing and forward references; and e → 0.
    #[test]
    fn bounded_law_lyapunov_decreases_from_large_error() {
        let g = KinematicGains {
            k_y: 25.0,
            ..KinematicGains::paper()
        }
        .with_large_error_bound(DEFAULT_LARGE_ERROR_M);
        let l2 = DEFAULT_LARGE_ERROR_M * DEFAULT_LARGE_ERROR_M;
        for sign in [1.0f32, -1.0] {
            let fault = [0.1f32, 0.05];
            assert_lyapunov_decreases(
                &g,
                [1.5, 3.0, 1.42],
                fault,
                200_000,
                |t| {
                    (
                        sign * (0.8 + 0.5 * libm::sinf(0.3 * t)),
                        0.2 * libm::cosf(0.5 * t),
                    )
                },
                |e| {
                    0.5 * l2 * libm::logf(1.0 + (e[0] * e[0] + e[1] * e[1]) / l2)
                        + (1.0 - libm::cosf(e[2])) / g.k_y
                },
                // Bounded for any error: |k_y·g·v_s·e_y| <= k_y·|v_s|·L/2.
                |te, eta, (vs, ws)| {
                    let lat = eta[1] - ws - g.k_th * te.sin_eth - fault[1];
                    assert!(lat.abs() <= g.k_y * vs.abs() * 0.5 * DEFAULT_LARGE_ERROR_M + 1e-4);
                },
            );
        }
    }

    /// The analytic η̇_c of the bounded law matches a finite difference,
    /// at a small and at a large error; with the bound off, the law is (14).
    #[test]
    fn bounded_eta_c_dot_matches_finite_difference() {
        let g = KinematicGains {
            k_y: 25.0,
            ..KinematicGains::paper()
        }
        .with_large_error_bound(DEFAULT_LARGE_ERROR_M);
        for e in [[0.3f32, -0.2, 0.4], [1.5, 3.0, 1.4]] {
            let de = [0.1f32, 0.05, -0.2];
            let (vs, vsd, ws, wsd) = (-0.7f32, 0.3f32, 0.2f32, -0.1f32);
            let f = [0.05f32, 0.02];
            let h = 1e-3f32;
            let step = |s: f32| {
                let ee = [e[0] + s * de[0], e[1] + s * de[1], e[2] + s * de[2]];
                g.eta_c(&ee.into(), vs + s * vsd, ws + s * wsd, f)
            };
            let (a, b) = (step(-h), step(h));
            let an = g.eta_c_dot(&e.into(), de, vs, vsd, wsd, f);
            for i in 0..2 {
                let fd = (b[i] - a[i]) / (2.0 * h);
                assert!((fd - an[i]).abs() < 1e-2, "{e:?} {i}: {fd} vs {}", an[i]);
            }
        }
        let off = KinematicGains::paper();
        let te = TrackingError::from([1.5f32, 3.0, 1.4]);
        assert_eq!(
            off.eta_c(&te, 0.7, 0.2, [0.0; 2]),
            off.with_large_error_bound(0.0)
                .eta_c(&te, 0.7, 0.2, [0.0; 2])
        );
    }
}
