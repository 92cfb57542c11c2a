//! The rig of the `wmr serve` tests: the simulated robot
//! (`hil_sim::device::serve`, the firmware's link handler, runtime and
//! estimator on the simulated plant: what `hil-sim device --pty` runs) on a
//! pseudo-terminal reached through a symbolic link (so that a restarted
//! robot, on a new pty, appears at the same path as a replugged USB robot
//! does), behind a line that drops and corrupts bytes and counts, frame by
//! frame, what it delivered intact; and the `wmr` binary as server and
//! clients, every run bounded in wall time (a hang fails the test).
#![allow(dead_code)]

use controller_core::ControllerKind;
use hil_sim::device::{open_pty, serve, SimRobot};
use hil_sim::scenario::{PerturbationPart, Scenario, Sensing};
use std::collections::HashSet;
use std::io::{Read, Write};
use std::os::unix::io::AsRawFd;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use wmr_protocol::{Decoded, FrameDecoder, Reply, MAX_FRAME};

/// The longest any wait of the rig and the tests may take (a hang fails;
/// a slow machine only waits longer): waits end on events, not on time.
pub const CEILING: Duration = Duration::from_secs(60);

/// Polls `cond` every 10 ms until it holds; fails with `what` after
/// [`CEILING`].
pub fn wait_until(what: &str, mut cond: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !cond() {
        assert!(t0.elapsed() < CEILING, "not within {CEILING:?}: {what}");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// One rig at a time: each serves a real-time robot (2 cores, shared).
pub fn serial() -> std::sync::MutexGuard<'static, ()> {
    hil_sim::device::PtyRobot::serial()
}

/// The paper robot without perturbations, the true pose measured (mocap).
pub fn quiet() -> Scenario {
    Scenario {
        name: "quiet".into(),
        duration_s: 60.0,
        perturbations: PerturbationPart::none(),
        ..Scenario::default()
    }
    .with_sensing(Sensing::Mocap)
}

/// A small deterministic generator (xorshift64*).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
}

/// What one direction of the line did. The bytes that come out are cut
/// at their zeros into the segments a receiver sees, and each is decoded
/// on its own (the protocol's decoder, fresh): what every receiver must
/// count as valid frames and as frame errors, whatever chunks it reads
/// them in and whatever it does with them afterwards.
#[derive(Clone, Debug, Default)]
pub struct Direction {
    /// Bytes through the line.
    pub bytes: u64,
    /// Bytes dropped.
    pub dropped: u64,
    /// Bytes with a bit flipped.
    pub corrupted: u64,
    /// Original (non-empty) frames sent.
    pub frames: u64,
    /// Frames that came out valid.
    pub valid: u64,
    /// Frame errors that came out (bad CRC, malformed, too long).
    pub damaged: u64,
    /// Sequence numbers of the telemetry frames sent ...
    pub telemetry_sent: Vec<u32>,
    /// ... and of those that came out valid.
    pub telemetry_delivered: HashSet<u32>,
    sent_frame: Vec<u8>,
    out_segment: Vec<u8>,
}

impl Direction {
    /// Telemetry sent and not delivered.
    pub fn telemetry_lost(&self) -> Vec<u32> {
        self.telemetry_sent
            .iter()
            .copied()
            .filter(|s| !self.telemetry_delivered.contains(s))
            .collect()
    }

    /// Decodes `segment` + delimiter as a receiver would; `to_host`: as
    /// replies (telemetry noted), else as requests.
    fn decode(segment: &[u8], to_host: bool) -> (u64, u64, Vec<u32>) {
        let mut bytes = segment.to_vec();
        bytes.push(0);
        let (mut valid, mut errors, mut tel) = (0, 0, Vec::new());
        let mut rest = &bytes[..];
        if to_host {
            let mut d = FrameDecoder::<MAX_FRAME>::new();
            while !rest.is_empty() {
                let (o, r) = d.feed::<Reply>(rest);
                rest = r;
                match o {
                    Some(Decoded::Frame { msg, .. }) => {
                        valid += 1;
                        if let Reply::Telemetry(t) = msg {
                            tel.push(t.seq);
                        }
                    }
                    Some(Decoded::OtherVersion { .. }) => valid += 1,
                    Some(Decoded::Error { .. }) => errors += 1,
                    None => {}
                }
            }
        } else {
            let mut d = FrameDecoder::<MAX_FRAME>::new();
            while !rest.is_empty() {
                let (o, r) = d.feed::<wmr_protocol::Request>(rest);
                rest = r;
                match o {
                    Some(Decoded::Frame { .. } | Decoded::OtherVersion { .. }) => valid += 1,
                    Some(Decoded::Error { .. }) => errors += 1,
                    None => {}
                }
            }
        }
        (valid, errors, tel)
    }

