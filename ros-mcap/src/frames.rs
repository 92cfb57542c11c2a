//! The ROS 2 messages of one sample, built in one place for both the MCAP
//! writer and a live ROS 2 bridge (`wmr-ros2`), so that a log and the
//! bridge's topics carry the same values: `/odom`, `/tf`, `/joint_states`,
//! `/wmr/tracking` on every frame and `/diagnostics` on a change and every
//! [`crate::DIAGNOSTICS_PERIOD_NS`].

use crate::msg::*;
use crate::{Geometry, TraceSample};
use wmr_protocol::{Counters, RunStateMsg, StopCode};

/// One sample of the robot or the simulator.
#[derive(Clone, Copy, Debug)]
pub struct LogFrame {
    /// Host Unix time of the sample \[ns\] (see [`crate::TimeMap`]).
    pub stamp_ns: u64,
    /// The tracking row (pose of G, as in the CSV).
    pub sample: TraceSample,
    /// PWM duty \[right, left\] (counts) when known.
    pub duty: Option<[i32; 2]>,
    /// An external pose was fused on this tick.
    pub external_pose: bool,
    /// The runtime flagged an input fault.
    pub input_fault: bool,
    /// State, stop and counters for `/diagnostics`.
    pub diag: DiagFrame,
    /// The robot estimator's covariance (telemetry group 8, protocol 5),
    /// when sent; without it `/odom` carries the fixed
    /// [`crate::POSE_COVARIANCE`] and [`crate::TWIST_COVARIANCE`].
    pub covariance: Option<EstimatorCovariance>,
}

/// The robot estimator's covariance of `base_link` (the axle midpoint).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimatorCovariance {
    /// Upper triangle of the covariance of (x, y, yaw), row by row: xx
    /// \[m²\], xy \[m²\], x·yaw \[m·rad\], yy \[m²\], y·yaw \[m·rad\], yaw·yaw
    /// \[rad²\].
    pub pose: [f64; 6],
    /// Variances of v \[(m/s)²\] and ω \[(rad/s)²\].
    pub twist: [f64; 2],
}

/// `/odom`'s pose and twist covariances (6×6, row major: x, y, z, roll,
/// pitch, yaw): the estimator's where the frame has them, in the x, y, yaw
/// rows and columns (v and ω for the twist), 10⁶ on the diagonal for what
/// a planar robot does not estimate (REP-105's "unknown"); the fixed
/// diagonals otherwise. The one place both the MCAP logs and the ROS 2
/// bridge fill them.
pub fn odom_covariances(c: Option<&EstimatorCovariance>) -> (Covariance, Covariance) {
    let Some(c) = c else {
        return (
            Covariance::diagonal(crate::POSE_COVARIANCE),
            Covariance::diagonal(crate::TWIST_COVARIANCE),
        );
    };
    const UNKNOWN: f64 = 1e6;
    // Row-major index of (i, j) in the 6×6; the planar axes x, y, yaw.
    let at = |i: usize, j: usize| 6 * i + j;
    let axes = [0, 1, 5];
    let mut pose = [0.0; 36];
    let mut twist = [0.0; 36];
    for i in [2, 3, 4] {
        pose[at(i, i)] = UNKNOWN;
    }
    for i in 1..5 {
        twist[at(i, i)] = UNKNOWN;
    }
    let mut k = 0;
    for a in 0..3 {
        for b in a..3 {
            let (i, j) = (axes[a], axes[b]);
            pose[at(i, j)] = c.pose[k];
            pose[at(j, i)] = c.pose[k];
            k += 1;
        }
    }
    twist[at(0, 0)] = c.twist[0];
    twist[at(5, 5)] = c.twist[1];
    (Covariance::from_array(pose), Covariance::from_array(twist))
}

/// What `/diagnostics` reports beyond the tracking row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiagFrame {
    /// Run state.
    pub state: RunStateMsg,
    /// The last stop's cause (events and status), if any seen.
    pub last_stop: Option<StopCode>,
    /// The link and runtime counters (telemetry group 4), if sent.
    pub counters: Option<Counters>,
}

/// The messages of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct RosMessages {
    /// `/odom`: `odom` → `base_link` (the axle midpoint), η as the twist.
    pub odom: Odometry,
    /// `/tf`: the same transform.
    pub tf: TfMessage,
    /// `/joint_states`: the wheels.
    pub joints: JointState,
    /// `/wmr/tracking`: the whole telemetry row (poses of G).
    pub tracking: Tracking,
    /// `/diagnostics`, when due (a change, or the period elapsed).
    pub diagnostics: Option<DiagnosticArray>,
}

