//! The estimator's covariance over the link (protocol 5, D155): the
//! simulated robot (robot-app's loop on the simulated board, the firmware's
//! device and estimator) driven through its port with framed requests, its
//! telemetry frames decoded and turned into `/odom` by ros-mcap (the code
//! both `wmr record --mcap` and the ROS 2 bridge use). Deterministic: robot
//! time only, no wall clock.

use controller_core::ControllerKind;
use hil_sim::device::SimRobot;
use hil_sim::scenario::{PerturbationPart, Scenario, Sensing, TrajectoryKind};
use ros_mcap::{Geometry, LogFrame, RosFrames};
use wmr_protocol::*;

/// The robot of a scenario with the gyro and the wheels only (no pose
/// source), and its host side.
struct Rig {
    robot: SimRobot,
    dec: FrameDecoder<MAX_FRAME>,
    seq: u16,
    frames: RosFrames,
}

/// What one tick brought back.
#[derive(Default)]
struct Got {
    replies: Vec<(u16, Reply)>,
    telemetry: Vec<Telemetry>,
}

impl Rig {
    fn new() -> Self {
        let scn = Scenario {
            name: "gyro-only circle".into(),
            duration_s: 60.0,
            trajectory: TrajectoryKind::Circle,
            perturbations: PerturbationPart::none(),
            initial_pose: [2.0, 0.0, std::f64::consts::FRAC_PI_2],
            ..Scenario::default()
        }
        .with_sensing(Sensing::Imu);
        let robot = SimRobot::new(&scn, ControllerKind::Proposed).unwrap();
        let p = controller_core::RobotParams::paper();
        let geometry = Geometry::new(
            p.wheel_radius_m as f64,
            p.half_track_m as f64,
            p.com_offset_m as f64,
        )
        .unwrap();
        Self {
            robot,
            dec: FrameDecoder::new(),
            seq: 0,
            frames: RosFrames::new(geometry),
        }
    }

    fn send_version(&mut self, req: &Request, version: u16) -> u16 {
        self.seq += 1;
        let mut out = [0u8; MAX_FRAME];
        let f = encode_with_version(req, self.seq, version, &mut out).unwrap();
        assert_eq!(self.robot.port_received(f), f.len());
        self.seq
    }

    /// Runs `ticks` control periods, a status request every 100 (the
    /// host's keep-alive against the link-silence watchdog); what came back.
    fn run(&mut self, ticks: usize) -> Got {
        let mut got = Got::default();
        let mut buf = [0u8; 1024];
        for k in 0..ticks {
            if k % 100 == 99 {
                self.send_version(&Request::GetStatus, PROTOCOL_VERSION);
            }
            self.robot.step().unwrap();
            loop {
                let n = self.robot.port_take_tx(&mut buf);
                if n == 0 {
                    break;
                }
                self.dec.feed_all::<Reply>(&buf[..n], |d| match d {
                    Decoded::Frame {
                        msg: Reply::Telemetry(t),
                        ..
                    } => got.telemetry.push(t),
                    Decoded::Frame { msg, .. } => got.replies.push((msg.seq().unwrap_or(0), msg)),
                    other => panic!("undecodable answer {other:?}"),
                });
            }
        }
        got
    }

    /// Sends `req` and runs until its answer; the answer.
    fn request(&mut self, req: &Request) -> Reply {
        let seq = self.send_version(req, PROTOCOL_VERSION);
        for _ in 0..100 {
            if let Some((_, r)) = self.run(1).replies.into_iter().find(|(s, _)| *s == seq) {
                return r;
            }
        }
        panic!("{req:?}: no answer in 100 ticks");
    }

    fn ok(&mut self, req: &Request) {
        let r = self.request(req);
        assert_eq!(r, Reply::Ack { seq: self.seq }, "{req:?}");
    }

    /// `/odom`'s position variance var(x) + var(y) \[m²\] and yaw
    /// variance \[rad²\] of a telemetry frame, as the bridge and the MCAP
    /// log publish them.
    fn odom_variances(&mut self, t: &Telemetry) -> (f64, f64) {
        let f = LogFrame::of_telemetry(t, 1_000 + t.t_robot_us as u64 * 1000, None).unwrap();
        let c = self.frames.messages(&f).odom.pose.covariance.to_array();
        (c[0] + c[7], c[35])
    }
}

