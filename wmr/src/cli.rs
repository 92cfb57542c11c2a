//! The `wmr` command line. Everything is library code ([`execute`]) so
//! tests drive it in-process over a pseudo-terminal.

use crate::link::{Link, LinkError};
use crate::record::trace_sample;
use crate::upload::{parse_upload, segments, Upload};
use crate::watch::{Stop, Watch};
use clap::{Args, Parser, Subcommand};
use serde::Serialize;
use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use wmr_protocol::{
    ErrorCode, Event, Reply, Request, RunStateMsg, StatusMsg, StopCode, TELEMETRY_ALL,
};

/// Host tool for the trajectory-tracking robot (and `hil-sim device --pty`).
#[derive(Debug, Parser)]
#[command(name = "wmr", version, about, long_about = None)]
pub struct Cli {
    /// Serial port or pseudo-terminal of the robot.
    #[arg(long, global = true, env = "WMR_PORT", value_name = "PATH")]
    pub port: Option<String>,
    /// Talk to the robot through the `wmr serve` listening on this socket
    /// [default: the server of --port when one runs, else --port itself].
    #[arg(long, global = true, env = "WMR_SERVE", value_name = "SOCKET")]
    pub serve: Option<PathBuf>,
    /// How long to wait for each answer before sending the request again [ms]
    /// [default: a fifth of the robot's link_timeout_ms, 100 ms for its 500].
    #[arg(long, global = true, value_name = "MS", value_parser = clap::value_parser!(u64).range(1..=60_000))]
    pub timeout_ms: Option<u64>,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Handshake, state, mode and every counter.
    Status,
    /// Start driving the loaded reference or velocity mode.
    Arm,
    /// Stop driving (motors off, not latched).
    Disarm,
    /// Emergency stop: latched, motors off at once.
    Estop,
    /// Clear a latched stop.
    Clear,
    /// Load a reference file (the scenario schema's `trajectory`, or waypoints).
    Upload(UploadArgs),
    /// Drive with a velocity command refreshed for a while, then let it time out.
    Drive(DriveArgs),
    /// Read or write parameters.
    Params(ParamsArgs),
    /// Record telemetry to a CSV (the columns of `hil-sim run --csv`) and print
    /// the metrics as JSON.
    Record(RecordArgs),
    /// Forward external poses from stdin lines or a UDP port
    /// (`x y theta [sx sy stheta] [@capture_time]`).
    PoseFeed(PoseFeedArgs),
    /// Identify the robot: drive the excitation and record (`run`), fit a log (`fit`).
    Identify(crate::identify::IdentifyArgs),
    /// A compact live status line (state, pose, speed, errors, health,
    /// counters) from telemetry.
    Watch(WatchArgs),
    /// The run metrics of a log, a trace CSV or an MCAP file (no robot
    /// needed): the numbers `record` prints.
    Metrics(MetricsArgs),
    /// Guided first power-up: each wheel driven alone, wiring and the robot
    /// file checked, the corrected file proposed (docs/commissioning.md).
    Commission(crate::commission::CommissionArgs),
    /// The robot file in the robot's flash: push, pull, diff, check.
    Robot(RobotArgs),
    /// Own the link to --port and serve every other command (and any
    /// number of clients) over a local socket (`wmr --serve SOCKET CMD`).
    Serve(crate::serve::ServeArgs),
}

/// `watch` options.
#[derive(Debug, Args)]
pub struct WatchArgs {
    /// Lines per second.
    #[arg(long, default_value_t = 5)]
    pub rate: u16,
    /// Stop after this much robot time [s] (default: until Ctrl-C).
    #[arg(long, value_name = "S")]
    pub seconds: Option<f64>,
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
    /// The metrics (no perturbation window), as `record` prints them.
    pub metrics: Option<track_log::Metrics>,
}

/// The metrics of a log file, CSV or MCAP.
pub fn metrics_of_file(path: &std::path::Path) -> Result<MetricsSummary, String> {
    let rows = ros_mcap::read_log(path).map_err(|e| e.to_string())?;
    Ok(MetricsSummary {
        rows: rows.len(),
        duration_s: match (rows.first(), rows.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        },
        metrics: track_log::metrics_from_trace(&rows, [0.0, 0.0], false),
    })
}

/// `robot` options.
#[derive(Debug, Args)]
pub struct RobotArgs {
    /// push, pull, diff or check.
    #[command(subcommand)]
    pub op: RobotOp,
}

/// `robot` operations.
#[derive(Debug, Subcommand)]
pub enum RobotOp {
    /// Validate FILE locally, store it in the robot's flash (hold only),
    /// read it back and compare, then reboot the robot into it.
    Push {
        /// Robot file (TOML, docs/robot.md).
        file: PathBuf,
        /// Store only: the robot runs it from its next boot.
        #[arg(long)]
        no_reboot: bool,
        /// Skip the local validation (to see the robot's own refusal).
        #[arg(long, hide = true)]
        no_local_check: bool,
    },
    /// Read the robot's stored record and print it as a robot file.
    Pull {
        /// Write it to this file instead of stdout.
        #[arg(short = 'o', long = "out")]
        out: Option<PathBuf>,
    },
    /// Field-by-field differences between FILE and the robot's record.
    Diff {
        /// Robot file (TOML).
        file: PathBuf,
    },
    /// Validate FILE offline (no robot needed) and print derived values.
    Check {
        /// Robot file (TOML).
        file: PathBuf,
    },
}

/// `upload` options.
#[derive(Debug, Args)]
pub struct UploadArgs {
    /// Reference file (TOML).
    #[arg(value_name = "FILE.toml")]
    pub file: PathBuf,
    /// Arm after loading, stream waypoints beyond the robot's buffer while
    /// running, and keep the link alive until the run ends (Ctrl-C: the robot
    /// brakes to a stop after link_timeout_ms).
    #[arg(long)]
    pub arm: bool,
    /// The robot's file: check every waypoint and the curve between each
    /// two against its limits before sending (the robot checks them too,
    /// but its refusal cannot say which limit).
    #[arg(long, value_name = "ROBOT.toml")]
    pub robot: Option<PathBuf>,
}

