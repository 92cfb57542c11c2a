//! `wmr status`: the handshake, the run state and every counter.

use crate::link::{Link, LinkError};
use crate::session;
use std::io::Write;

/// Prints the robot's handshake, state, counters and robot record.
pub fn print_status(link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    let hello = session::hello(link)?;
    let s = session::status(link)?;
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
    .map_err(session::io)?;
    writeln!(out, "counters: {:?}", s.counters).map_err(session::io)?;
    writeln!(
        out,
        "external poses refused by the estimator after their ack: {:?}; telemetry frames withheld (non-finite): {}",
        s.pose_rejects, s.nonfinite_telemetry
    )
    .map_err(session::io)?;
    writeln!(
        out,
        "board: last reset {:?}, port rx dropped {}, port rx errors {}",
        s.board.reset_cause, s.board.port_rx_dropped, s.board.port_rx_errors
    )
    .map_err(session::io)?;
    let r = s.robot;
    let source = match r.source {
        wmr_protocol::RobotSource::Builtin => "compiled-in (no robot store)",
        wmr_protocol::RobotSource::Flash => "flash",
        wmr_protocol::RobotSource::DefaultMissing => "compiled-in default (no record in flash)",
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
    .map_err(session::io)?;
    Ok(())
}
