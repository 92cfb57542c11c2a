//! `wmr commission`: the guided first power-up (issue 18,
//! docs/commissioning.md). Each wheel is driven alone in each direction
//! with the robot's wheel test (`Request::WheelTest`: hold only, open
//! loop, at most 20 % of stall torque, at most 2 s, ended by the robot);
//! the counts of both wheels and the gyro's yaw integral are checked
//! against the command and the robot file; the findings are printed in
//! plain words with their numbers and the corrected file proposed.

use crate::link::{Link, LinkError};
use robot_file::{Robot, YawAxis};
use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use wmr_protocol::{
    ErrorCode, Reply, Request, RunStateMsg, WheelTestCmd, WheelTestEnd, WheelTestResult,
};

/// `commission` options.
#[derive(Debug, clap::Args)]
pub struct CommissionArgs {
    /// The robot file the robot runs (TOML).
    #[arg(long, value_name = "FILE.toml")]
    pub robot: PathBuf,
    /// The robot stands on the floor (low torque): the gyro's yaw checks
    /// the encoders' direction and counts per revolution. Without it the
    /// robot is on a stand (wheels free) and you are asked what you saw.
    #[arg(long)]
    pub floor: bool,
    /// Write the proposed robot file here.
    #[arg(short = 'o', long, value_name = "FILE.toml")]
    pub output: Option<PathBuf>,
    /// Push the proposed file to the robot (asks first unless --yes).
    #[arg(long)]
    pub push: bool,
    /// Answer every confirmation with yes (non-interactive).
    #[arg(long)]
    pub yes: bool,
    /// On a stand: what you saw, non-interactive: `R,L` wheel turns of each
    /// wheel's forward test (signed: negative = it turned backwards).
    #[arg(long, value_name = "R,L", allow_hyphen_values = true)]
    pub turns: Option<String>,
    /// Test duration [ms] (at most 2000).
    #[arg(long, default_value_t = 1500, value_name = "MS")]
    pub duration_ms: u16,
}

/// One wrong thing found, with the fix.
#[derive(Clone, Debug, PartialEq)]
pub enum Finding {
    /// The wheel's encoder counts backwards (flip `encoders.inverted[w]`).
    EncoderInverted(usize),
    /// The wheel's motor turns backwards (flip `bridge.motor_inverted[w]`).
    MotorInverted(usize),
    /// Commanding one wheel moved the other wheel's counter: motors or
    /// encoders swapped (a wiring fix: the file cannot swap them).
    Swapped,
    /// The counts per revolution differ from the file (estimate).
    CountsPerRev(f32),
    /// The gyro's yaw sign is opposite (flip `imu.yaw_axis`).
    GyroInverted,
}

const WHEEL: [&str; 2] = ["right", "left"];

fn io(e: std::io::Error) -> LinkError {
    LinkError::Io(e.to_string())
}

/// Runs one wheel test and waits (bounded) for its end; the link is kept
/// alive with status reads, which do not end it, on the link's keep-alive
/// period (was a fixed 100 ms: a robot whose link timeout is under ~300 ms
/// ended the test on link silence).
pub fn wheel_test(link: &mut Link, cmd: WheelTestCmd) -> Result<WheelTestResult, LinkError> {
    let seq = match link.command(&Request::WheelTest(cmd))? {
        Reply::Ack { seq } => seq,
        r => return Err(LinkError::Unexpected(format!("{r:?}"))),
    };
    let deadline = Instant::now() + Duration::from_millis(cmd.duration_ms as u64 + 3000);
    let mut next_keepalive = Instant::now();
    while Instant::now() < deadline {
        if Instant::now() >= next_keepalive {
            link.send(&Request::GetStatus)?;
            next_keepalive = Instant::now() + link.timing().keep_alive;
        }
        for (s, r) in link.receive(Duration::from_millis(20))? {
            if let Reply::WheelTestDone { result, .. } = r {
                if s == seq {
                    return match result.end {
                        WheelTestEnd::Completed => Ok(result),
                        end => Err(LinkError::UnexpectedStop(format!(
                            "wheel test of the {} wheel ended early: {end:?} after {} ticks",
                            WHEEL[result.wheel as usize & 1],
                            result.ticks
                        ))),
                    };
                }
            }
        }
    }
    // Bounded: end it (any request does) and report.
    let _ = link.command(&Request::Disarm);
    Err(LinkError::NoAnswer("wheel test end".into()))
}

