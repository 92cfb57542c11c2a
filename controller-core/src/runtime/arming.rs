//! The operator button's arm / disarm / reset policy, hardware-agnostic.
//!
//! One button, sampled once per tick: a press counts when the button has
//! been held for `debounce_ticks` consecutive ticks (contact bounce and
//! short glitches never count), and a long press counts once (release
//! before the next press). Each press acts on the loop's state:
//!
//! | state | press |
//! |---|---|
//! | [`RunState::Disarmed`] | [`ControlLoop::arm`] (reference time restarts at 0) |
//! | [`RunState::Running`] | [`ControlLoop::disarm`] (motors off, not latched) |
//! | [`RunState::Stopped`] | [`ControlLoop::reset`] (clears the latch, back to disarmed; arming takes another press) |

use super::control_loop::ControlLoop;
use super::error::RuntimeConfigError;
use super::hardware::MotorDriver;
use super::state::{ArmError, RunState};

/// What a button sample did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ArmingEvent {
    /// No press completed on this sample.
    None,
    /// Armed from disarmed.
    Armed,
    /// Disarmed from running.
    Disarmed,
    /// A latched stop was cleared (now disarmed).
    Reset,
    /// The loop refused to arm.
    ArmRefused(ArmError),
}

/// Debounced button plus the arm / disarm / reset policy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArmingButton {
    debounce_ticks: u16,
    held_ticks: u16,
}

impl ArmingButton {
    /// A button whose press counts after `debounce_ticks` (>= 1)
    /// consecutive pressed samples.
    pub fn new(debounce_ticks: u16) -> Result<Self, RuntimeConfigError> {
        if debounce_ticks == 0 {
            return Err(RuntimeConfigError::InvalidDebounce);
        }
        Ok(Self {
            debounce_ticks,
            held_ticks: 0,
        })
    }

    /// Debounce only: true on the one sample where a press has been held
    /// for `debounce_ticks` samples.
    pub fn press(&mut self, pressed: bool) -> bool {
        if !pressed {
            self.held_ticks = 0;
            return false;
        }
        self.held_ticks = self.held_ticks.saturating_add(1);
        self.held_ticks == self.debounce_ticks
    }

