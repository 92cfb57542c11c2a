//! The identification log: one row per telemetry frame of a run, with what
//! the fit needs and the trace CSV (`track-log`) does not carry: both wheel
//! rates, the signed PWM duties and whether an external pose was fused.
//!
//! Every column comes from the existing telemetry (no protocol change,
//! D81): the wheel rates are the measured η = \[r(φ̇_R + φ̇_L)/2,
//! r(φ̇_R − φ̇_L)/(2h)\] inverted with the r and h the robot announces in
//! its handshake (the same numbers it formed η with, so the inversion is
//! exact to f32 rounding, whatever the true radii are), the duties are the
//! tracking group's `duty`, the pose is the robot's fused estimate (its
//! heading integrates the gyro minus its estimated bias when a gyro is
//! fitted; its position follows the external poses when they come).
//!
//! CSV: the header [`ID_CSV_HEADER`], then one row per [`IdRow`]; lines
//! starting with `#` are comments.

use std::io::{self, BufRead, Write};
use wmr_protocol::{RobotInfo, RunStateMsg, Telemetry};

/// One row of the identification log.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IdRow {
    /// Reference time since arming \[s\] (a multiple of the control period).
    pub t_s: f64,
    /// Measured wheel rates `[right, left]` \[rad/s\] (the runtime's
    /// windowed estimate from the encoder counts).
    pub wheel_rate_radps: [f64; 2],
    /// Signed PWM duty `[right, left]` \[counts\] written this tick (NaN: unknown).
    pub duty: [f64; 2],
    /// Commanded wheel torques `[right, left]` \[N·m\].
    pub torque_nm: [f64; 2],
    /// The robot's fused pose of G \[x m, y m, θ rad\].
    pub pose: [f64; 3],
    /// An external pose measurement was fused this tick.
    pub external_pose: bool,
    /// The torque request was clamped this tick.
    pub saturated: bool,
}

/// Header of the identification CSV.
pub const ID_CSV_HEADER: &str = "t_s,wheel_rate_r_radps,wheel_rate_l_radps,duty_r,duty_l,\
tau_r_nm,tau_l_nm,x_m,y_m,theta_rad,external_pose,saturated";

const COLUMNS: usize = 12;

/// Builds rows from successive telemetry frames of one run: at a
/// telemetry rate below the loop rate the per-tick `external_pose` flag of
/// a frame misses the poses fused on the ticks between frames, so a row's
/// flag is also set when the counters group's `external_poses` count grew
/// since the previous frame.
#[derive(Clone, Copy, Debug)]
pub struct RowBuilder {
    info: RobotInfo,
    last_external: Option<u32>,
}

impl RowBuilder {
    /// A builder for the robot that announced `info` in its handshake.
    pub fn new(info: RobotInfo) -> Self {
        Self {
            info,
            last_external: None,
        }
    }

    /// The row of the next frame ([`IdRow::from_telemetry`]).
    pub fn row(&mut self, t: &Telemetry) -> Option<IdRow> {
        let count = t.counters.map(|c| c.external_poses);
        let grew = matches!((self.last_external, count), (Some(a), Some(b)) if b != a);
        if count.is_some() {
            self.last_external = count;
        }
        IdRow::from_telemetry(t, &self.info).map(|mut r| {
            r.external_pose |= grew;
            r
        })
    }
}

impl IdRow {
    /// The row of one telemetry frame of a run (running or braking, with
    /// the tracking group), wheel rates from η with the robot's announced
    /// geometry `info`; `None` otherwise.
    pub fn from_telemetry(t: &Telemetry, info: &RobotInfo) -> Option<Self> {
        if !matches!(t.state, RunStateMsg::Running | RunStateMsg::Stopping) {
            return None;
        }
        let tr = t.tracking?;
        let (r, h) = (info.wheel_radius_m as f64, info.half_track_m as f64);
        let (v, w) = (tr.eta[0] as f64, tr.eta[1] as f64);
        Some(Self {
            t_s: t.t_ref_s as f64,
            wheel_rate_radps: [(v + h * w) / r, (v - h * w) / r],
            duty: [tr.duty[0] as f64, tr.duty[1] as f64],
            torque_nm: [tr.torque_nm[0] as f64, tr.torque_nm[1] as f64],
            pose: [
                tr.pose.x_m as f64,
                tr.pose.y_m as f64,
                tr.pose.theta_rad as f64,
            ],
            external_pose: t.estimators.is_some_and(|e| e.external_pose),
            saturated: tr.saturated,
        })
    }
}

/// Writes the header, the comment lines `comments` and the rows.
pub fn write_id_csv(mut w: impl Write, comments: &[String], rows: &[IdRow]) -> io::Result<()> {
    for c in comments {
        writeln!(w, "# {c}")?;
    }
    writeln!(w, "{ID_CSV_HEADER}")?;
    for r in rows {
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{},{},{}",
            r.t_s,
            r.wheel_rate_radps[0],
            r.wheel_rate_radps[1],
            r.duty[0],
            r.duty[1],
            r.torque_nm[0],
            r.torque_nm[1],
            r.pose[0],
            r.pose[1],
            r.pose[2],
            u8::from(r.external_pose),
            u8::from(r.saturated)
        )?;
    }
    Ok(())
}

