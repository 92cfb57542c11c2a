//! The server's I/O: one thread, one loop. The robot's port is read with
//! a 2 ms timeout (the loop's pace), the socket and the clients are
//! non-blocking; a client that does not read its frames loses them
//! (counted), never the robot or the other clients.

use super::core::{BestClock, Held, KeepAlive, ResetWatch};
use super::mux::{ClientId, Mux, MuxCounters, Note, Out, Own};
use super::{default_socket_path, ServeArgs, MAX_SOCKET_PATH};
use crate::link::Port;
use crate::session::ClockSample;
use crate::timing::LinkTiming;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::os::unix::fs::{FileTypeExt, PermissionsExt};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use wmr_protocol::{
    encode, Decoded, ErrorCode, Event, FrameDecoder, ParamId, Reply, Request, RunStateMsg,
    MAX_FRAME, PROTOCOL_VERSION,
};

/// Bytes queued for one client before its frames are dropped (about 1 s
/// of every telemetry group at 1 kHz).
const CLIENT_BUFFER: usize = 256 * 1024;
/// How often a lost port is re-opened.
const REOPEN_EVERY: Duration = Duration::from_millis(250);
/// An unanswered request is sent again after this long (D96): a pty or
/// USB round trip is about 1 ms, a UART's at 115 200 baud with the
/// largest frames both ways about 45 ms (then 4 x the best keep-alive
/// round trip, if longer) ...
const RESEND_EVERY: Duration = Duration::from_millis(25);
/// ... at most this many times (within a client's 100 ms answer timeout).
const RESENDS: u32 = 3;
/// How often the handshake is re-sent while the robot does not answer.
const HELLO_EVERY: Duration = Duration::from_millis(50);
/// Period of the server's status requests (state, counters, reset).
const STATUS_EVERY: Duration = Duration::from_millis(250);
/// A reset this soon after an acknowledged `Reboot` is the reboot.
const REBOOT_WINDOW: Duration = Duration::from_secs(10);
/// The port's read timeout: the loop's pace.
const PORT_READ: Duration = Duration::from_millis(2);
/// Empty reads in a row that mean the port hung up.
const HANGUP_READS: u32 = 20;
/// Client requests received while the link is not up are held this long
/// (a client that starts with its server gets its answer once the
/// handshake is done, instead of a lost request) ...
const HOLD_FOR: Duration = Duration::from_secs(1);
/// ... at most this many.
const HOLD_MAX: usize = 256;

/// What `wmr serve` prints when it ends (one JSON object on stdout).
#[derive(Clone, Debug, Default, Serialize)]
pub struct ServeSummary {
    /// The robot's port.
    pub port: String,
    /// The socket.
    pub socket: String,
    /// Time served \[s\].
    pub seconds: f64,
    /// Frames written to the robot (requests of clients and the server's own).
    pub frames_to_robot: u64,
    /// Frames not written whole within the port's write timeout (the robot
    /// not reading): lost.
    pub frames_to_robot_incomplete: u64,
    /// Valid frames received from the robot.
    pub frames_from_robot: u64,
    /// Frames from the robot dropped (bad CRC, malformed, too long): the line's faults.
    pub rx_errors: u64,
    /// Client requests dropped while the link was down (held for 1 s
    /// first: the client's retries then fail with "no answer").
    pub requests_dropped_link_down: u64,
    /// Clients that connected.
    pub clients_served: u64,
    /// Frames for clients dropped because the client did not read them.
    pub client_frames_dropped: u64,
    /// Robot resets not requested (its clock went back).
    pub resets: u32,
    /// Resets after an acknowledged `Reboot`.
    pub reboots: u32,
    /// Times the port was lost (read or write failed).
    pub port_losses: u32,
    /// Times the robot fell silent for the link timing's silence limit.
    pub silences: u32,
    /// Times the port was opened again after a loss.
    pub reconnects: u32,
    /// `Event::LinkLost` from the robot (its link-silence stop).
    pub link_lost_events: u32,
    /// Clock offset robot − host of the best recent sync \[µs\] (host
    /// time counted from the server's start).
    pub clock_offset_us: Option<i64>,
    /// Round trip of that sync \[µs\].
    pub clock_rtt_us: Option<u64>,
    /// The routing's counters.
    pub routing: MuxCounters,
    /// What made the exit status 1.
    pub unexpected: Vec<String>,
}

