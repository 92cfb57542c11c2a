//! Issue 19's end-to-end line: identification -> tuning -> push -> tracking
//! against the simulated robot of `hil-sim device --pty` (the rig of
//! `tests/common`: the device's link handler, runtime and estimator on the
//! simulated plant, served on a pty), with a robot whose plant differs from
//! its file.
//!
//! The robot file is robots/tb6612-2kg.toml (no gains: the paper's Table 2);
//! the plant is that file with mass +16.7 %, inertia −20 %, wheel radii
//! +1.1 % / −0.9 %, track +2.1 % and other Coulomb friction. The device's
//! scenario is what `hil-sim device --pty --scenario
//! scenarios/link_nominal.toml --robot FILE --plant PLANT ...` builds (parsed
//! by hil-sim's own command line): quiet while the robot is identified, then
//! (robot time >= [`WINDOW_S`]) wheel slip, lateral skid, a torque
//! disturbance and an actuator fault, the perturbations the tuning set
//! draws. Steps, each through the `wmr` binary except the tuning
//! (hil-sim's command line in-process):
//!
//! 1. `wmr identify run` (the built-in excitation, 30 s, yaw rate up to
//!    2 rad/s: at the default 1 rad/s the inertia of this 1.8 kg robot is
//!    identified to about ±35 %) and `wmr identify fit`
//!    -> an identified robot file: every fitted value nearer the plant than
//!    the file's, and within issue 19's margins (mass 5 %, inertia 10 %,
//!    radii 0.5 %, track 1 %).
//! 2. `hil-sim tune` on the identified file, a small budget (the proposed
//!    controller, mocap, 6 training scenarios of 30 s, 40 evaluations).
//! 3. The circle (2 m at 0.5 m/s, the tuning set's reference for this
//!    robot) tracked with the file's gains: `wmr upload` + `wmr record
//!    --arm`.
//! 4. `wmr robot push` of the tuned file (the robot reboots into it), the
//!    same circle again: the tracking error after the first 5 s must be at
//!    most half the file's gains' on the same plant and perturbations (the
//!    direct simulation of the same case gives about a tenth). A push that
//!    did not take, or gains the runtime ignored, tracks as before and fails.
use clap::Parser;
use common::{finish, wmr_cmd, Done, Robot};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

mod common;

/// Robot time from which the perturbations act [s], after the
/// identification run on any machine: its rate probe takes at most 5 x 3 s
/// of wall time (less robot time: the robot never runs ahead of the wall
/// clock), then 30 s of robot time. (It was 40 s: a probe that lost
/// frames at a few rates on a loaded machine ran the identification into
/// the perturbations.)
const WINDOW_S: f64 = 60.0;

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(format!("{}/../{rel}", env!("CARGO_MANIFEST_DIR")))
}

/// `wmr --port PORT ARGS...`, bounded; fails on a non-zero exit.
fn wmr(port: &Path, args: &[&str], bound_s: u64) -> Done {
    let child = wmr_cmd()
        .arg("--port")
        .arg(port)
        .args(args)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let what = format!("wmr {}", args.join(" "));
    let d = finish(child, Duration::from_secs(bound_s), &what);
    assert!(d.status.success(), "{what}: {d}");
    d
}

/// The plant: the file with its body and friction changed.
fn plant_file(file: &str) -> String {
    let mut t: toml::Table = toml::from_str(file).unwrap();
    t["name"] = "tb6612-2kg-plant".into();
    let body = t["body"].as_table_mut().unwrap();
    body["mass_kg"] = 2.1.into();
    body["inertia_kgm2"] = 0.0075.into();
    body["wheel_radius_m"] = toml::Value::Array(vec![0.0354.into(), 0.0347.into()]);
    body["track_m"] = 0.194.into();
    let motors = t["motors"].as_table_mut().unwrap();
    motors["coulomb_friction_nm"] = toml::Value::Array(vec![0.02.into(), 0.024.into()]);
    toml::to_string(&t).unwrap()
}