/// `drive` options.
#[derive(Debug, Args)]
pub struct DriveArgs {
    /// Linear velocity [m/s].
    #[arg(long, allow_hyphen_values = true, value_name = "M/S")]
    pub v: f32,
    /// Angular velocity [rad/s].
    #[arg(long, allow_hyphen_values = true, value_name = "RAD/S")]
    pub w: f32,
    /// How long to keep refreshing the command [s].
    #[arg(long = "for", value_name = "S")]
    pub for_s: f64,
    /// Command timeout on the robot [ms].
    #[arg(long, default_value_t = 300, value_name = "MS")]
    pub cmd_timeout_ms: u16,
}

/// `params` options.
#[derive(Debug, Args)]
pub struct ParamsArgs {
    /// get or set.
    #[command(subcommand)]
    pub op: ParamsOp,
}

/// `params` operations.
#[derive(Debug, Subcommand)]
pub enum ParamsOp {
    /// Print one parameter, or all.
    Get {
        /// Parameter name (docs/parameters.md); all when omitted.
        name: Option<String>,
    },
    /// Write one parameter.
    Set {
        /// Parameter name.
        name: String,
        /// Value in the parameter's unit.
        #[arg(allow_hyphen_values = true)]
        value: f32,
    },
}

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
    /// [default: the paper robot's 0.05] (the link does not report it).
    #[arg(long, value_name = "M")]
    pub com_offset_m: Option<f64>,
}

/// `pose-feed` options.
#[derive(Debug, Args)]
pub struct PoseFeedArgs {
    /// Listen on this UDP address (e.g. 0.0.0.0:9000) instead of stdin.
    #[arg(long, value_name = "ADDR:PORT")]
    pub udp: Option<String>,
    /// Standard deviations [m, m, rad] when a line gives none.
    #[arg(long, num_args = 3, default_values_t = [0.01, 0.01, 0.01])]
    pub std: Vec<f32>,
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
    /// The simulator's metrics of the log (no perturbation window).
    pub metrics: Option<track_log::Metrics>,
}

fn link_of(cli: &Cli) -> Result<Link, LinkError> {
    // Through a server when one is named or serves --port; every host-side
    // time derives from the robot's link timeout.
    let ep = crate::serve::Endpoint::resolve(cli.port.as_deref(), cli.serve.as_deref())?;
    crate::serve::open_link(&ep, cli.timeout_ms.map(Duration::from_millis))
}

/// Runs a parsed command line on a fresh link to `--port`.
pub fn execute(cli: &Cli, out: &mut dyn Write) -> Result<(), String> {
    if let Command::Identify(crate::identify::IdentifyArgs {
        op: crate::identify::IdentifyOp::Fit(a),
    }) = &cli.command
    {
        return crate::identify::fit(a, out); // a log, no robot
    }
    if let Command::Metrics(a) = &cli.command {
        let m = metrics_of_file(&a.file)?;
        let json = serde_json::to_string(&m).map_err(|e| e.to_string())?;
        return writeln!(out, "{json}").map_err(|e| e.to_string());
    }
    if let Command::Robot(RobotArgs {
        op: RobotOp::Check { file },
    }) = &cli.command
    {
        return crate::robot::check(file, out).map_err(|e| e.to_string());
    }
    if let Command::Serve(a) = &cli.command {
        let port = cli
            .port
            .as_deref()
            .ok_or("wmr serve needs --port PATH (or WMR_PORT): the robot's port")?;
        return crate::serve::serve(port, a, out);
    }
    let mut link = link_of(cli).map_err(|e| e.to_string())?;
    run(&cli.command, &mut link, out).map_err(|e| e.to_string())
}

fn io(e: std::io::Error) -> LinkError {
    LinkError::Io(e.to_string())
}

fn status(link: &mut Link) -> Result<StatusMsg, LinkError> {
    match link.command(&Request::GetStatus)? {
        Reply::Status { status, .. } => Ok(status),
        r => Err(LinkError::Unexpected(format!("{r:?}"))),
    }
}

