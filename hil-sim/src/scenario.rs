//! Scenarios: every knob of a run, the paper's Case 1 and Case 2 presets.
//!
//! Perturbations act inside the window `[window_s[0], window_s[1])` only
//! (paper: 10-35 s):
//!
//! * lateral skid δ_sl = skid_scale·(2 + 0.8 sin t) \[m/s\] (paper: skid_scale = 1,
//!   which no nonholonomic robot can track; default 0.05: D16),
//! * wheel slip ϖ_R = β sin t, ϖ_L = β cos t \[rad/s\], β ∈ (0, 0.2),
//! * external disturbance τ_d (not given by the paper: D17), amplitude A \[N·m\]:
//!   τ_θ = 0.5A·sin(0.9t), τ_dR = A(0.6 + 0.4 sin 2t), τ_dL = A(−0.3 + 0.5 cos 1.7t),
//! * actuator fault (Case 2): the body moves at (1 − ε)·η, ε ∈ (0.125, 0.25).

use crate::plant::Perturbation;
use crate::rng::Rng;
use serde::{Deserialize, Serialize};

/// Which reference trajectory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum TrajectoryKind {
    /// The paper's curve with the smooth signed-v_s heading (default).
    #[default]
    Paper,
    /// The paper's curve with the tangent heading (U-turn at cusps).
    PaperTangent,
    /// The paper's curve with the printed θ_d = 0.2t heading.
    PaperPrinted,
    /// Circle, radius 2 m at 0.5 m/s.
    Circle,
    /// Figure-eight, half-width 3 m, w = 0.2 rad/s.
    Figure8,
    /// Straight line along +x at 0.5 m/s from the origin.
    Line,
}

impl TrajectoryKind {
    /// The controller-core reference for this kind.
    pub fn reference(self) -> controller_core::trajectory::Reference {
        use controller_core::trajectory::*;
        match self {
            Self::Paper => Reference::Paper(PaperCurve::paper(PaperHeading::SignedSmooth)),
            Self::PaperTangent => Reference::Paper(PaperCurve::paper(PaperHeading::Tangent)),
            Self::PaperPrinted => Reference::Paper(PaperCurve::paper(PaperHeading::Printed)),
            Self::Circle => Reference::Circle(Circle {
                radius_m: 2.0,
                speed_mps: 0.5,
            }),
            Self::Figure8 => Reference::FigureEight(FigureEight {
                amplitude_m: 3.0,
                w_radps: 0.2,
            }),
            Self::Line => Reference::Line(Line {
                start: controller_core::Pose::new(0.0, 0.0, 0.0),
                speed_mps: 0.5,
            }),
        }
    }
}

/// A complete description of one simulated run (except the controller kind).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Scenario {
    /// Name shown in tables and plots.
    pub name: String,
    /// Run length \[s\].
    pub duration_s: f64,
    /// Controller period \[s\].
    pub control_period_s: f64,
    /// RK4 sub-steps per control period.
    pub substeps: u32,
    /// Perturbation window \[start, end) \[s\].
    pub window_s: [f64; 2],
    /// Initial pose of G \[x m, y m, θ rad\].
    pub initial_pose: [f64; 3],
    /// Reference trajectory.
    pub trajectory: TrajectoryKind,
    /// Wheel slip amplitude β \[rad/s\].
    pub beta: f64,
    /// Actuator fault ε (0 = none).
    pub eps: f64,
    /// Scale of the lateral skid δ_sl (1 = as printed).
    pub skid_scale: f64,
    /// Disturbance amplitude A \[N·m\].
    pub disturbance_nm: f64,
    /// Plant mass / controller model mass.
    pub mass_scale: f64,
    /// Plant inertia / controller model inertia.
    pub inertia_scale: f64,
    /// Per-wheel torque limit \[N·m\] (controller saturation and actuator limit).
    pub torque_limit_nm: f64,
    /// Encoder counts per wheel revolution (0 = ideal, unquantised).
    pub encoder_cpr: u32,
    /// PWM levels per polarity over the torque limit (0 = ideal).
    pub pwm_levels: u32,
    /// Std. dev. of the position measurement noise \[m\].
    pub pose_noise_m: f64,
    /// Std. dev. of the heading measurement noise \[rad\].
    pub heading_noise_rad: f64,
    /// Seed for the measurement noise (and for β, ε in the presets).
    pub seed: u64,
    /// Override of the kinematic gain k_y (None = controller default).
    pub k_y: Option<f64>,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            name: "custom".into(),
            duration_s: 40.0,
            control_period_s: 1e-3,
            substeps: 2,
            window_s: [10.0, 35.0],
            initial_pose: [2.5, 0.0, 0.0],
            trajectory: TrajectoryKind::Paper,
            beta: 0.1,
            eps: 0.0,
            skid_scale: 0.05,
            disturbance_nm: 1.0,
            mass_scale: 1.0,
            inertia_scale: 1.0,
            torque_limit_nm: controller_core::controller::DEFAULT_TORQUE_LIMIT_NM as f64,
            encoder_cpr: 0,
            pwm_levels: 0,
            pose_noise_m: 0.0,
            heading_noise_rad: 0.0,
            seed: 1,
            k_y: None,
        }
    }
}

