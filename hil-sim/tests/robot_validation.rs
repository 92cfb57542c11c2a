//! One validation of a robot (issue 31 item 3): a robot file that
//! robot-file accepts (`wmr robot check`, the store's commit) is a robot
//! the device boots. Mutated example robots (one numeric field scaled, as
//! the 424 mutated files), each either refused by the file's
//! validation or built into the simulated device (the runtime's, the
//! link's and the limits' checks of `Device::with_estimator`, what a boot
//! runs on a flash record).

use controller_core::ControllerKind;
use hil_sim::device::SimRobot;
use hil_sim::scenario::{Scenario, Sensing};
use proptest::prelude::*;

fn example_files() -> Vec<(String, toml::Table)> {
    let dir = format!("{}/../robots", env!("CARGO_MANIFEST_DIR"));
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).unwrap();
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                toml::from_str(&text).unwrap(),
            )
        })
        .collect()
}

/// Every numeric leaf of `t` with its path (array elements included).
fn numeric_paths(v: &toml::Value, path: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    match v {
        toml::Value::Table(t) => {
            for (k, x) in t {
                path.push(k.clone());
                numeric_paths(x, path, out);
                path.pop();
            }
        }
        toml::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                path.push(format!("#{i}"));
                numeric_paths(x, path, out);
                path.pop();
            }
        }
        toml::Value::Float(_) | toml::Value::Integer(_) => out.push(path.clone()),
        _ => {}
    }
}

fn leaf<'a>(v: &'a mut toml::Value, path: &[String]) -> &'a mut toml::Value {
    path.iter().fold(v, |v, k| match k.strip_prefix('#') {
        Some(i) => &mut v.as_array_mut().unwrap()[i.parse::<usize>().unwrap()],
        None => &mut v.as_table_mut().unwrap()[k.as_str()],
    })
}

/// The device built from `robot` as a boot builds it from a flash record
/// (the firmware's `config::runtime_config` and `config::device`: the
/// proposed controller at 1 kHz, the link from the file's `[limits]`, the
/// arm button's circle), and the simulated device of a scenario with it;
/// the first refusal.
fn boots(robot: &robot_file::Robot) -> Result<(), String> {
    use controller_core::trajectory::{PaperCurve, PaperHeading, Reference};
    robot.validate().map_err(|e| format!("robot: {e}"))?;
    let board = robot_file::BoardFacts::of_timer(robot, hil_sim::device::SIM_TIMER_CLOCK_HZ)
        .map_err(|e| format!("board: {e}"))?;
    let rt = robot
        .derive(
            &board,
            Reference::Paper(PaperCurve::paper(PaperHeading::SignedSmooth)),
        )
        .runtime;
    let dev = wmr_device::DeviceConfig::of_robot(
        robot,
        "test",
        0,
        Some(robot_app::DEFAULT_BUTTON_REFERENCE),
    );
    wmr_device::Device::<{ controller_core::estimator::HISTORY_LEN }>::with_estimator(
        dev,
        rt,
        controller_core::estimator::EstimatorConfig::EXAMPLE,
    )
    .map_err(|e| format!("device: {e}"))?;
    let scn = Scenario::default()
        .with_robots(Some(robot), None)
        .with_sensing(Sensing::Mocap);
    SimRobot::new(&scn, ControllerKind::Proposed).map(|_| ())
}

#[test]
fn every_robot_the_file_accepts_boots_on_the_device() {
    let files = example_files();
    let mut runner = proptest::test_runner::TestRunner::new(proptest::test_runner::Config {
        cases: std::env::var("WMR_FUZZ_CASES")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(400),
        ..Default::default()
    });
    let (accepted, refused) = (std::cell::Cell::new(0u32), std::cell::Cell::new(0u32));
    let factors = prop::sample::select(vec![
        0.0, 1e-4, 0.01, 0.1, 0.3, 0.5, 0.9, 1.1, 2.0, 3.0, 10.0, 100.0, 1e4, -1.0,
    ]);
    let cases = (0usize..64, any::<prop::sample::Index>(), factors);
    let result = runner.run(&cases, |(fi, field, factor)| {
        let (name, table) = &files[fi % files.len()];
        let mut v = toml::Value::Table(table.clone());
        let mut paths = Vec::new();
        numeric_paths(&v, &mut Vec::new(), &mut paths);
        let path = field.get(&paths).clone();
        let x = leaf(&mut v, &path);
        *x = match x {
            toml::Value::Integer(i) => toml::Value::Integer((*i as f64 * factor).round() as i64),
            toml::Value::Float(f) => toml::Value::Float(*f * factor),
            _ => unreachable!(),
        };
        let text = toml::to_string(&v).unwrap();
        if let Ok(robot) = robot_file::Robot::from_toml_str(&text) {
            accepted.set(accepted.get() + 1);
            if let Err(e) = boots(&robot) {
                panic!(
                    "{name} with {} × {factor}: the file accepts it, the device refuses: {e}",
                    path.join(".")
                );
            }
        } else {
            refused.set(refused.get() + 1);
        }
        Ok(())
    });
    result.unwrap();
    let (accepted, refused) = (accepted.get(), refused.get());
    eprintln!("{accepted} mutated robots accepted and booted, {refused} refused by the file");
    assert!(
        accepted > 50 && refused > 50,
        "{accepted} accepted, {refused} refused"
    );
}

/// The file: `robots/paper.tuned.toml` with `k_th = 2079.155`
/// passed `wmr robot check`; the device's limit (gains up to half the
/// control rate, 500/s) refused it at boot. Now the file's validation
/// refuses it, naming the field, the value and the range.
#[test]
fn a_gain_faster_than_the_loop_is_refused_by_the_file() {
    let path = format!("{}/../robots/paper.tuned.toml", env!("CARGO_MANIFEST_DIR"));
    let mut t: toml::Table = toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    t["gains"]["proposed"]["kinematic"]["k_th"] = toml::Value::Float(2079.155);
    let e = robot_file::Robot::from_toml_str(&toml::to_string(&t).unwrap()).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("gains.proposed.kinematic.k_th")
            && msg.contains("2079.155")
            && msg.contains("499.9"),
        "{msg}"
    );
}
