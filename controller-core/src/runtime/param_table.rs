//! The parameter table (issue 32, D144): every parameter the robot takes
//! from its robot file or live over the link, declared once, as PX4
//! declares its parameters once and generates the rest.
//!
//! Each [`Param`] gives the name (the robot file's path, `limits.torque_nm`;
//! a gain's path under its controller's section, `gains.kinematic.k_x`
//! for the file's `gains.<kind>.kinematic.k_x`), the unit, the default,
//! the physical range (a number, or a robot-dependent [`Bound`] of
//! [`super::bounds`]), who may change it when ([`Access`]), its wire id
//! on the link and its description. From it come the robot file's range
//! validation (robot-file), the device's parameter ranges and link-setting
//! checks (wmr-device), the protocol's parameter names (wmr-protocol
//! `ParamId::param`), `wmr params` (old names accepted with a "renamed to"
//! note), the ROS parameter descriptors (wmr-ros2) and the reference table
//! of book/src/reference/parameters.md (a test fails when they disagree).
//!
//! Every check of a range goes through [`Param::check`], so a value is
//! refused with the same [`RangeError`] — name, value, limit, what to do —
//! by the file, the device and the ROS parameter service.
//!
//! The descriptions are host-only (feature `describe`, which robot-file's
//! `std` turns on): the firmware links the ranges, not the prose.

use super::bounds::{
    max_gain_rate_per_s, max_ky, MAX_ACCEL_MPS2, MAX_ANG_ACCEL_RADPS2, MAX_SPEED_MPS,
    MAX_YAW_RATE_RADPS, MIN_ACCEL_MPS2, MIN_ANG_ACCEL_RADPS2, MIN_BRAKE_DECEL_MPS2,
    MIN_COMMAND_LIMIT, MIN_GAIN, MIN_TORQUE_NM,
};
use super::bridge::BridgeParams;
use super::encoder::MAX_SPEED_WINDOW;

/// One end of a parameter's physical range.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Bound {
    /// A number, in the parameter's unit.
    Value(f32),
    /// The robot's wheel stall torque η·N·k·V/R \[N·m\].
    StallTorque,
    /// The robot's top speed, [`super::bounds::top_speed_mps`] \[m/s\].
    TopSpeed,
    /// The robot's top yaw rate, top speed / half track, at most
    /// [`MAX_YAW_RATE_RADPS`] \[rad/s\].
    TopYawRate,
    /// Half the control rate, [`max_gain_rate_per_s`] \[1/s\].
    GainRate,
    /// The largest k_y, [`max_ky`] \[rad/m²\].
    MaxKy,
}

/// The robot-dependent numbers the [`Bound`]s take: computed by the robot
/// file from a robot (robot-file `Robot::bounds`) and by the device from
/// its runtime configuration (wmr-device `RobotLimits::bounds`), with the
/// same formulas.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotBounds {
    /// Wheel stall torque η·N·k·V/R \[N·m\].
    pub stall_torque_nm: f32,
    /// Top speed \[m/s\] (at most [`MAX_SPEED_MPS`]).
    pub top_speed_mps: f32,
    /// Top yaw rate \[rad/s\] (at most [`MAX_YAW_RATE_RADPS`]).
    pub top_yaw_rate_radps: f32,
    /// Control period \[s\].
    pub period_s: f32,
}

impl RobotBounds {
    /// The bounds of no particular robot at the 1 kHz control rate: every
    /// robot's range lies inside these (the host's check before it asks a
    /// robot it does not know).
    pub const ABSOLUTE: Self = Self {
        stall_torque_nm: f32::MAX,
        top_speed_mps: MAX_SPEED_MPS,
        top_yaw_rate_radps: MAX_YAW_RATE_RADPS,
        period_s: CONTROL_PERIOD_S,
    };

    /// The robot with stall torque `stall_torque_nm`, no-load ground speed
    /// `no_load_speed_mps` (r·V/(k·N), r the wheel radius the controller
    /// uses), half track `half_track_m` at control period `period_s`.
    pub fn of(
        stall_torque_nm: f32,
        no_load_speed_mps: f32,
        half_track_m: f32,
        period_s: f32,
    ) -> Self {
        let top_speed_mps = no_load_speed_mps.min(MAX_SPEED_MPS);
        Self {
            stall_torque_nm,
            top_speed_mps,
            top_yaw_rate_radps: (top_speed_mps / half_track_m).min(MAX_YAW_RATE_RADPS),
            period_s,
        }
    }
}

impl Bound {
    /// Its number for the robot `b`.
    pub fn eval(self, b: &RobotBounds) -> f32 {
        match self {
            Bound::Value(x) => x,
            Bound::StallTorque => b.stall_torque_nm,
            Bound::TopSpeed => b.top_speed_mps,
            Bound::TopYawRate => b.top_yaw_rate_radps,
            Bound::GainRate => max_gain_rate_per_s(b.period_s),
            Bound::MaxKy => max_ky(b.period_s, b.top_speed_mps),
        }
    }

    /// A number of no robot's ([`Bound::Value`]).
    pub const fn fixed(self) -> Option<f32> {
        match self {
            Bound::Value(x) => Some(x),
            _ => None,
        }
    }

    /// What a robot-dependent bound is, for messages and the docs (empty
    /// for a number).
    pub fn describe(self) -> &'static str {
        match self {
            Bound::Value(_) => "",
            Bound::StallTorque => "the robot's stall torque η·N·k·V/R",
            Bound::TopSpeed => "the robot's top speed min(r·V/(k·N), 10 m/s)",
            Bound::TopYawRate => "the robot's top yaw rate min(top speed/(track/2), 30 rad/s)",
            Bound::GainRate => "half the control rate 1/(2·period)",
            Bound::MaxKy => "(half the control rate / top speed)²",
        }
    }
}

