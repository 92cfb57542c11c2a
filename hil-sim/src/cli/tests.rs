//! Tests of the command line as a whole: parsing, errors, each subcommand's output.

use super::*;
use crate::scenario::{Scenario, Sensing, TrajectoryKind};
use controller_core::ControllerKind;

fn parse(args: &[&str]) -> Result<Cli, clap::Error> {
    Cli::try_parse_from(std::iter::once("hil-sim").chain(args.iter().copied()))
}

fn run_to_string(args: &[&str]) -> Result<String, String> {
    let cli = parse(args).map_err(|e| e.to_string())?;
    let mut buf = Vec::new();
    execute(&cli, &mut buf)?;
    Ok(String::from_utf8(buf).unwrap())
}

#[test]
fn argument_errors_are_rejected_by_the_parser() {
    for bad in [
        &["run", "--controller", "pid"][..],
        &["run", "--case", "3"],
        &["run", "--trajectory", "spiral"],
        &["run", "--beta", "abc"],
        &["run", "--case", "1", "--scenario", "x.toml"],
        &["montecarlo"],
        &["montecarlo", "--runs", "0"],
        &["frobnicate"],
    ] {
        assert!(parse(bad).is_err(), "{bad:?} should not parse");
    }
    let e = parse(&["run", "--controller", "pid"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("smc") && e.contains("proposed"), "{e}");
}

#[test]
fn invalid_values_give_errors_not_panics() {
    let e = run_to_string(&["run", "--eps", "1.5", "--json"]).unwrap_err();
    // The value and the range (issue 37).
    assert!(e.contains("eps = 1.5 must be in [0, 1)"), "{e}");
    let e = run_to_string(&["run", "--duration=-1"]).unwrap_err();
    assert!(e.contains("duration"), "{e}");
    let e = run_to_string(&["run", "--torque-limit", "NaN"]).unwrap_err();
    assert!(e.contains("torque"), "{e}");
    let e = run_to_string(&["run", "--scenario", "/nonexistent/x.toml"]).unwrap_err();
    assert!(e.contains("cannot read"), "{e}");
}

#[test]
fn flags_override_the_preset_and_the_file() {
    let cli = parse(&[
        "run",
        "--case",
        "1",
        "--seed",
        "4",
        "--beta",
        "0.15",
        "--mass-scale",
        "1.1",
        "--trajectory",
        "figure8",
        "--k-y",
        "10",
        "--sensing",
        "odometry",
        "--encoder-cpr",
        "1024",
    ])
    .unwrap();
    let Command::Run(a) = cli.command else {
        panic!()
    };
    let s = a.scenario.build().unwrap();
    assert_eq!(s.name, "case1");
    assert_eq!(
        (s.perturbations.beta, s.perturbations.eps, s.seed),
        (0.15, 0.0, 4)
    );
    assert_eq!(s.plant.mass_scale, 1.1);
    assert_eq!(s.trajectory, TrajectoryKind::Figure8);
    assert_eq!(s.controller.k_y, Some(10.0));
    assert_eq!(s.sensing.encoder_cpr, 1024);

    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("s.toml");
    std::fs::write(
        &f,
        "name = \"file\"\nbeta = 0.01\nsensing = \"mocap\"\npwm_levels = 255\npose_rate_hz = 50.0\n",
    )
    .unwrap();
    let cli = parse(&["run", "--scenario", f.to_str().unwrap(), "--beta", "0.02"]).unwrap();
    let Command::Run(a) = cli.command else {
        panic!()
    };
    let s = a.scenario.build().unwrap();
    assert_eq!(
        (s.name.as_str(), s.perturbations.beta, s.sensing.pwm_levels),
        ("file", 0.02, 255)
    );
}

#[test]
fn sensing_flags_override_the_preset() {
    let cli = parse(&[
        "run",
        "--sensing",
        "uwb",
        "--pose-rate",
        "20",
        "--pose-outage",
        "20,22",
        "--gyro-bias",
        "-0.01",
    ])
    .unwrap();
    let Command::Run(a) = cli.command else {
        panic!()
    };
    let s = a.scenario.build().unwrap();
    assert_eq!(s.sensing.preset, Sensing::Uwb);
    assert_eq!(s.sensing.pose.pose_rate_hz, Some(20.0));
    assert_eq!(
        s.sensing.pose.pose_outage_s,
        Some(crate::sensing::Window([20.0, 22.0]))
    );
    assert_eq!(s.sensing.gyro.gyro_bias_radps, Some(-0.01));
    let e = parse(&["run", "--sensing", "mocap", "--pose-outage", "20"]).unwrap_err();
    assert!(e.to_string().contains("START,END"), "{e}");
    let e = run_to_string(&["run", "--sensing", "odometry", "--pose-rate", "5"]).unwrap_err();
    assert!(e.contains("pose_*"), "{e}");
    let text = run_to_string(&[
        "run",
        "--sensing",
        "mocap",
        "--duration",
        "2",
        "--pose-outlier-fraction",
        "0.2",
    ])
    .unwrap();
    assert!(
        text.contains("sensing mocap") && text.contains("outliers injected"),
        "{text}"
    );
}

#[test]
fn run_json_is_one_object_with_every_metric_key() {
    let text =
        run_to_string(&["run", "--duration", "2", "--json", "--controller", "asmc"]).unwrap();
    assert_eq!(text.trim_end().lines().count(), 1);
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let o = v.as_object().unwrap();
    for k in [
        "rms_pos_err_m",
        "rms_pos_err_window_m",
        "max_pos_err_window_m",
        "rms_pos_err_after5_m",
        "final_pos_err_m",
        "settling_time_s",
        "torque_rms_nm",
        "max_abs_torque_nm",
        "chatter",
        "saturated_fraction",
        "fault_est_rmse",
        "controller",
        "scenario",
    ] {
        assert!(o.contains_key(k), "missing {k}");
    }
    assert!(o["fault_est_rmse"].is_null());
    assert_eq!(o["controller"], "asmc");
    let text = run_to_string(&["run", "--duration", "2", "--json"]).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(v["fault_est_rmse"].is_number());
}

#[test]
fn run_csv_has_header_and_one_row_per_10ms() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("t.csv");
    let text = run_to_string(&["run", "--duration", "1.5", "--csv", f.to_str().unwrap()]).unwrap();
    assert!(text.contains("150 rows"), "{text}");
    let csv = std::fs::read_to_string(&f).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], crate::report::CSV_HEADER);
    assert_eq!(lines.len(), 151);
    let t_last: f64 = lines[150].split(',').next().unwrap().parse().unwrap();
    assert!((t_last - 1.49).abs() < 1e-9);
    run_to_string(&[
        "run",
        "--duration",
        "1",
        "--csv",
        f.to_str().unwrap(),
        "--csv-every",
        "1",
    ])
    .unwrap();
    assert_eq!(std::fs::read_to_string(&f).unwrap().lines().count(), 1001);
}

