//! End-to-end over a pseudo-terminal against the simulated robot
//! (`hil_sim::device`, the firmware's link handler, runtime and estimator
//! on the simulated plant): `record --mcap` and `metrics`, and `pose-feed`
//! capture times reaching the estimator's history.

use controller_core::ControllerKind;
use hil_sim::device::{PtyRobot, SimRobot};
use hil_sim::scenario::{PerturbationPart, Scenario, Sensing};
use std::time::{Duration, Instant};
use wmr::session::{Capture, PoseClock, PoseTally};
use wmr::Link;
use wmr_protocol::*;

/// One simulated robot at a time (each runs in real time next to its host).
fn serial() -> std::sync::MutexGuard<'static, ()> {
    PtyRobot::serial()
}

/// The simulated robot served on a pty in a thread (the shared rig).
struct Robot(PtyRobot);

impl Robot {
    fn start(scn: &Scenario) -> Self {
        let robot = SimRobot::new(scn, ControllerKind::Proposed).unwrap();
        Self(PtyRobot::start(robot, 1.0).unwrap())
    }

    fn link(&self) -> Link {
        let mut l = Link::open(&self.0.path, Duration::from_secs(5)).unwrap();
        l.hello().unwrap();
        ok(
            &mut l,
            Request::SetParam {
                id: ParamId::LinkTimeoutMs,
                value: 10_000.0,
            },
        );
        l
    }

    fn finish(self) -> SimRobot {
        self.0.finish().unwrap()
    }
}

fn ok(link: &mut Link, req: Request) {
    link.command(&req)
        .unwrap_or_else(|e| panic!("{req:?}: {e}"));
}

fn quiet(sensing: Sensing) -> Scenario {
    Scenario {
        name: "quiet".into(),
        duration_s: 10.0,
        perturbations: PerturbationPart::none(),
        ..Scenario::default()
    }
    .with_sensing(sensing)
}

/// `record --mcap` of a run writes the CSV and the MCAP; `wmr metrics`
/// of either file gives the same numbers (the same JSON), equal to the
/// summary `record` printed, and the MCAP's rows are the CSV's bit for bit.
#[test]
fn record_mcap_and_csv_give_the_same_metrics() {
    let _s = serial();
    let robot = Robot::start(&quiet(Sensing::Mocap));
    let mut link = robot.link();
    ok(
        &mut link,
        Request::SetReference(BuiltinReference {
            shape: named_shape("paper").unwrap(),
            start: None,
            speed_scale: 1.0,
        }),
    );
    let dir = tempfile::tempdir().unwrap();
    let (csv, mcap) = (dir.path().join("r.csv"), dir.path().join("r.mcap"));
    let args = wmr::cli::RecordArgs {
        seconds: 3.0,
        out: csv.clone(),
        rate: 100,
        arm: true,
        quiet: true,
        mcap: Some(mcap.clone()),
        com_offset_m: None,
    };
    let mut out = Vec::new();
    wmr::cli::record(&args, &mut link, &mut out).unwrap();
    drop(link);
    robot.finish();
    let summary: serde_json::Value = serde_json::from_slice(&out).unwrap();
    let rows = summary["rows"].as_u64().unwrap();
    assert!(rows >= 290, "{rows} rows");
    let from_csv = wmr::record::metrics_of_file(&csv).unwrap();
    let from_mcap = wmr::record::metrics_of_file(&mcap).unwrap();
    let j = |m: &wmr::record::MetricsSummary| serde_json::to_value(m).unwrap();
    assert_eq!(j(&from_csv), j(&from_mcap));
    assert_eq!(from_csv.rows as u64, rows);
    assert_eq!(j(&from_csv)["metrics"], summary["metrics"]);
    assert!(from_csv.report.unwrap().metrics.rms_pos_err_m > 0.0);
    let a = ros_mcap::read_log(&csv).unwrap();
    let b = ros_mcap::read_log(&mcap).unwrap();
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(track_log::csv::trace_row(x), track_log::csv::trace_row(y));
    }
}