impl Bound {
    /// Its symbol in the docs' tables: the number, or `τ_stall`, `v_top`,
    /// `ω_top`, `R`, `(R/v_top)²` ([`Bound::describe`] says what each is).
    pub fn write(self, out: &mut dyn core::fmt::Write) -> core::fmt::Result {
        match self {
            Bound::Value(x) => write!(out, "{x}"),
            Bound::StallTorque => out.write_str("τ_stall"),
            Bound::TopSpeed => out.write_str("v_top"),
            Bound::TopYawRate => out.write_str("ω_top"),
            Bound::GainRate => out.write_str("R"),
            Bound::MaxKy => out.write_str("(R/v_top)²"),
        }
    }

    /// Every robot-dependent bound, for the docs' legend.
    pub const ROBOT: [Bound; 5] = [
        Bound::StallTorque,
        Bound::TopSpeed,
        Bound::TopYawRate,
        Bound::GainRate,
        Bound::MaxKy,
    ];
}

/// Who may change a parameter, and when.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Access {
    /// Only through the robot file (edit it, `wmr robot push`, reboot).
    File,
    /// From the file, and live over the link while the robot holds.
    Hold,
    /// From the file or the link's default, and live in any state.
    Live,
    /// Read only (a constant of the firmware).
    ReadOnly,
}

impl Access {
    /// `file only`, `hold only`, `live`, `read only`.
    pub fn describe(self) -> &'static str {
        match self {
            Access::File => "file only",
            Access::Hold => "hold only",
            Access::Live => "live",
            Access::ReadOnly => "read only",
        }
    }
}

/// A robot-dependent default: the formula that gives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Formula {
    /// robot-file `STALL_TORQUE_FRACTION` (1/5) × `limits.torque_nm`.
    StallTorqueFraction,
    /// robot-file `STALL_TIME_S` (0.25 s) / control period.
    StallTime,
    /// The paper's Table 2 (`ControllerConfig::paper(kind)`).
    PaperGains,
}

impl Formula {
    /// The formula, for the docs.
    pub fn describe(self) -> &'static str {
        match self {
            Formula::StallTorqueFraction => "derived: limits.torque_nm / 5",
            Formula::StallTime => "derived: 0.25 s / control period",
            Formula::PaperGains => "the paper's Table 2 (section absent)",
        }
    }
}

/// A parameter's default.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DefaultValue {
    /// None: the robot file must give it.
    Required,
    /// This number, in the parameter's unit.
    Value(f32),
    /// Derived from the robot by a formula.
    Derived(Formula),
}

/// Where the robot file holds a parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InFile {
    /// At its name.
    Yes,
    /// Under each controller's section: `gains.<kind>.` + the name after
    /// `gains.`.
    PerController,
    /// Not in the file (derived from it, or the link's own setting).
    No,
}

/// One parameter, declared once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Param {
    /// Its name: the file's path (see [`InFile`]), on the link, in
    /// `wmr params` and as a ROS parameter.
    pub name: &'static str,
    /// Its unit (empty: dimensionless).
    pub unit: &'static str,
    /// Smallest value accepted (no parameter's depends on the robot).
    pub min: f32,
    /// Largest value accepted.
    pub max: Bound,
    /// Who may change it when.
    pub access: Access,
    /// A whole number.
    pub integer: bool,
    /// Its id on the link (wmr-protocol `ParamId`, wire order), when the
    /// robot takes it over the link.
    pub wire: Option<u8>,
    /// Its default (host only).
    #[cfg(feature = "describe")]
    pub default: DefaultValue,
    /// Where the file holds it (host only).
    #[cfg(feature = "describe")]
    pub in_file: InFile,
    /// The name it had before issue 32 (`wmr params` takes it with a
    /// "renamed to" note; host only).
    #[cfg(feature = "describe")]
    pub old_name: Option<&'static str>,
    /// What it is (host only).
    #[cfg(feature = "describe")]
    pub description: &'static str,
}

/// The number of a [`Bound::Value`] (the table's least values).
const fn num(b: Bound) -> f32 {
    match b {
        Bound::Value(x) => x,
        _ => panic!("a least value is a number"),
    }
}

// The firmware links the range and access of each parameter it checks;
// the default, the file's place, the old name and the description are
// the host's (feature `describe`).
macro_rules! param {
    (
        description: $d:literal,
        name: $name:expr,
        unit: $unit:expr,
        min: $min:expr,
        max: $max:expr,
        default: $default:expr,
        access: $access:expr,
        in_file: $in_file:expr,
        integer: $integer:expr,
        wire: $wire:expr,
        old_name: $old:expr $(,)?
    ) => {
        Param {
            name: $name,
            unit: $unit,
            min: num($min),
            max: $max,
            access: $access,
            integer: $integer,
            wire: $wire,
            #[cfg(feature = "describe")]
            default: $default,
            #[cfg(feature = "describe")]
            in_file: $in_file,
            #[cfg(feature = "describe")]
            old_name: $old,
            #[cfg(feature = "describe")]
            description: $d,
        }
    };
}

/// Which end of its range a value fell beyond.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Beyond {
    /// Below the least value.
    Min,
    /// Above the largest value.
    Max,
    /// NaN or infinite.
    NotFinite,
    /// Not a whole number (an integer parameter).
    NotInteger,
}

/// A value refused by its parameter's range: the field, the value, the
/// limit; its `Display` says what to do.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RangeError {
    /// The field refused (the parameter's name; an element's path
    /// `body.wheel_radius_m[1]` for an array).
    pub field: &'static str,
    /// The value refused.
    pub value: f32,
    /// Which limit it broke.
    pub beyond: Beyond,
    /// The least value accepted.
    pub min: f32,
    /// The largest value accepted.
    pub max: f32,
    /// The bound that gave the broken limit.
    pub bound: Bound,
    /// The unit of the numbers.
    pub unit: &'static str,
}

impl RangeError {
    /// The limit broken (`min` or `max`; `max` for a non-finite value).
    pub fn limit(&self) -> f32 {
        match self.beyond {
            Beyond::Min => self.min,
            _ => self.max,
        }
    }

    /// The message without the field: "25 m/s² is above its limit 20 m/s²:
    /// set a value in [0.01, 20] m/s²".
    pub fn reason(&self) -> RangeReason<'_> {
        RangeReason(self)
    }
}