    /// Passes `input` through the line (faulty or not) into `out`.
    fn pass(
        &mut self,
        input: &[u8],
        faulty: bool,
        to_host: bool,
        rng: &mut Rng,
        out: &mut Vec<u8>,
    ) {
        for &b in input {
            self.bytes += 1;
            // Each byte dropped, or one of its bits flipped, with
            // probability 1/1000 each.
            let fate = match (faulty, rng.next() % 1000) {
                (true, 0) => None,
                (true, 1) => Some(b ^ (1 << (rng.next() % 8) as u8)),
                _ => Some(b),
            };
            match fate {
                None => self.dropped += 1,
                Some(c) if c != b => self.corrupted += 1,
                Some(_) => {}
            }
            // What was sent.
            if b != 0 {
                self.sent_frame.push(b);
            } else if !self.sent_frame.is_empty() {
                self.frames += 1;
                let (_, _, tel) = Self::decode(&self.sent_frame, to_host);
                self.telemetry_sent.extend(tel);
                self.sent_frame.clear();
            }
            // What came out.
            match fate {
                Some(0) => {
                    out.push(0);
                    if !self.out_segment.is_empty() {
                        let (v, e, tel) = Self::decode(&self.out_segment, to_host);
                        self.valid += v;
                        self.damaged += e;
                        self.telemetry_delivered.extend(tel);
                        self.out_segment.clear();
                    }
                }
                Some(c) => {
                    out.push(c);
                    self.out_segment.push(c);
                }
                None => {}
            }
        }
    }
}

/// Both directions of the line.
#[derive(Clone, Debug, Default)]
pub struct LineStats {
    /// Host (the server) to robot.
    pub to_robot: Direction,
    /// Robot to host.
    pub to_host: Direction,
}

/// The robot's end of the line: the pty master, bytes passed through
/// [`Direction::pass`] both ways.
struct FaultyPort {
    inner: serialport::TTYPort,
    faulty: Arc<AtomicBool>,
    stats: Arc<Mutex<LineStats>>,
    /// Reads by the robot (one per tick while its receive buffer has room).
    reads: Arc<AtomicU64>,
    rng_in: Rng,
    rng_out: Rng,
    pending: Vec<u8>,
}

impl FaultyPort {
    fn push_pending(&mut self) -> std::io::Result<()> {
        while !self.pending.is_empty() {
            match self.inner.write(&self.pending) {
                Ok(n) => {
                    self.pending.drain(..n);
                }
                Err(e) if transient(&e) => return Ok(()),
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}

fn transient(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::*;
    matches!(e.kind(), TimedOut | WouldBlock | Interrupted)
}

impl Read for FaultyPort {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.push_pending()?;
        self.reads.fetch_add(1, Ordering::Relaxed);
        let n = self.inner.read(buf)?;
        let mut out = Vec::with_capacity(n);
        let faulty = self.faulty.load(Ordering::Relaxed);
        self.stats.lock().unwrap().to_robot.pass(
            &buf[..n],
            faulty,
            false,
            &mut self.rng_in,
            &mut out,
        );
        buf[..out.len()].copy_from_slice(&out);
        Ok(out.len())
    }
}

impl Write for FaultyPort {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.push_pending()?;
        if self.pending.len() > 64 * 1024 {
            return Err(std::io::ErrorKind::WouldBlock.into());
        }
        let faulty = self.faulty.load(Ordering::Relaxed);
        let mut out = Vec::with_capacity(buf.len());
        self.stats
            .lock()
            .unwrap()
            .to_host
            .pass(buf, faulty, true, &mut self.rng_out, &mut out);
        self.pending.extend_from_slice(&out);
        self.push_pending()?;
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.push_pending()
    }
}

/// The simulated robot on a pty behind a faulty line, reached at
/// [`Robot::port`] (a symbolic link to the current pty).
pub struct Robot {
    /// A temporary directory for the link, sockets and logs.
    pub dir: tempfile::TempDir,
    /// The port path to give `wmr`.
    pub port: PathBuf,
    /// Whether the line injects faults now.
    pub faulty: Arc<AtomicBool>,
    /// What the line did (since the last start).
    pub stats: Arc<Mutex<LineStats>>,
    reads: Arc<AtomicU64>,
    scn: Scenario,
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<SimRobot>>,
    slave: Option<serialport::TTYPort>,
    starts: u64,
}

impl Robot {
    /// Starts the robot of `scn`, the line faulty or not.
    pub fn start(scn: &Scenario, faulty: bool) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let port = dir.path().join("robot");
        let mut r = Self {
            dir,
            port,
            faulty: Arc::new(AtomicBool::new(faulty)),
            stats: Arc::new(Mutex::new(LineStats::default())),
            reads: Arc::new(AtomicU64::new(0)),
            scn: scn.clone(),
            stop: Arc::new(AtomicBool::new(false)),
            handle: None,
            slave: None,
            starts: 0,
        };
        r.spawn();
        r
    }