/// The robot file of the robot on the link sets `base_link` (issue 32):
/// a simulated TB6612 robot (`robots/tb6612-2kg.toml`, d = 0.02 m, not the
/// paper's 0.05) recorded with `record --mcap` and no `--com-offset-m`
/// gives an MCAP whose every `/odom` pose is G moved back by 0.02 m along
/// the heading (G from the same frame's `/wmr/tracking`): the rigid-body
/// relation with the file's d. `session::com_offset_m`, which the ROS 2
/// bridge calls at connection, names the robot; a record pushed without
/// a reboot is not the one in force, so the robot cannot tell d and the
/// paper's is used with that reason; `--com-offset-m` overrides.
#[test]
fn base_link_uses_the_d_of_the_robot_on_the_link() {
    use wmr::session::{com_offset_m, ComOffsetSource, NotKnown};
    let _s = serial();
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../robots/tb6612-2kg.toml");
    let tb = robot_file::Robot::from_toml_str(&std::fs::read_to_string(file).unwrap()).unwrap();
    let d_file = tb.body.com_offset_m as f64;
    assert!(
        (d_file - 0.02).abs() < 1e-9 && (d_file - ros_mcap::default_com_offset_m()).abs() > 0.01
    );
    let robot = Robot::start(&quiet(Sensing::Mocap).with_robots(Some(&tb), None));
    let mut link = robot.link();
    let d = com_offset_m(&mut link, None).unwrap();
    assert_eq!(d.com_offset_m, d_file, "{d}");
    assert_eq!(d.source, ComOffsetSource::Robot(tb.name.as_str().into()));
    assert_eq!(
        com_offset_m(&mut link, Some(0.07)).unwrap().com_offset_m,
        0.07
    );
    // Drive a little so that the heading changes along the log.
    ok(
        &mut link,
        Request::Velocity {
            v_mps: 0.1,
            omega_radps: 0.5,
            timeout_ms: 2000,
        },
    );
    ok(&mut link, Request::Arm);
    let dir = tempfile::tempdir().unwrap();
    let (csv, mcap) = (dir.path().join("r.csv"), dir.path().join("r.mcap"));
    let args = wmr::cli::RecordArgs {
        seconds: 1.0,
        out: csv,
        rate: 50,
        arm: false,
        quiet: true,
        mcap: Some(mcap.clone()),
        com_offset_m: None,
    };
    wmr::cli::record(&args, &mut link, &mut Vec::new()).unwrap();
    // A new record stored without a reboot: the one in force is unknown
    // (pushed in hold: the velocity command may have timed out already).
    let _ = link.command(&Request::Disarm);
    let paper = concat!(env!("CARGO_MANIFEST_DIR"), "/../robots/paper.toml");
    wmr::robot::push(
        &mut link,
        std::path::Path::new(paper),
        true,
        true,
        &mut Vec::new(),
    )
    .unwrap();
    let d = com_offset_m(&mut link, None).unwrap();
    assert!(
        matches!(
            d.source,
            ComOffsetSource::PaperDefault(NotKnown::NotInForce { .. })
        ),
        "{d}"
    );
    assert_eq!(d.com_offset_m, ros_mcap::default_com_offset_m());
    drop(link);
    robot.finish();
    let msgs = ros_mcap::read_messages(&std::fs::read(&mcap).unwrap()).unwrap();
    let mut g_at = std::collections::HashMap::new();
    for m in msgs.iter().filter(|m| m.topic == ros_mcap::TOPIC_TRACKING) {
        let t: ros_mcap::msg::Tracking = ros_mcap::msg::decode(&m.data).unwrap();
        g_at.insert(m.log_time_ns, t.pose);
    }
    let mut checked = 0;
    let mut headings = Vec::new();
    for m in msgs.iter().filter(|m| m.topic == ros_mcap::TOPIC_ODOM) {
        let o: ros_mcap::msg::Odometry = ros_mcap::msg::decode(&m.data).unwrap();
        let g = g_at[&m.log_time_ns];
        let b = o.pose.pose.position;
        let (dx, dy) = (g[0] - b.x, g[1] - b.y);
        // G − base_link = d (cos θ, sin θ).
        assert!(
            (dx.hypot(dy) - d_file).abs() < 1e-6,
            "|G - base_link| {}",
            dx.hypot(dy)
        );
        assert!((dx - d_file * g[2].cos()).abs() < 1e-6 && (dy - d_file * g[2].sin()).abs() < 1e-6);
        headings.push(g[2]);
        checked += 1;
    }
    assert!(checked >= 40, "{checked} /odom messages");
    let span = headings.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - headings.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(span > 0.1, "the heading changed by {span} rad only");
}

