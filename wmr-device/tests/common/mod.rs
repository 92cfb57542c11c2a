//! What the device's host tests share: a runtime that scripted (never
//! moving) encoders do not trip, the framing of requests, reading back
//! every reply the device queued, and the nack code of a reply.

#![allow(dead_code)] // each test file uses its own part

use controller_core::runtime::RuntimeConfig;
use controller_core::ControllerKind;
use wmr_device::{Device, DeviceConfig, LinkConfig};
use wmr_protocol::*;

/// Control period of the tests \[µs\].
pub const PERIOD_US: u32 = 1000;

/// The example runtime with the stall check and the governor off: the
/// scripted encoders never follow the torque (the stall check would latch)
/// and a robot that never moves would have its reference held back (both
/// are tested in controller-core and end to end in hil-sim).
pub fn quiet_runtime() -> RuntimeConfig {
    let mut rt = RuntimeConfig::example(ControllerKind::Proposed);
    rt.safety.stall_ticks = u16::MAX;
    rt.pacing = controller_core::pacer::PacingConfig::off();
    rt
}

/// A test device's configuration with `capabilities`.
pub fn device_config(capabilities: u16) -> DeviceConfig {
    DeviceConfig {
        chip: "test",
        capabilities,
        link: LinkConfig::DEFAULT,
        button_reference: None,
    }
}

/// `req` framed with sequence number `seq`.
pub fn frame(req: &Request, seq: u16) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    encode(req, seq, &mut buf).unwrap().to_vec()
}

/// Every frame the device has queued, decoded by `rx`, to `on`.
pub fn drain(
    dev: &mut Device,
    rx: &mut FrameDecoder<MAX_FRAME>,
    mut on: impl FnMut(Decoded<Reply>),
) {
    let mut buf = [0u8; 4096];
    loop {
        let n = dev.pop_tx(&mut buf);
        if n == 0 {
            break;
        }
        rx.feed_all::<Reply>(&buf[..n], &mut on);
    }
}

/// The error code of a nack.
pub fn nack(r: &Reply) -> Option<ErrorCode> {
    match r {
        Reply::Nack { error, .. } => Some(*error),
        _ => None,
    }
}
