//! `wmr identify run` and `wmr identify fit`: drive the identification
//! excitation and record it, then fit the robot's parameters from the log
//! (robot-identify; book/src/how-to/identification.md).
//!
//! `run` uploads the excitation as streamed waypoints (the `upload --arm`
//! path: no protocol change), records every telemetry frame at the asked
//! rate into the identification CSV while streaming, and stops like any
//! run: the trajectory's end is the success; any other stop, or silence
//! beyond the link timing, is an error after the log up to it is written.
//! Every wait is bounded.

use crate::link::{Link, LinkError};
use crate::session::{Motion, Pump, SegmentStream};
use clap::{Args, Subcommand};
use robot_identify::excitation::{check, waypoints};
use robot_identify::{identify, read_id_csv, write_id_csv, FitOptions, IdRow, Prior, RowBuilder};
use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use wmr_protocol::{Event, Reply, Request, RunStateMsg, StopCode, TELEMETRY_ALL};

/// `identify` options.
#[derive(Debug, Args)]
pub struct IdentifyArgs {
    /// run or fit.
    #[command(subcommand)]
    pub op: IdentifyOp,
}

/// `identify` operations.
#[derive(Debug, Subcommand)]
pub enum IdentifyOp {
    /// Drive the excitation and record the identification log.
    Run(RunArgs),
    /// Fit the robot's parameters from an identification log.
    Fit(FitArgs),
}

/// `identify run` options.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Identification log to write (CSV).
    #[arg(short = 'o', long = "out", value_name = "LOG.csv")]
    pub out: PathBuf,
    /// Peak linear velocity [m/s].
    #[arg(long, default_value_t = 0.5)]
    pub v_amp: f32,
    /// Peak yaw rate [rad/s].
    #[arg(long, default_value_t = 1.0)]
    pub w_amp: f32,
    /// Base angular frequency of the sinusoids [rad/s].
    #[arg(long, default_value_t = 1.5)]
    pub w_base: f32,
    /// Length of the run [s].
    #[arg(long, default_value_t = 60.0)]
    pub duration: f32,
    /// The run must stay within this distance of its start [m].
    #[arg(long, default_value_t = 2.5)]
    pub area: f32,
    /// Telemetry rate [Hz] [default: the highest of 1000, 500, 250, 200,
    /// 100 Hz the link carried without loss in a 0.5 s probe in hold].
    #[arg(long)]
    pub rate: Option<u16>,
    /// The robot file of the robot (book/src/how-to/robot-file.md): its mass, inertia,
    /// wheel inertia and d enter the torque check of the excitation, and
    /// the log carries it for `identify fit` [default: the file the robot
    /// runs, read from its store; a robot that cannot tell gets a body of
    /// the handshake's mass, r and h (a uniform disc of radius h + r, said
    /// on the output) and a log without a robot file].
    #[arg(long, value_name = "FILE.toml")]
    pub robot: Option<PathBuf>,
}

/// `identify fit` options.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Identification log (from `wmr identify run`).
    #[arg(value_name = "LOG.csv")]
    pub log: PathBuf,
    /// The robot as configured when the log was recorded: a robot file
    /// (book/src/how-to/robot-file.md), or a flat TOML of `RobotParams` and `MotorParams`
    /// keys (`mass_kg`, ..., `duty_full_scale`, `control_period_s`,
    /// `speed_window_ticks`) [default: the robot file the log carries,
    /// which `wmr identify run` writes when it knows the robot; a log
    /// without one is refused].
    #[arg(long, value_name = "PRIOR.toml")]
    pub robot: Option<PathBuf>,
    /// PWM timer clock of the robot's board [Hz] (with a robot file: the
    /// duty's full scale is clock / bridge.pwm_frequency_hz) [default: the
    /// log's, which `wmr identify run` writes from the board the robot
    /// names in its handshake].
    #[arg(long)]
    pub timer_clock_hz: Option<u32>,
    /// Write the identified robot: the prior's robot file with the
    /// identified values (the report in its header comment); a flat TOML
    /// with a flat prior.
    #[arg(short = 'o', long = "out", value_name = "OUT.toml")]
    pub out: Option<PathBuf>,
    /// Savitzky-Golay window [s].
    #[arg(long, default_value_t = 0.15)]
    pub filter_window: f64,
    /// The robot's weighed mass [kg] (a kitchen scale; with its battery and
    /// everything it carries): taken as known, it fixes the scale the log
    /// cannot see, and the motor's torque per volt a = η_g·N·k/R is
    /// identified (written as motors.gear_efficiency) [default: a from the
    /// robot file; the report then says what is and is not identified].
    #[arg(long, value_name = "KG")]
    pub mass_kg: Option<f64>,
    /// For a trace CSV (`hil-sim run --csv`, `wmr record`): its pose column
    /// is a measurement of the true pose (hil-sim's traces), not the
    /// robot's own estimate, so the radii and the track are identified.
    #[arg(long)]
    pub pose_measured: bool,
}