/// [`RangeError::reason`]'s `Display`.
pub struct RangeReason<'a>(&'a RangeError);

fn unit_sep(unit: &str) -> &'static str {
    if unit.is_empty() {
        ""
    } else {
        " "
    }
}

impl core::fmt::Display for RangeReason<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let e = self.0;
        let (u, s) = (e.unit, unit_sep(e.unit));
        let note = e.bound.describe();
        let note_sep = if note.is_empty() { "" } else { ", " };
        match e.beyond {
            Beyond::NotFinite => write!(f, "{} is not a finite number", e.value)?,
            Beyond::NotInteger => write!(f, "{}{s}{u} is not a whole number", e.value)?,
            Beyond::Min => write!(
                f,
                "{}{s}{u} is below its limit {}{s}{u}{note_sep}{note}",
                e.value, e.min
            )?,
            Beyond::Max => write!(
                f,
                "{}{s}{u} is above its limit {}{s}{u}{note_sep}{note}",
                e.value, e.max
            )?,
        }
        write!(f, ": set a value in [{}, {}]{s}{u}", e.min, e.max)
    }
}

impl core::fmt::Display for RangeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}: {}", self.field, self.reason())
    }
}

impl Param {
    /// Its range \[min, max\] for the robot `b`, in its unit.
    pub fn range(&self, b: &RobotBounds) -> (f32, f32) {
        (self.min, self.max.eval(b))
    }

    /// Its range when it depends on no robot.
    pub const fn fixed_range(&self) -> Option<(f32, f32)> {
        match self.max.fixed() {
            Some(hi) => Some((self.min, hi)),
            None => None,
        }
    }

    /// Its default number ([`DefaultValue::Value`]; 0 otherwise).
    #[cfg(feature = "describe")]
    pub const fn default_value(&self) -> f32 {
        match self.default {
            DefaultValue::Value(x) => x,
            _ => 0.0,
        }
    }

    /// Checks `value` against its range for the robot `b` (and, for an
    /// integer parameter, that it is whole).
    pub fn check(&self, value: f32, b: &RobotBounds) -> Result<(), RangeError> {
        self.check_as(self.name, value, b)
    }

    /// [`Self::check`], naming the refused field `field` (an array's
    /// element).
    pub fn check_as(
        &self,
        field: &'static str,
        value: f32,
        b: &RobotBounds,
    ) -> Result<(), RangeError> {
        let (min, max) = self.range(b);
        let (beyond, bound) = if !value.is_finite() {
            (Beyond::NotFinite, self.max)
        } else if value < min {
            (Beyond::Min, Bound::Value(self.min))
        } else if value > max {
            (Beyond::Max, self.max)
        } else if self.integer && value != libm::truncf(value) {
            (Beyond::NotInteger, self.max)
        } else {
            return Ok(());
        };
        Err(RangeError {
            field,
            value,
            beyond,
            min,
            max,
            bound,
            unit: self.unit,
        })
    }

    #[cfg(feature = "describe")]
    /// The file's path for the controller section `section`
    /// (`proposed`, `smc`, `asmc`) when it is [`InFile::PerController`];
    /// its name otherwise. Host only (allocates nothing, writes `out`).
    pub fn write_file_path(
        &self,
        section: &str,
        out: &mut dyn core::fmt::Write,
    ) -> core::fmt::Result {
        match (self.in_file, self.name.strip_prefix("gains.")) {
            (InFile::PerController, Some(rest)) => write!(out, "gains.{section}.{rest}"),
            _ => out.write_str(self.name),
        }
    }
}

impl Param {
    /// Its range as the docs write it: `[0.01, τ_stall]`, `50..=10000`
    /// for a whole number.
    pub fn write_range(&self, out: &mut dyn core::fmt::Write) -> core::fmt::Result {
        if self.integer {
            write!(out, "{}..=", self.min)?;
            self.max.write(out)
        } else {
            write!(out, "[{}, ", self.min)?;
            self.max.write(out)?;
            out.write_str("]")
        }
    }

    /// Its default as the docs write it.
    #[cfg(feature = "describe")]
    pub fn write_default(&self, out: &mut dyn core::fmt::Write) -> core::fmt::Result {
        match self.default {
            DefaultValue::Required => out.write_str("required"),
            DefaultValue::Value(x) => write!(out, "{x}"),
            DefaultValue::Derived(f) => out.write_str(f.describe()),
        }
    }
}

/// The reference table of every parameter, in Markdown (book/src/reference/parameters.md
/// holds it; robot-file's test `params_doc` fails when they differ).
#[cfg(feature = "describe")]
pub fn write_reference(out: &mut dyn core::fmt::Write) -> core::fmt::Result {
    out.write_str(
        "| name | in the robot file | unit | default | range | changed | link id | was |\n\
         |---|---|---|---|---|---|---|---|\n",
    )?;
    for p in ALL.iter() {
        write!(out, "| `{}` | ", p.name)?;
        match p.in_file {
            InFile::Yes => write!(out, "`{}`", p.name)?,
            InFile::PerController => {
                out.write_str("`")?;
                p.write_file_path("<kind>", out)?;
                out.write_str("`")?;
            }
            InFile::No => out.write_str("–")?,
        }
        let unit = if p.unit.is_empty() { "–" } else { p.unit };
        write!(out, " | {unit} | ")?;
        p.write_default(out)?;
        out.write_str(" | ")?;
        p.write_range(out)?;
        write!(out, " | {} | ", p.access.describe())?;
        match p.wire {
            Some(w) => write!(out, "{w}")?,
            None => out.write_str("–")?,
        }
        match p.old_name {
            Some(o) => writeln!(out, " | `{o}` |")?,
            None => out.write_str(" | – |\n")?,
        }
    }
    out.write_str("\n| name | description |\n|---|---|\n")?;
    for p in ALL.iter() {
        writeln!(out, "| `{}` | {} |", p.name, p.description)?;
    }
    out.write_str("\n| bound | what |\n|---|---|\n")?;
    for b in Bound::ROBOT {
        out.write_str("| ")?;
        b.write(out)?;
        writeln!(out, " | {} |", b.describe())?;
    }
    Ok(())
}