#[test]
fn compare_without_plots_writes_metrics_json() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let text = run_to_string(&["compare", "--out", out, "--no-plots"]).unwrap();
    assert_eq!(
        text.lines()
            .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()) && l.contains("proposed"))
            .count(),
        4,
        "the paper table and the governed one: {text}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("metrics.json")).unwrap())
            .unwrap();
    assert_eq!(v.as_array().unwrap().len(), 6);
    assert_eq!(v[5]["case"], 2);
    assert_eq!(v[5]["controller"], "proposed");
    // The paper's setting: no governor, so no governor metrics.
    assert!(v[5].get("time_lag_final_s").is_none());
    assert_eq!(v[5]["scenario"]["governor"]["enabled"], false);
    let g: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("metrics_governor.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(g.as_array().unwrap().len(), 6);
    assert!(g[5]["time_lag_final_s"].as_f64().unwrap() >= 0.0);
    assert!(
        g[5]["scenario"]["governor"].get("enabled").is_none(),
        "on: the default"
    );
}

/// `hil-sim report` of a CSV logged at every control step gives the
/// simulation's own metrics (same accumulator, same values); a file that
/// is not a trace is a clear error.
#[test]
fn report_of_a_full_trace_csv_equals_the_run() {
    let mut scn = Scenario {
        duration_s: 6.0,
        ..Scenario::paper_case(1, 2, None, None)
    };
    scn.perturbations.window_s = [2.0, 4.0];
    let cfg = crate::sim::controller_config(&scn, ControllerKind::Asmc);
    let out = crate::sim::run_with(&scn, cfg, 1).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("t.csv");
    let f = std::fs::File::create(&csv).unwrap();
    crate::report::write_trace_csv(std::io::BufWriter::new(f), &out.trace).unwrap();
    let cli = Cli::try_parse_from([
        "hil-sim",
        "report",
        csv.to_str().unwrap(),
        "--window",
        "2",
        "4",
        "--controller",
        "asmc",
        "--no-plots",
        "--json",
    ])
    .unwrap();
    let mut buf = Vec::new();
    execute(&cli, &mut buf).unwrap();
    let m: crate::Metrics = serde_json::from_slice(&buf).unwrap();
    let s = &out.metrics;
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * (1.0 + b.abs());
    assert!(close(m.rms_pos_err_m, s.rms_pos_err_m));
    assert!(close(m.rms_pos_err_window_m, s.rms_pos_err_window_m));
    assert!(close(m.torque_rms_nm, s.torque_rms_nm));
    assert!(close(m.chatter, s.chatter));

    std::fs::write(dir.path().join("bad.csv"), "a,b\n").unwrap();
    let bad = dir.path().join("bad.csv");
    let cli = Cli::try_parse_from(["hil-sim", "report", bad.to_str().unwrap()]).unwrap();
    let e = execute(&cli, &mut Vec::new()).unwrap_err();
    assert!(
        e.contains("bad.csv") && e.contains("not a trace CSV"),
        "{e}"
    );
}

