//! The host end of the link: frames requests, waits for the answer with the
//! same sequence number, keeps telemetry and events that arrive meanwhile,
//! and turns every failure into a one-line [`LinkError`].

use crate::timing::LinkTiming;
use std::collections::VecDeque;
use std::io::{Read, Write};
use std::time::{Duration, Instant};
use wmr_protocol::{
    encode, Decoded, ErrorCode, FrameDecoder, Reply, Request, RobotInfo, MAX_FRAME,
    PROTOCOL_VERSION,
};

/// Why a command failed; `Display` is the one line `wmr` prints.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum LinkError {
    /// The port does not exist.
    NoSuchPort(String),
    /// The port exists but cannot be opened or configured.
    Open {
        /// The port.
        port: String,
        /// Why, as far as wmr can tell.
        kind: OpenFailure,
        /// The operating system's words.
        detail: String,
    },
    /// No answer within the timeout (what was waited for).
    NoAnswer(String),
    /// No answer to a request after every re-send: the robot is silent.
    Silent {
        /// The port (or the `wmr serve` socket).
        port: String,
        /// The request.
        request: String,
        /// How many times it was sent.
        tries: u32,
        /// How long wmr waited after each [ms].
        each_ms: u64,
    },
    /// Reading or writing the port failed: the link is gone.
    Lost {
        /// The port (or the `wmr serve` socket).
        port: String,
        /// The operating system's words.
        detail: String,
    },
    /// The robot speaks another protocol version.
    VersionMismatch {
        /// The robot's version.
        robot: u16,
    },
    /// The robot refused the request.
    Nack(String, ErrorCode),
    /// An unexpected answer.
    Unexpected(String),
    /// A local failure with its message (a file, an argument, an output):
    /// not the link's (that is [`LinkError::Lost`]).
    Io(String),
    /// The robot stopped when the host did not expect it (what and when).
    UnexpectedStop(String),
    /// No `wmr serve` at this socket (the socket, why).
    NoServer(String, String),
    /// `wmr upload` refused the file (what, by how much, what to do).
    Upload(Box<crate::refusal::UploadError>),
}

impl From<crate::refusal::UploadError> for LinkError {
    fn from(e: crate::refusal::UploadError) -> Self {
        Self::Upload(Box::new(e))
    }
}

impl std::fmt::Display for LinkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoSuchPort(p) => write!(
                f,
                "no such port: {p}: is the robot plugged in and powered (`ls /dev/ttyACM* \
                 /dev/ttyUSB*` lists the ports)? The simulated robot prints its port as its first \
                 line (`hil-sim device --pty`) and the port goes when it exits; give it with \
                 --port PATH or WMR_PORT"
            ),
            Self::Open { port, kind, detail } => {
                write!(f, "cannot open {port} ({detail}): ")?;
                match kind {
                    OpenFailure::Permission => write!(
                        f,
                        "no permission: add yourself to the port's group (`ls -l {port}` names it, \
                         usually dialout: `sudo usermod -aG dialout $USER`, then log in again)"
                    ),
                    OpenFailure::NotATerminal => write!(
                        f,
                        "it is not a serial port or terminal: give the robot's port (a USB robot: \
                         /dev/ttyACM*; the simulated robot prints its pty as its first line)"
                    ),
                    OpenFailure::Busy => write!(
                        f,
                        "another process has it: if it is `wmr serve`, give --serve SOCKET (or run \
                         the command with the same --port: it finds the server); else stop that \
                         process (`fuser {port}` names it)"
                    ),
                    OpenFailure::Other => write!(f, "check that it is the robot's port"),
                }
            }
            Self::NoAnswer(what) => write!(f, "no answer from the robot to {what}"),
            Self::Silent {
                port,
                request,
                tries,
                each_ms,
            } => write!(
                f,
                "no answer from the robot on {port} to {request} (sent {tries} times, {each_ms} ms \
                 apart): is it powered and running its firmware, and is {port} its port (a USB \
                 robot is /dev/ttyACM*, the simulated robot prints its port)? On a slow link raise \
                 --timeout-ms"
            ),
            Self::Lost { port, detail } => write!(
                f,
                "lost the link on {port} ({detail}): the robot was unplugged, reset or powered \
                 off, or the simulated robot exited (its port changes when it restarts); \
                 reconnect it and run the command again (`wmr status` checks the link)"
            ),
            Self::VersionMismatch { robot } => write!(
                f,
                "version mismatch: the robot speaks protocol {robot}, wmr speaks {PROTOCOL_VERSION}"
            ),
            Self::Nack(what, e) => {
                write!(f, "the robot refused {what}: {}", e.reason())?;
                match nack_advice(what, *e) {
                    Some(a) => write!(f, "; {a}"),
                    None => Ok(()),
                }
            }
            Self::Unexpected(what) => write!(f, "unexpected answer: {what}"),
            Self::Io(e) => write!(f, "{e}"),
            Self::UnexpectedStop(s) => write!(f, "the robot stopped unexpectedly: {s}"),
            Self::NoServer(p, e) => write!(f, "cannot connect to wmr serve at {p}: {e}"),
            Self::Upload(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for LinkError {}

/// The command that gets out of a refusal, where there is one.
pub fn nack_advice(request: &str, e: ErrorCode) -> Option<&'static str> {
    Some(match e {
        ErrorCode::Latched => {
            "`wmr status` shows why it stopped; fix that, then `wmr clear` releases the stop"
        }
        ErrorCode::Busy => "`wmr disarm` stops it first (or wait for the run to end)",
        ErrorCode::NoReference => {
            "load one first: `wmr upload FILE` (a trajectory or scenario file), or drive with \
             `wmr drive`"
        }
        ErrorCode::UploadIncomplete => {
            "upload it again (`wmr upload FILE`); a path longer than the robot's buffer runs \
             with `wmr upload FILE --arm`, which streams the rest"
        }
        ErrorCode::InvalidValue if request == "SetParam" => {
            "`wmr params get` lists every parameter with its range"
        }
        ErrorCode::ReadOnly => "`wmr params get` marks the writable parameters",
        ErrorCode::WrongMode => "`wmr status` shows the mode loaded",
        ErrorCode::NoStore => {
            "this firmware has no robot store: its robot file is compiled in (firmware/README.md)"
        }
        ErrorCode::BufferFull => "send it again once the robot has passed some waypoints",
        ErrorCode::VersionMismatch => "update wmr or the firmware so that both speak one protocol",
        _ => return None,
    })
}