impl RosMessages {
    /// Each message CDR-encoded with its index in [`crate::CHANNELS`]:
    /// `/odom`, `/tf`, `/joint_states`, `/wmr/tracking`, then
    /// `/diagnostics` when due.
    pub fn encoded(&self) -> Result<Vec<(usize, Vec<u8>)>, crate::LogError> {
        let e = |m: Result<Vec<u8>, String>| m.map_err(crate::LogError::Cdr);
        let mut out = vec![
            (0, e(encode(&self.odom))?),
            (1, e(encode(&self.tf))?),
            (2, e(encode(&self.joints))?),
            (3, e(encode(&self.tracking))?),
        ];
        if let Some(d) = &self.diagnostics {
            out.push((4, e(encode(d))?));
        }
        Ok(out)
    }
}

/// What makes a new `/diagnostics` message due at once.
#[derive(Clone, Copy, Debug, PartialEq)]
struct DiagKey {
    state: RunStateMsg,
    health: u8,
    reason: u8,
    stop: Option<StopCode>,
    input_fault: bool,
}

/// Turns frames, in time order, into messages: integrates the wheel
/// angles between frames and schedules `/diagnostics`.
#[derive(Clone, Debug)]
pub struct RosFrames {
    geometry: Geometry,
    wheel_angle_rad: [f64; 2],
    last: Option<(u64, [f64; 2])>,
    last_diag: Option<(u64, DiagKey)>,
}

impl RosFrames {
    /// For a robot of `geometry`, wheel angles from 0.
    pub fn new(geometry: Geometry) -> Self {
        Self {
            geometry,
            wheel_angle_rad: [0.0; 2],
            last: None,
            last_diag: None,
        }
    }

    /// The robot's geometry.
    pub fn geometry(&self) -> Geometry {
        self.geometry
    }

    /// The messages of the next frame.
    pub fn messages(&mut self, f: &LogFrame) -> RosMessages {
        let s = &f.sample;
        let stamp = Time::from_ns(f.stamp_ns);
        let header = |frame: &str| Header {
            stamp,
            frame_id: frame.to_string(),
        };
        // base_link = the axle midpoint.
        let b = self.geometry.axle_of(s.pose);
        let pose = Pose {
            position: Point {
                x: b[0],
                y: b[1],
                z: 0.0,
            },
            orientation: Quaternion::from_yaw(b[2]),
        };
        let (pose_cov, twist_cov) = odom_covariances(f.covariance.as_ref());
        let odom = Odometry {
            header: header(crate::FRAME_ODOM),
            child_frame_id: crate::FRAME_BASE.into(),
            pose: PoseWithCovariance {
                pose,
                covariance: pose_cov,
            },
            twist: TwistWithCovariance {
                twist: Twist {
                    linear: Vector3 {
                        x: s.eta[0],
                        y: 0.0,
                        z: 0.0,
                    },
                    angular: Vector3 {
                        x: 0.0,
                        y: 0.0,
                        z: s.eta[1],
                    },
                },
                covariance: twist_cov,
            },
        };
        let tf = TfMessage {
            transforms: vec![TransformStamped {
                header: header(crate::FRAME_ODOM),
                child_frame_id: crate::FRAME_BASE.into(),
                transform: Transform {
                    translation: Vector3 {
                        x: b[0],
                        y: b[1],
                        z: 0.0,
                    },
                    rotation: pose.orientation,
                },
            }],
        };
        // Wheel angles: the trapezoidal integral of the rates between frames.
        let rates = if s.eta.iter().all(|v| v.is_finite()) {
            self.geometry.wheel_rates(s.eta)
        } else {
            [0.0; 2]
        };
        if let Some((t, prev)) = self.last {
            let dt = f.stamp_ns.saturating_sub(t) as f64 * 1e-9;
            for i in 0..2 {
                self.wheel_angle_rad[i] += 0.5 * (prev[i] + rates[i]) * dt;
            }
        }
        self.last = Some((f.stamp_ns, rates));
        let joints = JointState {
            header: header(""),
            name: crate::WHEEL_JOINTS.iter().map(|n| n.to_string()).collect(),
            position: self.wheel_angle_rad.to_vec(),
            velocity: rates.to_vec(),
            effort: s.torque_nm.to_vec(),
        };
        let tracking = tracking_of(f, header(crate::FRAME_ODOM));
        let key = DiagKey {
            state: f.diag.state,
            health: s.health,
            reason: s.health_reason,
            stop: f.diag.last_stop,
            input_fault: f.input_fault,
        };
        let due = match self.last_diag {
            None => true,
            Some((t, k)) => {
                k != key || f.stamp_ns.saturating_sub(t) >= crate::DIAGNOSTICS_PERIOD_NS
            }
        };
        let diagnostics = due.then(|| {
            self.last_diag = Some((f.stamp_ns, key));
            DiagnosticArray {
                header: header(""),
                status: vec![diagnostic_status(f)],
            }
        });
        RosMessages {
            odom,
            tf,
            joints,
            tracking,
            diagnostics,
        }
    }
}