/// Issue 21 item 7 through the command line: valid-looking but absurd values
/// are refused with the field named, before anything runs.
#[test]
fn absurd_values_are_refused_before_running() {
    let e = run_to_string(&["run", "--duration", "0.1", "--torque-limit", "1e30"]).unwrap_err();
    assert!(e.contains("torque_limit_nm = 1e30"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("s.toml");
    std::fs::write(&f, "duration_s = 0.1\ninitial_pose = [1e308, 0.0, 0.0]\n").unwrap();
    let e = run_to_string(&["run", "--scenario", f.to_str().unwrap()]).unwrap_err();
    assert!(e.contains("initial_pose"), "{e}");
    let e = run_to_string(&["run", "--duration", "0.001", "--substeps", "4000000000"]).unwrap_err();
    assert!(e.contains("substeps"), "{e}");
    let e = run_to_string(&["run", "--duration", "0.001", "--control-period", "1e-9"]).unwrap_err();
    assert!(e.contains("control_period_s"), "{e}");
    let e = run_to_string(&["montecarlo", "--runs", "1", "--duration", "1e9"]).unwrap_err();
    assert!(e.contains("duration_s"), "{e}");
    // `device --for-s` NaN, negative or 0 exited 0 at once (a u32 wrap).
    for bad in ["NaN", "-5", "0"] {
        let arg = format!("--for-s={bad}");
        let e = run_to_string(&["device", "--pty", &arg]).unwrap_err();
        assert!(e.contains("--for-s"), "{bad}: {e}");
    }
}

/// The repository's robots/ directory.
fn robots_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots")
}

/// `--robot robots/paper.toml` runs the same robot as no flag: `compare`'s
/// text (every table) is identical but for the timing and the output path;
/// another robot changes it (the flag is not ignored).
#[test]
fn compare_with_the_paper_robot_file_equals_no_flag() {
    let paper = robots_dir().join("paper.toml");
    let small = robots_dir().join("tb6612-2kg.toml");
    let text = |extra: &[&str]| {
        let dir = tempfile::tempdir().unwrap();
        let mut args = vec![
            "compare",
            "--out",
            dir.path().to_str().unwrap(),
            "--no-plots",
        ];
        args.extend_from_slice(extra);
        let t = run_to_string(&args).unwrap();
        let out = dir.path().to_str().unwrap().to_string();
        t.lines()
            .filter(|l| !l.contains(" simulations in "))
            .map(|l| l.replace(&out, "OUT"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let none = text(&[]);
    assert_eq!(none, text(&["--robot", paper.to_str().unwrap()]));
    assert_ne!(none, text(&["--robot", small.to_str().unwrap()]));
}

/// Issue 18's acceptance: each example robot (robots/*.toml) runs in
/// `compare --robot FILE`: both cases of the three controllers, every
/// metric in metrics.json finite, the torque within the file's limit
/// (the controller saturates there: its `tau_max` can be no larger).
#[test]
fn compare_runs_each_example_robot() {
    for file in ["paper.toml", "tb6612-2kg.toml", "bts7960-10kg.toml"] {
        let path = robots_dir().join(file);
        let robot =
            robot_file::Robot::from_toml_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let args = [
            "compare",
            "--out",
            dir.path().to_str().unwrap(),
            "--no-plots",
            "--robot",
            path.to_str().unwrap(),
        ];
        let text = run_to_string(&args).unwrap_or_else(|e| panic!("{file}: {e}"));
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("metrics.json")).unwrap(),
        )
        .unwrap();
        let runs = json.as_array().unwrap_or_else(|| panic!("{file}: {json}"));
        assert_eq!(runs.len(), 6, "{file}: {text}");
        for m in runs {
            for k in [
                "rms_pos_err_m",
                "final_pos_err_m",
                "torque_rms_nm",
                "max_abs_torque_nm",
            ] {
                let v = m[k].as_f64().unwrap_or(f64::NAN);
                assert!(v.is_finite() && v >= 0.0, "{file}: {k} = {v}");
            }
            let tau_max = m["max_abs_torque_nm"].as_f64().unwrap();
            assert!(m["controller"].is_string(), "{file}: {m}");
            assert!(
                tau_max <= robot.limits.torque_nm as f64 * (1.0 + 1e-6),
                "{file}: torque {tau_max} above the file's limit {}",
                robot.limits.torque_nm
            );
        }
    }
}

/// A bad robot file is an error naming the file and the field, never a
/// panic, for every command that takes one.
#[test]
fn bad_robot_files_are_errors_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(robots_dir().join("paper.toml")).unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, text.replace("track_m = 0.4", "track_m = -0.4")).unwrap();
    let bad = bad.to_str().unwrap();
    let out = dir.path().to_str().unwrap();
    for args in [
        vec!["run", "--duration", "0.1", "--robot", bad],
        vec!["run", "--duration", "0.1", "--plant", bad],
        vec!["compare", "--no-plots", "--out", out, "--robot", bad],
        vec![
            "montecarlo",
            "--runs",
            "1",
            "--duration",
            "0.1",
            "--robot",
            bad,
        ],
        vec!["sweep", "--duration", "0.1", "--robot", bad],
    ] {
        let e = run_to_string(&args).unwrap_err();
        assert!(
            e.contains("bad.toml") && e.contains("body.track_m"),
            "{args:?}: {e}"
        );
    }
    let e = run_to_string(&["run", "--robot", "/nonexistent/robot.toml"]).unwrap_err();
    assert!(e.contains("cannot read robot file"), "{e}");
}

