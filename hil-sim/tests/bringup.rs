//! `wmr bringup` end to end against the simulated robot of `hil-sim
//! device --pty` (issue 34): the TB6612 robot whose plant differs from its
//! file (heavier, less inertia, a weaker gearbox), commissioned on the
//! floor, identified with its weighed mass, tuned by the `hil-sim` binary
//! (a small budget), pushed and verified; each step resumable from the
//! state file. Kept cheap: a 15 s identification, a tuning of 6
//! evaluations over 2 scenarios of 10 s, 10 s circles.

use controller_core::ControllerKind;
use hil_sim::device::{Miswire, PtyRobot, SimRobot};
use hil_sim::scenario::{PerturbationPart, Scenario, Sensing};
use robot_file::Robot;
use std::path::Path;

fn wmr(port: &str, args: &[&str]) -> (Result<(), String>, String) {
    let mut argv = vec!["wmr", "--port", port, "bringup"];
    argv.extend_from_slice(args);
    let cli = <wmr::cli::Cli as clap::Parser>::try_parse_from(&argv).unwrap();
    let mut out = Vec::new();
    let r = wmr::cli::execute(&cli, &mut out);
    let text = String::from_utf8_lossy(&out).to_string();
    eprintln!("--- wmr {}\n{text}{:?}", argv[3..].join(" "), r);
    (r, text)
}

fn state(robot: &Path) -> wmr::bringup::State {
    let t = std::fs::read_to_string(wmr::bringup::state_path(robot)).unwrap();
    toml::from_str(&t).unwrap()
}

#[test]
fn bringup_walks_every_step_resumes_and_verifies() {
    let _s = PtyRobot::serial();
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let mut file = Robot::from_toml_str(
        &std::fs::read_to_string(format!("{root}/robots/tb6612-2kg.toml")).unwrap(),
    )
    .unwrap();
    // The device runs at 2x real time: a link timeout of 2 s of robot
    // time is 1 s of wall time, clear of a loaded host's pauses (the file
    // is the robot's after every push too).
    file.limits.link_timeout_ms = 2000;
    let mut plant = file.clone();
    plant.body.mass_kg = 2.1;
    plant.body.inertia_kgm2 = 0.0075;
    plant.motors.gear_efficiency = 0.55;
    let scn = Scenario {
        name: "bringup".into(),
        initial_pose: [0.0, 0.0, 0.0],
        duration_s: 1.0e5,
        perturbations: PerturbationPart::none(),
        ..Scenario::default()
    }
    .with_robots(Some(&file), Some(&plant))
    .with_sensing(Sensing::Mocap);
    let robot =
        SimRobot::miswired(&scn, ControllerKind::Proposed, &Miswire::default(), |_| {}).unwrap();
    let robot = PtyRobot::start(robot, 2.0).unwrap();
    let port = robot.path.clone();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("robot.toml");
    std::fs::write(&path, file.to_toml_string()).unwrap();
    let p = path.to_str().unwrap();
    let common = [
        "--robot",
        p,
        "--floor",
        "--yes",
        "--mass-kg",
        "2.1",
        "--identify-s",
        "15",
        "--identify-w-amp",
        "2",
        "--rate",
        "100",
        "--tune-evaluations",
        "6",
        "--tune-args",
        "--controllers proposed --sensing mocap --train 2 --validate 1 --duration 15",
        "--verify-s",
        "10",
        "--verify-runs",
        "1",
    ];

    // 1. The tuner missing: the first three steps done and kept, a clear
    // error naming the option, non-zero.
    let mut args = common.to_vec();
    args.extend_from_slice(&["--hil-sim", "/no/such/hil-sim"]);
    let (r, text) = wmr(&port, &args);
    let e = r.unwrap_err();
    assert!(
        e.contains("cannot run /no/such/hil-sim") && e.contains("--hil-sim"),
        "{e}"
    );
    for step in [
        "step 1/6: commission",
        "step 2/6: identify",
        "step 3/6: fit",
        "step 4/6: tune",
    ] {
        assert!(text.contains(step), "{step}:\n{text}");
    }
    assert!(text.contains("clean"), "{text}");
    assert!(text.contains("given (--mass-kg)"), "{text}");
    assert_eq!(state(&path).done, ["commission", "identify", "fit"]);
    let identified =
        Robot::from_toml_str(&std::fs::read_to_string(state(&path).identified.unwrap()).unwrap())
            .unwrap();
    assert_eq!(identified.body.mass_kg, 2.1);

    // 2. Resumed with the tuner: from the tuning step on, nothing before.
    let hil_sim = env!("CARGO_BIN_EXE_hil-sim");
    let mut args = common.to_vec();
    args.extend_from_slice(&["--hil-sim", hil_sim]);
    let (r, text) = wmr(&port, &args);
    assert!(
        !text.contains("step 1/6") && !text.contains("step 3/6"),
        "{text}"
    );
    for step in ["step 4/6: tune", "step 5/6: push", "step 6/6: verify"] {
        assert!(text.contains(step), "{step}:\n{text}");
    }
    let st = state(&path);
    let (before, after) = (st.before_rms_m.unwrap(), st.after_rms_m.unwrap());
    assert!(
        before.is_finite() && after.is_finite() && before > 0.0,
        "{st:?}"
    );
    assert!(r.is_ok(), "{r:?}\n{text}");
    assert_eq!(
        st.done,
        ["commission", "identify", "fit", "tune", "push", "verify"]
    );
    assert!(text.contains("bring-up done"), "{text}");
    // The better file stays on the robot: the tuned one when it tracked no
    // worse, else the file before it, pushed back (a small tuning budget
    // can make it worse).
    let pushed_back = after > before;
    assert_eq!(
        st.running.as_deref(),
        Some(if pushed_back {
            path.as_path()
        } else {
            st.tuned.as_deref().unwrap()
        }),
        "{text}"
    );
    assert_eq!(
        text.contains("pushing the file before it back"),
        pushed_back,
        "{text}"
    );
    // 3. Again: every step done, nothing runs.
    let (r, text) = wmr(&port, &args);
    assert!(r.is_ok(), "{text}");
    assert!(!text.contains("step "), "{text}");
    // 4. --redo verify: only the verification runs (the tuned file pushed
    // again first when the last one pushed the file before it back).
    let mut redo = args.clone();
    redo.extend_from_slice(&["--redo", "verify"]);
    let (r, text) = wmr(&port, &redo);
    assert!(r.is_ok(), "{text}");
    assert!(
        text.contains("step 6/6: verify") && !text.contains("step 5/6"),
        "{text}"
    );
    let sim = robot.finish().unwrap();
    assert!(sim.reboots() >= 1, "the push rebooted the robot");
    assert!(sim.reboots() <= 4, "{} reboots", sim.reboots());
}

/// `wmr bringup` runs `hil-sim tune` as a program and reads its exit status:
/// the status that means "kept the start gains" is the same number on both
/// sides.
#[test]
fn bringup_reads_tunes_kept_start_status() {
    assert_eq!(
        wmr::bringup::HIL_SIM_TUNE_KEPT_START,
        hil_sim::cli::tune::EXIT_KEPT_START
    );
}