/// Gyro-only odometry drifts: `/odom`'s position covariance grows second
/// after second while the robot drives its circle with no pose fix, and
/// one fused external pose (1 cm, 0.01 rad) brings it down to about the
/// measurement's own variance. The twist's variances are those of the
/// estimator's model (positive, finite).
#[test]
fn odom_covariance_grows_without_a_fix_and_falls_after_a_pose() {
    let mut rig = Rig::new();
    let hello = rig.request(&Request::Hello {
        version: PROTOCOL_VERSION,
    });
    assert!(
        matches!(hello, Reply::Hello { version: 5, .. }),
        "{hello:?}"
    );
    rig.ok(&Request::SetReference(BuiltinReference {
        shape: named_shape("circle").unwrap(),
        start: None,
        speed_scale: 1.0,
    }));
    rig.ok(&Request::SetTelemetry {
        selection: TELEMETRY_ALL,
        rate_hz: 10,
    });
    rig.ok(&Request::Arm);
    // Five seconds of the circle, gyro and wheels only.
    let mut per_second = Vec::new();
    for _ in 0..5 {
        let got = rig.run(1000);
        let t = got.telemetry.last().copied().expect("telemetry at 10 Hz");
        assert_eq!(t.state, RunStateMsg::Running);
        let c = t.covariance.expect("group 8 is in TELEMETRY_ALL");
        let tw = c.twist_f32();
        assert!(tw.iter().all(|v| v.is_finite() && *v > 0.0), "{tw:?}");
        per_second.push(rig.odom_variances(&t));
    }
    for w in per_second.windows(2) {
        assert!(
            w[1].0 > w[0].0,
            "position variance did not grow: {per_second:?}"
        );
    }
    let before = per_second[4];
    assert!(
        before.0 > 1.5 * per_second[0].0,
        "a drift of 4 s barely shows: {per_second:?}"
    );
    // One pose of G, measured now, 1 cm and 0.01 rad.
    let g = rig.robot.true_pose();
    let now_us = rig.robot.now_us().wrapping_sub(2_000);
    rig.ok(&Request::ExternalPose {
        t_robot_us: now_us,
        pose: PoseMsg {
            x_m: g[0] as f32,
            y_m: g[1] as f32,
            theta_rad: g[2] as f32,
        },
        std_dev: [0.01, 0.01, 0.01],
    });
    let got = rig.run(200);
    let t = *got.telemetry.last().unwrap();
    let after = rig.odom_variances(&t);
    // At the update var(x) + var(y) is at most the measurement's 2·(1 cm)²
    // (a Kalman update never leaves more than the measured variance on the
    // measured coordinates; O_B adds d²·var(θ) ≈ 2.5e-7); the up to 0.2 s
    // of driving until the frame adds less than as much again.
    assert!(
        after.0 < 3.0 * 2e-4,
        "after the pose {after:?}, before {before:?}"
    );
    assert!(
        after.0 < before.0 / 4.0,
        "after {after:?}, before {before:?}"
    );
    assert!(
        after.1 < before.1,
        "yaw: after {after:?}, before {before:?}"
    );
}

/// A host of the previous protocol (4, before the covariance group) is
/// refused by this robot: its hello answered with the robot's version 5
/// (so the host can say which versions differ), anything else `Nack
/// VersionMismatch`, and nothing acted on.
#[test]
fn a_protocol_4_host_is_refused() {
    let mut rig = Rig::new();
    let old = PROTOCOL_VERSION - 1;
    assert_eq!(old, 4);
    let hello = rig.send_version(&Request::Hello { version: old }, old);
    let tel = rig.send_version(
        &Request::SetTelemetry {
            selection: TELEMETRY_ALL,
            rate_hz: 100,
        },
        old,
    );
    let got = rig.run(50);
    assert!(
        got.replies.iter().any(|(s, r)| *s == hello
            && matches!(
                r,
                Reply::Hello {
                    version: PROTOCOL_VERSION,
                    ..
                }
            )),
        "{:?}",
        got.replies
    );
    assert!(got.replies.contains(&(
        tel,
        Reply::Nack {
            seq: tel,
            error: ErrorCode::VersionMismatch
        }
    )));
    assert!(got.telemetry.is_empty(), "telemetry turned on by a v4 host");
}
