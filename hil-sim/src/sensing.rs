//! The sensing presets: which simulated sensors sit between the plant and
//! the firmware runtime, with what parameters (book/src/reference/scenario-file.md lists them),
//! and the `gyro_*`/`pose_*` overrides on top ([`GyroOverrides`],
//! [`PoseOverrides`]: each knob one field, read by serde for scenario files
//! and by clap for the command line, inside the scenario's `[sensing]` part).

use serde::{Deserialize, Serialize};
use sim_robot::{GyroModel, PoseSourceModel};

pub use sim_robot::sensors::{PRESET_GYRO, PRESET_MOCAP, PRESET_UWB};

/// What the controller gets from the simulated robot, and how it drives it:
/// a named sensor preset (values in book/src/reference/scenario-file.md; each field
/// overridable by the `gyro_*` and `pose_*` keys).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Sensing {
    /// The paper's setting: the bare controller gets the true pose of G
    /// every tick (plus `pose_noise_m`/`heading_noise_rad`) and η from the
    /// exact wheel-angle change over the last period; its torque is applied
    /// exactly (an ideal torque source).
    #[default]
    Ideal,
    /// The firmware's runtime behind simulated 16-bit encoders
    /// (`encoder_cpr`, `speed_window_ticks`) and an H-bridge with integer duty
    /// (`pwm_levels`) into the DC-motor model; the pose from wheel odometry
    /// only (blind to slip and to the actuator fault).
    Odometry,
    /// As `odometry`, plus a z-gyro (heading sees skid and slip; position
    /// still from the wheels).
    Imu,
    /// As `imu`, plus motion capture: pose of G at 100 Hz, 10 ms latency,
    /// 2 mm and 0.005 rad noise.
    Mocap,
    /// As `imu`, plus UWB: position at 10 Hz, 100 ms latency, 5 cm noise,
    /// no heading.
    Uwb,
}

impl Sensing {
    /// Every preset, in the order of the docs.
    pub const ALL: [Sensing; 5] = [
        Sensing::Ideal,
        Sensing::Odometry,
        Sensing::Imu,
        Sensing::Mocap,
        Sensing::Uwb,
    ];

    /// The preset's name as on the command line and in TOML.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ideal => "ideal",
            Self::Odometry => "odometry",
            Self::Imu => "imu",
            Self::Mocap => "mocap",
            Self::Uwb => "uwb",
        }
    }
}

/// Overrides of the preset's gyro (None = the preset's value).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, clap::Args)]
pub struct GyroOverrides {
    /// Gyro noise density [rad/s/√Hz].
    #[arg(long = "gyro-noise-density")]
    pub gyro_noise_density: Option<f64>,
    /// Gyro initial bias [rad/s].
    #[arg(
        long = "gyro-bias",
        value_name = "rad/s",
        allow_negative_numbers = true
    )]
    pub gyro_bias_radps: Option<f64>,
    /// Gyro bias random walk [rad/s/√s].
    #[arg(long = "gyro-bias-walk")]
    pub gyro_bias_walk: Option<f64>,
    /// Gyro scale-factor error (0.01 = 1 % high).
    #[arg(long = "gyro-scale-error", allow_negative_numbers = true)]
    pub gyro_scale_error: Option<f64>,
    /// Gyro full scale [rad/s].
    #[arg(long = "gyro-saturation", value_name = "rad/s")]
    pub gyro_saturation_radps: Option<f64>,
    /// Gyro output rate [Hz].
    #[arg(long = "gyro-rate", value_name = "Hz")]
    pub gyro_rate_hz: Option<f64>,
}

/// A time window [start, end) [s], written `START,END` on the command line
/// and `[start, end]` in TOML.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Window(pub [f64; 2]);

impl std::str::FromStr for Window {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let v: Vec<&str> = s.split(',').collect();
        let num = |t: &str| {
            t.trim()
                .parse::<f64>()
                .map_err(|_| format!("'{t}' is not a number"))
        };
        match v[..] {
            [a, b] => Ok(Self([num(a)?, num(b)?])),
            _ => Err(format!("takes START,END (two numbers), not '{s}'")),
        }
    }
}