/// Why a port could not be opened, as far as wmr can tell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OpenFailure {
    /// The user may not open it.
    Permission,
    /// Not a serial port or terminal (a file, `/dev/null`).
    NotATerminal,
    /// Another process holds it (locked or busy).
    Busy,
    /// Anything else.
    Other,
}

impl OpenFailure {
    /// Classifies a serialport error.
    pub fn of(e: &serialport::Error) -> Self {
        let d = e.description.to_ascii_lowercase();
        match e.kind {
            serialport::ErrorKind::Io(std::io::ErrorKind::PermissionDenied) => Self::Permission,
            serialport::ErrorKind::NoDevice => Self::Busy,
            _ if d.contains("permission") => Self::Permission,
            _ if d.contains("lock") || d.contains("busy") => Self::Busy,
            _ if d.contains("typewriter") || d.contains("inappropriate ioctl") => {
                Self::NotATerminal
            }
            _ => Self::Other,
        }
    }
}

/// A byte stream to the robot (a serial port, a pseudo-terminal).
pub trait Port: Read + Write + Send {}
impl<T: Read + Write + Send> Port for T {}

/// What the handshake told.
#[derive(Clone, Debug, PartialEq)]
pub struct HelloInfo {
    /// The robot's protocol version (equal to ours after [`Link::hello`]).
    pub version: u16,
    /// `CAP_*` bits.
    pub capabilities: u16,
    /// Chip or board.
    pub chip: String,
    /// Robot constants.
    pub robot: RobotInfo,
}

/// The host end of the link.
pub struct Link {
    port: Box<dyn Port>,
    decoder: FrameDecoder<MAX_FRAME>,
    seq: u16,
    timing: LinkTiming,
    /// An answer timeout given by the user (kept when the timing is re-derived).
    answer_override: Option<Duration>,
    last_rx: Instant,
    /// Telemetry and events received while waiting for answers, oldest first.
    pub stream: VecDeque<Reply>,
    /// The last successful handshake.
    pub last_hello: Option<HelloInfo>,
    buf: Vec<u8>,
    /// The port's path (or the server's socket) for error messages.
    name: String,
}

/// A short name of a request for error messages.
pub fn request_name(r: &Request) -> String {
    let s = format!("{r:?}");
    let end = s.find([' ', '(', '{']).unwrap_or(s.len());
    s[..end].to_string()
}

impl Link {
    /// Opens a serial port or pseudo-terminal at `path` with a fixed answer
    /// timeout (see [`Link::open_timed`]).
    pub fn open(path: &str, timeout: Duration) -> Result<Self, LinkError> {
        Self::open_timed(path, Some(timeout))
    }

