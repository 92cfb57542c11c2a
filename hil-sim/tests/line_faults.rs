//! The host tool on a bad line (issue 21): a proxy between `wmr` and
//! `hil-sim device --pty` drops, corrupts and delays bytes and cuts the line.
//! `wmr` runs in-process (`wmr::cli::execute`, whose `Err` is the binary's
//! exit code 1) in a thread; the test bounds every run in wall time
//! ([`BOUND`]) so a hang fails instead of blocking the suite.
//!
//! Asserted: no hang beyond the bound; no success (exit 0) after an
//! unexpected stop; a drive at 0.1 % byte faults completes; the robot answers
//! again after the line returns.
//!
//! No wait is a wall-clock guess: the proxy decodes what the robot sends
//! (before the line's faults, so also while the line is cut) and the tests
//! cut the line once the robot reports it runs and keep it cut until the
//! robot reports the stop the test is about.

use clap::Parser;
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};
use wmr_protocol::{Decoded, Event, FrameDecoder, Reply, RunStateMsg, StopCode, MAX_FRAME};

/// No wmr command here may take longer (wall time): the longest run is a
/// 60 s drive, with margin for a loaded machine. Waits for the robot's
/// reports end on them, at most this long.
const BOUND: Duration = Duration::from_secs(120);

/// One at a time: each test serves a real-time robot (2 cores, shared).
fn serial() -> std::sync::MutexGuard<'static, ()> {
    static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// What the line does now.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
enum Line {
    /// Every byte through.
    Clean = 0,
    /// Nothing through (a cut cable).
    Cut = 1,
    /// Each byte dropped, or corrupted, with probability 1/1000 each, and
    /// chunks delayed by up to 4 ms.
    Faulty = 2,
}

/// What the robot reported last (its frames as it sent them, whatever the
/// line then did to them): its state and the last stop's cause, from
/// state events, status answers and telemetry.
#[derive(Clone, Copy, Debug, Default)]
struct Seen {
    state: Option<RunStateMsg>,
    cause: Option<StopCode>,
    link_lost: bool,
    /// A frame saying the robot runs went through a clean line ...
    running_delivered: bool,
    /// ... and a telemetry frame saying so.
    running_telemetry_delivered: bool,
}

impl Seen {
    fn note(&mut self, r: &Reply, clean: bool) {
        match r {
            Reply::Event(Event::StateChanged { state, cause }) => {
                self.state = Some(*state);
                if cause.is_some() {
                    self.cause = *cause;
                }
            }
            Reply::Event(Event::LinkLost) => self.link_lost = true,
            Reply::Status { status, .. } => {
                self.state = Some(status.state);
                if status.last_stop.is_some() {
                    self.cause = status.last_stop;
                }
            }
            Reply::Telemetry(t) => self.state = Some(t.state),
            _ => {}
        }
        self.running_delivered |= clean && self.state == Some(RunStateMsg::Running);
        self.running_telemetry_delivered |=
            clean && matches!(r, Reply::Telemetry(t) if t.state == RunStateMsg::Running);
    }
}

/// `hil-sim device --pty` behind a fault-injecting proxy; `path` is the
/// proxy's pty for wmr.
struct Rig {
    child: std::process::Child,
    path: String,
    line: Arc<AtomicU32>,
    stop: Arc<AtomicBool>,
    seen: Arc<Mutex<Seen>>,
    _slave: serialport::TTYPort,
}

/// A small deterministic generator (xorshift64*), one per direction.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
}

/// Copies `from` to `to` while `stop` is false, applying the line's faults;
/// with `seen` (the robot's direction), notes what the robot sent.
fn pump(
    mut from: Box<dyn serialport::SerialPort>,
    mut to: Box<dyn serialport::SerialPort>,
    line: Arc<AtomicU32>,
    stop: Arc<AtomicBool>,
    seed: u64,
    seen: Option<Arc<Mutex<Seen>>>,
) {
    let mut rng = Rng(seed);
    let mut decoder = FrameDecoder::<MAX_FRAME>::new();
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::Relaxed) {
        let n = match from.read(&mut buf) {
            Ok(n) => n,
            Err(_) => {
                std::thread::sleep(Duration::from_millis(1));
                continue;
            }
        };
        let mode = line.load(Ordering::Relaxed);
        if let Some(seen) = &seen {
            let mut rest = &buf[..n];
            while !rest.is_empty() {
                let (d, r) = decoder.feed::<Reply>(rest);
                rest = r;
                if let Some(Decoded::Frame { msg, .. }) = d {
                    seen.lock().unwrap().note(&msg, mode == Line::Clean as u32);
                }
            }
        }
        let mut out = Vec::with_capacity(n);
        for &b in &buf[..n] {
            match mode {
                m if m == Line::Cut as u32 => {}
                m if m == Line::Faulty as u32 => match rng.next() % 1000 {
                    0 => {}                                           // dropped
                    1 => out.push(b ^ (1 << (rng.next() % 8) as u8)), // corrupted
                    _ => out.push(b),
                },
                _ => out.push(b),
            }
        }
        if mode == Line::Faulty as u32 {
            std::thread::sleep(Duration::from_micros(rng.next() % 4000));
        }
        if !out.is_empty() {
            let _ = to.write_all(&out);
            let _ = to.flush();
        }
    }
}

