extern crate std;
use super::*;
use proptest::prelude::*;
use std::format;
use std::string::String;
use std::vec::Vec as StdVec;

fn frame<M: Serialize>(msg: &M, seq: u16) -> StdVec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    encode(msg, seq, &mut buf).unwrap().to_vec()
}

fn decode_all<M: DeserializeOwned>(
    dec: &mut FrameDecoder<MAX_FRAME>,
    bytes: &[u8],
) -> StdVec<Decoded<M>> {
    let mut out = StdVec::new();
    dec.feed_all::<M>(bytes, |d| out.push(d));
    out
}

/// `feed` one call at a time, checking that each call makes progress
/// (an independent loop to hold `feed_all` against).
fn decode_stepwise<M: DeserializeOwned>(
    dec: &mut FrameDecoder<MAX_FRAME>,
    mut bytes: &[u8],
) -> StdVec<Decoded<M>> {
    let mut out = StdVec::new();
    while !bytes.is_empty() {
        let (d, rest) = dec.feed::<M>(bytes);
        assert!(rest.len() < bytes.len() || d.is_some(), "no progress");
        out.extend(d);
        bytes = rest;
    }
    out
}

/// Every variant of `T` by its postcard index: variant i followed by zero
/// bytes decodes (every field's zero value) exactly for i < variant count.
fn variants<T: DeserializeOwned>() -> StdVec<T> {
    let mut out = StdVec::new();
    for i in 0u8..=127 {
        let mut bytes = [0u8; 128];
        bytes[0] = i;
        if let Ok(v) = postcard::from_bytes::<T>(&bytes) {
            out.push(v);
        }
    }
    out
}

fn variant_name<T: core::fmt::Debug>(v: &T) -> String {
    let s = format!("{v:?}");
    s.split(|c: char| !c.is_alphanumeric() && c != '_')
        .next()
        .unwrap()
        .into()
}

fn sample_requests() -> StdVec<Request> {
    let mut pts = heapless::Vec::new();
    for i in 0..SEGMENT_POINTS {
        pts.push(Waypoint {
            t_s: i as f32 * 0.1,
            pose: PoseMsg {
                x_m: 1.5,
                y_m: -2.0,
                theta_rad: 3.1,
            },
            v_mps: -1.25,
            omega_radps: 0.5,
        })
        .unwrap();
    }
    let mut v = variants::<Request>();
    v.push(Request::TrajectorySegment {
        first_index: u32::MAX,
        points: pts,
    });
    v.push(Request::ClockSync {
        host_time_us: u64::MAX,
    });
    // The largest robot-record chunk.
    v.push(Request::RobotChunk {
        offset: u16::MAX,
        data: (0..ROBOT_CHUNK).map(|i| i as u8 | 0x80).collect(),
    });
    v
}

/// The largest robot replies: a full data chunk, a fault with the longest
/// field path and a range.
fn sample_robot_replies() -> StdVec<Reply> {
    let field: String = "x".repeat(ROBOT_FIELD_LEN + 10);
    let fault = RobotFault::new(
        RobotFaultKind::OutOfRange,
        &field,
        Some([f32::MIN, f32::MAX]),
    );
    assert_eq!(fault.field.len(), ROBOT_FIELD_LEN, "cut to the limit");
    std::vec![
        Reply::RobotData {
            seq: u16::MAX,
            total_len: u16::MAX,
            offset: u16::MAX,
            data: (0..ROBOT_CHUNK).map(|i| i as u8 | 0x80).collect(),
        },
        Reply::RobotRejected {
            seq: u16::MAX,
            fault,
        },
        Reply::Status {
            seq: u16::MAX,
            status: StatusMsg {
                state: RunStateMsg::Stopped,
                mode: ModeMsg::Trajectory,
                last_stop: Some(StopCode::Other),
                t_robot_us: u32::MAX,
                buffered_points: u16::MAX,
                counters: Counters {
                    ticks: u32::MAX,
                    run_ticks: u32::MAX,
                    overruns: u32::MAX,
                    max_loop_time_us: u32::MAX,
                    encoder_jumps: u32::MAX,
                    input_faults: u32::MAX,
                    torque_saturated: u32::MAX,
                    duty_saturated: u32::MAX,
                    external_poses: u32::MAX,
                    stops: u32::MAX,
                    rx_frames: u32::MAX,
                    rx_errors: u32::MAX,
                    rx_overflow: u32::MAX,
                    tx_dropped: u32::MAX,
                    nacks: u32::MAX,
                },
                pose_rejects: PoseRejects {
                    non_finite: u32::MAX,
                    bad_std_dev: u32::MAX,
                    from_future: u32::MAX,
                    too_old: u32::MAX,
                    out_of_order: u32::MAX,
                    outlier: u32::MAX,
                },
                nonfinite_telemetry: u32::MAX,
                board: BoardReport {
                    reset_cause: ResetCause::LowPower,
                    port_rx_dropped: u32::MAX,
                    port_rx_errors: u32::MAX,
                },
                robot: RobotReport {
                    source: RobotSource::DefaultCorrupt,
                    active_crc32: u32::MAX,
                    stored_crc32: u32::MAX,
                    writes: u16::MAX,
                    write_failures: u16::MAX,
                },
            },
        },
    ]
}