/// The control period every board runs at \[s\] (robot-file
/// `CONTROL_PERIOD_S`).
pub const CONTROL_PERIOD_S: f32 =
    crate::ControllerConfig::paper(crate::ControllerKind::Proposed).period_s;
/// Largest gain of the file's gain sections (any unit): beyond it a 1 kHz
/// discrete loop is far past stability; tuning stays well inside.
pub const MAX_GAIN: f32 = 1.0e4;
/// Least positive gain of the file's gain sections.
const P: f32 = 1e-6;

const fn v(x: f32) -> Bound {
    Bound::Value(x)
}

use Access::{File, Hold, Live, ReadOnly};
#[cfg_attr(not(feature = "describe"), allow(unused_imports))]
use DefaultValue::{Required, Value};

// ---- [body] ----

/// `body.mass_kg`.
pub static BODY_MASS_KG: Param = param! {
    description: "total mass m; below 100 g or above 500 kg is not a two-wheeler this firmware drives",
    name: "body.mass_kg", unit: "kg", min: v(0.1), max: v(500.0), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `body.inertia_kgm2`.
pub static BODY_INERTIA_KGM2: Param = param! {
    description: "yaw inertia about G; also m·track²/1000 ≤ I ≤ m·(track² + r²)",
    name: "body.inertia_kgm2", unit: "kg·m²", min: v(1e-5), max: v(500.0), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `body.wheel_inertia_kgm2`.
pub static BODY_WHEEL_INERTIA_KGM2: Param = param! {
    description: "one wheel about its axle with the rotor reflected (J_rotor·N²); also ≤ m·r²",
    name: "body.wheel_inertia_kgm2", unit: "kg·m²", min: v(0.0), max: v(1.0), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `body.com_offset_m`.
pub static BODY_COM_OFFSET_M: Param = param! {
    description: "G ahead of the axle midpoint (the paper's d); also < track/2",
    name: "body.com_offset_m", unit: "m", min: v(0.0), max: v(2.0), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `body.wheel_radius_m` (each of `[right, left]`).
pub static BODY_WHEEL_RADIUS_M: Param = param! {
    description: "wheel radii [right, left]; differing by at most 10 % of their mean",
    name: "body.wheel_radius_m", unit: "m", min: v(0.005), max: v(0.5), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `body.track_m`.
pub static BODY_TRACK_M: Param = param! {
    description: "distance between the tyres' contact lines",
    name: "body.track_m", unit: "m", min: v(0.03), max: v(2.0), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};

// ---- [motors] ----

/// `motors.torque_constant_nm_per_a`.
pub static MOTORS_TORQUE_CONSTANT: Param = param! {
    description: "at the motor shaft (= back-EMF constant in V·s/rad)",
    name: "motors.torque_constant_nm_per_a", unit: "N·m/A", min: v(1e-4), max: v(5.0),
    default: Required, access: File, in_file: InFile::Yes, integer: false, wire: None,
    old_name: None,
};
/// `motors.resistance_ohm`.
pub static MOTORS_RESISTANCE_OHM: Param = param! {
    description: "winding resistance",
    name: "motors.resistance_ohm", unit: "Ω", min: v(0.01), max: v(1000.0), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `motors.gear_ratio`.
pub static MOTORS_GEAR_RATIO: Param = param! {
    description: "motor turns per wheel turn",
    name: "motors.gear_ratio", unit: "", min: v(1.0), max: v(1000.0), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `motors.gear_efficiency`.
pub static MOTORS_GEAR_EFFICIENCY: Param = param! {
    description: "above 1 is a perpetual-motion gearbox",
    name: "motors.gear_efficiency", unit: "", min: v(0.1), max: v(1.0), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `motors.supply_voltage_v`.
pub static MOTORS_SUPPLY_VOLTAGE_V: Param = param! {
    description: "the bridge's supply",
    name: "motors.supply_voltage_v", unit: "V", min: v(1.0), max: v(60.0), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `motors.viscous_friction_nms_per_rad` (each wheel).
pub static MOTORS_VISCOUS_FRICTION: Param = param! {
    description: "at the wheel, [right, left]; also b·ω₀ ≤ τ_stall/2",
    name: "motors.viscous_friction_nms_per_rad", unit: "N·m·s/rad", min: v(0.0), max: v(10.0),
    default: Required, access: File, in_file: InFile::Yes, integer: false, wire: None,
    old_name: None,
};
/// `motors.coulomb_friction_nm` (each wheel).
pub static MOTORS_COULOMB_FRICTION_NM: Param = param! {
    description: "at the wheel, [right, left]; also ≤ τ_stall/2",
    name: "motors.coulomb_friction_nm", unit: "N·m", min: v(0.0), max: v(100.0),
    default: Required, access: File, in_file: InFile::Yes, integer: false, wire: None,
    old_name: None,
};

// ---- [encoders], [bridge] ----

/// `encoders.counts_per_wheel_rev`.
pub static ENCODERS_COUNTS_PER_WHEEL_REV: Param = param! {
    description: "lines × 4 × gear ratio; also ≤ 32,767 counts per tick at limits.max_speed_mps and fine enough for the direction check",
    name: "encoders.counts_per_wheel_rev", unit: "counts", min: v(4.0), max: v(1.0e6),
    default: Required, access: File, in_file: InFile::Yes, integer: false, wire: None,
    old_name: None,
};
/// `encoders.speed_window_ticks`.
pub static ENCODERS_SPEED_WINDOW_TICKS: Param = param! {
    description: "window of the speed estimate: one count per N ticks of resolution, N/2 ticks of delay",
    name: "encoders.speed_window_ticks", unit: "ticks", min: v(1.0),
    max: v(MAX_SPEED_WINDOW as f32), default: Required, access: File, in_file: InFile::Yes,
    integer: true, wire: None, old_name: None,
};
/// `bridge.pwm_frequency_hz`.
pub static BRIDGE_PWM_FREQUENCY_HZ: Param = param! {
    description: "PWM frequency; also 100..=65,535 duty levels at the boards' 96 and 168 MHz timer clocks",
    name: "bridge.pwm_frequency_hz", unit: "Hz",
    min: v(BridgeParams::PWM_FREQUENCY_RANGE_HZ.0 as f32),
    max: v(BridgeParams::PWM_FREQUENCY_RANGE_HZ.1 as f32), default: Required, access: File,
    in_file: InFile::Yes, integer: true, wire: None, old_name: None,
};
/// `bridge.max_duty_fraction`.
pub static BRIDGE_MAX_DUTY_FRACTION: Param = param! {
    description: "largest duty the runtime commands (bootstrap-driven bridges need < 1)",
    name: "bridge.max_duty_fraction", unit: "", min: v(0.05), max: v(1.0), default: Required,
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};

// ---- [limits] ----

/// `limits.torque_nm` (wire `TorqueLimitNm`, was `torque_limit_nm`).
pub static LIMITS_TORQUE_NM: Param = param! {
    description: "per-wheel torque limit: the controller saturates at it",
    name: "limits.torque_nm", unit: "N·m", min: v(MIN_TORQUE_NM), max: Bound::StallTorque,
    default: Required, access: Hold, in_file: InFile::Yes, integer: false, wire: Some(0),
    old_name: Some("torque_limit_nm"),
};
/// `limits.max_speed_mps` (wire `MaxSpeedMps`, was `max_speed_mps`).
pub static LIMITS_MAX_SPEED_MPS: Param = param! {
    description: "largest |v| a velocity command may ask; the file also needs ≤ r_min·V/(k·N)",
    name: "limits.max_speed_mps", unit: "m/s", min: v(MIN_COMMAND_LIMIT), max: Bound::TopSpeed,
    default: Required, access: Hold, in_file: InFile::Yes, integer: false, wire: Some(12),
    old_name: Some("max_speed_mps"),
};
/// `limits.max_yaw_rate_radps` (wire `MaxYawRateRadps`, was `max_yaw_rate_radps`).
pub static LIMITS_MAX_YAW_RATE_RADPS: Param = param! {
    description: "largest |ω| a velocity command may ask; the file also needs ≤ 2·r_min·V/(k·N)/track",
    name: "limits.max_yaw_rate_radps", unit: "rad/s", min: v(MIN_COMMAND_LIMIT),
    max: Bound::TopYawRate, default: Required, access: Hold, in_file: InFile::Yes,
    integer: false, wire: Some(13), old_name: Some("max_yaw_rate_radps"),
};
/// `limits.max_accel_mps2` (wire `AccelMps2`, was `accel_mps2`).
pub static LIMITS_MAX_ACCEL_MPS2: Param = param! {
    description: "acceleration limit of velocity commands; the file also needs ≤ 2·torque_nm/(r·m)",
    name: "limits.max_accel_mps2", unit: "m/s²", min: v(MIN_ACCEL_MPS2), max: v(MAX_ACCEL_MPS2),
    default: Required, access: Hold, in_file: InFile::Yes, integer: false, wire: Some(9),
    old_name: Some("accel_mps2"),
};
/// `limits.link_timeout_ms` (wire `LinkTimeoutMs`, was `link_timeout_ms`).
pub static LIMITS_LINK_TIMEOUT_MS: Param = param! {
    description: "controlled stop after this long without a valid frame while moving under host control",
    name: "limits.link_timeout_ms", unit: "ms", min: v(50.0), max: v(10_000.0),
    default: Required, access: Live, in_file: InFile::Yes, integer: true, wire: Some(8),
    old_name: Some("link_timeout_ms"),
};

// ---- [gains.<kind>] ----

/// `gains.<kind>.kinematic.k_x` (wire `Kx`, was `k_x`).
pub static GAINS_K_X: Param = param! {
    description: "kinematic gain k_x of eq. (14)",
    name: "gains.kinematic.k_x", unit: "1/s", min: v(MIN_GAIN), max: Bound::GainRate,
    default: DefaultValue::Derived(Formula::PaperGains), access: Hold,
    in_file: InFile::PerController, integer: false, wire: Some(1), old_name: Some("k_x"),
};
/// `gains.<kind>.kinematic.k_y` (wire `Ky`, was `k_y`).
pub static GAINS_K_Y: Param = param! {
    description: "kinematic gain k_y of eq. (14)",
    name: "gains.kinematic.k_y", unit: "rad/m²", min: v(MIN_GAIN), max: Bound::MaxKy,
    default: DefaultValue::Derived(Formula::PaperGains), access: Hold,
    in_file: InFile::PerController, integer: false, wire: Some(2), old_name: Some("k_y"),
};
/// `gains.<kind>.kinematic.k_th` (wire `Ktheta`, was `k_theta`).
pub static GAINS_K_TH: Param = param! {
    description: "kinematic gain k_θ of eq. (14)",
    name: "gains.kinematic.k_th", unit: "1/s", min: v(MIN_GAIN), max: Bound::GainRate,
    default: DefaultValue::Derived(Formula::PaperGains), access: Hold,
    in_file: InFile::PerController, integer: false, wire: Some(3), old_name: Some("k_theta"),
};
/// `gains.<kind>.kinematic.large_error_m`.
pub static GAINS_LARGE_ERROR_M: Param = param! {
    description: "D23's bound on the tracking error (0 = off)",
    name: "gains.kinematic.large_error_m", unit: "m", min: v(0.0), max: v(100.0),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.observer.l_v`.
pub static GAINS_OBSERVER_L_V: Param = param! {
    description: "fault-observer gain l_v of eq. (13)",
    name: "gains.observer.l_v", unit: "1/s", min: v(P), max: v(MAX_GAIN),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.observer.l_omega`.
pub static GAINS_OBSERVER_L_OMEGA: Param = param! {
    description: "fault-observer gain l_ω of eq. (13)",
    name: "gains.observer.l_omega", unit: "1/s", min: v(P), max: v(MAX_GAIN),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.observer.max_estimate[0]`.
pub static GAINS_OBSERVER_MAX_ESTIMATE_V: Param = param! {
    description: "clamp of the fault estimate F̂'s speed row; 0: off",
    name: "gains.observer.max_estimate[0]", unit: "m/s", min: v(0.0), max: v(100.0),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.observer.max_estimate[1]`.
pub static GAINS_OBSERVER_MAX_ESTIMATE_OMEGA: Param = param! {
    description: "clamp of the fault estimate F̂'s yaw-rate row; 0: off",
    name: "gains.observer.max_estimate[1]", unit: "rad/s", min: v(0.0), max: v(100.0),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.eso.lambda` (each of three).
pub static GAINS_ESO_LAMBDA: Param = param! {
    description: "fal-ESO gains of eq. (18)",
    name: "gains.eso.lambda", unit: "", min: v(P), max: v(MAX_GAIN),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.eso.zeta`.
pub static GAINS_ESO_ZETA: Param = param! {
    description: "fal's linear zone",
    name: "gains.eso.zeta", unit: "", min: v(P), max: v(100.0),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.eso.alpha`.
pub static GAINS_ESO_ALPHA: Param = param! {
    description: "fal's exponent",
    name: "gains.eso.alpha", unit: "", min: v(P), max: v(1.0 - P),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.eso.max_disturbance[0]`.
pub static GAINS_ESO_MAX_DISTURBANCE_V: Param = param! {
    description: "clamp of the ESO's disturbance estimate x̂3, speed row; 0: off",
    name: "gains.eso.max_disturbance[0]", unit: "m/s²", min: v(0.0), max: v(1000.0),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.eso.max_disturbance[1]`.
pub static GAINS_ESO_MAX_DISTURBANCE_OMEGA: Param = param! {
    description: "clamp of the ESO's disturbance estimate x̂3, yaw-rate row; 0: off",
    name: "gains.eso.max_disturbance[1]", unit: "rad/s²", min: v(0.0), max: v(1000.0),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.sliding.k_s` (wire `Ks`, was `k_s`).
pub static GAINS_K_S: Param = param! {
    description: "sliding-surface gain k_s of eq. (20)",
    name: "gains.sliding.k_s", unit: "1/s", min: v(MIN_GAIN), max: Bound::GainRate,
    default: DefaultValue::Derived(Formula::PaperGains), access: Hold,
    in_file: InFile::PerController, integer: false, wire: Some(4), old_name: Some("k_s"),
};
/// `gains.<kind>.sliding.switching.fixed.k`.
pub static GAINS_SWITCHING_FIXED_K: Param = param! {
    description: "switching gain of plain SMC",
    name: "gains.sliding.switching.fixed.k", unit: "", min: v(0.0), max: v(MAX_GAIN),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.sliding.switching.adaptive.gamma`.
pub static GAINS_ADAPTIVE_GAMMA: Param = param! {
    description: "adaptation gain γ of eq. (22)",
    name: "gains.sliding.switching.adaptive.gamma", unit: "", min: v(0.0), max: v(MAX_GAIN),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.sliding.switching.adaptive.leakage`.
pub static GAINS_ADAPTIVE_LEAKAGE: Param = param! {
    description: "leakage of the adaptation, eq. (22)",
    name: "gains.sliding.switching.adaptive.leakage", unit: "1/s", min: v(0.0), max: v(MAX_GAIN),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.sliding.switching.adaptive.rho0`.
pub static GAINS_ADAPTIVE_RHO0: Param = param! {
    description: "initial switching gain ρ̂(0); rho_min ≤ rho0 ≤ rho_max",
    name: "gains.sliding.switching.adaptive.rho0", unit: "", min: v(0.0), max: v(MAX_GAIN),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.sliding.switching.adaptive.rho_min`.
pub static GAINS_ADAPTIVE_RHO_MIN: Param = param! {
    description: "least switching gain ρ̂",
    name: "gains.sliding.switching.adaptive.rho_min", unit: "", min: v(0.0), max: v(MAX_GAIN),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.sliding.switching.adaptive.rho_max`.
pub static GAINS_ADAPTIVE_RHO_MAX: Param = param! {
    description: "largest switching gain ρ̂",
    name: "gains.sliding.switching.adaptive.rho_max", unit: "", min: v(0.0), max: v(MAX_GAIN),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};
/// `gains.<kind>.sliding.switching.adaptive.dead_zone`.
pub static GAINS_ADAPTIVE_DEAD_ZONE: Param = param! {
    description: "dead zone of the adaptation, eq. (23)",
    name: "gains.sliding.switching.adaptive.dead_zone", unit: "", min: v(0.0), max: v(100.0),
    default: DefaultValue::Derived(Formula::PaperGains), access: File,
    in_file: InFile::PerController, integer: false, wire: None, old_name: None,
};

// ---- not in the file ----

/// `stall_torque_nm` (wire `StallTorqueNm`).
pub static STALL_TORQUE_NM: Param = param! {
    description: "the safety supervisor's stall check arms at this wheel torque",
    name: "stall_torque_nm", unit: "N·m", min: v(MIN_TORQUE_NM), max: Bound::StallTorque,
    default: DefaultValue::Derived(Formula::StallTorqueFraction), access: Hold, in_file: InFile::No,
    integer: false, wire: Some(5), old_name: None,
};
/// `stall_ticks` (wire `StallTicks`).
pub static STALL_TICKS: Param = param! {
    description: "a wheel pushing at the stall torque without a count for this long is stalled",
    name: "stall_ticks", unit: "ticks", min: v(1.0), max: v(u16::MAX as f32),
    default: DefaultValue::Derived(Formula::StallTime), access: Hold, in_file: InFile::No,
    integer: true, wire: Some(6), old_name: None,
};
/// `telemetry_rate_hz` (wire `TelemetryRateHz`).
pub static TELEMETRY_RATE_HZ: Param = param! {
    description: "telemetry frames per second (0 = off)",
    name: "telemetry_rate_hz", unit: "Hz", min: v(0.0), max: v(1000.0), default: Value(0.0),
    access: Live, in_file: InFile::No, integer: true, wire: Some(7), old_name: None,
};
/// `ang_accel_radps2` (wire `AngAccelRadps2`).
pub static ANG_ACCEL_RADPS2: Param = param! {
    description: "angular acceleration of velocity commands and of the braking profile",
    name: "ang_accel_radps2", unit: "rad/s²", min: v(MIN_ANG_ACCEL_RADPS2),
    max: v(MAX_ANG_ACCEL_RADPS2), default: Value(3.0), access: Hold, in_file: InFile::No,
    integer: false, wire: Some(10), old_name: None,
};
/// `brake_decel_mps2` (wire `BrakeDecelMps2`).
pub static BRAKE_DECEL_MPS2: Param = param! {
    description: "deceleration of a controlled stop",
    name: "brake_decel_mps2", unit: "m/s²", min: v(MIN_BRAKE_DECEL_MPS2), max: v(MAX_ACCEL_MPS2),
    default: Value(1.0), access: Hold, in_file: InFile::No, integer: false, wire: Some(11),
    old_name: None,
};
/// `control_period_s` (wire `ControlPeriodS`).
pub static CONTROL_PERIOD: Param = param! {
    description: "control period (a constant of the firmware)",
    name: "control_period_s", unit: "s", min: v(CONTROL_PERIOD_S), max: v(CONTROL_PERIOD_S),
    default: Value(CONTROL_PERIOD_S), access: ReadOnly, in_file: InFile::No, integer: false,
    wire: Some(14), old_name: None,
};

/// Farthest start position from the origin \[m\] (`control.initial_x_m`,
/// `control.initial_y_m`): odometry's frame is the robot's own, a
/// kilometre is beyond any run of a small robot and keeps f32 positions at
/// 0.1 mm.
pub const MAX_INITIAL_POSITION_M: f32 = 1000.0;

/// `control.initial_x_m`.
pub static CONTROL_INITIAL_X_M: Param = param! {
    description: "where odometry starts, x (the `[control]` section, D139)",
    name: "control.initial_x_m", unit: "m", min: v(-MAX_INITIAL_POSITION_M),
    max: v(MAX_INITIAL_POSITION_M), default: Value(0.0),
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `control.initial_y_m`.
pub static CONTROL_INITIAL_Y_M: Param = param! {
    description: "where odometry starts, y (the `[control]` section, D139)",
    name: "control.initial_y_m", unit: "m", min: v(-MAX_INITIAL_POSITION_M),
    max: v(MAX_INITIAL_POSITION_M), default: Value(0.0),
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `control.initial_heading_rad`.
pub static CONTROL_INITIAL_HEADING_RAD: Param = param! {
    description: "where odometry starts, heading counter-clockwise from +x (the `[control]` section, D139)",
    name: "control.initial_heading_rad", unit: "rad", min: v(-core::f32::consts::PI),
    max: v(core::f32::consts::PI), default: Value(0.0),
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};

/// `estimator.gyro_noise_density`.
pub static ESTIMATOR_GYRO_NOISE_DENSITY: Param = param! {
    description: "gyro angle random walk the pose estimator assumes (the data sheet's rate noise density; MPU-6050: 8.7e-5); above 0.1 rad/s/√Hz is no gyro worth fusing",
    name: "estimator.gyro_noise_density", unit: "rad/s/√Hz", min: v(1e-7), max: v(0.1),
    default: Value(0.001),
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `estimator.gyro_bias_walk`.
pub static ESTIMATOR_GYRO_BIAS_WALK: Param = param! {
    description: "gyro bias random walk the pose estimator assumes",
    name: "estimator.gyro_bias_walk", unit: "rad/s/√s", min: v(1e-8), max: v(0.1),
    default: Value(0.0005),
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `estimator.speed_noise_mps_per_sqrt_hz`.
pub static ESTIMATOR_SPEED_NOISE: Param = param! {
    description: "white noise on the wheel-derived speed the pose estimator assumes",
    name: "estimator.speed_noise_mps_per_sqrt_hz", unit: "m/s/√Hz", min: v(1e-6), max: v(1.0),
    default: Value(0.02),
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `estimator.slip_fraction`.
pub static ESTIMATOR_SLIP_FRACTION: Param = param! {
    description: "relative wheel-odometry error from slip and faults, a density per √s (0: wheels that never slip)",
    name: "estimator.slip_fraction", unit: "1/√s", min: v(0.0), max: v(1.0),
    default: Value(0.02),
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};
/// `estimator.wheel_yaw_noise`.
pub static ESTIMATOR_WHEEL_YAW_NOISE: Param = param! {
    description: "white noise on the wheels' yaw rate, used without a gyro",
    name: "estimator.wheel_yaw_noise", unit: "rad/s/√Hz", min: v(1e-6), max: v(10.0),
    default: Value(0.05),
    access: File, in_file: InFile::Yes, integer: false, wire: None, old_name: None,
};

/// Every parameter: the file's in file order, then those only the link
/// sets.
pub static ALL: [&Param; 57] = [
    &BODY_MASS_KG,
    &BODY_INERTIA_KGM2,
    &BODY_WHEEL_INERTIA_KGM2,
    &BODY_COM_OFFSET_M,
    &BODY_WHEEL_RADIUS_M,
    &BODY_TRACK_M,
    &MOTORS_TORQUE_CONSTANT,
    &MOTORS_RESISTANCE_OHM,
    &MOTORS_GEAR_RATIO,
    &MOTORS_GEAR_EFFICIENCY,
    &MOTORS_SUPPLY_VOLTAGE_V,
    &MOTORS_VISCOUS_FRICTION,
    &MOTORS_COULOMB_FRICTION_NM,
    &ENCODERS_COUNTS_PER_WHEEL_REV,
    &ENCODERS_SPEED_WINDOW_TICKS,
    &BRIDGE_PWM_FREQUENCY_HZ,
    &BRIDGE_MAX_DUTY_FRACTION,
    &LIMITS_TORQUE_NM,
    &LIMITS_MAX_SPEED_MPS,
    &LIMITS_MAX_YAW_RATE_RADPS,
    &LIMITS_MAX_ACCEL_MPS2,
    &LIMITS_LINK_TIMEOUT_MS,
    &CONTROL_INITIAL_X_M,
    &CONTROL_INITIAL_Y_M,
    &CONTROL_INITIAL_HEADING_RAD,
    &ESTIMATOR_GYRO_NOISE_DENSITY,
    &ESTIMATOR_GYRO_BIAS_WALK,
    &ESTIMATOR_SPEED_NOISE,
    &ESTIMATOR_SLIP_FRACTION,
    &ESTIMATOR_WHEEL_YAW_NOISE,
    &GAINS_K_X,
    &GAINS_K_Y,
    &GAINS_K_TH,
    &GAINS_LARGE_ERROR_M,
    &GAINS_OBSERVER_L_V,
    &GAINS_OBSERVER_L_OMEGA,
    &GAINS_OBSERVER_MAX_ESTIMATE_V,
    &GAINS_OBSERVER_MAX_ESTIMATE_OMEGA,
    &GAINS_ESO_LAMBDA,
    &GAINS_ESO_ZETA,
    &GAINS_ESO_ALPHA,
    &GAINS_ESO_MAX_DISTURBANCE_V,
    &GAINS_ESO_MAX_DISTURBANCE_OMEGA,
    &GAINS_K_S,
    &GAINS_SWITCHING_FIXED_K,
    &GAINS_ADAPTIVE_GAMMA,
    &GAINS_ADAPTIVE_DEAD_ZONE,
    &GAINS_ADAPTIVE_LEAKAGE,
    &GAINS_ADAPTIVE_RHO0,
    &GAINS_ADAPTIVE_RHO_MIN,
    &GAINS_ADAPTIVE_RHO_MAX,
    &STALL_TORQUE_NM,
    &STALL_TICKS,
    &TELEMETRY_RATE_HZ,
    &ANG_ACCEL_RADPS2,
    &BRAKE_DECEL_MPS2,
    &CONTROL_PERIOD,
];

/// The parameters the link reads and writes, in wire order (index = wire
/// id; wmr-protocol's `ParamId::ALL`).
pub static WIRE: [&Param; 15] = [
    &LIMITS_TORQUE_NM,
    &GAINS_K_X,
    &GAINS_K_Y,
    &GAINS_K_TH,
    &GAINS_K_S,
    &STALL_TORQUE_NM,
    &STALL_TICKS,
    &TELEMETRY_RATE_HZ,
    &LIMITS_LINK_TIMEOUT_MS,
    &LIMITS_MAX_ACCEL_MPS2,
    &ANG_ACCEL_RADPS2,
    &BRAKE_DECEL_MPS2,
    &LIMITS_MAX_SPEED_MPS,
    &LIMITS_MAX_YAW_RATE_RADPS,
    &CONTROL_PERIOD,
];

/// The parameter named `name`.
pub fn find(name: &str) -> Option<&'static Param> {
    ALL.iter().copied().find(|p| p.name == name)
}

/// The parameter that had the name `old` before issue 32.
#[cfg(feature = "describe")]
pub fn find_old(old: &str) -> Option<&'static Param> {
    WIRE.iter().copied().find(|p| p.old_name == Some(old))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_ids_are_the_positions_and_names_are_unique() {
        for (i, p) in WIRE.iter().enumerate() {
            assert_eq!(p.wire, Some(i as u8), "{}", p.name);
            assert!(ALL.iter().any(|q| core::ptr::eq(*q, *p)), "{}", p.name);
        }
        for p in ALL.iter() {
            if let Some(w) = p.wire {
                assert!(core::ptr::eq(WIRE[w as usize], *p), "{}", p.name);
            }
            assert_eq!(
                ALL.iter().filter(|q| q.name == p.name).count(),
                1,
                "{}",
                p.name
            );
            assert!(core::ptr::eq(find(p.name).unwrap(), *p));
            #[cfg(feature = "describe")]
            if let Some(o) = p.old_name {
                assert!(core::ptr::eq(find_old(o).unwrap(), *p));
                assert!(find(o).is_none(), "{o} is both an old and a new name");
            }
        }
    }

    #[test]
    fn defaults_lie_in_their_ranges() {
        let b = RobotBounds::ABSOLUTE;
        for p in ALL.iter() {
            let (lo, hi) = p.range(&b);
            assert!(lo <= hi, "{}", p.name);
            #[cfg(feature = "describe")]
            if let DefaultValue::Value(x) = p.default {
                assert!(p.check(x, &b).is_ok(), "{}", p.name);
            }
        }
    }

    #[test]
    fn a_refusal_names_the_field_value_limit_and_what_to_do() {
        let b = RobotBounds::of(0.53, 4.0, 0.1, 1e-3);
        let e = LIMITS_TORQUE_NM.check(0.6, &b).unwrap_err();
        assert_eq!(
            (e.field, e.value, e.limit()),
            ("limits.torque_nm", 0.6, 0.53)
        );
        assert_eq!(e.beyond, Beyond::Max);
        let s = std::format!("{e}");
        assert_eq!(
            s,
            "limits.torque_nm: 0.6 N·m is above its limit 0.53 N·m, the robot's stall \
             torque η·N·k·V/R: set a value in [0.01, 0.53] N·m"
        );
        assert!(LIMITS_TORQUE_NM.check(0.53, &b).is_ok());
        assert_eq!(
            LIMITS_TORQUE_NM.check(f32::NAN, &b).unwrap_err().beyond,
            Beyond::NotFinite
        );
        assert_eq!(
            LIMITS_LINK_TIMEOUT_MS.check(500.5, &b).unwrap_err().beyond,
            Beyond::NotInteger
        );
        // k_y's bound: (500 / 4)².
        let ky = GAINS_K_Y.range(&b).1;
        assert!((ky / (125.0 * 125.0) - 1.0).abs() < 1e-5, "{ky}");
    }
}