/// Runs one command on an open link (after the handshake).
pub fn run(cmd: &Command, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    match cmd {
        Command::Status => {
            let hello = match link.last_hello.clone() {
                Some(h) => h,
                None => link.hello()?,
            };
            let s = status(link)?;
            writeln!(
                out,
                "robot: {} (protocol {}), state {:?}, mode {:?}, last stop {}, time {:.3} s, {} waypoints buffered",
                hello.chip,
                hello.version,
                s.state,
                s.mode,
                s.last_stop.map_or_else(|| "none".into(), |c| format!("{c:?}")),
                s.t_robot_us as f64 * 1e-6,
                s.buffered_points
            )
            .map_err(io)?;
            writeln!(out, "counters: {:?}", s.counters).map_err(io)?;
            writeln!(
                out,
                "external poses refused by the estimator after their ack: {:?}; telemetry frames withheld (non-finite): {}",
                s.pose_rejects, s.nonfinite_telemetry
            )
            .map_err(io)?;
            writeln!(
                out,
                "board: last reset {:?}, port rx dropped {}, port rx errors {}",
                s.board.reset_cause, s.board.port_rx_dropped, s.board.port_rx_errors
            )
            .map_err(io)?;
            let r = s.robot;
            let source = match r.source {
                wmr_protocol::RobotSource::Builtin => "compiled-in (no robot store)",
                wmr_protocol::RobotSource::Flash => "flash",
                wmr_protocol::RobotSource::DefaultMissing => {
                    "compiled-in default (no record in flash)"
                }
                wmr_protocol::RobotSource::DefaultCorrupt => {
                    "compiled-in default (the record in flash is corrupt or invalid)"
                }
            };
            writeln!(
                out,
                "robot record: {source}, CRC-32 {:08x}; stored {}; writes {}, failed {}",
                r.active_crc32,
                match r.stored_crc32 {
                    0 => "none".to_string(),
                    c if c == r.active_crc32 => "the same".to_string(),
                    c => format!("{c:08x} (runs after a reboot)"),
                },
                r.writes,
                r.write_failures
            )
            .map_err(io)?;
        }
        Command::Arm => {
            link.command(&Request::Arm)?;
            writeln!(
                out,
                "armed; the robot brakes to a stop after link_timeout_ms without a frame: keep `wmr record` or `wmr pose-feed` running"
            )
            .map_err(io)?;
        }
        Command::Disarm => {
            link.command(&Request::Disarm)?;
            writeln!(out, "disarmed").map_err(io)?;
        }
        Command::Estop => {
            link.command(&Request::EmergencyStop)?;
            writeln!(out, "emergency stop latched (clear with `wmr clear`)").map_err(io)?;
        }
        Command::Clear => {
            link.command(&Request::ClearStop)?;
            writeln!(out, "stop cleared: hold").map_err(io)?;
        }
        Command::Upload(a) => upload(a, link, out)?,
        Command::Drive(a) => drive(a, link, out)?,
        Command::Params(a) => params(&a.op, link, out)?,
        Command::Record(a) => record(a, link, out)?,
        Command::PoseFeed(a) => pose_feed(a, link, out)?,
        Command::Identify(a) => match &a.op {
            crate::identify::IdentifyOp::Run(r) => crate::identify::run(r, link, out)?,
            crate::identify::IdentifyOp::Fit(f) => {
                crate::identify::fit(f, out).map_err(LinkError::Io)?
            }
        },
        Command::Watch(a) => watch_live(a, link, out)?,
        Command::Metrics(a) => {
            let m = metrics_of_file(&a.file).map_err(LinkError::Io)?;
            let json = serde_json::to_string(&m).map_err(|e| LinkError::Io(e.to_string()))?;
            writeln!(out, "{json}").map_err(io)?;
        }
        Command::Commission(a) => crate::commission::commission(a, link, out)?,
        Command::Robot(a) => match &a.op {
            RobotOp::Push {
                file,
                no_reboot,
                no_local_check,
            } => crate::robot::push(link, file, !no_local_check, *no_reboot, out)?,
            RobotOp::Pull { out: file } => crate::robot::pull(link, file.as_deref(), out)?,
            RobotOp::Diff { file } => crate::robot::diff(link, file, out)?,
            RobotOp::Check { file } => crate::robot::check(file, out)?,
        },
        Command::Serve(_) => {
            return Err(LinkError::Io(
                "wmr serve owns a port: it does not run on a link".into(),
            ))
        }
    }
    Ok(())
}

/// Sends the segments from `next`, waiting (up to `patience`) while the
/// robot's buffer is full; returns the next segment to send.
fn send_segments(
    link: &mut Link,
    segs: &[Request],
    mut next: usize,
    patience: Duration,
) -> Result<usize, LinkError> {
    let mut waited = Instant::now();
    let mut watch = Watch::new(link);
    while next < segs.len() {
        match link.request(&segs[next])? {
            Reply::TrajectoryAck { .. } => {
                next += 1;
                waited = Instant::now();
            }
            Reply::Nack {
                error: ErrorCode::BufferFull,
                ..
            } => {
                if waited.elapsed() >= patience {
                    break;
                }
                // Waiting for the buffer to drain: a robot that stopped
                // meanwhile never drains it.
                let period = watch.timing().keep_alive;
                if let Some(s) = watch.step(link, None, period)?.stopped {
                    return Err(LinkError::UnexpectedStop(format!(
                        "{s} while streaming waypoints"
                    )));
                }
            }
            Reply::Nack {
                error: ErrorCode::InvalidValue,
                ..
            } => {
                return Err(LinkError::Io(format!(
                    "the robot refused the segment from waypoint {}: a waypoint, or the \
                     curve from the one before it, asks more than the robot's speed, yaw rate \
                     or acceleration; `wmr upload FILE --robot ROBOT.toml` names which",
                    next * wmr_protocol::SEGMENT_POINTS
                )))
            }
            Reply::Nack { error, .. } => {
                return Err(LinkError::Nack("TrajectorySegment".into(), error))
            }
            r => return Err(LinkError::Unexpected(format!("{r:?}"))),
        }
    }
    Ok(next)
}

fn upload(a: &UploadArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    let text = std::fs::read_to_string(&a.file)
        .map_err(|e| LinkError::Io(format!("cannot read {}: {e}", a.file.display())))?;
    let (up, ignored) =
        parse_upload(&text, &a.file.display().to_string()).map_err(LinkError::Io)?;
    if !ignored.is_empty() {
        eprintln!(
            "note: {} keys describe the simulated world and were ignored: {}",
            ignored.len(),
            ignored.join(", ")
        );
    }
    match up {
        Upload::Builtin(r) => {
            link.command(&Request::SetReference(r))?;
            writeln!(out, "reference loaded: {:?}", r.shape).map_err(io)?;
            if a.arm {
                link.command(&Request::Arm)?;
                writeln!(
                    out,
                    "armed; the robot runs while wmr runs (Ctrl-C: it brakes to a stop)"
                )
                .map_err(io)?;
                keep_alive_until_stop(link, out)?;
            }
        }
        Upload::Waypoints(pts) => {
            if let Some(path) = &a.robot {
                let robot = crate::robot::read_file(path)?;
                crate::upload::check_waypoints(&pts, &robot)
                    .map_err(|e| LinkError::Io(format!("{}: {e}", a.file.display())))?;
            }
            link.command(&Request::TrajectoryBegin {
                total_points: pts.len() as u32,
            })?;
            let segs = segments(&pts);
            let next = send_segments(link, &segs, 0, Duration::ZERO)?;
            writeln!(
                out,
                "{} of {} waypoints loaded",
                (next * wmr_protocol::SEGMENT_POINTS).min(pts.len()),
                pts.len()
            )
            .map_err(io)?;
            if next < segs.len() && !a.arm {
                return Err(LinkError::Io(
                    "the trajectory is longer than the robot's buffer: use --arm to stream the rest while running".into(),
                ));
            }
            if a.arm {
                link.command(&Request::Arm)?;
                writeln!(out, "armed").map_err(io)?;
                // The buffer drains as waypoints pass: stream the rest.
                let patience = Duration::from_secs_f64(
                    (pts.last().map_or(0.0, |w| w.t_s) as f64).max(1.0) + 5.0,
                );
                let done = send_segments(link, &segs, next, patience)?;
                if done < segs.len() {
                    return Err(LinkError::NoAnswer(
                        "the trajectory stream (buffer stayed full)".into(),
                    ));
                }
                writeln!(out, "all {} waypoints streamed", pts.len()).map_err(io)?;
                keep_alive_until_stop(link, out)?;
            }
        }
    }
    Ok(())
}

