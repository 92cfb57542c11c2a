//! The perturbations of the paper's section 4 as functions of time.
//!
//! Inside the window `[window_s[0], window_s[1])` only (paper: 10-35 s):
//!
//! * lateral skid δ_sl = skid_scale·(2 + 0.8 sin t) \[m/s\] (paper: skid_scale = 1,
//!   which no nonholonomic robot can track; the simulator's default is 0.05: D16),
//! * wheel slip ϖ_R = β sin t, ϖ_L = β cos t \[rad/s\], β ∈ (0, 0.2),
//! * external disturbance τ_d (not given by the paper: D17), amplitude A \[N·m\]:
//!   τ_θ = 0.5A·sin(0.9t), τ_dR = A(0.6 + 0.4 sin 2t), τ_dL = A(−0.3 + 0.5 cos 1.7t),
//! * actuator fault (Case 2): the body moves at (1 − ε)·η; beyond the paper,
//!   ε may ramp linearly from `fault_eps` at the window's start to
//!   `fault_eps_end` at its end (a growing fault).

use crate::math::{round, sin_cos};
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
    /// ε at the window's end, ramped linearly from `fault_eps` at its start
    /// (None = constant `fault_eps`, the paper's setting).
    pub fault_eps_end: Option<f64>,
}

impl PerturbationProfile {
    /// No perturbation at all.
    pub const NONE: Self = Self {
        window_s: [0.0, 0.0],
        beta_radps: 0.0,
        fault_eps: 0.0,
        skid_scale: 0.0,
        disturbance_nm: 0.0,
        fault_eps_end: None,
    };

    /// ε at `t_s` inside the window: `fault_eps`, or the ramp to
    /// `fault_eps_end`.
    #[inline]
    pub fn fault_eps_at(&self, t_s: f64) -> f64 {
        match self.fault_eps_end {
            None => self.fault_eps,
            Some(end) => {
                let [w0, w1] = self.window_s;
                let u = if w1 > w0 { (t_s - w0) / (w1 - w0) } else { 0.0 };
                self.fault_eps + (end - self.fault_eps) * u.clamp(0.0, 1.0)
            }
        }
    }

    /// True inside the window.
    #[inline]
    pub fn in_window(&self, t_s: f64) -> bool {
        t_s >= self.window_s[0] && t_s < self.window_s[1]
    }

    /// Perturbations at time `t_s` (zero outside the window).
    #[inline]
    pub fn at(&self, t_s: f64) -> Perturbation {
        if !self.in_window(t_s) {
            return Perturbation::default();
        }
        let mut p = self.at_phasors(FREQUENCIES_RADPS.map(|w| sin_cos(w * t_s)));
        p.fault_eps = self.fault_eps_at(t_s);
        p
    }

    /// The perturbations from (sin, cos) of t, 0.9t and 1.7t (in the window).
    #[inline]
    fn at_phasors(&self, [(s, c), (s09, _), (_, c17)]: [(f64, f64); 3]) -> Perturbation {
        let sin_2t = 2.0 * s * c;
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
                0.5 * a * s09,
                a * (0.6 + 0.4 * sin_2t),
                a * (-0.3 + 0.5 * c17),
            ],
            fault_eps: self.fault_eps,
        }
    }
}

/// Evaluates a [`PerturbationProfile`] along a run whose queries fall on a
/// regular grid t = k·`step_s` (an RK4 integrator at its half steps):
/// sin/cos of the profile's three frequencies advance from one grid point
/// to the next by a fixed rotation instead of new sin/cos calls. Exact to
/// rounding: the phasors are recomputed from sin/cos every
/// [`Self::RESYNC_STEPS`] points and whenever a query leaves the grid
/// sequence, and the last query is remembered (a repeated time returns the
/// same value).
#[derive(Clone, Copy, Debug)]
pub struct PerturbationGrid {
    profile: PerturbationProfile,
    step_s: f64,
    /// Rotation by one grid step for the frequencies 1, 0.9 and 1.7 rad/s.
    rotation: [(f64, f64); 3],
    /// Grid index and (sin, cos) at it of the last query inside the window.
    phasor: Option<(i64, [(f64, f64); 3])>,
    /// Since the last resync.
    rotations: u32,
    /// The last query and its answer.
    last: Option<(f64, Perturbation)>,
}