/// Reads an identification CSV; `origin` names the source in errors.
pub fn read_id_csv(r: impl BufRead, origin: &str) -> Result<Vec<IdRow>, String> {
    let mut header_seen = false;
    let mut out = Vec::new();
    for (i, line) in r.lines().enumerate() {
        let line = line.map_err(|e| format!("{origin}: {e}"))?;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if !header_seen {
            if line != ID_CSV_HEADER {
                return Err(format!(
                    "{origin}:{}: not an identification log (header differs from `wmr identify run`'s)",
                    i + 1
                ));
            }
            header_seen = true;
            continue;
        }
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != COLUMNS {
            return Err(format!(
                "{origin}:{}: {} columns, expected {COLUMNS}",
                i + 1,
                cells.len()
            ));
        }
        let mut v = [0.0f64; COLUMNS];
        for (k, c) in cells.iter().enumerate() {
            v[k] = c.trim().parse().map_err(|_| {
                format!(
                    "{origin}:{}: column {} is not a number: {c:?}",
                    i + 1,
                    k + 1
                )
            })?;
        }
        out.push(IdRow {
            t_s: v[0],
            wheel_rate_radps: [v[1], v[2]],
            duty: [v[3], v[4]],
            torque_nm: [v[5], v[6]],
            pose: [v[7], v[8], v[9]],
            external_pose: v[10] != 0.0,
            saturated: v[11] != 0.0,
        });
    }
    if !header_seen {
        return Err(format!("{origin}: empty file"));
    }
    Ok(out)
}

/// Rows from a trace CSV (`hil-sim run --csv`, `wmr record`: track-log's
/// format), which has no duties (the fit then uses the torque form) and η
/// instead of the wheel rates: they are recovered with the r and h of
/// `robot`, which must be the robot the log's η was formed with.
/// `pose_measured`: the trace's pose is a measurement of the true pose
/// (hil-sim's traces log the true pose of G), not the robot's own estimate
/// (`wmr record`), so it carries the length scale.
pub fn rows_from_trace(
    trace: &[track_log::TraceSample],
    robot: &controller_core::RobotParams,
    pose_measured: bool,
) -> Vec<IdRow> {
    let (r, h) = (robot.wheel_radius_m as f64, robot.half_track_m as f64);
    trace
        .iter()
        .map(|s| IdRow {
            t_s: s.t_s,
            wheel_rate_radps: [(s.eta[0] + h * s.eta[1]) / r, (s.eta[0] - h * s.eta[1]) / r],
            duty: [f64::NAN; 2],
            torque_nm: s.torque_nm,
            pose: s.pose,
            external_pose: pose_measured,
            saturated: s.saturated,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use wmr_protocol::{PoseMsg, TrackingTelemetry};

    /// Wheel rates recovered from η by the announced geometry are those
    /// that η was formed from (controller-core's forward map), and the CSV
    /// reads back what it wrote.
    #[test]
    fn wheel_rates_from_eta_and_csv_round_trip() {
        let p = controller_core::RobotParams::paper();
        let rates = [3.25f32, -1.5];
        let eta = p.eta_from_wheel_rates(rates);
        let info = RobotInfo {
            wheel_radius_m: p.wheel_radius_m,
            half_track_m: p.half_track_m,
            mass_kg: p.mass_kg,
            control_period_s: 1e-3,
            torque_limit_nm: 10.0,
        };
        let t = Telemetry {
            seq: 0,
            t_robot_us: 0,
            t_ref_s: 0.5,
            state: RunStateMsg::Running,
            tracking: Some(TrackingTelemetry {
                pose: PoseMsg {
                    x_m: 1.0,
                    y_m: 2.0,
                    theta_rad: 0.3,
                },
                eta: [eta.v_mps, eta.omega_radps],
                duty: [120, -340],
                ..Default::default()
            }),
            estimators: None,
            counters: None,
            covariance: None,
        };
        let row = IdRow::from_telemetry(&t, &info).unwrap();
        for (got, want) in row.wheel_rate_radps.iter().zip(rates) {
            assert!((got - want as f64).abs() < 1e-5);
        }
        assert_eq!(row.duty, [120.0, -340.0]);
        let mut buf = Vec::new();
        write_id_csv(&mut buf, &["robot r = 0.1".into()], &[row, row]).unwrap();
        let back = read_id_csv(&buf[..], "mem").unwrap();
        assert_eq!(back, vec![row, row]);
        assert!(read_id_csv(&b"a,b\n1,2\n"[..], "x")
            .unwrap_err()
            .contains("header"));
        let hold = Telemetry {
            state: RunStateMsg::Hold,
            ..t
        };
        assert!(IdRow::from_telemetry(&hold, &info).is_none());
    }

    /// At a telemetry rate below the loop rate the per-tick flag misses the
    /// poses fused between frames: the builder flags a row when the
    /// counters' `external_poses` grew (every frame here has the flag off;
    /// the count grows on the second and fourth). Without the counter the
    /// log of a 500 Hz run had no external pose at all (D81).
    #[test]
    fn external_poses_between_frames_are_flagged() {
        let info = RobotInfo {
            wheel_radius_m: 0.1,
            half_track_m: 0.2,
            mass_kg: 15.0,
            control_period_s: 1e-3,
            torque_limit_nm: 10.0,
        };
        let frame = |n: u32| Telemetry {
            seq: n,
            t_robot_us: 2000 * n,
            t_ref_s: 0.002 * n as f32,
            state: RunStateMsg::Running,
            tracking: Some(TrackingTelemetry::default()),
            estimators: Some(wmr_protocol::EstimatorTelemetry::default()),
            counters: Some(wmr_protocol::Counters {
                external_poses: [5, 6, 6, 7, 7][n as usize],
                ..Default::default()
            }),
            covariance: None,
        };
        let mut b = RowBuilder::new(info);
        let flags: Vec<bool> = (0..5)
            .map(|n| b.row(&frame(n)).unwrap().external_pose)
            .collect();
        assert_eq!(flags, [false, true, false, true, false]);
    }
}
