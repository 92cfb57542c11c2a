//! `wmr pose-feed`: external poses from stdin lines or a UDP port, each
//! stamped in robot time through the session's clock
//! ([`crate::session::ClockTracker`]) and sent as an `ExternalPose`.

use crate::link::{Link, LinkError};
use crate::session::{self, io, Capture, ClockTracker, PoseClock, PoseTally};
use clap::Args;
use std::io::{BufRead, Write};
use std::time::{Duration, Instant};

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

/// Why a pose line is not a pose.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PoseLineError {
    /// Two `@` words.
    #[error("two capture times in {0:?}")]
    TwoCaptureTimes(String),
    /// `@` and no number.
    #[error("capture time {0:?} is not a number")]
    CaptureNotANumber(String),
    /// Neither a Unix time nor a recent age.
    #[error(
        "capture time {0:?}: give Unix seconds (@1764632000.125) or an age up to {MAX_AGE_S} s before arrival (@-0.08)"
    )]
    CaptureOutOfRange(String),
    /// A word that is no number.
    #[error("not numbers: {0:?}")]
    NotNumbers(String),
    /// Neither 3 nor 6 numbers.
    #[error("{0} numbers, expected `x y theta [sx sy stheta] [@capture_time]`")]
    Count(usize),
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
pub fn parse_pose_line(line: &str, std: [f32; 3]) -> Result<Option<PoseLine>, PoseLineError> {
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
                return Err(PoseLineError::TwoCaptureTimes(line.into()));
            }
            let t: f64 = t
                .parse()
                .map_err(|_| PoseLineError::CaptureNotANumber(word.into()))?;
            capture = if t.is_finite() && t < 0.0 && -t <= MAX_AGE_S {
                Capture::AgoS(-t)
            } else if t.is_finite() && t >= MIN_UNIX_S {
                Capture::UnixS(t)
            } else {
                return Err(PoseLineError::CaptureOutOfRange(word.into()));
            };
        } else {
            nums.push(
                word.parse::<f32>()
                    .map_err(|_| PoseLineError::NotNumbers(line.into()))?,
            );
        }
    }
    let v = nums;
    let (pose, std) = match v.len() {
        3 => ([v[0], v[1], v[2]], std),
        6 => ([v[0], v[1], v[2]], [v[3], v[4], v[5]]),
        n => return Err(PoseLineError::Count(n)),
    };
    Ok(Some(PoseLine { pose, std, capture }))
}

/// Feeds pose lines from `lines` (numbered from 1) to the robot; returns
/// the tally. Each line is stamped in robot time: at its capture time when
/// it gives one, else when it arrives. `at_arrival` gives, as each line
/// arrives, the clock and the arrival time on its host clock \[µs\]
/// (`pose-feed`: its [`ClockTracker`], re-synced when due; a test: its own).
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
                let sent = at_arrival(link).and_then(|(clock, arrival)| {
                    link.command(&clock.request(p.pose, p.std, p.capture, arrival))
                });
                match sent {
                    Ok(_) => tally.accepted(),
                    Err(LinkError::Nack(_, e)) => {
                        tally.refused(e);
                        eprintln!("line {n}: refused: {}", e.reason());
                    }
                    Err(LinkError::NoAnswer(what) | LinkError::Silent { request: what, .. }) => {
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

/// `pose-feed`: lines from stdin or UDP datagrams until the input ends
/// (or the robot answers no pose for [`POSE_FEED_GIVE_UP`]); prints the
/// tally.
pub fn pose_feed(a: &PoseFeedArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    let period_s = session::hello(link)?.robot.control_period_s;
    let mut sync = ClockTracker::start(link, period_s, 1)?;
    // Re-synced before a line when the last sync is older than the link's
    // keep-alive period (one exchange), so that its stamps follow the
    // robot's clock as it drifts (the arrival read before the round trip:
    // the stamp errs early).
    let keep_alive = link.timing().keep_alive;
    let mut at_arrival = |l: &mut Link| -> Result<(PoseClock, u64), LinkError> {
        let arrival = sync.host_us();
        if sync.last_sync().elapsed() >= keep_alive {
            sync.resync(l)?;
        }
        Ok((sync.pose_clock(), arrival))
    };
    let std = [a.std[0], a.std[1], a.std[2]];
    let mut tally = PoseTally::default();
    match &a.udp {
        None => {
            let lines = std::io::stdin().lock().lines().map(|l| l.map_err(io));
            feed_lines(link, &mut at_arrival, std, lines, &mut tally)?;
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
                feed_lines(link, &mut at_arrival, std, lines.into_iter(), &mut tally)?;
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

#[cfg(test)]
mod tests {
    use super::*;

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
            let e = parse_pose_line(bad, std).unwrap_err().to_string();
            assert!(e.contains("capture time"), "{bad}: {e}");
        }
        assert_eq!(parse_pose_line("  # comment", std).unwrap(), None);
        assert_eq!(parse_pose_line("1 2", std), Err(PoseLineError::Count(2)));
        assert!(parse_pose_line("x y z", std)
            .unwrap_err()
            .to_string()
            .contains("not numbers"));
    }
}