impl Rig {
    fn start() -> Self {
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_hil-sim"))
            .args([
                "device",
                "--pty",
                "--for-s",
                "600",
                "--scenario",
                concat!(
                    env!("CARGO_MANIFEST_DIR"),
                    "/../scenarios/link_nominal.toml"
                ),
            ])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("hil-sim device");
        let mut robot_path = String::new();
        let mut out = child.stdout.take().unwrap();
        let mut b = [0u8; 1];
        while out.read(&mut b).unwrap() == 1 && b[0] != b'\n' {
            robot_path.push(b[0] as char);
        }
        assert!(robot_path.starts_with("/dev/"), "{robot_path:?}");
        let robot = serialport::new(&robot_path, 115_200)
            .timeout(Duration::from_millis(2))
            .open()
            .expect("the robot's pty");
        let (master, slave) = serialport::TTYPort::pair().expect("a pty pair");
        let path = serialport::SerialPort::name(&slave).unwrap();
        let mut host: Box<dyn serialport::SerialPort> = Box::new(master);
        host.set_timeout(Duration::from_millis(2)).unwrap();
        let line = Arc::new(AtomicU32::new(Line::Clean as u32));
        let stop = Arc::new(AtomicBool::new(false));
        let seen = Arc::new(Mutex::new(Seen::default()));
        let (r2, h2) = (robot.try_clone().unwrap(), host.try_clone().unwrap());
        for (from, to, seed, seen) in [
            (host, robot, 1u64, None),
            (r2, h2, 2u64, Some(seen.clone())),
        ] {
            let (l, s) = (line.clone(), stop.clone());
            std::thread::spawn(move || pump(from, to, l, s, seed, seen));
        }
        Self {
            child,
            path,
            line,
            stop,
            seen,
            _slave: slave,
        }
    }

    fn set(&self, l: Line) {
        self.line.store(l as u32, Ordering::Relaxed);
    }