/// Longest wall time any wait here may take (a hang fails; a slow
/// machine only waits longer).
const CEILING: Duration = Duration::from_secs(60);

/// Reads for up to 10 ms: the telemetry received so far into `history`
/// (robot time, estimate of G, speed).
fn drain(link: &mut Link, history: &mut Vec<(u32, PoseMsg, f32)>) {
    let first = link.next_stream(Duration::from_millis(10)).unwrap();
    for r in first.into_iter().chain(std::mem::take(&mut link.stream)) {
        if let Reply::Telemetry(t) = r {
            if let Some(tr) = t.tracking {
                history.push((t.t_robot_us, tr.pose, tr.eta[0]));
            }
        }
    }
}

fn status(link: &mut Link) -> StatusMsg {
    match link.command(&Request::GetStatus).unwrap() {
        Reply::Status { status, .. } => status,
        r => panic!("{r:?}"),
    }
}

/// Drives straight at 0.5 m/s (IMU sensing: no pose source of its own, so
/// the estimate is odometry until the host's pose), then feeds one pose
/// line: the estimate at robot time t_c, 80 ms before the line's arrival.
/// Returns the estimator's innovation for it and the speed; also the
/// clock's arrival margin \[µs\].
///
/// Every time is robot time, whatever the machine's speed: the line's
/// arrival is not read from the wall clock, nor the clock re-synced:
/// `feed_lines` is given the clock of one sync and, as the arrival, the
/// host time whose robot time (through the clock sync) is the newest
/// telemetry's stamp, a time the robot has reached. A host starved for
/// longer than the estimator's history (~270 ms of robot time) gets its
/// line refused as too old: it tries again with fresher telemetry.
fn innovation_of_an_80ms_old_pose(with_capture_time: bool) -> ([f32; 3], f64, u64) {
    let robot = Robot::start(&quiet(Sensing::Imu));
    let mut link = robot.link();
    let velocity = Request::Velocity {
        v_mps: 0.5,
        omega_radps: 0.0,
        timeout_ms: 5000,
    };
    ok(&mut link, velocity.clone());
    ok(&mut link, Request::Arm);
    ok(
        &mut link,
        Request::SetTelemetry {
            selection: TELEMETRY_TRACKING,
            rate_hz: 500,
        },
    );
    // Steady speed first.
    let mut history: Vec<(u32, PoseMsg, f32)> = Vec::new();
    let end = Instant::now() + CEILING;
    while history.last().is_none_or(|h| h.0 < 2_000_000) {
        assert!(Instant::now() < end, "no telemetry up to 2 s");
        drain(&mut link, &mut history);
    }
    let t0 = Instant::now();
    let unix_t0_ns = ros_mcap::unix_now_ns();
    let sync = wmr::session::clock_sync(&mut link, t0, 5).unwrap();
    let clock = PoseClock::from_sync(sync, unix_t0_ns, 0.001);
    let (a, arrival_stamp_us) = loop {
        assert!(Instant::now() < end, "no pose line admitted");
        // The command's timeout is robot time: refreshed on every try.
        ok(&mut link, velocity.clone());
        // Telemetry up to now, from at least 100 ms after the sync (so
        // that the capture time is after it).
        let fresh = sync.robot_us as u32 + 100_000;
        while history.last().is_none_or(|h| h.0 < fresh) {
            assert!(Instant::now() < end, "no telemetry after the sync");
            drain(&mut link, &mut history);
        }
        let newest = history.last().unwrap().0;
        // The host time whose arrival stamp is `newest`.
        let arrival = (newest as i64 - clock.offset_us + clock.arrival_margin_us as i64) as u64;
        assert_eq!(clock.robot_stamp_us(Capture::Arrival, arrival), newest);
        let t_c = clock.robot_stamp_us(Capture::AgoS(0.08), arrival);
        let i = history
            .iter()
            .rposition(|h| h.0 <= t_c)
            .expect("telemetry at the capture time");
        let (a, b) = (history[i], history[(i + 1).min(history.len() - 1)]);
        let w = if b.0 > a.0 {
            (t_c - a.0) as f32 / (b.0 - a.0) as f32
        } else {
            0.0
        };
        let lerp = |p: f32, q: f32| p + w * (q - p);
        let (x, y) = (lerp(a.1.x_m, b.1.x_m), lerp(a.1.y_m, b.1.y_m));
        let line = if with_capture_time {
            format!("{x} {y} 0 0.05 0.05 0 @-0.08")
        } else {
            format!("{x} {y} 0 0.05 0.05 0")
        };
        let mut tally = PoseTally::default();
        wmr::pose_feed::feed_lines(
            &mut link,
            |_| Ok((clock, arrival)),
            [0.05, 0.05, 0.0],
            std::iter::once(Ok(line)),
            &mut tally,
        )
        .unwrap();
        match tally.refused_total() {
            0 => break (a, newest),
            // The host was starved past the history: again.
            1 if tally.to_string().contains(ErrorCode::PoseTooOld.reason()) => {
                eprintln!("{tally}: trying again");
            }
            _ => panic!("{tally}"),
        }
    };
    // The robot uses it on its next tick.
    loop {
        let st = status(&mut link);
        assert_eq!(st.pose_rejects, PoseRejects::default(), "{st:?}");
        if st.counters.external_poses > 0 {
            assert!(st.t_robot_us > arrival_stamp_us);
            break;
        }
        assert!(Instant::now() < end, "the pose is never used: {st:?}");
        std::thread::sleep(Duration::from_millis(10));
    }
    drop(link);
    let mut sim = robot.finish();
    let st = sim.device().control().estimator_status();
    assert_eq!(st.accepted, 1, "{st:?}");
    (st.last_innovation, a.2 as f64, clock.arrival_margin_us)
}

