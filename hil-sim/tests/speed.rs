//! `hil-sim device --pty --speed N` with `wmr record --arm` (issue 32): the
//! binary serves the simulated robot N times faster than real time, the
//! host (wmr's own record loop, as the CLI opens the link) keeps it alive
//! on its wall clock, and the run is recorded to its end at every speed.
//! Before, the device counted the link timeout in robot time: the host's
//! keep-alive every fifth of the timeout (wall) was a whole timeout of
//! robot time at N = 5, and the run ended in `Hold (LinkSilence)`.
//!
//! Nothing here depends on how fast the machine is: a robot that cannot
//! reach N (a loaded machine, or N = 1000, which none reaches) runs slower,
//! which only lengthens the host's durations in wall time; every wait is
//! on an event with a generous ceiling.

use std::io::Read;
use std::process::{Child, Command, Stdio};
use wmr::serve::{open_link, Endpoint};
use wmr_protocol::{
    named_shape, BuiltinReference, Reply, Request, RunStateMsg, StopCode, PROTOCOL_VERSION,
};

/// Robot time recorded per run \[s\]: 20 link timeouts of the paper robot
/// (500 ms), 50 keep-alive periods of the host.
const RECORD_S: f64 = 10.0;

/// The binary on a pty at `speed`; its pty path (the first stdout line).
fn device(speed: f64) -> (Child, String) {
    let scenario = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/link_nominal.toml"
    );
    let mut child = Command::new(env!("CARGO_BIN_EXE_hil-sim"))
        .args(["device", "--pty", "--speed", &speed.to_string()])
        .args(["--scenario", scenario])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut out = child.stdout.take().unwrap();
    let mut path = String::new();
    let mut b = [0u8; 1];
    while out.read(&mut b).unwrap() == 1 && b[0] != b'\n' {
        path.push(b[0] as char);
    }
    assert!(path.starts_with("/dev/pts/"), "speed {speed}: {path:?}");
    (child, path)
}

/// One run at `speed`: the paper curve loaded, `wmr record --arm --seconds
/// RECORD_S`; returns (rows, dropped frames).
fn record_at(speed: f64) -> (u64, u64) {
    let (mut child, path) = device(speed);
    // As every `wmr` command opens it: handshake, then the timing from the
    // robot's link timeout.
    let mut link = open_link(&Endpoint::Port(path), None).unwrap();
    assert_eq!(link.hello().unwrap().version, PROTOCOL_VERSION);
    let reference = Request::SetReference(BuiltinReference {
        shape: named_shape("paper").unwrap(),
        start: None,
        speed_scale: 1.0,
    });
    link.command(&reference).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let args = wmr::cli::RecordArgs {
        seconds: RECORD_S,
        out: dir.path().join("rec.csv"),
        rate: 100,
        arm: true,
        quiet: true,
        mcap: None,
        com_offset_m: None,
    };
    let mut out = Vec::new();
    let result = wmr::cli::record(&args, &mut link, &mut out);
    // The robot still runs the curve (reference time RECORD_S of its 31 s
    // period): no stop of any kind, LinkSilence least of all.
    let status = match link.command(&Request::GetStatus) {
        Ok(Reply::Status { status, .. }) => status,
        r => panic!("speed {speed}: status: {r:?}"),
    };
    let _ = link.command(&Request::Disarm);
    drop(link);
    child.kill().unwrap();
    child.wait().unwrap();
    result.unwrap_or_else(|e| panic!("speed {speed}: wmr record --arm: {e}"));
    assert_eq!(
        status.state,
        RunStateMsg::Running,
        "speed {speed}: {status:?}"
    );
    assert_ne!(
        status.last_stop,
        Some(StopCode::LinkSilence),
        "speed {speed}"
    );
    let summary: serde_json::Value = serde_json::from_slice(&out).unwrap();
    let rows = summary["rows"].as_u64().unwrap();
    let dropped = summary["dropped_frames"].as_u64().unwrap();
    (rows, dropped)
}

/// `--speed 1, 2, 5, 10` each records the whole run, every 100 Hz frame
/// received or counted missing by its sequence number; and a speed no
/// machine reaches (1000: the robot falls behind it) is as safe.
#[test]
fn record_arm_completes_at_every_speed() {
    let want = (RECORD_S * 100.0).round() as u64;
    for speed in [1.0, 2.0, 5.0, 10.0, 1000.0] {
        let (rows, dropped) = record_at(speed);
        eprintln!("speed {speed}: {rows} rows, {dropped} frames dropped");
        // Frames lost to a host that did not read in time are counted by
        // their sequence numbers (the last one received may then lie past
        // the end); none is lost silently.
        assert!(
            rows + dropped >= want - 10 && rows <= want,
            "speed {speed}: {rows} rows + {dropped} dropped, want {want}"
        );
        if dropped == 0 {
            assert!(rows >= want - 10, "speed {speed}: {rows} rows");
        }
        // The host reads at least the first frames at any speed.
        assert!(rows > 0, "speed {speed}: nothing recorded");
    }
}
