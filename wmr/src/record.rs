//! Telemetry into the one log format: each frame with the tracking group
//! becomes a [`TraceSample`] row with the columns of `hil-sim run --csv`.
//! Time is the reference time since arming. What the robot cannot know is
//! `NaN`: the true fault `f_true_*`, and the estimator columns when that
//! telemetry group is off. The pose is the robot's estimate.

use track_log::TraceSample;
use wmr_protocol::{RunStateMsg, Telemetry};

/// The row of one telemetry frame; `None` without the tracking group or
/// outside a run (hold, latched stop).
pub fn trace_sample(t: &Telemetry) -> Option<TraceSample> {
    if !matches!(t.state, RunStateMsg::Running | RunStateMsg::Stopping) {
        return None;
    }
    let tr = t.tracking?;
    let f = |a: [f32; 2]| [a[0] as f64, a[1] as f64];
    let nan = [f64::NAN; 2];
    let p = |p: wmr_protocol::PoseMsg| [p.x_m as f64, p.y_m as f64, p.theta_rad as f64];
    let (pose, rp) = (p(tr.pose), p(tr.ref_pose));
    let err = [rp[0] - pose[0], rp[1] - pose[1]];
    let est = t.estimators;
    Some(TraceSample {
        t_s: t.t_ref_s as f64,
        ref_pose: rp,
        pose,
        pos_err_m: (err[0] * err[0] + err[1] * err[1]).sqrt(),
        err_xy_m: err,
        e: [tr.error[0] as f64, tr.error[1] as f64, tr.error[2] as f64],
        eta: f(tr.eta),
        eta_c: f(tr.eta_c),
        torque_nm: f(tr.torque_nm),
        s: est.map_or(nan, |e| f(e.s)),
        rho_hat: est.map_or(nan, |e| f(e.rho_hat)),
        d_hat: est.map_or(nan, |e| f(e.d_hat)),
        f_hat: est.map_or(nan, |e| f(e.f_hat)),
        f_true: nan,
        saturated: tr.saturated,
        time_scale: tr.time_scale as f64,
        tau_s: tr.tau_s as f64,
        health: tr.health,
        health_reason: tr.health_reason,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use wmr_protocol::{PoseMsg, TrackingTelemetry};

    #[test]
    fn rows_only_while_running_with_the_position_error() {
        let mut t = Telemetry {
            seq: 0,
            t_robot_us: 0,
            t_ref_s: 1.5,
            state: RunStateMsg::Hold,
            tracking: Some(TrackingTelemetry {
                pose: PoseMsg {
                    x_m: 1.0,
                    y_m: 1.0,
                    theta_rad: 0.0,
                },
                ref_pose: PoseMsg {
                    x_m: 4.0,
                    y_m: 5.0,
                    theta_rad: 0.0,
                },
                ..Default::default()
            }),
            estimators: None,
            counters: None,
        };
        assert!(trace_sample(&t).is_none());
        t.state = RunStateMsg::Running;
        let s = trace_sample(&t).unwrap();
        assert_eq!(s.pos_err_m, 5.0);
        assert_eq!(s.t_s, 1.5);
        assert!(s.f_true[0].is_nan() && s.rho_hat[0].is_nan());
    }
}