/// Keeps the link alive until the robot is at rest and prints why; only the
/// trajectory's end and a deliberate disarm (`wmr disarm`, the button) are a
/// success (a stop for any other cause, or silence beyond the link timing's
/// limit, is an error).
fn keep_alive_until_stop(link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    let mut watch = Watch::new(link);
    let period = watch.timing().keep_alive;
    let stop = loop {
        if let Some(s) = watch.step(link, None, period)?.stopped {
            break s;
        }
    };
    writeln!(out, "stopped: {stop}").map_err(io)?;
    expect_cause(
        stop,
        &[StopCode::TrajectoryEnd, StopCode::Disarmed],
        "the run",
    )
}

/// `Ok` when `stop` has the expected cause, else the unexpected stop.
fn expect_cause(stop: Stop, expected: &[StopCode], what: &str) -> Result<(), LinkError> {
    match stop.cause {
        Some(c) if expected.contains(&c) => Ok(()),
        _ => Err(LinkError::UnexpectedStop(format!(
            "{stop} during {what} (expected {expected:?})"
        ))),
    }
}

/// Longest wait for the robot to come to rest after a stop began [s]: its
/// controlled stop is bounded by its own limits (`RobotLimits::stop_bound_s`:
/// the braking ramp from top speed, at most 10 m/s at the least braking
/// deceleration 0.25 m/s², 40 s, then at most 2 s waiting for the wheels
/// at rest), below this.
const STOP_WAIT: Duration = Duration::from_secs(45);

fn drive(a: &DriveArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    if !(a.for_s.is_finite() && (0.0..=86_400.0).contains(&a.for_s)) {
        return Err(LinkError::Io("--for must be in [0, 86400] s".into()));
    }
    if a.cmd_timeout_ms == 0 {
        return Err(LinkError::Io("--cmd-timeout-ms must be > 0".into()));
    }
    let cmd = Request::Velocity {
        v_mps: a.v,
        omega_radps: a.w,
        timeout_ms: a.cmd_timeout_ms,
    };
    link.command(&cmd)?;
    if status(link)?.state == RunStateMsg::Hold {
        // Again, so that its timeout runs from just before the arm and not
        // from before the status round trip (with a lost frame or two on a
        // bad line, the two could outlast the command's timeout: the robot
        // would stop at once).
        link.command(&cmd)?;
        link.command(&Request::Arm)?;
    }
    let mut watch = Watch::new(link);
    // The refresh is the keep-alive: inside both the command's timeout and
    // the link timeout.
    let refresh =
        Duration::from_millis((a.cmd_timeout_ms as u64 / 3).max(10)).min(watch.timing().keep_alive);
    let t0 = Instant::now();
    while t0.elapsed().as_secs_f64() < a.for_s {
        let step = watch.step(link, Some(&cmd), refresh)?;
        let refused = step.answers.iter().find_map(|(_, r)| match r {
            Reply::Nack { error, .. } => Some(*error),
            _ => None,
        });
        // A refresh refused because the robot left velocity mode means it
        // stopped (its stop event may have been lost): report that stop,
        // read from its status, not the refusal.
        if refused == Some(ErrorCode::WrongMode) && step.stopped.is_none() {
            let s = watch.until_stopped(link, STOP_WAIT)?;
            return Err(LinkError::UnexpectedStop(format!(
                "{s} after {:.2} s of {:.2} s of driving (velocity refreshes refused: no longer in velocity mode)",
                t0.elapsed().as_secs_f64(),
                a.for_s
            )));
        }
        if let Some(s) = step.stopped {
            return Err(LinkError::UnexpectedStop(format!(
                "{s} after {:.2} s of {:.2} s of driving",
                t0.elapsed().as_secs_f64(),
                a.for_s
            )));
        }
        if step.stopping {
            let s = watch.until_stopped(link, STOP_WAIT)?;
            return Err(LinkError::UnexpectedStop(format!(
                "{s} after {:.2} s of {:.2} s of driving",
                t0.elapsed().as_secs_f64(),
                a.for_s
            )));
        }
        if let Some(error) = refused {
            return Err(LinkError::Nack("Velocity".into(), error));
        }
    }
    // No more refreshes: the command times out on the robot.
    let stop = watch.until_stopped(link, STOP_WAIT)?;
    writeln!(out, "stopped: {stop}").map_err(io)?;
    expect_cause(stop, &[StopCode::VelocityTimeout], "drive")
}

fn params(op: &ParamsOp, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    use crate::params::{get, set, ParamsError};
    match op {
        ParamsOp::Get { name } => get(name.as_deref(), link, out, &mut std::io::stderr()),
        ParamsOp::Set { name, value } => set(name, *value, link, out, &mut std::io::stderr()),
    }
    .map_err(|e| match e {
        ParamsError::Link(e) => e,
        e => LinkError::Io(e.to_string()),
    })
}

fn host_us(t0: Instant) -> u64 {
    t0.elapsed().as_micros() as u64
}

