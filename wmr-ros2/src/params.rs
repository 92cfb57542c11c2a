//! The robot's parameters as ROS parameters of the bridge's node (D123):
//! the `rcl_interfaces` services `get_parameters`, `get_parameter_types`,
//! `set_parameters`, `list_parameters` and `describe_parameters` under the
//! node's name, served by the bridge's own loop with the bridge's service
//! mapping (ros2-client's built-in parameter services run in its
//! `Spinner`, always with the "enhanced" mapping, and keep values in the
//! node: here every value lives on the robot).
//!
//! Every read asks the robot (`GetParam`), every write goes through the
//! link (`SetParam`): a value the robot refuses gives
//! `SetParametersResult { successful: false, reason }` with the robot's
//! reason (its range checks and "hold only" rule, wmr-protocol's
//! `ParamId`), and nothing is cached that could disagree with the robot.
//! The names are wmr-protocol's (`wmr params get NAME`): `k_x`,
//! `max_speed_mps`, ...

use ros2_client::parameters::raw::{ParameterDescriptor, ParameterType, ParameterValue};
use wmr_protocol::ParamId;

/// One robot parameter offered as a ROS parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RosParam {
    /// The robot's parameter.
    pub id: ParamId,
    /// Settable through ROS (else read only: `set_parameters` refuses it).
    pub writable: bool,
    /// A ROS integer (else a double).
    pub integer: bool,
    /// What it is, its unit, when the robot takes it.
    pub description: &'static str,
}

const fn p(id: ParamId, writable: bool, integer: bool, description: &'static str) -> RosParam {
    RosParam {
        id,
        writable,
        integer,
        description,
    }
}

/// Why a parameter is read only here although the link can write it.
pub const BRIDGE_OWNED: &str =
    "set by the bridge itself (telemetry rate: --rate-hz; link timeout: the link's keep-alive follows it)";

/// Every robot parameter, in wmr-protocol's wire order. Writable: the gains
/// and limits the robot takes while it holds. Read only: the control
/// period (a constant of the firmware) and the two the bridge sets itself
/// ([`BRIDGE_OWNED`]).
pub const PARAMS: [RosParam; 15] = [
    p(
        ParamId::TorqueLimitNm,
        true,
        false,
        "per-wheel torque limit [N·m]; hold only",
    ),
    p(
        ParamId::Kx,
        true,
        false,
        "kinematic gain k_x of eq. (14) [1/s]; hold only",
    ),
    p(
        ParamId::Ky,
        true,
        false,
        "kinematic gain k_y of eq. (14) [1/m²]; hold only",
    ),
    p(
        ParamId::Ktheta,
        true,
        false,
        "kinematic gain k_θ of eq. (14) [1/m]; hold only",
    ),
    p(
        ParamId::Ks,
        true,
        false,
        "sliding-surface gain k_s of eq. (20); hold only",
    ),
    p(
        ParamId::StallTorqueNm,
        true,
        false,
        "stall torque of the safety supervisor [N·m]; hold only",
    ),
    p(
        ParamId::StallTicks,
        true,
        true,
        "stall time of the safety supervisor [control ticks]; hold only",
    ),
    p(
        ParamId::TelemetryRateHz,
        false,
        true,
        "telemetry rate [Hz] (read only: --rate-hz)",
    ),
    p(
        ParamId::LinkTimeoutMs,
        false,
        true,
        "link-silence timeout while moving [ms] (read only here)",
    ),
    p(
        ParamId::AccelMps2,
        true,
        false,
        "acceleration limit of velocity commands [m/s²]; hold only",
    ),
    p(
        ParamId::AngAccelRadps2,
        true,
        false,
        "angular acceleration limit of velocity commands [rad/s²]; hold only",
    ),
    p(
        ParamId::BrakeDecelMps2,
        true,
        false,
        "deceleration of a controlled stop [m/s²]; hold only",
    ),
    p(
        ParamId::MaxSpeedMps,
        true,
        false,
        "largest |v| a velocity command may ask [m/s]; hold only",
    ),
    p(
        ParamId::MaxYawRateRadps,
        true,
        false,
        "largest |ω| a velocity command may ask [rad/s]; hold only",
    ),
    p(
        ParamId::ControlPeriodS,
        false,
        false,
        "control period [s] (a firmware constant)",
    ),
];

