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
    // No --robot: the robot's own file, from its store (D216).
    assert!(
        text.contains("(the file the robot runs, read from its store)"),
        "{text}"
    );
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
        mass_kg: None,
        pose_measured: false,
    };
    let mut report = Vec::new();
    wmr::identify::fit(&fit, &mut report).unwrap();
    let report = String::from_utf8_lossy(&report).to_string();
    assert!(
        report.contains("the robot file the log carries"),
        "{report}"
    );
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

/// Issue 34: the weighed mass fixes the scale the log cannot see. The
/// TB6612 robot's plant is heavier (2.1 kg, file 1.8), has less inertia
/// (0.0075, file 0.0094) and a weaker gearbox (η 0.55, file 0.7: its
/// torque per volt a = η·N·k/R is 0.0252 N·m/V, the file's 0.0321). With
/// `--mass-kg 2.1` the fit identifies a within 5 % and the inertia within
/// 10 % of the plant's (issue 19's margins for the inertia); without it
/// the report says the scale is not identified, and the mass it gives is
/// M_v = m + I_w·Σ1/r² times the file's a over the plant's, less the
/// wheels' term (2.89 kg: as the 1.44 kg for 0.95 kg), with the
/// ratios it did identify.
#[test]
fn the_weighed_mass_identifies_the_motor_and_without_it_the_report_says_so() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let file_path = format!("{root}/robots/tb6612-2kg.toml");
    let text = std::fs::read_to_string(&file_path).unwrap();
    let file = robot_file::Robot::from_toml_str(&text).unwrap();
    let mut plant = file.clone();
    plant.body.mass_kg = 2.1;
    plant.body.inertia_kgm2 = 0.0075;
    plant.motors.gear_efficiency = 0.55;
    let a_plant = (plant.motors.gear_efficiency
        * plant.motors.gear_ratio
        * plant.motors.torque_constant_nm_per_a
        / plant.motors.resistance_ohm) as f64;
    let mut scn = Scenario {
        name: "identify-mass".into(),
        initial_pose: [0.0, 0.0, 0.0],
        ..Scenario::default()
    }
    .with_robots(Some(&file), Some(&plant));
    let p = &mut scn.perturbations;
    p.beta = 0.0;
    p.eps = 0.0;
    p.skid_scale = 0.0;
    p.disturbance_nm = 0.0;
    scn.sensing.preset = Sensing::Mocap;
    let _s = hil_sim::device::PtyRobot::serial();
    let (mut master, _slave, path) = open_pty().unwrap();
    let mut robot = SimRobot::new(&scn, ControllerKind::Proposed).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    let handle = std::thread::spawn(move || serve(&mut robot, &mut master, 2.0, &s));
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("id.csv");
    let mut link = wmr::Link::open(&path, Duration::from_millis(500)).unwrap();
    link.hello().unwrap();
    link.command(&wmr_protocol::Request::SetParam {
        id: wmr_protocol::ParamId::LinkTimeoutMs,
        value: 5000.0,
    })
    .unwrap();
    let run = wmr::identify::RunArgs {
        out: log.clone(),
        v_amp: 0.5,
        w_amp: 2.0,
        w_base: 1.5,
        duration: 30.0,
        area: 2.5,
        rate: Some(250),
        // The device's store holds the file: neither run nor fit is
        // given it (D216).
        robot: None,
    };
    let mut text = Vec::new();
    let r = wmr::identify::run(&run, &mut link, &mut text);
    let text = String::from_utf8_lossy(&text).to_string();
    r.unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert!(
        text.contains("robot: \"tb6612-2kg\" (the file the robot runs, read from its store)"),
        "{text}"
    );
    drop(link);
    stop.store(true, Ordering::Relaxed);
    handle.join().unwrap().unwrap();
    let fit = |mass_kg: Option<f64>, out: &std::path::Path| {
        let args = wmr::identify::FitArgs {
            log: log.clone(),
            robot: None,
            timer_clock_hz: None,
            out: Some(out.to_path_buf()),
            filter_window: 0.15,
            mass_kg,
            pose_measured: false,
        };
        let mut report = Vec::new();
        wmr::identify::fit(&args, &mut report).unwrap();
        let report = String::from_utf8_lossy(&report).to_string();
        assert!(
            report.contains("prior: robot \"tb6612-2kg\", the robot file the log carries"),
            "{report}"
        );
        let r = robot_file::Robot::from_toml_str(&std::fs::read_to_string(out).unwrap()).unwrap();
        (report, r)
    };
    let (report, weighed) = fit(Some(2.1), &dir.path().join("weighed.toml"));
    println!("{report}");
    let m = &weighed.motors;
    let a =
        (m.gear_efficiency * m.gear_ratio * m.torque_constant_nm_per_a / m.resistance_ohm) as f64;
    let inertia = weighed.body.inertia_kgm2 as f64;
    println!(
        "weighed: a {a:.5} N·m/V (plant {a_plant:.5}, {:+.1} %), inertia {inertia:.5} (plant 0.0075, {:+.1} %)",
        100.0 * (a / a_plant - 1.0),
        100.0 * (inertia / 0.0075 - 1.0)
    );
    assert_eq!(weighed.body.mass_kg, 2.1);
    assert!(
        (a / a_plant - 1.0).abs() < 0.05,
        "a {a} vs {a_plant}\n{report}"
    );
    assert!(
        (inertia / 0.0075 - 1.0).abs() < 0.10,
        "inertia {inertia}\n{report}"
    );
    assert!(report.contains("given (--mass-kg)"), "{report}");
    let (report, unweighed) = fit(None, &dir.path().join("unweighed.toml"));
    println!("{report}");
    assert!(report.contains("scale NOT identified"), "{report}");
    assert!(report.contains("give --mass-kg"), "{report}");
    // The mass the prior's a implies: M_v = m + I_w·Σ1/r² scaled by
    // a_file/a_plant (0.7/0.55), less the wheels' term (I_w is the
    // prior's): a wrong scale, said as such, not a bad fit.
    let iw = 2.0 * file.body.wheel_inertia_kgm2 as f64 / (0.035f64 * 0.035);
    let implied = (2.1 + iw) * 0.7 / 0.55 - iw;
    let m = unweighed.body.mass_kg as f64;
    println!("unweighed: mass {m:.3} kg (plant 2.1, the prior's a implies {implied:.3})");
    assert!((m / implied - 1.0).abs() < 0.05, "mass {m}\n{report}");
}