/// Telemetry frames missing between sequence numbers `last` and `seq`; a
/// number going back is a robot that restarted its count (a reset, seen
/// through `wmr serve`), not four billion frames lost.
pub fn telemetry_gap(last: u32, seq: u32) -> u64 {
    match seq.wrapping_sub(last) {
        d if d > 0 && d <= 1 << 31 => (d - 1) as u64,
        _ => 0,
    }
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
    // The MCAP log: its geometry from the handshake, stamps from robot
    // time through the clock offset measured now (ros_mcap::TimeMap).
    let t0 = Instant::now();
    let unix_t0_ns = ros_mcap::unix_now_ns();
    let mut mcap = match &a.mcap {
        None => None,
        Some(path) => {
            let robot = match &link.last_hello {
                Some(h) => h.robot,
                None => link.hello()?.robot,
            };
            let geometry = ros_mcap::Geometry::new(
                robot.wheel_radius_m as f64,
                robot.half_track_m as f64,
                a.com_offset_m
                    .unwrap_or_else(ros_mcap::default_com_offset_m),
            )
            .map_err(|e| LinkError::Io(e.to_string()))?;
            let log = ros_mcap::McapLog::create(path, geometry, "wmr record")
                .map_err(|e| LinkError::Io(e.to_string()))?;
            let sync = clock_sync(link, t0, 5)?;
            let map =
                ros_mcap::TimeMap::new(sync.robot_us as u32, unix_t0_ns + sync.host_mid_us * 1000);
            Some((log, map, path))
        }
    };
    let mut last_stop: Option<StopCode> = None;
    link.command(&Request::SetTelemetry {
        selection: TELEMETRY_ALL,
        rate_hz: a.rate,
    })?;
    if a.arm {
        link.command(&Request::Arm)?;
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
    let mut last_ping = Instant::now();
    let mut last_frame = Instant::now();
    let mut first_us: Option<u32> = None;
    let mut last_seq: Option<u32> = None;
    let mut dropped = 0u64;
    let mut rows = Vec::new();
    let mut seen_running = false;
    let mut ended: Option<Stop> = None;
    let keep_alive = link.timing().keep_alive;
    loop {
        // Keep the link alive (the robot brakes after link_timeout_ms of silence).
        if last_ping.elapsed() >= keep_alive {
            link.send(&Request::ClockSync {
                host_time_us: host_us(t0),
            })?;
            last_ping = Instant::now();
        }
        match link.next_stream(Duration::from_millis(20))? {
            Some(Reply::Telemetry(t)) => {
                last_frame = Instant::now();
                if let Some(s) = last_seq {
                    dropped += telemetry_gap(s, t.seq);
                }
                last_seq = Some(t.seq);
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
        if last_frame.elapsed() > Duration::from_secs(2) {
            pb.abandon();
            return Err(LinkError::NoAnswer("telemetry (no frame for 2 s)".into()));
        }
    }
    pb.finish_and_clear();
    // The cause of a stop seen only in telemetry: the status's last stop.
    if let Some(s) = &mut ended {
        if s.cause.is_none() {
            s.cause = status(link).ok().and_then(|st| st.last_stop);
        }
        eprintln!("the run ended: {s}");
    }
    let _ = link.command(&Request::SetTelemetry {
        selection: TELEMETRY_ALL,
        rate_hz: 0,
    });
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
        metrics: track_log::metrics_from_trace(&rows, [0.0, 0.0], false),
    };
    let json = serde_json::to_string(&summary).map_err(|e| LinkError::Io(e.to_string()))?;
    writeln!(out, "{json}").map_err(io)?;
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

/// `watch`: one status line per telemetry frame at `--rate`, the link
/// kept alive meanwhile; ends after `--seconds` of robot time.
fn watch_live(a: &WatchArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    if a.rate == 0 || a.rate > 100 {
        return Err(LinkError::Io("--rate must be in 1..=100 lines/s".into()));
    }
    if let Some(s) = a.seconds {
        if !(s.is_finite() && s > 0.0) {
            return Err(LinkError::Io("--seconds must be > 0".into()));
        }
    }
    link.command(&Request::SetTelemetry {
        selection: TELEMETRY_ALL,
        rate_hz: a.rate,
    })?;
    let t0 = Instant::now();
    let keep_alive = link.timing().keep_alive;
    let mut last_ping = Instant::now();
    let mut last_frame = Instant::now();
    let mut first_us: Option<u32> = None;
    let mut status = crate::watch::LiveStatus::default();
    // Through `wmr serve` telemetry comes at the highest rate any client
    // asked for: one line per 1/rate of robot time (half a tick's slack).
    let line_us = 1_000_000 / a.rate as u32;
    let mut last_line_us: Option<u32> = None;
    loop {
        if last_ping.elapsed() >= keep_alive {
            link.send(&Request::ClockSync {
                host_time_us: host_us(t0),
            })?;
            last_ping = Instant::now();
        }
        match link.next_stream(Duration::from_millis(20))? {
            Some(Reply::Telemetry(t)) => {
                last_frame = Instant::now();
                let first = *first_us.get_or_insert(t.t_robot_us);
                if last_line_us.is_none_or(|l| t.t_robot_us.wrapping_sub(l) + 500 >= line_us) {
                    writeln!(out, "{}", status.line(&t)).map_err(io)?;
                    last_line_us = Some(t.t_robot_us);
                }
                if a.seconds
                    .is_some_and(|s| t.t_robot_us.wrapping_sub(first) as f64 * 1e-6 >= s)
                {
                    break;
                }
            }
            Some(Reply::Event(e)) => status.event(&e),
            _ => {}
        }
        if last_frame.elapsed() > Duration::from_secs(2) {
            return Err(LinkError::NoAnswer("telemetry (no frame for 2 s)".into()));
        }
    }
    let _ = link.command(&Request::SetTelemetry {
        selection: TELEMETRY_ALL,
        rate_hz: 0,
    });
    Ok(())
}

/// One clock-sync exchange: the robot's time and the host time (µs since
/// the caller's `t0`) at the midpoint of its round trip.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClockSample {
    /// The robot's clock \[µs\] (u32 on the wire, widened).
    pub robot_us: u64,
    /// Host time at the round trip's midpoint \[µs since t0\].
    pub host_mid_us: u64,
    /// The round trip \[µs\].
    pub rtt_us: u64,
}

impl ClockSample {
    /// Clock offset robot − host \[µs\].
    pub fn offset_us(&self) -> i64 {
        self.robot_us as i64 - self.host_mid_us as i64
    }
}

/// The best of `n` clock-sync exchanges: the one with the shortest round
/// trip (its midpoint is the best estimate of when the robot read its clock).
pub fn clock_sync(link: &mut Link, t0: Instant, n: usize) -> Result<ClockSample, LinkError> {
    let mut best: Option<ClockSample> = None;
    for _ in 0..n.max(1) {
        let sent = host_us(t0);
        match link.command(&Request::ClockSync { host_time_us: sent })? {
            Reply::ClockSync { robot_time_us, .. } => {
                let recv = host_us(t0);
                let s = ClockSample {
                    robot_us: robot_time_us as u64,
                    host_mid_us: (sent + recv) / 2,
                    rtt_us: recv - sent,
                };
                if best.is_none_or(|b| s.rtt_us < b.rtt_us) {
                    best = Some(s);
                }
            }
            r => return Err(LinkError::Unexpected(format!("{r:?}"))),
        }
    }
    best.ok_or_else(|| LinkError::NoAnswer("ClockSync".into()))
}

/// When a pose was taken, as a `pose-feed` line gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Capture {
    /// No time given: the pose is stamped when its line arrives.
    Arrival,
    /// Host Unix time \[s\] (a localiser's header stamp).
    UnixS(f64),
    /// This long before the line arrived \[s\] (`@-0.08`).
    AgoS(f64),
}

/// A pose line: pose of G \[m, m, rad\], standard deviations \[m, m, rad\]
/// and when it was taken.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseLine {
    /// x, y, θ of G.
    pub pose: [f32; 3],
    /// σx, σy, σθ (σθ = 0: position only).
    pub std: [f32; 3],
    /// Capture time.
    pub capture: Capture,
}