/// A pose line with an 80 ms-old capture time (`@-0.08`) is applied at
/// its capture time through the estimator's history: the estimate there
/// is what the line says, so the innovation is ~0 (telemetry every 2 ms
/// interpolated: well under 5 mm at 0.5 m/s). The same line without a
/// capture time is applied at arrival, 80 ms later, where the robot is
/// v·80 ms = 40 mm further along x: the innovation is −v·0.08 (less the
/// arrival margin). Both in robot time (see the helper): the machine's
/// speed changes nothing. (That arrival stamps less the margin are not in
/// the robot's future is `capture_times_map_to_robot_time`'s, in wmr.)
#[test]
fn pose_with_capture_time_is_applied_at_its_capture_time() {
    let _s = serial();
    let (stamped, v, _) = innovation_of_an_80ms_old_pose(true);
    let (arrival, v2, margin_us) = innovation_of_an_80ms_old_pose(false);
    eprintln!(
        "v {v:.3} / {v2:.3} m/s; innovation with capture time {stamped:?}, without {arrival:?}"
    );
    assert!(
        (v - 0.5).abs() < 0.05 && (v2 - 0.5).abs() < 0.05,
        "not at speed: {v}, {v2}"
    );
    assert!(
        stamped[0].abs() < 0.005 && stamped[1].abs() < 0.005,
        "{stamped:?}"
    );
    // Stamped at arrival less the margin (a ms or two): that much less.
    let expect = -(v2 * (0.08 - margin_us as f64 * 1e-6)) as f32;
    assert!(
        (arrival[0] - expect).abs() < 0.008,
        "{arrival:?} vs {expect}"
    );
    assert!(arrival[1].abs() < 0.005, "{arrival:?}");
}
