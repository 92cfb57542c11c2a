//! The sensing presets: which simulated sensors sit between the plant and
//! the firmware runtime, with what parameters (docs/scenario.md lists them),
//! and the scenario's `gyro_*`/`pose_*` overrides on top.

use crate::scenario::{Scenario, Sensing};
use sim_robot::{GyroModel, PoseSourceModel};

pub use sim_robot::sensors::{PRESET_GYRO, PRESET_MOCAP, PRESET_UWB};

/// The sensors of a scenario: preset plus overrides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorSetup {
    /// The z-gyro, if the preset has one.
    pub gyro: Option<GyroModel>,
    /// The external pose source, if the preset has one.
    pub pose: Option<PoseSourceModel>,
}

impl SensorSetup {
    /// The preset of `scn.sensing` with the scenario's overrides; an
    /// override of a sensor the preset does not have is an error.
    pub fn of(scn: &Scenario) -> Result<Self, String> {
        let (gyro, pose) = match scn.sensing {
            Sensing::Ideal | Sensing::Odometry => (None, None),
            Sensing::Imu => (Some(PRESET_GYRO), None),
            Sensing::Mocap => (Some(PRESET_GYRO), Some(PRESET_MOCAP)),
            Sensing::Uwb => (Some(PRESET_GYRO), Some(PRESET_UWB)),
        };
        let name = scn.sensing.name();
        let gyro_keys = [
            scn.gyro_noise_density,
            scn.gyro_bias_radps,
            scn.gyro_bias_walk,
            scn.gyro_scale_error,
            scn.gyro_saturation_radps,
            scn.gyro_rate_hz,
        ];
        let gyro = match gyro {
            Some(mut g) => {
                let o = |v: Option<f64>, d: f64| v.unwrap_or(d);
                g.noise_density_radps_per_sqrt_hz =
                    o(scn.gyro_noise_density, g.noise_density_radps_per_sqrt_hz);
                g.bias_radps = o(scn.gyro_bias_radps, g.bias_radps);
                g.bias_walk_radps_per_sqrt_s = o(scn.gyro_bias_walk, g.bias_walk_radps_per_sqrt_s);
                g.scale_error = o(scn.gyro_scale_error, g.scale_error);
                g.saturation_radps = o(scn.gyro_saturation_radps, g.saturation_radps);
                g.rate_hz = o(scn.gyro_rate_hz, g.rate_hz);
                g.validate().map_err(|e| format!("gyro: {e}"))?;
                Some(g)
            }
            None if gyro_keys.iter().any(Option::is_some) => {
                return Err(format!(
                    "gyro_* keys need a sensing preset with a gyro (imu, mocap, uwb), not {name}"
                ))
            }
            None => None,
        };
        let pose_set = [
            scn.pose_rate_hz,
            scn.pose_latency_s,
            scn.pose_jitter_s,
            scn.pose_std_m,
            scn.pose_heading_std_rad,
            scn.pose_dropout,
            scn.pose_outlier_fraction,
            scn.pose_outlier_m,
        ]
        .iter()
        .any(Option::is_some)
            || scn.pose_outage_s.is_some();
        let pose = match pose {
            Some(mut p) => {
                let o = |v: Option<f64>, d: f64| v.unwrap_or(d);
                p.rate_hz = o(scn.pose_rate_hz, p.rate_hz);
                p.latency_s = o(scn.pose_latency_s, p.latency_s);
                p.jitter_s = o(scn.pose_jitter_s, p.jitter_s);
                p.position_noise_m = o(scn.pose_std_m, p.position_noise_m);
                if let Some(h) = scn.pose_heading_std_rad {
                    p.heading_noise_rad = (h != 0.0).then_some(h);
                }
                p.dropout = o(scn.pose_dropout, p.dropout);
                if scn.pose_outage_s.is_some() {
                    p.outage_s = scn.pose_outage_s;
                }
                p.outlier_fraction = o(scn.pose_outlier_fraction, p.outlier_fraction);
                p.outlier_m = o(scn.pose_outlier_m, p.outlier_m);
                p.validate().map_err(|e| format!("external pose: {e}"))?;
                if p.latency_s + p.jitter_s > MAX_POSE_DELAY_S {
                    return Err(format!(
                        "pose_latency_s + pose_jitter_s must be <= {MAX_POSE_DELAY_S} s (the estimator's history)"
                    ));
                }
                Some(p)
            }
            None if pose_set => {
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

    #[test]
    fn presets_have_the_issue_values() {
        let s = |sensing| {
            SensorSetup::of(&Scenario {
                sensing,
                ..Scenario::default()
            })
            .unwrap()
        };
        assert_eq!(
            s(Sensing::Ideal),
            SensorSetup {
                gyro: None,
                pose: None
            }
        );
        assert_eq!(
            s(Sensing::Odometry),
            SensorSetup {
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
            sensing: Sensing::Mocap,
            pose_rate_hz: Some(50.0),
            pose_heading_std_rad: Some(0.0),
            pose_outage_s: Some([20.0, 22.0]),
            gyro_bias_radps: Some(0.02),
            ..Scenario::default()
        };
        let s = SensorSetup::of(&scn).unwrap();
        let p = s.pose.unwrap();
        assert_eq!(
            (p.rate_hz, p.heading_noise_rad, p.outage_s),
            (50.0, None, Some([20.0, 22.0]))
        );
        assert_eq!(s.gyro.unwrap().bias_radps, 0.02);
        let bad = Scenario {
            sensing: Sensing::Imu,
            pose_rate_hz: Some(50.0),
            ..Scenario::default()
        };
        assert!(bad.validate().unwrap_err().contains("pose_*"));
        let bad = Scenario {
            sensing: Sensing::Odometry,
            gyro_rate_hz: Some(50.0),
            ..Scenario::default()
        };
        assert!(bad.validate().unwrap_err().contains("gyro_*"));
        let bad = Scenario {
            sensing: Sensing::Uwb,
            pose_latency_s: Some(0.3),
            ..Scenario::default()
        };
        assert!(bad.validate().unwrap_err().contains("history"));
        let bad = Scenario {
            sensing: Sensing::Uwb,
            pose_dropout: Some(2.0),
            ..Scenario::default()
        };
        assert!(bad.validate().is_err());
    }
}
