//! Host tests of the device handler with scripted hardware: every request
//! in every state, random and corrupted bytes. Invariants checked after
//! every tick: no panic; motors disabled unless running; never running
//! without a mode; a latched stop is left only through a clear; every
//! intact request answered exactly once.

use controller_core::runtime::{NoGyro, RuntimeConfig, TickTiming, WheelOdometryOnly};
use controller_core::ControllerKind;
use proptest::prelude::*;
use sim_robot::test_doubles::{RecordingDriver, ScriptedEncoder};
use wmr_device::{Device, DeviceConfig, LinkConfig};
use wmr_protocol::*;

/// Control period of the tests \[µs\].
const PERIOD_US: u32 = 1000;

struct Rig {
    dev: Device,
    enc: [ScriptedEncoder; 2],
    drv: RecordingDriver,
    now_us: u32,
    rx: FrameDecoder<MAX_FRAME>,
    replies: Vec<Reply>,
}

fn device_config() -> DeviceConfig {
    DeviceConfig {
        chip: "test",
        capabilities: CAP_TRAJECTORY | CAP_VELOCITY | CAP_EXTERNAL_POSE,
        link: LinkConfig::DEFAULT,
        button_reference: None,
    }
}

impl Rig {
    fn new() -> Self {
        let mut rt = RuntimeConfig::example(ControllerKind::Proposed);
        // The scripted encoders never move: no stall detection in these
        // tests (the closed-loop ones in hil-sim run it).
        rt.safety.stall_ticks = u16::MAX;
        // Nor the governor: a robot that never moves would hold its
        // reference back (tested with the governor in controller-core and
        // end to end in hil-sim's link tests).
        rt.pacing = controller_core::pacer::PacingConfig::off();
        Self {
            dev: Device::new(device_config(), rt).unwrap(),
            enc: [ScriptedEncoder(0); 2],
            drv: RecordingDriver::default(),
            now_us: 0,
            rx: FrameDecoder::new(),
            replies: Vec::new(),
        }
    }

    fn tick(&mut self) {
        self.now_us = self.now_us.wrapping_add(1000);
        let before = self.dev.state();
        let rep = self.dev.tick(
            self.now_us,
            &mut self.enc,
            &mut self.drv,
            &mut NoGyro,
            &mut WheelOdometryOnly,
            TickTiming::on_schedule_at(self.now_us, PERIOD_US),
        );
        let after = self.dev.state();
        // Invariants.
        let moving = matches!(after, RunStateMsg::Running | RunStateMsg::Stopping);
        if !moving {
            assert!(!self.drv.enabled, "motors enabled in {after:?}");
            assert_eq!(rep.torque_nm, [0.0; 2]);
        }
        if moving {
            assert_ne!(self.dev.mode(), ModeMsg::None, "running without a mode");
        }
        if before == RunStateMsg::Stopped {
            assert!(
                matches!(after, RunStateMsg::Stopped | RunStateMsg::Hold),
                "left a latched stop to {after:?}"
            );
        }
        assert!(rep.torque_nm.iter().all(|t| t.is_finite()));
        let mut buf = [0u8; 4096];
        loop {
            let n = self.dev.pop_tx(&mut buf);
            if n == 0 {
                break;
            }
            let mut rest = &buf[..n];
            while !rest.is_empty() {
                let (d, r) = self.rx.feed::<Reply>(rest);
                rest = r;
                match d {
                    Some(Decoded::Frame { msg, .. }) => self.replies.push(msg),
                    None => {}
                    Some(other) => panic!("device sent a bad frame: {other:?}"),
                }
            }
        }
    }

    fn send_raw(&mut self, bytes: &[u8]) {
        assert_eq!(self.dev.push_rx(bytes), bytes.len());
    }

    /// Pushes `bytes` at the link's pace: one receive budget per tick.
    fn feed(&mut self, bytes: &[u8]) {
        for c in bytes.chunks(wmr_device::RX_BYTES_PER_TICK) {
            self.send_raw(c);
            self.tick();
        }
    }

    fn send(&mut self, req: &Request, seq: u16) {
        let mut buf = [0u8; MAX_FRAME];
        let f = encode(req, seq, &mut buf).unwrap().to_vec();
        self.send_raw(&f);
    }