#[test]
fn every_message_round_trips_through_a_frame() {
    let mut dec = FrameDecoder::<MAX_FRAME>::new();
    for (i, req) in sample_requests().into_iter().enumerate() {
        let bytes = frame(&req, i as u16);
        assert!(bytes.len() <= MAX_FRAME);
        assert_eq!(*bytes.last().unwrap(), 0);
        assert_eq!(
            bytes.iter().filter(|&&b| b == 0).count(),
            1,
            "COBS: one zero"
        );
        let got = decode_all::<Request>(&mut dec, &bytes);
        assert_eq!(
            got,
            [Decoded::Frame {
                seq: i as u16,
                msg: req
            }]
        );
    }
    let mut replies = variants::<Reply>();
    replies.extend(sample_robot_replies());
    replies.push(Reply::Telemetry(Telemetry {
        seq: u32::MAX,
        t_robot_us: u32::MAX,
        t_ref_s: 1.0e6,
        state: RunStateMsg::Stopping,
        tracking: Some(TrackingTelemetry {
            duty: [i32::MIN, i32::MAX],
            ..Default::default()
        }),
        estimators: Some(EstimatorTelemetry::default()),
        counters: Some(Counters {
            ticks: u32::MAX,
            rx_frames: u32::MAX,
            nacks: u32::MAX,
            ..Default::default()
        }),
        covariance: Some(CovarianceTelemetry::default()),
    }));
    for r in replies {
        let bytes = frame(&r, 7);
        assert!(bytes.len() <= MAX_FRAME, "{r:?}: {}", bytes.len());
        assert_eq!(
            decode_all::<Reply>(&mut dec, &bytes),
            [Decoded::Frame { seq: 7, msg: r }]
        );
    }
}

#[test]
fn the_enumeration_finds_every_variant() {
    // Guards the doc test below: it must see all of them.
    assert_eq!(variants::<Request>().len(), 22);
    assert_eq!(variants::<Reply>().len(), 13);
    assert_eq!(variants::<ParamId>().len(), ParamId::ALL.len());
    for (p, q) in variants::<ParamId>().into_iter().zip(ParamId::ALL) {
        assert_eq!(p, q);
        assert_eq!(ParamId::from_name(p.name()), Some(p));
    }
}

/// Every variant of every message enum, and every parameter name and error
/// code, has its entry in book/src/reference/protocol.md: adding one without documenting
/// it fails here.
#[test]
fn every_message_is_documented() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../book/src/reference/protocol.md"
    );
    let doc = std::fs::read_to_string(path).expect("book/src/reference/protocol.md");
    // The wire layout, generated from the types, names every variant: the
    // hand-written description of each must be elsewhere.
    let (head, rest) = doc
        .split_once("<!-- wire-layout begin")
        .expect("wire-layout begin");
    let (_, tail) = rest
        .split_once("<!-- wire-layout end -->")
        .expect("wire-layout end");
    let doc = format!("{head}{tail}");
    let mut missing = StdVec::new();
    let mut check = |kind: &str, name: String| {
        let entry = if kind == "name" {
            format!("`{name}`")
        } else {
            format!("`{kind}::{name}`")
        };
        if !doc.contains(&entry) {
            missing.push(entry);
        }
    };
    variants::<Request>()
        .iter()
        .for_each(|v| check("Request", variant_name(v)));
    variants::<Reply>()
        .iter()
        .for_each(|v| check("Reply", variant_name(v)));
    variants::<ErrorCode>()
        .iter()
        .for_each(|v| check("ErrorCode", variant_name(v)));
    variants::<Event>()
        .iter()
        .for_each(|v| check("Event", variant_name(v)));
    variants::<StopCode>()
        .iter()
        .for_each(|v| check("StopCode", variant_name(v)));
    variants::<RunStateMsg>()
        .iter()
        .for_each(|v| check("RunStateMsg", variant_name(v)));
    variants::<ModeMsg>()
        .iter()
        .for_each(|v| check("ModeMsg", variant_name(v)));
    variants::<BuiltinShape>()
        .iter()
        .for_each(|v| check("BuiltinShape", variant_name(v)));
    variants::<RobotFaultKind>()
        .iter()
        .for_each(|v| check("RobotFaultKind", variant_name(v)));
    variants::<RobotSource>()
        .iter()
        .for_each(|v| check("RobotSource", variant_name(v)));
    for p in ParamId::ALL {
        check("ParamId", variant_name(&p));
        check("name", p.name().into());
    }
    assert!(
        missing.is_empty(),
        "book/src/reference/protocol.md lacks {missing:?}"
    );
    assert!(doc.contains(&format!("PROTOCOL_VERSION = {PROTOCOL_VERSION}")));
}