struct Client {
    stream: UnixStream,
    decoder: FrameDecoder<MAX_FRAME>,
    out: Vec<u8>,
    /// Logged once it sent a frame (`wmr --port` probing for a server
    /// connects and leaves at once).
    announced: bool,
}

#[derive(Clone, Copy, Debug)]
enum LinkState {
    Down {
        since: Instant,
        next_try: Instant,
        reported: bool,
    },
    Handshake {
        since: Instant,
        last_hello: Option<Instant>,
        reported: bool,
    },
    Up,
}

struct Server<'a> {
    port_path: String,
    port: Option<Box<dyn Port>>,
    decoder: FrameDecoder<MAX_FRAME>,
    mux: Mux,
    listener: UnixListener,
    clients: BTreeMap<ClientId, Client>,
    next_client: ClientId,
    link: LinkState,
    ever_up: bool,
    timing: LinkTiming,
    t0: Instant,
    last_tx: Instant,
    last_rx: Instant,
    keep: KeepAlive,
    last_client_rx: Option<Instant>,
    last_expire: Instant,
    silent_since: Option<Instant>,
    robot_state: Option<RunStateMsg>,
    resets: ResetWatch,
    reboot_acked: Option<Instant>,
    report_cause: bool,
    hello: Option<Reply>,
    clock: BestClock,
    fatal: Option<String>,
    held: Held,
    empty_reads: u32,
    s: ServeSummary,
    stop: &'a AtomicBool,
    live: Option<super::live::ServeLive>,
}

/// Why `wmr serve` ended with status 1.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// `--for` or `--give-up-after` out of range.
    #[error("--{flag} {value}: give a time in (0, 1e7] s")]
    BadTime {
        /// The flag.
        flag: &'static str,
        /// Its value.
        value: f64,
    },
    /// The socket could not be made (the message names it and why).
    #[error("{0}")]
    Socket(String),
    /// Writing stdout failed.
    #[error("cannot write the output: {0}")]
    Output(String),
    /// The link could not go on (version mismatch, refused handshake,
    /// `--give-up-after` passed).
    #[error("{0}")]
    Fatal(String),
    /// Something unexpected happened while serving.
    #[error("{} unexpected event(s) while serving {port}: {}", .events.len(), .events.join("; "))]
    Unexpected {
        /// The robot's port.
        port: String,
        /// What happened.
        events: Vec<String>,
    },
}

static SIGNALLED: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    SIGNALLED.store(true, Ordering::SeqCst);
}

/// `wmr serve --port PORT`: serves until Ctrl-C or SIGTERM (or `--for`);
/// prints the socket's path first and the [`ServeSummary`] last. `Err`
/// (exit status 1) on a fatal error or when something unexpected happened.
pub fn serve(port: &str, a: &ServeArgs, out: &mut dyn Write) -> Result<(), ServeError> {
    let handler = on_signal as extern "C" fn(libc::c_int);
    // SAFETY: the handler only stores to an atomic (async-signal-safe).
    unsafe {
        libc::signal(libc::SIGINT, handler as libc::sighandler_t);
        libc::signal(libc::SIGTERM, handler as libc::sighandler_t);
    }
    serve_until(port, a, out, &SIGNALLED)
}