    /// Sends and ticks until the answer to `seq` arrives.
    fn request(&mut self, req: &Request, seq: u16) -> Reply {
        self.replies.clear();
        self.send(req, seq);
        for _ in 0..10 {
            self.tick();
            if let Some(r) = self.replies.iter().find(|r| r.seq() == Some(seq)) {
                return r.clone();
            }
        }
        panic!("no answer to {req:?}");
    }
}

fn nack(r: &Reply) -> Option<ErrorCode> {
    match r {
        Reply::Nack { error, .. } => Some(*error),
        _ => None,
    }
}

fn circle() -> Request {
    Request::SetReference(BuiltinReference {
        shape: BuiltinShape::Circle {
            radius_m: 1.0,
            speed_mps: 0.3,
        },
        start: None,
        speed_scale: 1.0,
    })
}

#[test]
fn boots_in_hold_and_refuses_to_arm_without_a_mode() {
    let mut rig = Rig::new();
    rig.tick();
    assert_eq!(rig.dev.state(), RunStateMsg::Hold);
    assert_eq!(
        nack(&rig.request(&Request::Arm, 1)),
        Some(ErrorCode::NoReference)
    );
    assert!(!rig.drv.enabled);
    assert_eq!(rig.request(&circle(), 2), Reply::Ack { seq: 2 });
    assert_eq!(rig.request(&Request::Arm, 3), Reply::Ack { seq: 3 });
    assert_eq!(rig.dev.state(), RunStateMsg::Running);
    assert!(rig.drv.enabled);
}

#[test]
fn hello_reports_version_and_robot() {
    let mut rig = Rig::new();
    match rig.request(
        &Request::Hello {
            version: PROTOCOL_VERSION,
        },
        9,
    ) {
        Reply::Hello {
            version,
            chip,
            robot,
            ..
        } => {
            assert_eq!(version, PROTOCOL_VERSION);
            assert_eq!(chip.as_str(), "test");
            assert_eq!(robot.wheel_radius_m, 0.1);
        }
        r => panic!("{r:?}"),
    }
    // Another version: the hello is still answered (with ours), anything
    // else is refused.
    let mut buf = [0u8; MAX_FRAME];
    let f = encode_with_version(&Request::Hello { version: 7 }, 4, 7, &mut buf)
        .unwrap()
        .to_vec();
    rig.send_raw(&f);
    rig.tick();
    assert!(matches!(
        rig.replies.last(),
        Some(Reply::Hello {
            seq: 4,
            version: PROTOCOL_VERSION,
            ..
        })
    ));
    let f = encode_with_version(&Request::Arm, 5, 7, &mut buf)
        .unwrap()
        .to_vec();
    rig.send_raw(&f);
    rig.tick();
    assert_eq!(
        rig.replies.last(),
        Some(&Reply::Nack {
            seq: 5,
            error: ErrorCode::VersionMismatch
        })
    );
}

#[test]
fn estop_is_zero_torque_on_the_tick_that_reads_it_and_latches() {
    let mut rig = Rig::new();
    rig.request(&circle(), 1);
    rig.request(&Request::Arm, 2);
    for _ in 0..5 {
        rig.tick();
    }
    assert!(rig.drv.enabled);
    rig.send(&Request::EmergencyStop, 3);
    rig.tick();
    assert!(!rig.drv.enabled);
    assert_eq!(rig.dev.state(), RunStateMsg::Stopped);
    assert_eq!(
        nack(&rig.request(&Request::Arm, 4)),
        Some(ErrorCode::Latched)
    );
    assert_eq!(rig.request(&Request::ClearStop, 5), Reply::Ack { seq: 5 });
    assert_eq!(rig.dev.state(), RunStateMsg::Hold);
    assert_eq!(rig.request(&Request::Arm, 6), Reply::Ack { seq: 6 });
}

