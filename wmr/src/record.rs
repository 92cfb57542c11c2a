//! Telemetry into the logs: each frame with the tracking group becomes a
//! [`TraceSample`] row with the columns of `hil-sim run --csv` (the
//! conversion is ros-mcap's, shared with the MCAP log), and, with
//! `record --mcap`, a [`ros_mcap::LogFrame`] on the ROS 2 topics.
//! Time in the rows is the reference time since arming. What the robot
//! cannot know is `NaN`: the true fault `f_true_*`, and the estimator
//! columns when that telemetry group is off. The pose is the robot's
//! estimate of G.

use track_log::TraceSample;
use wmr_protocol::{RunStateMsg, Telemetry};

/// The row of one telemetry frame; `None` without the tracking group or
/// outside a run (hold, latched stop).
pub fn trace_sample(t: &Telemetry) -> Option<TraceSample> {
    if !matches!(t.state, RunStateMsg::Running | RunStateMsg::Stopping) {
        return None;
    }
    ros_mcap::sample_of_telemetry(t)
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
