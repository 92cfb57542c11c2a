//! Fakes of the runtime's hardware for tests (feature `test-doubles`, as
//! sim-robot re-exports them; always built for this crate's own tests):
//! a scripted encoder, a recording motor driver, a scripted pose source
//! and the straight-line runtime configuration the tests share.

use super::{DutyCommand, Encoder, MotorDriver, PoseSource, RuntimeConfig};
use crate::controller::ControllerKind;
use crate::estimator::PoseMeasurement;
use crate::trajectory::{Line, Reference};
use crate::Pose;

/// An encoder counter that reads whatever the test put in it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ScriptedEncoder(pub u16);

impl Encoder for ScriptedEncoder {
    fn count(&mut self) -> u16 {
        self.0
    }
}

/// A motor driver that records what it was told.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RecordingDriver {
    /// Enabled (set since the last disable).
    pub enabled: bool,
    /// The last command (zero after a disable).
    pub duty: [DutyCommand; 2],
    /// Calls of `set`.
    pub sets: u32,
    /// Calls of `disable`.
    pub disables: u32,
}

impl MotorDriver for RecordingDriver {
    fn set(&mut self, cmd: [DutyCommand; 2]) {
        self.enabled = true;
        self.duty = cmd;
        self.sets += 1;
    }
    fn disable(&mut self) {
        self.enabled = false;
        self.duty = [DutyCommand::ZERO; 2];
        self.disables += 1;
    }
}

/// A pose source delivering one measurement (then nothing).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OneShotPose(pub Option<PoseMeasurement>);

impl OneShotPose {
    /// One measurement of `pose` stamped `stamp_us`, motion-capture-like
    /// (2 mm, 0.005 rad).
    pub fn at(stamp_us: u32, pose: Pose) -> Self {
        Self(Some(PoseMeasurement {
            stamp_us,
            pose,
            position_std_m: 0.002,
            heading_std_rad: Some(0.005),
        }))
    }
}

impl PoseSource for OneShotPose {
    fn measurement(&mut self) -> Option<PoseMeasurement> {
        self.0.take()
    }
}

/// The example runtime (proposed controller) tracking a straight line
/// along +x from the origin at `speed_mps`, starting on it.
pub fn line_config(speed_mps: f32) -> RuntimeConfig {
    let start = Pose::new(0.0, 0.0, 0.0);
    RuntimeConfig {
        reference: Reference::Line(Line { start, speed_mps }),
        initial_pose: start,
        ..RuntimeConfig::example(ControllerKind::Proposed)
    }
}
