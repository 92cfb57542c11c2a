//! Validation errors: the field by its TOML path and the reason.

use controller_core::error::ConfigError;
use controller_core::runtime::param_table::RangeError;
use controller_core::runtime::RuntimeConfigError;

/// Why a field is refused.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum Reason {
    /// NaN or infinite.
    NotFinite,
    /// Outside the physical range `[min, max]` (in `unit`).
    OutOfRange {
        /// The value found.
        value: f32,
        /// Smallest accepted value.
        min: f32,
        /// Largest accepted value.
        max: f32,
        /// Unit of the three numbers.
        unit: &'static str,
    },
    /// Outside its range in the parameter table (controller-core
    /// `param_table`): the value, the limit broken, the range; the same
    /// refusal the device and the ROS bridge give.
    Range(RangeError),
    /// Inconsistent with another field (`with`, a TOML path): `why`.
    Inconsistent {
        /// The other field.
        with: &'static str,
        /// The rule broken.
        why: &'static str,
    },
    /// Beyond what another field allows: the value, the bound computed from
    /// the other field (`with`) and what to do (`why`).
    Exceeds {
        /// The value found.
        value: f32,
        /// The bound it breaks.
        limit: f32,
        /// Unit of both numbers.
        unit: &'static str,
        /// The other field or the formula of the bound.
        with: &'static str,
        /// The rule broken and what to do.
        why: &'static str,
    },
    /// `format` is not the version this build reads ([`crate::FORMAT`]).
    UnsupportedFormat {
        /// The version found.
        found: u32,
    },
    /// controller-core refused the controller configuration.
    Controller(ConfigError),
    /// controller-core refused the runtime configuration.
    Runtime(RuntimeConfigError),
}

/// A robot refused by [`crate::Robot::validate`] (or a derivation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobotError {
    /// TOML path of the field, e.g. `"body.wheel_radius_m[1]"`.
    pub field: &'static str,
    /// Why.
    pub reason: Reason,
}

impl RobotError {
    pub(crate) const fn new(field: &'static str, reason: Reason) -> Self {
        Self { field, reason }
    }
}

impl core::fmt::Display for RobotError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}: ", self.field)?;
        match self.reason {
            Reason::NotFinite => write!(f, "not a finite number"),
            Reason::OutOfRange {
                value,
                min,
                max,
                unit,
            } => {
                write!(
                    f,
                    "{value} {unit} is outside the physical range [{min}, {max}] {unit}"
                )
            }
            Reason::Range(e) => write!(f, "{}", e.reason()),
            Reason::Inconsistent { with, why } => write!(f, "inconsistent with {with}: {why}"),
            Reason::Exceeds {
                value,
                limit,
                unit,
                with,
                why,
            } => write!(
                f,
                "{value} {unit} is beyond its bound {limit:.4} {unit} ({with}): {why}"
            ),
            Reason::UnsupportedFormat { found } => write!(
                f,
                "format {found} is not supported (this build reads format {})",
                crate::FORMAT
            ),
            Reason::Controller(e) => write!(f, "refused by the controller: {e}"),
            Reason::Runtime(e) => write!(f, "refused by the runtime: {e:?}"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for RobotError {}
