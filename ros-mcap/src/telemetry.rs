//! A robot's telemetry frame as a log frame: the tracking group is the
//! trace row (the columns of `hil-sim run --csv`), the estimator group its
//! estimator columns (`NaN` with that group off), the counters group the
//! diagnostics' counters. What the robot cannot know is `NaN`: the true
//! fault `f_true`. The pose is the robot's estimate of G.

use crate::{DiagFrame, EstimatorCovariance, LogFrame, TraceSample};
use wmr_protocol::{PoseMsg, StopCode, Telemetry};

/// The trace row of a telemetry frame, whatever the run state; `None`
/// without the tracking group.
pub fn sample_of_telemetry(t: &Telemetry) -> Option<TraceSample> {
    let tr = t.tracking?;
    let f = |a: [f32; 2]| [a[0] as f64, a[1] as f64];
    let nan = [f64::NAN; 2];
    let p = |p: PoseMsg| [p.x_m as f64, p.y_m as f64, p.theta_rad as f64];
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

impl LogFrame {
    /// The frame of telemetry `t` taken at host Unix time `stamp_ns`, with
    /// the last stop the host has seen; `None` without the tracking group.
    pub fn of_telemetry(t: &Telemetry, stamp_ns: u64, last_stop: Option<StopCode>) -> Option<Self> {
        let sample = sample_of_telemetry(t)?;
        Some(Self {
            stamp_ns,
            sample,
            duty: t.tracking.map(|tr| tr.duty),
            external_pose: t.estimators.is_some_and(|e| e.external_pose),
            input_fault: t.estimators.is_some_and(|e| e.input_fault),
            diag: DiagFrame {
                state: t.state,
                last_stop,
                counters: t.counters,
            },
            covariance: t.covariance.map(|c| EstimatorCovariance {
                pose: c.pose_f32().map(f64::from),
                twist: c.twist_f32().map(f64::from),
            }),
        })
    }
}