/// Overrides of the preset's external pose source (None = the preset's value).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, clap::Args)]
pub struct PoseOverrides {
    /// External pose rate [Hz].
    #[arg(long = "pose-rate", value_name = "Hz")]
    pub pose_rate_hz: Option<f64>,
    /// External pose latency [s].
    #[arg(long = "pose-latency", value_name = "s")]
    pub pose_latency_s: Option<f64>,
    /// External pose extra latency, uniform in [0, jitter] [s].
    #[arg(long = "pose-jitter", value_name = "s")]
    pub pose_jitter_s: Option<f64>,
    /// External pose position noise std. dev. [m].
    #[arg(long = "pose-std", value_name = "m")]
    pub pose_std_m: Option<f64>,
    /// External pose heading noise std. dev. [rad] (0 = no heading).
    #[arg(long = "pose-heading-std", value_name = "rad")]
    pub pose_heading_std_rad: Option<f64>,
    /// Probability that an external pose is lost.
    #[arg(long = "pose-dropout")]
    pub pose_dropout: Option<f64>,
    /// No external poses are taken in [start, end) [s] (e.g. 20,22).
    #[arg(
        long = "pose-outage",
        value_name = "START,END",
        allow_negative_numbers = true
    )]
    pub pose_outage_s: Option<Window>,
    /// Fraction of external poses that are outliers.
    #[arg(long = "pose-outlier-fraction")]
    pub pose_outlier_fraction: Option<f64>,
    /// Position error of an outlier [m].
    #[arg(long = "pose-outlier", value_name = "m")]
    pub pose_outlier_m: Option<f64>,
}

/// The sensor models of a scenario: its preset's, with the overrides applied.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorModels {
    /// The z-gyro, if the preset has one.
    pub gyro: Option<GyroModel>,
    /// The external pose source, if the preset has one.
    pub pose: Option<PoseSourceModel>,
}

impl SensorModels {
    /// The preset `sensing` with the overrides `gyro` and `pose`; an
    /// override of a sensor the preset does not have is an error.
    pub fn of(
        sensing: Sensing,
        gyro: &GyroOverrides,
        pose: &PoseOverrides,
    ) -> Result<Self, String> {
        let (preset_gyro, preset_pose) = match sensing {
            Sensing::Ideal | Sensing::Odometry => (None, None),
            Sensing::Imu => (Some(PRESET_GYRO), None),
            Sensing::Mocap => (Some(PRESET_GYRO), Some(PRESET_MOCAP)),
            Sensing::Uwb => (Some(PRESET_GYRO), Some(PRESET_UWB)),
        };
        let name = sensing.name();
        let o = |v: Option<f64>, d: f64| v.unwrap_or(d);
        let gyro = match preset_gyro {
            Some(mut g) => {
                g.noise_density_radps_per_sqrt_hz =
                    o(gyro.gyro_noise_density, g.noise_density_radps_per_sqrt_hz);
                g.bias_radps = o(gyro.gyro_bias_radps, g.bias_radps);
                g.bias_walk_radps_per_sqrt_s = o(gyro.gyro_bias_walk, g.bias_walk_radps_per_sqrt_s);
                g.scale_error = o(gyro.gyro_scale_error, g.scale_error);
                g.saturation_radps = o(gyro.gyro_saturation_radps, g.saturation_radps);
                g.rate_hz = o(gyro.gyro_rate_hz, g.rate_hz);
                g.validate().map_err(|e| format!("gyro: {e}"))?;
                Some(g)
            }
            None if *gyro != GyroOverrides::default() => {
                return Err(format!(
                    "gyro_* keys need a sensing preset with a gyro (imu, mocap, uwb), not {name}"
                ))
            }
            None => None,
        };
        let pose = match preset_pose {
            Some(mut p) => {
                let ov = pose;
                p.rate_hz = o(ov.pose_rate_hz, p.rate_hz);
                p.latency_s = o(ov.pose_latency_s, p.latency_s);
                p.jitter_s = o(ov.pose_jitter_s, p.jitter_s);
                p.position_noise_m = o(ov.pose_std_m, p.position_noise_m);
                if let Some(h) = ov.pose_heading_std_rad {
                    p.heading_noise_rad = (h != 0.0).then_some(h);
                }
                p.dropout = o(ov.pose_dropout, p.dropout);
                if let Some(Window(w)) = ov.pose_outage_s {
                    p.outage_s = Some(w);
                }
                p.outlier_fraction = o(ov.pose_outlier_fraction, p.outlier_fraction);
                p.outlier_m = o(ov.pose_outlier_m, p.outlier_m);
                p.validate().map_err(|e| format!("external pose: {e}"))?;
                if p.latency_s + p.jitter_s > MAX_POSE_DELAY_S {
                    return Err(format!(
                        "pose_latency_s + pose_jitter_s must be <= {MAX_POSE_DELAY_S} s (the estimator's history)"
                    ));
                }
                Some(p)
            }
            None if *pose != PoseOverrides::default() => {
                return Err(format!(
                "pose_* keys need a sensing preset with an external pose (mocap, uwb), not {name}"
            ))
            }
            None => None,
        };
        Ok(Self { gyro, pose })
    }
}

