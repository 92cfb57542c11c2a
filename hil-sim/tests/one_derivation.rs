//! The one derivation (D139): a scenario's overrides are typed edits of the
//! robot, so a command-line override and a robot file that says the same
//! thing give the same runtime, and one robot value reaches the
//! controller, the safety limits, the device's limits and the plant
//! through `Robot::derive` alone.

use controller_core::ControllerKind;
use hil_sim::scenario::{Robot, Scenario, Sensing};
use std::process::Command;

fn robot(name: &str) -> Robot {
    let path = format!("{}/../robots/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    Robot::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// `--encoder-cpr 4096 --pwm-levels 1000` derive what a robot file with a
/// 4,096-count encoder derives: before D139 the flags replaced the
/// encoder after the derivation, so the direction block stayed the one of
/// the file's 24,000 counts, the check's tolerance was below two quanta of
/// the coarser encoder and the run was refused.
#[test]
fn cli_encoder_override_derives_like_the_file() {
    let mut scn = Scenario::default().with_sensing(Sensing::Mocap);
    scn.sensing.encoder_cpr = 4096;
    scn.sensing.pwm_levels = 1000;
    scn.validate().unwrap();
    let mut file = Robot::paper();
    file.encoders.counts_per_wheel_rev = 4096.0;
    let period_s = scn.control_period_s as f32;
    assert_eq!(scn.safety_limits(), file.safety_limits(period_s));
    // The block is longer than the 24,000-count encoder's: the derivation
    // saw the override.
    assert!(
        scn.safety_limits().direction_block_ticks
            > Robot::paper().safety_limits(period_s).direction_block_ticks
    );
    let rt = scn.derive(ControllerKind::Proposed).runtime;
    assert_eq!(rt.encoder.counts_per_wheel_rev, 4096.0);
    assert_eq!(rt.motor.duty_full_scale, 1000);
    controller_core::runtime::ControlLoop::<{ controller_core::estimator::HISTORY_LEN }>::new(rt)
        .expect("the runtime takes the derived configuration");

    // And the command line runs it (issue 32's failing command).
    let out = Command::new(env!("CARGO_BIN_EXE_hil-sim"))
        .args([
            "run",
            "--sensing",
            "mocap",
            "--encoder-cpr",
            "4096",
            "--pwm-levels",
            "1000",
            "--duration",
            "3",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// One robot value, the torque limit, walked from the file: the
/// controller saturates at it, the stall and direction thresholds are the
/// derived fractions of it, the device's limits bound the commanded torque
/// with it, and the plant robot carries it — all from the file's number,
/// through `Robot::derive`, on each example robot.
#[test]
fn the_torque_limit_walks_from_the_file_everywhere() {
    for name in ["paper", "tb6612-2kg", "bts7960-10kg"] {
        let r = robot(name);
        let limit = r.limits.torque_nm;
        let scn = Scenario::default()
            .with_robots(Some(&r), None)
            .with_sensing(Sensing::Mocap);
        let d = scn.derive(ControllerKind::Proposed);
        assert_eq!(d.runtime.controller.torque_limit_nm, limit, "{name}");
        assert_eq!(
            d.runtime.safety.stall_torque_nm,
            robot_file::STALL_TORQUE_FRACTION * limit,
            "{name}"
        );
        assert!(
            d.runtime.safety.direction_torque_nm <= 0.5 * limit,
            "{name}"
        );
        // The device built from the derivation (as a boot builds it) runs
        // the controller at the file's limit, and its limits accept it.
        let dev_cfg = wmr_device::DeviceConfig::of_robot(&r, "test", 0, None);
        let dev =
            wmr_device::Device::<{ controller_core::estimator::HISTORY_LEN }>::with_estimator(
                dev_cfg,
                d.runtime,
                d.estimator,
            )
            .unwrap_or_else(|e| panic!("{name}: {e:?}"));
        assert_eq!(
            dev.control().config().controller.torque_limit_nm,
            limit,
            "{name}"
        );
        let lim = wmr_device::limits::RobotLimits::of(&d.runtime);
        assert!(lim.stall_torque_nm >= limit, "{name}");
        assert_eq!(scn.plant_robot().unwrap().limits.torque_nm, limit, "{name}");
        // The scenario's override edits the same value for all of them.
        let mut over = scn.clone();
        over.plant.torque_limit_nm = Some(f64::from(limit) * 0.5);
        let d2 = over.derive(ControllerKind::Proposed);
        assert_eq!(d2.runtime.controller.torque_limit_nm, 0.5 * limit);
        assert_eq!(
            d2.runtime.safety.stall_torque_nm,
            robot_file::STALL_TORQUE_FRACTION * 0.5 * limit
        );
    }
}

/// The `[control]` section reaches every simulation: a file that runs SMC
/// without the governor, from (1, 2), makes a scenario that does not say
/// otherwise run that; the scenario's own keys still win.
#[test]
fn control_section_reaches_the_scenario() {
    let mut r = Robot::paper();
    r.control.governor = false;
    r.control.clean_start = false;
    let scn = Scenario::default().with_robots(Some(&r), None);
    assert!(!scn.governor_on());
    let d = scn.derive(ControllerKind::Smc);
    assert_eq!(
        d.runtime.pacing,
        controller_core::pacer::PacingConfig::off()
    );
    assert_eq!(
        d.runtime.controller.kinematic.large_error_m,
        controller_core::ControllerConfig::paper(ControllerKind::Smc)
            .kinematic
            .large_error_m
    );
    let mut on = scn.clone();
    on.governor.enabled = Some(true);
    on.controller.clean_start = Some(true);
    let d = on.derive(ControllerKind::Smc);
    assert_eq!(d.runtime.pacing, controller_core::pacer::PacingConfig::on());
    assert_eq!(
        d.runtime.controller.kinematic.large_error_m,
        controller_core::kinematic::DEFAULT_LARGE_ERROR_M
    );
}
