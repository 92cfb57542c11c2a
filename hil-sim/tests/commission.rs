//! `wmr commission` against the simulated robot with deliberate wiring
//! mistakes (issue 18): each mistake is found, and the robot running the
//! proposed file is clean on a second run (the swap, a wiring fix, is
//! found and left to the wires).

use controller_core::ControllerKind;
use hil_sim::device::{Miswire, PtyRobot, SimRobot};
use hil_sim::scenario::{PerturbationPart, Scenario, Sensing, TrajectoryKind};
use robot_file::Robot;
use std::path::PathBuf;
use std::time::Duration;
use wmr::commission::{commission, CommissionArgs};
use wmr::Link;

const PAPER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../robots/paper.toml");

fn floor_scenario() -> Scenario {
    // Wheel odometry plus a z-gyro.
    Scenario {
        name: "commission".into(),
        duration_s: 60.0,
        trajectory: TrajectoryKind::Line,
        perturbations: PerturbationPart::none(),
        ..Scenario::default()
    }
    .with_sensing(Sensing::Imu)
}

/// Runs `wmr commission --floor` on a simulated robot miswired by
/// `miswire` whose runtime runs `file`; returns (ok, output, proposed file).
/// One robot at a time (each runs at 2x real time next to its host), its
/// link timeout 5 s: commissioning does not test link silence, and a host
/// held up on a loaded machine must not end a wheel test (at 2x, the
/// default 500 ms is 250 ms of wall time).
fn run(file: &Robot, miswire: Miswire, tag: &str) -> (bool, String, Option<Robot>) {
    let _s = PtyRobot::serial();
    let scn = floor_scenario();
    let f = file.clone();
    let robot = SimRobot::miswired(&scn, ControllerKind::Proposed, &miswire, move |rt| {
        // The robot runs the file: its inversion flags and resolution.
        rt.encoder.inverted = f.encoders.inverted;
        rt.encoder.counts_per_wheel_rev = f.encoders.counts_per_wheel_rev;
        rt.motor_inverted = f.bridge.motor_inverted;
    })
    .unwrap();
    let robot = PtyRobot::start(robot, 2.0).unwrap();
    let dir = std::env::temp_dir().join(format!("wmr-commission-{}-{tag}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let robot_path = dir.join("robot.toml");
    std::fs::write(&robot_path, file.to_toml_string()).unwrap();
    let out_path: PathBuf = dir.join("fixed.toml");
    let _ = std::fs::remove_file(&out_path);
    let args = CommissionArgs {
        robot: robot_path,
        floor: true,
        output: Some(out_path.clone()),
        push: false,
        yes: true,
        turns: None,
        duration_ms: 1000,
    };
    let mut link = Link::open(&robot.path, Duration::from_millis(1000)).unwrap();
    link.hello().unwrap();
    link.command(&wmr_protocol::Request::SetParam {
        id: wmr_protocol::ParamId::LinkTimeoutMs,
        value: 5000.0,
    })
    .unwrap();
    let mut out = Vec::new();
    let r = commission(&args, &mut link, &mut out);
    robot.finish().unwrap();
    let mut text = String::from_utf8(out).unwrap();
    if let Err(e) = &r {
        text.push_str(&format!("error: {e}\n"));
    }
    let fixed = std::fs::read_to_string(&out_path)
        .ok()
        .map(|t| Robot::from_toml_str(&t).unwrap());
    (r.is_ok(), text, fixed)
}

fn paper() -> Robot {
    Robot::from_toml_str(&std::fs::read_to_string(PAPER).unwrap()).unwrap()
}

/// Finds the mistake (`expect` in a finding line), and the robot running
/// the proposed file is clean.
fn finds_and_fixes(miswire: Miswire, expect: &str, tag: &str) -> Robot {
    let file = paper();
    let (ok, text, fixed) = run(&file, miswire, tag);
    eprintln!("{text}");
    assert!(!ok, "commission passed a miswired robot:\n{text}");
    assert!(
        text.lines()
            .any(|l| l.starts_with("finding:") && l.contains(expect)),
        "no finding '{expect}':\n{text}"
    );
    let fixed = fixed.expect("no proposed file");
    let (ok2, text2, _) = run(&fixed, miswire, &format!("{tag}-fixed"));
    eprintln!("{text2}");
    assert!(ok2, "the proposed file is not clean:\n{text2}");
    fixed
}

#[test]
fn a_correctly_wired_robot_is_clean() {
    let (ok, text, fixed) = run(&paper(), Miswire::default(), "clean");
    assert!(ok, "{text}");
    assert!(text.contains("clean"), "{text}");
    assert!(fixed.is_none());
}

#[test]
fn an_inverted_encoder_is_found_and_fixed() {
    let mut m = Miswire::default();
    m.wiring.encoder_inverted[1] = true;
    let fixed = finds_and_fixes(m, "left encoder counts backwards", "enc");
    // Mirrored left encoder in the file: the fix un-mirrors it.
    assert_eq!(fixed.encoders.inverted, [false, false]);
    assert_eq!(fixed.bridge.motor_inverted, paper().bridge.motor_inverted);
}

#[test]
fn an_inverted_motor_is_found_and_fixed() {
    let mut m = Miswire::default();
    m.wiring.motor_inverted[0] = true;
    let fixed = finds_and_fixes(m, "right motor turns backwards", "motor");
    assert_eq!(fixed.bridge.motor_inverted, [true, true]);
    assert_eq!(fixed.encoders.inverted, paper().encoders.inverted);
}

#[test]
fn wrong_counts_per_revolution_are_measured_against_the_gyro() {
    let file = paper();
    let true_cpr = 0.8 * file.encoders.counts_per_wheel_rev;
    let m = Miswire {
        counts_per_wheel_rev: Some(true_cpr),
        ..Miswire::default()
    };
    let fixed = finds_and_fixes(m, "counts per wheel revolution", "cpr");
    let got = fixed.encoders.counts_per_wheel_rev;
    // Within 5 % of the plant's (the check's own tolerance).
    assert!((got / true_cpr - 1.0).abs() < 0.05, "{got} vs {true_cpr}");
}

#[test]
fn swapped_motors_are_found_as_a_wiring_fix() {
    let mut m = Miswire::default();
    m.wiring.motors_swapped = true;
    let (ok, text, _) = run(&paper(), m, "swap");
    assert!(!ok, "{text}");
    assert!(
        text.lines()
            .any(|l| l.starts_with("finding:") && l.contains("swapped")),
        "{text}"
    );
    assert!(text.contains("wiring fix"), "{text}");
}