#[test]
fn configuration_only_in_hold() {
    let mut rig = Rig::new();
    let set = |v| Request::SetParam {
        id: ParamId::TorqueLimitNm,
        value: v,
    };
    assert_eq!(rig.request(&set(5.0), 1), Reply::Ack { seq: 1 });
    assert_eq!(
        nack(&rig.request(&set(-1.0), 2)),
        Some(ErrorCode::InvalidValue)
    );
    assert_eq!(
        nack(&rig.request(&set(f32::NAN), 3)),
        Some(ErrorCode::InvalidValue)
    );
    assert_eq!(
        nack(&rig.request(
            &Request::SetParam {
                id: ParamId::ControlPeriodS,
                value: 0.002
            },
            4
        )),
        Some(ErrorCode::ReadOnly)
    );
    rig.request(&circle(), 5);
    rig.request(&Request::Arm, 6);
    assert_eq!(nack(&rig.request(&set(4.0), 7)), Some(ErrorCode::Busy));
    assert_eq!(nack(&rig.request(&circle(), 8)), Some(ErrorCode::Busy));
    assert_eq!(
        rig.request(&Request::GetParam(ParamId::TorqueLimitNm), 9),
        Reply::Param {
            seq: 9,
            id: ParamId::TorqueLimitNm,
            value: 5.0
        }
    );
    // Telemetry rate: any state.
    assert_eq!(
        rig.request(
            &Request::SetParam {
                id: ParamId::TelemetryRateHz,
                value: 50.0
            },
            10
        ),
        Reply::Ack { seq: 10 }
    );
}

#[test]
fn link_silence_while_running_brakes_then_holds() {
    let mut rig = Rig::new();
    rig.request(&circle(), 1);
    rig.request(&Request::Arm, 2);
    let timeout_ticks = LinkConfig::DEFAULT.link_timeout_ms as usize;
    let mut stopping_at = None;
    for k in 0..timeout_ticks + 2000 {
        rig.tick();
        if stopping_at.is_none() && rig.dev.state() != RunStateMsg::Running {
            stopping_at = Some(k);
        }
        if rig.dev.state() == RunStateMsg::Hold {
            break;
        }
    }
    let k = stopping_at.expect("never stopped");
    assert!(k <= timeout_ticks + 1, "braking began at tick {k}");
    assert_eq!(rig.dev.state(), RunStateMsg::Hold);
    assert!(rig.replies.contains(&Reply::Event(Event::LinkLost)));
    assert!(rig.replies.contains(&Reply::Event(Event::StateChanged {
        state: RunStateMsg::Hold,
        cause: Some(StopCode::LinkSilence)
    })));
}

#[test]
fn velocity_command_expires_and_the_robot_disarms() {
    let mut rig = Rig::new();
    let v = Request::Velocity {
        v_mps: 0.2,
        omega_radps: 0.0,
        timeout_ms: 100,
    };
    rig.request(&v, 1);
    rig.request(&Request::Arm, 2);
    assert_eq!(rig.dev.state(), RunStateMsg::Running);
    let mut ticks = 0;
    // Keep the link alive with status requests (no velocity refresh).
    while rig.dev.state() != RunStateMsg::Hold {
        if ticks % 50 == 0 {
            rig.send(&Request::GetStatus, 3);
        }
        rig.tick();
        ticks += 1;
        assert!(ticks < 1000, "still {:?}", rig.dev.state());
    }
    // 100 ms timeout, then at most 0.2 m/s / 1 m/s² = 200 ms of braking.
    assert!(ticks <= 100 + 200 + 5, "{ticks} ticks");
    assert!(rig.replies.contains(&Reply::Event(Event::StateChanged {
        state: RunStateMsg::Hold,
        cause: Some(StopCode::VelocityTimeout)
    })));
    let too_fast = Request::Velocity {
        v_mps: 5.0,
        omega_radps: 0.0,
        timeout_ms: 100,
    };
    assert_eq!(
        nack(&rig.request(&too_fast, 4)),
        Some(ErrorCode::InvalidValue)
    );
}