#[test]
fn version_mismatch_is_reported_with_the_hello_still_readable() {
    let mut buf = [0u8; MAX_FRAME];
    let f = encode_with_version(&Request::Hello { version: 9 }, 3, 9, &mut buf)
        .unwrap()
        .to_vec();
    let mut dec = FrameDecoder::<MAX_FRAME>::new();
    assert_eq!(
        decode_all::<Request>(&mut dec, &f),
        [Decoded::OtherVersion {
            seq: 3,
            version: 9,
            msg: Some(Request::Hello { version: 9 })
        }]
    );
}

#[test]
fn oversized_frame_is_dropped_and_the_next_one_decodes() {
    let mut dec = FrameDecoder::<MAX_FRAME>::new();
    let mut bytes = std::vec![0x55u8; 3 * MAX_FRAME];
    bytes.push(0);
    bytes.extend(frame(&Request::Arm, 5));
    // Fed in small chunks, as a UART delivers them.
    let mut got = StdVec::new();
    for chunk in bytes.chunks(7) {
        got.extend(decode_all::<Request>(&mut dec, chunk));
    }
    assert_eq!(
        got,
        [
            Decoded::Error {
                seq: None,
                error: ErrorCode::TooLong
            },
            Decoded::Frame {
                seq: 5,
                msg: Request::Arm
            }
        ]
    );
}

proptest! {
    /// Random bytes: never a panic, always progress, never more outcomes
    /// than delimiters (+1 for an overflow).
    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2000)) {
        let mut dec = FrameDecoder::<MAX_FRAME>::new();
        let got = decode_all::<Request>(&mut dec, &bytes);
        let zeros = bytes.iter().filter(|&&b| b == 0).count();
        prop_assert!(got.len() <= zeros + bytes.len() / MAX_FRAME + 1);
    }

    /// `feed_all` gives exactly the outcomes of calling `feed` until the
    /// input is used up, whatever the chunking of a stream of good,
    /// damaged and garbage bytes.
    #[test]
    fn feed_all_is_the_feed_loop(
        garbage in proptest::collection::vec(any::<u8>(), 0..300),
        flip in any::<prop::sample::Index>(),
        chunk in 1usize..64,
    ) {
        let mut bytes = StdVec::new();
        for (i, r) in sample_requests().iter().take(4).enumerate() {
            bytes.extend(frame(r, i as u16));
        }
        let n = bytes.len();
        bytes[flip.index(n)] ^= 0x10;
        bytes.extend(&garbage);
        bytes.extend(frame(&Request::Arm, 9));
        let mut a = FrameDecoder::<MAX_FRAME>::new();
        let mut whole = StdVec::new();
        for c in bytes.chunks(chunk) {
            a.feed_all::<Request>(c, |d| whole.push(d));
        }
        let mut b = FrameDecoder::<MAX_FRAME>::new();
        let stepwise = decode_stepwise::<Request>(&mut b, &bytes);
        prop_assert_eq!(whole, stepwise);
    }

    /// One flipped bit anywhere in a frame is never accepted as a
    /// different valid message: it is dropped (CRC, COBS or decode error),
    /// or decodes to the very same message (a flip in COBS overhead that
    /// cancels out cannot happen, but the check is what matters).
    #[test]
    fn corrupted_frames_are_rejected(
        idx in 0usize..SEGMENT_POINTS + 2, byte in any::<prop::sample::Index>(), bit in 0u8..8,
    ) {
        let reqs = sample_requests();
        let req = &reqs[idx % reqs.len()];
        let mut f = frame(req, 42);
        let n = f.len() - 1; // keep the delimiter
        let i = byte.index(n);
        f[i] ^= 1 << bit;
        let mut dec = FrameDecoder::<MAX_FRAME>::new();
        let got = decode_all::<Request>(&mut dec, &f);
        for d in got {
            match d {
                Decoded::Frame { seq, msg } => prop_assert!(seq == 42 && &msg == req, "accepted {msg:?}"),
                Decoded::OtherVersion { .. } => prop_assert!(false, "version bit survived the CRC"),
                Decoded::Error { .. } => {}
            }
        }
    }

    /// A frame cut anywhere and followed by a good one: the good one
    /// always decodes.
    #[test]
    fn truncated_frame_then_good_frame(cut in any::<prop::sample::Index>()) {
        let reqs = sample_requests();
        let long = frame(reqs.last().unwrap(), 1);
        let mut bytes = long[..cut.index(long.len() - 1)].to_vec();
        bytes.push(0);
        bytes.extend(frame(&Request::Disarm, 2));
        let mut dec = FrameDecoder::<MAX_FRAME>::new();
        let got = decode_all::<Request>(&mut dec, &bytes);
        prop_assert_eq!(got.last(), Some(&Decoded::Frame { seq: 2, msg: Request::Disarm }));
    }
}