/// The test torque \[N·m\]: half of the commissioning cap the robot file
/// implies (20 % of stall, the torque limit, the robot's own torque limit).
pub fn test_torque_nm(robot: &Robot, robot_limit_nm: f32) -> f32 {
    let cap = (wmr_protocol::WHEEL_TEST_STALL_FRACTION * robot.stall_torque_nm())
        .min(robot.limits.torque_nm)
        .min(if robot_limit_nm > 0.0 {
            robot_limit_nm
        } else {
            f32::MAX
        });
    0.5 * cap
}

/// The yaw \[rad\] wheel counts imply on the file's geometry (Eq. 3: ψ =
/// r (φ_R − φ_L) / track).
pub fn wheel_yaw_rad(robot: &Robot, counts: [i32; 2], counts_per_rev: f32) -> f32 {
    let rad_per_count = core::f32::consts::TAU / counts_per_rev;
    robot.mean_wheel_radius_m() * (counts[0] - counts[1]) as f32 * rad_per_count
        / robot.body.track_m
}

/// The findings of the four tests `[right+, right−, left+, left−]`
/// (`seen`: on a stand, the turns the user saw per wheel's forward test).
pub fn analyse(
    robot: &Robot,
    tests: &[WheelTestResult; 4],
    seen: Option<[f32; 2]>,
) -> Result<Vec<Finding>, String> {
    let mut f = Vec::new();
    let cpr = robot.encoders.counts_per_wheel_rev;
    let mut corrected: Vec<[i32; 2]> = Vec::new();
    let mut gyro_disagrees = [false; 2];
    for w in 0..2 {
        let (fwd, rev) = (&tests[2 * w], &tests[2 * w + 1]);
        let me = fwd.counts[w].abs().max(rev.counts[w].abs());
        let other = fwd.counts[1 - w].abs().max(rev.counts[1 - w].abs());
        if me.max(other) < 10 {
            return Err(format!(
                "the {} wheel did not move ({} and {} counts): motor unpowered, a broken wire, or the torque too low for its friction",
                WHEEL[w], fwd.counts[w], rev.counts[w]
            ));
        }
        if other > 2 * me {
            if !f.contains(&Finding::Swapped) {
                f.push(Finding::Swapped);
            }
            continue;
        }
        let counts_forward = fwd.counts[w] > 0 && rev.counts[w] < 0;
        // What the wheel really did: the gyro on the floor (its yaw sign
        // against the counts' yaw), the user on a stand.
        let moved_forward = match (fwd.gyro_yaw_rad, seen) {
            (Some(g), _) if robot_floor_yaw_ok(g) => {
                let wy = wheel_yaw_rad(robot, fwd.counts, cpr);
                let agree = g * wy > 0.0;
                gyro_disagrees[w] = !agree;
                counts_forward == agree
            }
            (_, Some(t)) => t[w] > 0.0,
            _ => {
                return Err(format!(
                    "no gyro yaw and no answer: cannot tell which way the {} wheel turned (give --floor with a gyro, or --turns R,L)",
                    WHEEL[w]
                ))
            }
        };
        match (counts_forward, moved_forward) {
            (true, true) => {}
            (false, true) => f.push(Finding::EncoderInverted(w)),
            (false, false) => f.push(Finding::MotorInverted(w)),
            // Counts forward but the wheel went backwards: both flags
            // wrong, or the gyro's sign (decided over both wheels below).
            (true, false) => {}
        }
    }
    // Both wheels' counts with the encoder fixes applied.
    let enc_sign = |w: usize| {
        if f.contains(&Finding::EncoderInverted(w)) {
            -1
        } else {
            1
        }
    };
    for t in tests {
        corrected.push([t.counts[0] * enc_sign(0), t.counts[1] * enc_sign(1)]);
    }
    if gyro_disagrees == [true, true]
        && !f
            .iter()
            .any(|x| matches!(x, Finding::EncoderInverted(_) | Finding::MotorInverted(_)))
    {
        f.push(Finding::GyroInverted);
    } else {
        for (w, d) in gyro_disagrees.iter().enumerate() {
            let counted_fwd = tests[2 * w].counts[w] > 0;
            if *d && counted_fwd {
                f.push(Finding::EncoderInverted(w));
                f.push(Finding::MotorInverted(w));
            }
        }
    }
    // Counts per revolution against an independent reference.
    let estimate = if f.contains(&Finding::Swapped) {
        None
    } else if let Some(t) = seen {
        let mut est = Vec::new();
        for w in 0..2 {
            if t[w].abs() > 0.1 {
                est.push(tests[2 * w].counts[w].abs() as f32 / t[w].abs());
            }
        }
        (!est.is_empty()).then(|| est.iter().sum::<f32>() / est.len() as f32)
    } else {
        // Eq. (3): ψ_gyro = 2π r (c_R − c_L) / (track · cpr) over the four
        // tests: cpr by least squares, Σ a·ψ / Σ ψ² with a = 2π r Δc / track.
        let gyro_sign = if f.contains(&Finding::GyroInverted) {
            -1.0
        } else {
            1.0
        };
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for (c, t) in corrected.iter().zip(tests) {
            if let Some(g) = t.gyro_yaw_rad {
                let g = g as f64 * gyro_sign;
                let arc = core::f64::consts::TAU
                    * robot.mean_wheel_radius_m() as f64
                    * (c[0] - c[1]) as f64
                    / robot.body.track_m as f64;
                num += arc * g;
                den += g * g;
            }
        }
        (den > 0.05 * 0.05 && num > 0.0).then(|| (num / den) as f32)
    };
    if let Some(e) = estimate {
        if (e / cpr - 1.0).abs() > 0.05 {
            f.push(Finding::CountsPerRev(e));
        }
    }
    Ok(f)
}