    /// One sample of the button (`pressed` = held down now): on a completed
    /// press, applies the policy to `cl` (disarming turns `motors` off).
    pub fn update<const H: usize>(
        &mut self,
        pressed: bool,
        cl: &mut ControlLoop<H>,
        motors: &mut impl MotorDriver,
    ) -> ArmingEvent {
        if !self.press(pressed) {
            return ArmingEvent::None;
        }
        match cl.state() {
            RunState::Disarmed => match cl.arm() {
                Ok(()) => ArmingEvent::Armed,
                Err(e) => ArmingEvent::ArmRefused(e),
            },
            RunState::Running => {
                cl.disarm(motors);
                ArmingEvent::Disarmed
            }
            RunState::Stopped(_) => {
                cl.reset();
                ArmingEvent::Reset
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::ControllerKind;
    use crate::runtime::test_doubles::RecordingDriver;
    use crate::runtime::{NoGyro, RuntimeConfig, StopReason, TickTiming, WheelOdometryOnly};

    const N: u16 = 20;

    fn loop_() -> ControlLoop {
        ControlLoop::new(RuntimeConfig::example(ControllerKind::Proposed)).unwrap()
    }

    /// Holds the button for `ticks` samples, then releases it for one;
    /// returns the events that were not `None`.
    fn hold(
        b: &mut ArmingButton,
        ticks: u32,
        cl: &mut ControlLoop,
        d: &mut RecordingDriver,
    ) -> std::vec::Vec<(u32, ArmingEvent)> {
        let mut ev = std::vec::Vec::new();
        for k in 0..ticks {
            let e = b.update(true, cl, d);
            if e != ArmingEvent::None {
                ev.push((k, e));
            }
        }
        assert_eq!(b.update(false, cl, d), ArmingEvent::None);
        ev
    }

    #[test]
    fn bounce_shorter_than_debounce_never_counts() {
        let mut b = ArmingButton::new(N).unwrap();
        // Bursts of 1..N-1 pressed samples separated by a release.
        for len in 1..N {
            for _ in 0..len {
                assert!(!b.press(true));
            }
            assert!(!b.press(false));
        }
    }

    #[test]
    fn press_counts_once_at_debounce_and_long_press_once() {
        let mut b = ArmingButton::new(N).unwrap();
        let presses: std::vec::Vec<u32> = (0..10 * N as u32).filter(|_| b.press(true)).collect();
        // Counted exactly on the N-th sample, never again while held.
        assert_eq!(presses, [N as u32 - 1]);
        assert!(!b.press(false));
        // Released and pressed again: a second press.
        let again = (0..N).filter(|_| b.press(true)).count();
        assert_eq!(again, 1);
    }

    #[test]
    fn arm_then_disarm() {
        let (mut cl, mut d) = (loop_(), RecordingDriver::default());
        let mut b = ArmingButton::new(N).unwrap();
        assert_eq!(
            hold(&mut b, N as u32, &mut cl, &mut d),
            [(N as u32 - 1, ArmingEvent::Armed)]
        );
        assert_eq!(cl.state(), RunState::Running);
        // A long second press disarms, once.
        assert_eq!(
            hold(&mut b, 5 * N as u32, &mut cl, &mut d),
            [(N as u32 - 1, ArmingEvent::Disarmed)]
        );
        assert_eq!(cl.state(), RunState::Disarmed);
        assert!(!d.enabled);
    }

    #[test]
    fn running_loop_drives_until_disarmed() {
        let (mut cl, mut d) = (loop_(), RecordingDriver::default());
        let mut b = ArmingButton::new(N).unwrap();
        hold(&mut b, N as u32, &mut cl, &mut d);
        let t = TickTiming::on_schedule(1000);
        let mut enc = [Enc; 2];
        cl.tick(&mut enc, &mut d, &mut NoGyro, &mut WheelOdometryOnly, t);
        assert!(d.enabled, "armed loop drives the motors");
        assert_eq!(
            hold(&mut b, N as u32, &mut cl, &mut d),
            [(N as u32 - 1, ArmingEvent::Disarmed)]
        );
        assert!(!d.enabled, "disarm turns the driver off at once");
        cl.tick(&mut enc, &mut d, &mut NoGyro, &mut WheelOdometryOnly, t);
        assert!(!d.enabled);
    }

    #[derive(Clone, Copy)]
    struct Enc;
    impl crate::runtime::Encoder for Enc {
        fn count(&mut self) -> u16 {
            0
        }
    }

    /// A latched stop: the first press only resets (to disarmed), the
    /// second arms.
    #[test]
    fn reset_from_stopped_then_arm() {
        let (mut cl, mut d) = (loop_(), RecordingDriver::default());
        let mut b = ArmingButton::new(N).unwrap();
        cl.stop(&mut d);
        assert_eq!(cl.state(), RunState::Stopped(StopReason::Commanded));
        assert_eq!(
            hold(&mut b, N as u32, &mut cl, &mut d),
            [(N as u32 - 1, ArmingEvent::Reset)]
        );
        assert_eq!(cl.state(), RunState::Disarmed);
        assert!(!d.enabled);
        assert_eq!(
            hold(&mut b, N as u32, &mut cl, &mut d),
            [(N as u32 - 1, ArmingEvent::Armed)]
        );
        assert_eq!(cl.state(), RunState::Running);
    }

    #[test]
    fn zero_debounce_rejected() {
        assert_eq!(
            ArmingButton::new(0).err(),
            Some(RuntimeConfigError::InvalidDebounce)
        );
        assert!(ArmingButton::new(1).is_ok());
    }
}