/// Unix times before this \[s\] (2001-09-09) are not a clock's reading.
const MIN_UNIX_S: f64 = 1e9;
/// Oldest capture accepted on the host side \[s\]: far beyond any
/// estimator history (the robot refuses what is older than its own).
const MAX_AGE_S: f64 = 60.0;

/// Parses `x y theta [sx sy stheta] [@T]` (spaces or commas; `#`
/// comments). `@T` is the capture time: Unix seconds (`@1764632000.125`,
/// the localiser's stamp), or a negative age relative to the line's
/// arrival (`@-0.08`: taken 80 ms before).
pub fn parse_pose_line(line: &str, std: [f32; 3]) -> Result<Option<PoseLine>, String> {
    let line = line.split('#').next().unwrap_or("").trim();
    if line.is_empty() {
        return Ok(None);
    }
    let mut capture = Capture::Arrival;
    let mut nums = Vec::new();
    for word in line
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
    {
        if let Some(t) = word.strip_prefix('@') {
            if capture != Capture::Arrival {
                return Err(format!("two capture times in {line:?}"));
            }
            let t: f64 = t
                .parse()
                .map_err(|_| format!("capture time {word:?} is not a number"))?;
            capture = if t.is_finite() && t < 0.0 && -t <= MAX_AGE_S {
                Capture::AgoS(-t)
            } else if t.is_finite() && t >= MIN_UNIX_S {
                Capture::UnixS(t)
            } else {
                return Err(format!(
                    "capture time {word:?}: give Unix seconds (@1764632000.125) or an age up to {MAX_AGE_S} s before arrival (@-0.08)"
                ));
            };
        } else {
            nums.push(
                word.parse::<f32>()
                    .map_err(|_| format!("not numbers: {line:?}"))?,
            );
        }
    }
    let v = nums;
    let (pose, std) = match v.len() {
        3 => ([v[0], v[1], v[2]], std),
        6 => ([v[0], v[1], v[2]], [v[3], v[4], v[5]]),
        n => {
            return Err(format!(
                "{n} numbers, expected `x y theta [sx sy stheta] [@capture_time]`"
            ))
        }
    };
    Ok(Some(PoseLine { pose, std, capture }))
}

/// Host time and robot time, for stamping poses: `host_us` counts from
/// `t0`, `unix_t0_ns` is the Unix time at `t0`, and the clock offset
/// robot − host is from [`clock_sync`].
#[derive(Clone, Copy, Debug)]
pub struct PoseClock {
    /// Unix time at t0 \[ns\].
    pub unix_t0_ns: u64,
    /// Robot − host clock offset \[µs\].
    pub offset_us: i64,
    /// How much earlier than its arrival a pose without a capture time is
    /// stamped \[µs\]: the offset's uncertainty, so that the stamp is never
    /// in the robot's future (refused as `PoseFromFuture`).
    pub arrival_margin_us: u64,
}

impl PoseClock {
    /// The clock of a sync exchange taken at Unix time `unix_t0_ns` (= t0)
    /// with a robot of control period `period_s`: the robot read its clock
    /// somewhere in the round trip and only at a tick, so the offset is
    /// uncertain by half the round trip plus a period (the arrival margin).
    pub fn from_sync(sync: ClockSample, unix_t0_ns: u64, period_s: f32) -> Self {
        let period_us = if period_s.is_finite() && period_s > 0.0 && period_s < 1.0 {
            (period_s as f64 * 1e6).round() as u64
        } else {
            1000
        };
        Self {
            unix_t0_ns,
            offset_us: sync.offset_us(),
            arrival_margin_us: sync.rtt_us.div_ceil(2) + period_us,
        }
    }

    /// Robot time \[µs, u32 clock\] of a pose taken as `capture` says, its
    /// line having arrived at host time `arrival_us` (µs since t0).
    pub fn robot_stamp_us(&self, capture: Capture, arrival_us: u64) -> u32 {
        let host_us = match capture {
            Capture::Arrival => arrival_us as i64 - self.arrival_margin_us as i64,
            Capture::AgoS(a) => arrival_us as i64 - (a * 1e6).round() as i64,
            Capture::UnixS(t) => {
                ((t * 1e9) as i128 - self.unix_t0_ns as i128).div_euclid(1000) as i64
            }
        };
        (host_us + self.offset_us) as u32
    }

    /// The `ExternalPose` request of a line that arrived at `arrival_us`.
    pub fn request(&self, p: &PoseLine, arrival_us: u64) -> Request {
        Request::ExternalPose {
            t_robot_us: self.robot_stamp_us(p.capture, arrival_us),
            pose: wmr_protocol::PoseMsg {
                x_m: p.pose[0],
                y_m: p.pose[1],
                theta_rad: p.pose[2],
            },
            std_dev: p.std,
        }
    }
}