fn io(e: std::io::Error) -> LinkError {
    LinkError::Io(e.to_string())
}

/// The prior of `--robot` (or the paper robot with the example motor).
pub fn prior_from_toml(text: &str, origin: &str) -> Result<Prior, String> {
    let table: toml::Table =
        toml::from_str(text).map_err(|e| format!("{origin}: {}", e.to_string().trim_end()))?;
    let mut p = Prior::paper();
    for (k, v) in &table {
        let x = match v {
            toml::Value::Float(f) => *f,
            toml::Value::Integer(i) => *i as f64,
            _ => return Err(format!("{origin}: `{k}` must be a number")),
        };
        let f = x as f32;
        match k.as_str() {
            "mass_kg" => p.robot.mass_kg = f,
            "inertia_kgm2" => p.robot.inertia_kgm2 = f,
            "wheel_inertia_kgm2" => p.robot.wheel_inertia_kgm2 = f,
            "wheel_radius_m" => p.robot.wheel_radius_m = f,
            "half_track_m" => p.robot.half_track_m = f,
            "com_offset_m" => p.robot.com_offset_m = f,
            "torque_constant_nm_per_a" => p.motor.torque_constant_nm_per_a = f,
            "winding_resistance_ohm" => p.motor.winding_resistance_ohm = f,
            "gear_ratio" => p.motor.gear_ratio = f,
            "gear_efficiency" => p.motor.gear_efficiency = f,
            "supply_voltage_v" => p.motor.supply_voltage_v = f,
            "max_duty_fraction" => p.motor.max_duty_fraction = f,
            "duty_full_scale" if (1.0..=65535.0).contains(&x) => p.motor.duty_full_scale = x as u16,
            "control_period_s" if x > 0.0 && x < 1.0 => p.control_period_s = x,
            "speed_window_ticks" if (1.0..=255.0).contains(&x) => p.speed_window_ticks = x as u32,
            "duty_full_scale" | "control_period_s" | "speed_window_ticks" => {
                return Err(format!("{origin}: `{k}` = {x} is out of range"))
            }
            _ => return Err(format!("{origin}: unknown key `{k}`")),
        }
    }
    p.robot
        .validate()
        .map_err(|e| format!("{origin}: robot: {e:?}"))?;
    p.motor
        .validate()
        .map_err(|e| format!("{origin}: motor: {e:?}"))?;
    Ok(p)
}

/// Why `identify fit` failed.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// A file could not be read or written.
    #[error("cannot {what} {path}: {err}")]
    File {
        /// "read" or "write".
        what: &'static str,
        /// The file.
        path: String,
        /// Why.
        err: String,
    },
    /// The log, the prior or the fit refused (the message names the file).
    #[error("{0}")]
    Input(String),
    /// `--filter-window` not positive.
    #[error("--filter-window must be > 0 s (got {0})")]
    FilterWindow(f64),
    /// A duty log without its board's timer clock.
    #[error(
        "{log}: the log does not say its board's PWM timer clock (logs of `wmr identify run` \
         do, for a board it knows): give --timer-clock-hz ({known})"
    )]
    NoTimerClock {
        /// The log.
        log: String,
        /// The clocks of the boards wmr knows.
        known: String,
    },
    /// Neither `--robot` nor a robot file in the log.
    #[error(
        "{log}: which robot? the log carries no robot file (`wmr identify run` writes the one \
         it used when it knows it: --robot, or the robot's own store): give --robot FILE.toml, \
         the robot as configured when the log was recorded (robots/paper.toml for the paper's)"
    )]
    NoRobot {
        /// The log.
        log: String,
    },
    /// Writing the report.
    #[error("cannot write the report: {0}")]
    Output(String),
}

/// The comment key of the timer clock in an identification log.
const TIMER_CLOCK_KEY: &str = "timer_clock_hz = ";

/// The comment (and blank) lines a log starts with.
fn header_lines(text: &str) -> impl Iterator<Item = &str> {
    text.lines()
        .take_while(|l| l.starts_with('#') || l.trim().is_empty())
}

