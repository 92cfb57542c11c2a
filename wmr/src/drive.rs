//! `wmr drive`: velocity mode from the command line.

use crate::link::{Link, LinkError};
use crate::session::{self, expect_cause, Motion, Watch};
use clap::Args;
use std::io::Write;
use std::time::{Duration, Instant};
use wmr_protocol::{ErrorCode, Reply, RunStateMsg, StopCode};

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

/// Longest wait for the robot to come to rest after a stop began [s]: its
/// controlled stop is bounded by its own limits (`RobotLimits::stop_bound_s`:
/// the braking ramp from top speed, at most 10 m/s at the least braking
/// deceleration 0.25 m/s², 40 s, then at most 2 s waiting for the wheels
/// at rest), below this.
const STOP_WAIT: Duration = Duration::from_secs(45);

/// `drive`: a velocity command refreshed for `--for` seconds (the refresh
/// is the keep-alive), then left to time out on the robot.
pub fn drive(a: &DriveArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    if !(a.for_s.is_finite() && (0.0..=86_400.0).contains(&a.for_s)) {
        return Err(LinkError::Io("--for must be in [0, 86400] s".into()));
    }
    if a.cmd_timeout_ms == 0 {
        return Err(LinkError::Io("--cmd-timeout-ms must be > 0".into()));
    }
    let cmd = session::velocity(a.v, a.w, a.cmd_timeout_ms);
    link.command(&cmd)?;
    if session::status(link)?.state == RunStateMsg::Hold {
        // Again, so that its timeout runs from just before the arm and not
        // from before the status round trip (with a lost frame or two on a
        // bad line, the two could outlast the command's timeout: the robot
        // would stop at once).
        link.command(&cmd)?;
        Motion::Arm.send(link)?;
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
    writeln!(out, "stopped: {stop}").map_err(session::io)?;
    expect_cause(stop, &[StopCode::VelocityTimeout], "drive")
}