/// [body] values: mass, inertia, right and left radius, track.
fn body(text: &str) -> [f64; 5] {
    let t: toml::Table = toml::from_str(text).unwrap();
    let b = t["body"].as_table().unwrap();
    let f = |k: &str| b[k].as_float().unwrap();
    let r = b["wheel_radius_m"].as_array().unwrap();
    [
        f("mass_kg"),
        f("inertia_kgm2"),
        r[0].as_float().unwrap(),
        r[1].as_float().unwrap(),
        f("track_m"),
    ]
}

/// Robot time the robot reports (`wmr status`) [s].
fn robot_time_s(port: &Path) -> f64 {
    let d = wmr(port, &["status"], 10);
    let t = d
        .stdout
        .split("time ")
        .nth(1)
        .and_then(|s| s.split(" s").next())
        .and_then(|s| s.parse().ok());
    t.unwrap_or_else(|| panic!("no robot time in {d}"))
}

/// The circle from where the robot stands, tracked for `seconds`: the
/// recording's RMS position error after the first 5 s [m].
fn track_circle(port: &Path, dir: &Path, name: &str, seconds: f64) -> f64 {
    // Where the robot is (its estimate, in hold): `wmr watch`'s last line.
    let w = wmr(port, &["watch", "--seconds", "0.3", "--rate", "10"], 20);
    let pose: Vec<f64> = w
        .stdout
        .lines()
        .rev()
        .find_map(|l| l.split(" | G ").nth(1))
        .and_then(|s| s.split(" | ").next())
        .map(|s| {
            s.split_whitespace()
                .filter_map(|x| x.parse().ok())
                .collect()
        })
        .unwrap_or_default();
    let [x, y, th] = pose[..] else {
        panic!("no pose in {w}")
    };
    let traj = dir.join(format!("{name}.toml"));
    std::fs::write(
        &traj,
        format!("trajectory = \"circle\"\nstart_pose = [{x}, {y}, {th}]\n"),
    )
    .unwrap();
    wmr(port, &["upload", traj.to_str().unwrap()], 20);
    let csv = dir.join(format!("{name}.csv"));
    let secs = seconds.to_string();
    let d = wmr(
        port,
        &[
            "record",
            "--arm",
            "--seconds",
            &secs,
            "--quiet",
            "--out",
            csv.to_str().unwrap(),
        ],
        seconds as u64 + 30,
    );
    // The run goes on after the recording: a deliberate stop.
    wmr(port, &["disarm"], 10);
    let summary: serde_json::Value = d
        .stdout
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str(l).ok())
        .unwrap_or_else(|| panic!("no summary: {d}"));
    assert_eq!(summary["dropped_frames"], 0, "{summary}");
    summary["metrics"]["rms_pos_err_after5_m"]
        .as_f64()
        .unwrap_or_else(|| panic!("{summary}"))
}

