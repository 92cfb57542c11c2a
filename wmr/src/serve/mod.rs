//! # `wmr serve`: one process owns the link
//!
//! `wmr serve --port DEV` opens the robot's port (exclusively), keeps the
//! link alive and serves any number of clients over a Unix domain socket:
//! every other `wmr` command (`drive`, `record`, `pose-feed`, `upload`,
//! `watch`, ...) and library users such as the ROS 2 bridge, all at once.
//!
//! **The socket.** By default `$XDG_RUNTIME_DIR/wmr/<port>.sock` (else
//! `/tmp/wmr-<uid>/<port>.sock`), `<port>` being the port's absolute path
//! with every character other than a letter or digit replaced by `_`
//! (`/dev/ttyACM0` → `_dev_ttyACM0.sock`): [`default_socket_path`]. The
//! directory is created with mode 0700, the socket with 0600 (only its
//! user may drive the robot). `wmr serve --socket PATH` puts it elsewhere;
//! its first stdout line is the socket's path.
//!
//! **How a client finds it.** `wmr --serve PATH CMD` (or `WMR_SERVE=PATH`)
//! talks to that server. `wmr --port DEV CMD` goes through the server of
//! `DEV` when one listens on DEV's default socket, and opens DEV directly
//! otherwise: the same command line works with and without a server.
//! A library user does the same with [`Endpoint::resolve`] and
//! [`open_link`], or [`crate::Link::connect`] for a known socket: the
//! result is an ordinary [`crate::Link`] (D95).
//!
//! **On the socket** run the link's own frames (book/src/reference/protocol.md), so that
//! the client side is the existing [`crate::Link`] over a
//! [`std::os::unix::net::UnixStream`]: no command has code of its own for
//! the server. The server gives each request a sequence number of its own
//! on the robot's link and answers the client under the client's number;
//! telemetry goes to every client that turned it on (the robot sends the
//! union of the groups at the highest rate asked, each frame unchanged, so
//! that a gap in its sequence numbers is a frame lost on the robot's side or
//! the line), events go to every client (D96).
//!
//! **Keep-alive, clock, reconnection** (D97): a clock-sync keep-alive at
//! the link timing's period (a fifth of the robot's link timeout) and a
//! status every 250 ms while a client has sent a request within the link
//! timeout, or whenever the robot is not moving; while the robot moves and
//! no client is alive the server is silent, so that the robot's
//! link-silence stop still protects it when its driver is gone. Its clock
//! (offset and round trip of the best recent sync) is printed. A lost port
//! (unplug, a restarted simulator) is re-opened every 250 ms; a robot
//! whose clock went backwards has reset: reported with its reset cause, its
//! telemetry setting restored.
//!
//! **Exit** (D98): on Ctrl-C / SIGTERM or after `--for`, with a JSON summary
//! of its counters on stdout; status 0 only when nothing unexpected
//! happened (no robot reset but a requested reboot, no link-loss stop, no
//! lost port, the link up at the end), 1 otherwise and at once when the port
//! stays lost beyond `--give-up-after`.

mod core;
mod live;
mod mux;
mod server;

pub use mux::{with_seq, ClientId, Mux, MuxCounters, Out, TelemetrySub};
pub use server::{serve, serve_until, ServeError, ServeSummary};

use crate::link::{Link, LinkError};
use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The environment variable naming a server's socket (`--serve`).
pub const SOCKET_ENV: &str = "WMR_SERVE";

/// Longest socket path a Unix domain socket takes \[bytes\] (`sun_path`
/// less its terminating zero).
pub const MAX_SOCKET_PATH: usize = 107;

