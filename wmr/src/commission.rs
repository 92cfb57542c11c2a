//! `wmr commission`: the guided first power-up (issue 18,
//! book/src/how-to/commissioning.md). Each wheel is driven alone in each direction
//! with the robot's wheel test (`Request::WheelTest`: hold only, open
//! loop, at most the torque limit, at most 2 s, ended by the robot) at a
//! torque above the wheel's breakaway friction (the file's, raised step by
//! step when the wheel does not move: issue 34, D170); the counts of both
//! wheels and the gyro's yaw integral are checked against the command and
//! the robot file; the findings are printed in plain words with their
//! numbers and the corrected file proposed.

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
    /// Test torque at the wheel [N·m] (0 < T <= the cap: the torque limit)
    /// [default: above the file's Coulomb friction, raised step by step up
    /// to the cap while a wheel does not move].
    #[arg(long, value_name = "N·m")]
    pub torque_nm: Option<f32>,
}

/// Why commissioning could not decide, or failed.
#[derive(Debug, thiserror::Error)]
pub enum CommissionError {
    /// The link or the robot.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The robot file.
    #[error("{path}: {err}")]
    RobotFile {
        /// The file.
        path: String,
        /// Why.
        err: String,
    },
    /// `--torque-nm` out of its range.
    #[error("--torque-nm {value}: {why}")]
    Torque {
        /// The value given.
        value: f32,
        /// The limit and what to do.
        why: String,
    },
    /// `--turns` or an answer is not what was asked.
    #[error("{0}")]
    Answer(String),
    /// The robot is not in hold.
    #[error(
        "the robot is {0}: commissioning needs hold (`wmr disarm`, `wmr clear` a latched stop)"
    )]
    NotInHold(String),
    /// A wheel (or the other wheel's counter) moved less than a test needs.
    #[error(
        "the {wheel} wheel moved {counts} counts at {torque_nm:.3} N·m: below the gearbox's friction? {advice} \
         (a test needs {needed} counts, a tenth of a turn)"
    )]
    TooLittle {
        /// "right" or "left".
        wheel: &'static str,
        /// The larger count change of its tests.
        counts: i32,
        /// The torque of its last test \[N·m\].
        torque_nm: f32,
        /// Counts a test needs.
        needed: i32,
        /// What to do.
        advice: String,
    },
    /// On the floor: a gyro fitted but the robot hardly turned while the
    /// wheel's counter moved.
    #[error(
        "the robot turned {yaw_rad:.4} rad in the {wheel} wheel's test while its counter moved {counts} counts: \
         on the floor one wheel alone turns the robot (at least 0.01 rad): is it on a stand, or the wheel slipping? \
         (on a stand: drop --floor and give --turns R,L)"
    )]
    NoTurn {
        /// "right" or "left".
        wheel: &'static str,
        /// The gyro's yaw \[rad\].
        yaw_rad: f32,
        /// The wheel's counts.
        counts: i32,
    },
    /// On the floor without a gyro reading.
    #[error(
        "no gyro reading in the {0} wheel's test: --floor needs a gyro (the robot reported none): \
         on a stand, drop --floor and give --turns R,L"
    )]
    NoGyro(&'static str),
    /// Findings (the message counts them).
    #[error("{count} finding(s){}", wiring_note(*.wiring))]
    Findings {
        /// How many.
        count: usize,
        /// A wiring fix among them.
        wiring: bool,
    },
    /// The robot refused the test torque as above its own cap.
    #[error(
        "the robot refused the wheel test at {torque_nm:.3} N·m as above its cap (this file implies {cap_nm:.3} N·m): \
         the robot runs another file? push this one (`wmr robot push`), or give a lower --torque-nm"
    )]
    RobotCap {
        /// The torque asked \[N·m\].
        torque_nm: f32,
        /// The cap the file implies \[N·m\].
        cap_nm: f32,
    },
    /// Writing the output.
    #[error("cannot write the output: {0}")]
    Output(String),
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

fn wiring_note(wiring: bool) -> &'static str {
    if wiring {
        ", a wiring fix among them"
    } else {
        ""
    }
}

/// Each step of the ramp multiplies the torque by this while a wheel
/// moves less than [`needed_counts`] (up to the cap).
pub const RAMP_FACTOR: f32 = 1.5;

