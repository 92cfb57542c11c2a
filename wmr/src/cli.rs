//! The `wmr` command line: argument parsing and dispatch. Each command's
//! logic is in its module ([`crate::status`], [`crate::upload`],
//! [`crate::drive`], [`crate::params`], [`crate::record`],
//! [`crate::pose_feed`], [`crate::identify`], [`crate::watch`],
//! [`crate::commission`], [`crate::bringup`], [`crate::robot`],
//! [`crate::serve`]), the link's
//! session (clock, keep-alive, segment streaming, motion commands) in
//! [`crate::session`]. Everything is library code ([`execute`]) so tests
//! drive it in-process over a pseudo-terminal.

use crate::link::{Link, LinkError};
use crate::session::{io, Motion};
use clap::{Parser, Subcommand};
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

// The argument types and the commands' entry points by their old paths
// (`wmr::cli::RecordArgs`, `wmr::cli::record`, ...): the same items, not
// copies.
pub use crate::drive::DriveArgs;
pub use crate::params::{ParamsArgs, ParamsOp};
pub use crate::pose_feed::PoseFeedArgs;
pub use crate::record::{record, MetricsArgs, MetricsSummary, RecordArgs, RecordSummary};
pub use crate::robot::{RobotArgs, RobotOp};
pub use crate::upload::UploadArgs;
pub use crate::watch::WatchArgs;

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
    Upload(crate::upload::UploadArgs),
    /// Drive with a velocity command refreshed for a while, then let it time out.
    Drive(crate::drive::DriveArgs),
    /// Read or write parameters.
    Params(crate::params::ParamsArgs),
    /// Record telemetry to a CSV (the columns of `hil-sim run --csv`) and print
    /// the metrics as JSON.
    Record(crate::record::RecordArgs),
    /// Forward external poses from stdin lines or a UDP port
    /// (`x y theta [sx sy stheta] [@capture_time]`).
    PoseFeed(crate::pose_feed::PoseFeedArgs),
    /// Identify the robot: drive the excitation and record (`run`), fit a log (`fit`).
    Identify(crate::identify::IdentifyArgs),
    /// A compact live status line (state, pose, speed, errors, health,
    /// counters) from telemetry.
    Watch(crate::watch::WatchArgs),
    /// The run metrics of a log, a trace CSV or an MCAP file (no robot
    /// needed): the numbers `record` prints.
    Metrics(crate::record::MetricsArgs),
    /// Guided first power-up: each wheel driven alone, wiring and the robot
    /// file checked, the corrected file proposed (book/src/how-to/commissioning.md).
    Commission(crate::commission::CommissionArgs),
    /// Guided bring-up: commission, identification run, fit, tune, push,
    /// verification; each step resumable (book/src/how-to/bringup.md).
    Bringup(crate::bringup::BringupArgs),
    /// The robot file in the robot's flash: push, pull, diff, check.
    Robot(crate::robot::RobotArgs),
    /// Own the link to --port and serve every other command (and any
    /// number of clients) over a local socket (`wmr --serve SOCKET CMD`).
    Serve(crate::serve::ServeArgs),
}

/// Exit status of a command that failed: the one line after `error: ` on
/// stderr says why.
pub const EXIT_ERROR: i32 = 1;

/// Every exit status of `wmr` but clap's usage error (the book's
/// reference, errors.md, adds it from clap).
pub const EXIT_CODES: [(i32, &str); 2] = [
    (0, "the command succeeded"),
    (
        EXIT_ERROR,
        "the command failed: the line after `error:` on stderr says why (the link, the robot's refusal, a file)",
    ),
];

