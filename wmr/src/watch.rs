//! `wmr watch`: one compact status line per telemetry frame at `--rate`
//! ([`LiveStatus`]), the link kept alive meanwhile by the session's
//! telemetry stream.

use crate::link::{Link, LinkError};
use crate::session::{self, TelemetryStream};
use clap::Args;
use std::io::Write;
use wmr_protocol::{Event, Reply, StopCode};

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

/// `watch`: one status line per telemetry frame at `--rate`, the link
/// kept alive meanwhile; ends after `--seconds` of robot time.
pub fn watch(a: &WatchArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    if a.rate == 0 || a.rate > 100 {
        return Err(LinkError::Io("--rate must be in 1..=100 lines/s".into()));
    }
    if let Some(s) = a.seconds {
        if !(s.is_finite() && s > 0.0) {
            return Err(LinkError::Io("--seconds must be > 0".into()));
        }
    }
    let mut stream = TelemetryStream::start(link, a.rate)?;
    let mut first_us: Option<u32> = None;
    let mut status = LiveStatus::default();
    // Through `wmr serve` telemetry comes at the highest rate any client
    // asked for: one line per 1/rate of robot time (half a tick's slack).
    let line_us = 1_000_000 / a.rate as u32;
    let mut last_line_us: Option<u32> = None;
    loop {
        match stream.next(link)? {
            Some(Reply::Telemetry(t)) => {
                let first = *first_us.get_or_insert(t.t_robot_us);
                if last_line_us.is_none_or(|l| t.t_robot_us.wrapping_sub(l) + 500 >= line_us) {
                    writeln!(out, "{}", status.line(&t)).map_err(session::io)?;
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
    }
    stream.stop(link);
    Ok(())
}

/// `wmr watch`'s compact status line of each telemetry frame, and the
/// last stop seen in events.
#[derive(Clone, Debug, Default)]
pub struct LiveStatus {
    last_stop: Option<StopCode>,
}

impl LiveStatus {
    /// Notes a stop cause from an event.
    pub fn event(&mut self, e: &Event) {
        if let Event::StateChanged { cause: Some(c), .. } = e {
            self.last_stop = Some(*c);
        }
    }

    /// One line: robot time, state, pose of G, speed, errors, torque,
    /// health and reason, the last stop, counters (`-` for a group the
    /// frame lacks).
    pub fn line(&self, t: &wmr_protocol::Telemetry) -> String {
        use std::fmt::Write as _;
        let mut s = format!(
            "{:>9.3} s {:<8}",
            t.t_robot_us as f64 * 1e-6,
            format!("{:?}", t.state)
        );
        match &t.tracking {
            Some(tr) => {
                let ex = tr.ref_pose.x_m - tr.pose.x_m;
                let ey = tr.ref_pose.y_m - tr.pose.y_m;
                let reason = track_log::HEALTH_REASONS
                    .get(tr.health_reason as usize)
                    .copied()
                    .unwrap_or("?");
                let health = ["nominal", "degraded", "safe stop"]
                    .get(tr.health as usize)
                    .copied()
                    .unwrap_or("?");
                let _ = write!(
                    s,
                    " | G {:.3} {:.3} m {:.3} rad | v {:.3} m/s w {:.3} rad/s | err {:.3} m (e {:.3} {:.3} m {:.3} rad) | tau {:.2} {:.2} N·m{} | {health} ({reason})",
                    tr.pose.x_m,
                    tr.pose.y_m,
                    tr.pose.theta_rad,
                    tr.eta[0],
                    tr.eta[1],
                    (ex * ex + ey * ey).sqrt(),
                    tr.error[0],
                    tr.error[1],
                    tr.error[2],
                    tr.torque_nm[0],
                    tr.torque_nm[1],
                    if tr.saturated { " sat" } else { "" },
                );
            }
            None => s.push_str(" | no tracking telemetry"),
        }
        match self.last_stop {
            Some(c) => {
                let _ = write!(s, " | last stop {c:?}");
            }
            None => s.push_str(" | last stop -"),
        }
        if let Some(c) = &t.counters {
            let _ = write!(
                s,
                " | ext poses {} stops {} enc jumps {} overruns {} rx err {} tx drop {} nacks {}",
                c.external_poses,
                c.stops,
                c.encoder_jumps,
                c.overruns,
                c.rx_errors,
                c.tx_dropped,
                c.nacks
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wmr_protocol::{Counters, PoseMsg, RunStateMsg, Telemetry, TrackingTelemetry};

    #[test]
    fn live_line_shows_state_pose_error_health_stop_and_counters() {
        let mut live = LiveStatus::default();
        let mut t = Telemetry {
            seq: 1,
            t_robot_us: 12_345_000,
            t_ref_s: 1.0,
            state: RunStateMsg::Running,
            tracking: Some(TrackingTelemetry {
                pose: PoseMsg {
                    x_m: 1.0,
                    y_m: 2.0,
                    theta_rad: 0.5,
                },
                ref_pose: PoseMsg {
                    x_m: 1.3,
                    y_m: 2.4,
                    theta_rad: 0.5,
                },
                eta: [0.25, -0.125],
                health: 1,
                health_reason: 1,
                ..Default::default()
            }),
            estimators: None,
            counters: Some(Counters {
                external_poses: 7,
                nacks: 2,
                ..Default::default()
            }),
            covariance: None,
        };
        let l = live.line(&t);
        for part in [
            "12.345 s Running",
            "G 1.000 2.000 m 0.500 rad",
            "v 0.250 m/s w -0.125 rad/s",
            // |(0.3, 0.4)| = 0.5 m.
            "err 0.500 m",
            "degraded (saturation)",
            "last stop -",
            "ext poses 7",
            "nacks 2",
        ] {
            assert!(l.contains(part), "{part:?} not in {l:?}");
        }
        assert!(!l.contains('\n'));
        live.event(&Event::StateChanged {
            state: RunStateMsg::Stopped,
            cause: Some(StopCode::EncoderJump),
        });
        t.tracking = None;
        t.state = RunStateMsg::Stopped;
        let l = live.line(&t);
        assert!(
            l.contains("Stopped")
                && l.contains("last stop EncoderJump")
                && l.contains("no tracking"),
            "{l}"
        );
    }
}