/// The prefix of the comment lines that carry the robot file in an
/// identification log (after the comment's `# `).
const ROBOT_LINE: &str = "robot| ";

/// The comment lines that carry `robot` in an identification log (its
/// robot file, a line each, after [`ROBOT_LINE`]), with a first line
/// saying where it came from.
fn robot_comments(robot: &robot_file::Robot, origin: &str) -> Vec<String> {
    let mut c = vec![format!(
        "robot file ({origin}): `wmr identify fit` takes it when not given --robot"
    )];
    c.extend(
        robot
            .to_toml_string()
            .lines()
            .map(|l| format!("{ROBOT_LINE}{l}")),
    );
    c
}

/// The robot file a log carries ([`robot_comments`]): `None` when it
/// carries none, the robot file's own error when it does not read.
pub fn robot_of_log(text: &str) -> Option<Result<robot_file::Robot, String>> {
    let prefix = format!("# {ROBOT_LINE}");
    let lines: Vec<&str> = header_lines(text)
        .filter_map(|l| l.strip_prefix(prefix.as_str()))
        .collect();
    if lines.is_empty() {
        return None;
    }
    Some(
        robot_file::Robot::from_toml_str(&(lines.join("\n") + "\n"))
            .map_err(|e| format!("the robot file the log carries: {e}")),
    )
}

/// A body of mass `mass_kg` on wheels of radius `r_m` at half track
/// `h_m`, for a robot whose robot file is not known: a uniform disc of
/// radius h + r (I = m·(h + r)²/2), wheels of 5 % of the mass each as
/// discs (I_w = 0.05·m·r²/2), G a quarter of h ahead of the axle (the
/// paper robot's d/h). The excitation's torque check only; the paper
/// robot's absolute inertias (I = 2.5 kg·m², I_w = 0.001 kg·m²) overstated
/// a 1 kg robot's torque 10-40 times.
pub fn body_of_size(mass_kg: f32, r_m: f32, h_m: f32) -> controller_core::RobotParams {
    controller_core::RobotParams {
        mass_kg,
        inertia_kgm2: 0.5 * mass_kg * (h_m + r_m) * (h_m + r_m),
        wheel_inertia_kgm2: 0.05 * mass_kg * r_m * r_m * 0.5,
        wheel_radius_m: r_m,
        half_track_m: h_m,
        com_offset_m: 0.25 * h_m,
    }
}

/// The timer clock a log's comment lines give (`# ... timer_clock_hz = N`).
pub fn timer_clock_of_log(text: &str) -> Option<u32> {
    header_lines(text).find_map(|l| {
        let rest = &l[l.find(TIMER_CLOCK_KEY)? + TIMER_CLOCK_KEY.len()..];
        rest.split(|c: char| !c.is_ascii_digit())
            .next()?
            .parse()
            .ok()
    })
}

