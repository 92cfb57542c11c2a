//! `wmr params get|set NAME`: the robot's parameters by the parameter
//! table's names (controller-core `runtime::param_table`, D144), the
//! names before issue 32 with a "renamed to" note, and refusals that say
//! the value, the limit and what to do.

use crate::link::{Link, LinkError};
use clap::{Args, Subcommand};
use controller_core::runtime::param_table::{self, Access, Param, RangeError, RobotBounds};
use std::io::Write;
use wmr_protocol::{ErrorCode, ParamId, Reply, Request};

/// A parameter name resolved: the parameter, and a note when the name is
/// one it had before issue 32.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Resolved {
    /// The parameter.
    pub id: ParamId,
    /// "torque_limit_nm was renamed to limits.torque_nm" for an old name.
    pub note: Option<String>,
}

/// Why `wmr params` refused or failed.
#[derive(Debug)]
pub enum ParamsError {
    /// Not a parameter's name, old or new.
    Unknown(String),
    /// The value is outside the parameter's range for any robot (checked
    /// before asking the robot): the field, the value, the limit.
    Range(RangeError),
    /// The robot refused the value (its own range, tighter than any
    /// robot's for a robot-dependent bound, or its state).
    Refused {
        /// The parameter.
        id: ParamId,
        /// The value asked.
        value: f32,
        /// The robot's code.
        code: ErrorCode,
    },
    /// The robot refused a value beyond its own range, computed from the
    /// robot file it runs (read from its store).
    RefusedRange {
        /// The robot's name.
        robot: String,
        /// The value, the limit and the range.
        error: RangeError,
    },
    /// The link failed.
    Link(LinkError),
}

