//! Parameters: the device's configuration ([`DeviceConfig`], [`LinkConfig`]),
//! its validation, and the [`ParamId`]s the host reads and writes.

use crate::limits::RobotLimits;
use crate::reference::PlacedReference;
use controller_core::runtime::param_table::{self as table, Access, RangeError, RobotBounds};
use controller_core::runtime::{
    ControlLoop, ReconfigureError, RunState, RuntimeConfig, RuntimeConfigError,
};
use wmr_protocol::{BuiltinReference, ErrorCode, ParamId, TelemetrySelection, TELEMETRY_ALL};

/// Longest velocity-command timeout \[ms\].
pub const MAX_VELOCITY_TIMEOUT_MS: u16 = 5000;

/// Link settings of the device; every field is a [`ParamId`] the host can
/// read, and write where the protocol allows.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkConfig {
    /// Controlled stop after this long without a valid frame while running
    /// under host control \[ms\] ([`table::LIMITS_LINK_TIMEOUT_MS`]).
    pub link_timeout_ms: u32,
    /// Acceleration limit of velocity commands \[m/s²\]
    /// ([`table::LIMITS_MAX_ACCEL_MPS2`]).
    pub accel_mps2: f32,
    /// Angular acceleration of velocity commands and of the braking
    /// profile \[rad/s²\] ([`table::ANG_ACCEL_RADPS2`]).
    pub ang_accel_radps2: f32,
    /// Deceleration of a controlled stop \[m/s²\] ([`table::BRAKE_DECEL_MPS2`]).
    pub brake_decel_mps2: f32,
    /// Largest |v| of a velocity command \[m/s\] (up to the robot's top speed).
    pub max_speed_mps: f32,
    /// Largest |ω| of a velocity command \[rad/s\] (up to the robot's top yaw rate).
    pub max_yaw_rate_radps: f32,
    /// Telemetry rate \[Hz\] (0 = off).
    pub telemetry_rate_hz: u16,
    /// Telemetry groups.
    pub telemetry_selection: TelemetrySelection,
}

impl LinkConfig {
    /// Defaults: 500 ms link timeout, 1 m/s² and 3 rad/s² for velocity
    /// commands, 1 m/s² braking, 1 m/s and 3 rad/s command limits,
    /// telemetry off.
    pub const DEFAULT: Self = Self {
        link_timeout_ms: 500,
        accel_mps2: 1.0,
        ang_accel_radps2: 3.0,
        brake_decel_mps2: 1.0,
        max_speed_mps: 1.0,
        max_yaw_rate_radps: 3.0,
        telemetry_rate_hz: 0,
        telemetry_selection: TELEMETRY_ALL,
    };

    /// Checks every field against its range in the parameter table
    /// (controller-core `param_table`; the robot-dependent ends at their
    /// largest, [`RobotBounds::ABSOLUTE`]: the [`Device`](crate::Device)
    /// checks them against its robot); the error names the first field
    /// out of range, its value and the limit.
    pub fn validate(self) -> Result<Self, DeviceConfigError> {
        let b = RobotBounds::ABSOLUTE;
        let checks = [
            (&table::LIMITS_MAX_ACCEL_MPS2, self.accel_mps2),
            (&table::ANG_ACCEL_RADPS2, self.ang_accel_radps2),
            (&table::BRAKE_DECEL_MPS2, self.brake_decel_mps2),
            (&table::LIMITS_MAX_SPEED_MPS, self.max_speed_mps),
            (&table::LIMITS_MAX_YAW_RATE_RADPS, self.max_yaw_rate_radps),
            (&table::LIMITS_LINK_TIMEOUT_MS, self.link_timeout_ms as f32),
            (&table::TELEMETRY_RATE_HZ, self.telemetry_rate_hz as f32),
        ];
        for (p, x) in checks {
            p.check(x, &b).map_err(DeviceConfigError::OutOfRange)?;
        }
        Ok(self)
    }
}

/// Range of the link timeout \[ms\] (the parameter table's
/// `limits.link_timeout_ms`).
pub const LINK_TIMEOUT_MS: core::ops::RangeInclusive<u32> = 50..=10_000;
/// Largest telemetry rate \[Hz\] (the parameter table's `telemetry_rate_hz`).
pub const MAX_TELEMETRY_RATE_HZ: u16 = 1000;

/// Everything a [`Device`](crate::Device) is built from besides the runtime.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceConfig {
    /// Chip or board name sent in the handshake (≤ 16 bytes).
    pub chip: &'static str,
    /// `CAP_*` bits sent in the handshake.
    pub capabilities: u16,
    /// Link settings.
    pub link: LinkConfig,
    /// What the arm button drives when the host has loaded nothing
    /// (`None`: the button arms only a loaded mode).
    pub button_reference: Option<BuiltinReference>,
}

