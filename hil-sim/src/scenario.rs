//! Scenarios: every knob of a run, the paper's Case 1 and Case 2 presets.
//!
//! Perturbations act inside the window `[window_s[0], window_s[1])` only
//! (paper: 10-35 s); their formulas are in `sim_robot::perturbation` (skid
//! δ_sl, wheel slip ϖ, disturbance τ_d, actuator fault ε).
//!
//! [`Sensing`] chooses what sits between the plant and the controller: the
//! paper's ideal measurements, or the firmware's runtime behind simulated
//! encoders, an H-bridge and the preset's gyro and external pose source
//! ([`crate::sensing`], which also holds the `gyro_*`/`pose_*` overrides:
//! one struct each, flattened here so the TOML keys stay top-level).

use crate::rng::Rng;
pub use crate::sensing::Sensing;
use crate::sensing::{GyroOverrides, PoseOverrides};
use controller_core::runtime::{EncoderParams, MotorParams};
use serde::{Deserialize, Serialize};
use sim_robot::{Perturbation, PerturbationProfile};

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
#[serde(default)]
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
    /// Growing fault (beyond the paper): ε at the window's end, ramped
    /// linearly from `eps` at its start (None = constant `eps`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub eps_end: Option<f64>,
    /// Fraction of the commanded torque each wheel `[right, left]` delivers
    /// inside the window (beyond the paper; \[1, 1\] = healthy).
    #[serde(skip_serializing_if = "is_healthy_wheels")]
    pub wheel_torque_scale: [f64; 2],
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
    /// Measurements and actuation between plant and controller.
    pub sensing: Sensing,
    /// Encoder counts per wheel revolution after ×4 decoding (firmware
    /// sensing only; 0 = the example encoder's).
    pub encoder_cpr: u32,
    /// Speed-estimate window \[ticks\] (firmware sensing only; 0 = the
    /// example encoder's).
    pub speed_window_ticks: u8,
    /// PWM counts at 100 % duty (firmware sensing only; 0 = the example
    /// motor's).
    pub pwm_levels: u32,
    /// Std. dev. of the position measurement noise \[m\].
    pub pose_noise_m: f64,
    /// Std. dev. of the heading measurement noise \[rad\].
    pub heading_noise_rad: f64,
    /// Overrides of the sensing preset's gyro (keys `gyro_*`).
    #[serde(flatten)]
    pub gyro: GyroOverrides,
    /// Overrides of the sensing preset's external pose source (keys `pose_*`).
    #[serde(flatten)]
    pub pose: PoseOverrides,
    /// Seed for the measurement noise (and for β, ε in the presets).
    pub seed: u64,
    /// Override of the kinematic gain k_y (None = controller default).
    pub k_y: Option<f64>,
    /// Reference governor and health machine (`controller_core::pacer`),
    /// beyond the paper; on by default, off in [`Self::as_printed`].
    #[serde(skip_serializing_if = "is_true")]
    pub governor: bool,
    /// Large-error bound of the kinematic law's lateral term (D23), beyond
    /// the paper; on by default, off in [`Self::as_printed`].
    #[serde(skip_serializing_if = "is_true")]
    pub clean_start: bool,
    /// Keys of a scenario file that are not in the schema: a scenario with
    /// any is invalid ([`Self::validate`]), so a typo never silently falls
    /// back to a default. (serde's `deny_unknown_fields` cannot be combined
    /// with the flattened parts.)
    #[serde(flatten, skip_serializing)]
    pub unknown_keys: std::collections::BTreeMap<String, toml::Value>,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            name: "custom".into(),
            duration_s: 40.0,
            control_period_s: 1e-3,
            substeps: 1,
            window_s: [10.0, 35.0],
            initial_pose: [2.5, 0.0, 0.0],
            trajectory: TrajectoryKind::Paper,
            beta: 0.1,
            eps: 0.0,
            eps_end: None,
            wheel_torque_scale: [1.0, 1.0],
            skid_scale: 0.05,
            disturbance_nm: 1.0,
            mass_scale: 1.0,
            inertia_scale: 1.0,
            torque_limit_nm: controller_core::controller::DEFAULT_TORQUE_LIMIT_NM as f64,
            sensing: Sensing::Ideal,
            encoder_cpr: 0,
            speed_window_ticks: 0,
            pwm_levels: 0,
            pose_noise_m: 0.0,
            heading_noise_rad: 0.0,
            gyro: GyroOverrides::default(),
            pose: PoseOverrides::default(),
            seed: 1,
            k_y: None,
            governor: true,
            clean_start: true,
            unknown_keys: Default::default(),
        }
    }
}

fn is_true(b: &bool) -> bool {
    *b
}

