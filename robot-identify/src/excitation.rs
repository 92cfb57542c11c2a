//! The identification run's reference as timed waypoints (`wmr upload`'s
//! streaming path: no protocol change, D80), and its safety checks against
//! the robot's limits.

use controller_core::trajectory::Excitation;
use controller_core::{Pose, ReducedModel, RobotParams};
use wmr_protocol::{PoseMsg, Waypoint};

/// Waypoint spacing of the uploaded excitation \[s\]: 40 per second keep
/// the cubic Hermite between them within 1 mm of the excitation's path,
/// and its yaw rate where the excitation reverses within 1.2x of the
/// excitation's own peak. At 20 per second the Hermite curve between two
/// waypoints straddling a reversal swept its heading at up to 16.8 rad/s
/// (the excitation's peak: 2.7 rad/s), beyond the 2 kg robot's 12.9 rad/s
/// top yaw rate: the device's segment check (issue 31) refused it.
pub const WAYPOINT_SPACING_S: f32 = 0.025;

/// Peak quantities of an excitation for a robot model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExcitationPeaks {
    /// max |v| \[m/s\].
    pub speed_mps: f32,
    /// max |ω| \[rad/s\].
    pub yaw_rate_radps: f32,
    /// max wheel torque the nominal model asks, N⁻¹(η̇ − Mη) \[N·m\].
    pub torque_nm: f32,
    /// Largest distance from the start \[m\].
    pub excursion_m: f32,
}

/// Peaks of `ex` driven by the robot `robot` from the origin.
pub fn peaks(ex: &Excitation, robot: &RobotParams) -> Result<ExcitationPeaks, String> {
    let model = ReducedModel::new(robot).map_err(|e| format!("robot: {e:?}"))?;
    let mut p = ExcitationPeaks {
        speed_mps: 0.0,
        yaw_rate_radps: 0.0,
        torque_nm: 0.0,
        excursion_m: 0.0,
    };
    for (_, s) in ex.samples(Pose::new(0.0, 0.0, 0.0), 0.005) {
        p.speed_mps = p.speed_mps.max(s.v_mps.abs());
        p.yaw_rate_radps = p.yaw_rate_radps.max(s.omega_radps.abs());
        let m = model.m_eta([s.v_mps, s.omega_radps]);
        let tau = model.n_inv_mul([s.v_dot_mps2 - m[0], s.omega_dot_radps2 - m[1]]);
        p.torque_nm = p.torque_nm.max(tau[0].abs()).max(tau[1].abs());
        p.excursion_m = p.excursion_m.max(s.pose.x_m.hypot(s.pose.y_m));
    }
    Ok(p)
}

/// The excitation as waypoints every [`WAYPOINT_SPACING_S`], starting at
/// `start`.
pub fn waypoints(ex: &Excitation, start: Pose) -> Vec<Waypoint> {
    // Integrate finely, keep every waypoint spacing.
    let fine = 0.005f32;
    let every = (WAYPOINT_SPACING_S / fine).round() as usize;
    ex.samples(start, fine)
        .step_by(every)
        .map(|(t, s)| Waypoint {
            t_s: t,
            pose: PoseMsg {
                x_m: s.pose.x_m,
                y_m: s.pose.y_m,
                theta_rad: s.pose.theta_rad,
            },
            v_mps: s.v_mps,
            omega_radps: s.omega_radps,
        })
        .collect()
}

/// Checks that `ex` is safe for a robot: speed and yaw rate within the
/// given tops, the nominal torque at most `torque_fraction` of the limit,
/// the travel within `area_radius_m`. The error says which bound fails.
pub fn check(
    ex: &Excitation,
    robot: &RobotParams,
    top_speed_mps: f32,
    top_yaw_rate_radps: f32,
    torque_limit_nm: f32,
    torque_fraction: f32,
    area_radius_m: f32,
) -> Result<ExcitationPeaks, String> {
    ex.validate().map_err(|_| {
        "excitation parameters must be finite and > 0, with duration > 2·ramp".to_string()
    })?;
    let p = peaks(ex, robot)?;
    if p.speed_mps > top_speed_mps {
        return Err(format!(
            "peak speed {:.3} m/s above the robot's {top_speed_mps:.3}",
            p.speed_mps
        ));
    }
    if p.yaw_rate_radps > top_yaw_rate_radps {
        return Err(format!(
            "peak yaw rate {:.3} rad/s above the robot's {top_yaw_rate_radps:.3}",
            p.yaw_rate_radps
        ));
    }
    if p.torque_nm > torque_fraction * torque_limit_nm {
        return Err(format!(
            "the model asks {:.2} N·m per wheel, above {:.0} % of the {torque_limit_nm} N·m limit (lower the amplitudes or the frequency)",
            p.torque_nm,
            100.0 * torque_fraction
        ));
    }
    if p.excursion_m > area_radius_m {
        return Err(format!(
            "the run leaves a {area_radius_m} m radius ({:.2} m from the start)",
            p.excursion_m
        ));
    }
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default excitation for the paper robot stays within a 2.5 m
    /// radius and asks a fraction of the 10 N·m limit; the waypoints are
    /// spaced as stated and start at rest at the start pose.
    #[test]
    fn default_excitation_is_safe_for_the_paper_robot() {
        let ex = Excitation::for_limits(1.0, 2.0);
        let p = check(&ex, &RobotParams::paper(), 1.0, 2.0, 10.0, 0.5, 2.5).unwrap();
        assert!(p.speed_mps <= 0.5 + 1e-6 && p.yaw_rate_radps <= 1.0 + 1e-6);
        assert!(p.torque_nm > 0.1, "{p:?}");
        let w = waypoints(&ex, Pose::new(0.5, -0.5, 1.0));
        assert_eq!(w.len(), 2401);
        assert!((w[1].t_s - WAYPOINT_SPACING_S).abs() < 1e-6);
        assert_eq!((w[0].pose.x_m, w[0].pose.y_m, w[0].v_mps), (0.5, -0.5, 0.0));
        let e = check(&ex, &RobotParams::paper(), 1.0, 2.0, 0.1, 0.5, 2.5).unwrap_err();
        assert!(e.contains("N·m"), "{e}");
        let e = check(&ex, &RobotParams::paper(), 0.3, 2.0, 10.0, 0.5, 2.5).unwrap_err();
        assert!(e.contains("speed"), "{e}");
    }
}