    /// Waits (at most [`BOUND`]) until what the robot reported satisfies
    /// `cond`.
    fn wait_for(&self, what: &str, cond: impl Fn(&Seen) -> bool) {
        let t0 = Instant::now();
        loop {
            let seen = *self.seen.lock().unwrap();
            if cond(&seen) {
                return;
            }
            assert!(
                t0.elapsed() < BOUND,
                "the robot never reported {what}: {seen:?}"
            );
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Waits until the robot's report that it runs has gone through to wmr.
    fn wait_running(&self) {
        self.wait_for("running", |s| s.running_delivered);
    }

    /// `wmr params set limits.link_timeout_ms MS` (the robot's link timeout).
    fn set_link_timeout_ms(&self, ms: u32) {
        let (r, out) = finish(
            &self.wmr(&["params", "set", "limits.link_timeout_ms", &ms.to_string()]),
            "params set",
        );
        r.unwrap_or_else(|e| panic!("{e}\n{out}"));
    }

    /// Starts `wmr --port <proxy> ARGS...` in a thread: (result, stdout).
    fn wmr(&self, args: &[&str]) -> mpsc::Receiver<(Result<(), String>, String)> {
        let mut argv = vec!["wmr".to_string(), "--port".into(), self.path.clone()];
        argv.extend(args.iter().map(|s| s.to_string()));
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let cli = wmr::cli::Cli::try_parse_from(&argv).expect("wmr arguments");
            let mut out = Vec::new();
            let r = wmr::cli::execute(&cli, &mut out);
            let _ = tx.send((r, String::from_utf8_lossy(&out).into_owned()));
        });
        rx
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Waits for a wmr run, at most [`BOUND`]; its result and stdout.
fn finish(
    rx: &mpsc::Receiver<(Result<(), String>, String)>,
    what: &str,
) -> (Result<(), String>, String) {
    rx.recv_timeout(BOUND)
        .unwrap_or_else(|_| panic!("`wmr {what}` still running after {BOUND:?}: it hangs"))
}

fn square() -> &'static str {
    concat!(env!("CARGO_MANIFEST_DIR"), "/../trajectories/square.toml")
}

/// `wmr upload --arm` through a cut of the line while the square runs, the
/// line back once the robot is at rest after its link-silence stop (issue
/// 21 item 4: it hung forever, the stop event lost and the wait
/// unbounded): a clear error within the bound, and the robot answers
/// `wmr status` once the line is back (hold, stopped on link silence).
#[test]
fn upload_arm_through_a_cut_line_fails_clearly_and_recovers() {
    let _s = serial();
    let rig = Rig::start();
    let t0 = Instant::now();
    let run = rig.wmr(&["upload", square(), "--arm"]);
    rig.wait_running();
    rig.set(Line::Cut);
    rig.wait_for("a link-silence stop, at rest", |s| {
        s.state == Some(RunStateMsg::Hold) && s.cause == Some(StopCode::LinkSilence)
    });
    rig.set(Line::Clean);
    let (r, out) = finish(&run, "upload --arm");
    let e = r.expect_err("a cut line during the run is not a success");
    assert!(
        e.contains("stopped unexpectedly") || e.contains("no answer"),
        "{e}\n{out}"
    );
    assert!(t0.elapsed() < BOUND);
    // The controlled stop ends once the robot is at rest (issue 31): ask
    // until it has, at most 60 times.
    let mut out = String::new();
    for _ in 0..60 {
        let (r, o) = finish(&rig.wmr(&["status"]), "status");
        r.unwrap();
        out = o;
        if !out.contains("state Stopping") {
            break;
        }
        std::thread::sleep(Duration::from_millis(250));
    }
    assert!(
        out.contains("state Hold") && out.contains("LinkSilence"),
        "{out}"
    );
}

/// A cut while `wmr drive` runs, until the robot has stopped on the
/// velocity command's 300 ms timeout (robot time; the old answer wait gave
/// up after 2 x 500 ms): its event is lost; wmr must not report success
/// (issue 21 item 5: it kept refreshing, acked in hold, and exited 0). The
/// robot's link timeout is 5 s here: the stop is the command's, and wmr's
/// silence limit (4 link timeouts) is far off.
#[test]
fn drive_after_an_unexpected_stop_is_not_a_success() {
    let _s = serial();
    let rig = Rig::start();
    rig.set_link_timeout_ms(5000);
    let run = rig.wmr(&["drive", "--v", "0.2", "--w", "0.1", "--for", "60"]);
    rig.wait_running();
    rig.set(Line::Cut);
    rig.wait_for("a stop on the velocity timeout", |s| {
        s.state != Some(RunStateMsg::Running) && s.cause == Some(StopCode::VelocityTimeout)
    });
    rig.set(Line::Clean);
    let (r, out) = finish(&run, "drive");
    let e = r.expect_err("the robot stopped in the middle of the drive");
    assert!(e.contains("stopped unexpectedly"), "{e}\n{out}");
}

/// At 0.1 % byte drops and 0.1 % corrupted bytes with jitter, a 3 s drive
/// runs to its end and stops on its own velocity timeout, not early (issue
/// 21 item 5: one lost frame cost a 500 ms answer timeout plus a retry, more
/// than the robot's link timeout). wmr's timing is a fixed fraction of the
/// robot's link timeout (keep-alive and answer timeout a fifth): the test
/// sets 2.5 s, the same fractions with 5x the absolute slack for a host
/// held up by a loaded machine (at the default 500 ms it stopped on link
/// silence under load: 400 ms of scheduling delay is no line fault); the
/// command's timeout 2 s, 4 refresh periods of 500 ms.
#[test]
fn drive_at_byte_faults_runs_to_its_end() {
    let _s = serial();
    let rig = Rig::start();
    // Connect on a clean line, then degrade it.
    let (r, _) = finish(&rig.wmr(&["status"]), "status");
    r.unwrap();
    rig.set_link_timeout_ms(2500);
    rig.set(Line::Faulty);
    for _ in 0..2 {
        let (r, out) = finish(
            &rig.wmr(&[
                "drive",
                "--v",
                "0.2",
                "--w",
                "0.2",
                "--for",
                "3",
                "--cmd-timeout-ms",
                "2000",
            ]),
            "drive",
        );
        r.unwrap_or_else(|e| panic!("{e}\n{out}"));
        assert!(out.contains("stopped: Hold (VelocityTimeout)"), "{out}");
    }
}

/// `wmr record --arm` of the square through a cut of the line until the
/// robot reports its link-silence stop: the log is written, but the exit is
/// not a success (before, wmr printed "the run ended" and exited 0, or
/// waited on for reference time that no longer advanced).
#[test]
fn record_arm_through_a_cut_line_is_not_a_success() {
    let _s = serial();
    let rig = Rig::start();
    let (r, _) = finish(&rig.wmr(&["upload", square()]), "upload");
    r.unwrap();
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    let run = rig.wmr(&[
        "record",
        "--arm",
        "--quiet",
        "--seconds",
        "10",
        "--out",
        csv.to_str().unwrap(),
    ]);
    // `record` ends on a stop once its telemetry said the robot runs
    // (a run that stops before wmr heard it running is not in this test).
    rig.wait_for("running, in telemetry", |s| s.running_telemetry_delivered);
    rig.set(Line::Cut);
    rig.wait_for("a link-silence stop", |s| {
        s.link_lost || s.cause == Some(StopCode::LinkSilence)
    });
    rig.set(Line::Clean);
    let (r, out) = finish(&run, "record --arm");
    let e = r.expect_err("the run was stopped by the cut");
    assert!(
        e.contains("stopped unexpectedly") && e.contains("LinkSilence"),
        "{e}\n{out}"
    );
    assert!(out.contains("\"rows\""), "the summary is printed: {out}");
    assert!(std::fs::metadata(&csv).unwrap().len() > 0);
}
