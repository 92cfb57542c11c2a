//! The perturbations of the paper's section 4 as functions of time.
//!
//! Inside the window `[window_s[0], window_s[1])` only (paper: 10-35 s):
//!
//! * lateral skid δ_sl = skid_scale·(2 + 0.8 sin t) \[m/s\] (paper: skid_scale = 1,
//!   which no nonholonomic robot can track; the simulator's default is 0.05: D16),
//! * wheel slip ϖ_R = β sin t, ϖ_L = β cos t \[rad/s\], β ∈ (0, 0.2),
//! * external disturbance τ_d (not given by the paper: D17), amplitude A \[N·m\]:
//!   τ_θ = 0.5A·sin(0.9t), τ_dR = A(0.6 + 0.4 sin 2t), τ_dL = A(−0.3 + 0.5 cos 1.7t),
//! * actuator fault (Case 2): the body moves at (1 − ε)·η.

use crate::math::{cos, sin, sin_cos};
use crate::plant::Perturbation;

/// Amplitudes and window of the section-4 perturbations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerturbationProfile {
    /// Window \[start, end) \[s\] in which everything acts.
    pub window_s: [f64; 2],
    /// Wheel slip amplitude β \[rad/s\].
    pub beta_radps: f64,
    /// Actuator fault ε (0 = healthy).
    pub fault_eps: f64,
    /// Scale of the lateral skid δ_sl (1 = as printed).
    pub skid_scale: f64,
    /// Disturbance amplitude A \[N·m\].
    pub disturbance_nm: f64,
}

impl PerturbationProfile {
    /// No perturbation at all.
    pub const NONE: Self = Self {
        window_s: [0.0, 0.0],
        beta_radps: 0.0,
        fault_eps: 0.0,
        skid_scale: 0.0,
        disturbance_nm: 0.0,
    };

    /// True inside the window.
    pub fn in_window(&self, t_s: f64) -> bool {
        t_s >= self.window_s[0] && t_s < self.window_s[1]
    }

    /// Perturbations at time `t_s` (zero outside the window).
    pub fn at(&self, t_s: f64) -> Perturbation {
        if !self.in_window(t_s) {
            return Perturbation::default();
        }
        let t = t_s;
        let (s, c) = sin_cos(t);
        let a = self.disturbance_nm;
        let beta = self.beta_radps;
        Perturbation {
            skid_mps: self.skid_scale * (2.0 + 0.8 * s),
            skid_rate_mps2: self.skid_scale * 0.8 * c,
            wheel_slip_radps: [beta * s, beta * c],
            wheel_slip_rate_radps2: [beta * c, -beta * s],
            tau_d: [
                0.0,
                0.0,
                0.5 * a * sin(0.9 * t),
                a * (0.6 + 0.4 * sin(2.0 * t)),
                a * (-0.3 + 0.5 * cos(1.7 * t)),
            ],
            fault_eps: self.fault_eps,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The printed rates are the time derivatives of the printed signals
    /// (central differences).
    #[test]
    fn rates_are_derivatives_of_the_signals() {
        let p = PerturbationProfile {
            window_s: [0.0, 100.0],
            beta_radps: 0.15,
            fault_eps: 0.2,
            skid_scale: 0.5,
            disturbance_nm: 1.0,
        };
        let h = 1e-6;
        for i in 1..200 {
            let t = 0.37 * i as f64;
            let (a, b, m) = (p.at(t - h), p.at(t + h), p.at(t));
            let d = |x: f64, y: f64| (y - x) / (2.0 * h);
            assert!((d(a.skid_mps, b.skid_mps) - m.skid_rate_mps2).abs() < 1e-7);
            for w in 0..2 {
                let num = d(a.wheel_slip_radps[w], b.wheel_slip_radps[w]);
                assert!((num - m.wheel_slip_rate_radps2[w]).abs() < 1e-7);
            }
        }
    }

    #[test]
    fn nothing_outside_the_window() {
        let p = PerturbationProfile {
            window_s: [10.0, 35.0],
            beta_radps: 0.1,
            fault_eps: 0.2,
            skid_scale: 0.05,
            disturbance_nm: 1.0,
        };
        assert_eq!(p.at(9.999), Perturbation::default());
        assert_eq!(p.at(35.0), Perturbation::default());
        assert_eq!(p.at(10.0).fault_eps, 0.2);
    }
}