/// The parameter of a ROS name.
pub fn find(name: &str) -> Option<&'static RosParam> {
    PARAMS.iter().find(|p| p.id.name() == name)
}

impl RosParam {
    /// Its ROS name.
    pub fn name(&self) -> &'static str {
        self.id.name()
    }

    /// Its ROS type (`rcl_interfaces/msg/ParameterType`).
    pub fn ros_type(&self) -> u8 {
        if self.integer {
            ParameterType::INTEGER
        } else {
            ParameterType::DOUBLE
        }
    }

    /// The robot's value (f32 on the link) as a ROS value.
    pub fn ros_value(&self, v: f32) -> ParameterValue {
        let mut out = value(ParameterType::NOT_SET);
        if self.integer && v.is_finite() {
            out.ptype = ParameterType::INTEGER;
            out.int_value = v.round() as i64;
        } else {
            out.ptype = ParameterType::DOUBLE;
            out.double_value = v as f64;
        }
        out
    }

    /// The value to send to the robot, or why not: read only, or a ROS
    /// value of the wrong type (a double takes an integer too, as
    /// `ros2 param set NODE k_x 2` sends one; an integer takes no double).
    /// The range is the robot's to check.
    pub fn robot_value(&self, v: &ParameterValue) -> Result<f32, String> {
        if !self.writable {
            return Err(match self.id {
                ParamId::ControlPeriodS => format!("{} is read only", self.name()),
                _ => format!("{} is read only here: {BRIDGE_OWNED}", self.name()),
            });
        }
        match (v.ptype, self.integer) {
            (ParameterType::DOUBLE, false) => Ok(v.double_value as f32),
            (ParameterType::INTEGER, _) => Ok(v.int_value as f32),
            (t, _) => Err(format!(
                "{} takes {}, not {}",
                self.name(),
                type_name(self.ros_type()),
                type_name(t)
            )),
        }
    }

    /// Its `rcl_interfaces/msg/ParameterDescriptor`.
    pub fn descriptor(&self) -> ParameterDescriptor {
        ParameterDescriptor {
            name: self.name().into(),
            r#type: self.ros_type(),
            description: self.description.into(),
            additional_constraints: if self.writable {
                "checked by the robot (physical range; only while it holds): a refusal carries its reason".into()
            } else {
                String::new()
            },
            read_only: !self.writable,
            dynamic_typing: false,
            floating_point_range: Vec::new(),
            integer_range: Vec::new(),
        }
    }
}

/// A value of type `ptype`, every field empty: what `get_parameters`
/// answers for a name that is not a parameter (NOT_SET).
pub fn value(ptype: u8) -> ParameterValue {
    ParameterValue {
        ptype,
        boolean_value: false,
        int_value: 0,
        double_value: 0.0,
        string_value: String::new(),
        byte_array: Vec::new(),
        bool_array: Vec::new(),
        int_array: Vec::new(),
        double_array: Vec::new(),
        string_array: Vec::new(),
    }
}

fn type_name(t: u8) -> &'static str {
    match t {
        ParameterType::NOT_SET => "no value",
        ParameterType::BOOL => "a bool",
        ParameterType::INTEGER => "an integer",
        ParameterType::DOUBLE => "a double",
        ParameterType::STRING => "a string",
        _ => "an array",
    }
}

