use super::*;
use crate::msg::*;
use wmr_protocol::{RunStateMsg, StopCode};

fn geom() -> Geometry {
    Geometry::new(0.1, 0.2, 0.05).unwrap()
}

fn row(k: usize) -> TraceSample {
    let t = k as f64 * 0.01;
    TraceSample {
        t_s: t,
        ref_pose: [t.cos(), t.sin(), t],
        pose: [t.cos() + 0.01, t.sin(), t + 0.001],
        pos_err_m: 0.01 + 1e-17 * k as f64,
        err_xy_m: [-0.01, 0.0],
        e: [0.1, -0.2, 0.3],
        eta: [0.5, 0.25],
        eta_c: [0.5, 0.2],
        torque_nm: [(k as f64).sin(), -(k as f64).cos()],
        s: [1e-3, f64::NAN],
        rho_hat: [0.1, 0.2],
        d_hat: [f64::MIN_POSITIVE, -1e300],
        f_hat: [0.01, -0.02],
        f_true: [f64::NAN, f64::NAN],
        saturated: k % 3 == 0,
        time_scale: 1.0 - 1e-3 * k as f64,
        tau_s: t * 0.99,
        health: (k / 40 % 3) as u8,
        health_reason: (k / 40 % 9) as u8,
    }
}

fn frame(k: usize, state: RunStateMsg) -> LogFrame {
    LogFrame {
        stamp_ns: 1_700_000_000_000_000_000 + k as u64 * 10_000_000,
        sample: row(k),
        duty: Some([k as i32, -(k as i32)]),
        external_pose: k % 2 == 0,
        input_fault: false,
        diag: DiagFrame {
            state,
            last_stop: None,
            counters: None,
        },
        covariance: None,
    }
}

fn same(a: &TraceSample, b: &TraceSample) -> bool {
    // Bit for bit, NaN equal to NaN.
    let bits = |s: &TraceSample| format!("{:?}", track_log::csv::trace_row(s));
    bits(a) == bits(b)
}

fn write(frames: &[LogFrame]) -> (Vec<u8>, LogStats) {
    let mut buf = std::io::Cursor::new(Vec::new());
    let mut log = McapLog::new(&mut buf, geom(), "test").unwrap();
    for f in frames {
        log.write(f).unwrap();
    }
    let stats = log.finish().unwrap();
    (buf.into_inner(), stats)
}

/// Written and read back, the running and stopping rows come back bit for
/// bit (the hold rows are not rows of the CSV either).
#[test]
fn trace_round_trip_is_exact_and_keeps_only_running_rows() {
    let mut frames: Vec<LogFrame> = (0..300).map(|k| frame(k, RunStateMsg::Running)).collect();
    frames[0].diag.state = RunStateMsg::Hold;
    frames[299].diag.state = RunStateMsg::Stopping;
    let (bytes, stats) = write(&frames);
    assert_eq!(stats.frames, 300);
    let back = read_trace(&bytes).unwrap();
    assert_eq!(back.len(), 299);
    for (a, b) in frames[1..].iter().zip(&back) {
        assert!(same(&a.sample, b), "{:?}\n{:?}", a.sample, b);
    }
    // The metrics of both are the metrics of the same rows.
    let rows: Vec<TraceSample> = frames[1..].iter().map(|f| f.sample).collect();
    assert_eq!(
        track_log::metrics_from_trace(&rows, [0.0, 0.0], false),
        track_log::metrics_from_trace(&back, [0.0, 0.0], false)
    );
}

/// Every topic gets one message per frame, `/diagnostics` on a change of
/// health (every 40 frames here) and otherwise once a second: 300 frames
/// 10 ms apart are 3 s.
#[test]
fn topics_times_and_diagnostics_rate() {
    let frames: Vec<LogFrame> = (0..300).map(|k| frame(k, RunStateMsg::Running)).collect();
    let (bytes, stats) = write(&frames);
    let msgs = read_messages(&bytes).unwrap();
    let count = |t: &str| msgs.iter().filter(|m| m.topic == t).count();
    for t in [TOPIC_ODOM, TOPIC_TF, TOPIC_JOINT_STATES, TOPIC_TRACKING] {
        assert_eq!(count(t), 300, "{t}");
    }
    // Health changes at frames 40, 80, ..., 280 (7 changes); within each
    // 40-frame (0.4 s) stretch no 1 s period passes: 1 + 7 messages.
    assert_eq!(count(TOPIC_DIAGNOSTICS), 8);
    assert_eq!(stats.diagnostics, 8);
    assert_eq!(stats.messages as usize, msgs.len());
    // Log time = header stamp = the frame's stamp.
    for m in msgs.iter().filter(|m| m.topic == TOPIC_ODOM) {
        let o: Odometry = decode(&m.data).unwrap();
        assert_eq!(o.header.stamp.to_ns(), m.log_time_ns);
        assert_eq!(m.schema, "nav_msgs/msg/Odometry");
    }
}