/// [`serve`] until `stop` is set (no signal handlers: for library users
/// and tests running the server in a thread).
pub fn serve_until(
    port: &str,
    a: &ServeArgs,
    out: &mut dyn Write,
    stop: &AtomicBool,
) -> Result<(), ServeError> {
    let deadline = match a.for_s {
        None => None,
        Some(s) if s.is_finite() && s > 0.0 && s <= 1e7 => {
            Some(Instant::now() + Duration::from_secs_f64(s))
        }
        Some(value) => return Err(ServeError::BadTime { flag: "for", value }),
    };
    let give_up = match a.give_up_after {
        None => None,
        Some(s) if s.is_finite() && s > 0.0 && s <= 1e7 => Some(Duration::from_secs_f64(s)),
        Some(value) => {
            return Err(ServeError::BadTime {
                flag: "give-up-after",
                value,
            })
        }
    };
    let (sock, default_dir) = match &a.socket {
        Some(p) => (p.clone(), false),
        None => (default_socket_path(port), true),
    };
    let listener = bind(&sock, default_dir).map_err(ServeError::Socket)?;
    let shown = sock.display().to_string();
    let w = |out: &mut dyn Write, s: &str| -> Result<(), ServeError> {
        writeln!(out, "{s}")
            .and_then(|_| out.flush())
            .map_err(|e| ServeError::Output(e.to_string()))
    };
    if let Err(e) = w(out, &shown) {
        let _ = std::fs::remove_file(&sock);
        return Err(e);
    }
    let now = Instant::now();
    let mut server = Server {
        port_path: port.to_string(),
        port: None,
        decoder: FrameDecoder::new(),
        mux: Mux::new(),
        listener,
        clients: BTreeMap::new(),
        next_client: 1,
        link: LinkState::Down {
            since: now,
            next_try: now,
            reported: false,
        },
        ever_up: false,
        timing: LinkTiming::default(),
        t0: now,
        last_tx: now,
        last_rx: now,
        keep: KeepAlive::default(),
        last_client_rx: None,
        last_expire: now,
        silent_since: None,
        robot_state: None,
        resets: ResetWatch::default(),
        reboot_acked: None,
        report_cause: false,
        hello: None,
        clock: BestClock::default(),
        fatal: None,
        held: Held::new(HOLD_FOR, HOLD_MAX),
        empty_reads: 0,
        s: ServeSummary {
            port: port.to_string(),
            socket: shown.clone(),
            ..Default::default()
        },
        stop,
        live: a
            .live
            .then(|| super::live::ServeLive::new(a.live_at.clone(), a.com_offset_m)),
    };
    if a.live {
        server.mux.set_own_telemetry(super::mux::TelemetrySub {
            selection: wmr_protocol::TELEMETRY_ALL,
            rate_hz: a.live_rate_hz,
        });
    }
    server.log(&format!(
        "serving {port} on {shown} (clients: `wmr --serve {shown} CMD`, or `wmr --port {port} CMD`)"
    ));
    let r = server.run(deadline, give_up);
    server.shutdown();
    let _ = std::fs::remove_file(&sock);
    let mut summary = server.s.clone();
    summary.seconds = server.t0.elapsed().as_secs_f64();
    summary.routing = server.mux.counters;
    if let Some(c) = server.clock.best() {
        summary.clock_offset_us = Some(c.offset_us());
        summary.clock_rtt_us = Some(c.rtt_us);
    }
    let json = serde_json::to_string(&summary).map_err(|e| ServeError::Output(e.to_string()))?;
    w(out, &json)?;
    r.map_err(ServeError::Fatal)?;
    if summary.unexpected.is_empty() {
        Ok(())
    } else {
        Err(ServeError::Unexpected {
            port: port.to_string(),
            events: summary.unexpected,
        })
    }
}

/// Binds the socket: its directory must exist (the default one is
/// created, mode 0700); a stale socket (nobody listening) is replaced, a
/// live one or another file is an error.
fn bind(sock: &Path, default_dir: bool) -> Result<UnixListener, String> {
    let shown = sock.display();
    let len = sock.as_os_str().len();
    if len > MAX_SOCKET_PATH {
        return Err(format!(
            "socket path {shown} is too long ({len} bytes, a Unix socket takes at most {MAX_SOCKET_PATH}): give a shorter --socket"
        ));
    }
    let dir = match sock.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if default_dir {
        std::fs::create_dir_all(&dir)
            .and_then(|_| std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)))
            .map_err(|e| format!("cannot create the socket directory {}: {e}", dir.display()))?;
    } else if !dir.is_dir() {
        return Err(format!(
            "cannot create socket {shown}: directory {} does not exist",
            dir.display()
        ));
    }
    if let Ok(m) = std::fs::symlink_metadata(sock) {
        if !m.file_type().is_socket() {
            return Err(format!(
                "cannot create socket {shown}: a file that is not a socket is in the way"
            ));
        }
        if UnixStream::connect(sock).is_ok() {
            return Err(format!(
                "another wmr serve already listens on {shown} (stop it, or give --socket)"
            ));
        }
        std::fs::remove_file(sock)
            .map_err(|e| format!("cannot remove the stale socket {shown}: {e}"))?;
    }
    let l = UnixListener::bind(sock).map_err(|e| format!("cannot create socket {shown}: {e}"))?;
    let cleanup = |e: std::io::Error| {
        let _ = std::fs::remove_file(sock);
        format!("socket {shown}: {e}")
    };
    std::fs::set_permissions(sock, std::fs::Permissions::from_mode(0o600)).map_err(cleanup)?;
    l.set_nonblocking(true).map_err(cleanup)?;
    Ok(l)
}

fn transient(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::*;
    matches!(e.kind(), TimedOut | WouldBlock | Interrupted)
}

