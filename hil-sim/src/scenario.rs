//! Scenarios: every knob of a run, the paper's Case 1 and Case 2 presets.
//!
//! Perturbations act inside the window `[window_s[0], window_s[1])` only
//! (paper: 10-35 s); their formulas are in `sim_robot::perturbation` (skid
//! δ_sl, wheel slip ϖ, disturbance τ_d, actuator fault ε).
//!
//! A scenario is the run's own keys and five parts ([`PlantPart`],
//! [`PerturbationPart`], [`SensingPart`], [`ControllerPart`],
//! [`GovernorPart`]), each one struct read by serde (a TOML table of that
//! name) and by clap (the `hil-sim run`/`device` flags), so each knob is
//! declared once. [`Sensing`] chooses what sits between the plant and the
//! controller: the paper's ideal measurements, or the firmware's runtime
//! behind simulated encoders, an H-bridge and the preset's gyro and external
//! pose source ([`crate::sensing`], which also holds the `gyro_*`/`pose_*`
//! overrides, flattened into `[sensing]`).

use crate::rng::Rng;
pub use crate::sensing::Sensing;
use crate::sensing::{GyroOverrides, PoseOverrides};
use controller_core::runtime::{EncoderParams, MotorParams};
pub use robot_file::Robot;
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
    /// Square, 2 m sides from the origin along +x at up to 0.5 m/s, quarter
    /// turns on the spot at up to 1 rad/s (each from rest).
    Square,
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
            Self::Square => Reference::Square(Square {
                side_m: 2.0,
                speed_mps: 0.5,
                yaw_rate_radps: 1.0,
            }),
        }
    }
}

/// The schema version of scenario files this build writes and reads
/// (`version = 2`: nested parts; files without `version` are version 1,
/// flat, and are upgraded on load: [`crate::scenario_file`]).
pub const SCENARIO_VERSION: u32 = 2;

/// A complete description of one simulated run (except the controller kind):
/// the run's own keys, then one part per concern (TOML tables `[plant]`,
/// `[perturbations]`, `[sensing]`, `[controller]`, `[governor]`).
///
/// Each part is one struct that serde (scenario files) and clap (the
/// `hil-sim run`/`device` flags, through [`crate::cli::ScenarioArgs`]) both
/// read, so a knob is declared once: its field, unit, doc and flag name.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, clap::Args)]
#[serde(default, deny_unknown_fields)]
pub struct Scenario {
    /// Schema version of the file (2; see [`SCENARIO_VERSION`]).
    #[arg(skip = SCENARIO_VERSION)]
    pub version: u32,
    /// Name shown in tables and plots.
    #[arg(skip)]
    pub name: String,
    /// Run length [s].
    #[arg(long = "duration", value_name = "s")]
    pub duration_s: f64,
    /// Controller period [s].
    #[arg(long = "control-period", value_name = "s")]
    pub control_period_s: f64,
    /// RK4 sub-steps per control period.
    #[arg(long)]
    pub substeps: u32,
    /// Initial pose of G [x m, y m, θ rad] (`X,Y,THETA`).
    #[arg(long, value_name = "X,Y,THETA", value_parser = floats::<3>, allow_negative_numbers = true)]
    pub initial_pose: [f64; 3],
    /// Reference trajectory.
    #[arg(long, value_enum)]
    pub trajectory: TrajectoryKind,
    /// Seed for the measurement noise (and for β, ε in the presets).
    #[arg(long)]
    pub seed: u64,
    /// The robot the controller is configured for: its model, gains, motor,
    /// encoder and limits, and (unless [`PlantPart`] says otherwise) the
    /// simulated robot too. The paper's robot ([`Robot::paper`]) unless
    /// `--robot FILE` (a robot file, book/src/how-to/robot-file.md) names another; not a
    /// key of the scenario file.
    #[serde(skip, default = "Robot::paper")]
    #[arg(skip = Robot::paper())]
    pub robot: Robot,
    /// The simulated robot against the controller's model.
    #[command(flatten)]
    pub plant: PlantPart,
    /// Section-4 perturbations and the faults beyond the paper.
    #[command(flatten)]
    pub perturbations: PerturbationPart,
    /// Measurements and actuation between plant and controller.
    #[command(flatten)]
    pub sensing: SensingPart,
    /// Overrides of the controller's configuration.
    #[command(flatten)]
    pub controller: ControllerPart,
    /// Reference governor and health machine.
    #[command(flatten)]
    pub governor: GovernorPart,
}