/// Constant health: one diagnostics message per second of log time.
#[test]
fn diagnostics_once_a_second_without_changes() {
    let frames: Vec<LogFrame> = (0..1000)
        .map(|k| {
            let mut f = frame(k, RunStateMsg::Running);
            f.sample.health = 0;
            f.sample.health_reason = 0;
            f
        })
        .collect();
    let (bytes, _) = write(&frames);
    let n = read_messages(&bytes)
        .unwrap()
        .iter()
        .filter(|m| m.topic == TOPIC_DIAGNOSTICS)
        .count();
    // 10 s of frames: at 0, 1, ..., 9 s.
    assert_eq!(n, 10);
}

/// base_link is the axle midpoint d behind G; the wheel angles are the
/// integral of (v ± hω)/r: at v = 0.5 m/s, ω = 0.25 rad/s for 2.99 s the
/// right wheel turns (0.5 + 0.05)/0.1 · 2.99 rad.
#[test]
fn odometry_is_of_the_axle_and_joints_integrate_the_wheel_rates() {
    let frames: Vec<LogFrame> = (0..300).map(|k| frame(k, RunStateMsg::Running)).collect();
    let (bytes, _) = write(&frames);
    let msgs = read_messages(&bytes).unwrap();
    let odo: Vec<Odometry> = msgs
        .iter()
        .filter(|m| m.topic == TOPIC_ODOM)
        .map(|m| decode(&m.data).unwrap())
        .collect();
    for (o, f) in odo.iter().zip(&frames) {
        let g = f.sample.pose;
        let p = o.pose.pose.position;
        // |G − O_B| = d along the heading.
        assert!(((g[0] - p.x).hypot(g[1] - p.y) - 0.05).abs() < 1e-12);
        assert!(((g[1] - p.y).atan2(g[0] - p.x) - g[2]).abs() < 1e-9);
        assert!((o.pose.pose.orientation.yaw() - g[2]).abs() < 1e-12);
        assert_eq!(o.header.frame_id, FRAME_ODOM);
        assert_eq!(o.child_frame_id, FRAME_BASE);
        assert_eq!(o.twist.twist.linear.x, f.sample.eta[0]);
        assert_eq!(o.twist.twist.angular.z, f.sample.eta[1]);
        assert_eq!(o.pose.covariance.to_array()[35], POSE_COVARIANCE[5]);
    }
    let last: JointState = msgs
        .iter()
        .rev()
        .find(|m| m.topic == TOPIC_JOINT_STATES)
        .map(|m| decode(&m.data).unwrap())
        .unwrap();
    assert_eq!(last.name, WHEEL_JOINTS);
    assert!(
        (last.position[0] - 5.5 * 2.99).abs() < 1e-9,
        "{:?}",
        last.position
    );
    assert!((last.position[1] - 4.5 * 2.99).abs() < 1e-9);
    assert_eq!(last.velocity, vec![5.5, 4.5]);
    let tf: TfMessage = msgs
        .iter()
        .find(|m| m.topic == TOPIC_TF)
        .map(|m| decode(&m.data).unwrap())
        .unwrap();
    assert_eq!(
        tf.transforms[0].transform.translation.x,
        odo[0].pose.pose.position.x
    );
}

#[test]
fn diagnostics_report_stop_counters_and_level() {
    let mut f = frame(0, RunStateMsg::Stopped);
    f.diag.last_stop = Some(StopCode::EncoderJump);
    f.diag.counters = Some(wmr_protocol::Counters {
        encoder_jumps: 3,
        ..Default::default()
    });
    let (bytes, _) = write(&[f]);
    let m = read_messages(&bytes)
        .unwrap()
        .into_iter()
        .find(|m| m.topic == TOPIC_DIAGNOSTICS)
        .unwrap();
    let d: DiagnosticArray = decode(&m.data).unwrap();
    let s = &d.status[0];
    assert_eq!(s.level, DiagnosticStatus::ERROR);
    let v = |k: &str| {
        s.values
            .iter()
            .find(|kv| kv.key == k)
            .unwrap()
            .value
            .clone()
    };
    assert_eq!(v("last_stop"), "EncoderJump");
    assert_eq!(v("encoder_jumps"), "3");
    assert_eq!(v("state"), "Stopped");
}

#[test]
fn time_map_unwraps_the_robot_clock() {
    let mut m = TimeMap::new(u32::MAX - 999, 5_000_000_000);
    assert_eq!(m.host_ns(u32::MAX - 999), 5_000_000_000);
    // 2000 µs later the u32 clock has wrapped.
    assert_eq!(m.host_ns(1000), 5_000_000_000 + 2_000_000);
    assert_eq!(m.host_ns(2000), 5_000_000_000 + 3_000_000);
}

