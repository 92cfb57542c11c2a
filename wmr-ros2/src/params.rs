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
//! The names, units, ranges, read-only flags and descriptions come from
//! controller-core's parameter table (`runtime::param_table`, D144), the
//! names `wmr params` takes (`gains.kinematic.k_x`, `limits.max_speed_mps`,
//! ...). A value outside its range is refused here before the robot is
//! asked, with the refusal the robot file and the device give
//! ([`Param::check`]); a robot-dependent bound (the stall torque, the top
//! speed) is the robot's to check when the bridge does not know the robot.

use controller_core::runtime::param_table::{Access, Param, RangeError, RobotBounds};
use ros2_client::parameters::raw::{
    FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType, ParameterValue,
};
use wmr_protocol::ParamId;

/// One robot parameter offered as a ROS parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RosParam {
    /// The robot's parameter.
    pub id: ParamId,
}

/// Why a parameter is read only here although the link can write it.
pub const BRIDGE_OWNED: &str =
    "set by the bridge itself (telemetry rate: --rate-hz; link timeout: the link's keep-alive follows it)";

/// Every robot parameter, in wmr-protocol's wire order. Writable: the gains
/// and limits the robot takes while it holds. Read only: the control
/// period (a constant of the firmware) and the two the bridge sets itself
/// ([`BRIDGE_OWNED`]).
pub const PARAMS: [RosParam; 15] = {
    let mut out = [RosParam {
        id: ParamId::ALL[0],
    }; 15];
    let mut i = 0;
    while i < 15 {
        out[i] = RosParam {
            id: ParamId::ALL[i],
        };
        i += 1;
    }
    out
};

/// The parameter of a ROS name.
pub fn find(name: &str) -> Option<&'static RosParam> {
    PARAMS.iter().find(|p| p.id.name() == name)
}

/// Why `set_parameters` refused a value before asking the robot.
#[derive(Clone, Debug, PartialEq)]
pub enum SetRefusal {
    /// Read only (always, or here: [`BRIDGE_OWNED`]).
    ReadOnly {
        /// The parameter's name.
        name: &'static str,
        /// Set by the bridge itself.
        bridge_owned: bool,
    },
    /// A ROS value of the wrong type.
    WrongType {
        /// The parameter's name.
        name: &'static str,
        /// The type it takes.
        takes: u8,
        /// The type sent.
        sent: u8,
    },
    /// Outside its range (the parameter table's, as the robot file and
    /// the device check it).
    Range(RangeError),
}