/// Why a command line failed.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The link or the robot.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// A log file (`metrics`).
    #[error(transparent)]
    Log(#[from] ros_mcap::LogError),
    /// `identify fit`.
    #[error(transparent)]
    Fit(#[from] crate::identify::FitError),
    /// `serve`.
    #[error(transparent)]
    Serve(#[from] crate::serve::ServeError),
    /// `commission`.
    #[error(transparent)]
    Commission(#[from] crate::commission::CommissionError),
    /// `bringup`.
    #[error(transparent)]
    Bringup(#[from] crate::bringup::BringupError),
    /// `wmr serve` without `--port`.
    #[error("wmr serve needs --port PATH (or WMR_PORT): the robot's port")]
    ServeNeedsPort,
    /// Writing the output.
    #[error("cannot write the output: {0}")]
    Output(String),
}

fn link_of(cli: &Cli) -> Result<Link, LinkError> {
    // Through a server when one is named or serves --port; every host-side
    // time derives from the robot's link timeout.
    let ep = crate::serve::Endpoint::resolve(cli.port.as_deref(), cli.serve.as_deref())?;
    crate::serve::open_link(&ep, cli.timeout_ms.map(Duration::from_millis))
}

/// Runs a parsed command line; `Err` is the one line the binary prints
/// after `error: `.
pub fn execute(cli: &Cli, out: &mut dyn Write) -> Result<(), String> {
    dispatch(cli, out).map_err(|e| e.to_string())
}

/// Runs a parsed command line: the commands without a robot here, the
/// others on a fresh link to `--port` (or its server) by [`run`].
pub fn dispatch(cli: &Cli, out: &mut dyn Write) -> Result<(), CliError> {
    match &cli.command {
        Command::Identify(crate::identify::IdentifyArgs {
            op: crate::identify::IdentifyOp::Fit(a),
        }) => Ok(crate::identify::fit(a, out)?), // a log, no robot
        Command::Metrics(a) => {
            let m = crate::record::metrics_of_file(&a.file)?;
            if let Some(r) = &m.report {
                eprintln!("{r}");
            }
            let json = serde_json::to_string(&m).map_err(|e| CliError::Output(e.to_string()))?;
            writeln!(out, "{json}").map_err(|e| CliError::Output(e.to_string()))
        }
        Command::Robot(RobotArgs {
            op: RobotOp::Check { file },
        }) => Ok(crate::robot::check(file, out)?),
        Command::Serve(a) => {
            let port = cli.port.as_deref().ok_or(CliError::ServeNeedsPort)?;
            Ok(crate::serve::serve(port, a, out)?)
        }
        Command::Commission(a) => {
            let mut link = link_of(cli)?;
            Ok(crate::commission::commission(a, &mut link, out)?)
        }
        Command::Bringup(a) => {
            let mut link = link_of(cli)?;
            Ok(crate::bringup::bringup(a, &mut link, out)?)
        }
        cmd => {
            let mut link = link_of(cli)?;
            Ok(run(cmd, &mut link, out)?)
        }
    }
}

/// Runs one command on an open link (after the handshake). The commands
/// that need no robot (`metrics`, `identify fit`, `robot check`, `serve`)
/// are [`dispatch`]'s.
pub fn run(cmd: &Command, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    let said = |out: &mut dyn Write, s: &str| writeln!(out, "{s}").map_err(io);
    match cmd {
        Command::Status => crate::status::print_status(link, out),
        Command::Arm => {
            Motion::Arm.send(link)?;
            said(
                out,
                "armed; the robot brakes to a stop after link_timeout_ms without a frame: keep `wmr record` or `wmr pose-feed` running",
            )
        }
        Command::Disarm => {
            Motion::Disarm.send(link)?;
            said(out, "disarmed")
        }
        Command::Estop => {
            Motion::EmergencyStop.send(link)?;
            said(out, "emergency stop latched (clear with `wmr clear`)")
        }
        Command::Clear => {
            Motion::ClearStop.send(link)?;
            said(out, "stop cleared: hold")
        }
        Command::Upload(a) => crate::upload::upload(a, link, out),
        Command::Drive(a) => crate::drive::drive(a, link, out),
        Command::Params(a) => crate::params::params(&a.op, link, out),
        Command::Record(a) => crate::record::record(a, link, out),
        Command::PoseFeed(a) => crate::pose_feed::pose_feed(a, link, out),
        Command::Identify(a) => match &a.op {
            crate::identify::IdentifyOp::Run(r) => crate::identify::run(r, link, out),
            crate::identify::IdentifyOp::Fit(_) => Err(LinkError::Io(
                "identify fit reads a log: it does not run on a link".into(),
            )),
        },
        Command::Watch(a) => crate::watch::watch(a, link, out),
        Command::Commission(a) => {
            crate::commission::commission(a, link, out).map_err(|e| match e {
                crate::commission::CommissionError::Link(l) => l,
                e => LinkError::Io(e.to_string()),
            })
        }
        Command::Bringup(a) => crate::bringup::bringup(a, link, out).map_err(|e| match e {
            crate::bringup::BringupError::Link(l) => l,
            e => LinkError::Io(e.to_string()),
        }),
        Command::Robot(a) => crate::robot::robot(&a.op, link, out),
        Command::Metrics(_) => Err(LinkError::Io(
            "wmr metrics reads a file: it does not run on a link".into(),
        )),
        Command::Serve(_) => Err(LinkError::Io(
            "wmr serve owns a port: it does not run on a link".into(),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wmr_protocol::ErrorCode;

    #[test]
    fn one_line_errors() {
        let e = LinkError::Nack("Arm".into(), ErrorCode::NoReference);
        // The refusal, then the command that gets out of it.
        assert!(e.to_string().starts_with(
            "the robot refused Arm: no reference, trajectory or velocity command loaded; \
             load one first: `wmr upload FILE`"
        ));
        let e = Link::open("/dev/no-such-port", Duration::from_millis(10))
            .err()
            .unwrap();
        // What happened, the port, what to do.
        let s = e.to_string();
        assert!(
            s.starts_with("no such port: /dev/no-such-port: ") && s.contains("--port PATH"),
            "{s}"
        );
        // Not a terminal: /dev/null exists everywhere and is no tty.
        let e = Link::open("/dev/null", Duration::from_millis(10))
            .err()
            .unwrap();
        assert!(
            matches!(
                e,
                LinkError::Open {
                    kind: crate::OpenFailure::NotATerminal,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(e.to_string().contains("not a serial port"), "{e}");
        for e in [
            LinkError::NoAnswer("Hello".into()),
            LinkError::Silent {
                port: "/dev/pts/9".into(),
                request: "Hello".into(),
                tries: 3,
                each_ms: 100,
            },
            LinkError::Lost {
                port: "/dev/pts/9".into(),
                detail: "Broken pipe".into(),
            },
        ] {
            let s = e.to_string();
            assert!(!s.contains('\n') && !s.contains("link error"), "{s}");
        }
        let s = LinkError::Silent {
            port: "/dev/pts/9".into(),
            request: "Hello".into(),
            tries: 3,
            each_ms: 100,
        }
        .to_string();
        assert!(
            s.contains("/dev/pts/9 to Hello (sent 3 times, 100 ms apart)"),
            "{s}"
        );
    }

    /// Every subcommand parses to the variant `run` or `dispatch` handles
    /// (clap's own consistency check of the derived parser).
    #[test]
    fn the_parser_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }
}