/// `[plant]`: the simulated robot against the controller's model. The
/// plant is the controller's robot ([`Scenario::robot`]), or the robot file
/// of `--plant FILE` ([`Self::robot`]), with the robot-file fields of the
/// `[plant.body]`, `[plant.motors]`, ... tables over it, then the scales,
/// the actuation delay and the electrical lag below ([`Scenario::plant_robot`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, clap::Args)]
#[serde(default, deny_unknown_fields)]
pub struct PlantPart {
    /// Plant mass / controller model mass.
    #[arg(long)]
    pub mass_scale: f64,
    /// Plant inertia / controller model inertia.
    #[arg(long)]
    pub inertia_scale: f64,
    /// Per-wheel torque limit [N·m] (controller saturation and actuator
    /// limit; None = the robot file's `limits.torque_nm`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long = "torque-limit", value_name = "N·m")]
    pub torque_limit_nm: Option<f64>,
    /// Actuation delay of the plant [s]: the torque the controller commands
    /// acts this much later (0 = none; the model assumes none).
    #[arg(long = "actuation-delay", value_name = "s")]
    pub actuation_delay_s: f64,
    /// Electrical time constant L/R of the plant's motors [s]: the torque
    /// follows the command with this first-order lag (0 = none; the model
    /// assumes none).
    #[arg(long = "electrical-time-constant", value_name = "s")]
    pub electrical_time_constant_s: f64,
    /// The plant's own robot file (`--plant FILE`), when it differs from
    /// the controller's; not a key of the scenario file (its fields are:
    /// the tables below).
    #[serde(skip)]
    #[arg(skip)]
    pub robot: Option<Robot>,
    /// Fields of the robot file's `[body]` for the plant (`[plant.body]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub body: Option<toml::Table>,
    /// Fields of the robot file's `[motors]` for the plant (`[plant.motors]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub motors: Option<toml::Table>,
    /// Fields of the robot file's `[encoders]` for the plant (`[plant.encoders]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub encoders: Option<toml::Table>,
    /// Fields of the robot file's `[bridge]` for the plant (`[plant.bridge]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub bridge: Option<toml::Table>,
    /// Fields of the robot file's `[limits]` for the plant (`[plant.limits]`:
    /// `torque_nm` is the drive's hard limit).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub limits: Option<toml::Table>,
}

impl Default for PlantPart {
    fn default() -> Self {
        Self {
            mass_scale: 1.0,
            inertia_scale: 1.0,
            torque_limit_nm: None,
            actuation_delay_s: 0.0,
            electrical_time_constant_s: 0.0,
            robot: None,
            body: None,
            motors: None,
            encoders: None,
            bridge: None,
            limits: None,
        }
    }
}