/// The `/wmr/tracking` message of a frame.
pub(crate) fn tracking_of(f: &LogFrame, header: Header) -> Tracking {
    let s = &f.sample;
    Tracking {
        header,
        t_s: s.t_s,
        state: f.diag.state as u8,
        ref_pose: s.ref_pose,
        pose: s.pose,
        pos_err_m: s.pos_err_m,
        err_xy_m: s.err_xy_m,
        e: s.e,
        eta: s.eta,
        eta_c: s.eta_c,
        torque_nm: s.torque_nm,
        duty: f.duty.map_or([f64::NAN; 2], |d| [d[0] as f64, d[1] as f64]),
        s: s.s,
        rho_hat: s.rho_hat,
        d_hat: s.d_hat,
        f_hat: s.f_hat,
        f_true: s.f_true,
        saturated: s.saturated,
        time_scale: s.time_scale,
        tau_s: s.tau_s,
        health: s.health,
        health_reason: s.health_reason,
        external_pose: f.external_pose,
        input_fault: f.input_fault,
    }
}

/// The name of a health mode (0 nominal, 1 degraded, 2 safe stop).
pub fn health_name(h: u8) -> &'static str {
    match h {
        0 => "nominal",
        1 => "degraded",
        2 => "safe stop",
        _ => "unknown",
    }
}

/// The one status of the robot: level OK when running nominally or at
/// rest without a latched stop, WARN when degraded, ERROR in a latched stop
/// or a safe stop.
pub fn diagnostic_status(f: &LogFrame) -> DiagnosticStatus {
    let s = &f.sample;
    let reason = track_log::HEALTH_REASONS
        .get(s.health_reason as usize)
        .copied()
        .unwrap_or("unknown");
    let stop = f
        .diag
        .last_stop
        .map_or_else(|| "none".to_string(), |c| format!("{c:?}"));
    let level = if f.diag.state == RunStateMsg::Stopped || s.health >= 2 {
        DiagnosticStatus::ERROR
    } else if s.health == 1 || f.input_fault {
        DiagnosticStatus::WARN
    } else {
        DiagnosticStatus::OK
    };
    let mut values = Vec::new();
    let mut kv = |k: &str, v: String| {
        values.push(KeyValue {
            key: k.to_string(),
            value: v,
        })
    };
    kv("state", format!("{:?}", f.diag.state));
    kv("health", health_name(s.health).to_string());
    kv("health_reason", reason.to_string());
    kv("last_stop", stop.clone());
    kv("input_fault", f.input_fault.to_string());
    kv("f_hat_v_mps", s.f_hat[0].to_string());
    kv("f_hat_omega_radps", s.f_hat[1].to_string());
    kv("rho_hat_v", s.rho_hat[0].to_string());
    kv("rho_hat_omega", s.rho_hat[1].to_string());
    kv("d_hat_v", s.d_hat[0].to_string());
    kv("d_hat_omega", s.d_hat[1].to_string());
    kv("time_scale", s.time_scale.to_string());
    if let Some(c) = f.diag.counters {
        for (k, v) in counter_values(&c) {
            kv(k, v.to_string());
        }
    }
    DiagnosticStatus {
        level,
        name: "wmr: robot".into(),
        message: format!(
            "{:?}, {} ({reason}), last stop {stop}",
            f.diag.state,
            health_name(s.health)
        ),
        hardware_id: "wmr".into(),
        values,
    }
}

/// Every counter by its protocol name (book/src/reference/protocol.md).
pub fn counter_values(c: &Counters) -> [(&'static str, u32); 15] {
    [
        ("ticks", c.ticks),
        ("run_ticks", c.run_ticks),
        ("overruns", c.overruns),
        ("max_loop_time_us", c.max_loop_time_us),
        ("encoder_jumps", c.encoder_jumps),
        ("input_faults", c.input_faults),
        ("torque_saturated", c.torque_saturated),
        ("duty_saturated", c.duty_saturated),
        ("external_poses", c.external_poses),
        ("stops", c.stops),
        ("rx_frames", c.rx_frames),
        ("rx_errors", c.rx_errors),
        ("rx_overflow", c.rx_overflow),
        ("tx_dropped", c.tx_dropped),
        ("nacks", c.nacks),
    ]
}