impl std::fmt::Display for SetRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::ReadOnly {
                name,
                bridge_owned: false,
            } => write!(f, "{name} is read only"),
            Self::ReadOnly { name, .. } => write!(f, "{name} is read only here: {BRIDGE_OWNED}"),
            Self::WrongType { name, takes, sent } => write!(
                f,
                "{name} takes {}, not {}",
                type_name(*takes),
                type_name(*sent)
            ),
            Self::Range(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for SetRefusal {}

impl RosParam {
    /// Its declaration in the parameter table.
    pub fn param(&self) -> &'static Param {
        self.id.param()
    }

    /// Its ROS name (the table's).
    pub fn name(&self) -> &'static str {
        self.id.name()
    }

    /// Set by the bridge itself ([`BRIDGE_OWNED`]).
    pub fn bridge_owned(&self) -> bool {
        matches!(self.id, ParamId::TelemetryRateHz | ParamId::LinkTimeoutMs)
    }

    /// Settable through ROS (else read only: `set_parameters` refuses
    /// it): what the table lets the link write, but the bridge's own.
    pub fn writable(&self) -> bool {
        matches!(self.param().access, Access::Hold | Access::Live) && !self.bridge_owned()
    }

    /// A ROS integer (else a double).
    pub fn integer(&self) -> bool {
        self.param().integer
    }

    /// What it is, its unit, when the robot takes it (the table's
    /// description and access).
    pub fn description(&self) -> String {
        let p = self.param();
        let unit = if p.unit.is_empty() {
            String::new()
        } else {
            format!(" [{}]", p.unit)
        };
        let when = if self.bridge_owned() {
            "read only here: --rate-hz, the link's keep-alive".to_string()
        } else {
            p.access.describe().to_string()
        };
        format!("{}{unit}; {when}", p.description)
    }

    /// Its ROS type (`rcl_interfaces/msg/ParameterType`).
    pub fn ros_type(&self) -> u8 {
        if self.integer() {
            ParameterType::INTEGER
        } else {
            ParameterType::DOUBLE
        }
    }

    /// The robot's value (f32 on the link) as a ROS value.
    pub fn ros_value(&self, v: f32) -> ParameterValue {
        let mut out = value(ParameterType::NOT_SET);
        if self.integer() && v.is_finite() {
            out.ptype = ParameterType::INTEGER;
            out.int_value = v.round() as i64;
        } else {
            out.ptype = ParameterType::DOUBLE;
            out.double_value = v as f64;
        }
        out
    }

    /// The value to send to the robot, or why not: read only, a ROS value
    /// of the wrong type (a double takes an integer too, as `ros2 param
    /// set NODE gains.kinematic.k_x 2` sends one; an integer takes no
    /// double), or outside its range for the robot `bounds`
    /// ([`RobotBounds::ABSOLUTE`] when the bridge does not know the robot:
    /// the robot then checks its own tighter bound).
    pub fn robot_value(&self, v: &ParameterValue, bounds: &RobotBounds) -> Result<f32, SetRefusal> {
        if !self.writable() {
            return Err(SetRefusal::ReadOnly {
                name: self.name(),
                bridge_owned: self.bridge_owned(),
            });
        }
        let x = match (v.ptype, self.integer()) {
            (ParameterType::DOUBLE, false) => v.double_value as f32,
            (ParameterType::INTEGER, _) => v.int_value as f32,
            (t, _) => {
                return Err(SetRefusal::WrongType {
                    name: self.name(),
                    takes: self.ros_type(),
                    sent: t,
                })
            }
        };
        self.param().check(x, bounds).map_err(SetRefusal::Range)?;
        Ok(x)
    }

    /// Its `rcl_interfaces/msg/ParameterDescriptor`: the table's range
    /// (its robot-dependent ends from `robot` when the bridge knows the
    /// robot; else the range is left out and named in
    /// `additional_constraints`).
    pub fn descriptor(&self, robot: Option<&RobotBounds>) -> ParameterDescriptor {
        let p = self.param();
        let range = match robot {
            Some(b) => Some(p.range(b)),
            None => p.fixed_range(),
        };
        let (mut floating_point_range, mut integer_range) = (Vec::new(), Vec::new());
        match (range, self.integer()) {
            (Some((lo, hi)), true) => integer_range.push(IntegerRange {
                from_value: lo as i64,
                to_value: hi as i64,
                step: 1,
            }),
            (Some((lo, hi)), false) => floating_point_range.push(FloatingPointRange {
                from_value: lo as f64,
                to_value: hi as f64,
                step: 0.0,
            }),
            (None, _) => {}
        }
        let mut constraints = String::new();
        if self.writable() {
            constraints = "only while the robot holds; a refusal carries its reason".into();
            if range.is_none() {
                let mut r = String::new();
                let _ = p.write_range(&mut r);
                constraints = format!(
                    "range {r} {} (the robot checks its own bound: {}); {constraints}",
                    p.unit,
                    p.max.describe()
                );
            }
        }
        ParameterDescriptor {
            name: self.name().into(),
            r#type: self.ros_type(),
            description: self.description(),
            additional_constraints: constraints,
            read_only: !self.writable(),
            dynamic_typing: false,
            floating_point_range,
            integer_range,
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

/// `list_parameters`' answer: the names, and the namespaces they are in.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Listed {
    /// The parameters' names.
    pub names: Vec<String>,
    /// Each name's part before its last `.`, once.
    pub prefixes: Vec<String>,
}

/// `list_parameters`, rclcpp's rule: with no `prefixes`, every name with
/// fewer than `depth` dots (all at depth 0); else the names equal to a
/// prefix or under it (`prefix.`...) with fewer than `depth` dots after
/// it.
pub fn list(prefixes: &[String], depth: u64) -> Listed {
    let dots = |s: &str| s.matches('.').count() as u64;
    let mut out = Listed::default();
    for n in PARAMS.iter().map(|p| p.name()) {
        let all = prefixes.is_empty() && (depth == 0 || dots(n) < depth);
        let under = prefixes.iter().any(|pre| {
            n == pre
                || n.strip_prefix(pre.as_str())
                    .is_some_and(|r| r.starts_with('.') && (depth == 0 || dots(r) < depth))
        });
        if all || under {
            out.names.push(n.into());
            if let Some((ns, _)) = n.rsplit_once('.') {
                if !out.prefixes.iter().any(|p| p == ns) {
                    out.prefixes.push(ns.into());
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn double(x: f64) -> ParameterValue {
        let mut v = value(ParameterType::DOUBLE);
        v.double_value = x;
        v
    }

    #[test]
    fn every_robot_parameter_once_in_wire_order() {
        let ids: Vec<ParamId> = PARAMS.iter().map(|p| p.id).collect();
        assert_eq!(ids, ParamId::ALL.to_vec());
        for p in &PARAMS {
            assert_eq!(find(p.name()), Some(p));
        }
        assert_eq!(find("k_x"), None);
        assert_eq!(find("gains.kinematic.k_x").unwrap().id, ParamId::Kx);
    }

    #[test]
    fn only_the_hold_only_gains_and_limits_are_writable() {
        // The table's "hold only" ones are writable; the "live" ones are
        // the bridge's own; the control period is read only.
        let read_only: Vec<&str> = PARAMS
            .iter()
            .filter(|p| !p.writable())
            .map(|p| p.name())
            .collect();
        assert_eq!(
            read_only,
            [
                "telemetry_rate_hz",
                "limits.link_timeout_ms",
                "control_period_s"
            ]
        );
        assert!(PARAMS
            .iter()
            .filter(|p| p.writable())
            .all(|p| p.description().ends_with("hold only")));
    }

    #[test]
    fn values_convert_and_wrong_types_are_refused() {
        let b = RobotBounds::ABSOLUTE;
        let kx = find("gains.kinematic.k_x").unwrap();
        let v = kx.ros_value(2.5);
        assert_eq!((v.ptype, v.double_value), (ParameterType::DOUBLE, 2.5));
        assert_eq!(kx.robot_value(&v, &b), Ok(2.5));
        let mut i = value(ParameterType::INTEGER);
        i.int_value = 3;
        assert_eq!(kx.robot_value(&i, &b), Ok(3.0));
        let mut s = value(ParameterType::STRING);
        s.string_value = "3".into();
        let e = kx.robot_value(&s, &b).unwrap_err().to_string();
        assert!(
            e.contains("gains.kinematic.k_x takes a double, not a string"),
            "{e}"
        );

        let ticks = find("stall_ticks").unwrap();
        let v = ticks.ros_value(250.0);
        assert_eq!((v.ptype, v.int_value), (ParameterType::INTEGER, 250));
        assert!(ticks.robot_value(&double(250.0), &b).is_err());

        let e = find("control_period_s")
            .unwrap()
            .robot_value(&double(250.0), &b)
            .unwrap_err()
            .to_string();
        assert!(e.contains("read only"), "{e}");
        let e = find("telemetry_rate_hz")
            .unwrap()
            .robot_value(&i, &b)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--rate-hz"), "{e}");
        // NaN is refused with the table's reason, as the robot would.
        let e = kx.robot_value(&double(f64::NAN), &b).unwrap_err();
        assert!(
            matches!(e, SetRefusal::Range(r) if r.field == "gains.kinematic.k_x"),
            "{e:?}"
        );
        // A non-finite integer parameter comes back as a double, not as 0.
        assert_eq!(ticks.ros_value(f32::NAN).ptype, ParameterType::DOUBLE);
    }

    #[test]
    fn list_by_prefix_and_depth() {
        let all = list(&[], 0);
        assert_eq!(all.names.len(), PARAMS.len());
        assert!(all.prefixes.contains(&"limits".to_string()));
        assert!(all.prefixes.contains(&"gains.kinematic".to_string()));
        // Depth 1: the names without a dot.
        assert_eq!(
            list(&[], 1).names,
            [
                "stall_torque_nm",
                "stall_ticks",
                "telemetry_rate_hz",
                "ang_accel_radps2",
                "brake_decel_mps2",
                "control_period_s"
            ]
        );
        assert_eq!(
            list(&["gains.kinematic.k_x".into()], 0).names,
            ["gains.kinematic.k_x"]
        );
        // "gains.kin" is not a prefix in rcl's sense (no "gains.kin." name).
        assert!(list(&["gains.kin".into()], 0).names.is_empty());
        assert_eq!(
            list(&["gains".into()], 0).names,
            [
                "gains.kinematic.k_x",
                "gains.kinematic.k_y",
                "gains.kinematic.k_th",
                "gains.sliding.k_s"
            ]
        );
        // rclcpp counts the dots after the prefix, its own separator
        // included: "limits.torque_nm" is at depth 2 under "limits",
        // "gains.kinematic.k_x" at depth 3 under "gains".
        assert!(list(&["limits".into()], 1).names.is_empty());
        assert_eq!(list(&["limits".into()], 2).names.len(), 5);
        assert!(list(&["gains".into()], 2).names.is_empty());
        assert_eq!(list(&["gains".into()], 3).names.len(), 4);
    }

    #[test]
    fn descriptors_give_the_tables_range_type_and_read_only() {
        let d = find("control_period_s").unwrap().descriptor(None);
        assert!(d.read_only);
        assert_eq!(d.r#type, ParameterType::DOUBLE);
        let d = find("stall_ticks").unwrap().descriptor(None);
        assert!(!d.read_only);
        assert_eq!(d.r#type, ParameterType::INTEGER);
        assert_eq!(
            (d.integer_range[0].from_value, d.integer_range[0].to_value),
            (1, 65535)
        );
        let d = find("limits.max_accel_mps2").unwrap().descriptor(None);
        let r = &d.floating_point_range[0];
        assert_eq!((r.from_value as f32, r.to_value as f32), (0.01, 20.0));
        assert!(d
            .description
            .starts_with("acceleration limit of velocity commands"));
        assert!(d.description.contains("[m/s²]"), "{}", d.description);
        // A robot-dependent bound: named when the robot is not known,
        // given when it is.
        let t = find("limits.torque_nm").unwrap();
        let d = t.descriptor(None);
        assert!(d.floating_point_range.is_empty());
        assert!(
            d.additional_constraints.contains("stall torque"),
            "{}",
            d.additional_constraints
        );
        let b = RobotBounds::of(0.53, 4.0, 0.1, 1e-3);
        let d = t.descriptor(Some(&b));
        assert_eq!(d.floating_point_range[0].to_value as f32, 0.53);
    }
}