/// `identify fit`: the report on `out`, the robot file with `-o`.
pub fn fit(a: &FitArgs, out: &mut dyn Write) -> Result<(), FitError> {
    let origin = a.log.display().to_string();
    let text = std::fs::read_to_string(&a.log).map_err(|e| FitError::File {
        what: "read",
        path: origin.clone(),
        err: e.to_string(),
    })?;
    let is_trace = text
        .lines()
        .find(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .is_some_and(|l| l.trim_end() == track_log::csv::CSV_HEADER);
    // The board's timer clock (the duty's full scale): given, else the
    // log's; a trace has no duties, so it does not enter.
    let clock = || -> Result<u32, FitError> {
        match a.timer_clock_hz.or_else(|| timer_clock_of_log(&text)) {
            Some(c) => Ok(c),
            None if is_trace => Ok(robot_file::SUPPORTED_TIMER_CLOCKS_HZ[0]),
            None => Err(FitError::NoTimerClock {
                log: origin.clone(),
                known: "96000000 for an STM32F411 or hil-sim's device, 168000000 for an STM32F446"
                    .into(),
            }),
        }
    };
    // The prior: a robot file (the usual case), or the flat keys.
    let (prior, base) = match &a.robot {
        Some(path) => {
            let prior_text = std::fs::read_to_string(path).map_err(|e| FitError::File {
                what: "read",
                path: path.display().to_string(),
                err: e.to_string(),
            })?;
            let po = path.display().to_string();
            let is_file = prior_text
                .parse::<toml::Table>()
                .is_ok_and(|t| t.contains_key("format") || t.contains_key("body"));
            if is_file {
                let robot = robot_file::Robot::from_toml_str(&prior_text)
                    .map_err(|e| FitError::Input(format!("{po}: {e}")))?;
                let p = Prior::from_robot(&robot, clock()?)
                    .map_err(|e| FitError::Input(format!("{po}: {e}")))?;
                (p, Some(robot))
            } else {
                (
                    prior_from_toml(&prior_text, &po).map_err(FitError::Input)?,
                    None,
                )
            }
        }
        None => match robot_of_log(&text) {
            Some(r) => {
                let robot = r.map_err(|e| FitError::Input(format!("{origin}: {e}")))?;
                let p = Prior::from_robot(&robot, clock()?)
                    .map_err(|e| FitError::Input(format!("{origin}: {e}")))?;
                writeln!(
                    out,
                    "prior: robot \"{}\", the robot file the log carries",
                    robot.name.as_str()
                )
                .map_err(|e| FitError::Output(e.to_string()))?;
                (p, Some(robot))
            }
            None => return Err(FitError::NoRobot { log: origin }),
        },
    };
    let w = |e: std::io::Error| FitError::Output(e.to_string());
    let rows = if is_trace {
        writeln!(
            out,
            "{origin}: a trace CSV (no duties): the torque form, wheel rates from η with the prior's r and h"
        )
        .map_err(w)?;
        let trace =
            track_log::csv::read_trace_csv(text.as_bytes(), &origin).map_err(FitError::Input)?;
        robot_identify::log::rows_from_trace(&trace, &prior.robot, a.pose_measured)
    } else {
        read_id_csv(text.as_bytes(), &origin).map_err(FitError::Input)?
    };
    let opts = FitOptions {
        filter_window_s: a.filter_window,
        mass_kg: a.mass_kg,
        ..FitOptions::default()
    };
    if !(opts.filter_window_s.is_finite() && opts.filter_window_s > 0.0) {
        return Err(FitError::FilterWindow(opts.filter_window_s));
    }
    let id =
        identify(&rows, &prior, &opts).map_err(|e| FitError::Input(format!("{origin}: {e}")))?;
    write!(out, "{}", robot_identify::report::text(&id, &prior)).map_err(w)?;
    if let Some(path) = &a.out {
        let text = match &base {
            Some(robot) => {
                let (text, said) = robot_identify::report::robot_file(&id, &prior, robot)
                    .map_err(FitError::Input)?;
                for l in said {
                    writeln!(out, "{l}").map_err(w)?;
                }
                text
            }
            None => robot_identify::report::robot_toml(&id, &prior),
        };
        std::fs::write(path, text).map_err(|e| FitError::File {
            what: "write",
            path: path.display().to_string(),
            err: e.to_string(),
        })?;
        writeln!(out, "robot written to {}", path.display()).map_err(w)?;
    }
    Ok(())
}

/// Two telemetry poses of a robot in hold this far apart in robot time
/// \[µs\] that agree within [`SETTLED_POS_M`] and [`SETTLED_HEADING_RAD`]
/// give its pose: in hold the robot does not move, so a pose that still
/// changes is its estimator correcting (the first external poses fused
/// after a boot move it from the file's start pose to where the robot
/// stands).
const SETTLED_GAP_US: u32 = 200_000;
/// See [`SETTLED_GAP_US`] \[m\] (motion capture's noise is ~2 mm).
const SETTLED_POS_M: f32 = 0.01;
/// See [`SETTLED_GAP_US`] \[rad\].
const SETTLED_HEADING_RAD: f32 = 0.01;

/// The pose the robot reports in hold, once its estimate has settled
/// ([`SETTLED_GAP_US`]); the latest after 3 s if it never does.
pub fn current_pose(link: &mut Link) -> Result<controller_core::Pose, LinkError> {
    let t0 = Instant::now();
    let mut anchor: Option<(u32, controller_core::Pose)> = None;
    let mut latest = None;
    while t0.elapsed() < Duration::from_secs(3) {
        if let Some(Reply::Telemetry(t)) = link.next_stream(Duration::from_millis(20))? {
            if let Some(tr) = t.tracking {
                let p = controller_core::Pose::new(tr.pose.x_m, tr.pose.y_m, tr.pose.theta_rad);
                latest = Some(p);
                match anchor {
                    Some((t_us, a)) if t.t_robot_us.wrapping_sub(t_us) >= SETTLED_GAP_US => {
                        let moved_m = ((p.x_m - a.x_m).powi(2) + (p.y_m - a.y_m).powi(2)).sqrt();
                        let turned = controller_core::math::wrap_angle(p.theta_rad - a.theta_rad);
                        if moved_m <= SETTLED_POS_M && turned.abs() <= SETTLED_HEADING_RAD {
                            return Ok(p);
                        }
                        anchor = Some((t.t_robot_us, p));
                    }
                    Some(_) => {}
                    None => anchor = Some((t.t_robot_us, p)),
                }
            }
        }
    }
    latest.ok_or_else(|| LinkError::NoAnswer("telemetry (no frame for 3 s)".into()))
}

/// Rates the probe tries, fastest first \[Hz\].
const PROBE_RATES_HZ: [u16; 5] = [1000, 500, 250, 200, 100];

/// The highest of [`PROBE_RATES_HZ`] whose frames all arrived over 0.5 s
/// of robot time in hold (sequence numbers without a gap); 100 Hz when
/// none did (the fit then has a coarse log, and says how many frames were
/// dropped).
fn probe_rate(link: &mut Link) -> Result<u16, LinkError> {
    for rate in PROBE_RATES_HZ {
        link.command(&Request::SetTelemetry {
            selection: TELEMETRY_ALL,
            rate_hz: rate,
        })?;
        let (mut first_us, mut frames, mut gaps) = (None::<u32>, 0u32, 0u32);
        let mut last_seq = None::<u32>;
        let wall = Instant::now();
        while wall.elapsed() < Duration::from_secs(3) {
            if let Some(Reply::Telemetry(t)) = link.next_stream(Duration::from_millis(10))? {
                if let Some(s) = last_seq {
                    gaps += t.seq.wrapping_sub(s).saturating_sub(1);
                }
                last_seq = Some(t.seq);
                frames += 1;
                let t0 = *first_us.get_or_insert(t.t_robot_us);
                if t.t_robot_us.wrapping_sub(t0) >= 500_000 {
                    break;
                }
            }
        }
        if frames > 10 && gaps == 0 {
            return Ok(rate);
        }
    }
    Ok(100)
}

/// `identify run`.
pub fn run(a: &RunArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    if a.rate.is_some_and(|r| r == 0 || r > 1000) {
        return Err(LinkError::Io("--rate must be in 1..=1000 Hz".into()));
    }
    let hello = crate::session::hello(link)?;
    let info = hello.robot;
    let ex = controller_core::trajectory::Excitation {
        v_amp_mps: a.v_amp,
        omega_amp_radps: a.w_amp,
        w_radps: a.w_base,
        duration_s: a.duration,
        ramp_s: 3.0f32.min(0.25 * a.duration),
    };
    // The model of the check: the file's body (given, else the one the
    // robot runs), with the r and h the robot announces (what the
    // waypoints become wheel rates with).
    let file_robot = match &a.robot {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| LinkError::Io(format!("cannot read {}: {e}", path.display())))?;
            let r = robot_file::Robot::from_toml_str(&text)
                .map_err(|e| LinkError::Io(format!("{}: {e}", path.display())))?;
            Some((r, format!("--robot {}", path.display())))
        }
        None => {
            let known = match crate::session::robot_in_force(link) {
                Ok(k) => k,
                Err(e) => Err(crate::session::NotKnown::Unread(e.to_string())),
            };
            match known {
                Ok(r) => Some((
                    r,
                    "the file the robot runs, read from its store".to_string(),
                )),
                Err(why) => {
                    writeln!(
                        out,
                        "robot file: not known ({why}): the torque check takes a uniform disc of \
                         the handshake's {} kg, r {} m, h {} m, and the log carries no robot file \
                         (give --robot FILE.toml here or to `identify fit`)",
                        info.mass_kg, info.wheel_radius_m, info.half_track_m
                    )
                    .map_err(io)?;
                    None
                }
            }
        }
    };
    let body = match &file_robot {
        Some((r, origin)) => {
            writeln!(out, "robot: \"{}\" ({origin})", r.name.as_str()).map_err(io)?;
            r.robot_params()
        }
        None => body_of_size(info.mass_kg, info.wheel_radius_m, info.half_track_m),
    };
    let robot = controller_core::RobotParams {
        wheel_radius_m: info.wheel_radius_m,
        half_track_m: info.half_track_m,
        ..body
    };
    // The robot refuses waypoints beyond its limits; the torque and the
    // area are checked here, against half the torque limit.
    let peaks = check(
        &ex,
        &robot,
        f32::INFINITY,
        f32::INFINITY,
        info.torque_limit_nm,
        0.5,
        a.area,
    )
    .map_err(|e| LinkError::Io(format!("excitation: {e}")))?;
    let file = std::fs::File::create(&a.out)
        .map_err(|e| LinkError::Io(format!("cannot create {}: {e}", a.out.display())))?;
    let rate = match a.rate {
        Some(r) => r,
        None => probe_rate(link)?,
    };
    writeln!(out, "telemetry at {rate} Hz").map_err(io)?;
    link.command(&Request::SetTelemetry {
        selection: TELEMETRY_ALL,
        rate_hz: rate,
    })?;
    let start = current_pose(link)?;
    let pts = waypoints(&ex, start);
    // The robot checks every segment against its limits too (issue 31);
    // with its file, say which before anything is sent.
    if let Some((r, _)) = &file_robot {
        crate::upload::check_waypoints(&pts, r)
            .map_err(|e| LinkError::Io(format!("excitation: {e}")))?;
    }
    let mut stream = SegmentStream::begin(link, &pts)?;
    writeln!(
        out,
        "excitation: {} waypoints over {:.0} s, peaks {:.2} m/s, {:.2} rad/s, {:.2} N·m (model), within {:.2} m",
        pts.len(),
        ex.duration_s,
        peaks.speed_mps,
        peaks.yaw_rate_radps,
        peaks.torque_nm,
        peaks.excursion_m
    )
    .map_err(io)?;
    // Fill the buffer, arm, stream the rest while recording.
    let mut armed = false;
    let mut rows: Vec<IdRow> = Vec::new();
    let mut builder = RowBuilder::new(info);
    let (mut frames, mut dropped, mut last_seq) = (0u64, 0u64, None::<u32>);
    let mut seen_running = false;
    let mut ended: Option<(RunStateMsg, Option<StopCode>)> = None;
    let keep_alive = link.timing().keep_alive;
    let mut last_tx = Instant::now();
    let mut last_frame = Instant::now();
    let deadline = Instant::now() + Duration::from_secs_f64(ex.duration_s as f64 + 30.0);
    loop {
        // Fill the buffer (again each SEGMENT_RETRY while it is full);
        // arm once it is full or the excitation is all in.
        if !stream.done() {
            if let Some(p) = stream.pump_when_due(link)? {
                last_tx = Instant::now();
                if !armed {
                    Motion::Arm.send(link)?;
                    armed = true;
                }
                if p == Pump::Done {
                    continue;
                }
            }
        } else if !armed {
            Motion::Arm.send(link)?;
            armed = true;
        }
        if last_tx.elapsed() >= keep_alive {
            link.send(&Request::ClockSync { host_time_us: 0 })?;
            last_tx = Instant::now();
        }
        match link.next_stream(Duration::from_millis(5))? {
            Some(Reply::Telemetry(t)) => {
                last_frame = Instant::now();
                frames += 1;
                if let Some(s) = last_seq {
                    dropped += crate::session::telemetry_gap(s, t.seq);
                }
                last_seq = Some(t.seq);
                seen_running |= t.state == RunStateMsg::Running;
                if let Some(row) = builder.row(&t) {
                    rows.push(row);
                }
                if seen_running && matches!(t.state, RunStateMsg::Hold | RunStateMsg::Stopped) {
                    ended = Some((t.state, None));
                }
            }
            Some(Reply::Event(Event::StateChanged { state, cause }))
                if seen_running && matches!(state, RunStateMsg::Hold | RunStateMsg::Stopped) =>
            {
                ended = Some((state, cause));
            }
            _ => {}
        }
        if ended.is_some() {
            break;
        }
        if last_frame.elapsed() > Duration::from_secs(2) || Instant::now() > deadline {
            let _ = link.request(&Request::Disarm);
            return Err(LinkError::NoAnswer(
                "telemetry (no frame for 2 s, or the run overran its length): disarmed".into(),
            ));
        }
    }
    let _ = link.command(&Request::SetTelemetry {
        selection: TELEMETRY_ALL,
        rate_hz: 0,
    });
    let mut comments = vec![
        format!(
            "wmr identify run: robot r = {} m, h = {} m, m = {} kg, period {} s, torque limit {} N·m",
            info.wheel_radius_m,
            info.half_track_m,
            info.mass_kg,
            info.control_period_s,
            info.torque_limit_nm
        ),
        format!(
            "excitation: v_amp {} m/s, w_amp {} rad/s, w {} rad/s, {} s; telemetry {} Hz, {frames} frames, {dropped} dropped",
            ex.v_amp_mps, ex.omega_amp_radps, ex.w_radps, ex.duration_s, rate
        ),
    ];
    // The robot file, for `identify fit` without --robot.
    if let Some((r, origin)) = &file_robot {
        comments.extend(robot_comments(r, origin));
    }
    // The board's timer clock (the duty's full scale) for `identify fit`.
    match crate::session::timer_clock_of_chip(&hello.chip) {
        Some(hz) => comments.push(format!("board \"{}\": {TIMER_CLOCK_KEY}{hz}", hello.chip)),
        None => eprintln!(
            "note: board \"{}\" is not one wmr knows the PWM timer clock of: give `identify fit` --timer-clock-hz",
            hello.chip
        ),
    }
    write_id_csv(std::io::BufWriter::new(file), &comments, &rows)
        .map_err(|e| LinkError::Io(format!("cannot write {}: {e}", a.out.display())))?;
    writeln!(
        out,
        "{} rows written to {} ({frames} frames, {dropped} dropped)",
        rows.len(),
        a.out.display()
    )
    .map_err(io)?;
    let (state, mut cause) = ended.unwrap_or((RunStateMsg::Hold, None));
    if cause.is_none() {
        if let Ok(Reply::Status { status, .. }) = link.request(&Request::GetStatus) {
            cause = status.last_stop;
        }
    }
    match cause {
        Some(StopCode::TrajectoryEnd) => Ok(()),
        c => Err(LinkError::UnexpectedStop(format!(
            "{state:?} ({c:?}) before the excitation ended; the log up to it is written"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prior_toml_keys_ranges_and_errors() {
        let p = prior_from_toml(
            "mass_kg = 12.5\nwheel_radius_m = 0.08\ngear_ratio = 30\nduty_full_scale = 1000\nspeed_window_ticks = 8\n",
            "p.toml",
        )
        .unwrap();
        assert_eq!(p.robot.mass_kg, 12.5);
        assert_eq!(p.robot.wheel_radius_m, 0.08);
        assert_eq!(p.motor.gear_ratio, 30.0);
        assert_eq!(p.motor.duty_full_scale, 1000);
        assert_eq!(p.speed_window_ticks, 8);
        let e = prior_from_toml("mass = 3\n", "p.toml").unwrap_err();
        assert!(e.contains("unknown key `mass`"), "{e}");
        let e = prior_from_toml("mass_kg = -3\n", "p.toml").unwrap_err();
        assert!(e.contains("robot"), "{e}");
        let e = prior_from_toml("gear_efficiency = 1.5\n", "p.toml").unwrap_err();
        assert!(e.contains("motor"), "{e}");
        let e = prior_from_toml("speed_window_ticks = 0\n", "p.toml").unwrap_err();
        assert!(e.contains("out of range"), "{e}");
        let e = prior_from_toml("mass_kg = \"heavy\"\n", "p.toml").unwrap_err();
        assert!(e.contains("must be a number"), "{e}");
    }

    fn paper_file() -> PathBuf {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../robots/paper.toml").into()
    }

    /// The robot file `identify run` writes into the log reads back as the
    /// same robot (the fit's prior without --robot), past the other
    /// comments; a log without one is refused by `fit`, naming --robot,
    /// and a damaged one with the robot file's own error.
    #[test]
    fn the_log_carries_the_robot_file_to_the_fit() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
        let text = std::fs::read_to_string(format!("{root}/robots/tb6612-2kg.toml")).unwrap();
        let robot = robot_file::Robot::from_toml_str(&text).unwrap();
        let mut comments = vec!["wmr identify run: robot r = 0.035 m".to_string()];
        comments.extend(robot_comments(&robot, "--robot tb6612-2kg.toml"));
        comments.push("board \"stm32f411ce\": timer_clock_hz = 96000000".into());
        let mut log = Vec::new();
        write_id_csv(&mut log, &comments, &[]).unwrap();
        let log = String::from_utf8(log).unwrap();
        assert_eq!(robot_of_log(&log), Some(Ok(robot.clone())), "{log}");
        assert_eq!(timer_clock_of_log(&log), Some(96_000_000));
        let bare = format!("{}\n", robot_identify::log::ID_CSV_HEADER);
        assert_eq!(robot_of_log(&bare), None);
        let damaged = log.replace("mass_kg = ", "mass_kg = -");
        let e = robot_of_log(&damaged).unwrap().unwrap_err();
        assert!(e.contains("mass_kg"), "{e}");
        let dir = std::env::temp_dir().join(format!("wmr-identify-robot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("id.csv");
        std::fs::write(&f, &bare).unwrap();
        let a = FitArgs {
            log: f.clone(),
            robot: None,
            timer_clock_hz: Some(96_000_000),
            out: None,
            filter_window: 0.15,
            mass_kg: None,
            pose_measured: false,
        };
        let e = fit(&a, &mut Vec::new()).unwrap_err();
        assert!(matches!(e, FitError::NoRobot { .. }), "{e}");
        assert!(e.to_string().contains("give --robot FILE.toml"), "{e}");
        // With it: past the prior, to the log's own (empty) contents.
        std::fs::write(&f, &log).unwrap();
        let mut report = Vec::new();
        let e = fit(&a, &mut report).unwrap_err().to_string();
        assert!(e.contains("at least 100"), "{e}");
        let report = String::from_utf8(report).unwrap();
        assert!(
            report.contains("robot \"tb6612-2kg\", the robot file the log carries"),
            "{report}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The body of a robot of unknown file: a uniform disc of radius
    /// h + r has I = m(h + r)²/2 (its second moment), and the wheels'
    /// inertia is that of discs of 5 % of the mass each.
    #[test]
    fn a_body_of_size_is_a_uniform_disc() {
        let b = body_of_size(0.85, 0.03, 0.08);
        assert_eq!(b.mass_kg, 0.85);
        assert!((b.inertia_kgm2 - 0.85 * 0.11 * 0.11 / 2.0).abs() < 1e-7);
        assert!((b.wheel_inertia_kgm2 - 0.0425 * 0.03 * 0.03 / 2.0).abs() < 1e-9);
        assert!(b.validate().is_ok());
        // The paper robot's I = 2.5 kg·m² for a 0.85 kg robot: ~240 times.
        assert!(controller_core::RobotParams::paper().inertia_kgm2 / b.inertia_kgm2 > 200.0);
    }

    #[test]
    fn fit_of_a_missing_or_foreign_file_is_a_clear_error() {
        let args = |log: PathBuf| FitArgs {
            log,
            robot: Some(paper_file()),
            timer_clock_hz: Some(96_000_000),
            out: None,
            filter_window: 0.15,
            mass_kg: None,
            pose_measured: false,
        };
        let mut out = Vec::new();
        let e = fit(&args("/no/such/log.csv".into()), &mut out)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot read /no/such/log.csv"), "{e}");
        let dir = std::env::temp_dir().join(format!("wmr-identify-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("trace.csv");
        std::fs::write(&f, "t,x\n1,2\n").unwrap();
        let e = fit(&args(f.clone()), &mut out).unwrap_err().to_string();
        assert!(e.contains("not an identification log"), "{e}");
        std::fs::write(
            &f,
            format!(
                "{}\n0,0,0,0,0,0,0,0,0,0,0,0\n",
                robot_identify::log::ID_CSV_HEADER
            ),
        )
        .unwrap();
        let e = fit(&args(f.clone()), &mut out).unwrap_err().to_string();
        assert!(e.contains("at least 100"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The log's timer clock is the one `identify run` wrote for its
    /// board; a duty log without one is refused, naming the flag, and the
    /// flag overrides the log.
    #[test]
    fn the_timer_clock_comes_from_the_log() {
        let log = format!(
            "# wmr identify run: robot r = 0.1 m\n# board \"stm32f446re\": timer_clock_hz = 168000000\n{}\n",
            robot_identify::log::ID_CSV_HEADER
        );
        assert_eq!(timer_clock_of_log(&log), Some(168_000_000));
        assert_eq!(
            crate::session::timer_clock_of_chip("stm32f446re"),
            Some(168_000_000)
        );
        let bare = format!(
            "{}\n0,0,0,0,0,0,0,0,0,0,0,0\n",
            robot_identify::log::ID_CSV_HEADER
        );
        assert_eq!(timer_clock_of_log(&bare), None);
        let dir = std::env::temp_dir().join(format!("wmr-identify-clock-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("id.csv");
        std::fs::write(&f, &bare).unwrap();
        let mut a = FitArgs {
            log: f.clone(),
            robot: Some(paper_file()),
            timer_clock_hz: None,
            out: None,
            filter_window: 0.15,
            mass_kg: None,
            pose_measured: false,
        };
        let e = fit(&a, &mut Vec::new()).unwrap_err();
        assert!(matches!(e, FitError::NoTimerClock { .. }), "{e}");
        assert!(e.to_string().contains("--timer-clock-hz"), "{e}");
        // Given: past the clock, to the log's own (too short) contents.
        a.timer_clock_hz = Some(96_000_000);
        let e = fit(&a, &mut Vec::new()).unwrap_err().to_string();
        assert!(e.contains("at least 100"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