/// `wmr serve` options.
#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    /// The socket to listen on [default: $XDG_RUNTIME_DIR/wmr/<port>.sock,
    /// else /tmp/wmr-<uid>/<port>.sock].
    #[arg(long, value_name = "PATH")]
    pub socket: Option<PathBuf>,
    /// Stop serving after this long [s] (default: until Ctrl-C or SIGTERM).
    #[arg(long = "for", value_name = "S")]
    pub for_s: Option<f64>,
    /// Exit with an error when the port stays lost (or the robot silent)
    /// this long [s] (default: keep trying).
    #[arg(long, value_name = "S")]
    pub give_up_after: Option<f64>,
    /// Also serve a live view to Foxglove (a ws-protocol WebSocket server:
    /// the topics and schemas of `wmr record --mcap`; book/src/how-to/foxglove.md).
    /// The server then asks the robot for every telemetry group at
    /// --live-rate-hz itself.
    #[arg(long)]
    pub live: bool,
    /// --live-host, --live-port.
    #[command(flatten)]
    pub live_at: ros_mcap::live::LiveArgs,
    /// Telemetry rate the live view asks for [Hz].
    #[arg(long, value_name = "HZ", default_value_t = 50, value_parser = clap::value_parser!(u16).range(1..=1000))]
    pub live_rate_hz: u16,
    /// d, G ahead of the axle midpoint, for the live view's base_link [m]
    /// [default: body.com_offset_m of the robot file the robot runs, read
    /// from its store; the paper robot's 0.05 when it cannot tell, with
    /// the reason logged].
    #[arg(long, value_name = "M", value_parser = ros_mcap::parse_com_offset_m)]
    pub com_offset_m: Option<f64>,
}

/// The user's runtime directory for sockets: `$XDG_RUNTIME_DIR/wmr`, else
/// `/tmp/wmr-<uid>`.
pub fn socket_dir() -> PathBuf {
    match std::env::var_os("XDG_RUNTIME_DIR").filter(|d| !d.is_empty()) {
        Some(d) => PathBuf::from(d).join("wmr"),
        None => PathBuf::from(format!("/tmp/wmr-{}", uid())),
    }
}

fn uid() -> u32 {
    // SAFETY: getuid has no preconditions and cannot fail.
    unsafe { libc::getuid() }
}

/// The default socket of a server of `port`: in [`socket_dir`], named after
/// the port's absolute path (symbolic links not resolved: a port that is a
/// link to a device that comes and goes keeps its socket).
pub fn default_socket_path(port: &str) -> PathBuf {
    let p = Path::new(port);
    let abs = if p.is_absolute() {
        p.to_path_buf()
    } else {
        std::env::current_dir()
            .map(|d| d.join(p))
            .unwrap_or_else(|_| p.to_path_buf())
    };
    let name: String = abs
        .to_string_lossy()
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    socket_dir().join(format!("{name}.sock"))
}

/// A connection to a server: a [`UnixStream`] whose end (the server gone)
/// is an error rather than silence.
pub struct ServerStream(UnixStream);

impl Read for ServerStream {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        match self.0.read(buf) {
            Ok(0) if !buf.is_empty() => Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "wmr serve closed the connection",
            )),
            r => r,
        }
    }
}

impl Write for ServerStream {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

// The client side of `Link` lives here, beside the socket it connects
// to, so that `link` does not depend on `serve`.
impl Link {
    /// A link through the `wmr serve` listening on `socket` (see
    /// this module) with a fixed answer timeout: the same link as
    /// [`Link::open`]'s, the server routing its requests and answers among
    /// its other clients.
    pub fn connect(socket: &std::path::Path, timeout: Duration) -> Result<Self, LinkError> {
        Self::connect_timed(socket, Some(timeout))
    }

    /// [`Link::connect`] with the answer timeout derived from the link
    /// timeout unless `timeout` is given (as [`Link::open_timed`]).
    pub fn connect_timed(
        socket: &std::path::Path,
        timeout: Option<Duration>,
    ) -> Result<Self, LinkError> {
        let stream = connect(socket)?;
        Ok(Self::from_port_timed(Box::new(stream), timeout))
    }
}

/// Connects to the server listening on `socket`; reads wait at most 5 ms
/// (as a port's do, for [`Link`]).
pub fn connect(socket: &Path) -> Result<ServerStream, LinkError> {
    let shown = socket.display().to_string();
    let hint = "is `wmr serve --port DEV` running?";
    if !socket.exists() {
        return Err(LinkError::NoServer(
            shown,
            format!("no such socket ({hint})"),
        ));
    }
    let s = UnixStream::connect(socket).map_err(|e| {
        LinkError::NoServer(
            shown.clone(),
            match e.kind() {
                std::io::ErrorKind::ConnectionRefused => {
                    format!("nobody listens there: a stale socket ({hint})")
                }
                _ => format!("{e} ({hint})"),
            },
        )
    })?;
    s.set_read_timeout(Some(Duration::from_millis(5)))
        .map_err(|e| LinkError::NoServer(shown.clone(), e.to_string()))?;
    Ok(ServerStream(s))
}

/// Where a command talks to the robot.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Endpoint {
    /// The port itself (exclusive: no other process can use it meanwhile).
    Port(String),
    /// A `wmr serve` socket.
    Server(PathBuf),
}