fn robot_floor_yaw_ok(g: f32) -> bool {
    g.is_finite() && g.abs() > 0.01
}

fn flip(a: YawAxis) -> YawAxis {
    match a {
        YawAxis::PlusZ => YawAxis::MinusZ,
        YawAxis::MinusZ => YawAxis::PlusZ,
        YawAxis::PlusX => YawAxis::MinusX,
        YawAxis::MinusX => YawAxis::PlusX,
        YawAxis::PlusY => YawAxis::MinusY,
        YawAxis::MinusY => YawAxis::PlusY,
    }
}

/// The robot file with the findings fixed (swaps are left: wiring).
pub fn corrected(robot: &Robot, findings: &[Finding]) -> Robot {
    let mut r = robot.clone();
    for f in findings {
        match f {
            Finding::EncoderInverted(w) => r.encoders.inverted[*w] ^= true,
            Finding::MotorInverted(w) => r.bridge.motor_inverted[*w] ^= true,
            Finding::CountsPerRev(c) => r.encoders.counts_per_wheel_rev = c.round(),
            Finding::GyroInverted => r.imu.yaw_axis = flip(r.imu.yaw_axis),
            Finding::Swapped => {}
        }
    }
    r
}

fn describe(robot: &Robot, f: &Finding) -> String {
    match f {
        Finding::EncoderInverted(w) => format!(
            "the {} encoder counts backwards: the wheel turned forward but counted down (fix: encoders.inverted[{w}] = {})",
            WHEEL[*w], !robot.encoders.inverted[*w]
        ),
        Finding::MotorInverted(w) => format!(
            "the {} motor turns backwards for a forward command (fix: bridge.motor_inverted[{w}] = {})",
            WHEEL[*w], !robot.bridge.motor_inverted[*w]
        ),
        Finding::Swapped => "driving one wheel moved the other wheel's counter: the motors or the encoders are swapped. The robot file cannot swap them: swap the motor leads or the encoder connectors and run commission again".into(),
        Finding::CountsPerRev(c) => format!(
            "counts per wheel revolution: measured {c:.0}, the file says {:.0} ({:+.1} %) (fix: encoders.counts_per_wheel_rev = {:.0})",
            robot.encoders.counts_per_wheel_rev,
            100.0 * (c / robot.encoders.counts_per_wheel_rev - 1.0),
            c.round()
        ),
        Finding::GyroInverted => format!(
            "the gyro's yaw has the opposite sign of the wheels' (fix: imu.yaw_axis = {:?})",
            flip(robot.imu.yaw_axis)
        ),
    }
}