impl LinkConfig {
    /// The link settings of `robot`: its link timeout and its speed,
    /// yaw-rate and acceleration limits (`[limits]`), the rest
    /// [`LinkConfig::DEFAULT`]'s (braking, angular acceleration, telemetry).
    pub fn of_robot(robot: &robot_file::Robot) -> Self {
        let l = &robot.limits;
        Self {
            link_timeout_ms: l.link_timeout_ms,
            accel_mps2: l.max_accel_mps2,
            max_speed_mps: l.max_speed_mps,
            max_yaw_rate_radps: l.max_yaw_rate_radps,
            ..Self::DEFAULT
        }
    }
}

impl DeviceConfig {
    /// The device configuration of `robot` ([`LinkConfig::of_robot`]) for
    /// the board named `chip` with handshake `capabilities` and the arm
    /// button's `button_reference`.
    pub fn of_robot(
        robot: &robot_file::Robot,
        chip: &'static str,
        capabilities: u16,
        button_reference: Option<BuiltinReference>,
    ) -> Self {
        Self {
            chip,
            capabilities,
            link: LinkConfig::of_robot(robot),
            button_reference,
        }
    }

    /// Checks the link settings, the chip name and the button reference
    /// (against the robot's limits `lim`).
    pub fn validate(self, lim: &RobotLimits) -> Result<Self, DeviceConfigError> {
        self.link.validate()?;
        if self.chip.len() > 16 {
            return Err(DeviceConfigError::ChipName);
        }
        if let Some(b) = &self.button_reference {
            PlacedReference::within(b, lim).ok_or(DeviceConfigError::ButtonReference)?;
        }
        Ok(self)
    }
}

/// A device configuration rejected at construction.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum DeviceConfigError {
    /// The runtime configuration.
    Runtime(RuntimeConfigError),
    /// A parameter (a link setting, a gain, a torque) is outside its
    /// physical range (the parameter table, [`RobotLimits::check`]): the
    /// field, the value, the limit.
    OutOfRange(RangeError),
    /// The chip name is longer than 16 bytes.
    ChipName,
    /// The button reference is invalid.
    ButtonReference,
}

impl core::fmt::Display for DeviceConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Runtime(e) => write!(f, "runtime: {e}"),
            Self::OutOfRange(e) => write!(f, "{e}"),
            Self::ChipName => f.write_str("chip name longer than 16 bytes"),
            Self::ButtonReference => f.write_str("invalid button reference"),
        }
    }
}

/// The value of parameter `id`.
pub(crate) fn read(rt: &RuntimeConfig, link: &LinkConfig, id: ParamId) -> f32 {
    let c = &rt.controller;
    let s = &rt.safety;
    let l = link;
    match id {
        ParamId::TorqueLimitNm => c.torque_limit_nm,
        ParamId::Kx => c.kinematic.k_x,
        ParamId::Ky => c.kinematic.k_y,
        ParamId::Ktheta => c.kinematic.k_th,
        ParamId::Ks => c.sliding.k_s,
        ParamId::StallTorqueNm => s.stall_torque_nm,
        ParamId::StallTicks => s.stall_ticks as f32,
        ParamId::TelemetryRateHz => l.telemetry_rate_hz as f32,
        ParamId::LinkTimeoutMs => l.link_timeout_ms as f32,
        ParamId::AccelMps2 => l.accel_mps2,
        ParamId::AngAccelRadps2 => l.ang_accel_radps2,
        ParamId::BrakeDecelMps2 => l.brake_decel_mps2,
        ParamId::MaxSpeedMps => l.max_speed_mps,
        ParamId::MaxYawRateRadps => l.max_yaw_rate_radps,
        ParamId::ControlPeriodS => c.period_s,
    }
}

/// Checks every parameter with a physical range against the robot's
/// limits (at construction; [`write`] checks the one it writes).
pub(crate) fn check_physical(
    rt: &RuntimeConfig,
    link: &LinkConfig,
    lim: &RobotLimits,
) -> Result<(), DeviceConfigError> {
    for id in ParamId::ALL {
        if lim.range(id).is_some() {
            lim.check(id.param(), read(rt, link, id))
                .map_err(DeviceConfigError::OutOfRange)?;
        }
    }
    Ok(())
}

/// Refused while running.
pub(crate) fn in_hold(state: RunState) -> Result<(), ErrorCode> {
    match state {
        RunState::Running => Err(ErrorCode::Busy),
        _ => Ok(()),
    }
}

/// Why the device refused a `SetParam` ([`check_set`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SetParamError {
    /// The parameter cannot be written (`control_period_s`).
    ReadOnly,
    /// The value is outside the parameter's range for this robot (the
    /// parameter table): the field, the value, the limit.
    Range(RangeError),
}

impl SetParamError {
    /// Its code on the link.
    pub fn code(self) -> ErrorCode {
        match self {
            Self::ReadOnly => ErrorCode::ReadOnly,
            Self::Range(_) => ErrorCode::InvalidValue,
        }
    }
}

impl core::fmt::Display for SetParamError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::ReadOnly => f.write_str(ErrorCode::ReadOnly.reason()),
            Self::Range(e) => write!(f, "{e}"),
        }
    }
}