impl Endpoint {
    /// `serve` when given (`--serve`, `WMR_SERVE`); else the server of
    /// `port` when one listens on its [`default_socket_path`]; else the
    /// port itself.
    pub fn resolve(port: Option<&str>, serve: Option<&Path>) -> Result<Self, LinkError> {
        if let Some(s) = serve {
            return Ok(Self::Server(s.to_path_buf()));
        }
        let port = port.ok_or_else(|| {
            LinkError::Io(format!(
                "no port: give --port PATH (or set WMR_PORT), or --serve SOCKET ({SOCKET_ENV})"
            ))
        })?;
        let sock = default_socket_path(port);
        if sock.exists() && UnixStream::connect(&sock).is_ok() {
            return Ok(Self::Server(sock));
        }
        Ok(Self::Port(port.to_string()))
    }
}

/// Opens `ep` and shakes hands: the protocol version checked, the answer
/// timing derived from the robot's link timeout (`timeout`, when given,
/// replaces the answer timeout), as every `wmr` command starts.
pub fn open_link(ep: &Endpoint, timeout: Option<Duration>) -> Result<Link, LinkError> {
    let mut link = match ep {
        Endpoint::Port(p) => Link::open_timed(p, timeout)?,
        Endpoint::Server(s) => {
            Link::connect_timed(s, timeout)?.named(&format!("wmr serve at {}", s.display()))
        }
    };
    link.hello()?;
    if let Ok(wmr_protocol::Reply::Param { value, .. }) = link.command(
        &wmr_protocol::Request::GetParam(wmr_protocol::ParamId::LinkTimeoutMs),
    ) {
        if value.is_finite() && value >= 1.0 {
            link.set_link_timeout_ms(value as u32);
        }
    }
    Ok(link)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_socket_is_named_after_the_port() {
        let p = default_socket_path("/dev/ttyACM0");
        assert_eq!(p.file_name().unwrap(), "_dev_ttyACM0.sock");
        assert_eq!(p.parent().unwrap(), socket_dir());
        // Two ports, two sockets.
        assert_ne!(p, default_socket_path("/dev/ttyACM1"));
        // A relative port is named by its absolute path.
        let cwd = std::env::current_dir().unwrap();
        assert_eq!(
            default_socket_path("robot"),
            default_socket_path(cwd.join("robot").to_str().unwrap())
        );
    }

    #[test]
    fn a_missing_server_is_a_clear_error() {
        let e = connect(Path::new("/nonexistent-dir/wmr.sock"))
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("/nonexistent-dir/wmr.sock") && e.contains("wmr serve"),
            "{e}"
        );
        assert!(!e.contains('\n'));
    }

    #[test]
    fn explicit_server_wins_and_no_port_is_an_error() {
        let s = Path::new("/tmp/x.sock");
        assert_eq!(
            Endpoint::resolve(Some("/dev/ttyACM0"), Some(s)).unwrap(),
            Endpoint::Server(s.into())
        );
        assert_eq!(
            Endpoint::resolve(Some("/dev/no-server-here-0"), None).unwrap(),
            Endpoint::Port("/dev/no-server-here-0".into())
        );
        let e = Endpoint::resolve(None, None).unwrap_err().to_string();
        assert!(e.contains("--port") && e.contains("--serve"), "{e}");
    }
}
