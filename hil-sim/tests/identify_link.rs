//! `wmr identify run` against the simulated robot of `hil-sim device`
//! over a pseudo-terminal, then `wmr identify fit` on the log it wrote:
//! the whole identification path of a user, with no hardware.

use controller_core::ControllerKind;
use hil_sim::device::{open_pty, serve, SimRobot};
use hil_sim::scenario::{Scenario, Sensing};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

#[test]
fn identify_run_then_fit_over_the_pty() {
    // The plant 20 % heavier than the robot's configuration.
    let mut scn = Scenario {
        name: "identify".into(),
        initial_pose: [0.0, 0.0, 0.0],
        ..Scenario::default()
    };
    let p = &mut scn.perturbations;
    p.beta = 0.0;
    p.eps = 0.0;
    p.skid_scale = 0.0;
    p.disturbance_nm = 0.0;
    scn.plant.mass_scale = 1.2;
    scn.sensing.preset = Sensing::Mocap;
    let (mut master, _slave, path) = open_pty().unwrap();
    let mut robot = SimRobot::new(&scn, ControllerKind::Proposed).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    let handle = std::thread::spawn(move || serve(&mut robot, &mut master, 2.0, &s));
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("id.csv");
    let out_toml = dir.path().join("robot.toml");
    let mut link = wmr::Link::open(&path, Duration::from_millis(500)).unwrap();
    link.hello().unwrap();
    // The robot runs at 2x real time: its default 500 ms link timeout is
    // 250 ms of wall time, too close to the host's 100 ms keep-alive on a
    // loaded machine. Identification does not test link silence.
    link.command(&wmr_protocol::Request::SetParam {
        id: wmr_protocol::ParamId::LinkTimeoutMs,
        value: 5000.0,
    })
    .unwrap();
    let run = wmr::identify::RunArgs {
        out: log.clone(),
        v_amp: 0.5,
        w_amp: 1.0,
        w_base: 1.5,
        duration: 24.0,
        area: 2.5,
        // Not probed: the probe keeps the highest rate the host kept up
        // with for 3 s of wall time, which depends on the machine's load.
        rate: Some(250),
        robot: None,
    };
    let mut text = Vec::new();
    let r = wmr::identify::run(&run, &mut link, &mut text);
    let text = String::from_utf8_lossy(&text).to_string();
    r.unwrap_or_else(|e| panic!("{e}\n{text}"));
    drop(link);
    stop.store(true, Ordering::Relaxed);
    handle.join().unwrap().unwrap();
    let fit = wmr::identify::FitArgs {
        log,
        robot: None,
        // The log says its board's clock (`identify run` wrote it).
        timer_clock_hz: None,
        out: Some(out_toml.clone()),
        filter_window: 0.15,
        pose_measured: false,
    };
    let mut report = Vec::new();
    wmr::identify::fit(&fit, &mut report).unwrap();
    let report = String::from_utf8_lossy(&report).to_string();
    let toml_text = std::fs::read_to_string(&out_toml).unwrap();
    // A robot file (the paper robot's, identified values in place; `fit`
    // validated it before writing).
    let table: toml::Table = toml::from_str(&toml_text).unwrap();
    let body = table["body"].as_table().unwrap();
    let mass = body["mass_kg"].as_float().unwrap();
    let inertia = body["inertia_kgm2"].as_float().unwrap();
    println!("{text}\n{report}\n{toml_text}");
    assert!((mass / 18.0 - 1.0).abs() < 0.05, "mass {mass}\n{report}");
    assert!(
        (inertia / 2.5 - 1.0).abs() < 0.10,
        "inertia {inertia}\n{report}"
    );
}
