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
    ErrorCode, Event, ParamId, Reply, Request, RunStateMsg, StatusMsg, StopCode, TELEMETRY_ALL,
};

/// Host tool for the trajectory-tracking robot (and `hil-sim device --pty`).
#[derive(Debug, Parser)]
#[command(name = "wmr", version, about, long_about = None)]
pub struct Cli {
    /// Serial port or pseudo-terminal of the robot.
    #[arg(long, global = true, env = "WMR_PORT", value_name = "PATH")]
    pub port: Option<String>,
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
    /// Forward external poses from stdin lines or a UDP port.
    PoseFeed(PoseFeedArgs),
    /// Guided first power-up: each wheel driven alone, wiring and the robot
    /// file checked, the corrected file proposed (docs/commissioning.md).
    Commission(crate::commission::CommissionArgs),
    /// The robot file in the robot's flash: push, pull, diff, check.
    Robot(RobotArgs),
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
        /// Parameter name (docs/protocol.md); all when omitted.
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
    /// The simulator's metrics of the log (no perturbation window).
    pub metrics: Option<track_log::Metrics>,
}

fn link_of(cli: &Cli) -> Result<Link, LinkError> {
    let port = cli
        .port
        .as_deref()
        .ok_or_else(|| LinkError::Io("no port: give --port PATH (or set WMR_PORT)".into()))?;
    let mut link = Link::open_timed(port, cli.timeout_ms.map(Duration::from_millis))?;
    link.hello()?;
    // Every host-side time derives from the robot's link timeout.
    if let Ok(Reply::Param { value, .. }) = link.command(&Request::GetParam(ParamId::LinkTimeoutMs))
    {
        if value.is_finite() && value >= 1.0 {
            link.set_link_timeout_ms(value as u32);
        }
    }
    Ok(link)
}

/// Runs a parsed command line on a fresh link to `--port`.
pub fn execute(cli: &Cli, out: &mut dyn Write) -> Result<(), String> {
    if let Command::Robot(RobotArgs {
        op: RobotOp::Check { file },
    }) = &cli.command
    {
        return crate::robot::check(file, out).map_err(|e| e.to_string());
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
/// controlled stop is bounded by its own limits, far below this.
const STOP_WAIT: Duration = Duration::from_secs(10);

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

fn param_id(name: &str) -> Result<ParamId, LinkError> {
    ParamId::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = ParamId::ALL.iter().map(|p| p.name()).collect();
        LinkError::Io(format!(
            "unknown parameter {name:?} (one of: {})",
            names.join(", ")
        ))
    })
}

fn params(op: &ParamsOp, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    match op {
        ParamsOp::Get { name } => {
            let ids = match name {
                Some(n) => vec![param_id(n)?],
                None => ParamId::ALL.to_vec(),
            };
            for id in ids {
                match link.command(&Request::GetParam(id))? {
                    Reply::Param { value, .. } => {
                        writeln!(out, "{} = {value}", id.name()).map_err(io)?
                    }
                    r => return Err(LinkError::Unexpected(format!("{r:?}"))),
                }
            }
        }
        ParamsOp::Set { name, value } => {
            let id = param_id(name)?;
            link.command(&Request::SetParam { id, value: *value })
                .map_err(|e| match e {
                    LinkError::Nack(_, c) => LinkError::Nack(format!("{name} = {value}"), c),
                    e => e,
                })?;
            writeln!(out, "{name} = {value}").map_err(io)?;
        }
    }
    Ok(())
}

fn host_us(t0: Instant) -> u64 {
    t0.elapsed().as_micros() as u64
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
    let t0 = Instant::now();
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
                    dropped += t.seq.wrapping_sub(s).saturating_sub(1) as u64;
                }
                last_seq = Some(t.seq);
                let t_us = *first_us.get_or_insert(t.t_robot_us);
                seen_running |= t.state == RunStateMsg::Running;
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
    let summary = RecordSummary {
        rows: rows.len(),
        dropped_frames: dropped,
        duration_s: match (rows.first(), rows.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        },
        csv: a.out.display().to_string(),
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
        _ => Ok(()),
    }
}

/// Clock offset robot − host \[µs\] from `n` exchanges, the one with the
/// shortest round trip (its midpoint is the best estimate).
fn clock_offset(link: &mut Link, t0: Instant, n: usize) -> Result<i64, LinkError> {
    let mut best: Option<(u64, i64)> = None;
    for _ in 0..n {
        let sent = host_us(t0);
        match link.command(&Request::ClockSync { host_time_us: sent })? {
            Reply::ClockSync { robot_time_us, .. } => {
                let recv = host_us(t0);
                let rtt = recv - sent;
                let mid = (sent + recv) / 2;
                let off = robot_time_us as i64 - mid as i64;
                if best.is_none_or(|(r, _)| rtt < r) {
                    best = Some((rtt, off));
                }
            }
            r => return Err(LinkError::Unexpected(format!("{r:?}"))),
        }
    }
    Ok(best.map_or(0, |(_, o)| o))
}