/// The geometry's ranges are the robot file's (the parameter table's):
/// each refusal names the field, the value, the limit and what to set,
/// and so does a `--com-offset-m` flag's value.
#[test]
fn bad_geometry_and_bad_files_are_clear_errors() {
    let e = Geometry::new(0.0, 0.2, 0.05).unwrap_err().to_string();
    assert!(
        e.contains("body.wheel_radius_m: 0 m is below its limit 0.005 m"),
        "{e}"
    );
    let e = Geometry::new(0.1, f64::NAN, 0.05).unwrap_err().to_string();
    assert!(e.contains("body.track_m"), "{e}");
    let e = Geometry::new(0.1, 0.2, -0.1).unwrap_err().to_string();
    assert!(
        e.contains("body.com_offset_m: -0.1 m is below its limit 0 m"),
        "{e}"
    );
    let e = Geometry::new(0.1, 0.2, 3.0).unwrap_err().to_string();
    assert!(e.contains("above its limit 2 m"), "{e}");
    assert_eq!(parse_com_offset_m("0.02"), Ok(0.02));
    let e = parse_com_offset_m("3").unwrap_err();
    assert!(
        e.contains("body.com_offset_m: 3 m is above its limit 2 m: set a value in [0, 2] m"),
        "{e}"
    );
    let e = parse_com_offset_m("two").unwrap_err();
    assert!(e.contains("not a number"), "{e}");
    assert!(parse_com_offset_m("NaN").is_err());
    assert!(read_trace(b"t_s,x\n")
        .unwrap_err()
        .to_string()
        .contains("not an MCAP"));
    let (bytes, _) = write(&[frame(0, RunStateMsg::Running)]);
    // Cut short: an error, not a panic.
    assert!(read_trace(&bytes[..bytes.len() / 2]).is_err());
}

/// The simulator's writer stamps each row at the start plus its time.
#[test]
fn sim_trace_file_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("sim.mcap");
    let rows: Vec<TraceSample> = (0..50).map(row).collect();
    let stats = write_sim_trace(&p, geom(), &rows, 1_000_000_000).unwrap();
    assert_eq!(stats.frames, 50);
    let back = read_log(&p).unwrap();
    assert!(rows.iter().zip(&back).all(|(a, b)| same(a, b)));
    let msgs = read_messages(&std::fs::read(&p).unwrap()).unwrap();
    let last = msgs
        .iter()
        .rev()
        .find(|m| m.topic == TOPIC_TRACKING)
        .unwrap();
    assert_eq!(last.log_time_ns, 1_000_000_000 + 490_000_000);
}

/// A protocol-5 frame's covariance group reaches `/odom`: the x, y, yaw
/// block is the estimator's (symmetric, at the 6×6 positions x = 0,
/// y = 1, yaw = 5), the twist's v and ω variances likewise, 10⁶ for the
/// axes a planar robot does not estimate; a frame without it keeps the
/// fixed diagonals.
#[test]
fn estimator_covariance_fills_odom() {
    use wmr_protocol::{CovarianceTelemetry, Telemetry, TrackingTelemetry};
    let pose = [4e-4, 1e-5, -2e-4, 9e-4, 3e-4, 2.5e-3];
    let twist = [1e-3, 4e-6];
    let mut t = Telemetry {
        seq: 1,
        t_robot_us: 1000,
        t_ref_s: 0.0,
        state: RunStateMsg::Running,
        tracking: Some(TrackingTelemetry::default()),
        estimators: None,
        counters: None,
        covariance: Some(CovarianceTelemetry::from_f32(pose, twist)),
    };
    let f = LogFrame::of_telemetry(&t, 1_000, None).unwrap();
    let m = RosFrames::new(geom()).messages(&f);
    let p = m.odom.pose.covariance.to_array();
    let w = m.odom.twist.covariance.to_array();
    let at = |i: usize, j: usize| 6 * i + j;
    let want = [(0, 0), (0, 1), (0, 5), (1, 1), (1, 5), (5, 5)];
    for (k, (i, j)) in want.into_iter().enumerate() {
        // bfloat16 on the wire: within 2^-8 relative.
        assert!((p[at(i, j)] - pose[k] as f64).abs() <= pose[k].abs() as f64 / 256.0);
        assert_eq!(p[at(i, j)], p[at(j, i)], "symmetric at ({i}, {j})");
    }
    for i in 2..5 {
        assert_eq!(p[at(i, i)], 1e6);
        assert_eq!(w[at(i, i)], 1e6);
    }
    assert!((w[0] - 1e-3).abs() <= 1e-3 / 256.0);
    assert!((w[35] - 4e-6).abs() <= 4e-6 / 256.0);
    // 3 variances, 3 covariances twice, 3 unknowns: nothing else.
    assert_eq!(p.iter().filter(|v| **v != 0.0).count(), 3 + 2 * 3 + 3);
    t.covariance = None;
    let f = LogFrame::of_telemetry(&t, 1_000, None).unwrap();
    let m = RosFrames::new(geom()).messages(&f);
    assert_eq!(
        m.odom.pose.covariance,
        msg::Covariance::diagonal(POSE_COVARIANCE)
    );
    assert_eq!(
        m.odom.twist.covariance,
        msg::Covariance::diagonal(TWIST_COVARIANCE)
    );
}