impl PlantPart {
    /// The robot-file sections this part overrides, by section name.
    fn sections(&self) -> [(&'static str, &Option<toml::Table>); 5] {
        [
            ("body", &self.body),
            ("motors", &self.motors),
            ("encoders", &self.encoders),
            ("bridge", &self.bridge),
            ("limits", &self.limits),
        ]
    }

    /// True when the plant is the controller's robot as it is (no file, no
    /// field override; the scales, delay and lag aside).
    pub fn is_model(&self) -> bool {
        self.robot.is_none() && self.sections().iter().all(|(_, t)| t.is_none())
    }
}

/// `[perturbations]`: what acts on the plant inside the window (paper
/// section 4, and the faults beyond it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, clap::Args)]
#[serde(default, deny_unknown_fields)]
pub struct PerturbationPart {
    /// Perturbation window [start, end) [s] (`START,END`).
    #[arg(long = "window", value_name = "START,END", value_parser = floats::<2>, allow_negative_numbers = true)]
    pub window_s: [f64; 2],
    /// Wheel slip amplitude β [rad/s].
    #[arg(long)]
    pub beta: f64,
    /// Actuator fault ε in [0, 1) (body moves at (1 − ε)·η in the window).
    #[arg(long)]
    pub eps: f64,
    /// Growing fault (beyond the paper): ε at the window's end, ramped
    /// linearly from `eps` at its start (None = constant `eps`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub eps_end: Option<f64>,
    /// Fraction of the commanded torque each wheel `RIGHT,LEFT` delivers
    /// inside the window (beyond the paper; 1,1 = healthy).
    #[serde(skip_serializing_if = "is_healthy_wheels")]
    #[arg(long, value_name = "RIGHT,LEFT", value_parser = floats::<2>)]
    pub wheel_torque_scale: [f64; 2],
    /// Scale of the lateral skid δ_sl (1 = as printed in the paper).
    #[arg(long)]
    pub skid_scale: f64,
    /// Disturbance amplitude A [N·m].
    #[arg(long = "disturbance", value_name = "N·m")]
    pub disturbance_nm: f64,
}

impl Default for PerturbationPart {
    fn default() -> Self {
        Self {
            window_s: [10.0, 35.0],
            beta: 0.1,
            eps: 0.0,
            eps_end: None,
            wheel_torque_scale: [1.0, 1.0],
            skid_scale: 0.05,
            disturbance_nm: 1.0,
        }
    }
}

impl PerturbationPart {
    /// No perturbation at all: an empty window, no slip, fault, skid or
    /// disturbance (nominal tracking).
    pub fn none() -> Self {
        Self {
            window_s: [0.0, 0.0],
            beta: 0.0,
            eps: 0.0,
            eps_end: None,
            wheel_torque_scale: [1.0, 1.0],
            skid_scale: 0.0,
            disturbance_nm: 0.0,
        }
    }
}

/// `[sensing]`: the sensor preset between plant and controller and its
/// overrides.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, clap::Args)]
#[serde(default)]
pub struct SensingPart {
    /// Sensor preset between plant and controller: the paper's ideal
    /// measurements, or the firmware runtime behind simulated encoders and
    /// PWM with a gyro (imu) and an external pose (mocap, uwb); the
    /// --gyro-* and --pose-* flags override the preset (book/src/reference/scenario-file.md).
    #[arg(long = "sensing", value_enum)]
    pub preset: Sensing,
    /// Encoder counts per wheel revolution after ×4 decoding (firmware
    /// sensing only; 0 = the example encoder's 24000).
    #[arg(long)]
    pub encoder_cpr: u32,
    /// Speed-estimate window [ticks] (firmware sensing only; 0 = the
    /// example encoder's 4).
    #[arg(long = "speed-window", value_name = "TICKS")]
    pub speed_window_ticks: u8,
    /// PWM counts at 100 % duty (firmware sensing only; 0 = the example
    /// motor's 4800).
    #[arg(long)]
    pub pwm_levels: u32,
    /// Std. dev. of the position measurement noise [m] (ideal sensing).
    #[arg(long = "pose-noise", value_name = "m")]
    pub pose_noise_m: f64,
    /// Std. dev. of the heading measurement noise [rad] (ideal sensing).
    #[arg(long = "heading-noise", value_name = "rad")]
    pub heading_noise_rad: f64,
    /// Overrides of the preset's gyro (keys `gyro_*`, flags `--gyro-*`).
    #[serde(flatten)]
    #[command(flatten)]
    pub gyro: GyroOverrides,
    /// Overrides of the preset's external pose source (keys `pose_*`,
    /// flags `--pose-*`).
    #[serde(flatten)]
    #[command(flatten)]
    pub pose: PoseOverrides,
    /// Keys of the `[sensing]` table that are not in the schema: a scenario
    /// with any is invalid ([`Scenario::validate`]), so a typo never
    /// silently falls back to a default. (serde's `deny_unknown_fields`
    /// cannot be combined with the flattened overrides.)
    #[serde(flatten, skip_serializing)]
    #[arg(skip)]
    pub unknown_keys: std::collections::BTreeMap<String, toml::Value>,
}

/// `[controller]`: overrides of the controller's configuration (Table 2
/// gains otherwise).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, clap::Args)]
#[serde(default, deny_unknown_fields)]
pub struct ControllerPart {
    /// Override of the kinematic gain k_y (None = controller default).
    #[arg(long)]
    pub k_y: Option<f64>,
    /// Large-error bound of the kinematic law's lateral term (D23), beyond
    /// the paper (None = the robot file's `control.clean_start`, on unless
    /// the file says otherwise; off in [`Scenario::as_printed`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long, value_name = "BOOL", action = clap::ArgAction::Set)]
    pub clean_start: Option<bool>,
}

/// `[governor]`: the reference governor and health machine
/// (`controller_core::pacer`), beyond the paper.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, clap::Args)]
#[serde(default, deny_unknown_fields)]
pub struct GovernorPart {
    /// Governor and health machine on (None = the robot file's
    /// `control.governor`, on unless the file says otherwise; off in
    /// [`Scenario::as_printed`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long = "governor", value_name = "BOOL", action = clap::ArgAction::Set)]
    pub enabled: Option<bool>,
}

/// The parts of a scenario, as the TOML tables of a version-2 file.
pub const PARTS: [&str; 5] = [
    "plant",
    "perturbations",
    "sensing",
    "controller",
    "governor",
];

/// A scenario with every optional key set (and every key that is left out
/// at its default set to another value), so that its TOML form shows every
/// key of the schema: what the docs test and the version-1 upgrade read.
pub fn every_key_set() -> Scenario {
    let mut s = Scenario::default().with_sensing(Sensing::Mocap);
    s.perturbations.eps_end = Some(0.3);
    s.plant.torque_limit_nm = Some(8.0);
    s.plant.actuation_delay_s = 0.002;
    s.perturbations.wheel_torque_scale = [1.0, 0.5];
    s.controller.k_y = Some(20.0);
    s.controller.clean_start = Some(false);
    s.governor.enabled = Some(false);
    s.sensing.gyro = GyroOverrides {
        gyro_noise_density: Some(1e-4),
        gyro_bias_radps: Some(0.01),
        gyro_bias_walk: Some(1e-4),
        gyro_scale_error: Some(0.01),
        gyro_saturation_radps: Some(30.0),
        gyro_rate_hz: Some(500.0),
    };
    s.sensing.pose = PoseOverrides {
        pose_rate_hz: Some(50.0),
        pose_latency_s: Some(0.01),
        pose_jitter_s: Some(0.001),
        pose_std_m: Some(0.002),
        pose_heading_std_rad: Some(0.004),
        pose_dropout: Some(0.1),
        pose_outage_s: Some(crate::sensing::Window([1.0, 2.0])),
        pose_outlier_fraction: Some(0.05),
        pose_outlier_m: Some(1.0),
    };
    s
}

/// `N` comma-separated numbers (`1,2` or `2.5,0,0`), the command-line form
/// of the scenario's array keys.
pub fn floats<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<&str> = s.split(',').collect();
    if v.len() != N {
        return Err(format!("takes {N} comma-separated numbers, not '{s}'"));
    }
    let mut out = [0.0; N];
    for (o, t) in out.iter_mut().zip(v) {
        *o = t
            .trim()
            .parse::<f64>()
            .map_err(|_| format!("'{t}' is not a number"))?;
    }
    Ok(out)
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            version: SCENARIO_VERSION,
            name: "custom".into(),
            duration_s: 40.0,
            control_period_s: 1e-3,
            substeps: 1,
            initial_pose: [2.5, 0.0, 0.0],
            trajectory: TrajectoryKind::Paper,
            seed: 1,
            robot: Robot::paper(),
            plant: PlantPart::default(),
            perturbations: PerturbationPart::default(),
            sensing: SensingPart::default(),
            controller: ControllerPart::default(),
            governor: GovernorPart::default(),
        }
    }
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
        let mut s = Self {
            name: format!("case{case}"),
            seed,
            ..Self::default()
        };
        s.perturbations.beta = beta.unwrap_or(b);
        s.perturbations.eps = if case >= 2 { eps.unwrap_or(e) } else { 0.0 };
        s
    }

    /// This scenario in the paper's setting: no governor, no health machine
    /// (what `compare`'s first table runs).
    pub fn as_printed(mut self) -> Self {
        self.governor.enabled = Some(false);
        self.controller.clean_start = Some(false);
        self
    }

    /// This scenario with `robot` as the controller's robot and `plant` as
    /// the simulated one (each None: unchanged).
    pub fn with_robots(mut self, robot: Option<&Robot>, plant: Option<&Robot>) -> Self {
        if let Some(r) = robot {
            self.robot = r.clone();
        }
        if let Some(p) = plant {
            self.plant.robot = Some(p.clone());
        }
        self
    }

    /// This scenario with the sensing preset `preset` (its overrides kept).
    pub fn with_sensing(mut self, preset: Sensing) -> Self {
        self.sensing.preset = preset;
        self
    }

    /// The runtime/simulator pacing configuration for this scenario.
    pub fn pacing(&self) -> controller_core::pacer::PacingConfig {
        self.derive(controller_core::ControllerKind::Proposed)
            .runtime
            .pacing
    }

    /// True when the reference governor and health machine run: the
    /// scenario's `[governor] enabled`, else the robot file's
    /// `control.governor`.
    pub fn governor_on(&self) -> bool {
        self.governor.enabled.unwrap_or(self.robot.control.governor)
    }

    /// Checks the knobs; a clear message for the first bad one.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |x: f64| x.is_finite() && x > 0.0;
        let nonneg = |x: f64| x.is_finite() && x >= 0.0;
        let ideal = self.sensing.preset == Sensing::Ideal;
        let (pt, pl, se) = (&self.perturbations, &self.plant, &self.sensing);
        // Each rule with the values found (issue 37: a refusal says the
        // value, the limit and what to do).
        let checks: [(bool, &dyn Fn() -> String); 18] = [
            (pos(self.duration_s), &|| {
                format!("duration_s = {} must be > 0 s", self.duration_s)
            }),
            (
                pos(self.control_period_s) && self.control_period_s <= 0.1,
                &|| {
                    format!(
                        "control_period_s = {} must be in (0, 0.1] s",
                        self.control_period_s
                    )
                },
            ),
            (self.substeps >= 1, &|| {
                format!("substeps = {} must be >= 1", self.substeps)
            }),
            (
                pt.window_s.iter().all(|x| x.is_finite()) && pt.window_s[0] <= pt.window_s[1],
                &|| format!("window_s = {:?} must be finite, start <= end", pt.window_s),
            ),
            (self.initial_pose.iter().all(|x| x.is_finite()), &|| {
                format!("initial_pose = {:?} must be finite", self.initial_pose)
            }),
            (nonneg(pt.beta), &|| {
                format!("beta = {} must be >= 0", pt.beta)
            }),
            (nonneg(pt.eps) && pt.eps < 1.0, &|| {
                format!(
                    "eps = {} must be in [0, 1) (the lost share of a wheel's torque)",
                    pt.eps
                )
            }),
            (pt.eps_end.is_none_or(|e| nonneg(e) && e < 1.0), &|| {
                format!("eps_end = {:?} must be in [0, 1)", pt.eps_end)
            }),
            (
                pt.wheel_torque_scale.iter().all(|&k| nonneg(k) && k <= 1.0),
                &|| {
                    format!(
                        "wheel_torque_scale = {:?} must be in [0, 1] each",
                        pt.wheel_torque_scale
                    )
                },
            ),
            (nonneg(pt.skid_scale) && nonneg(pt.disturbance_nm), &|| {
                format!(
                    "skid_scale = {} and disturbance_nm = {} must be >= 0",
                    pt.skid_scale, pt.disturbance_nm
                )
            }),
            (pos(pl.mass_scale) && pos(pl.inertia_scale), &|| {
                format!(
                    "mass_scale = {} and inertia_scale = {} must be > 0",
                    pl.mass_scale, pl.inertia_scale
                )
            }),
            (pl.torque_limit_nm.is_none_or(pos), &|| {
                format!("torque_limit_nm = {:?} must be > 0 N·m", pl.torque_limit_nm)
            }),
            (
                nonneg(pl.actuation_delay_s)
                    && pl.actuation_delay_s <= 1.0
                    && nonneg(pl.electrical_time_constant_s)
                    && pl.electrical_time_constant_s <= 1.0,
                &|| {
                    format!(
                        "actuation_delay_s = {} and electrical_time_constant_s = {} must be in [0, 1] s",
                        pl.actuation_delay_s, pl.electrical_time_constant_s
                    )
                },
            ),
            (
                nonneg(se.pose_noise_m) && nonneg(se.heading_noise_rad),
                &|| {
                    format!(
                        "pose_noise_m = {} and heading_noise_rad = {} must be >= 0",
                        se.pose_noise_m, se.heading_noise_rad
                    )
                },
            ),
            (self.controller.k_y.is_none_or(pos), &|| {
                format!("k_y = {:?} must be > 0", self.controller.k_y)
            }),
            (
                !ideal || (se.encoder_cpr == 0 && se.pwm_levels == 0 && se.speed_window_ticks == 0),
                &|| {
                    "encoder_cpr, pwm_levels and speed_window_ticks need a firmware sensing preset (ideal sensing has no encoders or PWM)".into()
                },
            ),
            (
                ideal || (se.pose_noise_m == 0.0 && se.heading_noise_rad == 0.0),
                &|| {
                    "pose_noise_m and heading_noise_rad are the noise of ideal sensing; the external pose of mocap/uwb takes pose_std_m and pose_heading_std_rad".into()
                },
            ),
            (se.pwm_levels <= u16::MAX as u32, &|| {
                format!(
                    "pwm_levels = {} must be <= 65535 (a 16-bit timer)",
                    se.pwm_levels
                )
            }),
        ];
        if let Some(key) = self.sensing.unknown_keys.keys().next() {
            return Err(format!(
                "scenario '{}': unknown key `{key}` in [sensing] (schema: book/src/reference/scenario-file.md)",
                self.name
            ));
        }
        if self.version != SCENARIO_VERSION {
            return Err(format!(
                "scenario '{}': version = {} is not a scenario schema this build reads (1 = flat keys, upgraded on load; {SCENARIO_VERSION} = nested parts: book/src/reference/scenario-file.md)",
                self.name, self.version
            ));
        }
        match checks.iter().find(|(ok, _)| !ok) {
            Some((_, msg)) => Err(format!("scenario '{}': {}", self.name, msg())),
            None => self
                .sensor_setup()
                .map(|_| ())
                .and_then(|_| self.plant_robot().map(|_| ()))
                .and_then(|_| {
                    self.controller_robot(controller_core::ControllerKind::Proposed)
                        .validate()
                        .map_err(|e| match self.override_of(e.field) {
                            Some(key) => {
                                format!("{key} (written into the robot's {}): {e}", e.field)
                            }
                            None => format!("robot (with the scenario's overrides): {e}"),
                        })
                })
                .map_err(|e| format!("scenario '{}': {e}", self.name)),
        }
    }

    /// The sensors of this scenario: its sensing preset with its overrides.
    pub fn sensor_setup(&self) -> Result<crate::sensing::SensorModels, String> {
        crate::sensing::SensorModels::of(
            self.sensing.preset,
            &self.sensing.gyro,
            &self.sensing.pose,
        )
    }

    /// The section-4 perturbations of this scenario.
    pub fn perturbations(&self) -> PerturbationProfile {
        PerturbationProfile {
            window_s: self.perturbations.window_s,
            beta_radps: self.perturbations.beta,
            fault_eps: self.perturbations.eps,
            skid_scale: self.perturbations.skid_scale,
            disturbance_nm: self.perturbations.disturbance_nm,
            fault_eps_end: self.perturbations.eps_end,
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

    /// The controller's encoders (firmware sensing): the robot's, with
    /// `encoder_cpr` and `speed_window_ticks` where not 0.
    pub fn encoder(&self) -> EncoderParams {
        self.controller_robot(controller_core::ControllerKind::Proposed)
            .encoder_params()
    }

    /// The per-wheel torque limit [N·m]: `plant.torque_limit_nm`, or the
    /// robot file's `limits.torque_nm`.
    pub fn torque_limit_nm(&self) -> f64 {
        self.plant
            .torque_limit_nm
            .unwrap_or(f64::from(self.robot.limits.torque_nm))
    }

    /// The controller's robot for `kind`: the robot file with the
    /// scenario's overrides written into it as typed edits (D139): the
    /// controller `kind`, `[controller] clean_start`, `[governor] enabled`,
    /// the start pose, `plant.torque_limit_nm` (the drive's limit is the
    /// controller's), `[controller] k_y` (into `[gains.<kind>]`) and the
    /// sensing part's `encoder_cpr` and `speed_window_ticks`. Not
    /// validated ([`Scenario::validate`] does).
    pub fn controller_robot(&self, kind: controller_core::ControllerKind) -> Robot {
        let mut r = self.robot.clone();
        let c = &mut r.control;
        c.controller = kind;
        c.clean_start = self.controller.clean_start.unwrap_or(c.clean_start);
        c.governor = self.governor_on();
        let [x, y, th] = self.initial_pose;
        (c.initial_x_m, c.initial_y_m, c.initial_heading_rad) = (x as f32, y as f32, th as f32);
        r.limits.torque_nm = self.torque_limit_nm() as f32;
        if let Some(k_y) = self.controller.k_y {
            let mut g = r.gains.resolved(kind);
            g.kinematic.k_y = k_y as f32;
            *r.gains.of_mut(kind) = Some(g);
        }
        self.sensing.edit_encoders(&mut r.encoders);
        r
    }

    /// The scenario key, with its value, that wrote robot field `field` in
    /// [`Self::controller_robot`] (None: the robot file's own value), so
    /// that a refusal names what the user wrote.
    fn override_of(&self, field: &str) -> Option<String> {
        let s = &self.sensing;
        match field {
            "limits.torque_nm" => self
                .plant
                .torque_limit_nm
                .map(|t| format!("torque_limit_nm = {t:e}")),
            "control.initial_x_m" | "control.initial_y_m" | "control.initial_heading_rad" => {
                Some(format!("initial_pose = {:?}", self.initial_pose))
            }
            "encoders.counts_per_wheel_rev" if s.encoder_cpr != 0 => {
                Some(format!("encoder_cpr = {}", s.encoder_cpr))
            }
            "encoders.speed_window_ticks" if s.speed_window_ticks != 0 => {
                Some(format!("speed_window_ticks = {}", s.speed_window_ticks))
            }
            f if f.ends_with("kinematic.k_y") => self.controller.k_y.map(|k| format!("k_y = {k}")),
            _ => None,
        }
    }

    /// What the simulated board tells the derivation: the PWM resolution
    /// (`pwm_levels`, or the robot's bridge frequency on the F411's timer
    /// clock [`TIMER_CLOCK_HZ`]), the scenario's control period and the
    /// sensing preset's gyro saturation.
    pub fn board_facts(&self) -> robot_file::BoardFacts {
        robot_file::BoardFacts {
            pwm_full_scale: self.duty_full_scale(),
            control_period_s: self.control_period_s as f32,
            gyro_saturation_radps: self
                .sensor_setup()
                .ok()
                .and_then(|s| s.gyro)
                .map(|g| g.saturation_radps as f32),
        }
    }

    /// The one derivation (`Robot::derive`) of the controller's robot for
    /// `kind` ([`Self::controller_robot`]) on the simulated board
    /// ([`Self::board_facts`]) following the scenario's trajectory.
    pub fn derive(&self, kind: controller_core::ControllerKind) -> robot_file::Derived {
        self.controller_robot(kind)
            .derive(&self.board_facts(), self.trajectory.reference())
    }

    /// Controller configuration for this scenario (the derivation's, see
    /// [`Self::controller_robot`] for what the scenario changes).
    pub fn controller_config(
        &self,
        kind: controller_core::ControllerKind,
    ) -> controller_core::ControllerConfig {
        self.derive(kind).runtime.controller
    }

    /// The runtime's safety limits for this scenario's robot and period
    /// (`Robot::safety_limits` through the derivation).
    pub fn safety_limits(&self) -> controller_core::runtime::SafetyLimits {
        self.derive(controller_core::ControllerKind::Proposed)
            .runtime
            .safety
    }

    /// The firmware runtime's configuration for this scenario with
    /// `controller` (e.g. tuned gains) and `safety`: the derivation's for
    /// `controller.kind`, with those two in place.
    pub fn runtime_config(
        &self,
        controller: controller_core::ControllerConfig,
        safety: controller_core::runtime::SafetyLimits,
    ) -> controller_core::runtime::RuntimeConfig {
        controller_core::runtime::RuntimeConfig {
            controller,
            safety,
            ..self.derive(controller.kind).runtime
        }
    }

    /// The PWM counts at full duty: `pwm_levels`, or the robot's bridge
    /// frequency on the F411's timer clock ([`TIMER_CLOCK_HZ`]).
    fn duty_full_scale(&self) -> u16 {
        match self.sensing.pwm_levels {
            0 => self
                .robot
                .pwm_full_scale(TIMER_CLOCK_HZ)
                .unwrap_or(MotorParams::EXAMPLE.duty_full_scale),
            n => n as u16,
        }
    }

    /// The controller's motors (firmware sensing): the robot's, with
    /// `pwm_levels` counts at full duty (where not 0).
    pub fn motor(&self) -> MotorParams {
        self.derive(controller_core::ControllerKind::Proposed)
            .runtime
            .motor
    }

    /// The simulated robot: the plant's robot file (`--plant`, or the
    /// controller's robot) with the `[plant.<section>]` fields written
    /// over its sections and the sensing part's encoder overrides, then
    /// validated as a robot file (errors name the field as
    /// `plant.<path>`). Each section is edited as a typed value: no text
    /// round trip (D139).
    pub fn plant_robot(&self) -> Result<Robot, String> {
        let mut robot = self.plant.robot.as_ref().unwrap_or(&self.robot).clone();
        fn edit<T: Serialize + serde::de::DeserializeOwned>(
            name: &str,
            section: &mut T,
            over: &Option<toml::Table>,
        ) -> Result<(), String> {
            let Some(over) = over else { return Ok(()) };
            let mut t = match toml::Value::try_from(&*section) {
                Ok(toml::Value::Table(t)) => t,
                _ => return Err(format!("plant.{name}: not a section of the robot file")),
            };
            for (k, v) in over {
                if !t.contains_key(k) {
                    return Err(format!(
                        "plant.{name}.{k}: not a field of the robot file's [{name}] (book/src/how-to/robot-file.md)"
                    ));
                }
                t.insert(k.clone(), v.clone());
            }
            *section = toml::Value::Table(t)
                .try_into()
                .map_err(|e| format!("plant.{name}: {e}"))?;
            Ok(())
        }
        let p = &self.plant;
        edit("body", &mut robot.body, &p.body)?;
        edit("motors", &mut robot.motors, &p.motors)?;
        edit("encoders", &mut robot.encoders, &p.encoders)?;
        edit("bridge", &mut robot.bridge, &p.bridge)?;
        edit("limits", &mut robot.limits, &p.limits)?;
        self.sensing.edit_encoders(&mut robot.encoders);
        robot
            .validate()
            .map_err(|e| format!("plant (robot file with the [plant.*] fields): {e}"))?;
        Ok(robot)
    }
}

impl SensingPart {
    /// Writes `encoder_cpr` and `speed_window_ticks` (where not 0) into a
    /// robot's `[encoders]`: the controller's and the plant's encoders are
    /// the same part.
    pub fn edit_encoders(&self, e: &mut robot_file::Encoders) {
        if self.encoder_cpr != 0 {
            e.counts_per_wheel_rev = self.encoder_cpr as f32;
        }
        if self.speed_window_ticks != 0 {
            e.speed_window_ticks = self.speed_window_ticks;
        }
    }
}

/// Timer clock the PWM resolution is derived at when `pwm_levels` is 0
/// [Hz]: the STM32F411's 96 MHz (robot-file's first supported clock; the
/// paper robot's 20 kHz gives the example's 4,800 levels).
pub const TIMER_CLOCK_HZ: u32 = robot_file::SUPPORTED_TIMER_CLOCKS_HZ[0];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_draw_in_paper_ranges_and_are_seeded() {
        for seed in 0..200 {
            let c2 = Scenario::paper_case(2, seed, None, None);
            assert!(c2.perturbations.beta > 0.0 && c2.perturbations.beta < 0.2);
            assert!(c2.perturbations.eps > 0.125 && c2.perturbations.eps < 0.25);
            assert_eq!(c2, Scenario::paper_case(2, seed, None, None));
            let c1 = Scenario::paper_case(1, seed, None, None);
            assert_eq!(c1.perturbations.eps, 0.0);
            assert_eq!(c1.perturbations.beta, c2.perturbations.beta);
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
        let mut s = Scenario::default();
        s.perturbations.eps = 1.5;
        assert!(s.validate().unwrap_err().contains("eps"));
        let mut s = Scenario::default();
        s.plant.torque_limit_nm = Some(f64::NAN);
        assert!(s.validate().unwrap_err().contains("torque"));
    }
}
