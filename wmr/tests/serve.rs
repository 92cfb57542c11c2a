//! `wmr serve` end to end: the `wmr` binary as the server and as its
//! clients, the simulated robot (`hil_sim::device`, what `hil-sim device
//! --pty` serves) on a pty behind a line that can drop and corrupt bytes
//! (`common`). Every process is bounded in wall time: a hang fails.

mod common;

use common::*;
use std::process::Stdio;
use std::time::Duration;
use wmr::Link;

const BOUND: Duration = Duration::from_secs(30);

/// `drive`, `record` and `watch` at once through one server on a clean
/// line (before the server, the second command could not open the port):
/// each does what it does alone, the server exits 0 with nothing unexpected.
#[test]
fn drive_record_and_watch_at_once_through_one_server() {
    let _s = serial();
    let mut robot = Robot::start(&quiet(), false);
    // The default socket, named after the port.
    let server = Server::start_args(&robot.port, &[]);
    let sock = server.socket.clone();
    assert_eq!(
        sock,
        wmr::serve::default_socket_path(robot.port.to_str().unwrap())
    );
    let csv = robot.dir.path().join("r.csv");
    let drive = client(&sock, &["drive", "--v", "0.2", "--w", "0.1", "--for", "4"]);
    std::thread::sleep(Duration::from_millis(700));
    let record = client(
        &sock,
        &[
            "record",
            "--seconds",
            "2",
            "--rate",
            "50",
            "--quiet",
            "--out",
            csv.to_str().unwrap(),
        ],
    );
    let watch = client(&sock, &["watch", "--seconds", "1", "--rate", "5"]);
    // `--port` finds the server of the port by itself.
    let status = wmr_cmd()
        .arg("--port")
        .arg(&robot.port)
        .arg("status")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let status = finish(status, BOUND, "status");
    assert!(status.status.success(), "{status}");
    assert!(status.stdout.contains("state Running"), "{status}");
    let watch = finish(watch, BOUND, "watch");
    assert!(watch.status.success(), "{watch}");
    // 1 s at 5 lines/s although record asked the robot for 50 Hz.
    let lines = watch.stdout.lines().count();
    assert!((4..=7).contains(&lines), "{lines} lines\n{watch}");
    let record = finish(record, BOUND, "record");
    assert!(record.status.success(), "{record}");
    let summary: serde_json::Value =
        serde_json::from_str(record.stdout.lines().last().unwrap()).unwrap();
    // 2 s at 50 Hz while running, none lost on a clean line.
    assert_eq!(summary["dropped_frames"], 0, "{record}");
    let rows = summary["rows"].as_u64().unwrap();
    assert!((95..=101).contains(&rows), "{record}");
    let drive = finish(drive, BOUND, "drive");
    assert!(drive.status.success(), "{drive}");
    assert!(
        drive.stdout.contains("stopped: Hold (VelocityTimeout)"),
        "{drive}"
    );
    let (status, summary, log) = server.stop();
    assert!(status.success(), "{status}\n{summary}\n{log}");
    assert_eq!(summary["unexpected"], serde_json::json!([]), "{log}");
    assert_eq!(summary["client_frames_dropped"], 0);
    assert!(!sock.exists(), "the socket is removed at exit");
    std::thread::sleep(Duration::from_millis(100));
    let mut sim = robot.stop();
    // Every frame the server wrote reached the robot (clean line).
    assert_eq!(
        summary["frames_to_robot"].as_u64().unwrap(),
        sim.device().counters().rx_frames as u64
    );
}

/// A bad socket is a one-line error naming it, for clients and server.
#[test]
fn bad_socket_paths_are_clear_errors() {
    let _s = serial();
    let dir = tempfile::tempdir().unwrap();
    // A client with no server.
    let missing = dir.path().join("none.sock");
    let c = finish(
        client(&missing, &["status"]),
        BOUND,
        "status without server",
    );
    assert!(!c.status.success());
    assert!(
        c.stderr.contains(&format!(
            "cannot connect to wmr serve at {}",
            missing.display()
        )) && c.stderr.contains("no such socket"),
        "{c}"
    );
    // A stale socket: nobody listens.
    let stale = dir.path().join("stale.sock");
    drop(std::os::unix::net::UnixListener::bind(&stale).unwrap());
    let c = finish(client(&stale, &["status"]), BOUND, "status on stale");
    assert!(!c.status.success());
    assert!(c.stderr.contains("nobody listens"), "{c}");
    // A server whose socket directory does not exist, or whose path is too
    // long for a Unix socket, or where a plain file is in the way.
    let robot = Robot::start(&quiet(), false);
    let long = dir.path().join("x".repeat(120));
    let file = dir.path().join("file");
    std::fs::write(&file, "not a socket").unwrap();
    for (sock, msg) in [
        (
            std::path::PathBuf::from("/nonexistent-dir/s.sock"),
            "directory /nonexistent-dir does not exist",
        ),
        (long, "too long"),
        (file.clone(), "not a socket"),
    ] {
        let c = wmr_cmd()
            .arg("--port")
            .arg(&robot.port)
            .args(["serve", "--socket"])
            .arg(&sock)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let c = finish(c, BOUND, "serve on a bad socket");
        assert!(!c.status.success(), "{c}");
        assert!(c.stderr.contains(msg), "{msg}: {c}");
        assert_eq!(c.stderr.lines().count(), 1, "{c}");
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "not a socket");
    // A second server on a live socket.
    let sock = robot.dir.path().join("s.sock");
    let first = Server::start(&robot.port, &sock, &[]);
    let c = wmr_cmd()
        .arg("--port")
        .arg(&robot.port)
        .args(["serve", "--socket"])
        .arg(&sock)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let c = finish(c, BOUND, "second serve");
    assert!(!c.status.success());
    assert!(c.stderr.contains("already listens"), "{c}");
    // The first still serves.
    let mut l = Link::connect(&sock, Duration::from_millis(500)).unwrap();
    l.hello().unwrap();
    drop(l);
    let (status, _, log) = first.stop();
    assert!(status.success(), "{log}");
}