/// `--plant` with a robot whose track is 5 % wider changes the run (the
/// plant differs from the model), and the same file as `--robot` and
/// `--plant` equals `--robot` alone.
#[test]
fn plant_file_makes_the_simulated_robot_differ() {
    let dir = tempfile::tempdir().unwrap();
    let paper = robots_dir().join("paper.toml");
    let text = std::fs::read_to_string(&paper).unwrap();
    let wide = dir.path().join("wide.toml");
    std::fs::write(&wide, text.replace("track_m = 0.4", "track_m = 0.42")).unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec!["run", "--duration", "12", "--json"];
        args.extend_from_slice(extra);
        let v: serde_json::Value = serde_json::from_str(&run_to_string(&args).unwrap()).unwrap();
        v["rms_pos_err_window_m"].as_f64().unwrap()
    };
    let p = paper.to_str().unwrap();
    let nominal = run(&["--robot", p]);
    assert_eq!(nominal, run(&["--robot", p, "--plant", p]));
    assert_ne!(nominal, run(&["--plant", wide.to_str().unwrap()]));
}

/// `compare --robot` says when the paper's cases are beyond the robot
/// (independent reasons: the paper's own robot, 4 m/s at no load
/// (24 V / (0.05 V·s/rad × 12) × 0.1 m) and 10 N·m, follows its curve; the
/// 2 kg robot's 1.22 m/s and 0.25 N·m are below the curve's speed and the
/// paper's 1 N·m disturbance).
#[test]
fn compare_notes_a_robot_the_paper_cases_are_beyond() {
    let load = |f: &str| {
        robot_file::Robot::from_toml_str(&std::fs::read_to_string(robots_dir().join(f)).unwrap())
            .unwrap()
    };
    assert_eq!(
        super::compare::paper_cases_beyond(&load("paper.toml")),
        None
    );
    let note = super::compare::paper_cases_beyond(&load("tb6612-2kg.toml")).unwrap();
    eprintln!("{note}");
    assert!(note.contains("reaches at most 1.22 m/s"), "{note}");
    assert!(note.contains("speed of 1.97 m/s"), "{note}");
    assert!(note.contains("hil-sim sweep --robot"), "{note}");
    // Within its speed (the 0.5 m/s circle), the paper's 1 N·m
    // disturbance is still 4x the robot's 0.25 N·m.
    let mut scn = crate::scenario::Scenario::paper_case(2, 1, None, None)
        .with_robots(Some(&load("tb6612-2kg.toml")), None);
    scn.trajectory = crate::scenario::TrajectoryKind::Circle;
    let e = crate::limits::check_within_robot(&scn).unwrap_err();
    assert!(e.contains("1 N·m is 4.0x"), "{e}");
    assert!(e.contains("--disturbance 0.025"), "{e}");
}