/// `pose-feed`'s clock: synchronised with the robot at the start (the
/// best of 5 exchanges) and again before a line when the last sync is
/// older than the link's keep-alive period (one exchange), so that its
/// stamps follow the robot's clock as it drifts against the host's (a
/// crystal's 50 ppm exceeds a 1 ms arrival margin within 20 s; a simulated
/// robot on a loaded machine falls behind in steps).
pub struct PoseSync {
    t0: Instant,
    unix_t0_ns: u64,
    period_s: f32,
    clock: PoseClock,
    last: Instant,
}

impl PoseSync {
    /// The first sync, with a robot of control period `period_s`.
    pub fn new(link: &mut Link, period_s: f32) -> Result<Self, LinkError> {
        let t0 = Instant::now();
        let unix_t0_ns = ros_mcap::unix_now_ns();
        let clock = PoseClock::from_sync(clock_sync(link, t0, 5)?, unix_t0_ns, period_s);
        Ok(Self {
            t0,
            unix_t0_ns,
            period_s,
            clock,
            last: Instant::now(),
        })
    }

    /// The clock for a line arriving now and its arrival \[µs since t0\]
    /// (read before a re-sync's round trip: the stamp errs early).
    pub fn at_arrival(&mut self, link: &mut Link) -> Result<(PoseClock, u64), LinkError> {
        let arrival = host_us(self.t0);
        if self.last.elapsed() >= link.timing().keep_alive {
            let s = clock_sync(link, self.t0, 1)?;
            self.clock = PoseClock::from_sync(s, self.unix_t0_ns, self.period_s);
            self.last = Instant::now();
        }
        Ok((self.clock, arrival))
    }
}

/// Feeds pose lines from `lines` (numbered from 1) to the robot; returns
/// the tally. Each line is stamped in robot time: at its capture time when
/// it gives one, else when it arrives. `at_arrival` gives, as each line
/// arrives, the clock and the arrival time on its host clock \[µs\]
/// (`pose-feed`: [`PoseSync::at_arrival`]; a test: its own).
pub fn feed_lines(
    link: &mut Link,
    mut at_arrival: impl FnMut(&mut Link) -> Result<(PoseClock, u64), LinkError>,
    std: [f32; 3],
    lines: impl Iterator<Item = Result<String, LinkError>>,
    tally: &mut PoseTally,
) -> Result<(), LinkError> {
    for (i, line) in lines.enumerate() {
        let line = line?;
        let n = i + 1;
        match parse_pose_line(&line, std) {
            Ok(None) => {}
            Err(e) => eprintln!("line {n}: {e}"),
            Ok(Some(p)) => {
                // A pose is perishable: one the robot did not answer (a
                // cut line, a busy link) is counted lost and the feed goes
                // on; only a robot silent for POSE_FEED_GIVE_UP ends it
                // (issue 31 item 6: a 0.5 s cut ended the feed).
                let sent = at_arrival(link)
                    .and_then(|(clock, arrival)| link.command(&clock.request(&p, arrival)));
                match sent {
                    Ok(_) => tally.accepted(),
                    Err(LinkError::Nack(_, e)) => {
                        tally.refused(e);
                        eprintln!("line {n}: refused: {}", e.reason());
                    }
                    Err(LinkError::NoAnswer(what)) => {
                        let silent = tally.lost(Instant::now());
                        eprintln!("line {n}: lost (no answer to {what})");
                        if silent >= POSE_FEED_GIVE_UP {
                            return Err(LinkError::NoAnswer(format!(
                                "any pose for {:.0} s ({} lost)",
                                silent.as_secs_f64(),
                                tally.lost
                            )));
                        }
                    }
                    Err(e) => return Err(e),
                }
            }
        }
    }
    Ok(())
}

fn pose_feed(a: &PoseFeedArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    let period_s = match &link.last_hello {
        Some(h) => h.robot.control_period_s,
        None => link.hello()?.robot.control_period_s,
    };
    let mut sync = PoseSync::new(link, period_s)?;
    let std = [a.std[0], a.std[1], a.std[2]];
    let mut tally = PoseTally::default();
    match &a.udp {
        None => {
            let lines = std::io::stdin().lock().lines().map(|l| l.map_err(io));
            feed_lines(link, |l| sync.at_arrival(l), std, lines, &mut tally)?;
        }
        Some(addr) => {
            let sock = std::net::UdpSocket::bind(addr)
                .map_err(|e| LinkError::Io(format!("cannot listen on {addr}: {e}")))?;
            let mut buf = [0u8; 1500];
            loop {
                let (len, _) = sock.recv_from(&mut buf).map_err(io)?;
                let text = String::from_utf8_lossy(&buf[..len]).into_owned();
                let lines: Vec<Result<String, LinkError>> =
                    text.lines().map(|l| Ok(l.to_string())).collect();
                feed_lines(
                    link,
                    |l| sync.at_arrival(l),
                    std,
                    lines.into_iter(),
                    &mut tally,
                )?;
            }
        }
    }
    writeln!(out, "{tally}").map_err(io)?;
    Ok(())
}

/// How long `pose-feed` goes on while the robot answers no pose: longer
/// than any line cut a serial or USB link recovers from, shorter than a
/// user's patience with a gone robot.
pub const POSE_FEED_GIVE_UP: Duration = Duration::from_secs(10);

/// What `pose-feed` sent, what the robot refused, by reason, and what it
/// did not answer.
#[derive(Debug, Default)]
pub struct PoseTally {
    sent: u64,
    refused: Vec<(ErrorCode, u64)>,
    /// Poses the robot did not answer.
    pub lost: u64,
    /// Since when no pose was answered (None: the last one was).
    silent_since: Option<Instant>,
}

impl PoseTally {
    /// One pose sent and acknowledged.
    pub fn accepted(&mut self) {
        self.sent += 1;
        self.silent_since = None;
    }

    /// One pose sent and not answered at `now`; returns how long no pose
    /// has been answered.
    pub fn lost(&mut self, now: Instant) -> Duration {
        self.sent += 1;
        self.lost += 1;
        now - *self.silent_since.get_or_insert(now)
    }

