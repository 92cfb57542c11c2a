//! Host tests of the device handler with scripted hardware: every request
//! in every state, random and corrupted bytes. Invariants checked after
//! every tick: no panic; motors disabled unless running; never running
//! without a mode; a latched stop is left only through a clear; every
//! intact request answered exactly once.

mod common;

use common::{device_config, drain, frame, nack, quiet_runtime, PERIOD_US};
use controller_core::runtime::{NoGyro, TickTiming, WheelOdometryOnly};
use proptest::prelude::*;
use sim_robot::test_doubles::{RecordingDriver, ScriptedEncoder};
use wmr_device::{Device, LinkConfig};
use wmr_protocol::*;

struct Rig {
    dev: Device,
    enc: [ScriptedEncoder; 2],
    drv: RecordingDriver,
    now_us: u32,
    rx: FrameDecoder<MAX_FRAME>,
    replies: Vec<Reply>,
    /// v of the last tick's reference \[m/s\].
    last_ref_v: f32,
}

impl Rig {
    fn new() -> Self {
        Self::with(
            Device::new(
                device_config(CAP_TRAJECTORY | CAP_VELOCITY | CAP_EXTERNAL_POSE),
                quiet_runtime(),
            )
            .unwrap(),
        )
    }

    fn with(dev: Device) -> Self {
        Self {
            dev,
            enc: [ScriptedEncoder(0); 2],
            drv: RecordingDriver::default(),
            now_us: 0,
            rx: FrameDecoder::new(),
            replies: Vec::new(),
            last_ref_v: 0.0,
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
        self.last_ref_v = rep.reference.v_mps;
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
        let replies = &mut self.replies;
        drain(&mut self.dev, &mut self.rx, |d| match d {
            Decoded::Frame { msg, .. } => replies.push(msg),
            other => panic!("device sent a bad frame: {other:?}"),
        });
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
        self.send_raw(&frame(req, seq));
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

/// The board's report (reset cause, the port's losses) reaches the host in
/// the status reply as the board set it; unknown until it does.
#[test]
fn status_carries_the_board_report() {
    let mut rig = Rig::new();
    let Reply::Status { status, .. } = rig.request(&Request::GetStatus, 1) else {
        panic!("no status");
    };
    assert_eq!(status.board, wmr_protocol::BoardReport::default());
    assert_eq!(status.board.reset_cause, wmr_protocol::ResetCause::Unknown);
    let report = wmr_protocol::BoardReport {
        reset_cause: wmr_protocol::ResetCause::IndependentWatchdog,
        port_rx_dropped: 7,
        port_rx_errors: 3,
    };
    *rig.dev.board_report_mut() = report;
    let Reply::Status { status, .. } = rig.request(&Request::GetStatus, 2) else {
        panic!("no status");
    };
    assert_eq!(status.board, report);
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

/// A robot whose clock runs N times the host's (`set_host_clock(N·1000)`,
/// `hil-sim device --speed N`) counts the host's durations in the host's
/// time: the link timeout (500 ms) lasts N·500 robot ms, a velocity
/// command's timeout N times its robot ms, to the tick; N = 1 is the
/// default robot's. Before, the watchdog counted robot time and a host
/// keeping alive every fifth of the timeout on its wall clock was silent
/// for a whole timeout at N = 5 (issue 32).
#[test]
fn host_durations_count_the_hosts_clock() {
    for n in [1u32, 2, 5, 10] {
        let mut rig = Rig::new();
        rig.dev.set_host_clock(n * 1000);
        rig.request(&circle(), 1);
        rig.request(&Request::Arm, 2);
        let timeout_ticks = (LinkConfig::DEFAULT.link_timeout_ms * n) as usize;
        let mut k = 0;
        while rig.dev.state() == RunStateMsg::Running {
            rig.tick();
            k += 1;
            assert!(k < 2 * timeout_ticks + 10, "n = {n}: still running");
        }
        assert!(
            (timeout_ticks..=timeout_ticks + 1).contains(&k),
            "n = {n}: braking began at tick {k}, the timeout is {timeout_ticks}"
        );

        let mut rig = Rig::new();
        rig.dev.set_host_clock(n * 1000);
        let v = Request::Velocity {
            v_mps: 0.2,
            omega_radps: 0.0,
            timeout_ms: 40,
        };
        rig.request(&v, 1);
        rig.request(&Request::Arm, 2);
        // Expires 40·n ticks after the command's tick (the arm's request
        // took a tick or two of them).
        let mut k = 0;
        while rig.dev.state() == RunStateMsg::Running {
            rig.tick();
            k += 1;
            assert!(k < 10_000, "n = {n}: never expired");
        }
        let expiry = 40 * n as usize;
        assert!(
            (expiry - 5..=expiry + 1).contains(&k),
            "n = {n}: the velocity command expired after {k} ticks, its timeout {expiry}"
        );
    }
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
        Request::RobotBegin { total_len: 10 },
        Request::RobotChunk {
            offset: 0,
            data: heapless::Vec::new(),
        },
        Request::RobotCommit,
        Request::RobotRead { offset: 0 },
        Request::Reboot,
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
    assert_eq!(reqs.len(), 21, "one of each Request variant");
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
                // The robot record: hold only, and this rig has no store.
                (
                    RunStateMsg::Running | RunStateMsg::Stopping,
                    Request::RobotBegin { .. }
                    | Request::RobotChunk { .. }
                    | Request::RobotCommit
                    | Request::Reboot,
                ) => assert_eq!(refused, Some(ErrorCode::Busy), "{state:?} {req:?}"),
                (
                    RunStateMsg::Stopped,
                    Request::RobotBegin { .. }
                    | Request::RobotChunk { .. }
                    | Request::RobotCommit
                    | Request::Reboot,
                ) => assert_eq!(refused, Some(ErrorCode::Latched), "{req:?}"),
                (_, Request::RobotRead { .. })
                | (
                    RunStateMsg::Hold,
                    Request::RobotBegin { .. } | Request::RobotChunk { .. } | Request::RobotCommit,
                ) => assert_eq!(refused, Some(ErrorCode::NoStore), "{state:?} {req:?}"),
                (RunStateMsg::Hold, Request::Reboot) => {
                    assert_eq!(answer, Reply::Ack { seq });
                    assert!(rig.dev.reboot_requested());
                    let again = rig.request(&Request::Arm, 9999);
                    assert_eq!(
                        nack(&again),
                        Some(ErrorCode::Busy),
                        "armed before the reboot"
                    );
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

// ---- Issue 21: values that are valid but absurd -------------------------

/// Issue 21 item 1: a braking deceleration or angular acceleration so small
/// that a controlled stop would never end is refused, with the field named
/// at construction and `InvalidValue` over the link.
#[test]
fn braking_settings_below_the_physical_minimum_are_refused() {
    for id in [ParamId::BrakeDecelMps2, ParamId::AngAccelRadps2] {
        let mut rig = Rig::new();
        for value in [1e-45, 1e-3, 0.0, -1.0] {
            let r = rig.request(&Request::SetParam { id, value }, 1);
            assert_eq!(nack(&r), Some(ErrorCode::InvalidValue), "{id:?} = {value}");
        }
    }
    let slow = LinkConfig {
        brake_decel_mps2: 1e-45,
        ..LinkConfig::DEFAULT
    };
    let Err(wmr_device::DeviceConfigError::OutOfRange(e)) = slow.validate() else {
        panic!("{:?}", slow.validate())
    };
    assert_eq!(
        (e.field, e.value, e.limit()),
        ("brake_decel_mps2", 1e-45, 0.25)
    );
    let err = wmr_device::DeviceConfigError::OutOfRange(e).to_string();
    assert!(
        err.contains("brake_decel_mps2: 0.000000000000000000000000000000000000000000001 m/s² is below its limit 0.25 m/s²"),
        "{err}"
    );
}

/// Issue 31 item 1: each waypoint within the limits is not enough, the
/// curve between two can ask far more. The three uploads on the
/// paper robot (top speed 4 m/s, top yaw rate 20 rad/s), every waypoint at
/// rest or at a speed within the limits, are refused, the segment named:
/// waypoints 1 m apart 10 ms apart (149 m/s between them) and 1,000 m
/// apart 1 s apart (813 m/s... and 6 km/s² of acceleration) by the device
/// at upload, a ±0.1 m slalom every 0.2 s (72.7 rad/s) by the host's
/// check. The same trajectories slowed down enough are accepted.
#[test]
fn uploads_beyond_the_robots_limits_between_waypoints_are_refused() {
    use wmr_device::limits::{Quantity, RobotLimits};
    use wmr_device::reference::{check_segment, SegmentError, WaypointBuffer};
    let rig = Rig::new();
    let lim = RobotLimits::of(rig.dev.control().config());
    assert!((lim.top_speed_mps - 4.0).abs() < 1e-3 && (lim.top_yaw_rate_radps - 20.0).abs() < 1e-2);
    let wp = |t_s: f32, x_m: f32, y_m: f32, v_mps: f32| Waypoint {
        t_s,
        pose: PoseMsg {
            x_m,
            y_m,
            theta_rad: 0.0,
        },
        v_mps,
        omega_radps: 0.0,
    };
    // (waypoints, the quantity refused, the first segment refused)
    let hops = |dx: f32, dt: f32| {
        (0..8)
            .map(|i| wp(i as f32 * dt, (i % 2) as f32 * dx, 0.0, 0.0))
            .collect::<Vec<_>>()
    };
    let slalom = |dt: f32| {
        (0..8)
            .map(|i| {
                wp(
                    i as f32 * dt,
                    i as f32 * 0.2,
                    if i % 2 == 0 { 0.1 } else { -0.1 },
                    1.0,
                )
            })
            .collect::<Vec<_>>()
    };
    // The slalom's yaw rate is beyond what the device checks at upload
    // (speed and acceleration, within a tick's budget): the host's check
    // refuses it (`wmr upload --robot`), the device's per-tick check never
    // drives it (device_fuzz).
    let e = check_segment(&slalom(0.2)[0], &slalom(0.2)[1], &lim).unwrap_err();
    assert_eq!(e.quantity, Quantity::YawRateRadps, "{e:?}");
    assert!(e.value > e.limit, "{e:?}");
    for (what, points, quantity) in [
        ("1 m every 10 ms", hops(1.0, 0.01), Quantity::AccelMps2),
        ("1,000 m every 1 s", hops(1000.0, 1.0), Quantity::AccelMps2),
    ] {
        let mut buf = WaypointBuffer::default();
        buf.begin(8);
        match buf.push(0, &points, None, &lim) {
            Err(SegmentError::BeyondLimits { index, exceeded }) => {
                assert_eq!(index, 0, "{what}");
                assert_eq!(exceeded.quantity, quantity, "{what}: {exceeded:?}");
                assert!(exceeded.value > exceeded.limit, "{what}: {exceeded:?}");
            }
            other => panic!("{what}: {other:?}"),
        }
        // Over the link: refused, nothing armed.
        let mut rig = Rig::new();
        rig.request(&Request::TrajectoryBegin { total_points: 8 }, 1);
        let r = rig.request(
            &Request::TrajectorySegment {
                first_index: 0,
                points: points.iter().copied().collect(),
            },
            2,
        );
        assert_eq!(
            r,
            Reply::Nack {
                seq: 2,
                error: ErrorCode::InvalidValue
            },
            "{what}"
        );
        assert!(matches!(rig.request(&Request::Arm, 3), Reply::Nack { .. }));
    }
    // Speed alone: 3 m apart every 1 s at rest at each waypoint peaks at
    // 1.5·3/1 = 4.5 m/s (the Hermite curve between two standstills), with
    // 6·3/1² = 18 m/s² at the ends: within the paper robot's acceleration
    // (32 m/s²) but not its speed.
    let points = hops(3.0, 1.0);
    let e = check_segment(&points[0], &points[1], &lim).unwrap_err();
    assert_eq!(e.quantity, Quantity::SpeedMps, "{e:?}");
    assert!((4.5..4.5 * 1.05).contains(&e.value), "{e:?}");
    // Slowed down: the same hops every 2 s (0.75 m/s peak, 0.75 m/s²),
    // the slalom every 2 s.
    for points in [hops(1.0, 2.0), slalom(2.0)] {
        let mut buf = WaypointBuffer::default();
        buf.begin(8);
        buf.push(0, &points, None, &lim).unwrap();
    }
}

/// Issue 21 item 2: gains and references that are finite but absurd.
#[test]
fn absurd_gains_and_references_are_refused() {
    let mut rig = Rig::new();
    for (id, value) in [
        (ParamId::Kx, 3.4e38),
        (ParamId::Ky, 3.4e38),
        (ParamId::Ktheta, 1e9),
        (ParamId::Ks, 1e9),
        (ParamId::Kx, 1e-30),
        (ParamId::TorqueLimitNm, 1e6),
        (ParamId::MaxSpeedMps, 9.0),
    ] {
        let r = rig.request(&Request::SetParam { id, value }, 1);
        assert_eq!(nack(&r), Some(ErrorCode::InvalidValue), "{id:?} = {value}");
    }
    // Within the ranges: accepted (paper gains, 4 m/s top speed).
    for (id, value) in [
        (ParamId::Ky, 250.0),
        (ParamId::Kx, 1.2),
        (ParamId::MaxSpeedMps, 3.0),
    ] {
        let r = rig.request(&Request::SetParam { id, value }, 2);
        assert_eq!(r, Reply::Ack { seq: 2 }, "{id:?} = {value}");
    }
    let circle = |radius_m: f32, speed_mps: f32| {
        Request::SetReference(BuiltinReference {
            shape: BuiltinShape::Circle {
                radius_m,
                speed_mps,
            },
            start: None,
            speed_scale: 1.0,
        })
    };
    for (r, v) in [
        (1.2e-38, 1e6),
        (1.0, 1e6),
        (1e-4, 0.3),
        (1e9, 0.3),
        (0.1, 3.0),
    ] {
        let a = rig.request(&circle(r, v), 3);
        assert_eq!(
            nack(&a),
            Some(ErrorCode::InvalidValue),
            "circle {r} m at {v} m/s"
        );
    }
    // The paper's curve at twice its speed is fine (3.9 m/s < 4 m/s), at
    // three times not.
    for (scale, ok) in [(2.0, true), (3.0, false)] {
        let paper = Request::SetReference(BuiltinReference {
            shape: named_shape("paper").unwrap(),
            start: None,
            speed_scale: scale,
        });
        let a = rig.request(&paper, 4);
        assert_eq!(nack(&a).is_none(), ok, "paper at scale {scale}: {a:?}");
    }
    let far = PoseMsg {
        x_m: 3.4e38,
        y_m: 0.0,
        theta_rad: 0.0,
    };
    assert_eq!(
        nack(&rig.request(&Request::SetPose(far), 7)),
        Some(ErrorCode::InvalidValue)
    );
    let wp = |v_mps: f32, x_m: f32| Waypoint {
        t_s: 0.0,
        pose: PoseMsg {
            x_m,
            y_m: 0.0,
            theta_rad: 0.0,
        },
        v_mps,
        omega_radps: 0.0,
    };
    for w in [wp(1e6, 0.0), wp(0.1, 1e30)] {
        rig.request(&Request::TrajectoryBegin { total_points: 2 }, 5);
        let seg = Request::TrajectorySegment {
            first_index: 0,
            points: [w].into_iter().collect(),
        };
        assert_eq!(nack(&rig.request(&seg, 6)), Some(ErrorCode::InvalidValue));
    }
}

/// An external pose at `x_m` on the estimate's line (y, θ: the start's).
fn pose_req(t_robot_us: u32, x_m: f32, std_dev: [f32; 3]) -> Request {
    let start =
        controller_core::runtime::RuntimeConfig::example(controller_core::ControllerKind::Proposed)
            .initial_pose;
    Request::ExternalPose {
        t_robot_us,
        pose: PoseMsg {
            x_m,
            y_m: start.y_m,
            theta_rad: start.theta_rad,
        },
        std_dev,
    }
}

/// Issue 21 item 3: every pose the estimator would drop is refused on
/// arrival with its reason; one it refuses later (the chi-square gate) is
/// counted in the status.
#[test]
fn external_poses_are_refused_with_the_estimators_reason() {
    let mut rig = Rig::new();
    for _ in 0..50 {
        rig.tick();
    }
    // The device handles the request on the next tick, stamped now + 1 ms.
    let now = rig.now_us + PERIOD_US;
    let start = rig.dev.control().estimator().estimate().pose;
    let x0 = start.x_m;
    let cases = [
        (
            pose_req(now + 5_000, x0, [0.01; 3]),
            ErrorCode::PoseFromFuture,
        ),
        (
            pose_req(now - 1_000, x0, [0.0, 0.0, 0.01]),
            ErrorCode::PoseBadStdDev,
        ),
        (
            pose_req(now - 1_000, x0, [5000.0, 5000.0, 0.01]),
            ErrorCode::PoseBadStdDev,
        ),
        (
            pose_req(now - 1_000, x0, [0.01, 0.01, -1.0]),
            ErrorCode::PoseBadStdDev,
        ),
        (
            pose_req(now - 1_000, 1e30, [0.01; 3]),
            ErrorCode::PoseNonFinite,
        ),
        (
            pose_req(now - 1_000, f32::NAN, [0.01; 3]),
            ErrorCode::PoseNonFinite,
        ),
        (
            pose_req(now.wrapping_sub(10_000_000), x0, [0.01; 3]),
            ErrorCode::PoseTooOld,
        ),
    ];
    for (i, (req, code)) in cases.iter().enumerate() {
        let seq = 10 + i as u16;
        rig.replies.clear();
        rig.send(req, seq);
        rig.tick();
        let a = rig.replies.iter().find(|r| r.seq() == Some(seq)).unwrap();
        assert_eq!(nack(a), Some(*code), "{req:?}");
    }
    // A consistent pose: accepted and used.
    let now = rig.now_us + PERIOD_US;
    let used_before = rig.dev.counters().external_poses;
    assert_eq!(
        rig.request(&pose_req(now - 2_000, x0, [0.01; 3]), 30),
        Reply::Ack { seq: 30 }
    );
    assert_eq!(
        rig.dev.counters().external_poses,
        used_before + 1,
        "{:?}",
        rig.dev.control().estimator().status()
    );
    // An older one than the last accepted: out of order.
    let now = rig.now_us + PERIOD_US;
    let a = rig.request(&pose_req(now - 5_000, x0, [0.01; 3]), 31);
    assert_eq!(nack(&a), Some(ErrorCode::PoseOutOfOrder));
    // 50 m away at 1 cm: admissible, so acked, then the gate refuses it
    // when it is used; the status says so.
    let now = rig.now_us + PERIOD_US;
    assert_eq!(
        rig.request(&pose_req(now - 1_000, x0 + 50.0, [0.01; 3]), 32),
        Reply::Ack { seq: 32 }
    );
    rig.tick();
    match rig.request(&Request::GetStatus, 33) {
        Reply::Status { status, .. } => {
            assert_eq!(
                status.pose_rejects.outlier,
                1,
                "{status:?} {:?}",
                rig.dev.control().estimator().status()
            );
            assert_eq!(status.counters.external_poses, used_before + 1);
        }
        r => panic!("{r:?}"),
    }
}

fn line_wp(i: u32) -> Waypoint {
    Waypoint {
        t_s: i as f32 * 0.1,
        pose: PoseMsg {
            x_m: i as f32 * 0.01,
            y_m: 0.0,
            theta_rad: 0.0,
        },
        v_mps: 0.1,
        omega_radps: 0.0,
    }
}

fn line_seg(first: u32, n: u32) -> Request {
    Request::TrajectorySegment {
        first_index: first,
        points: (first..first + n).map(line_wp).collect(),
    }
}

/// Issue 21 item 6: a cut upload (48 of 80 waypoints, room for more) cannot
/// be armed; the complete one can.
#[test]
fn a_half_uploaded_trajectory_cannot_be_armed() {
    let mut rig = Rig::new();
    rig.request(&Request::TrajectoryBegin { total_points: 80 }, 1);
    for s in 0..6 {
        let r = rig.request(&line_seg(8 * s, 8), 2);
        assert!(matches!(r, Reply::TrajectoryAck { .. }), "{r:?}");
    }
    assert_eq!(
        nack(&rig.request(&Request::Arm, 3)),
        Some(ErrorCode::UploadIncomplete)
    );
    assert_eq!(rig.dev.state(), RunStateMsg::Hold);
    // Shorter, complete: armable.
    rig.request(&Request::TrajectoryBegin { total_points: 20 }, 4);
    for (first, n) in [(0, 8), (8, 8), (16, 4)] {
        rig.request(&line_seg(first, n), 5);
    }
    assert_eq!(rig.request(&Request::Arm, 6), Reply::Ack { seq: 6 });
    assert_eq!(rig.dev.state(), RunStateMsg::Running);
}

/// Issue 21 item 6: a segment sent again after its acknowledgement was
/// lost is acknowledged again (same index, same content); a different
/// content at an old index is still out of order.
#[test]
fn a_retried_segment_is_acknowledged_again() {
    let mut rig = Rig::new();
    rig.request(&Request::TrajectoryBegin { total_points: 24 }, 1);
    rig.request(&line_seg(0, 8), 2);
    rig.request(&line_seg(8, 8), 3);
    let again = rig.request(&line_seg(8, 8), 4);
    assert_eq!(
        again,
        Reply::TrajectoryAck {
            seq: 4,
            next_index: 16,
            free: 64 - 16
        }
    );
    let mut other = line_seg(8, 8);
    if let Request::TrajectorySegment { points, .. } = &mut other {
        points[3].v_mps = 0.2;
    }
    assert_eq!(nack(&rig.request(&other, 5)), Some(ErrorCode::OutOfOrder));
    let r = rig.request(&line_seg(16, 8), 6);
    assert!(
        matches!(r, Reply::TrajectoryAck { next_index: 24, .. }),
        "{r:?}"
    );
}

// ---- Issue 18: the robot record --------------------------------------

/// A test record: bytes whose last four are a checksum of the rest; a
/// record with byte 5 = 0xEE is "out of range" at field `body.mass_kg`.
fn record(len: usize, seed: u8) -> Vec<u8> {
    let mut b: Vec<u8> = (0..len - 4).map(|i| seed.wrapping_add(i as u8)).collect();
    b[5] = 0;
    let s: u32 = b.iter().map(|&x| x as u32).sum();
    b.extend(s.to_le_bytes());
    b
}

fn check_record(b: &[u8]) -> Result<(), RobotFault> {
    if b.len() < 8 {
        return Err(RobotFault::new(RobotFaultKind::Truncated, "", None));
    }
    let n = b.len() - 4;
    let s: u32 = b[..n].iter().map(|&x| x as u32).sum();
    if s.to_le_bytes() != b[n..] {
        return Err(RobotFault::new(RobotFaultKind::BadCrc, "", None));
    }
    if b[5] == 0xEE {
        return Err(RobotFault::new(
            RobotFaultKind::OutOfRange,
            "body.mass_kg",
            Some([0.1, 500.0]),
        ));
    }
    Ok(())
}

fn with_store() -> (Rig, Vec<u8>) {
    let mut rig = Rig::new();
    let default = record(100, 1);
    rig.dev
        .attach_robot_store(check_record, &default, RobotSource::DefaultMissing);
    (rig, default)
}

/// Uploads `rec` in chunks (acked each); returns the commit's answer
/// after `write` (the board's write result, `None`: not performed).
fn push(rig: &mut Rig, rec: &[u8], seq0: u16) {
    let a = rig.request(
        &Request::RobotBegin {
            total_len: rec.len() as u16,
        },
        seq0,
    );
    assert_eq!(a, Reply::Ack { seq: seq0 });
    for (k, c) in rec.chunks(ROBOT_CHUNK).enumerate() {
        let seq = seq0 + 1 + k as u16;
        let req = Request::RobotChunk {
            offset: (k * ROBOT_CHUNK) as u16,
            data: c.iter().copied().collect(),
        };
        assert_eq!(rig.request(&req, seq), Reply::Ack { seq });
    }
}

fn pull(rig: &mut Rig, seq0: u16) -> Vec<u8> {
    let mut out = Vec::new();
    for k in 0..10u16 {
        match rig.request(
            &Request::RobotRead {
                offset: out.len() as u16,
            },
            seq0 + k,
        ) {
            Reply::RobotData {
                total_len,
                data,
                offset,
                ..
            } => {
                assert_eq!(offset as usize, out.len());
                out.extend(data.iter());
                if out.len() == total_len as usize {
                    return out;
                }
            }
            other => panic!("{other:?}"),
        }
    }
    panic!("read did not end");
}

fn status(rig: &mut Rig, seq: u16) -> StatusMsg {
    match rig.request(&Request::GetStatus, seq) {
        Reply::Status { status, .. } => status,
        other => panic!("{other:?}"),
    }
}

/// A valid record: uploaded in chunks, validated on commit, the commit
/// answered only when the board's write finished, arming refused in
/// between, then read back equal and reported in the status.
#[test]
fn a_valid_record_is_stored_after_the_boards_write_and_reads_back() {
    let (mut rig, default) = with_store();
    assert_eq!(pull(&mut rig, 10), default);
    let st = status(&mut rig, 20);
    assert_eq!(st.robot.source, RobotSource::DefaultMissing);
    assert_eq!(st.robot.stored_crc32, 0);
    let rec = record(300, 7);
    push(&mut rig, &rec, 100);
    rig.replies.clear();
    rig.send(&Request::RobotCommit, 200);
    for _ in 0..5 {
        rig.tick();
    }
    assert!(
        rig.replies.iter().all(|r| r.seq() != Some(200)),
        "answered before the write"
    );
    assert_eq!(rig.dev.pending_robot_write(), Some(rec.as_slice()));
    rig.request(&circle(), 201);
    assert_eq!(
        nack(&rig.request(&Request::Arm, 202)),
        Some(ErrorCode::Busy)
    );
    assert_eq!(rig.dev.state(), RunStateMsg::Hold);
    rig.dev.robot_write_done(true);
    rig.tick();
    assert!(rig.replies.contains(&Reply::Ack { seq: 200 }));
    assert_eq!(rig.dev.pending_robot_write(), None);
    assert_eq!(pull(&mut rig, 300), rec);
    let st = status(&mut rig, 400);
    // Takes effect at the next boot: the active record is still the default.
    assert_eq!(st.robot.source, RobotSource::DefaultMissing);
    assert_eq!(
        st.robot.active_crc32,
        wmr_device::robot::record_crc32(&default)
    );
    assert_eq!(st.robot.stored_crc32, wmr_device::robot::record_crc32(&rec));
    assert_eq!(st.robot.writes, 1);
    // Arming works again.
    assert_eq!(rig.request(&Request::Arm, 401), Reply::Ack { seq: 401 });
}

/// Issue 31 item 5: the last `RobotChunk` retried after its
/// acknowledgement was lost (the same offset, the same bytes) is
/// acknowledged again and changes nothing, as trajectory segments are; the
/// same offset with other bytes is still out of order; the record commits
/// and reads back equal.
#[test]
fn a_retried_robot_chunk_is_acknowledged_again() {
    let (mut rig, _) = with_store();
    let rec = record(300, 9);
    push(&mut rig, &rec, 100);
    let k = (rec.len() - 1) / ROBOT_CHUNK * ROBOT_CHUNK;
    let last = Request::RobotChunk {
        offset: k as u16,
        data: rec[k..].iter().copied().collect(),
    };
    assert_eq!(rig.request(&last, 150), Reply::Ack { seq: 150 });
    let mut other = rec[k..].to_vec();
    other[0] ^= 0xFF;
    let changed = Request::RobotChunk {
        offset: k as u16,
        data: other.iter().copied().collect(),
    };
    assert_eq!(
        nack(&rig.request(&changed, 151)),
        Some(ErrorCode::OutOfOrder)
    );
    rig.send(&Request::RobotCommit, 200);
    rig.tick();
    assert_eq!(rig.dev.pending_robot_write(), Some(rec.as_slice()));
    rig.dev.robot_write_done(true);
    rig.tick();
    assert!(rig.replies.contains(&Reply::Ack { seq: 200 }));
    assert_eq!(pull(&mut rig, 300), rec);
}

/// A record the validator refuses is answered with the field, and nothing
/// is handed to the board; a failed write keeps the old record.
#[test]
fn a_bad_record_is_refused_naming_the_field_and_a_failed_write_keeps_the_old() {
    let (mut rig, default) = with_store();
    let mut bad = record(200, 3);
    bad[5] = 0xEE;
    let n = bad.len() - 4;
    let s: u32 = bad[..n].iter().map(|&x| x as u32).sum();
    bad[n..].copy_from_slice(&s.to_le_bytes());
    push(&mut rig, &bad, 10);
    match rig.request(&Request::RobotCommit, 50) {
        Reply::RobotRejected { fault, .. } => {
            assert_eq!(fault.kind, RobotFaultKind::OutOfRange);
            assert_eq!(fault.field.as_str(), "body.mass_kg");
            assert_eq!(fault.range, Some([0.1, 500.0]));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(rig.dev.pending_robot_write(), None);
    // A corrupted byte: the checksum.
    let mut torn = record(200, 4);
    torn[100] ^= 1;
    push(&mut rig, &torn, 60);
    assert!(matches!(
        rig.request(&Request::RobotCommit, 90),
        Reply::RobotRejected {
            fault: RobotFault {
                kind: RobotFaultKind::BadCrc,
                ..
            },
            ..
        }
    ));
    // The board's write fails: StoreFailed, the old record stays.
    push(&mut rig, &record(150, 5), 100);
    rig.send(&Request::RobotCommit, 120);
    rig.tick();
    rig.dev.robot_write_done(false);
    rig.tick();
    assert!(rig.replies.contains(&Reply::Nack {
        seq: 120,
        error: ErrorCode::StoreFailed
    }));
    assert_eq!(pull(&mut rig, 130), default);
    assert_eq!(status(&mut rig, 140).robot.write_failures, 1);
}

/// Chunks out of order or past the declared length, a commit before the
/// last chunk, a length of 0 or above the maximum: refused.
#[test]
fn uploads_that_do_not_add_up_are_refused() {
    let (mut rig, _) = with_store();
    let chunk = |offset: u16, n: usize| Request::RobotChunk {
        offset,
        data: (0..n as u8).collect(),
    };
    assert_eq!(
        nack(&rig.request(&chunk(0, 10), 1)),
        Some(ErrorCode::OutOfOrder)
    );
    for (seq, len) in [(2, 0u16), (3, ROBOT_BLOB_MAX as u16 + 1)] {
        let a = rig.request(&Request::RobotBegin { total_len: len }, seq);
        assert_eq!(nack(&a), Some(ErrorCode::InvalidValue));
    }
    rig.request(&Request::RobotBegin { total_len: 200 }, 4);
    assert_eq!(rig.request(&chunk(0, 128), 5), Reply::Ack { seq: 5 });
    assert_eq!(
        nack(&rig.request(&chunk(0, 10), 6)),
        Some(ErrorCode::OutOfOrder)
    );
    assert_eq!(
        nack(&rig.request(&chunk(128, 100), 7)),
        Some(ErrorCode::InvalidValue)
    );
    assert_eq!(
        nack(&rig.request(&Request::RobotCommit, 8)),
        Some(ErrorCode::UploadIncomplete)
    );
    assert_eq!(
        nack(&rig.request(&Request::RobotRead { offset: 1000 }, 9)),
        Some(ErrorCode::InvalidValue)
    );
    assert_eq!(rig.dev.pending_robot_write(), None);
}

/// Issue 31 item 6: values bad by construction are `InvalidValue` in any
/// state (stall_ticks beyond 16 bits, a pose at 1e30 m, both while
/// running, were `Busy`); `SetPose` keeps the estimator's refusal counters
/// (it reset them).
#[test]
fn bad_values_while_running_and_set_pose_keeps_the_refusal_counters() {
    let mut rig = Rig::new();
    // An external pose 100 m away with a 1 cm std dev: acked, then
    // refused by the estimator's gate (stamped at a tick already run).
    for _ in 0..50 {
        rig.tick();
    }
    let t = rig.now_us - 10_000;
    let a = rig.request(
        &Request::ExternalPose {
            t_robot_us: t,
            pose: PoseMsg {
                x_m: 100.0,
                y_m: 0.0,
                theta_rad: 0.0,
            },
            std_dev: [0.01, 0.01, 0.0],
        },
        1,
    );
    assert_eq!(a, Reply::Ack { seq: 1 });
    for _ in 0..3 {
        rig.tick();
    }
    let before = status(&mut rig, 2).pose_rejects;
    assert_eq!(before.outlier, 1, "{before:?}");
    let set = Request::SetPose(PoseMsg {
        x_m: 1.0,
        y_m: 0.0,
        theta_rad: 0.0,
    });
    assert_eq!(rig.request(&set, 3), Reply::Ack { seq: 3 });
    assert_eq!(status(&mut rig, 4).pose_rejects, before);
    rig.request(&circle(), 5);
    assert_eq!(rig.request(&Request::Arm, 6), Reply::Ack { seq: 6 });
    let stall = Request::SetParam {
        id: ParamId::StallTicks,
        value: 1e6,
    };
    assert_eq!(nack(&rig.request(&stall, 7)), Some(ErrorCode::InvalidValue));
    let far = Request::SetPose(PoseMsg {
        x_m: 1e30,
        y_m: 0.0,
        theta_rad: 0.0,
    });
    assert_eq!(nack(&rig.request(&far, 8)), Some(ErrorCode::InvalidValue));
    // Good values wait for hold.
    let ok = Request::SetParam {
        id: ParamId::StallTicks,
        value: 300.0,
    };
    assert_eq!(nack(&rig.request(&ok, 9)), Some(ErrorCode::Busy));
    assert_eq!(nack(&rig.request(&set, 10)), Some(ErrorCode::Busy));
}

// ---- Issue 32: one parameter table ---------------------------------------

/// Issue 32: a parameter's range is refused identically — the same bound,
/// the error naming the field, the value and the limit — by the robot
/// file and by the device's set-param path (and by the ROS bridge's
/// parameter service: wmr-ros2 `tests/param_range.rs`), one fixed bound
/// and two of the robot's own (its stall torque, its top speed). The
/// device refuses on the link and keeps the value.
#[test]
fn a_range_is_refused_identically_by_the_file_and_the_device() {
    use controller_core::runtime::param_table::Beyond;
    use robot_file::{Reason, Robot};
    use wmr_device::limits::RobotLimits;
    use wmr_device::{check_set, DeviceConfig, SetParamError};
    let paper = Robot::paper();
    let kind = controller_core::ControllerKind::Proposed;
    let board = robot_file::BoardFacts::of_timer(&paper, 96_000_000).unwrap();
    let rt = paper
        .derive(
            &board,
            controller_core::runtime::RuntimeConfig::example(kind).reference,
        )
        .runtime;
    let dev = Device::new(
        DeviceConfig::of_robot(&paper, "test", CAP_VELOCITY, None),
        rt,
    )
    .unwrap();
    let mut rig = Rig::with(dev);
    let lim = RobotLimits::of(rig.dev.control().config());
    let stall = paper.stall_torque_nm();
    type Set = fn(&mut Robot, f32);
    let cases: [(ParamId, f32, f32, Set); 3] = [
        (ParamId::AccelMps2, 25.0, 20.0, |r, v| {
            r.limits.max_accel_mps2 = v
        }),
        (ParamId::TorqueLimitNm, 30.0, stall, |r, v| {
            r.limits.torque_nm = v
        }),
        (ParamId::MaxSpeedMps, 5.0, lim.top_speed_mps, |r, v| {
            r.limits.max_speed_mps = v
        }),
    ];
    for (seq, (id, value, limit, set)) in cases.into_iter().enumerate() {
        let mut bad = paper.clone();
        set(&mut bad, value);
        let fe = bad.validate().unwrap_err();
        let Reason::Range(file) = fe.reason else {
            panic!("{id:?}: {fe}")
        };
        let Err(SetParamError::Range(device)) = check_set(&lim, id, value) else {
            panic!("{id:?}: {:?}", check_set(&lim, id, value))
        };
        assert_eq!(file, device, "{id:?}");
        assert_eq!((fe.field, device.field), (id.name(), id.name()));
        assert_eq!(
            (device.value, device.limit(), device.beyond),
            (value, limit, Beyond::Max)
        );
        assert_eq!(fe.to_string(), device.to_string());
        assert!(
            fe.to_string()
                .contains(&format!("is above its limit {limit}")),
            "{fe}"
        );
        assert!(fe.to_string().contains(": set a value in [0.01, "), "{fe}");
        // The set-param path: refused on the link, the value kept.
        let get = |rig: &mut Rig, seq| match rig.request(&Request::GetParam(id), seq) {
            Reply::Param { value, .. } => value,
            r => panic!("{r:?}"),
        };
        let before = get(&mut rig, 100 + seq as u16);
        let r = rig.request(&Request::SetParam { id, value }, 200 + seq as u16);
        assert_eq!(nack(&r), Some(ErrorCode::InvalidValue), "{id:?}");
        assert_eq!(get(&mut rig, 300 + seq as u16), before);
    }
    assert!(paper.limits.torque_nm < stall);
}

/// Runs the armed rig to hold, a status request every 100 ticks keeping
/// the link alive; the stop's cause.
fn run_to_hold(rig: &mut Rig, max_ticks: usize) -> Option<StopCode> {
    let mut seq = 100;
    for k in 0..max_ticks {
        if k % 100 == 0 {
            seq += 1;
            rig.send(&Request::GetStatus, seq);
        }
        rig.tick();
        if rig.dev.state() == RunStateMsg::Hold {
            return rig.replies.iter().rev().find_map(|r| match r {
                Reply::Event(Event::StateChanged {
                    state: RunStateMsg::Hold,
                    cause,
                }) => *cause,
                _ => None,
            });
        }
    }
    panic!("still {:?} after {max_ticks} ticks", rig.dev.state());
}

/// Issue 37 (D195): a trajectory longer than the buffer, armed with only
/// its first 64 waypoints and never streamed (the README's `upload` then
/// `record --arm`), runs them and stops as `Other`, not `TrajectoryEnd`:
/// a host must not take the truncated run for the path's end. The
/// complete trajectory still ends as `TrajectoryEnd`.
#[test]
fn a_trajectory_that_runs_out_of_streamed_waypoints_is_not_its_end() {
    let mut rig = Rig::new();
    rig.request(&Request::TrajectoryBegin { total_points: 100 }, 1);
    for s in 0..8 {
        let r = rig.request(&line_seg(8 * s, 8), 2);
        assert!(matches!(r, Reply::TrajectoryAck { .. }), "{r:?}");
    }
    assert_eq!(rig.request(&Request::Arm, 3), Reply::Ack { seq: 3 });
    // 64 waypoints, 0.1 s apart: 6.3 s, then the brake.
    assert_eq!(run_to_hold(&mut rig, 12_000), Some(StopCode::Other));

    let mut rig = Rig::new();
    rig.request(&Request::TrajectoryBegin { total_points: 20 }, 1);
    for (first, n) in [(0, 8), (8, 8), (16, 4)] {
        rig.request(&line_seg(first, n), 2);
    }
    assert_eq!(rig.request(&Request::Arm, 3), Reply::Ack { seq: 3 });
    assert_eq!(run_to_hold(&mut rig, 6_000), Some(StopCode::TrajectoryEnd));
}
