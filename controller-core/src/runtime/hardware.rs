//! The hardware the runtime drives, as traits: a board (or a simulator)
//! implements them with its registers (or models).

use super::motor::DutyCommand;
use crate::estimator::{GyroSample, PoseMeasurement};

/// Per wheel `[right, left]`: the usual mounting of a differential drive,
/// the left motor and encoder mirrored (they turn backwards when the robot
/// drives forward). The default of [`EncoderParams::EXAMPLE`](super::EncoderParams::EXAMPLE) and
/// [`RuntimeConfig::example`](super::RuntimeConfig::example).
pub const MIRRORED_LEFT: [bool; 2] = [false, true];

/// A wheel, for fault reports and indexing `[right, left]` arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Wheel {
    /// Right wheel (index 0).
    Right,
    /// Left wheel (index 1).
    Left,
}

impl Wheel {
    /// Both wheels in array order.
    pub const BOTH: [Wheel; 2] = [Wheel::Right, Wheel::Left];

    /// Index into a `[right, left]` array.
    pub const fn index(self) -> usize {
        match self {
            Wheel::Right => 0,
            Wheel::Left => 1,
        }
    }
}

/// One quadrature encoder: the raw free-running 16-bit hardware count
/// (e.g. a timer in encoder mode, or a simulated counter).
pub trait Encoder {
    /// Current raw count (wraps at 2¹⁶).
    fn count(&mut self) -> u16;
}

/// Both wheel encoders, read together once per tick.
///
/// Implemented for a `(right, left)` tuple and a `[right, left]` array of
/// [`Encoder`]s.
pub trait WheelEncoders {
    /// Raw counts `[right, left]`.
    fn counts(&mut self) -> [u16; 2];
}

impl<R: Encoder, L: Encoder> WheelEncoders for (R, L) {
    fn counts(&mut self) -> [u16; 2] {
        [self.0.count(), self.1.count()]
    }
}

impl<E: Encoder> WheelEncoders for [E; 2] {
    fn counts(&mut self) -> [u16; 2] {
        let [r, l] = self;
        [r.count(), l.count()]
    }
}

/// The motor driver (H-bridge) of both wheels. Implementations must start
/// disabled (outputs off) and stay disabled until the first [`Self::set`].
pub trait MotorDriver {
    /// Enables the bridge (if disabled) and applies `[right, left]` duty and
    /// direction. Duty is in counts of [`MotorParams::duty_full_scale`](super::MotorParams::duty_full_scale).
    fn set(&mut self, cmd: [DutyCommand; 2]);
    /// Zero duty and bridge disabled (motors coast). Called on every tick
    /// while not running, so it must be idempotent and cheap.
    fn disable(&mut self);
}

/// A z-axis rate gyro (the yaw rate of the body, which the wheels do not
/// see when they slip). Optional: without one the runtime uses the wheels'
/// yaw rate and says so in the estimator's status.
pub trait Gyro {
    /// The latest sample, or `None` when there is none (not fitted, not
    /// answering). A sample may be repeated; its stamp says how old it is.
    fn sample(&mut self) -> Option<GyroSample>;
}

/// No gyro fitted.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoGyro;

impl Gyro for NoGyro {
    fn sample(&mut self) -> Option<GyroSample> {
        None
    }
}

/// An optional external measurement of the pose of G (motion capture, a
/// camera, a lidar localiser, UWB...), timestamped when taken, with its
/// uncertainty. Wheel odometry cannot see wheel slip or an actuator fault
/// that changes the body's motion, so the fault observer only works with
/// such a measurement.
pub trait PoseSource {
    /// The next measurement not yet delivered, oldest first, or `None`. The
    /// runtime calls it up to [`MAX_POSES_PER_TICK`] times per tick; the
    /// estimator uses measurements up to its history length late.
    fn measurement(&mut self) -> Option<PoseMeasurement>;
}

/// Most pose measurements the runtime takes from its [`PoseSource`] in one tick.
pub const MAX_POSES_PER_TICK: usize = 4;

/// The default [`PoseSource`]: never has a measurement (wheel odometry only).
#[derive(Clone, Copy, Debug, Default)]
pub struct WheelOdometryOnly;

impl PoseSource for WheelOdometryOnly {
    fn measurement(&mut self) -> Option<PoseMeasurement> {
        None
    }
}