/// The longest delay of an external pose the runtime can still use \[s\]
/// (its estimator's history, less one tick of margin).
pub const MAX_POSE_DELAY_S: f64 = 0.25;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    #[test]
    fn windows_parse() {
        assert_eq!("3,4".parse::<Window>(), Ok(Window([3.0, 4.0])));
        assert!("3".parse::<Window>().unwrap_err().contains("START,END"));
        assert!("a,4".parse::<Window>().unwrap_err().contains("'a'"));
    }

    #[test]
    fn presets_have_the_issue_values() {
        let s = |sensing| {
            SensorModels::of(
                sensing,
                &GyroOverrides::default(),
                &PoseOverrides::default(),
            )
            .unwrap()
        };
        assert_eq!(
            s(Sensing::Ideal),
            SensorModels {
                gyro: None,
                pose: None
            }
        );
        assert_eq!(
            s(Sensing::Odometry),
            SensorModels {
                gyro: None,
                pose: None
            }
        );
        assert!(s(Sensing::Imu).gyro.is_some() && s(Sensing::Imu).pose.is_none());
        let m = s(Sensing::Mocap).pose.unwrap();
        assert_eq!(
            (m.rate_hz, m.latency_s, m.position_noise_m),
            (100.0, 0.01, 0.002)
        );
        assert_eq!(m.heading_noise_rad, Some(0.005));
        let u = s(Sensing::Uwb).pose.unwrap();
        assert_eq!(
            (u.rate_hz, u.latency_s, u.position_noise_m),
            (10.0, 0.1, 0.05)
        );
        assert_eq!(u.heading_noise_rad, None);
    }

    #[test]
    fn overrides_apply_and_misplaced_ones_are_errors() {
        let scn = Scenario {
            sensing: crate::scenario::SensingPart {
                preset: Sensing::Mocap,
                pose: PoseOverrides {
                    pose_rate_hz: Some(50.0),
                    pose_heading_std_rad: Some(0.0),
                    pose_outage_s: Some(Window([20.0, 22.0])),
                    ..PoseOverrides::default()
                },
                gyro: GyroOverrides {
                    gyro_bias_radps: Some(0.02),
                    ..GyroOverrides::default()
                },
                ..Default::default()
            },
            ..Scenario::default()
        };
        let s = SensorModels::of(scn.sensing.preset, &scn.sensing.gyro, &scn.sensing.pose).unwrap();
        let p = s.pose.unwrap();
        assert_eq!(
            (p.rate_hz, p.heading_noise_rad, p.outage_s),
            (50.0, None, Some([20.0, 22.0]))
        );
        assert_eq!(s.gyro.unwrap().bias_radps, 0.02);
        let bad = Scenario {
            sensing: crate::scenario::SensingPart {
                preset: Sensing::Imu,
                pose: PoseOverrides {
                    pose_rate_hz: Some(50.0),
                    ..PoseOverrides::default()
                },
                ..Default::default()
            },
            ..Scenario::default()
        };
        assert!(bad.validate().unwrap_err().contains("pose_*"));
        let bad = Scenario {
            sensing: crate::scenario::SensingPart {
                preset: Sensing::Odometry,
                gyro: GyroOverrides {
                    gyro_rate_hz: Some(50.0),
                    ..GyroOverrides::default()
                },
                ..Default::default()
            },
            ..Scenario::default()
        };
        assert!(bad.validate().unwrap_err().contains("gyro_*"));
        let bad = Scenario {
            sensing: crate::scenario::SensingPart {
                preset: Sensing::Uwb,
                pose: PoseOverrides {
                    pose_latency_s: Some(0.3),
                    ..PoseOverrides::default()
                },
                ..Default::default()
            },
            ..Scenario::default()
        };
        assert!(bad.validate().unwrap_err().contains("history"));
        let bad = Scenario {
            sensing: crate::scenario::SensingPart {
                preset: Sensing::Uwb,
                pose: PoseOverrides {
                    pose_dropout: Some(2.0),
                    ..PoseOverrides::default()
                },
                ..Default::default()
            },
            ..Scenario::default()
        };
        assert!(bad.validate().is_err());
    }
}
