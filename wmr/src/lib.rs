//! # wmr
//!
//! Host tool for the trajectory-tracking robot: talks [`wmr_protocol`] over a
//! serial port, a USB CDC-ACM port or the pseudo-terminal of the simulated
//! robot (`hil-sim device --pty`). See `wmr --help` and book/src/how-to/talk-to-the-robot.md.
//!
//! ## Through `wmr serve`
//!
//! A [`Link`] may also run through a `wmr serve` process that owns the port,
//! beside any number of other clients (`wmr record`, `drive`, a ROS 2
//! bridge): [`serve::Endpoint::resolve`] picks the server named by the user
//! (`--serve`, [`serve::SOCKET_ENV`]), else the server of the port when one
//! listens on its [`serve::default_socket_path`], else the port itself, and
//! [`serve::open_link`] opens it and shakes hands as every `wmr` command
//! does; [`Link::connect`] takes a known socket. The link behaves as over
//! the port (the server routes answers by sequence number and fans
//! telemetry out; book/src/how-to/serve.md):
//!
//! ```no_run
//! use wmr::serve::{open_link, Endpoint};
//! let ep = Endpoint::resolve(Some("/dev/ttyACM0"), None)?;
//! let mut link = open_link(&ep, None)?;
//! let status = link.command(&wmr_protocol::Request::GetStatus)?;
//! # Ok::<(), wmr::LinkError>(())
//! ```
#![deny(missing_docs)]

pub mod bringup;
pub mod cli;
pub mod commission;
pub mod drive;
pub mod identify;
pub mod link;
pub mod params;
pub mod pose_feed;
pub mod record;
pub mod reference;
pub mod refusal;
pub mod robot;
pub mod serve;
pub mod session;
pub mod status;
pub mod timing;
pub mod upload;
pub mod watch;

pub use link::{HelloInfo, Link, LinkError, OpenFailure};