/// The profile's angular frequencies \[rad/s\]: slip and skid (1), τ_θ (0.9), τ_dL (1.7).
const FREQUENCIES_RADPS: [f64; 3] = [1.0, 0.9, 1.7];

impl PerturbationGrid {
    /// Grid points between exact recomputations of the phasors (bounds the
    /// rounding drift of repeated rotation to ~10⁻¹³).
    pub const RESYNC_STEPS: u32 = 1000;

    /// An evaluator of `profile` for queries on the grid k·`step_s` (> 0).
    pub fn new(profile: PerturbationProfile, step_s: f64) -> Self {
        Self {
            profile,
            step_s,
            rotation: FREQUENCIES_RADPS.map(|w| sin_cos(w * step_s)),
            phasor: None,
            rotations: 0,
            last: None,
        }
    }

    /// The perturbations at `t_s`; equal to [`PerturbationProfile::at`]
    /// to rounding.
    #[inline]
    pub fn at(&mut self, t_s: f64) -> Perturbation {
        if let Some((t, p)) = self.last {
            // The same time, or the same instant reached by another sum
            // (k·Δt + Δt and (k + 1)·Δt differ in the last bits; 10⁻¹² s per
            // second of run time is some 4,500 ulps, the signals move by
            // less than 10⁻¹¹ in that time): the same value.
            if t.to_bits() == t_s.to_bits() || (t - t_s).abs() <= 1e-12 * t_s.abs().max(1.0) {
                return p;
            }
        }
        let p = if self.profile.in_window(t_s) {
            let ph = self.phasors(t_s);
            let mut p = self.profile.at_phasors(ph);
            p.fault_eps = self.profile.fault_eps_at(t_s);
            p
        } else {
            Perturbation::default()
        };
        self.last = Some((t_s, p));
        p
    }

