//! # wmr-protocol
//!
//! The host link of the trajectory-tracking robot: one `no_std`, allocation-free
//! crate used by the firmware, the simulated robot (`hil-sim device`) and the
//! host tool (`wmr`).
//!
//! * Messages: [`Request`] (host → robot) and [`Reply`] (robot → host:
//!   answers, telemetry, events), serde + postcard.
//! * Framing: each message travels in an envelope
//!   `{version, seq, body, crc16}` (postcard), COBS-encoded and terminated by
//!   a zero byte; [`FrameDecoder`] reassembles frames from any byte chunks
//!   with postcard's COBS accumulator and checks the version and the
//!   CRC-16/CCITT-FALSE ([`crc`]) over version, seq and body.
//! * Versioning: [`PROTOCOL_VERSION`]; the rule is in `book/src/reference/protocol.md`.
//!
//! Bad input never panics: every decode outcome is a [`Decoded`] value.
#![no_std]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod crc;
pub mod message;

pub use message::*;

use postcard::accumulator::{CobsAccumulator, FeedResult};
use serde::{de::DeserializeOwned, Deserialize, Serialize};

/// The protocol version. Bumped on any change to a message other than an
/// addition at the end of an enum that old peers never receive (see
/// `book/src/reference/protocol.md`, "Versioning").
pub const PROTOCOL_VERSION: u16 = 5;

/// Largest serialized message body \[bytes\].
pub const MAX_BODY: usize = 240;

/// Largest frame on the wire, COBS overhead and delimiter included \[bytes\].
pub const MAX_FRAME: usize = 256;

/// The envelope around every message body.
#[derive(Serialize, Deserialize)]
struct Envelope<'a> {
    version: u16,
    seq: u16,
    #[serde(borrow)]
    body: &'a [u8],
    crc: u16,
}

fn envelope_crc(version: u16, seq: u16, body: &[u8]) -> u16 {
    let c = crc::crc16_update(crc::CRC_INIT, &version.to_le_bytes());
    let c = crc::crc16_update(c, &seq.to_le_bytes());
    crc::crc16_update(c, body)
}

/// Why a message could not be framed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EncodeError {
    /// The body exceeds [`MAX_BODY`] or the output buffer is too small.
    TooLarge,
}

/// Frames `msg` with sequence number `seq` at [`PROTOCOL_VERSION`] into
/// `out` (at least [`MAX_FRAME`] bytes to be sure); returns the frame,
/// delimiter included.
pub fn encode<'o, M: Serialize>(
    msg: &M,
    seq: u16,
    out: &'o mut [u8],
) -> Result<&'o mut [u8], EncodeError> {
    encode_with_version(msg, seq, PROTOCOL_VERSION, out)
}

/// As [`encode`] with an explicit version (for tests of mismatches).
pub fn encode_with_version<'o, M: Serialize>(
    msg: &M,
    seq: u16,
    version: u16,
    out: &'o mut [u8],
) -> Result<&'o mut [u8], EncodeError> {
    let mut body = [0u8; MAX_BODY];
    let body = postcard::to_slice(msg, &mut body).map_err(|_| EncodeError::TooLarge)?;
    let env = Envelope {
        version,
        seq,
        crc: envelope_crc(version, seq, body),
        body,
    };
    let frame = postcard::to_slice_cobs(&env, out).map_err(|_| EncodeError::TooLarge)?;
    if frame.len() > MAX_FRAME {
        return Err(EncodeError::TooLarge);
    }
    Ok(frame)
}

/// One outcome of [`FrameDecoder::feed`].
#[derive(Clone, Debug, PartialEq)]
pub enum Decoded<M> {
    /// A valid frame.
    Frame {
        /// The envelope's sequence number.
        seq: u16,
        /// The message.
        msg: M,
    },
    /// A frame of another protocol version. `hello` is set when its body
    /// still decodes as `M` (the handshake messages never change, so a
    /// peer can answer a hello of any version with its own).
    OtherVersion {
        /// The envelope's sequence number.
        seq: u16,
        /// The peer's version.
        version: u16,
        /// The message, if it decodes.
        msg: Option<M>,
    },
    /// A dropped frame; `seq` when the envelope was intact (CRC good).
    Error {
        /// The envelope's sequence number, when trustworthy.
        seq: Option<u16>,
        /// Why.
        error: ErrorCode,
    },
}

