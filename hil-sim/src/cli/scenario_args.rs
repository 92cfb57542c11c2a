//! [`ScenarioArgs`]: the scenario flags shared by `run` and `device` (they
//! mirror [`Scenario`]'s fields; the `--gyro-*` and `--pose-*` overrides
//! are the very structs the scenario holds, [`GyroOverrides`] and
//! [`PoseOverrides`], each knob declared once for serde and clap).

use crate::scenario::{Scenario, Sensing, TrajectoryKind};
use crate::scenario_file::load_scenario;
use crate::sensing::{overlay, GyroOverrides, PoseOverrides};
use clap::Args;
use std::path::PathBuf;

/// Scenario selection and overrides shared by `run`.
#[derive(Debug, Args, Default, Clone)]
pub struct ScenarioArgs {
    /// Paper preset: 1 = disturbance + slip, 2 = + actuator fault [default: 2].
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=2), conflicts_with = "scenario")]
    pub case: Option<u8>,
    /// Scenario TOML file (schema: docs/scenario.md); the flags below override it.
    #[arg(long, value_name = "FILE.toml")]
    pub scenario: Option<PathBuf>,
    /// Seed: draws β, ε of the preset, and the measurement noise.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Wheel slip amplitude β [rad/s].
    #[arg(long)]
    pub beta: Option<f64>,
    /// Actuator fault ε in [0, 1) (body moves at (1 − ε)·η in the window).
    #[arg(long)]
    pub eps: Option<f64>,
    /// Scale of the lateral skid δ_sl (1 = as printed in the paper).
    #[arg(long)]
    pub skid_scale: Option<f64>,
    /// Disturbance amplitude A [N·m].
    #[arg(long, value_name = "N·m")]
    pub disturbance: Option<f64>,
    /// Per-wheel torque limit [N·m].
    #[arg(long, value_name = "N·m")]
    pub torque_limit: Option<f64>,
    /// Plant mass / controller model mass.
    #[arg(long)]
    pub mass_scale: Option<f64>,
    /// Plant inertia / controller model inertia.
    #[arg(long)]
    pub inertia_scale: Option<f64>,
    /// Reference trajectory.
    #[arg(long, value_enum)]
    pub trajectory: Option<TrajectoryKind>,
    /// Run length [s].
    #[arg(long, value_name = "s")]
    pub duration: Option<f64>,
    /// Sensor preset between plant and controller: the paper's ideal
    /// measurements, or the firmware runtime behind simulated encoders and
    /// PWM with a gyro (imu) and an external pose (mocap, uwb); the
    /// --gyro-* and --pose-* flags override the preset (docs/scenario.md).
    #[arg(long, value_enum)]
    pub sensing: Option<Sensing>,
    /// Overrides of the preset's gyro (`--gyro-*`).
    #[command(flatten)]
    pub gyro: GyroOverrides,
    /// Overrides of the preset's external pose source (`--pose-*`).
    #[command(flatten)]
    pub pose: PoseOverrides,
    /// Firmware sensing: encoder counts per wheel revolution (0 = example's 24000).
    #[arg(long)]
    pub encoder_cpr: Option<u32>,
    /// Firmware sensing: speed-estimate window [ticks] (0 = example's 4).
    #[arg(long, value_name = "TICKS")]
    pub speed_window: Option<u8>,
    /// Firmware sensing: PWM counts at full duty (0 = example's 4800).
    #[arg(long)]
    pub pwm_levels: Option<u32>,
    /// Std. dev. of the position measurement noise [m].
    #[arg(long, value_name = "m")]
    pub pose_noise: Option<f64>,
    /// Std. dev. of the heading measurement noise [rad].
    #[arg(long, value_name = "rad")]
    pub heading_noise: Option<f64>,
    /// Kinematic gain k_y override.
    #[arg(long)]
    pub k_y: Option<f64>,
    /// Controller period [s].
    #[arg(long, value_name = "s")]
    pub control_period: Option<f64>,
    /// RK4 sub-steps per control period.
    #[arg(long)]
    pub substeps: Option<u32>,
    /// Reference governor and health machine (beyond the paper; default on).
    #[arg(long, value_name = "BOOL", action = clap::ArgAction::Set)]
    pub governor: Option<bool>,
    /// Large-error bound of the kinematic law (clean start; default on).
    #[arg(long, value_name = "BOOL", action = clap::ArgAction::Set)]
    pub clean_start: Option<bool>,
    /// Growing fault: ε at the window's end, ramped from --eps at its start.
    #[arg(long)]
    pub eps_end: Option<f64>,
    /// Fraction of its torque the left wheel delivers in the window (weak wheel).
    #[arg(long, value_name = "FRACTION")]
    pub left_torque_scale: Option<f64>,
}

impl ScenarioArgs {
    /// The scenario: the file or the paper preset, then the flags on top;
    /// validated.
    pub fn build(&self) -> Result<Scenario, String> {
        let mut scn = match &self.scenario {
            Some(path) => {
                let mut s = load_scenario(path)?;
                if let Some(seed) = self.seed {
                    s.seed = seed;
                }
                s
            }
            None => {
                Scenario::paper_case(self.case.unwrap_or(2), self.seed.unwrap_or(1), None, None)
            }
        };
        macro_rules! set {
            ($($flag:ident => $field:ident),* $(,)?) => {
                $( if let Some(v) = self.$flag { scn.$field = v.into(); } )*
            };
        }
        set!(
            beta => beta,
            eps => eps,
            skid_scale => skid_scale,
            disturbance => disturbance_nm,
            torque_limit => torque_limit_nm,
            mass_scale => mass_scale,
            inertia_scale => inertia_scale,
            trajectory => trajectory,
            duration => duration_s,
            sensing => sensing,
            encoder_cpr => encoder_cpr,
            speed_window => speed_window_ticks,
            pwm_levels => pwm_levels,
            pose_noise => pose_noise_m,
            heading_noise => heading_noise_rad,
            control_period => control_period_s,
            substeps => substeps,
            governor => governor,
            clean_start => clean_start,
        );
        scn.gyro = overlay(&scn.gyro, &self.gyro);
        scn.pose = overlay(&scn.pose, &self.pose);
        if let Some(k) = self.k_y {
            scn.k_y = Some(k);
        }
        if let Some(e) = self.eps_end {
            scn.eps_end = Some(e);
        }
        if let Some(k) = self.left_torque_scale {
            scn.wheel_torque_scale[1] = k;
        }
        scn.validate()?;
        Ok(scn)
    }
}