    /// Opens a serial port or pseudo-terminal at `path` (the baud rate does
    /// not matter for USB CDC and ptys; 115200 for a UART); `timeout`, when
    /// given, replaces the answer timeout derived from the link timeout.
    pub fn open_timed(path: &str, timeout: Option<Duration>) -> Result<Self, LinkError> {
        if !std::path::Path::new(path).exists() {
            return Err(LinkError::NoSuchPort(path.into()));
        }
        let port = serialport::new(path, 115_200)
            .timeout(Duration::from_millis(5))
            .open_native()
            .map_err(|e| LinkError::Open {
                port: path.into(),
                kind: OpenFailure::of(&e),
                detail: e.to_string(),
            })?;
        use serialport::SerialPort;
        // Stale bytes from before we opened (telemetry to nobody) go.
        let _ = port.clear(serialport::ClearBuffer::Input);
        Ok(Self::from_port_timed(Box::new(port), timeout).named(path))
    }

    /// A link over any byte stream with a fixed answer timeout (see
    /// [`Link::from_port_timed`]).
    pub fn from_port(port: Box<dyn Port>, timeout: Duration) -> Self {
        Self::from_port_timed(port, Some(timeout))
    }

    /// A link over any byte stream whose reads return within a few ms
    /// (errors of kind `TimedOut`/`WouldBlock` mean "nothing yet"), timed for
    /// the default link timeout ([`LinkTiming::default`]); `timeout`, when
    /// given, replaces the derived answer timeout.
    pub fn from_port_timed(port: Box<dyn Port>, timeout: Option<Duration>) -> Self {
        let mut timing = LinkTiming::default();
        if let Some(t) = timeout {
            timing = timing.with_answer_timeout(t);
        }
        Self {
            port,
            decoder: FrameDecoder::new(),
            seq: 0,
            timing,
            answer_override: timeout,
            last_rx: Instant::now(),
            stream: VecDeque::new(),
            last_hello: None,
            buf: Vec::new(),
            name: "the robot's port".into(),
        }
    }

    /// The link named `name` in its errors (the port's path).
    pub fn named(mut self, name: &str) -> Self {
        self.name = name.into();
        self
    }

    /// The port's path (or the server's socket), as errors name it.
    pub fn name(&self) -> &str {
        &self.name
    }

    fn lost(&self, e: std::io::Error) -> LinkError {
        LinkError::Lost {
            port: self.name.clone(),
            detail: e.to_string(),
        }
    }

    /// The answer timeout.
    pub fn timeout(&self) -> Duration {
        self.timing.answer_timeout
    }

    /// The link's timing.
    pub fn timing(&self) -> LinkTiming {
        self.timing
    }

    /// Re-derives the timing from the robot's link timeout (read after the
    /// handshake); an answer timeout given to [`Link::from_port`] is kept.
    pub fn set_link_timeout_ms(&mut self, link_timeout_ms: u32) {
        let t = LinkTiming::from_link_timeout_ms(link_timeout_ms);
        self.timing = match self.answer_override {
            Some(a) => t.with_answer_timeout(a),
            None => t,
        };
    }

    /// When the last valid frame arrived (the link's creation before any).
    pub fn last_rx(&self) -> Instant {
        self.last_rx
    }

    /// Sends `req` with a fresh sequence number; returns the number.
    pub fn send(&mut self, req: &Request) -> Result<u16, LinkError> {
        // 0 is the sequence number of streams: never used for a request.
        self.seq = self.seq.checked_add(1).unwrap_or(1);
        let mut buf = [0u8; MAX_FRAME + 1];
        // A leading delimiter resynchronises a robot that saw half a frame.
        buf[0] = 0;
        let n = encode(req, self.seq, &mut buf[1..])
            .map_err(|_| LinkError::Io("request too large".into()))?
            .len();
        self.port
            .write_all(&buf[..n + 1])
            .and_then(|_| self.port.flush())
            .map_err(|e| self.lost(e))?;
        Ok(self.seq)
    }

    /// Writes raw bytes (tests: garbage on the wire).
    pub fn write_raw(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.port.write_all(bytes).map_err(|e| self.lost(e))
    }

