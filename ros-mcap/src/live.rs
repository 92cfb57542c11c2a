//! The live view (feature `live`): a Foxglove WebSocket server
//! (ws-protocol `foxglove.websocket.v1`, the `foxglove` crate) carrying
//! the MCAP logs' topics with the same `ros2msg` schemas and CDR bytes
//! ([`crate::CHANNELS`], [`crate::RosMessages::encoded`]), so one Foxglove
//! layout (`book/src/how-to/foxglove-layout.json`) shows a log and a live robot or
//! simulation alike. `wmr serve --live`, `wmr-ros2 --live` and `hil-sim
//! run --live` start it; it binds 127.0.0.1 unless told otherwise (D158).

use crate::frames::{LogFrame, RosFrames};
use crate::{msg, Geometry, LogError};
use foxglove::{Context, PartialMetadata, RawChannel, Schema, WebSocketServer};
use std::sync::Arc;

/// The address the live view binds by default: loopback only.
pub const DEFAULT_LIVE_HOST: &str = "127.0.0.1";
/// The ws-protocol's customary port (Foxglove's "Open connection" default).
pub const DEFAULT_LIVE_PORT: u16 = 8765;

/// The live view's address flags, one declaration for `hil-sim run`,
/// `wmr serve` and `wmr-ros2` (each flattens it beside its own `--live`,
/// whose help says what that program streams).
#[derive(Clone, Debug, PartialEq, Eq, clap::Args)]
pub struct LiveArgs {
    /// Address the live view binds (loopback unless you open it).
    #[arg(long, value_name = "HOST", default_value = DEFAULT_LIVE_HOST)]
    pub live_host: String,
    /// Port of the live view (0: any free port; the one taken is printed).
    #[arg(long, value_name = "PORT", default_value_t = DEFAULT_LIVE_PORT)]
    pub live_port: u16,
}

impl LiveArgs {
    /// Starts a view on these flags' address (see [`LiveView::start`]).
    pub fn start(&self, geometry: Geometry, name: &str) -> Result<LiveView, LiveError> {
        LiveView::start(&self.live_host, self.live_port, geometry, name)
    }

    /// The address a client opens, for a view listening on `port` (the
    /// one taken when the flag said 0): the line each program prints.
    pub fn url(&self, port: u16) -> String {
        format!("ws://{}:{port}", self.live_host)
    }
}

/// Why the live view could not start.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LiveError {
    /// A channel could not be created.
    #[error("live view: channel {topic}: {reason}")]
    Channel {
        /// Its topic.
        topic: &'static str,
        /// The library's reason.
        reason: String,
    },
    /// The server did not start (the port taken, the address not local).
    #[error("live view: cannot serve on {host}:{port}: {reason} (choose another with --live-port, 0 for any free port)")]
    Bind {
        /// Host asked for.
        host: String,
        /// Port asked for.
        port: u16,
        /// The library's reason.
        reason: String,
    },
}

/// A running live view: publishes each frame's messages to the clients
/// subscribed to their topics.
pub struct LiveView {
    /// Held: the server and the channels keep only weak references to it.
    _context: Arc<Context>,
    channels: Vec<Arc<RawChannel>>,
    frames: RosFrames,
    server: Option<foxglove::WebSocketServerHandle>,
    port: u16,
}

impl LiveView {
    /// Serves on `host:port` (`port` 0: any free port, see [`Self::port`])
    /// for a robot of `geometry`; `name` is the server's name the client
    /// sees ("wmr serve", "wmr-ros2", "hil-sim run").
    pub fn start(host: &str, port: u16, geometry: Geometry, name: &str) -> Result<Self, LiveError> {
        // Its own context: several views in one process (tests) stay apart.
        let ctx = Context::new();
        let mut channels = Vec::new();
        for (topic, ty) in crate::CHANNELS {
            let ch = ctx
                .channel_builder(topic)
                .message_encoding("cdr")
                .schema(Schema::new(ty, "ros2msg", msg::schema(ty).into_bytes()))
                .build_raw()
                .map_err(|e| LiveError::Channel {
                    topic,
                    reason: e.to_string(),
                })?;
            channels.push(ch);
        }
        let server = WebSocketServer::new()
            .name(name)
            .bind(host, port)
            .context(&ctx)
            .start_blocking()
            .map_err(|e| LiveError::Bind {
                host: host.to_string(),
                port,
                reason: e.to_string(),
            })?;
        let port = server.port();
        Ok(Self {
            _context: ctx,
            channels,
            frames: RosFrames::new(geometry),
            server: Some(server),
            port,
        })
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// True once a client has subscribed to every topic (a run that waits
    /// for its viewer starts then: nothing published before is lost).
    pub fn subscribed_to_all(&self) -> bool {
        self.channels.iter().all(|c| c.has_sinks())
    }

    /// Waits until no client is connected (`hil-sim run --live-wait`: the
    /// viewer that was waited for leaves when it has seen the run).
    pub fn wait_for_clients_to_leave(&self) {
        while self.clients() > 0 {
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.server.as_ref().map_or(0, |s| s.client_count())
    }

    /// Publishes frame `f` on every topic (`/diagnostics` when due), each
    /// message stamped with the frame's time (the same as in the MCAP log).
    pub fn publish(&mut self, f: &LogFrame) -> Result<(), LogError> {
        for (i, data) in self.frames.messages(f).encoded()? {
            self.channels[i].log_with_meta(
                &data,
                PartialMetadata {
                    log_time: Some(f.stamp_ns),
                },
            );
        }
        Ok(())
    }
}

impl Drop for LiveView {
    fn drop(&mut self) {
        if let Some(s) = self.server.take() {
            // Close the connections: a graceful shutdown.
            s.stop().wait_blocking();
        }
    }
}