/// `list_parameters`: the names under any of `prefixes` (all when empty;
/// a name is under a prefix when it is the prefix or starts with it and a
/// `.`, rcl's rule). The names have no `.`, so the depth never cuts one.
pub fn list(prefixes: &[String]) -> Vec<String> {
    PARAMS
        .iter()
        .map(|p| p.name())
        .filter(|n| {
            prefixes.is_empty()
                || prefixes.iter().any(|pre| {
                    *n == pre
                        || n.strip_prefix(pre.as_str())
                            .is_some_and(|r| r.starts_with('.'))
                })
        })
        .map(String::from)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_robot_parameter_once_in_wire_order() {
        let ids: Vec<ParamId> = PARAMS.iter().map(|p| p.id).collect();
        assert_eq!(ids, ParamId::ALL.to_vec());
        for p in &PARAMS {
            assert_eq!(find(p.name()), Some(p));
        }
        assert_eq!(find("kx"), None);
    }

    #[test]
    fn only_the_hold_only_gains_and_limits_are_writable() {
        // wmr-protocol documents each ParamId as "(hold only)", "(any
        // state)" or "(read only)": the hold-only ones are the gains and
        // limits; the any-state ones are the bridge's own.
        let read_only: Vec<&str> = PARAMS
            .iter()
            .filter(|p| !p.writable)
            .map(|p| p.name())
            .collect();
        assert_eq!(
            read_only,
            ["telemetry_rate_hz", "link_timeout_ms", "control_period_s"]
        );
        assert!(PARAMS
            .iter()
            .filter(|p| p.writable)
            .all(|p| p.description.ends_with("hold only")));
    }

    #[test]
    fn values_convert_and_wrong_types_are_refused() {
        let kx = find("k_x").unwrap();
        let v = kx.ros_value(2.5);
        assert_eq!((v.ptype, v.double_value), (ParameterType::DOUBLE, 2.5));
        assert_eq!(kx.robot_value(&v), Ok(2.5));
        let mut i = value(ParameterType::INTEGER);
        i.int_value = 3;
        assert_eq!(kx.robot_value(&i), Ok(3.0));
        let mut s = value(ParameterType::STRING);
        s.string_value = "3".into();
        let e = kx.robot_value(&s).unwrap_err();
        assert!(e.contains("k_x takes a double, not a string"), "{e}");

        let ticks = find("stall_ticks").unwrap();
        let v = ticks.ros_value(250.0);
        assert_eq!((v.ptype, v.int_value), (ParameterType::INTEGER, 250));
        let mut d = value(ParameterType::DOUBLE);
        d.double_value = 250.0;
        assert!(ticks.robot_value(&d).is_err());

        let e = find("control_period_s")
            .unwrap()
            .robot_value(&d)
            .unwrap_err();
        assert!(e.contains("read only"), "{e}");
        let e = find("telemetry_rate_hz")
            .unwrap()
            .robot_value(&i)
            .unwrap_err();
        assert!(e.contains("--rate-hz"), "{e}");
        // NaN is passed on: the robot's range check refuses it (its reason).
        let mut nan = value(ParameterType::DOUBLE);
        nan.double_value = f64::NAN;
        assert!(kx.robot_value(&nan).unwrap().is_nan());
        // A non-finite integer parameter comes back as a double, not as 0.
        assert_eq!(ticks.ros_value(f32::NAN).ptype, ParameterType::DOUBLE);
    }

    #[test]
    fn list_by_prefix() {
        assert_eq!(list(&[]).len(), PARAMS.len());
        assert_eq!(list(&["k_x".into()]), ["k_x"]);
        // "k" is not a prefix in rcl's sense (no "k." name).
        assert!(list(&["k".into()]).is_empty());
        assert_eq!(
            list(&["max_speed_mps".into(), "k_s".into()]),
            ["k_s", "max_speed_mps"]
        );
    }

    #[test]
    fn descriptors_say_read_only_and_type() {
        let d = find("control_period_s").unwrap().descriptor();
        assert!(d.read_only);
        assert_eq!(d.r#type, ParameterType::DOUBLE);
        let d = find("stall_ticks").unwrap().descriptor();
        assert!(!d.read_only);
        assert_eq!(d.r#type, ParameterType::INTEGER);
    }
}
