//! The commissioning wheel test (issue 18) on the device with a scripted
//! shaft: each wheel's raw encoder follows its own bridge's signed duty
//! (motor and encoder on one shaft), so the inversion flags of the example
//! robot (left motor and encoder mirrored) must cancel. Checked: refusals
//! with their codes, only the asked wheel driven, in the asked direction,
//! every end (time up, another request, link silence, a latched stop,
//! the button) turning the motors off on that tick, within its bound.

mod common;

use common::{device_config, drain, frame, nack, quiet_runtime, PERIOD_US};
use controller_core::runtime::{DutyCommand, NoGyro, RuntimeConfig, TickTiming, WheelOdometryOnly};
use controller_core::ControllerKind;
use sim_robot::test_doubles::{RecordingDriver, ScriptedEncoder};
use wmr_device::wheel_test::torque_cap_nm;
use wmr_device::Device;
use wmr_protocol::*;

struct Rig {
    dev: Device,
    enc: [ScriptedEncoder; 2],
    drv: RecordingDriver,
    now_us: u32,
    rx: FrameDecoder<MAX_FRAME>,
    replies: Vec<Reply>,
    /// Raw counts per tick per full-scale duty (the scripted shaft).
    jump: Option<u16>,
    cap_nm: f32,
}

impl Rig {
    fn new() -> Self {
        let rt = quiet_runtime();
        let cap_nm = torque_cap_nm(&rt);
        Self {
            dev: Device::new(device_config(CAP_VELOCITY), rt).unwrap(),
            enc: [ScriptedEncoder(0); 2],
            drv: RecordingDriver::default(),
            now_us: 0,
            rx: FrameDecoder::new(),
            replies: Vec::new(),
            jump: None,
            cap_nm,
        }
    }

    fn tick(&mut self) {
        // The shaft: this tick's raw count follows what the bridge was
        // driven with since the last tick (5 counts per tick when driven).
        for i in 0..2 {
            let s = self.drv.duty[i].signed().signum() as i16 * 5;
            self.enc[i].0 = self.enc[i].0.wrapping_add_signed(s);
        }
        if let Some(j) = self.jump.take() {
            self.enc[0].0 = self.enc[0].0.wrapping_add(j);
        }
        self.now_us = self.now_us.wrapping_add(PERIOD_US);
        self.dev.tick(
            self.now_us,
            &mut self.enc,
            &mut self.drv,
            &mut NoGyro,
            &mut WheelOdometryOnly,
            TickTiming::on_schedule_at(self.now_us, PERIOD_US),
        );
        let replies = &mut self.replies;
        drain(&mut self.dev, &mut self.rx, |d| {
            if let Decoded::Frame { msg, .. } = d {
                replies.push(msg);
            }
        });
    }

    fn send(&mut self, req: &Request, seq: u16) {
        let f = frame(req, seq);
        assert_eq!(self.dev.push_rx(&f), f.len());
    }

    fn answer(&mut self, req: &Request, seq: u16) -> Reply {
        self.replies.clear();
        self.send(req, seq);
        self.tick();
        self.replies
            .iter()
            .find(|r| r.seq() == Some(seq))
            .cloned()
            .expect("no answer")
    }

    fn done(&self) -> Option<WheelTestResult> {
        self.replies.iter().find_map(|r| match r {
            Reply::WheelTestDone { result, .. } => Some(*result),
            _ => None,
        })
    }
}

fn test(wheel: u8, torque_nm: f32, duration_ms: u16) -> Request {
    Request::WheelTest(WheelTestCmd {
        wheel,
        torque_nm,
        duration_ms,
    })
}

#[test]
fn cap_is_the_torque_limit_and_below_stall_at_the_duty_limit() {
    let rt = RuntimeConfig::example(ControllerKind::Proposed);
    let m = rt.motor;
    // Stall torque at the wheel: k_t · I_stall · G · η, I_stall = V·d/R.
    let stall = m.torque_constant_nm_per_a * (m.supply_voltage_v * m.max_duty_fraction)
        / m.winding_resistance_ohm
        * m.gear_ratio
        * m.gear_efficiency;
    let cap = torque_cap_nm(&rt);
    assert!(cap <= stall * 1.0001 && cap <= rt.controller.torque_limit_nm);
    assert!(cap > 0.0);
    // The torque limit itself when stall is above it (D170: a fifth of
    // stall was below small gearboxes' friction).
    let near = |a: f32, b: f32| (a - b).abs() <= 1e-5 * b;
    assert!(near(cap, rt.controller.torque_limit_nm.min(stall)), "{cap}");
    let mut low = rt;
    low.controller.torque_limit_nm = 0.5 * stall;
    assert!(near(torque_cap_nm(&low), 0.5 * stall));
    low.controller.torque_limit_nm = 2.0 * stall;
    assert!(near(torque_cap_nm(&low), stall));
}

