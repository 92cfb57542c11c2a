//! Telemetry into the logs: each frame with the tracking group becomes a
//! [`TraceSample`] row with the columns of `hil-sim run --csv` (the
//! conversion is ros-mcap's, shared with the MCAP log), and, with
//! `record --mcap`, a [`ros_mcap::LogFrame`] on the ROS 2 topics.
//! Time in the rows is the reference time since arming. What the robot
//! cannot know is `NaN`: the true fault `f_true_*`, and the estimator
//! columns when that telemetry group is off. The pose is the robot's
//! estimate of G. `wmr record` and `wmr metrics` live here too.

use crate::link::{Link, LinkError};
use crate::session::{self, expect_cause, ClockTracker, Motion, Stop, TelemetryStream};
use clap::Args;
use serde::Serialize;
use std::io::Write;
use std::path::PathBuf;
use track_log::TraceSample;
use wmr_protocol::{Event, Reply, RunStateMsg, StopCode, Telemetry};

/// `record` options.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// Robot time to record [s].
    #[arg(long, value_name = "S")]
    pub seconds: f64,
    /// CSV file to write.
    #[arg(long, value_name = "FILE.csv")]
    pub out: PathBuf,
    /// Telemetry rate [Hz].
    #[arg(long, default_value_t = 100)]
    pub rate: u16,
    /// Arm when recording starts and record reference time [0, S) of the run.
    #[arg(long)]
    pub arm: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Also write a ROS 2 MCAP log of every telemetry frame (/odom, /tf,
    /// /joint_states, /diagnostics, /wmr/tracking: ros-mcap/README.md).
    #[arg(long, value_name = "FILE.mcap")]
    pub mcap: Option<PathBuf>,
    /// d, G ahead of the axle midpoint, for the MCAP's base_link [m]
    /// [default: body.com_offset_m of the robot file the robot runs, read
    /// from its store; the paper robot's 0.05 when it cannot tell].
    #[arg(long, value_name = "M", value_parser = ros_mcap::parse_com_offset_m)]
    pub com_offset_m: Option<f64>,
}

/// The metrics summary of `record` (one JSON object on stdout).
#[derive(Debug, Serialize)]
pub struct RecordSummary {
    /// Rows written.
    pub rows: usize,
    /// Telemetry frames missing (gaps in their sequence numbers).
    pub dropped_frames: u64,
    /// Reference time covered [s].
    pub duration_s: f64,
    /// The CSV file.
    pub csv: String,
    /// The MCAP file, with `--mcap`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mcap: Option<String>,
    /// The log's report (`None` under two rows): `metrics` with a window
    /// that fits the path that ran (`window_s`, the log's span), the lag
    /// at the end (`end_lag_s`, `end_offset_m`) and the `health` shares.
    #[serde(flatten)]
    pub report: Option<track_log::LogReport>,
}

/// `metrics` options.
#[derive(Debug, Args)]
pub struct MetricsArgs {
    /// `wmr record`'s CSV or MCAP, `hil-sim run --csv` or `--mcap`.
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
}

/// What `wmr metrics` prints (one JSON object).
#[derive(Debug, Serialize)]
pub struct MetricsSummary {
    /// Rows of the log (running or stopping).
    pub rows: usize,
    /// Reference time covered [s].
    pub duration_s: f64,
    /// The log's report, as `record` prints it.
    #[serde(flatten)]
    pub report: Option<track_log::LogReport>,
}

/// The metrics of a log file, CSV or MCAP.
pub fn metrics_of_file(path: &std::path::Path) -> Result<MetricsSummary, ros_mcap::LogError> {
    let rows = ros_mcap::read_log(path)?;
    Ok(MetricsSummary {
        rows: rows.len(),
        duration_s: match (rows.first(), rows.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        },
        report: track_log::log_report(&rows),
    })
}

/// The row of one telemetry frame; `None` without the tracking group or
/// outside a run (hold, latched stop).
pub fn trace_sample(t: &Telemetry) -> Option<TraceSample> {
    if !matches!(t.state, RunStateMsg::Running | RunStateMsg::Stopping) {
        return None;
    }
    ros_mcap::sample_of_telemetry(t)
}