    #[inline]
    fn phasors(&mut self, t_s: f64) -> [(f64, f64); 3] {
        let tol = 1e-9 * self.step_s.max(1.0);
        // The usual query: the grid point after the last one (no division,
        // no rounding; the same test as below with k = k_prev + 1).
        if let Some((k_prev, ph)) = self.phasor {
            let k = k_prev + 1;
            if self.rotations < Self::RESYNC_STEPS && (t_s - k as f64 * self.step_s).abs() <= tol {
                let next = core::array::from_fn(|i| {
                    let (s, c) = ph[i];
                    let (sr, cr) = self.rotation[i];
                    (s * cr + c * sr, c * cr - s * sr)
                });
                self.phasor = Some((k, next));
                self.rotations += 1;
                return next;
            }
        }
        let k = round(t_s / self.step_s);
        let on_grid = (t_s - k * self.step_s).abs() <= tol;
        let k = k as i64;
        let exact = FREQUENCIES_RADPS.map(|w| sin_cos(w * t_s));
        self.phasor = on_grid.then_some((k, exact));
        self.rotations = 0;
        exact
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Case-style profile: the fault ε = 0.2 and the 1 N·m disturbance over
    /// `window_s`, with the slip frequency and skid scale given.
    fn case_profile(window_s: [f64; 2], beta_radps: f64, skid_scale: f64) -> PerturbationProfile {
        PerturbationProfile {
            window_s,
            beta_radps,
            fault_eps: 0.2,
            skid_scale,
            disturbance_nm: 1.0,
            fault_eps_end: None,
        }
    }

    /// The printed rates are the time derivatives of the printed signals
    /// (central differences).
    #[test]
    fn rates_are_derivatives_of_the_signals() {
        let p = case_profile([0.0, 100.0], 0.15, 0.5);
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

    /// Along an RK4 half-step grid over a whole window (more than one
    /// resync), the rotated phasors equal direct evaluation to rounding;
    /// off-grid and repeated queries too.
    #[test]
    fn grid_equals_direct_evaluation() {
        let p = case_profile([1.0, 30.0], 0.15, 0.05);
        let h = 1e-3;
        let mut g = PerturbationGrid::new(p, 0.5 * h);
        let close = |a: &Perturbation, b: &Perturbation| {
            let fields = |x: &Perturbation| {
                let mut v = [0.0; 10];
                v[0] = x.skid_mps;
                v[1] = x.skid_rate_mps2;
                v[2..4].copy_from_slice(&x.wheel_slip_radps);
                v[4..6].copy_from_slice(&x.wheel_slip_rate_radps2);
                v[6..9].copy_from_slice(&x.tau_d[2..5]);
                v[9] = x.fault_eps;
                v
            };
            let (u, w) = (fields(a), fields(b));
            (0..10).all(|i| (u[i] - w[i]).abs() < 1e-12)
        };
        for k in 0..32_000u32 {
            let t = k as f64 * h;
            for tq in [t, t + 0.5 * h, t + h, t + h] {
                assert!(close(&g.at(tq), &p.at(tq)), "t = {tq}");
            }
            if k % 997 == 0 {
                let off = t + 0.123e-3;
                assert!(close(&g.at(off), &p.at(off)), "off grid {off}");
            }
        }
    }

    /// The loop asks at (k + 1)·h the instant the last RK4 step asked at
    /// k·h + h; where the two sums differ in their last bits it is still one
    /// instant: the same value, no recomputation (D57; it used to recompute
    /// the three phasors with sin/cos there).
    #[test]
    fn same_instant_by_another_sum_is_one_query() {
        let p = case_profile([0.0, 100.0], 0.15, 0.05);
        let h = 1e-3;
        let mut g = PerturbationGrid::new(p, 0.5 * h);
        let mut other_sum = 0;
        for k in 0..5000 {
            let t = k as f64 * h;
            g.at(t);
            g.at(t + 0.5 * h);
            let end = g.at(t + h);
            let next_t = (k + 1) as f64 * h;
            let next = g.at(next_t);
            if (t + h).to_bits() != next_t.to_bits() {
                other_sum += 1;
                assert_eq!(end, next, "k = {k}");
            }
        }
        assert!(other_sum > 100, "{other_sum}");
    }

    #[test]
    fn nothing_outside_the_window() {
        let p = case_profile([10.0, 35.0], 0.1, 0.05);
        assert_eq!(p.at(9.999), Perturbation::default());
        assert_eq!(p.at(35.0), Perturbation::default());
        assert_eq!(p.at(10.0).fault_eps, 0.2);
    }

    /// The ramp: ε = fault_eps at the window's start, fault_eps_end at its
    /// end, linear between (the grid evaluator agrees), none outside.
    #[test]
    fn fault_ramp_is_linear_over_the_window() {
        let p = PerturbationProfile {
            window_s: [10.0, 35.0],
            fault_eps: 0.0,
            fault_eps_end: Some(0.6),
            ..PerturbationProfile::NONE
        };
        assert_eq!(p.at(10.0).fault_eps, 0.0);
        assert!((p.at(22.5).fault_eps - 0.3).abs() < 1e-12);
        assert!((p.at(34.999).fault_eps - 0.6).abs() < 1e-4);
        assert_eq!(p.at(35.0).fault_eps, 0.0);
        let mut g = PerturbationGrid::new(p, 5e-4);
        for k in 0..80_000 {
            let t = k as f64 * 5e-4;
            assert_eq!(g.at(t).fault_eps, p.at(t).fault_eps);
        }
    }
}