#[test]
fn trajectory_upload_streams_and_refuses_out_of_order() {
    let mut rig = Rig::new();
    assert_eq!(
        rig.request(&Request::TrajectoryBegin { total_points: 100 }, 1),
        Reply::Ack { seq: 1 }
    );
    let wp = |i: u32| Waypoint {
        t_s: i as f32 * 0.1,
        pose: PoseMsg {
            x_m: i as f32 * 0.01,
            y_m: 0.0,
            theta_rad: 0.0,
        },
        v_mps: 0.1,
        omega_radps: 0.0,
    };
    let seg = |first: u32, n: u32| Request::TrajectorySegment {
        first_index: first,
        points: (first..first + n).map(wp).collect(),
    };
    assert_eq!(
        nack(&rig.request(&seg(8, 8), 2)),
        Some(ErrorCode::OutOfOrder)
    );
    let mut next = 0;
    for s in 0..8u16 {
        match rig.request(&seg(next, 8), 10 + s) {
            Reply::TrajectoryAck {
                next_index, free, ..
            } => {
                next = next_index;
                assert_eq!(free as u32, 64 - next);
            }
            r => panic!("{r:?}"),
        }
    }
    assert_eq!(next, 64);
    assert_eq!(
        nack(&rig.request(&seg(64, 8), 30)),
        Some(ErrorCode::BufferFull)
    );
    assert_eq!(rig.dev.mode(), ModeMsg::Trajectory);
    rig.request(&Request::Arm, 31);
    // After 2 s of running, 20 waypoints have passed: room for more.
    for k in 0..2000 {
        if k % 100 == 0 {
            rig.send(&Request::GetStatus, 32);
        }
        rig.tick();
    }
    let r = rig.request(&seg(64, 8), 33);
    assert!(
        matches!(r, Reply::TrajectoryAck { next_index: 72, .. }),
        "{r:?} state {:?} tau {}",
        rig.dev.state(),
        rig.dev.control().reference_time_s()
    );
}

#[test]
fn garbage_is_counted_and_answered_with_frame_errors() {
    let mut rig = Rig::new();
    rig.send_raw(&[1, 2, 3, 0, 0x55, 0x66, 0]);
    rig.tick();
    rig.send_raw(&[9, 0]);
    rig.tick();
    let c = rig.dev.counters();
    assert_eq!(c.rx_errors, 3);
    // Every dropped frame counted, at most one frame error answered per tick.
    assert_eq!(
        rig.replies
            .iter()
            .filter(|r| matches!(r, Reply::FrameError { .. }))
            .count(),
        2
    );
}

fn any_request() -> impl Strategy<Value = Request> {
    let f = prop_oneof![
        Just(0.5f32),
        Just(-0.3),
        Just(f32::NAN),
        Just(1e9),
        -2.0f32..2.0
    ];
    let pose = (f.clone(), f.clone(), f.clone()).prop_map(|(x, y, t)| PoseMsg {
        x_m: x,
        y_m: y,
        theta_rad: t,
    });
    let param = prop::sample::select(ParamId::ALL.to_vec());
    prop_oneof![
        Just(Request::Hello { version: 1 }),
        Just(Request::GetStatus),
        Just(Request::Arm),
        Just(Request::Arm),
        Just(Request::Disarm),
        Just(Request::EmergencyStop),
        Just(Request::ClearStop),
        pose.clone().prop_map(Request::SetPose),
        (any::<u32>(), pose.clone()).prop_map(|(t, p)| Request::ExternalPose {
            t_robot_us: t,
            pose: p,
            std_dev: [0.01; 3]
        }),
        any::<u64>().prop_map(|h| Request::ClockSync { host_time_us: h }),
        (f.clone(), f.clone(), prop::option::of(pose.clone())).prop_map(|(a, s, start)| {
            Request::SetReference(BuiltinReference {
                shape: BuiltinShape::Circle {
                    radius_m: a,
                    speed_mps: 0.3,
                },
                start,
                speed_scale: s,
            })
        }),
        (0u32..20).prop_map(|n| Request::TrajectoryBegin { total_points: n }),
        (0u32..20, 0usize..=8, f.clone()).prop_map(|(first, n, v)| {
            Request::TrajectorySegment {
                first_index: first,
                points: (0..n)
                    .map(|i| Waypoint {
                        t_s: (first as usize + i) as f32 * 0.05,
                        pose: PoseMsg::default(),
                        v_mps: v,
                        omega_radps: 0.0,
                    })
                    .collect(),
            }
        }),
        (f.clone(), f.clone(), 0u16..200).prop_map(|(v, w, t)| Request::Velocity {
            v_mps: v,
            omega_radps: w,
            timeout_ms: t
        }),
        param.clone().prop_map(Request::GetParam),
        (param, f).prop_map(|(id, value)| Request::SetParam { id, value }),
        (any::<u8>(), 0u16..2000).prop_map(|(s, r)| Request::SetTelemetry {
            selection: s,
            rate_hz: r
        }),
    ]
}