    /// One pose sent and refused with `e`.
    pub fn refused(&mut self, e: ErrorCode) {
        self.sent += 1;
        self.silent_since = None;
        match self.refused.iter_mut().find(|(c, _)| *c == e) {
            Some((_, n)) => *n += 1,
            None => self.refused.push((e, 1)),
        }
    }

    /// Poses refused, all reasons.
    pub fn refused_total(&self) -> u64 {
        self.refused.iter().map(|(_, n)| n).sum()
    }
}

impl std::fmt::Display for PoseTally {
    /// `N poses sent, M refused` and one `  K: reason` line per reason.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} poses sent, {} refused, {} lost",
            self.sent,
            self.refused_total(),
            self.lost
        )?;
        for (e, n) in &self.refused {
            write!(f, "\n  {n}: {}", e.reason())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// pose-feed's silence (issue 31 item 6): measured from the first
    /// unanswered pose, reset by any answer, counted in the tally's line.
    #[test]
    fn pose_feed_counts_lost_poses_and_their_silence() {
        let mut t = PoseTally::default();
        let t0 = Instant::now();
        assert_eq!(t.lost(t0), Duration::ZERO);
        assert_eq!(
            t.lost(t0 + Duration::from_millis(500)),
            Duration::from_millis(500)
        );
        t.accepted();
        assert_eq!(t.lost(t0 + Duration::from_secs(20)), Duration::ZERO);
        assert_eq!(t.lost, 3);
        assert_eq!(t.to_string(), "4 poses sent, 0 refused, 3 lost");
    }

    /// Gaps in telemetry numbers: the frames between, across the u32 wrap;
    /// none for a repeat or a count that restarted (a robot reset).
    #[test]
    fn telemetry_gaps() {
        assert_eq!(telemetry_gap(5, 6), 0);
        assert_eq!(telemetry_gap(5, 9), 3);
        assert_eq!(telemetry_gap(u32::MAX, 1), 1);
        assert_eq!(telemetry_gap(5, 5), 0);
        assert_eq!(telemetry_gap(4000, 2), 0);
    }

    #[test]
    fn pose_tally_counts_refusals_by_reason() {
        let mut t = PoseTally::default();
        t.accepted();
        t.refused(ErrorCode::PoseBadStdDev);
        t.refused(ErrorCode::PoseNonFinite);
        t.refused(ErrorCode::PoseBadStdDev);
        assert_eq!(t.refused_total(), 3);
        let text = t.to_string();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("4 poses sent, 3 refused, 0 lost"));
        assert_eq!(
            lines.next(),
            Some(format!("  2: {}", ErrorCode::PoseBadStdDev.reason()).as_str())
        );
        assert_eq!(
            lines.next(),
            Some(format!("  1: {}", ErrorCode::PoseNonFinite.reason()).as_str())
        );
        assert_eq!(lines.next(), None);
    }

    #[test]
    fn pose_lines() {
        let std = [0.01, 0.02, 0.03];
        let line = |pose, std, capture| Some(PoseLine { pose, std, capture });
        assert_eq!(
            parse_pose_line("1.5 -2 0.25", std).unwrap(),
            line([1.5, -2.0, 0.25], std, Capture::Arrival)
        );
        assert_eq!(
            parse_pose_line("1,2,3, 0.1,0.1,0.2 # mocap", std).unwrap(),
            line([1.0, 2.0, 3.0], [0.1, 0.1, 0.2], Capture::Arrival)
        );
        assert_eq!(
            parse_pose_line("1 2 3 @-0.08", std).unwrap(),
            line([1.0, 2.0, 3.0], std, Capture::AgoS(0.08))
        );
        assert_eq!(
            parse_pose_line("@1764632000.5 1 2 3 0.1 0.1 0", std).unwrap(),
            line(
                [1.0, 2.0, 3.0],
                [0.1, 0.1, 0.0],
                Capture::UnixS(1764632000.5)
            )
        );
        for bad in [
            "1 2 3 @0.08",
            "1 2 3 @nan",
            "1 2 3 @-100",
            "1 2 3 @x",
            "1 2 3 @-1 @-2",
        ] {
            let e = parse_pose_line(bad, std).unwrap_err();
            assert!(e.contains("capture time"), "{bad}: {e}");
        }
        assert_eq!(parse_pose_line("  # comment", std).unwrap(), None);
        assert!(parse_pose_line("1 2", std)
            .unwrap_err()
            .contains("expected"));
        assert!(parse_pose_line("x y z", std)
            .unwrap_err()
            .contains("not numbers"));
    }

    /// A capture time maps to robot time through the clock offset: 80 ms
    /// before arrival is 80 000 µs before the arrival's robot time, and a
    /// Unix stamp lands where the host clock read it.
    #[test]
    fn capture_times_map_to_robot_time() {
        let sync = ClockSample {
            robot_us: 5_500_000,
            host_mid_us: 500_000,
            rtt_us: 301,
        };
        let clock = PoseClock::from_sync(sync, 1_764_632_000_000_000_000, 0.001);
        assert_eq!(clock.offset_us, 5_000_000);
        let arrival = 2_000_000;
        let at = 7_000_000;
        // At arrival less the offset's uncertainty: ⌈301/2⌉ µs + one period.
        assert_eq!(
            clock.robot_stamp_us(Capture::Arrival, arrival),
            at - 151 - 1000
        );
        assert_eq!(
            clock.robot_stamp_us(Capture::AgoS(0.08), arrival),
            at - 80_000
        );
        // t0 + 1.92 s in Unix time = 80 ms before the arrival at t0 + 2 s.
        assert_eq!(
            clock.robot_stamp_us(Capture::UnixS(1_764_632_001.92), arrival),
            at - 80_000
        );
    }

    #[test]
    fn one_line_errors() {
        let e = LinkError::Nack("Arm".into(), ErrorCode::NoReference);
        assert_eq!(
            e.to_string(),
            "the robot refused Arm: no reference, trajectory or velocity command loaded"
        );
        let e = Link::open("/dev/no-such-port", Duration::from_millis(10))
            .err()
            .unwrap();
        assert_eq!(e.to_string(), "no such port: /dev/no-such-port");
        assert!(!LinkError::NoAnswer("Hello".into())
            .to_string()
            .contains('\n'));
    }
}