#[test]
fn bad_tests_are_refused_with_their_code_and_nothing_moves() {
    let mut r = Rig::new();
    let cap = r.cap_nm;
    for (req, code) in [
        (test(2, 0.1 * cap, 100), ErrorCode::InvalidValue),
        (test(0, 0.0, 100), ErrorCode::InvalidValue),
        (test(0, f32::NAN, 100), ErrorCode::InvalidValue),
        (test(0, 0.5 * cap, 0), ErrorCode::InvalidValue),
        (
            test(0, 0.5 * cap, WHEEL_TEST_MAX_MS + 1),
            ErrorCode::InvalidValue,
        ),
        (test(0, 1.01 * cap, 100), ErrorCode::AboveTestCap),
        (test(1, -1.01 * cap, 100), ErrorCode::AboveTestCap),
    ] {
        let a = r.answer(&req, 7);
        assert_eq!(nack(&a), Some(code), "{req:?}");
        assert!(!r.drv.enabled);
        assert_eq!(r.drv.sets, 0);
    }
}

#[test]
fn refused_while_running_and_while_latched() {
    let mut r = Rig::new();
    let v = Request::Velocity {
        v_mps: 0.0,
        omega_radps: 0.0,
        timeout_ms: 1000,
    };
    assert_eq!(r.answer(&v, 1), Reply::Ack { seq: 1 });
    assert_eq!(r.answer(&Request::Arm, 2), Reply::Ack { seq: 2 });
    assert_eq!(r.dev.state(), RunStateMsg::Running);
    let a = r.answer(&test(0, 0.5 * r.cap_nm, 100), 3);
    assert_eq!(nack(&a), Some(ErrorCode::Busy));
    r.answer(&Request::EmergencyStop, 4);
    assert_eq!(r.dev.state(), RunStateMsg::Stopped);
    let a = r.answer(&test(0, 0.5 * r.cap_nm, 100), 5);
    assert_eq!(nack(&a), Some(ErrorCode::Latched));
    assert!(!r.drv.enabled);
}

#[test]
fn each_wheel_each_direction_drives_only_that_wheel_and_ends_itself() {
    for wheel in [0u8, 1] {
        for sign in [1.0f32, -1.0] {
            let mut r = Rig::new();
            let torque = sign * 0.5 * r.cap_nm;
            assert_eq!(
                r.answer(&test(wheel, torque, 100), 9),
                Reply::Ack { seq: 9 }
            );
            let w = wheel as usize;
            let mut ticks = 0;
            while r.done().is_none() {
                // Host keeps the link alive with reads (they do not end it).
                if ticks % 50 == 0 {
                    r.send(&Request::GetStatus, 100);
                }
                assert!(r.drv.enabled, "motors off during the test at tick {ticks}");
                assert_ne!(r.drv.duty[w].duty, 0);
                assert_eq!(r.drv.duty[1 - w], DutyCommand::ZERO);
                r.tick();
                ticks += 1;
                assert!(ticks <= 102, "test ran past its 100 ms");
            }
            let res = r.done().unwrap();
            assert!(!r.drv.enabled, "motors on after the end");
            assert_eq!(res.end, WheelTestEnd::Completed);
            assert_eq!(res.wheel, wheel);
            assert!((99..=101).contains(&res.ticks), "{}", res.ticks);
            // Forward after the flags: the mirrored left's motor and
            // encoder flags cancel on the scripted shaft.
            assert!(res.counts[w] as f32 * sign > 400.0, "{res:?}");
            assert_eq!(res.counts[1 - w], 0);
            assert_eq!(res.gyro_yaw_rad, None);
            // The bridge of the mirrored left wheel is driven reversed
            // for a forward torque.
            let bridge_forward = res.duty > 0;
            assert_eq!(bridge_forward, (sign > 0.0) != (wheel == 1), "{res:?}");
            // Nothing drives afterwards.
            for _ in 0..10 {
                r.tick();
                assert!(!r.drv.enabled);
            }
        }
    }
}

#[test]
fn another_command_link_silence_a_stop_and_the_button_end_it_on_that_tick() {
    // Another request.
    let mut r = Rig::new();
    r.answer(&test(0, 0.5 * r.cap_nm, 2000), 1);
    r.tick();
    assert!(r.drv.enabled);
    r.answer(&Request::Disarm, 2);
    assert!(!r.drv.enabled);
    assert_eq!(r.done().unwrap().end, WheelTestEnd::Command);

    // Link silence: the default link timeout is 500 ms.
    let mut r = Rig::new();
    r.answer(&test(1, -0.5 * r.cap_nm, 2000), 1);
    let mut ticks = 0;
    while r.done().is_none() {
        r.tick();
        ticks += 1;
        assert!(ticks <= 502);
    }
    assert!(ticks >= 499, "{ticks}");
    assert!(!r.drv.enabled);
    assert_eq!(r.done().unwrap().end, WheelTestEnd::LinkLost);

    // An encoder jump beyond the runtime's limit ends it, motors off.
    let mut r = Rig::new();
    r.answer(&test(0, 0.5 * r.cap_nm, 2000), 1);
    r.tick();
    r.jump = Some(20_000);
    r.tick();
    assert!(!r.drv.enabled);
    assert_eq!(r.done().unwrap().end, WheelTestEnd::EncoderJump);

    // The button.
    let mut r = Rig::new();
    r.answer(&test(0, 0.5 * r.cap_nm, 2000), 1);
    r.tick();
    r.replies.clear();
    r.dev.button_pressed(&mut r.drv);
    assert!(!r.drv.enabled);
    assert_eq!(
        r.dev.state(),
        RunStateMsg::Hold,
        "the press only ends the test"
    );
    r.tick();
    assert_eq!(r.done().unwrap().end, WheelTestEnd::Command);
    assert!(!r.drv.enabled);
}