/// Reassembles frames from byte chunks: a COBS accumulator of `N` bytes
/// (use [`MAX_FRAME`]), then envelope, version, CRC and body checks.
pub struct FrameDecoder<const N: usize> {
    acc: CobsAccumulator<N>,
    pending: usize,
    discarding: bool,
}

impl<const N: usize> Default for FrameDecoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameDecoder<N> {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            acc: CobsAccumulator::new(),
            pending: 0,
            discarding: false,
        }
    }

    /// Feeds bytes; returns at most one outcome and the input not yet
    /// consumed (call again with it until it is empty). Empty frames
    /// (a lone delimiter, used to resynchronise) are skipped silently; the
    /// rest of an oversized frame is discarded up to its delimiter.
    pub fn feed<'a, M: DeserializeOwned>(
        &mut self,
        input: &'a [u8],
    ) -> (Option<Decoded<M>>, &'a [u8]) {
        if input.is_empty() {
            return (None, input);
        }
        if self.discarding {
            return match input.iter().position(|&b| b == 0) {
                Some(i) => {
                    self.discarding = false;
                    (None, &input[i + 1..])
                }
                None => (None, &[]),
            };
        }
        if self.pending == 0 && input[0] == 0 {
            return (None, &input[1..]);
        }
        match self.acc.feed_ref::<Envelope<'_>>(input) {
            FeedResult::Consumed => {
                self.pending += input.len();
                (None, &[])
            }
            FeedResult::OverFull(rest) => {
                self.pending = 0;
                // `rest` starts after the delimiter when the frame ended in
                // this chunk; otherwise the frame goes on: discard it.
                let ended = rest.len() < input.len() && input[input.len() - rest.len() - 1] == 0;
                self.discarding = !ended;
                let err = Decoded::Error {
                    seq: None,
                    error: ErrorCode::TooLong,
                };
                (Some(err), if ended { rest } else { &[] })
            }
            FeedResult::DeserError(rest) => {
                self.pending = 0;
                let err = Decoded::Error {
                    seq: None,
                    error: ErrorCode::Malformed,
                };
                (Some(err), rest)
            }
            FeedResult::Success { data, remaining } => {
                self.pending = 0;
                (Some(check_envelope(&data)), remaining)
            }
        }
    }

    /// Feeds all of `input`, calling `on` with each outcome in order: the
    /// loop around [`feed`](Self::feed) that every reader of a byte stream
    /// writes (same outcomes, whatever the chunking).
    pub fn feed_all<M: DeserializeOwned>(
        &mut self,
        mut input: &[u8],
        mut on: impl FnMut(Decoded<M>),
    ) {
        while !input.is_empty() {
            let (decoded, rest) = self.feed::<M>(input);
            input = rest;
            if let Some(d) = decoded {
                on(d);
            }
        }
    }
}

fn check_envelope<M: DeserializeOwned>(env: &Envelope<'_>) -> Decoded<M> {
    if envelope_crc(env.version, env.seq, env.body) != env.crc {
        return Decoded::Error {
            seq: None,
            error: ErrorCode::BadCrc,
        };
    }
    let msg = match postcard::take_from_bytes::<M>(env.body) {
        Ok((m, [])) => Some(m),
        _ => None,
    };
    if env.version != PROTOCOL_VERSION {
        return Decoded::OtherVersion {
            seq: env.seq,
            version: env.version,
            msg,
        };
    }
    match msg {
        Some(msg) => Decoded::Frame { seq: env.seq, msg },
        None => Decoded::Error {
            seq: Some(env.seq),
            error: ErrorCode::Malformed,
        },
    }
}

#[cfg(test)]
mod tests;
