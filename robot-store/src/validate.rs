//! robot-file's decode and validation errors in wire form: the
//! [`RobotValidator`](crate::RobotValidator) the boards give the device and
//! the store.

use robot_file::{DecodeError, Reason, Robot, RobotError};
use wmr_protocol::{RobotFault, RobotFaultKind};

/// A validation error: its field's TOML path, the kind and, for a range,
/// the range.
pub fn robot_fault(e: &RobotError) -> RobotFault {
    let (kind, range) = match e.reason {
        Reason::NotFinite => (RobotFaultKind::NotFinite, None),
        Reason::OutOfRange { min, max, .. } => (RobotFaultKind::OutOfRange, Some([min, max])),
        Reason::Range(e) => (RobotFaultKind::OutOfRange, Some([e.min, e.max])),
        Reason::Inconsistent { .. } => (RobotFaultKind::Inconsistent, None),
        Reason::Exceeds { limit, .. } => (RobotFaultKind::Inconsistent, Some([0.0, limit])),
        Reason::UnsupportedFormat { .. } => (RobotFaultKind::UnsupportedFormat, None),
        _ => (RobotFaultKind::Refused, None),
    };
    RobotFault::new(kind, e.field, range)
}

/// A decode error of the binary form.
pub fn decode_fault(e: &DecodeError) -> RobotFault {
    let whole = |kind| RobotFault::new(kind, "", None);
    match e {
        DecodeError::Truncated => whole(RobotFaultKind::Truncated),
        DecodeError::BadMagic => whole(RobotFaultKind::BadMagic),
        DecodeError::UnsupportedFormat { .. } => whole(RobotFaultKind::UnsupportedFormat),
        DecodeError::BadLength => whole(RobotFaultKind::BadLength),
        DecodeError::BadCrc => whole(RobotFaultKind::BadCrc),
        DecodeError::Invalid(r) => robot_fault(r),
        _ => whole(RobotFaultKind::Malformed),
    }
}

/// The [`RobotValidator`](crate::RobotValidator) of robot-file's binary
/// form: [`Robot::decode`] (header, CRC-32, payload, every field).
pub fn validate_robot(record: &[u8]) -> Result<(), RobotFault> {
    Robot::decode(record)
        .map(|_| ())
        .map_err(|e| decode_fault(&e))
}
