//! `hil-sim device --pty`: the simulated robot behind a pseudo-terminal.

use super::controller_arg::ControllerArg;
use super::scenario_args::ScenarioArgs;
use crate::device::{open_pty, serve, Miswire, SimRobot};
use clap::Args;
use controller_core::ControllerKind;
use std::io::Write;
use std::sync::atomic::AtomicBool;

/// `device` options.
#[derive(Debug, Args)]
pub struct DeviceArgs {
    /// Serve on a new pseudo-terminal (the only transport so far); its path is
    /// the first line on stdout.
    #[arg(long, required = true)]
    pub pty: bool,
    /// Run N times faster than real time (robot time is simulated time; the
    /// host's durations, link_timeout_ms and velocity timeouts, count real time).
    #[arg(long, default_value_t = 1.0, value_name = "N")]
    pub speed: f64,
    /// Controller the runtime runs, at every boot [default: the robot
    /// file's `[control] controller`, the pushed file's after `wmr robot
    /// push`, as the firmware]
    #[arg(long, value_enum)]
    pub controller: Option<ControllerArg>,
    /// Stop after this much robot time [s] (default: run until killed).
    #[arg(long, value_name = "s")]
    pub for_s: Option<f64>,
    /// The simulated robot: sensing, resolution, perturbations (their window is
    /// in robot time since start) and initial pose; the trajectory comes from
    /// the host.
    #[command(flatten)]
    pub scenario: ScenarioArgs,
    /// Wiring mistakes of the simulated robot, for `wmr commission`
    /// (comma-separated): encoder-inverted-right|left, motor-inverted-right|left,
    /// motors-swapped, encoders-swapped, counts-per-rev=N (the plant's).
    #[arg(long, value_name = "LIST", value_parser = parse_miswire)]
    pub miswire: Option<Miswire>,
}

/// `--miswire` items.
pub fn parse_miswire(s: &str) -> Result<Miswire, String> {
    let mut m = Miswire::default();
    for item in s.split(',').map(str::trim).filter(|i| !i.is_empty()) {
        let w = &mut m.wiring;
        match item {
            "encoder-inverted-right" => w.encoder_inverted[0] = true,
            "encoder-inverted-left" => w.encoder_inverted[1] = true,
            "motor-inverted-right" => w.motor_inverted[0] = true,
            "motor-inverted-left" => w.motor_inverted[1] = true,
            "motors-swapped" => w.motors_swapped = true,
            "encoders-swapped" => w.encoders_swapped = true,
            _ => match item.strip_prefix("counts-per-rev=").map(str::parse::<f32>) {
                Some(Ok(c)) if c.is_finite() && (1.0..=1.0e7).contains(&c) => {
                    m.counts_per_wheel_rev = Some(c)
                }
                _ => return Err(format!("--miswire: unknown or bad item '{item}'")),
            },
        }
    }
    Ok(m)
}

/// The scenario and controller `hil-sim device` serves: with `--robot FILE`
/// and no `--scenario`, the robot starts where its file says odometry
/// starts (`[control] initial_*`, as the firmware boots), not at the paper
/// case's 2.5 m (`--initial-pose` overrides), and without the paper case's
/// perturbations unless `--case` or their flags ask (its 1 N·m disturbance
/// alone is 4x a TB6612 robot's torque limit); the controller is
/// `--controller`, else the file's `[control] controller`.
pub fn device_scenario(
    a: &DeviceArgs,
) -> Result<(crate::scenario::Scenario, ControllerKind), String> {
    let s = &a.scenario;
    let robot_only = s.scenario.is_none() && s.robots.robot.is_some();
    let mut scn = s.build_from(robot_only && s.case.is_none())?;
    if robot_only && s.flags.get::<[f64; 3]>("initial_pose").is_none() {
        let c = &scn.robot.control;
        scn.initial_pose = [
            c.initial_x_m as f64,
            c.initial_y_m as f64,
            c.initial_heading_rad as f64,
        ];
    }
    crate::limits::check_scenario(&scn)?;
    let kind: ControllerKind = match a.controller {
        Some(c) => c.into(),
        None => scn.robot.control.controller,
    };
    Ok((scn, kind))
}

/// `hil-sim device --pty`.
pub fn device(a: &DeviceArgs, out: &mut dyn Write) -> Result<(), String> {
    if !(a.speed.is_finite() && a.speed > 0.0 && a.speed <= 1000.0) {
        return Err(format!(
            "--speed {} must be in (0, 1000] (times real time; 1 runs at real time)",
            a.speed
        ));
    }
    let (scn, kind) = device_scenario(a)?;
    if let Some(t) = a.for_s {
        crate::limits::check_device_for_s(t)?;
    }
    let mut robot = SimRobot::miswired(&scn, kind, &a.miswire.unwrap_or_default(), |_| {})?;
    if a.controller.is_none() {
        robot.follow_flash_robot();
    }
    let (mut master, _slave, path) = open_pty()?;
    writeln!(out, "{path}").map_err(|e| e.to_string())?;
    out.flush().map_err(|e| e.to_string())?;
    eprintln!(
        "simulated robot on {path} ({} sensing, {} controller, {}x real time); talk to it with `wmr --port {path} status`",
        match scn.sensing.preset {
            crate::scenario::Sensing::Ideal => "mocap",
            s => s.name(),
        },
        kind.name(),
        a.speed
    );
    let stop = AtomicBool::new(false);
    match a.for_s {
        None => serve(&mut robot, &mut master, a.speed, &stop),
        Some(t) => {
            std::thread::scope(|s| {
                let h = s.spawn(|| serve(&mut robot, &mut master, a.speed, &stop));
                // Robot time t at `speed` x real time (no tick count: it wrapped a u32).
                std::thread::sleep(std::time::Duration::from_secs_f64(t / a.speed));
                stop.store(true, std::sync::atomic::Ordering::Relaxed);
                h.join().map_err(|_| "device thread panicked".to_string())?
            })
        }
    }
}