/// `Telemetry::is_finite` sees a NaN or an infinity in every float of
/// every group (the device's last check before a frame goes out).
#[test]
fn telemetry_finiteness_checks_every_float() {
    let ok = Telemetry {
        seq: 1,
        t_robot_us: 2,
        t_ref_s: 0.5,
        state: RunStateMsg::Running,
        tracking: Some(TrackingTelemetry::default()),
        estimators: Some(EstimatorTelemetry::default()),
        counters: Some(Counters::default()),
        covariance: Some(CovarianceTelemetry::default()),
    };
    assert!(ok.is_finite());
    let mut bad: StdVec<Telemetry> = StdVec::new();
    for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let tr = TrackingTelemetry::default();
        let tracking = [
            TrackingTelemetry {
                pose: PoseMsg {
                    x_m: x,
                    ..PoseMsg::default()
                },
                ..tr
            },
            TrackingTelemetry {
                ref_pose: PoseMsg {
                    theta_rad: x,
                    ..PoseMsg::default()
                },
                ..tr
            },
            TrackingTelemetry {
                error: [0.0, 0.0, x],
                ..tr
            },
            TrackingTelemetry {
                eta: [x, 0.0],
                ..tr
            },
            TrackingTelemetry {
                eta_c: [0.0, x],
                ..tr
            },
            TrackingTelemetry {
                torque_nm: [x, 0.0],
                ..tr
            },
            TrackingTelemetry {
                time_scale: x,
                ..tr
            },
            TrackingTelemetry { tau_s: x, ..tr },
        ];
        for t in tracking {
            bad.push(Telemetry {
                tracking: Some(t),
                ..ok
            });
        }
        let es = EstimatorTelemetry::default();
        for e in [
            EstimatorTelemetry { s: [x, 0.0], ..es },
            EstimatorTelemetry {
                rho_hat: [0.0, x],
                ..es
            },
            EstimatorTelemetry {
                d_hat: [x, 0.0],
                ..es
            },
            EstimatorTelemetry {
                f_hat: [0.0, x],
                ..es
            },
        ] {
            bad.push(Telemetry {
                estimators: Some(e),
                ..ok
            });
        }
        bad.push(Telemetry { t_ref_s: x, ..ok });
        for k in 0..8 {
            let mut c = [0.0f32; 8];
            c[k] = x;
            bad.push(Telemetry {
                covariance: Some(CovarianceTelemetry::from_f32(
                    [c[0], c[1], c[2], c[3], c[4], c[5]],
                    [c[6], c[7]],
                )),
                ..ok
            });
        }
    }
    for t in bad {
        assert!(!t.is_finite(), "{t:?}");
    }
}