fn open_port(path: &str) -> Result<Box<dyn Port>, String> {
    if !Path::new(path).exists() {
        return Err("no such port".into());
    }
    let port = serialport::new(path, 115_200)
        .timeout(PORT_READ)
        .open_native()
        .map_err(|e| e.to_string())?;
    use serialport::SerialPort;
    let _ = port.clear(serialport::ClearBuffer::Input);
    Ok(Box::new(port))
}

impl Server<'_> {
    fn log(&self, msg: &str) {
        eprintln!(
            "wmr serve [{:9.3} s] {msg}",
            self.t0.elapsed().as_secs_f64()
        );
    }

    fn host_us(&self) -> u64 {
        self.t0.elapsed().as_micros() as u64
    }

    fn unexpected(&mut self, what: String) {
        self.log(&what);
        self.s.unexpected.push(what);
    }

    fn run(&mut self, deadline: Option<Instant>, give_up: Option<Duration>) -> Result<(), String> {
        loop {
            let now = Instant::now();
            if self.stop.load(Ordering::Relaxed) || deadline.is_some_and(|d| now >= d) {
                return Ok(());
            }
            if let Some(f) = self.fatal.take() {
                return Err(f);
            }
            self.accept();
            self.read_clients();
            self.poll_robot();
            self.timers(give_up);
            self.flush_clients();
        }
    }

    /// Telemetry off (the server's clients are gone) and the answers in
    /// flight read: until none is pending and the robot has been quiet for
    /// 50 ms, for at most 2 s (was 200 ms: a robot slow to answer, e.g. a
    /// simulated one on a loaded machine, left frames unread and the
    /// summary's counts short).
    fn shutdown(&mut self) {
        let ids: Vec<ClientId> = self.clients.keys().copied().collect();
        for id in ids {
            self.drop_client(id);
        }
        if self.port.is_some() && matches!(self.link, LinkState::Up) {
            let o = self.mux.telemetry_request(Instant::now());
            self.dispatch(vec![o]);
        }
        let end = Instant::now() + Duration::from_secs(2);
        let mut quiet_since = Instant::now();
        while self.port.is_some() && Instant::now() < end {
            let before = self.s.frames_from_robot + self.s.rx_errors;
            self.poll_robot();
            if self.s.frames_from_robot + self.s.rx_errors != before {
                quiet_since = Instant::now();
            } else if quiet_since.elapsed() > Duration::from_millis(50) && self.mux.pending() == 0 {
                break;
            }
        }
        if !matches!(self.link, LinkState::Up) && self.s.unexpected.is_empty() {
            self.s.unexpected.push(format!(
                "the link to {} was down at the end",
                self.port_path
            ));
        }
    }

    fn accept(&mut self) {
        loop {
            match self.listener.accept() {
                Ok((stream, _)) => {
                    if stream.set_nonblocking(true).is_err() {
                        continue;
                    }
                    let id = self.next_client;
                    self.next_client += 1;
                    self.clients.insert(
                        id,
                        Client {
                            stream,
                            decoder: FrameDecoder::new(),
                            out: Vec::new(),
                            announced: false,
                        },
                    );
                    self.mux.add_client(id);
                    self.s.clients_served += 1;
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    self.log(&format!("accept: {e}"));
                    return;
                }
            }
        }
    }

    fn drop_client(&mut self, id: ClientId) {
        let Some(c) = self.clients.remove(&id) else {
            return;
        };
        let outs = self.mux.remove_client(id, Instant::now());
        self.dispatch(outs);
        if c.announced {
            self.log(&format!(
                "client {id} disconnected ({} connected)",
                self.clients.len()
            ));
        }
    }

    fn read_clients(&mut self) {
        let mut frames = Vec::new();
        let mut gone = Vec::new();
        let mut buf = [0u8; 4096];
        for (id, c) in self.clients.iter_mut() {
            loop {
                match c.stream.read(&mut buf) {
                    Ok(0) => {
                        gone.push(*id);
                        break;
                    }
                    Ok(n) => {
                        let mut rest = &buf[..n];
                        while !rest.is_empty() {
                            let (d, r) = c.decoder.feed::<Request>(rest);
                            rest = r;
                            if let Some(d) = d {
                                frames.push((*id, d));
                            }
                        }
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                    Err(_) => {
                        gone.push(*id);
                        break;
                    }
                }
            }
        }
        for (id, d) in frames {
            self.client_frame(id, d);
        }
        for id in gone {
            self.drop_client(id);
        }
    }

    fn client_frame(&mut self, id: ClientId, d: Decoded<Request>) {
        let now = Instant::now();
        let n = self.clients.len();
        if let Some(c) = self.clients.get_mut(&id).filter(|c| !c.announced) {
            c.announced = true;
            self.log(&format!("client {id} connected ({n} connected)"));
        }
        match d {
            Decoded::Frame { seq, msg } => {
                self.last_client_rx = Some(now);
                if matches!(self.link, LinkState::Up) {
                    let outs = self.mux.from_client(id, seq, msg, now);
                    self.dispatch(outs);
                } else {
                    self.s.requests_dropped_link_down += self.held.hold(id, seq, msg, now);
                }
            }
            // A client of another version: the robot's hello (so that it
            // names both versions), a refusal for anything else.
            Decoded::OtherVersion { seq, msg, .. } => {
                let r = match (msg, &self.hello) {
                    (Some(Request::Hello { .. }), Some(h)) => super::with_seq(h.clone(), seq),
                    _ => Reply::Nack {
                        seq,
                        error: ErrorCode::VersionMismatch,
                    },
                };
                self.send_client(id, &r);
            }
            Decoded::Error {
                seq: Some(seq),
                error,
            } => self.send_client(id, &Reply::Nack { seq, error }),
            Decoded::Error { seq: None, error } => {
                self.send_client(id, &Reply::FrameError { error })
            }
        }
    }

    fn send_client(&mut self, id: ClientId, reply: &Reply) {
        let Some(c) = self.clients.get_mut(&id) else {
            return;
        };
        let mut buf = [0u8; MAX_FRAME];
        let Ok(frame) = encode(reply, reply.seq().unwrap_or(0), &mut buf) else {
            return;
        };
        if c.out.len() + frame.len() > CLIENT_BUFFER {
            self.s.client_frames_dropped += 1;
            return;
        }
        c.out.extend_from_slice(frame);
    }

    fn flush_clients(&mut self) {
        let mut gone = Vec::new();
        for (id, c) in self.clients.iter_mut() {
            while !c.out.is_empty() {
                match c.stream.write(&c.out) {
                    Ok(0) => {
                        gone.push(*id);
                        break;
                    }
                    Ok(n) => {
                        c.out.drain(..n);
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                    Err(_) => {
                        gone.push(*id);
                        break;
                    }
                }
            }
        }
        for id in gone {
            self.drop_client(id);
        }
    }

    fn dispatch(&mut self, outs: Vec<Out>) {
        for o in outs {
            match o {
                Out::Robot(seq, req) => self.send_robot(seq, &req),
                Out::Client(id, r) => self.send_client(id, &r),
            }
        }
    }

    fn send_robot(&mut self, seq: u16, req: &Request) {
        let Some(port) = self.port.as_mut() else {
            return;
        };
        let mut buf = [0u8; MAX_FRAME + 1];
        // A leading delimiter resynchronises a robot that saw half a frame.
        let Ok(n) = encode(req, seq, &mut buf[1..]).map(|f| f.len()) else {
            return;
        };
        match port.write_all(&buf[..n + 1]).and_then(|_| port.flush()) {
            Ok(()) => {
                self.s.frames_to_robot += 1;
                self.last_tx = Instant::now();
            }
            // The robot does not read (its receive buffer full, a stalled
            // simulator): the frame is lost, not the port (its re-send or
            // the client's covers it; the next frame's delimiter resyncs).
            Err(e) if transient(&e) => self.s.frames_to_robot_incomplete += 1,
            Err(e) => self.port_lost(format!("write: {e}")),
        }
    }

    /// What the live view asked for.
    fn live_step(&mut self, step: super::live::LiveStep) {
        match step {
            super::live::LiveStep::None => {}
            super::live::LiveStep::Ask(req) => self.own(Own::RobotRead, req),
            super::live::LiveStep::Log(line) => self.log(&line),
        }
    }

    fn own(&mut self, own: Own, req: Request) {
        let o = self.mux.own(own, req, Instant::now());
        self.dispatch(vec![o]);
    }

    fn port_lost(&mut self, why: String) {
        self.port = None;
        self.empty_reads = 0;
        self.decoder = FrameDecoder::new();
        self.s.port_losses += 1;
        let now = Instant::now();
        self.link = LinkState::Down {
            since: now,
            next_try: now + REOPEN_EVERY,
            reported: true,
        };
        self.unexpected(format!(
            "port {} lost ({why}); re-opening it every {} ms",
            self.port_path,
            REOPEN_EVERY.as_millis()
        ));
    }

    fn poll_robot(&mut self) {
        let Some(port) = self.port.as_mut() else {
            std::thread::sleep(PORT_READ);
            return;
        };
        let mut chunk = [0u8; 2048];
        match port.read(&mut chunk) {
            // A tty read returns nothing only once poll said it could: the
            // other end hung up (a pty whose simulator exited; a USB port
            // errs instead). A few in a row, so that one spurious wake-up
            // is not a loss.
            Ok(0) => {
                self.empty_reads += 1;
                if self.empty_reads >= HANGUP_READS {
                    self.port_lost("the other end hung up".into());
                }
            }
            Ok(n) => {
                self.empty_reads = 0;
                self.feed(&chunk[..n])
            }
            Err(e) if transient(&e) => self.empty_reads = 0,
            Err(e) => self.port_lost(format!("read: {e}")),
        }
    }

    fn feed(&mut self, bytes: &[u8]) {
        let mut rest = bytes;
        while !rest.is_empty() {
            let (d, r) = self.decoder.feed::<Reply>(rest);
            rest = r;
            match d {
                Some(Decoded::Frame { msg, .. }) => {
                    self.s.frames_from_robot += 1;
                    self.heard();
                    self.reply(msg);
                }
                Some(Decoded::OtherVersion { version, msg, .. }) => {
                    self.s.frames_from_robot += 1;
                    self.heard();
                    if let Some(Reply::Hello { .. }) = msg {
                        self.fatal = Some(format!(
                            "version mismatch: the robot on {} speaks protocol {version}, wmr speaks {PROTOCOL_VERSION}",
                            self.port_path
                        ));
                    }
                }
                Some(Decoded::Error { .. }) => self.s.rx_errors += 1,
                None => {}
            }
        }
    }

    fn heard(&mut self) {
        self.last_rx = Instant::now();
        if let Some(since) = self.silent_since.take() {
            self.log(&format!(
                "the robot answers again after {:.1} s",
                since.elapsed().as_secs_f64()
            ));
        }
    }

    fn observe_clock(&mut self, robot_us: u32) {
        if let Some(why) = self.resets.clock(robot_us, Instant::now()) {
            self.reset(why);
        }
    }

    fn reset(&mut self, why: String) {
        let requested = self
            .reboot_acked
            .take()
            .is_some_and(|t| t.elapsed() < REBOOT_WINDOW);
        if requested {
            self.s.reboots += 1;
            self.log(&format!("the robot rebooted as requested: {why}"));
        } else {
            self.s.resets += 1;
            self.unexpected(format!("robot reset: {why}"));
        }
        self.resets.forget_ticks();
        self.robot_state = Some(RunStateMsg::Hold);
        self.report_cause = true;
        // It forgot its telemetry setting and any link timeout set.
        self.mux.robot_reset();
        let o = self.mux.telemetry_request(Instant::now());
        self.dispatch(vec![o]);
        self.own(Own::LinkTimeout, Request::GetParam(ParamId::LinkTimeoutMs));
        self.own(Own::Status, Request::GetStatus);
    }

    /// What every frame from the robot tells the server, then its routing.
    fn reply(&mut self, msg: Reply) {
        match &msg {
            Reply::Telemetry(t) => {
                self.observe_clock(t.t_robot_us);
                self.robot_state = Some(t.state);
                if let Some(Err(e)) = self.live.as_mut().map(|l| l.telemetry(t)) {
                    self.unexpected(e);
                }
            }
            Reply::ClockSync { robot_time_us, .. } => self.observe_clock(*robot_time_us),
            Reply::Status { status, .. } => {
                if let Some(step) = self
                    .live
                    .as_mut()
                    .map(|l| l.on_status(status.robot.active_crc32))
                {
                    self.live_step(step);
                }
                let ticks = status.counters.ticks;
                if let Some(why) = self.resets.status(status.t_robot_us, ticks, Instant::now()) {
                    self.reset(why);
                    // This status is the restarted robot's.
                    self.resets.status(status.t_robot_us, ticks, Instant::now());
                }
                self.robot_state = Some(status.state);
                if std::mem::take(&mut self.report_cause) {
                    self.log(&format!(
                        "the robot's last reset cause: {:?} (state {:?}, robot time {:.3} s)",
                        status.board.reset_cause,
                        status.state,
                        status.t_robot_us as f64 * 1e-6
                    ));
                }
            }
            Reply::Event(Event::StateChanged { state, cause }) => {
                self.robot_state = Some(*state);
                if let Some(c) = cause {
                    self.log(&format!("robot: {state:?} ({c:?})"));
                }
            }
            Reply::Event(Event::LinkLost) => {
                self.s.link_lost_events += 1;
                let live = self
                    .last_client_rx
                    .is_some_and(|t| t.elapsed() < self.timing.link_timeout);
                self.unexpected(format!(
                    "the robot's link-silence stop (Event::LinkLost){}",
                    if live {
                        " although a client was alive"
                    } else {
                        ": no client kept it alive"
                    }
                ));
            }
            _ => {}
        }
        let (outs, note) = self.mux.from_robot(msg);
        self.dispatch(outs);
        match note {
            None => {}
            Some(Note::LinkTimeoutSet(v)) => self.set_link_timeout(v),
            Some(Note::RebootAcked) => self.reboot_acked = Some(Instant::now()),
            Some(Note::Own(own, r)) => self.own_reply(own, *r),
        }
    }

    fn set_link_timeout(&mut self, v: f32) {
        if v.is_finite() && v >= 1.0 && v <= u32::MAX as f32 {
            let t = LinkTiming::from_link_timeout_ms(v as u32);
            if t != self.timing {
                self.timing = t;
                self.log(&format!(
                    "link timeout {} ms: keep-alive every {} ms",
                    t.link_timeout.as_millis(),
                    t.keep_alive.as_millis()
                ));
            }
        }
    }

    fn own_reply(&mut self, own: Own, r: Reply) {
        match (own, r) {
            // A late answer to an earlier handshake.
            (Own::Hello, Reply::Hello { .. }) if matches!(self.link, LinkState::Up) => {}
            (Own::Hello, h @ Reply::Hello { .. }) => {
                let Reply::Hello {
                    version, ref chip, ..
                } = h
                else {
                    return;
                };
                if version != PROTOCOL_VERSION {
                    self.fatal = Some(format!(
                        "version mismatch: the robot on {} speaks protocol {version}, wmr speaks {PROTOCOL_VERSION}",
                        self.port_path
                    ));
                    return;
                }
                self.log(&format!(
                    "connected to the robot on {} ({chip}, protocol {version})",
                    self.port_path
                ));
                if let Some(step) = self.live.as_mut().map(|l| l.on_hello(&h, Instant::now())) {
                    self.live_step(step);
                }
                self.hello = Some(h);
                self.link = LinkState::Up;
                if self.ever_up {
                    self.s.reconnects += 1;
                }
                self.ever_up = true;
                self.last_rx = Instant::now();
                // What it has now: its link timeout, state, telemetry.
                self.mux.robot_reset();
                let o = self.mux.telemetry_request(Instant::now());
                self.dispatch(vec![o]);
                self.own(Own::LinkTimeout, Request::GetParam(ParamId::LinkTimeoutMs));
                self.own(Own::Status, Request::GetStatus);
                self.keep.status_sent(Instant::now());
                // Requests that came meanwhile, if their clients still wait.
                let now = Instant::now();
                let clients = &self.clients;
                let (fresh, dropped) = self.held.release(now, |id| clients.contains_key(&id));
                self.s.requests_dropped_link_down += dropped;
                for (id, seq, req) in fresh {
                    let outs = self.mux.from_client(id, seq, req, now);
                    self.dispatch(outs);
                }
            }
            (Own::Hello, Reply::Nack { error, .. }) => {
                self.fatal = Some(format!(
                    "the robot on {} refused the handshake: {}",
                    self.port_path,
                    error.reason()
                ));
            }
            (Own::LinkTimeout, Reply::Param { value, .. }) => self.set_link_timeout(value),
            (Own::RobotRead, r) => {
                if let Some(step) = self.live.as_mut().map(|l| l.on_record(r)) {
                    self.live_step(step);
                }
            }
            (
                Own::KeepAlive,
                Reply::ClockSync {
                    host_time_us,
                    robot_time_us,
                    ..
                },
            ) => {
                let Some(sample) =
                    ClockSample::of_exchange(host_time_us, self.host_us(), robot_time_us)
                else {
                    return;
                };
                if self.clock.offer(sample, Instant::now()) {
                    self.log(&format!(
                        "clock: robot − host {} µs (round trip {} µs)",
                        sample.offset_us(),
                        sample.rtt_us
                    ));
                }
            }
            _ => {}
        }
    }

    fn give_up(&mut self, since: Instant, give_up: Option<Duration>, what: &str) {
        if let Some(g) = give_up {
            if since.elapsed() >= g && self.fatal.is_none() {
                self.fatal = Some(format!(
                    "gave up after {:.1} s: {what} (--give-up-after)",
                    since.elapsed().as_secs_f64()
                ));
            }
        }
    }

    fn timers(&mut self, give_up: Option<Duration>) {
        let now = Instant::now();
        if let Some(step) = self.live.as_mut().map(|l| l.poll(now)) {
            self.live_step(step);
        }
        if matches!(self.link, LinkState::Up) {
            let every = RESEND_EVERY
                .max(4 * Duration::from_micros(self.clock.best().map_or(0, |c| c.rtt_us)));
            let outs = self.mux.resends(now, every, RESENDS);
            self.dispatch(outs);
        }
        if now.duration_since(self.last_expire) >= Duration::from_secs(1) {
            self.mux.expire(now);
            self.last_expire = now;
        }
        match self.link {
            LinkState::Down {
                since,
                next_try,
                reported,
            } => {
                if now >= next_try {
                    match open_port(&self.port_path) {
                        Ok(p) => {
                            self.port = Some(p);
                            self.decoder = FrameDecoder::new();
                            if self.ever_up {
                                self.log(&format!(
                                    "port {} open again after {:.1} s",
                                    self.port_path,
                                    since.elapsed().as_secs_f64()
                                ));
                            }
                            self.link = LinkState::Handshake {
                                since,
                                last_hello: None,
                                reported: false,
                            };
                        }
                        Err(e) => {
                            if !reported {
                                self.log(&format!(
                                    "cannot open {}: {e}; retrying every {} ms",
                                    self.port_path,
                                    REOPEN_EVERY.as_millis()
                                ));
                            }
                            self.link = LinkState::Down {
                                since,
                                next_try: now + REOPEN_EVERY,
                                reported: true,
                            };
                        }
                    }
                }
                let what = if self.ever_up {
                    format!("port {} lost", self.port_path)
                } else {
                    format!("port {} cannot be opened", self.port_path)
                };
                self.give_up(since, give_up, &what);
            }
            LinkState::Handshake {
                since,
                last_hello,
                reported,
            } => {
                if last_hello.is_none_or(|t| now.duration_since(t) >= HELLO_EVERY) {
                    self.own(
                        Own::Hello,
                        Request::Hello {
                            version: PROTOCOL_VERSION,
                        },
                    );
                    let reported =
                        if !reported && now.duration_since(since) > Duration::from_secs(3) {
                            self.log(&format!(
                                "no answer from the robot on {} yet; retrying",
                                self.port_path
                            ));
                            true
                        } else {
                            reported
                        };
                    if let LinkState::Handshake { .. } = self.link {
                        self.link = LinkState::Handshake {
                            since,
                            last_hello: Some(now),
                            reported,
                        };
                    }
                }
                self.give_up(
                    since,
                    give_up,
                    &format!("no handshake with the robot on {}", self.port_path),
                );
            }
            LinkState::Up => self.keep_alive(now, give_up),
        }
    }

    /// Keep-alives and status while a client is alive or the robot is not
    /// moving; silence otherwise, so that the robot's link-silence stop
    /// fires when nobody drives it (a probe after twice its link timeout).
    fn keep_alive(&mut self, now: Instant, give_up: Option<Duration>) {
        let due = self.keep.due(
            now,
            &self.timing,
            STATUS_EVERY,
            self.last_client_rx,
            self.last_tx,
            self.robot_state,
        );
        if due.keep_alive {
            let host_time_us = self.host_us();
            self.own(Own::KeepAlive, Request::ClockSync { host_time_us });
        }
        if due.status {
            self.own(Own::Status, Request::GetStatus);
        }
        let silent = now.duration_since(self.last_rx);
        if silent > self.timing.silence_limit && now.duration_since(self.last_tx) < silent {
            match self.silent_since {
                None => {
                    self.silent_since = Some(self.last_rx);
                    self.s.silences += 1;
                    self.unexpected(format!(
                        "the robot on {} is silent ({:.1} s without a frame)",
                        self.port_path,
                        silent.as_secs_f64()
                    ));
                }
                Some(since) => self.give_up(since, give_up, "the robot is silent"),
            }
        }
    }
}