/// The fraction of a wheel turn a test must move the wheel (its counter,
/// or the other one's when swapped): enough for the gyro's yaw on the
/// floor (a tenth of a turn of a 30 mm wheel on a 140 mm track is 0.13
/// rad, the check needs 0.01) and for a person watching a marked wheel.
pub const MIN_TURN_FRACTION: f32 = 0.1;

/// Counts a test must move: a tenth of a turn, at least 10.
pub fn needed_counts(robot: &Robot) -> i32 {
    ((MIN_TURN_FRACTION * robot.encoders.counts_per_wheel_rev).round() as i32).max(10)
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

/// The wheel test's cap as the file and the robot imply it \[N·m\] (the
/// robot's own check: `wmr_device::wheel_test::torque_cap_nm`): the
/// torque limit (the file's and the robot's), never above the stall
/// torque at the duty limit.
pub fn test_cap_nm(robot: &Robot, robot_limit_nm: f32) -> f32 {
    let stall_at_duty = robot.stall_torque_nm() * robot.bridge.max_duty_fraction;
    stall_at_duty
        .min(robot.limits.torque_nm)
        .min(if robot_limit_nm > 0.0 {
            robot_limit_nm
        } else {
            f32::MAX
        })
}

/// The first test torque \[N·m\]: the file's breakaway (Coulomb) friction
/// plus a margin, the larger of half the friction and a tenth of the
/// stall torque (the torque of a frictionless wheel: it turns a 15 kg
/// robot by 0.2-0.9 rad in a second), at most 90 % of the cap `cap_nm`.
/// The robot file's friction of a small plastic gearbox can be half the
/// torque limit: a fixed tenth of stall did not move such a wheel (issue 34).
pub fn test_torque_nm(robot: &Robot, cap_nm: f32) -> f32 {
    let m = &robot.motors;
    let friction = m.coulomb_friction_nm[0].max(m.coulomb_friction_nm[1]);
    let base = (0.1 * robot.stall_torque_nm() * robot.bridge.max_duty_fraction).min(0.5 * cap_nm);
    (friction + (0.5 * friction).max(base)).min(0.9 * cap_nm)
}

/// `--torque-nm` checked against the cap: the value, or why not.
pub fn check_torque(value: f32, cap_nm: f32) -> Result<f32, CommissionError> {
    let why = if !value.is_finite() || value <= 0.0 {
        Some("must be a torque > 0 N·m (each wheel is driven both ways at it)".to_string())
    } else if value > cap_nm {
        Some(format!(
            "above the wheel test's cap {cap_nm:.3} N·m (the torque limit limits.torque_nm, at most the stall \
             torque at the duty limit): give at most {cap_nm:.3}, or raise limits.torque_nm in the file and push it"
        ))
    } else {
        None
    };
    match why {
        Some(why) => Err(CommissionError::Torque { value, why }),
        None => Ok(value),
    }
}

/// What to do when a wheel moved too little at `torque_nm`.
fn advice(torque_nm: f32, cap_nm: f32, user_torque: bool) -> String {
    if torque_nm < 0.999 * cap_nm {
        // Two decimals up (0.058 -> 0.06), never above the cap.
        let next = ((2.0 * torque_nm) * 100.0).ceil() / 100.0;
        let next = if next > torque_nm && next <= cap_nm {
            next
        } else {
            cap_nm
        };
        format!(
            "try --torque-nm {}{}",
            trim(next),
            if user_torque {
                ""
            } else {
                " (or the motor is unpowered, a wire broken)"
            }
        )
    } else {
        format!(
            "it is the cap (the torque limit {cap_nm:.3} N·m): check the motor's supply and wires, \
             the gearbox (turn the wheel by hand), or limits.torque_nm in the file"
        )
    }
}

/// A torque as the shortest decimal that reads back the same.
fn trim(x: f32) -> String {
    format!("{x}")
}

/// The yaw \[rad\] wheel counts imply on the file's geometry (Eq. 3: ψ =
/// r (φ_R − φ_L) / track).
pub fn wheel_yaw_rad(robot: &Robot, counts: [i32; 2], counts_per_rev: f32) -> f32 {
    let rad_per_count = core::f32::consts::TAU / counts_per_rev;
    robot.mean_wheel_radius_m() * (counts[0] - counts[1]) as f32 * rad_per_count
        / robot.body.track_m
}

/// The findings of the four tests `[right+, right−, left+, left−]`
/// (`seen`: on a stand, the turns the user saw per wheel's forward test;
/// `cap_nm` and `user_torque` phrase the advice when a wheel moved too
/// little).
pub fn analyse(
    robot: &Robot,
    tests: &[WheelTestResult; 4],
    seen: Option<[f32; 2]>,
    cap_nm: f32,
    user_torque: bool,
) -> Result<Vec<Finding>, CommissionError> {
    let mut f = Vec::new();
    let cpr = robot.encoders.counts_per_wheel_rev;
    let mut corrected: Vec<[i32; 2]> = Vec::new();
    let mut gyro_disagrees = [false; 2];
    for w in 0..2 {
        let (fwd, rev) = (&tests[2 * w], &tests[2 * w + 1]);
        let me = fwd.counts[w].abs().max(rev.counts[w].abs());
        let other = fwd.counts[1 - w].abs().max(rev.counts[1 - w].abs());
        let needed = needed_counts(robot);
        if me.max(other) < needed {
            let torque_nm = fwd.torque_nm.abs().max(rev.torque_nm.abs());
            return Err(CommissionError::TooLittle {
                wheel: WHEEL[w],
                counts: me.max(other),
                torque_nm,
                needed,
                advice: advice(torque_nm, cap_nm, user_torque),
            });
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
            (_, Some(t)) => t[w] > 0.0,
            (Some(g), None) if robot_floor_yaw_ok(g) => {
                let wy = wheel_yaw_rad(robot, fwd.counts, cpr);
                let agree = g * wy > 0.0;
                gyro_disagrees[w] = !agree;
                counts_forward == agree
            }
            (Some(g), None) => {
                return Err(CommissionError::NoTurn {
                    wheel: WHEEL[w],
                    yaw_rad: g,
                    counts: fwd.counts[w],
                })
            }
            (None, None) => return Err(CommissionError::NoGyro(WHEEL[w])),
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
    // Both wheels' counts with every encoder fix applied, those the gyro
    // decided above included (a wheel with both its motor and its encoder
    // inverted counts forward while it turns backwards: without its fix
    // here its tests cancel the other wheel's in the least squares below,
    // which then proposed a counts per revolution near 0).
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

fn ask(
    question: &str,
    out: &mut dyn Write,
    input: &mut dyn BufRead,
) -> Result<String, CommissionError> {
    write!(out, "{question} ").map_err(out_err)?;
    out.flush().map_err(out_err)?;
    let mut line = String::new();
    input
        .read_line(&mut line)
        .map_err(|e| CommissionError::Answer(format!("cannot read the answer: {e}")))?;
    Ok(line.trim().to_string())
}

fn out_err(e: std::io::Error) -> CommissionError {
    CommissionError::Output(e.to_string())
}

fn confirm(
    a: &CommissionArgs,
    question: &str,
    out: &mut dyn Write,
    input: &mut dyn BufRead,
) -> Result<bool, CommissionError> {
    if a.yes {
        writeln!(out, "{question} yes (--yes)").map_err(out_err)?;
        return Ok(true);
    }
    Ok(ask(&format!("{question} [y/N]"), out, input)?.eq_ignore_ascii_case("y"))
}

fn parse_turns(s: &str) -> Result<[f32; 2], CommissionError> {
    let bad = || {
        CommissionError::Answer(format!(
            "--turns '{s}': give R,L: the signed turns each marked wheel made in its forward test (e.g. 0.5,-0.5)"
        ))
    };
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    match v[..] {
        [r, l] if r.is_finite() && l.is_finite() => Ok([r, l]),
        _ => Err(bad()),
    }
}

/// Runs one wheel test of `wheel` at `torque_nm` (signed) and prints its line.
fn one_test(
    link: &mut Link,
    wheel: u8,
    torque_nm: f32,
    a: &CommissionArgs,
    cap_nm: f32,
    out: &mut dyn Write,
) -> Result<WheelTestResult, CommissionError> {
    let cmd = WheelTestCmd {
        wheel,
        torque_nm,
        duration_ms: a.duration_ms,
    };
    let r = match wheel_test(link, cmd) {
        Err(LinkError::Nack(_, ErrorCode::AboveTestCap)) => {
            return Err(CommissionError::RobotCap {
                torque_nm: torque_nm.abs(),
                cap_nm,
            })
        }
        r => r?,
    };
    writeln!(
        out,
        "{} wheel {} at {:.3} N·m: duty {}, {} ticks, counts right {} left {}, gyro yaw {}",
        WHEEL[wheel as usize],
        if torque_nm > 0.0 {
            "forward "
        } else {
            "backward"
        },
        torque_nm.abs(),
        r.duty,
        r.ticks,
        r.counts[0],
        r.counts[1],
        r.gyro_yaw_rad
            .map_or_else(|| "none".into(), |g| format!("{:.4} rad", g))
    )
    .map_err(out_err)?;
    Ok(r)
}

/// `wmr commission` reading answers from stdin: see [`commission_with`].
pub fn commission(
    a: &CommissionArgs,
    link: &mut Link,
    out: &mut dyn Write,
) -> Result<(), CommissionError> {
    let stdin = std::io::stdin();
    let mut input = stdin.lock();
    commission_with(a, link, out, &mut input)
}

/// `wmr commission`, the questions answered from `input`. `Ok` only when
/// nothing is wrong; findings (written to `-o`, pushed on confirmation),
/// a wheel that moved too little, and unexpected stops are errors.
pub fn commission_with(
    a: &CommissionArgs,
    link: &mut Link,
    out: &mut dyn Write,
    input: &mut dyn BufRead,
) -> Result<(), CommissionError> {
    let file_err = |e: String| CommissionError::RobotFile {
        path: a.robot.display().to_string(),
        err: e,
    };
    let text = std::fs::read_to_string(&a.robot).map_err(|e| file_err(e.to_string()))?;
    let robot = Robot::from_toml_str(&text).map_err(|e| file_err(e.to_string()))?;
    if a.duration_ms == 0 || a.duration_ms > wmr_protocol::WHEEL_TEST_MAX_MS {
        return Err(CommissionError::Answer(format!(
            "--duration-ms {}: must be in 1..={} ms (the robot ends every test within {} ms)",
            a.duration_ms,
            wmr_protocol::WHEEL_TEST_MAX_MS,
            wmr_protocol::WHEEL_TEST_MAX_MS
        )));
    }
    let seen_given = a.turns.as_deref().map(parse_turns).transpose()?;
    let hello = match link.last_hello.clone() {
        Some(h) => h,
        None => link.hello()?,
    };
    match link.command(&Request::GetStatus)? {
        Reply::Status { status, .. } if status.state == RunStateMsg::Hold => {}
        Reply::Status { status, .. } => {
            return Err(CommissionError::NotInHold(format!("{:?}", status.state)))
        }
        r => return Err(LinkError::Unexpected(format!("{r:?}")).into()),
    }
    let cap = test_cap_nm(&robot, hello.robot.torque_limit_nm);
    let user_torque = a.torque_nm.is_some();
    let torque = match a.torque_nm {
        Some(t) => check_torque(t, cap)?,
        None => test_torque_nm(&robot, cap),
    };
    let needed = needed_counts(&robot);
    let friction = robot.motors.coulomb_friction_nm;
    writeln!(
        out,
        "commissioning {} ({}): robot {} on {}; each wheel alone, forward then backward, open loop for {} ms at {:.3} N·m ({}; cap {:.3} N·m: the torque limit, the file's {:.3}, the robot's {:.3}){}. Abort: Ctrl-C or the button (the robot stops the test itself within {} ms of link silence)",
        robot.name.as_str(),
        a.robot.display(),
        hello.chip,
        if a.floor { "the floor" } else { "a stand" },
        a.duration_ms,
        torque,
        if user_torque {
            "--torque-nm".to_string()
        } else {
            format!(
                "above the file's Coulomb friction {:.3}/{:.3} N·m",
                friction[0], friction[1]
            )
        },
        cap,
        robot.limits.torque_nm,
        hello.robot.torque_limit_nm,
        if user_torque {
            String::new()
        } else {
            format!(
                "; raised x{RAMP_FACTOR} up to the cap while a wheel moves less than {needed} counts (a tenth of a turn)"
            )
        },
        link.timing().link_timeout.as_millis()
    )
    .map_err(out_err)?;
    if (hello.robot.torque_limit_nm - robot.limits.torque_nm).abs() > 1e-3 * robot.limits.torque_nm
    {
        writeln!(
            out,
            "limits: the robot's torque limit is {:.3} N·m, the file's {:.3} N·m: the robot does not run this file (push it first)",
            hello.robot.torque_limit_nm, robot.limits.torque_nm
        )
        .map_err(out_err)?;
    } else {
        writeln!(
            out,
            "limits: torque limit {:.3} N·m as in the file",
            robot.limits.torque_nm
        )
        .map_err(out_err)?;
    }
    let mut results = Vec::new();
    let mut used = [torque; 2];
    for w in 0..2u8 {
        // Forward, raised while the wheel does not move (the measured
        // breakaway), then backward at the torque that moved it.
        let mut tau = torque;
        let fwd = loop {
            let r = one_test(link, w, tau, a, cap, out)?;
            let moved = r.counts[0].abs().max(r.counts[1].abs());
            if moved >= needed || user_torque || tau >= 0.999 * cap {
                break r;
            }
            let next = (RAMP_FACTOR * tau).min(cap);
            writeln!(
                out,
                "the {} wheel moved {moved} counts at {tau:.3} N·m (a test needs {needed}): below its breakaway friction, {next:.3} N·m next",
                WHEEL[w as usize]
            )
            .map_err(out_err)?;
            tau = next;
        };
        let rev = one_test(link, w, -tau, a, cap, out)?;
        used[w as usize] = tau;
        results.push(fwd);
        results.push(rev);
    }
    if !user_torque && used != [torque; 2] {
        writeln!(
            out,
            "breakaway: the wheels moved at {:.3} (right) and {:.3} N·m (left), the file's Coulomb friction is {:.3}/{:.3} N·m: its friction is higher than the file says (`wmr identify` measures it)",
            used[0], used[1], friction[0], friction[1]
        )
        .map_err(out_err)?;
    }
    let tests: [WheelTestResult; 4] = [results[0], results[1], results[2], results[3]];
    let seen = match (seen_given, a.floor) {
        (Some(t), _) => Some(t),
        (None, true) => None,
        (None, false) => {
            let mut t = [0.0f32; 2];
            for (w, tw) in t.iter_mut().enumerate() {
                let line = ask(
                    &format!(
                        "how many turns did the marked {} wheel make in its forward test (negative if backwards)?",
                        WHEEL[w]
                    ),
                    out,
                    input,
                )?;
                *tw = line
                    .parse()
                    .ok()
                    .filter(|x: &f32| x.is_finite())
                    .ok_or_else(|| {
                        CommissionError::Answer(format!(
                        "'{line}': not a number of turns (e.g. 0.5, or -0.5 if it turned backwards)"
                    ))
                    })?;
            }
            Some(t)
        }
    };
    let findings = analyse(&robot, &tests, seen, cap, user_torque)?;
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
        .map_err(out_err)?;
        return Ok(());
    }
    for f in &findings {
        writeln!(out, "finding: {}", describe(&robot, f)).map_err(out_err)?;
    }
    let fixed = corrected(&robot, &findings);
    let wiring = findings.contains(&Finding::Swapped);
    if let Some(p) = &a.output {
        std::fs::write(p, fixed.to_toml_string()).map_err(|e| CommissionError::RobotFile {
            path: p.display().to_string(),
            err: e.to_string(),
        })?;
        writeln!(out, "proposed robot file written to {}", p.display()).map_err(out_err)?;
    }
    if a.push && !wiring && confirm(a, "push the proposed file to the robot?", out, input)? {
        // robot-store's `wmr robot push` code path (write, read back,
        // reboot into it, check).
        let path = a.output.as_deref().ok_or_else(|| {
            CommissionError::Answer("--push needs -o FILE (the file pushed)".into())
        })?;
        crate::robot::push(link, path, true, false, out)?;
        writeln!(out, "pushed: run commission again on the fixed file").map_err(out_err)?;
    }
    Err(CommissionError::Findings {
        count: findings.len(),
        wiring,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tb6612() -> Robot {
        let t = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../robots/tb6612-2kg.toml"
        ))
        .unwrap();
        Robot::from_toml_str(&t).unwrap()
    }

    /// The first torque is above the file's Coulomb friction by at least
    /// half of it, below 90 % of the cap; a frictionless robot gets a
    /// tenth of stall (at the duty limit), as before.
    #[test]
    fn the_test_torque_is_above_the_friction_and_below_the_cap() {
        let mut r = tb6612();
        let stall = r.stall_torque_nm() * r.bridge.max_duty_fraction;
        let cap = test_cap_nm(&r, 0.0);
        assert_eq!(cap, r.limits.torque_nm.min(stall));
        for c in [0.0f32, 0.03, 0.1, 0.15, 0.2] {
            r.motors.coulomb_friction_nm = [c, 0.5 * c];
            let t = test_torque_nm(&r, cap);
            assert!(t <= 0.9 * cap + 1e-6, "{c}: {t}");
            if c < 0.6 * cap {
                assert!(t >= 1.5 * c - 1e-6, "{c}: {t}");
            }
            if c == 0.0 {
                assert!((t - 0.1 * stall).abs() < 1e-6, "{t}");
            }
        }
        // The robot's smaller limit caps it.
        assert_eq!(test_cap_nm(&r, 0.1), 0.1);
    }

    /// `--torque-nm`: the value, or the limit and what to do.
    #[test]
    fn the_torque_option_is_checked_against_the_cap() {
        assert_eq!(check_torque(0.05, 0.12).unwrap(), 0.05);
        for bad in [0.0, -0.1, f32::NAN] {
            let e = check_torque(bad, 0.12).unwrap_err().to_string();
            assert!(e.contains("must be a torque > 0"), "{e}");
        }
        let e = check_torque(0.2, 0.12).unwrap_err().to_string();
        assert!(
            e.starts_with("--torque-nm 0.2: above the wheel test's cap 0.120 N·m")
                && e.contains("give at most 0.120"),
            "{e}"
        );
    }

    /// The advice doubles the torque (rounded up to 0.01 N·m) within the
    /// cap, the cap itself past it, and at the cap says what else to check.
    /// A wheel with both its motor and its encoder inverted, on the floor
    /// with a gyro, synthesised from eq. (3) (ψ = r·(φ_R − φ_L)/track): both
    /// flags are found, and the counts per revolution are checked against
    /// the gyro with that wheel's counts fixed (a file 20 % off is
    /// corrected to the true value; a right file gets no finding).
    #[test]
    fn a_wheel_with_motor_and_encoder_inverted_keeps_the_counts_check() {
        let robot = Robot::paper();
        let true_cpr = robot.encoders.counts_per_wheel_rev;
        let (r, track) = (robot.mean_wheel_radius_m(), robot.body.track_m);
        let half_turn = (0.5 * true_cpr) as i32;
        // [right+, right−, left+, left−]: the physical half-turns, the right
        // wheel driven backwards by its inverted motor.
        let physical = [[-1, 0], [1, 0], [0, 1], [0, -1]];
        let tests: [WheelTestResult; 4] = core::array::from_fn(|i| {
            let p = physical[i];
            let yaw = r * (p[0] - p[1]) as f32 * core::f32::consts::PI / track;
            WheelTestResult {
                wheel: (i / 2) as u8,
                torque_nm: if i % 2 == 0 { 1.0 } else { -1.0 },
                duty: 0,
                ticks: 1000,
                end: WheelTestEnd::Completed,
                // The right encoder inverted: it counts the opposite.
                counts: [-p[0] * half_turn, p[1] * half_turn],
                gyro_yaw_rad: Some(yaw),
            }
        });
        let f = analyse(&robot, &tests, None, 2.0, false).unwrap();
        assert!(f.contains(&Finding::EncoderInverted(0)), "{f:?}");
        assert!(f.contains(&Finding::MotorInverted(0)), "{f:?}");
        assert!(
            !f.iter().any(|x| matches!(x, Finding::CountsPerRev(_))),
            "{f:?}"
        );
        let mut off = robot.clone();
        off.encoders.counts_per_wheel_rev = 1.2 * true_cpr;
        let f = analyse(&off, &tests, None, 2.0, false).unwrap();
        let c = f
            .iter()
            .find_map(|x| match x {
                Finding::CountsPerRev(c) => Some(*c),
                _ => None,
            })
            .expect("the 20 % error is found");
        assert!((c / true_cpr - 1.0).abs() < 1e-3, "{c} vs {true_cpr}");
    }

    #[test]
    fn the_advice_names_the_torque_to_try() {
        assert!(advice(0.029, 0.12, true).starts_with("try --torque-nm 0.06"));
        assert!(advice(0.08, 0.12, true).starts_with("try --torque-nm 0.12"));
        assert!(advice(0.12, 0.12, false).contains("it is the cap"));
    }
}