    /// Reads what the port has (waiting at most its read timeout) and
    /// decodes it: answers are returned, streams queued.
    fn poll(&mut self) -> Result<Vec<(u16, Reply)>, LinkError> {
        let mut chunk = [0u8; 1024];
        match self.port.read(&mut chunk) {
            Ok(n) => self.buf.extend_from_slice(&chunk[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut
                        | std::io::ErrorKind::WouldBlock
                        | std::io::ErrorKind::Interrupted
                ) =>
            {
                std::thread::sleep(Duration::from_millis(1));
            }
            Err(e) => return Err(self.lost(e)),
        }
        let mut answers = Vec::new();
        let bytes = std::mem::take(&mut self.buf);
        let mut rest = &bytes[..];
        while !rest.is_empty() {
            let (d, r) = self.decoder.feed::<Reply>(rest);
            rest = r;
            if matches!(
                d,
                Some(Decoded::Frame { .. } | Decoded::OtherVersion { .. })
            ) {
                self.last_rx = Instant::now();
            }
            match d {
                Some(Decoded::Frame { msg, .. }) => match &msg {
                    Reply::Telemetry(_) | Reply::Event(_) => self.stream.push_back(msg),
                    _ => answers.push((msg.seq().unwrap_or(0), msg)),
                },
                Some(Decoded::OtherVersion { version, msg, .. }) => {
                    if let Some(Reply::Hello { seq, .. }) = msg {
                        answers.push((
                            seq,
                            Reply::Hello {
                                seq,
                                version,
                                capabilities: 0,
                                chip: heapless::String::new(),
                                robot: RobotInfo {
                                    wheel_radius_m: 0.0,
                                    half_track_m: 0.0,
                                    mass_kg: 0.0,
                                    control_period_s: 0.0,
                                    torque_limit_nm: 0.0,
                                },
                            },
                        ));
                    } else {
                        return Err(LinkError::VersionMismatch { robot: version });
                    }
                }
                // A partial frame at the start, noise: skip.
                Some(Decoded::Error { .. }) | None => {}
            }
        }
        Ok(answers)
    }

    /// Reads for up to `wait`; returns the next telemetry or event frame.
    pub fn next_stream(&mut self, wait: Duration) -> Result<Option<Reply>, LinkError> {
        let end = Instant::now() + wait;
        loop {
            if let Some(r) = self.stream.pop_front() {
                return Ok(Some(r));
            }
            self.poll()?;
            if Instant::now() >= end && self.stream.is_empty() {
                return Ok(None);
            }
        }
    }

    /// Reads for up to `wait`; returns the answers that arrived (any
    /// sequence number; telemetry and events go to [`Link::stream`]).
    pub fn receive(&mut self, wait: Duration) -> Result<Vec<(u16, Reply)>, LinkError> {
        let end = Instant::now() + wait;
        let mut answers = Vec::new();
        loop {
            answers.extend(self.poll()?);
            if Instant::now() >= end || !answers.is_empty() {
                return Ok(answers);
            }
        }
    }

    /// Sends `req` and waits for its answer, re-sending it on silence
    /// ([`LinkTiming::attempts`] times, [`LinkTiming::answer_timeout`] each).
    pub fn request(&mut self, req: &Request) -> Result<Reply, LinkError> {
        for _attempt in 0..self.timing.attempts.max(1) {
            let seq = self.send(req)?;
            let end = Instant::now() + self.timing.answer_timeout;
            // Read at least once: a host that was not scheduled until past
            // the timeout reads the answer waiting for it, not re-sends.
            loop {
                for (s, r) in self.poll()? {
                    if s == seq {
                        return Ok(r);
                    }
                }
                if Instant::now() >= end {
                    break;
                }
            }
        }
        Err(LinkError::Silent {
            port: self.name.clone(),
            request: request_name(req),
            tries: self.timing.attempts.max(1),
            each_ms: self.timing.answer_timeout.as_millis() as u64,
        })
    }

    /// Sends `req`; `Ok` on an ack, the reason on a nack.
    pub fn command(&mut self, req: &Request) -> Result<Reply, LinkError> {
        match self.request(req)? {
            Reply::Nack { error, .. } => Err(LinkError::Nack(request_name(req), error)),
            r => Ok(r),
        }
    }

    /// The handshake: fails with [`LinkError::VersionMismatch`] when the
    /// robot speaks another version.
    pub fn hello(&mut self) -> Result<HelloInfo, LinkError> {
        match self.command(&Request::Hello {
            version: PROTOCOL_VERSION,
        })? {
            Reply::Hello { version, .. } if version != PROTOCOL_VERSION => {
                Err(LinkError::VersionMismatch { robot: version })
            }
            Reply::Hello {
                version,
                capabilities,
                chip,
                robot,
                ..
            } => {
                let h = HelloInfo {
                    version,
                    capabilities,
                    chip: chip.as_str().into(),
                    robot,
                };
                self.last_hello = Some(h.clone());
                Ok(h)
            }
            r => Err(LinkError::Unexpected(format!("{r:?}"))),
        }
    }
}