fn confirm(a: &CommissionArgs, question: &str, out: &mut dyn Write) -> Result<bool, LinkError> {
    if a.yes {
        writeln!(out, "{question} yes (--yes)").map_err(io)?;
        return Ok(true);
    }
    write!(out, "{question} [y/N] ").map_err(io)?;
    out.flush().map_err(io)?;
    let mut line = String::new();
    std::io::stdin().lock().read_line(&mut line).map_err(io)?;
    Ok(line.trim().eq_ignore_ascii_case("y"))
}

fn parse_turns(s: &str) -> Result<[f32; 2], LinkError> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| LinkError::Io(format!("--turns '{s}': give R,L turns")))?;
    match v[..] {
        [r, l] if r.is_finite() && l.is_finite() => Ok([r, l]),
        _ => Err(LinkError::Io(format!("--turns '{s}': give R,L turns"))),
    }
}

/// `wmr commission`. `Ok` only when nothing is wrong (or every finding
/// was fixed in the pushed file); findings and unexpected stops are errors.
pub fn commission(
    a: &CommissionArgs,
    link: &mut Link,
    out: &mut dyn Write,
) -> Result<(), LinkError> {
    let text = std::fs::read_to_string(&a.robot)
        .map_err(|e| LinkError::Io(format!("{}: {e}", a.robot.display())))?;
    let robot = Robot::from_toml_str(&text)
        .map_err(|e| LinkError::Io(format!("{}: {e}", a.robot.display())))?;
    let hello = match link.last_hello.clone() {
        Some(h) => h,
        None => link.hello()?,
    };
    match link.command(&Request::GetStatus)? {
        Reply::Status { status, .. } if status.state == RunStateMsg::Hold => {}
        Reply::Status { status, .. } => {
            return Err(LinkError::Io(format!(
                "the robot is {:?}: commissioning needs hold (disarm, clear the stop)",
                status.state
            )))
        }
        r => return Err(LinkError::Unexpected(format!("{r:?}"))),
    }
    let torque = test_torque_nm(&robot, hello.robot.torque_limit_nm);
    writeln!(
        out,
        "commissioning {} ({}): robot {} on {}; each wheel alone, forward then backward, {:.3} N·m open loop for {} ms (cap: 20 % of the file's stall torque {:.2} N·m, torque limit {:.2} N·m, the robot's {:.2} N·m). Abort: Ctrl-C or the button (the robot stops the test itself within {} ms of link silence)",
        robot.name.as_str(),
        a.robot.display(),
        hello.chip,
        if a.floor { "the floor" } else { "a stand" },
        torque,
        a.duration_ms,
        robot.stall_torque_nm(),
        robot.limits.torque_nm,
        hello.robot.torque_limit_nm,
        link.timing().link_timeout.as_millis()
    )
    .map_err(io)?;
    if (hello.robot.torque_limit_nm - robot.limits.torque_nm).abs() > 1e-3 * robot.limits.torque_nm
    {
        writeln!(
            out,
            "limits: the robot's torque limit is {:.3} N·m, the file's {:.3} N·m: the robot does not run this file (push it first)",
            hello.robot.torque_limit_nm, robot.limits.torque_nm
        )
        .map_err(io)?;
    } else {
        writeln!(
            out,
            "limits: torque limit {:.3} N·m as in the file",
            robot.limits.torque_nm
        )
        .map_err(io)?;
    }
    let mut results = Vec::new();
    for w in 0..2u8 {
        for s in [1.0f32, -1.0] {
            let cmd = WheelTestCmd {
                wheel: w,
                torque_nm: s * torque,
                duration_ms: a.duration_ms,
            };
            let r = match wheel_test(link, cmd) {
                Err(LinkError::Nack(_, ErrorCode::AboveTestCap)) => wheel_test(
                    link,
                    WheelTestCmd {
                        torque_nm: 0.5 * cmd.torque_nm,
                        ..cmd
                    },
                )?,
                r => r?,
            };
            writeln!(
                out,
                "{} wheel {}: duty {}, {} ticks, counts right {} left {}, gyro yaw {}",
                WHEEL[w as usize],
                if s > 0.0 { "forward " } else { "backward" },
                r.duty,
                r.ticks,
                r.counts[0],
                r.counts[1],
                r.gyro_yaw_rad
                    .map_or_else(|| "none".into(), |g| format!("{:.4} rad", g))
            )
            .map_err(io)?;
            results.push(r);
        }
    }
    let tests: [WheelTestResult; 4] = [results[0], results[1], results[2], results[3]];
    let seen = match (&a.turns, a.floor) {
        (Some(t), _) => Some(parse_turns(t)?),
        (None, true) => None,
        (None, false) => {
            let mut t = [0.0f32; 2];
            for (w, tw) in t.iter_mut().enumerate() {
                write!(
                    out,
                    "how many turns did the marked {} wheel make in its forward test (negative if backwards)? ",
                    WHEEL[w]
                )
                .map_err(io)?;
                out.flush().map_err(io)?;
                let mut line = String::new();
                std::io::stdin().lock().read_line(&mut line).map_err(io)?;
                *tw = line
                    .trim()
                    .parse()
                    .map_err(|_| LinkError::Io(format!("'{}': not a number", line.trim())))?;
            }
            Some(t)
        }
    };
    let findings = analyse(&robot, &tests, seen).map_err(LinkError::Io)?;
    if findings.is_empty() {
        writeln!(
            out,
            "clean: both encoders count forward for a forward command, each wheel moves only its own counter{}",
            if seen.is_some() || tests[0].gyro_yaw_rad.is_some() {
                ", counts per revolution and gyro sign agree with the file"
            } else {
                ""
            }
        )
        .map_err(io)?;
        return Ok(());
    }
    for f in &findings {
        writeln!(out, "finding: {}", describe(&robot, f)).map_err(io)?;
    }
    let fixed = corrected(&robot, &findings);
    let wiring = findings.contains(&Finding::Swapped);
    if let Some(p) = &a.output {
        std::fs::write(p, fixed.to_toml_string())
            .map_err(|e| LinkError::Io(format!("{}: {e}", p.display())))?;
        writeln!(out, "proposed robot file written to {}", p.display()).map_err(io)?;
    }
    if a.push && !wiring && confirm(a, "push the proposed file to the robot?", out)? {
        // robot-store's `wmr robot push` code path (write, read back,
        // reboot into it, check).
        let path = a
            .output
            .as_deref()
            .ok_or_else(|| LinkError::Io("--push needs -o FILE (the file pushed)".into()))?;
        crate::robot::push(link, path, true, false, out)?;
        writeln!(out, "pushed: run commission again on the fixed file").map_err(io)?;
    }
    Err(LinkError::Io(format!(
        "{} finding(s){}",
        findings.len(),
        if wiring {
            ", a wiring fix among them"
        } else {
            ""
        }
    )))
}
