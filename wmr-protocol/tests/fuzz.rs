//! Frame-decoder fuzz (issue 21, acceptance): random bytes, corrupted,
//! truncated and oversized frames, fed in random chunks. The decoder never
//! panics, always makes progress, and resynchronises: a valid frame after any garbage and a
//! delimiter decodes. Cases per property: `WMR_FUZZ_CASES` (default 20,000;
//! e.g. `WMR_FUZZ_CASES=10000000 cargo test --release -p wmr-protocol
//! --test fuzz` runs for hours).

use proptest::prelude::*;
use wmr_protocol::*;

fn fuzz_cases(default: u32) -> u32 {
    std::env::var("WMR_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

fn frame(req: &Request, seq: u16) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    encode(req, seq, &mut buf).unwrap().to_vec()
}

fn a_request() -> impl Strategy<Value = Request> {
    prop_oneof![
        Just(Request::GetStatus),
        Just(Request::Arm),
        (any::<u32>(), any::<f32>(), any::<f32>()).prop_map(|(t, x, s)| Request::ExternalPose {
            t_robot_us: t,
            pose: PoseMsg {
                x_m: x,
                y_m: -x,
                theta_rad: s
            },
            std_dev: [s, s, x],
        }),
        (any::<u32>(), 0usize..=8).prop_map(|(first, n)| Request::TrajectorySegment {
            first_index: first,
            points: (0..n)
                .map(|i| Waypoint {
                    t_s: i as f32,
                    ..Waypoint::default()
                })
                .collect(),
        }),
        (any::<f32>(), any::<f32>(), any::<u16>()).prop_map(|(v, w, t)| Request::Velocity {
            v_mps: v,
            omega_radps: w,
            timeout_ms: t
        }),
        // The robot record (protocol 4): chunks of any bytes (zeros
        // included: COBS must carry them), begin/read at any offset.
        (
            any::<u16>(),
            proptest::collection::vec(any::<u8>(), 0..=ROBOT_CHUNK)
        )
            .prop_map(|(offset, data)| Request::RobotChunk {
                offset,
                data: data.into_iter().collect(),
            }),
        any::<u16>().prop_map(|total_len| Request::RobotBegin { total_len }),
        any::<u16>().prop_map(|offset| Request::RobotRead { offset }),
        Just(Request::RobotCommit),
        Just(Request::Reboot),
    ]
}

/// Feeds `bytes` in chunks of the given sizes (cycled); returns every
/// outcome.
fn feed_all(
    dec: &mut FrameDecoder<MAX_FRAME>,
    bytes: &[u8],
    chunks: &[usize],
) -> Vec<Decoded<Request>> {
    let mut out = Vec::new();
    let mut rest = bytes;
    let mut k = 0;
    while !rest.is_empty() {
        let n = chunks[k % chunks.len()].clamp(1, rest.len());
        k += 1;
        let mut chunk = &rest[..n];
        rest = &rest[n..];
        while !chunk.is_empty() {
            let before = chunk.len();
            let (d, r) = dec.feed::<Request>(chunk);
            // Progress: input consumed or an outcome produced.
            assert!(r.len() < before || d.is_some(), "no progress");
            chunk = r;
            out.extend(d);
        }
    }
    out
}

fn same_frame(d: &Decoded<Request>, seq: u16, msg: &Request) -> bool {
    // Compared through the wire: NaN fields make `==` false.
    match d {
        Decoded::Frame { seq: s, msg: m } => *s == seq && frame(m, *s) == frame(msg, seq),
        _ => false,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: fuzz_cases(20_000), ..ProptestConfig::default() })]

    /// Garbage, a delimiter, then a valid frame: the frame decodes,
    /// whatever came before and however the bytes are chunked.
    #[test]
    fn garbage_never_hides_the_next_frame(
        garbage in proptest::collection::vec(any::<u8>(), 0..700),
        req in a_request(),
        seq in any::<u16>(),
        chunks in proptest::collection::vec(1usize..300, 1..8),
    ) {
        let mut dec = FrameDecoder::<MAX_FRAME>::new();
        let mut bytes = garbage;
        bytes.push(0);
        bytes.extend(frame(&req, seq));
        let out = feed_all(&mut dec, &bytes, &chunks);
        let last = out.last().expect("an outcome");
        prop_assert!(same_frame(last, seq, &req), "{:?}", last);
    }

    /// A valid frame with bytes flipped or cut, then a valid one: no
    /// panic, and the valid frame decodes. (That the CRC catches the change
    /// is not asserted per case: CRC-16 lets about 1 in 65,536 corrupted
    /// envelopes through, which millions of cases would hit.)
    #[test]
    fn corrupted_frames_are_caught(
        a in a_request(),
        b in a_request(),
        flips in proptest::collection::vec((any::<usize>(), 1u8..=255), 0..4),
        cut in any::<usize>(),
        chunks in proptest::collection::vec(1usize..300, 1..8),
    ) {
        let fa = frame(&a, 1);
        let mut bad = fa[..fa.len() - 1].to_vec();
        for (i, x) in &flips {
            let n = bad.len();
            bad[i % n] ^= x;
        }
        let keep = if flips.is_empty() { cut % bad.len() } else { bad.len() };
        bad.truncate(keep);
        bad.retain(|&x| x != 0); // one frame: no delimiter inside
        bad.push(0);
        bad.extend(frame(&b, 2));
        let mut dec = FrameDecoder::<MAX_FRAME>::new();
        let out = feed_all(&mut dec, &bad, &chunks);
        let last = out.last().expect("an outcome");
        prop_assert!(same_frame(last, 2, &b), "{:?}", last);
    }
}