/// What goes on the wire in one step of a random session.
#[derive(Clone, Debug)]
enum Wire {
    Request(Request),
    Garbage(Vec<u8>),
    /// A valid frame with one byte changed.
    Corrupt(Request, usize, u8),
    Truncated(Request, usize),
    Oversized(usize),
    WrongVersion(Request, u16),
    Idle(u8),
}

fn any_wire() -> impl Strategy<Value = Wire> {
    prop_oneof![
        6 => any_request().prop_map(Wire::Request),
        1 => proptest::collection::vec(any::<u8>(), 0..300).prop_map(Wire::Garbage),
        1 => (any_request(), any::<usize>(), 1u8..=255).prop_map(|(r, i, x)| Wire::Corrupt(r, i, x)),
        1 => (any_request(), any::<usize>()).prop_map(|(r, i)| Wire::Truncated(r, i)),
        1 => (MAX_FRAME..3 * MAX_FRAME).prop_map(Wire::Oversized),
        1 => (any_request(), 2u16..100).prop_map(|(r, v)| Wire::WrongVersion(r, v)),
        2 => any::<u8>().prop_map(Wire::Idle),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Random sessions: every request kind in every state reached, mixed
    /// with garbage, corrupted, truncated, oversized and wrong-version
    /// frames. The invariants in `Rig::tick` hold on every tick; every
    /// intact request gets exactly one answer; every dropped frame is
    /// counted.
    #[test]
    fn random_sessions_keep_the_invariants(session in proptest::collection::vec(any_wire(), 1..60)) {
        let mut rig = Rig::new();
        let mut seq = 0u16;
        let mut intact = Vec::new();
        for w in session {
            let mut buf = [0u8; MAX_FRAME];
            match w {
                Wire::Request(r) => {
                    seq += 1;
                    intact.push(seq);
                    let f = encode(&r, seq, &mut buf).unwrap().to_vec();
                    rig.feed(&f);
                }
                Wire::Garbage(mut g) => { g.push(0); rig.feed(&g); }
                Wire::Corrupt(r, i, x) => {
                    let f = encode(&r, 60000, &mut buf).unwrap();
                    let n = f.len() - 1;
                    f[i % n] ^= x;
                    let f = f.to_vec();
                    rig.feed(&f);
                }
                Wire::Truncated(r, i) => {
                    let f = encode(&r, 60001, &mut buf).unwrap();
                    let n = f.len() - 1;
                    let mut t = f[..i % n].to_vec();
                    t.push(0);
                    rig.feed(&t);
                }
                Wire::Oversized(n) => {
                    let mut t = vec![7u8; n];
                    t.push(0);
                    rig.feed(&t);
                }
                Wire::WrongVersion(r, v) => {
                    seq += 1;
                    intact.push(seq);
                    let f = encode_with_version(&r, seq, v, &mut buf).unwrap().to_vec();
                    rig.feed(&f);
                }
                Wire::Idle(n) => for _ in 0..n { rig.tick(); },
            }
            for _ in 0..4 { rig.tick(); }
        }
        for _ in 0..20 { rig.tick(); }
        let c = rig.dev.counters();
        prop_assert_eq!(c.rx_overflow, 0);
        prop_assert_eq!(c.tx_dropped, 0);
        for s in intact {
            let answers = rig.replies.iter().filter(|r| r.seq() == Some(s)).count();
            prop_assert_eq!(answers, 1, "seq {} answered {} times", s, answers);
        }
    }
}

/// One request of every kind (valid where the state allows it).
fn one_of_each() -> Vec<Request> {
    vec![
        Request::Hello { version: 1 },
        Request::GetStatus,
        Request::Arm,
        Request::Disarm,
        Request::EmergencyStop,
        Request::ClearStop,
        Request::SetPose(PoseMsg::default()),
        Request::ExternalPose {
            t_robot_us: 0,
            pose: PoseMsg::default(),
            std_dev: [0.01; 3],
        },
        Request::ClockSync { host_time_us: 5 },
        circle(),
        Request::TrajectoryBegin { total_points: 2 },
        Request::TrajectorySegment {
            first_index: 0,
            points: heapless::Vec::new(),
        },
        Request::Velocity {
            v_mps: 0.1,
            omega_radps: 0.0,
            timeout_ms: 100,
        },
        Request::GetParam(ParamId::Ky),
        Request::SetParam {
            id: ParamId::Ky,
            value: 20.0,
        },
        Request::SetTelemetry {
            selection: TELEMETRY_ALL,
            rate_hz: 10,
        },
    ]
}

/// Brings a fresh rig into `state`.
fn rig_in(state: RunStateMsg) -> Rig {
    let mut rig = Rig::new();
    match state {
        RunStateMsg::Hold => {}
        RunStateMsg::Running => {
            rig.request(&circle(), 1000);
            rig.request(&Request::Arm, 1001);
        }
        RunStateMsg::Stopping => {
            rig.request(&circle(), 1000);
            rig.request(&Request::Arm, 1001);
            while rig.dev.state() != RunStateMsg::Stopping {
                rig.tick(); // link silence
            }
        }
        RunStateMsg::Stopped => {
            rig.request(&circle(), 1000);
            rig.request(&Request::Arm, 1001);
            rig.request(&Request::EmergencyStop, 1002);
        }
    }
    assert_eq!(rig.dev.state(), state);
    rig
}

/// Every kind of request in every state: exactly one answer, the
/// invariants of `Rig::tick` on every tick, and the state rules: arming
/// only from hold with a mode, configuration refused while moving, a latched
/// stop left only through a clear.
#[test]
fn every_request_in_every_state() {
    let reqs = one_of_each();
    assert_eq!(reqs.len(), 16, "one of each Request variant");
    for state in [
        RunStateMsg::Hold,
        RunStateMsg::Running,
        RunStateMsg::Stopping,
        RunStateMsg::Stopped,
    ] {
        for (i, req) in reqs.iter().enumerate() {
            let mut rig = rig_in(state);
            let seq = 2000 + i as u16;
            let answer = rig.request(req, seq);
            let refused = nack(&answer);
            let after = rig.dev.state();
            match (state, req) {
                (RunStateMsg::Hold, Request::Arm) => {
                    assert_eq!(refused, Some(ErrorCode::NoReference))
                }
                (RunStateMsg::Stopped, Request::Arm) => {
                    assert_eq!(refused, Some(ErrorCode::Latched))
                }
                (RunStateMsg::Stopping, Request::Arm) => {
                    assert_eq!(refused, Some(ErrorCode::Busy))
                }
                (RunStateMsg::Running | RunStateMsg::Stopping, Request::SetParam { .. })
                | (RunStateMsg::Running | RunStateMsg::Stopping, Request::SetPose(_))
                | (RunStateMsg::Running | RunStateMsg::Stopping, Request::SetReference(_))
                | (RunStateMsg::Running | RunStateMsg::Stopping, Request::TrajectoryBegin { .. }) =>
                {
                    assert_eq!(refused, Some(ErrorCode::Busy), "{state:?} {req:?}")
                }
                (_, Request::EmergencyStop) => {
                    assert_eq!(refused, None);
                    assert_eq!(after, RunStateMsg::Stopped);
                }
                (RunStateMsg::Stopped, Request::ClearStop) => {
                    assert_eq!(refused, None);
                    assert_eq!(after, RunStateMsg::Hold);
                }
                (_, Request::Disarm) => {
                    assert_eq!(refused, None);
                    assert!(matches!(after, RunStateMsg::Hold | RunStateMsg::Stopped));
                }
                _ => {}
            }
            if state == RunStateMsg::Stopped && !matches!(req, Request::ClearStop) {
                assert_eq!(after, RunStateMsg::Stopped, "{req:?} left the latched stop");
            }
            if state == RunStateMsg::Hold && !matches!(req, Request::Arm) {
                assert!(
                    !matches!(after, RunStateMsg::Running | RunStateMsg::Stopping),
                    "{req:?} moved the robot"
                );
            }
        }
    }
}