/// The wire ids are the parameter table's wire order (issue 32): a new
/// parameter or a reorder cannot change an id on the link.
#[test]
fn param_ids_are_the_tables_wire_order() {
    use controller_core::runtime::param_table::WIRE;
    assert_eq!(ParamId::ALL.len(), WIRE.len());
    for (i, id) in ParamId::ALL.into_iter().enumerate() {
        assert!(core::ptr::eq(id.param(), WIRE[i]), "{id:?}");
        assert_eq!(id.param().wire, Some(i as u8));
        // postcard writes the variant index: the wire id.
        let mut buf = [0u8; 4];
        let bytes = postcard::to_slice(&id, &mut buf).unwrap();
        assert_eq!(bytes, &[i as u8]);
        assert_eq!(ParamId::from_name(id.name()), Some(id));
    }
    assert_eq!(ParamId::TorqueLimitNm.name(), "limits.torque_nm");
    assert_eq!(ParamId::AccelMps2.name(), "limits.max_accel_mps2");
}

/// The largest telemetry frame the robot can send (every group, every
/// varint at its longest, a signed duty at both extremes) fits the body
/// limit: a frame that did not would never leave the robot. Protocol 5's
/// covariance group is what had to fit (16 bytes, D155).
#[test]
fn the_largest_telemetry_frame_fits() {
    let m = u32::MAX;
    let t = Telemetry {
        seq: m,
        t_robot_us: m,
        t_ref_s: f32::MAX,
        state: RunStateMsg::Stopped,
        tracking: Some(TrackingTelemetry {
            duty: [i32::MIN, i32::MIN],
            saturated: true,
            health: u8::MAX,
            health_reason: u8::MAX,
            ..Default::default()
        }),
        estimators: Some(EstimatorTelemetry {
            external_pose: true,
            input_fault: true,
            ..Default::default()
        }),
        counters: Some(Counters {
            ticks: m,
            run_ticks: m,
            overruns: m,
            max_loop_time_us: m,
            encoder_jumps: m,
            input_faults: m,
            torque_saturated: m,
            duty_saturated: m,
            external_poses: m,
            stops: m,
            rx_frames: m,
            rx_errors: m,
            rx_overflow: m,
            tx_dropped: m,
            nacks: m,
        }),
        covariance: Some(CovarianceTelemetry::from_f32([f32::MAX; 6], [f32::MIN; 2])),
    };
    let mut buf = [0u8; 512];
    let body = postcard::to_slice(&Reply::Telemetry(t), &mut buf).unwrap();
    assert!(body.len() <= MAX_BODY, "{} > {MAX_BODY}", body.len());
    let bytes = frame(&Reply::Telemetry(t), u16::MAX);
    assert!(bytes.len() <= MAX_FRAME);
    let c = CovarianceTelemetry::default();
    assert_eq!(postcard::to_slice(&c, &mut buf).unwrap().len(), 16);
}

/// bfloat16 against its definition: every value within 2^-8 relative
/// (round to nearest), the values bfloat16 holds exactly kept exactly,
/// ties to even, NaN and infinities kept, f32::MAX rounded up to infinity.
#[test]
fn bf16_rounds_to_nearest() {
    let mut x = 1.0e-30f32;
    while x < 1.0e30 {
        for v in [x, -x, x * 1.2345, x * 1.999] {
            let r = Bf16::from_f32(v).to_f32();
            assert!((r - v).abs() <= v.abs() / 256.0, "{v} -> {r}");
        }
        x *= 3.7;
    }
    for v in [
        0.0f32,
        -0.0,
        1.0,
        -2.5,
        0.0078125,
        3.0e38_f32.min(f32::MAX / 2.0),
    ] {
        let exact = f32::from_bits(v.to_bits() & 0xFFFF_0000);
        assert_eq!(Bf16::from_f32(exact).to_f32().to_bits(), exact.to_bits());
    }
    // 1 + 2^-8 lies halfway between 1 and 1 + 2^-7: ties to even (1).
    assert_eq!(Bf16::from_f32(1.0 + 1.0 / 256.0).to_f32(), 1.0);
    assert_eq!(
        Bf16::from_f32(1.0 + 3.0 / 256.0).to_f32(),
        1.0 + 4.0 / 256.0
    );
    assert!(Bf16::from_f32(f32::NAN).to_f32().is_nan());
    let nan_low = f32::from_bits(0x7F80_0001);
    assert!(Bf16::from_f32(nan_low).to_f32().is_nan());
    assert_eq!(Bf16::from_f32(f32::INFINITY).to_f32(), f32::INFINITY);
    assert_eq!(
        Bf16::from_f32(f32::NEG_INFINITY).to_f32(),
        f32::NEG_INFINITY
    );
    assert_eq!(Bf16::from_f32(f32::MAX).to_f32(), f32::INFINITY);
}