impl std::fmt::Display for ParamsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Unknown(name) => {
                let names: Vec<&str> = ParamId::ALL.iter().map(|p| p.name()).collect();
                write!(
                    f,
                    "unknown parameter {name:?} (one of: {}; book/src/reference/parameters.md)",
                    names.join(", ")
                )
            }
            Self::Range(e) => write!(f, "{e}"),
            Self::Refused { id, value, code } => {
                write!(
                    f,
                    "the robot refused {} = {value}: {}",
                    id.name(),
                    code.reason()
                )?;
                if *code == ErrorCode::InvalidValue {
                    write!(f, "; {}", robot_range(id.param()))?;
                }
                Ok(())
            }
            Self::RefusedRange { robot, error } => write!(
                f,
                "the robot refused {}: {} (robot {robot}'s file on the link)",
                error.field,
                error.reason()
            ),
            Self::Link(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for ParamsError {}

impl From<LinkError> for ParamsError {
    fn from(e: LinkError) -> Self {
        Self::Link(e)
    }
}

/// What to say when the robot refuses a value of `p` as out of range
/// (the link carries only the code; the range may be the robot's):
/// "limits.torque_nm's range is [0.01, τ_stall] N·m (τ_stall: the robot's
/// stall torque η·N·k·V/R): set a value within it". wmr-ros2 says the
/// same.
pub fn robot_range(p: &Param) -> String {
    use std::fmt::Write as _;
    let mut f = format!("{}'s range is ", p.name);
    let _ = p.write_range(&mut f);
    if !p.unit.is_empty() {
        let _ = write!(f, " {}", p.unit);
    }
    if p.max.fixed().is_none() {
        f += " (";
        let _ = p.max.write(&mut f);
        let _ = write!(f, ": {})", p.max.describe());
    }
    f + ": set a value within it"
}

/// The parameter that had the name `old` before issue 32
/// (`torque_limit_nm` is `limits.torque_nm`; the parameter table's
/// `find_old`).
pub fn from_old_name(old: &str) -> Option<ParamId> {
    let w = param_table::find_old(old)?.wire?;
    ParamId::ALL.get(w as usize).copied()
}

/// The parameter named `name` (the table's name, or its name before
/// issue 32 with a note).
pub fn resolve(name: &str) -> Result<Resolved, ParamsError> {
    if let Some(id) = ParamId::from_name(name) {
        return Ok(Resolved { id, note: None });
    }
    match from_old_name(name) {
        Some(id) => Ok(Resolved {
            id,
            note: Some(format!(
                "note: {name} was renamed to {} (book/src/reference/parameters.md)",
                id.name()
            )),
        }),
        None => Err(ParamsError::Unknown(name.into())),
    }
}

/// The host's check before it asks the robot: the range of any robot
/// (the robot-dependent ends at their largest) — the same
/// [`Param::check`] as the robot file's, the device's and the ROS
/// bridge's.
pub fn check_any_robot(id: ParamId, value: f32) -> Result<(), RangeError> {
    id.param().check(value, &RobotBounds::ABSOLUTE)
}

/// `wmr params get [NAME]`: prints `name = value` lines to `out`, a
/// rename note to `note`.
pub fn get(
    name: Option<&str>,
    link: &mut Link,
    out: &mut dyn Write,
    note: &mut dyn Write,
) -> Result<(), ParamsError> {
    let ids = match name {
        Some(n) => {
            let r = resolve(n)?;
            if let Some(m) = &r.note {
                let _ = writeln!(note, "{m}");
            }
            vec![r.id]
        }
        None => ParamId::ALL.to_vec(),
    };
    for id in ids {
        match link.command(&Request::GetParam(id))? {
            Reply::Param { value, .. } => writeln!(out, "{} = {value}", id.name())
                .map_err(|e| LinkError::Io(e.to_string()))?,
            r => return Err(LinkError::Unexpected(format!("{r:?}")).into()),
        }
    }
    Ok(())
}

/// `wmr params set NAME VALUE`: checks the value against the table,
/// writes it, prints `name = value`.
pub fn set(
    name: &str,
    value: f32,
    link: &mut Link,
    out: &mut dyn Write,
    note: &mut dyn Write,
) -> Result<(), ParamsError> {
    let r = resolve(name)?;
    if let Some(m) = &r.note {
        let _ = writeln!(note, "{m}");
    }
    let id = r.id;
    // A read-only parameter is the robot's to refuse (ReadOnly).
    if id.param().access != Access::ReadOnly {
        check_any_robot(id, value).map_err(ParamsError::Range)?;
    }
    match link.command(&Request::SetParam { id, value }) {
        Ok(_) => {}
        Err(LinkError::Nack(_, code)) => {
            // The link carries only the code: the robot's own range, with
            // its computed ends, from the robot file it runs.
            if code == ErrorCode::InvalidValue {
                if let Ok(Ok(robot)) = crate::session::robot_in_force(link) {
                    if let Err(error) = id.param().check(value, &robot.bounds()) {
                        return Err(ParamsError::RefusedRange {
                            robot: robot.name.to_string(),
                            error,
                        });
                    }
                }
            }
            return Err(ParamsError::Refused { id, value, code });
        }
        Err(e) => return Err(e.into()),
    }
    writeln!(out, "{} = {value}", id.name()).map_err(|e| LinkError::Io(e.to_string()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_names_resolve_with_a_renamed_note() {
        let r = resolve("torque_limit_nm").unwrap();
        assert_eq!(r.id, ParamId::TorqueLimitNm);
        assert_eq!(
            r.note.as_deref(),
            Some("note: torque_limit_nm was renamed to limits.torque_nm (book/src/reference/parameters.md)")
        );
        let r = resolve("accel_mps2").unwrap();
        assert_eq!(r.id, ParamId::AccelMps2);
        assert!(r.note.unwrap().contains("renamed to limits.max_accel_mps2"));
        assert_eq!(
            resolve("limits.torque_nm").unwrap(),
            Resolved {
                id: ParamId::TorqueLimitNm,
                note: None
            }
        );
        assert_eq!(resolve("stall_ticks").unwrap().id, ParamId::StallTicks);
        let e = resolve("torque").unwrap_err().to_string();
        assert!(e.contains("unknown parameter \"torque\""), "{e}");
        assert!(e.contains("limits.torque_nm"), "{e}");
    }

    #[test]
    fn a_refusal_says_the_range_and_what_to_do() {
        let e = check_any_robot(ParamId::AccelMps2, 25.0).unwrap_err();
        assert_eq!(
            ParamsError::Range(e).to_string(),
            "limits.max_accel_mps2: 25 m/s² is above its limit 20 m/s²: set a value in [0.01, 20] m/s²"
        );
        let e = ParamsError::Refused {
            id: ParamId::TorqueLimitNm,
            value: 30.0,
            code: ErrorCode::InvalidValue,
        }
        .to_string();
        assert_eq!(
            e,
            "the robot refused limits.torque_nm = 30: value NaN, infinite or outside its \
             physical range; limits.torque_nm's range is [0.01, τ_stall] N·m (τ_stall: the \
             robot's stall torque η·N·k·V/R): set a value within it"
        );
    }
}

/// `params` options.
#[derive(Debug, Args)]
pub struct ParamsArgs {
    /// get or set.
    #[command(subcommand)]
    pub op: ParamsOp,
}

/// `params` operations.
#[derive(Debug, Subcommand)]
pub enum ParamsOp {
    /// Print one parameter, or all.
    Get {
        /// Parameter name (book/src/reference/parameters.md; the names before issue 32
        /// are taken with a "renamed to" note); all when omitted.
        name: Option<String>,
    },
    /// Write one parameter.
    Set {
        /// Parameter name.
        name: String,
        /// Value in the parameter's unit.
        #[arg(allow_hyphen_values = true)]
        value: f32,
    },
}

/// `params get|set`: [`get`] and [`set`] with their notes on stderr.
pub fn params(op: &ParamsOp, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    match op {
        ParamsOp::Get { name } => get(name.as_deref(), link, out, &mut std::io::stderr()),
        ParamsOp::Set { name, value } => set(name, *value, link, out, &mut std::io::stderr()),
    }
    .map_err(|e| match e {
        ParamsError::Link(e) => e,
        e => LinkError::Io(e.to_string()),
    })
}
