//! Issue 32's acceptance: one parameter's range is refused identically —
//! the same bound, the error naming the field, the value and the limit —
//! by the robot file (robot-file's validation), the device (wmr-device's
//! set-param check) and the ROS parameter service (this bridge's
//! `set_parameters` handling), all three from controller-core's parameter
//! table (D144).

use controller_core::runtime::param_table::{Beyond, RobotBounds};
use robot_file::{Reason, Robot};
use ros2_client::parameters::raw::{ParameterType, ParameterValue};
use wmr_device::limits::RobotLimits;
use wmr_device::{check_set, SetParamError};
use wmr_protocol::ParamId;
use wmr_ros2::params::{self, SetRefusal};

fn double(x: f64) -> ParameterValue {
    let mut v = params::value(ParameterType::DOUBLE);
    v.double_value = x;
    v
}

fn device_limits(robot: &Robot) -> RobotLimits {
    let kind = controller_core::ControllerKind::Proposed;
    let board = robot_file::BoardFacts::of_timer(robot, 96_000_000).unwrap();
    let rt = robot
        .derive(
            &board,
            controller_core::runtime::RuntimeConfig::example(kind).reference,
        )
        .runtime;
    RobotLimits::of(&rt)
}

#[test]
fn a_range_is_refused_identically_by_the_file_the_device_and_ros() {
    let paper = Robot::paper();
    let lim = device_limits(&paper);
    type Set = fn(&mut Robot, f32);
    // limits.max_accel_mps2 = 25 (a fixed bound: the bridge refuses it
    // itself), limits.torque_nm above the stall torque (the robot's own
    // bound: the bridge refuses it when it knows the robot).
    let cases: [(ParamId, f32, Set); 2] = [
        (ParamId::AccelMps2, 25.0, |r, v| r.limits.max_accel_mps2 = v),
        (ParamId::TorqueLimitNm, 30.0, |r, v| r.limits.torque_nm = v),
    ];
    for (id, value, set) in cases {
        let mut bad = paper.clone();
        set(&mut bad, value);
        let fe = bad.validate().unwrap_err();
        let Reason::Range(file) = fe.reason else {
            panic!("{fe}")
        };
        let Err(SetParamError::Range(device)) = check_set(&lim, id, value) else {
            panic!("{id:?}")
        };
        let ros_param = params::find(id.name()).unwrap();
        let bounds = if id == ParamId::AccelMps2 {
            RobotBounds::ABSOLUTE
        } else {
            paper.bounds()
        };
        let Err(SetRefusal::Range(ros)) = ros_param.robot_value(&double(value as f64), &bounds)
        else {
            panic!("{id:?}")
        };
        assert_eq!(file, device, "{id:?}");
        assert_eq!(device, ros, "{id:?}");
        assert_eq!(ros.field, id.name());
        assert_eq!((ros.value, ros.beyond), (value, Beyond::Max));
        let text = fe.to_string();
        assert_eq!(text, device.to_string());
        assert_eq!(
            text,
            SetRefusal::Range(ros).to_string(),
            "the ROS reason is the file's"
        );
        assert!(text.contains("is above its limit"), "{text}");
        assert!(text.contains("set a value in"), "{text}");
    }
    let e = check_set(&lim, ParamId::AccelMps2, 25.0)
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "limits.max_accel_mps2: 25 m/s² is above its limit 20 m/s²: set a value in [0.01, 20] m/s²"
    );
}