/// Records telemetry; returns the summary it prints.
pub fn record(a: &RecordArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    if !(a.seconds.is_finite() && a.seconds > 0.0) {
        return Err(LinkError::Io("--seconds must be > 0".into()));
    }
    if a.rate == 0 || a.rate > 1000 {
        return Err(LinkError::Io("--rate must be in 1..=1000 Hz".into()));
    }
    let file = std::fs::File::create(&a.out)
        .map_err(|e| LinkError::Io(format!("cannot create {}: {e}", a.out.display())))?;
    // The MCAP log: its geometry from the handshake and the robot's file
    // (d), stamps from robot time through the clock offset measured now
    // (ros_mcap::TimeMap).
    let mut mcap = match &a.mcap {
        None => None,
        Some(path) => {
            let robot = session::hello(link)?.robot;
            let d = session::com_offset_m(link, a.com_offset_m)?;
            if !a.quiet || matches!(d.source, session::ComOffsetSource::PaperDefault(_)) {
                eprintln!("base_link: {d}");
            }
            let geometry = ros_mcap::Geometry::new(
                robot.wheel_radius_m as f64,
                robot.half_track_m as f64,
                d.com_offset_m,
            )
            .map_err(|e| LinkError::Io(e.to_string()))?;
            let log = ros_mcap::McapLog::create(path, geometry, "wmr record")
                .map_err(|e| LinkError::Io(e.to_string()))?;
            let clock = ClockTracker::start(link, robot.control_period_s, 1)?;
            Some((log, clock.time_map(), path))
        }
    };
    let mut last_stop: Option<StopCode> = None;
    let mut stream = TelemetryStream::start(link, a.rate)?;
    if a.arm {
        Motion::Arm.send(link)?;
    }
    let total_ms = (a.seconds * 1e3) as u64;
    let pb = if a.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        let pb = indicatif::ProgressBar::with_draw_target(
            Some(total_ms),
            indicatif::ProgressDrawTarget::stderr(),
        );
        if let Ok(style) = indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} ms robot time, {msg}",
        ) {
            pb.set_style(style.progress_chars("=> "));
        }
        pb
    };
    let mut first_us: Option<u32> = None;
    let mut rows = Vec::new();
    let mut seen_running = false;
    let mut ended: Option<Stop> = None;
    loop {
        // The stream keeps the link alive (the robot brakes after
        // link_timeout_ms of silence) and fails after 2 s without a frame.
        let next = match stream.next(link) {
            Ok(n) => n,
            Err(e) => {
                pb.abandon();
                return Err(e);
            }
        };
        match next {
            Some(Reply::Telemetry(t)) => {
                let t_us = *first_us.get_or_insert(t.t_robot_us);
                seen_running |= t.state == RunStateMsg::Running;
                if let Some((log, map, path)) = &mut mcap {
                    let stamp = map.host_ns(t.t_robot_us);
                    if let Some(f) = ros_mcap::LogFrame::of_telemetry(&t, stamp, last_stop) {
                        log.write(&f).map_err(|e| {
                            LinkError::Io(format!("cannot write {}: {e}", path.display()))
                        })?;
                    }
                }
                if let Some(row) = trace_sample(&t) {
                    rows.push(row);
                }
                // With --arm the recording covers reference time [0, S);
                // otherwise S of robot time from the first frame.
                let elapsed_ms = if a.arm {
                    rows.last()
                        .map_or(0, |r| (r.t_s * 1e3) as u64 + 1000 / a.rate as u64)
                } else {
                    t.t_robot_us.wrapping_sub(t_us) as u64 / 1000
                };
                pb.set_position(elapsed_ms.min(total_ms));
                pb.set_message(format!("{:?}, {} rows", t.state, rows.len()));
                if elapsed_ms >= total_ms {
                    break;
                }
                // The run ended and its event was lost: telemetry says so.
                if seen_running && matches!(t.state, RunStateMsg::Hold | RunStateMsg::Stopped) {
                    ended = Some(Stop {
                        state: t.state,
                        cause: None,
                    });
                    break;
                }
            }
            Some(Reply::Event(Event::StateChanged { state, cause }))
                if seen_running && matches!(state, RunStateMsg::Hold | RunStateMsg::Stopped) =>
            {
                ended = Some(Stop { state, cause });
                break;
            }
            Some(Reply::Event(Event::StateChanged { cause: Some(c), .. })) => last_stop = Some(c),
            _ => {}
        }
    }
    pb.finish_and_clear();
    // The cause of a stop seen only in telemetry: the status's last stop.
    if let Some(s) = &mut ended {
        if s.cause.is_none() {
            s.cause = session::status(link).ok().and_then(|st| st.last_stop);
        }
        eprintln!("the run ended: {s}");
    }
    let dropped = stream.dropped;
    stream.stop(link);
    track_log::csv::write_trace_csv(std::io::BufWriter::new(file), &rows)
        .map_err(|e| LinkError::Io(format!("cannot write {}: {e}", a.out.display())))?;
    if let Some((log, _, path)) = mcap {
        log.finish()
            .map_err(|e| LinkError::Io(format!("cannot write {}: {e}", path.display())))?;
    }
    let summary = RecordSummary {
        rows: rows.len(),
        dropped_frames: dropped,
        duration_s: match (rows.first(), rows.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        },
        csv: a.out.display().to_string(),
        mcap: a.mcap.as_ref().map(|p| p.display().to_string()),
        report: track_log::log_report(&rows),
    };
    if let Some(r) = &summary.report {
        eprintln!("{r}");
    }
    let json = serde_json::to_string(&summary).map_err(|e| LinkError::Io(e.to_string()))?;
    writeln!(out, "{json}").map_err(session::io)?;
    // With --arm the run is ours: only its end or a disarm is a success (the
    // log up to the stop is written either way).
    match ended {
        Some(s) if a.arm => expect_cause(
            s,
            &[StopCode::TrajectoryEnd, StopCode::Disarmed],
            "the recording",
        ),
        // Without --arm another client drives: a run ending by its own
        // end, a disarm or an expired velocity command is that client's
        // business; a safety stop or a lost link ended the recording early
        // and is not a success either (issue 31 item 6: it exited 0 after
        // 3.9 s of 15 s).
        Some(s) => expect_cause(
            s,
            &[
                StopCode::TrajectoryEnd,
                StopCode::Disarmed,
                StopCode::VelocityTimeout,
            ],
            "the run being recorded",
        ),
        None => Ok(()),
    }
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
            covariance: None,
        };
        assert!(trace_sample(&t).is_none());
        t.state = RunStateMsg::Running;
        let s = trace_sample(&t).unwrap();
        assert_eq!(s.pos_err_m, 5.0);
        assert_eq!(s.t_s, 1.5);
        assert!(s.f_true[0].is_nan() && s.rho_hat[0].is_nan());
    }
}