#[test]
fn identify_tune_push_and_track_a_robot_whose_plant_differs_from_its_file() {
    let _s = common::serial();
    let t0 = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let file = repo("robots/tb6612-2kg.toml");
    let file_text = std::fs::read_to_string(&file).unwrap();
    let plant = dir.path().join("plant.toml");
    let plant_text = plant_file(&file_text);
    std::fs::write(&plant, &plant_text).unwrap();
    // The scenario `hil-sim device --pty ...` serves.
    let window = format!("{WINDOW_S},100000");
    let scenario = repo("scenarios/link_nominal.toml");
    let argv = [
        "hil-sim",
        "device",
        "--pty",
        "--scenario",
        scenario.to_str().unwrap(),
        "--robot",
        file.to_str().unwrap(),
        "--plant",
        plant.to_str().unwrap(),
        "--initial-pose",
        "0,0,0",
        "--window",
        &window,
        "--beta",
        "0.1",
        "--eps",
        "0.2",
        "--skid-scale",
        "0.05",
        "--disturbance",
        "0.025",
    ];
    let cli = hil_sim::cli::Cli::try_parse_from(argv).unwrap();
    let hil_sim::cli::Command::Device(a) = &cli.command else {
        unreachable!()
    };
    let scn = a.scenario.build().unwrap();
    let mut robot = Robot::start(&scn, false);
    let port = robot.port.clone();

    // 1. Identification.
    let log = dir.path().join("id.csv");
    let identified = dir.path().join("identified.toml");
    wmr(
        &port,
        &[
            "identify",
            "run",
            "-o",
            log.to_str().unwrap(),
            "--duration",
            "30",
            "--w-amp",
            "2",
            "--robot",
            file.to_str().unwrap(),
        ],
        90,
    );
    let fit = wmr(
        &port,
        &[
            "identify",
            "fit",
            log.to_str().unwrap(),
            "--robot",
            file.to_str().unwrap(),
            "-o",
            identified.to_str().unwrap(),
        ],
        30,
    );
    let id_text = std::fs::read_to_string(&identified).unwrap();
    let (truth, prior, id) = (body(&plant_text), body(&file_text), body(&id_text));
    let names = ["mass", "inertia", "radius right", "radius left", "track"];
    let margins = [0.05, 0.10, 0.005, 0.005, 0.01];
    for i in 0..5 {
        let (e_id, e_file) = (id[i] / truth[i] - 1.0, prior[i] / truth[i] - 1.0);
        eprintln!(
            "{}: plant {:.5}, file {:.5} ({:+.2} %), identified {:.5} ({:+.2} %)",
            names[i],
            truth[i],
            prior[i],
            100.0 * e_file,
            id[i],
            100.0 * e_id
        );
        assert!(
            e_id.abs() < e_file.abs() && e_id.abs() < margins[i],
            "{}: identified {} for {} (file {}), margin {}\n{}",
            names[i],
            id[i],
            truth[i],
            prior[i],
            margins[i],
            fit.stdout
        );
    }

    // 2. Tuning of the identified file (the proposed controller: the one
    // the device runs), a budget for a test.
    let tuned = dir.path().join("tuned.toml");
    let tune = hil_sim::cli::Cli::try_parse_from([
        "hil-sim",
        "tune",
        "--robot",
        identified.to_str().unwrap(),
        "--controllers",
        "proposed",
        "--sensing",
        "mocap",
        "--train",
        "6",
        "--validate",
        "2",
        "--evaluations",
        "40",
        "--duration",
        "30",
        "--quiet",
        "--write",
        tuned.to_str().unwrap(),
    ])
    .unwrap();
    let mut table = Vec::new();
    hil_sim::cli::execute(&tune, &mut table).unwrap();
    eprintln!("{}", String::from_utf8_lossy(&table));
    let tuned_text = std::fs::read_to_string(&tuned).unwrap();
    assert!(tuned_text.contains("[gains.proposed"), "{tuned_text}");

    // 3. The file's gains (the device's compiled-in robot), perturbed.
    let wait = Instant::now();
    while robot_time_s(&port) < WINDOW_S {
        assert!(wait.elapsed() < Duration::from_secs(120), "robot time");
        std::thread::sleep(Duration::from_millis(500));
    }
    let before = track_circle(&port, dir.path(), "file-gains", 25.0);

    // 4. Push (reboot into it), track again.
    let push = wmr(&port, &["robot", "push", tuned.to_str().unwrap()], 30);
    assert!(push.stdout.contains("from flash"), "{push}");
    let after = track_circle(&port, dir.path(), "tuned-gains", 25.0);
    eprintln!(
        "circle, RMS position error after 5 s: file's gains {before:.4} m, tuned {after:.4} m ({:.0} s wall)",
        t0.elapsed().as_secs_f64()
    );
    let sim = robot.stop();
    assert_eq!(sim.reboots(), 1, "the push rebooted the robot once");
    assert!(
        after <= 0.5 * before,
        "tuned gains track the circle to {after:.4} m, the file's to {before:.4} m"
    );
}