fn is_healthy_wheels(s: &[f64; 2]) -> bool {
    *s == [1.0, 1.0]
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

    /// This scenario in the paper's setting: no governor, no health machine
    /// (what `compare`'s first table runs).
    pub fn as_printed(mut self) -> Self {
        self.governor = false;
        self.clean_start = false;
        self
    }

    /// The runtime/simulator pacing configuration for this scenario.
    pub fn pacing(&self) -> controller_core::pacer::PacingConfig {
        if self.governor {
            controller_core::pacer::PacingConfig::on()
        } else {
            controller_core::pacer::PacingConfig::off()
        }
    }

    /// Checks the knobs; a clear message for the first bad one.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |x: f64| x.is_finite() && x > 0.0;
        let nonneg = |x: f64| x.is_finite() && x >= 0.0;
        let ideal = self.sensing == Sensing::Ideal;
        let checks: [(bool, &str); 17] = [
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
                self.eps_end.is_none_or(|e| nonneg(e) && e < 1.0),
                "eps_end must be in [0, 1)",
            ),
            (
                self.wheel_torque_scale.iter().all(|&k| nonneg(k) && k <= 1.0),
                "wheel_torque_scale must be in [0, 1]",
            ),
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
            (
                !ideal || (self.encoder_cpr == 0 && self.pwm_levels == 0 && self.speed_window_ticks == 0),
                "encoder_cpr, pwm_levels and speed_window_ticks need a firmware sensing preset (ideal sensing has no encoders or PWM)",
            ),
            (
                ideal || (self.pose_noise_m == 0.0 && self.heading_noise_rad == 0.0),
                "pose_noise_m and heading_noise_rad are the noise of ideal sensing; the external pose of mocap/uwb takes pose_std_m and pose_heading_std_rad",
            ),
            (
                self.pwm_levels <= u16::MAX as u32,
                "pwm_levels must be <= 65535 (a 16-bit timer)",
            ),
        ];
        if let Some(key) = self.unknown_keys.keys().next() {
            return Err(format!(
                "scenario '{}': unknown key `{key}` (schema: docs/scenario.md)",
                self.name
            ));
        }
        match checks.iter().find(|(ok, _)| !ok) {
            Some((_, msg)) => Err(format!("scenario '{}': {msg}", self.name)),
            None => self
                .sensor_setup()
                .map(|_| ())
                .map_err(|e| format!("scenario '{}': {e}", self.name)),
        }
    }

    /// The sensors of this scenario: its sensing preset with its overrides.
    pub fn sensor_setup(&self) -> Result<crate::sensing::SensorModels, String> {
        crate::sensing::SensorModels::of(self.sensing, &self.gyro, &self.pose)
    }

    /// The section-4 perturbations of this scenario.
    pub fn perturbations(&self) -> PerturbationProfile {
        PerturbationProfile {
            window_s: self.window_s,
            beta_radps: self.beta,
            fault_eps: self.eps,
            skid_scale: self.skid_scale,
            disturbance_nm: self.disturbance_nm,
            fault_eps_end: self.eps_end,
        }
    }

    /// True inside the perturbation window.
    pub fn in_window(&self, t_s: f64) -> bool {
        self.perturbations().in_window(t_s)
    }

    /// Perturbations at time t (zero outside the window).
    pub fn perturbation(&self, t_s: f64) -> Perturbation {
        self.perturbations().at(t_s)
    }

    /// The simulated encoders (firmware sensing): `encoder_cpr` and
    /// `speed_window_ticks`, the example encoder's where 0, left mirrored.
    pub fn encoder(&self) -> EncoderParams {
        let ex = EncoderParams::EXAMPLE;
        EncoderParams {
            counts_per_wheel_rev: match self.encoder_cpr {
                0 => ex.counts_per_wheel_rev,
                n => n as f32,
            },
            speed_window_ticks: match self.speed_window_ticks {
                0 => ex.speed_window_ticks,
                n => n,
            },
            ..ex
        }
    }

    /// Controller configuration for this scenario: Table 2 gains plus the
    /// scenario's torque limit, period and optional k_y override.
    pub fn controller_config(
        &self,
        kind: controller_core::ControllerKind,
    ) -> controller_core::ControllerConfig {
        let mut cfg = controller_core::ControllerConfig::paper(kind);
        cfg.torque_limit_nm = self.torque_limit_nm as f32;
        cfg.period_s = self.control_period_s as f32;
        if let Some(k_y) = self.k_y {
            cfg.kinematic.k_y = k_y as f32;
        }
        if self.clean_start {
            cfg.kinematic.large_error_m = controller_core::kinematic::DEFAULT_LARGE_ERROR_M;
        }
        cfg
    }

    /// The firmware runtime's configuration for this scenario: `controller`,
    /// the scenario's reference and initial pose, its encoders and motors
    /// (left mirrored), `safety`, and its pacing.
    pub fn runtime_config(
        &self,
        controller: controller_core::ControllerConfig,
        safety: controller_core::runtime::SafetyLimits,
    ) -> controller_core::runtime::RuntimeConfig {
        let p0 = self.initial_pose;
        controller_core::runtime::RuntimeConfig {
            controller,
            reference: self.trajectory.reference(),
            initial_pose: controller_core::Pose::new(p0[0] as f32, p0[1] as f32, p0[2] as f32),
            encoder: self.encoder(),
            motor: self.motor(),
            motor_inverted: controller_core::runtime::MIRRORED_LEFT,
            safety,
            pacing: self.pacing(),
        }
    }

    /// The simulated motors (firmware sensing): the example motor with
    /// `pwm_levels` counts at full duty (the example's where 0).
    pub fn motor(&self) -> MotorParams {
        let ex = MotorParams::EXAMPLE;
        MotorParams {
            duty_full_scale: match self.pwm_levels {
                0 => ex.duty_full_scale,
                n => n as u16,
            },
            ..ex
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