/// A run the runtime stops says so, with the time and the reason (issue
/// 32: a run printed only a count of rejected steps): the plant's left
/// motor wired the other way round latches the direction check (D74).
#[test]
fn a_safe_stop_is_named_in_the_run_text() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("miswired.toml");
    std::fs::write(
        &f,
        "version = 2\nduration_s = 2.0\n[sensing]\npreset = \"mocap\"\n[plant.bridge]\nmotor_inverted = [false, false]\n",
    )
    .unwrap();
    let text = run_to_string(&["run", "--scenario", f.to_str().unwrap()]).unwrap();
    assert!(text.contains("SAFE STOP at t = "), "{text}");
    assert!(text.contains("DirectionMismatch"), "{text}");
    assert!(text.contains("after the safe stop above"), "{text}");
    // The JSON says so too (it reported no stop at all before: `safe_stop`
    // is the health machine's).
    let json = run_to_string(&["run", "--scenario", f.to_str().unwrap(), "--json"]).unwrap();
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
    let stop = &v["runtime_stop"];
    assert!(
        stop["reason"]
            .as_str()
            .unwrap()
            .starts_with("DirectionMismatch"),
        "{json}"
    );
    let t = stop["t_s"].as_f64().unwrap();
    assert!(t > 0.0 && t < 2.0, "{json}");
}

/// `hil-sim device --robot FILE` serves the file's robot from the file's
/// start pose and controller (the paper case's 2.5 m start and the
/// proposed controller only for the paper's robot); the flags override.
#[test]
fn the_device_starts_where_its_robot_file_says() {
    let dir = std::env::temp_dir().join(format!("hil-sim-dev-start-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let base = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../robots/tb6612-2kg.toml"
    ))
    .unwrap();
    let f = dir.join("r.toml");
    std::fs::write(
        &f,
        base + "\n[control]\ncontroller = \"smc\"\ninitial_x_m = -1.5\ninitial_y_m = 0.25\ninitial_heading_rad = 2.0\n",
    )
    .unwrap();
    let f = f.to_str().unwrap();
    let scn_of = |args: &[&str]| match parse(args).unwrap().command {
        Command::Device(a) => device::device_scenario(&a).unwrap(),
        _ => unreachable!(),
    };
    let (scn, kind) = scn_of(&["device", "--pty", "--robot", f]);
    assert_eq!(scn.initial_pose, [-1.5, 0.25, 2.0]);
    assert_eq!(kind, ControllerKind::Smc);
    // Unperturbed: the paper case's 1 N·m disturbance is 4x this robot's
    // 0.25 N·m torque limit.
    assert_eq!(scn.perturbations, crate::scenario::PerturbationPart::none());
    // --case brings the paper's perturbations back; a flag sets its own.
    let (scn, _) = scn_of(&["device", "--pty", "--robot", f, "--case", "2"]);
    assert_eq!(scn.perturbations.disturbance_nm, 1.0);
    assert!(scn.perturbations.eps > 0.0);
    let (scn, _) = scn_of(&[
        "device", "--pty", "--robot", f, "--window", "5,9", "--beta", "0.05",
    ]);
    assert_eq!(scn.perturbations.window_s, [5.0, 9.0]);
    assert_eq!(
        (scn.perturbations.beta, scn.perturbations.disturbance_nm),
        (0.05, 0.0)
    );
    let (scn, kind) = scn_of(&[
        "device",
        "--pty",
        "--robot",
        f,
        "--initial-pose",
        "1,2,0.5",
        "--controller",
        "asmc",
    ]);
    assert_eq!(scn.initial_pose, [1.0, 2.0, 0.5]);
    assert_eq!(kind, ControllerKind::Asmc);
    // No robot file: the paper case as before.
    let (scn, kind) = scn_of(&["device", "--pty"]);
    assert_eq!(scn.initial_pose, [2.5, 0.0, 0.0]);
    assert_eq!(scn.perturbations.disturbance_nm, 1.0);
    assert_eq!(kind, ControllerKind::Proposed);
    let _ = std::fs::remove_dir_all(&dir);
}