/// A pose \[m, m, rad\] and its standard deviations \[m, m, rad\].
pub type PoseLine = ([f32; 3], [f32; 3]);

/// Parses `x y theta [sx sy stheta]` (spaces or commas; `#` comments).
pub fn parse_pose_line(line: &str, std: [f32; 3]) -> Result<Option<PoseLine>, String> {
    let line = line.split('#').next().unwrap_or("").trim();
    if line.is_empty() {
        return Ok(None);
    }
    let v: Result<Vec<f32>, _> = line
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(str::parse)
        .collect();
    let v = v.map_err(|_| format!("not numbers: {line:?}"))?;
    match v.len() {
        3 => Ok(Some(([v[0], v[1], v[2]], std))),
        6 => Ok(Some(([v[0], v[1], v[2]], [v[3], v[4], v[5]]))),
        n => Err(format!("{n} numbers, expected `x y theta [sx sy stheta]`")),
    }
}

fn pose_feed(a: &PoseFeedArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    let t0 = Instant::now();
    let offset = clock_offset(link, t0, 5)?;
    let std = [a.std[0], a.std[1], a.std[2]];
    let mut tally = PoseTally::default();
    let mut send = |link: &mut Link, line: &str, n: usize| -> Result<(), LinkError> {
        match parse_pose_line(line, std) {
            Ok(None) => Ok(()),
            Err(e) => {
                eprintln!("line {n}: {e}");
                Ok(())
            }
            Ok(Some((p, s))) => {
                let t_robot_us = (host_us(t0) as i64 + offset) as u32;
                let req = Request::ExternalPose {
                    t_robot_us,
                    pose: wmr_protocol::PoseMsg {
                        x_m: p[0],
                        y_m: p[1],
                        theta_rad: p[2],
                    },
                    std_dev: s,
                };
                match link.command(&req) {
                    Ok(_) => tally.accepted(),
                    Err(LinkError::Nack(_, e)) => {
                        tally.refused(e);
                        eprintln!("line {n}: refused: {}", e.reason());
                    }
                    Err(e) => return Err(e),
                }
                Ok(())
            }
        }
    };
    match &a.udp {
        None => {
            for (i, line) in std::io::stdin().lock().lines().enumerate() {
                send(link, &line.map_err(io)?, i + 1)?;
            }
        }
        Some(addr) => {
            let sock = std::net::UdpSocket::bind(addr)
                .map_err(|e| LinkError::Io(format!("cannot listen on {addr}: {e}")))?;
            let mut buf = [0u8; 1500];
            let mut n = 0;
            loop {
                let (len, _) = sock.recv_from(&mut buf).map_err(io)?;
                for line in String::from_utf8_lossy(&buf[..len]).lines() {
                    n += 1;
                    send(link, line, n)?;
                }
            }
        }
    }
    writeln!(out, "{tally}").map_err(io)?;
    Ok(())
}

/// What `pose-feed` sent and what the robot refused, by reason.
#[derive(Debug, Default)]
pub struct PoseTally {
    sent: u64,
    refused: Vec<(ErrorCode, u64)>,
}

impl PoseTally {
    /// One pose sent and acknowledged.
    pub fn accepted(&mut self) {
        self.sent += 1;
    }

    /// One pose sent and refused with `e`.
    pub fn refused(&mut self, e: ErrorCode) {
        self.sent += 1;
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
            "{} poses sent, {} refused",
            self.sent,
            self.refused_total()
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
        assert_eq!(lines.next(), Some("4 poses sent, 3 refused"));
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
        assert_eq!(
            parse_pose_line("1.5 -2 0.25", std).unwrap(),
            Some(([1.5, -2.0, 0.25], std))
        );
        assert_eq!(
            parse_pose_line("1,2,3, 0.1,0.1,0.2 # mocap", std).unwrap(),
            Some(([1.0, 2.0, 3.0], [0.1, 0.1, 0.2]))
        );
        assert_eq!(parse_pose_line("  # comment", std).unwrap(), None);
        assert!(parse_pose_line("1 2", std)
            .unwrap_err()
            .contains("expected"));
        assert!(parse_pose_line("x y z", std)
            .unwrap_err()
            .contains("not numbers"));
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