    fn spawn(&mut self) {
        let (master, slave, path) = open_pty().unwrap();
        // Not inherited by the processes the tests start (a server holding
        // the master would never see the line hang up).
        for fd in [master.as_raw_fd(), slave.as_raw_fd()] {
            // SAFETY: fcntl on descriptors this function owns.
            unsafe {
                let flags = libc::fcntl(fd, libc::F_GETFD);
                libc::fcntl(fd, libc::F_SETFD, flags | libc::FD_CLOEXEC);
            }
        }
        let mut robot = SimRobot::new(&self.scn, ControllerKind::Proposed).unwrap();
        self.starts += 1;
        let mut port = FaultyPort {
            inner: master,
            faulty: self.faulty.clone(),
            stats: self.stats.clone(),
            reads: self.reads.clone(),
            rng_in: Rng(0x9E37_79B9 + self.starts),
            rng_out: Rng(0x85EB_CA6B + self.starts),
            pending: Vec::new(),
        };
        self.stop = Arc::new(AtomicBool::new(false));
        let s = self.stop.clone();
        self.handle = Some(std::thread::spawn(move || {
            serve(&mut robot, &mut port, 1.0, &s).unwrap();
            robot
        }));
        self.slave = Some(slave);
        // Point the link at the new pty (atomically: rename over it).
        let tmp = self.dir.path().join("robot.new");
        let _ = std::fs::remove_file(&tmp);
        std::os::unix::fs::symlink(&path, &tmp).unwrap();
        std::fs::rename(&tmp, &self.port).unwrap();
    }

    /// Stops the robot: its pty closes (the host sees the line hang up).
    pub fn stop(&mut self) -> SimRobot {
        self.stop.store(true, Ordering::Relaxed);
        let robot = self.handle.take().unwrap().join().unwrap();
        self.slave = None;
        let _ = std::fs::remove_file(&self.port);
        robot
    }

    /// Waits until the line has passed `frames` frames to the robot and the
    /// robot has read its port 20 more times (20 ticks: its 256-byte
    /// receive buffer is decoded, 128 bytes a tick), so that its counters
    /// hold every frame the host wrote; the host must have stopped writing.
    pub fn wait_delivered(&self, frames: u64) {
        wait_until(&format!("{frames} frames to the robot"), || {
            self.stats.lock().unwrap().to_robot.frames >= frames
        });
        let r0 = self.reads.load(Ordering::Relaxed);
        wait_until("20 more robot ticks", || {
            self.reads.load(Ordering::Relaxed) >= r0 + 20
        });
    }

    /// A fresh robot (boot state, its clock from 0) on a new pty at the
    /// same path: the simulator's process restarted.
    pub fn restart(&mut self) -> SimRobot {
        let old = self.stop();
        std::thread::sleep(Duration::from_millis(300));
        self.spawn();
        old
    }
}

impl Robot {
    /// `wmr serve` on this robot's port, its socket in the rig's directory:
    /// (the socket, the server).
    pub fn serve(&self, extra: &[&str]) -> (PathBuf, Server) {
        let sock = self.dir.path().join("s.sock");
        let server = Server::start(&self.port, &sock, extra);
        (sock, server)
    }
}

impl Drop for Robot {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// The `wmr` binary.
pub fn wmr_cmd() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wmr"))
}

/// A finished process: status, stdout, stderr.
pub struct Done {
    pub status: ExitStatus,
    pub stdout: String,
    pub stderr: String,
}

impl std::fmt::Display for Done {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}\n--- stdout\n{}\n--- stderr\n{}",
            self.status, self.stdout, self.stderr
        )
    }
}