/// β range of the paper, (0, 0.2) rad/s.
pub const BETA_RANGE: (f64, f64) = (0.0, 0.2);
/// ε range of the paper, (0.125, 0.25).
pub const EPS_RANGE: (f64, f64) = (0.125, 0.25);

impl Scenario {
    /// The paper's Case 1 (disturbance + slip) or Case 2 (+ actuator fault),
    /// with β and ε drawn from `seed` unless given.
    pub fn paper_case(case: u8, seed: u64, beta: Option<f64>, eps: Option<f64>) -> Self {
        let mut rng = Rng::new(seed);
        let b = rng.uniform_open(BETA_RANGE.0, BETA_RANGE.1);
        let e = rng.uniform_open(EPS_RANGE.0, EPS_RANGE.1);
        Self {
            name: format!("case{case}"),
            beta: beta.unwrap_or(b),
            eps: if case >= 2 { eps.unwrap_or(e) } else { 0.0 },
            seed,
            ..Self::default()
        }
    }

    /// Checks the knobs; a clear message for the first bad one.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |x: f64| x.is_finite() && x > 0.0;
        let nonneg = |x: f64| x.is_finite() && x >= 0.0;
        let checks: [(bool, &str); 12] = [
            (pos(self.duration_s), "duration_s must be > 0"),
            (
                pos(self.control_period_s) && self.control_period_s <= 0.1,
                "control_period_s must be in (0, 0.1]",
            ),
            (self.substeps >= 1, "substeps must be >= 1"),
            (
                self.window_s.iter().all(|x| x.is_finite()) && self.window_s[0] <= self.window_s[1],
                "window_s must be finite, start <= end",
            ),
            (
                self.initial_pose.iter().all(|x| x.is_finite()),
                "initial_pose must be finite",
            ),
            (nonneg(self.beta), "beta must be >= 0"),
            (nonneg(self.eps) && self.eps < 1.0, "eps must be in [0, 1)"),
            (
                nonneg(self.skid_scale) && nonneg(self.disturbance_nm),
                "skid_scale and disturbance_nm must be >= 0",
            ),
            (
                pos(self.mass_scale) && pos(self.inertia_scale),
                "mass_scale and inertia_scale must be > 0",
            ),
            (pos(self.torque_limit_nm), "torque_limit_nm must be > 0"),
            (
                nonneg(self.pose_noise_m) && nonneg(self.heading_noise_rad),
                "noise must be >= 0",
            ),
            (self.k_y.is_none_or(pos), "k_y must be > 0"),
        ];
        match checks.iter().find(|(ok, _)| !ok) {
            Some((_, msg)) => Err(format!("scenario '{}': {msg}", self.name)),
            None => Ok(()),
        }
    }

    /// True inside the perturbation window.
    pub fn in_window(&self, t_s: f64) -> bool {
        t_s >= self.window_s[0] && t_s < self.window_s[1]
    }

    /// Perturbations at time t (zero outside the window).
    pub fn perturbation(&self, t: f64) -> Perturbation {
        if !self.in_window(t) {
            return Perturbation::default();
        }
        let (s, c) = t.sin_cos();
        let a = self.disturbance_nm;
        Perturbation {
            skid_mps: self.skid_scale * (2.0 + 0.8 * s),
            skid_rate_mps2: self.skid_scale * 0.8 * c,
            wheel_slip_radps: [self.beta * s, self.beta * c],
            wheel_slip_rate_radps2: [self.beta * c, -self.beta * s],
            tau_d: [
                0.0,
                0.0,
                0.5 * a * (0.9 * t).sin(),
                a * (0.6 + 0.4 * (2.0 * t).sin()),
                a * (-0.3 + 0.5 * (1.7 * t).cos()),
            ],
            fault_eps: self.eps,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_draw_in_paper_ranges_and_are_seeded() {
        for seed in 0..200 {
            let c2 = Scenario::paper_case(2, seed, None, None);
            assert!(c2.beta > 0.0 && c2.beta < 0.2);
            assert!(c2.eps > 0.125 && c2.eps < 0.25);
            assert_eq!(c2, Scenario::paper_case(2, seed, None, None));
            let c1 = Scenario::paper_case(1, seed, None, None);
            assert_eq!(c1.eps, 0.0);
            assert_eq!(c1.beta, c2.beta);
            c2.validate().unwrap();
        }
    }

    #[test]
    fn perturbations_only_inside_window() {
        let s = Scenario::paper_case(2, 3, None, None);
        assert_eq!(s.perturbation(9.999), Perturbation::default());
        assert_eq!(s.perturbation(35.0), Perturbation::default());
        assert!(s.perturbation(10.0).fault_eps > 0.0);
    }

    #[test]
    fn bad_scenarios_rejected() {
        let s = Scenario {
            eps: 1.5,
            ..Scenario::default()
        };
        assert!(s.validate().unwrap_err().contains("eps"));
        let s = Scenario {
            torque_limit_nm: f64::NAN,
            ..Scenario::default()
        };
        assert!(s.validate().unwrap_err().contains("torque"));
    }
}