/// The device's check of a `SetParam` before anything changes: finite,
/// writable, and within the parameter's range for the robot `lim` (the
/// parameter table's [`Param::check`](table::Param::check), the check the
/// robot file and the ROS bridge make).
pub fn check_set(lim: &RobotLimits, id: ParamId, value: f32) -> Result<(), SetParamError> {
    let p = id.param();
    let range = |e| SetParamError::Range(e);
    if !value.is_finite() {
        return Err(range(lim.check(p, value).unwrap_err()));
    }
    if p.access == Access::ReadOnly {
        return Err(SetParamError::ReadOnly);
    }
    lim.check(p, value).map_err(range)
}

/// Writes parameter `id` (telemetry and the link timeout in any state,
/// the rest in hold only); nothing changes when it is refused.
// Out of line: one copy (smaller firmware; the call costs nothing here).
#[inline(never)]
pub(crate) fn write<const H: usize>(
    control: &mut ControlLoop<H>,
    link: &mut LinkConfig,
    lim: &RobotLimits,
    id: ParamId,
    value: f32,
) -> Result<(), ErrorCode> {
    check_set(lim, id, value).map_err(SetParamError::code)?;
    // In range and whole (integers): the casts are exact.
    match id {
        ParamId::TelemetryRateHz => {
            link.telemetry_rate_hz = value as u16;
            return Ok(());
        }
        ParamId::LinkTimeoutMs => {
            link.link_timeout_ms = value as u32;
            return Ok(());
        }
        ParamId::ControlPeriodS => return Err(ErrorCode::ReadOnly),
        _ => {}
    }
    let mut c = control.config().controller;
    let mut s = control.config().safety;
    let mut l = *link;
    match id {
        ParamId::TorqueLimitNm => c.torque_limit_nm = value,
        ParamId::Kx => c.kinematic.k_x = value,
        ParamId::Ky => c.kinematic.k_y = value,
        ParamId::Ktheta => c.kinematic.k_th = value,
        ParamId::Ks => c.sliding.k_s = value,
        ParamId::StallTorqueNm => s.stall_torque_nm = value,
        ParamId::StallTicks => s.stall_ticks = value as u16,
        ParamId::AccelMps2 => l.accel_mps2 = value,
        ParamId::AngAccelRadps2 => l.ang_accel_radps2 = value,
        ParamId::BrakeDecelMps2 => l.brake_decel_mps2 = value,
        ParamId::MaxSpeedMps => l.max_speed_mps = value,
        ParamId::MaxYawRateRadps => l.max_yaw_rate_radps = value,
        ParamId::TelemetryRateHz | ParamId::LinkTimeoutMs | ParamId::ControlPeriodS => {}
    }
    // A value bad by construction is InvalidValue in any state (issue 31
    // item 6: stall_ticks beyond 16 bits while moving was Busy); a good
    // one waits for hold.
    in_hold(control.state())?;
    control.reconfigure(c, s).map_err(|e| match e {
        ReconfigureError::Running => ErrorCode::Busy,
        _ => ErrorCode::InvalidValue,
    })?;
    *link = l;
    Ok(())
}

#[cfg(test)]
mod robot_tests {
    extern crate std;
    use super::*;
    use robot_file::Robot;

    /// The paper robot's `[limits]` are the link defaults: robot-file
    /// writes them as literals, this checks they agree.
    #[test]
    fn paper_robot_has_the_default_link() {
        assert_eq!(LinkConfig::of_robot(&Robot::paper()), LinkConfig::DEFAULT);
    }

    /// The link's own settings default to the parameter table's defaults
    /// (the table keeps its defaults on the host: the firmware links
    /// these numbers, and this checks they agree).
    #[test]
    fn link_defaults_are_the_tables() {
        let d = LinkConfig::DEFAULT;
        assert_eq!(d.ang_accel_radps2, table::ANG_ACCEL_RADPS2.default_value());
        assert_eq!(d.brake_decel_mps2, table::BRAKE_DECEL_MPS2.default_value());
        assert_eq!(
            d.telemetry_rate_hz as f32,
            table::TELEMETRY_RATE_HZ.default_value()
        );
    }

    /// Each example robot's device configuration passes the device's own
    /// checks against the limits of its runtime configuration.
    #[test]
    fn example_robots_give_valid_device_configs() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots");
        for f in ["paper.toml", "tb6612-2kg.toml", "bts7960-10kg.toml"] {
            let text = std::fs::read_to_string(dir.join(f)).unwrap();
            let robot = Robot::from_toml_str(&text).unwrap();
            let kind = controller_core::ControllerKind::Proposed;
            let board = robot_file::BoardFacts::of_timer(&robot, 96_000_000).unwrap();
            let rt = robot
                .derive(
                    &board,
                    controller_core::runtime::RuntimeConfig::example(kind).reference,
                )
                .runtime;
            let lim = RobotLimits::of(&rt);
            let dc = DeviceConfig::of_robot(&robot, "test", 0, None);
            dc.validate(&lim).unwrap_or_else(|e| panic!("{f}: {e:?}"));
            assert_eq!(dc.link.link_timeout_ms, robot.limits.link_timeout_ms);
        }
    }
}