/// Waits for `child` at most `bound` (then kills it and fails: it hangs).
pub fn finish(child: Child, bound: Duration, what: &str) -> Done {
    let pid = child.id() as libc::pid_t;
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    match rx.recv_timeout(bound) {
        Ok(o) => {
            let o = o.unwrap();
            Done {
                status: o.status,
                stdout: String::from_utf8_lossy(&o.stdout).into_owned(),
                stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
            }
        }
        Err(_) => {
            // SAFETY: kill has no memory preconditions; pid is our child's.
            unsafe { libc::kill(pid, libc::SIGKILL) };
            panic!("`{what}` still running after {bound:?}: it hangs");
        }
    }
}

/// `wmr --serve SOCKET ARGS...`, stdout and stderr piped, stdin null.
pub fn client(socket: &Path, args: &[&str]) -> Child {
    wmr_cmd()
        .arg("--serve")
        .arg(socket)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// `wmr serve` as a process.
pub struct Server {
    child: Option<Child>,
    /// Its socket (the first line it printed).
    pub socket: PathBuf,
    stderr: Arc<Mutex<String>>,
    stderr_reader: Option<JoinHandle<()>>,
    rest: Option<JoinHandle<String>>,
}

impl Server {
    /// `wmr --port PORT serve --socket SOCKET EXTRA...`; returns once the
    /// socket is listening (its path printed).
    pub fn start(port: &Path, socket: &Path, extra: &[&str]) -> Self {
        let mut args: Vec<&std::ffi::OsStr> = vec!["--socket".as_ref(), socket.as_os_str()];
        args.extend(extra.iter().map(|s| std::ffi::OsStr::new(*s)));
        Self::start_args(port, &args)
    }

    /// `wmr --port PORT serve ARGS...` (the default socket without --socket).
    pub fn start_args(port: &Path, args: &[&std::ffi::OsStr]) -> Self {
        let mut child = wmr_cmd()
            .arg("--port")
            .arg(port)
            .arg("serve")
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut out = child.stdout.take().unwrap();
        let mut err = child.stderr.take().unwrap();
        let stderr = Arc::new(Mutex::new(String::new()));
        let e = stderr.clone();
        let stderr_reader = std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = err.read(&mut buf) {
                if n == 0 {
                    break;
                }
                e.lock()
                    .unwrap()
                    .push_str(&String::from_utf8_lossy(&buf[..n]));
            }
        });
        let mut first = String::new();
        let mut b = [0u8; 1];
        let t0 = Instant::now();
        while out.read(&mut b).unwrap_or(0) == 1 && b[0] != b'\n' {
            first.push(b[0] as char);
            assert!(t0.elapsed() < CEILING);
        }
        let rest = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = out.read_to_string(&mut s);
            s
        });
        let s = Self {
            child: Some(child),
            socket: PathBuf::from(first),
            stderr,
            stderr_reader: Some(stderr_reader),
            rest: Some(rest),
        };
        assert!(s.wait_log("connected to the robot", CEILING), "{}", s.log());
        s
    }

    /// Its log so far.
    pub fn log(&self) -> String {
        self.stderr.lock().unwrap().clone()
    }

    /// Waits until its log contains `what` (at most `bound`).
    pub fn wait_log(&self, what: &str, bound: Duration) -> bool {
        let t0 = Instant::now();
        while t0.elapsed() < bound {
            if self.log().contains(what) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }

    /// SIGTERM, then its exit (within [`CEILING`]): status, summary JSON, log.
    pub fn stop(mut self) -> (ExitStatus, serde_json::Value, String) {
        let child = self.child.take().unwrap();
        // SAFETY: kill has no memory preconditions; pid is our child's.
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
        self.wait(child, CEILING)
    }

    /// Its exit by itself within `bound`.
    pub fn exit(mut self, bound: Duration) -> (ExitStatus, serde_json::Value, String) {
        let child = self.child.take().unwrap();
        self.wait(child, bound)
    }

    fn wait(
        &mut self,
        mut child: Child,
        bound: Duration,
    ) -> (ExitStatus, serde_json::Value, String) {
        let t0 = Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if t0.elapsed() > bound {
                let _ = child.kill();
                panic!(
                    "wmr serve still running {bound:?} after it should end: it hangs\n{}",
                    self.log()
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        // Both pipes read to their end: the whole summary and log.
        let rest = self.rest.take().unwrap().join().unwrap();
        if let Some(h) = self.stderr_reader.take() {
            let _ = h.join();
        }
        let summary = rest
            .lines()
            .rev()
            .find_map(|l| serde_json::from_str(l).ok())
            .unwrap_or(serde_json::Value::Null);
        (status, summary, self.log())
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}
